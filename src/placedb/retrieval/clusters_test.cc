// Spatial-locality clusters: grouping by place or by time, the neighbour
// graph, and their options.
#include "placedb/retrieval/clusters.h"

#include <gtest/gtest.h>

#include <cmath>

#include "placedb/retrieval/retriever.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::ThrowsWith;

// A database of keyframes at these positions (no features), in this order.
Database DatabaseAt(const std::vector<Eigen::Vector3d>& positions, bool with_poses = true) {
  Database db(FeatureType::kOrb, 32);
  FeatureSet none;
  none.descriptors = cv::Mat(0, 32, CV_8U);
  for (size_t i = 0; i < positions.size(); ++i) {
    Keyframe k;
    k.id = static_cast<int32_t>(i + 1);
    k.stored_size = cv::Size(64, 48);
    k.crop = cv::Rect(0, 0, 64, 48);
    if (with_poses) {
      Pose p;
      p.translation = positions[i];
      k.pose = p;
    }
    db.AddKeyframe(k, none);
  }
  return db;
}

// A robot drives 0 -> 10 m along x and back: the way back joins the way
// out's clusters (spatial locality, not time), neighbours follow the path.
TEST(ClusterSetTest, PosesGroupByPlaceAndLinkAlongThePath) {
  std::vector<Eigen::Vector3d> path;
  for (int i = 0; i <= 50; ++i) path.emplace_back(0.2 * i, 0.0, 0.0);
  for (int i = 50; i >= 0; --i) path.emplace_back(0.2 * i, 0.05, 0.0);
  const Database db = DatabaseAt(path);
  ClusterOptions options;
  options.radius_m = 1.0;
  const ClusterSet set = ClusterSet::Make(db, options);
  ASSERT_TRUE(set.by_pose());
  // Seeds every ~1.2 m along 10 m: far fewer clusters than keyframes.
  EXPECT_GE(set.size(), 5u);
  EXPECT_LE(set.size(), 11u);
  size_t members = 0;
  for (size_t c = 0; c < set.size(); ++c) {
    members += set.Members(static_cast<int>(c)).size();
    EXPECT_TRUE(std::is_sorted(set.Members(static_cast<int>(c)).begin(),
                               set.Members(static_cast<int>(c)).end()));
  }
  EXPECT_EQ(members, db.size());
  // The way back seeds no cluster of its own: it joins the way out's, each
  // keyframe the cluster of its place on the way out or a neighbour of it.
  int way_out = 0;
  for (uint32_t i = 0; i <= 50; ++i) way_out = std::max(way_out, set.ClusterOf(i));
  EXPECT_EQ(static_cast<size_t>(way_out) + 1, set.size());
  for (uint32_t i = 0; i <= 50; ++i) {
    const int out = set.ClusterOf(i), back = set.ClusterOf(101 - i);
    const auto& nb = set.Neighbours(out);
    EXPECT_TRUE(out == back || std::binary_search(nb.begin(), nb.end(), back)) << "keyframe " << i;
  }
  // Every keyframe is within the radius of its cluster's seed, and
  // consecutive keyframes are in the same or neighbouring clusters.
  for (uint32_t i = 0; i < db.size(); ++i) {
    const int c = set.ClusterOf(i);
    const uint32_t seed = set.Members(c).front();
    EXPECT_LE((db.keyframe(i).pose->translation - db.keyframe(seed).pose->translation).norm(),
              1.0 + 1e-9);
    if (i > 0 && set.ClusterOf(i - 1) != c) {
      const auto& nb = set.Neighbours(c);
      EXPECT_TRUE(std::binary_search(nb.begin(), nb.end(), set.ClusterOf(i - 1)));
    }
  }
  // The ends of the corridor are not neighbours; hops widen the search.
  const int start = set.ClusterOf(0), end = set.ClusterOf(50);
  EXPECT_FALSE(std::binary_search(set.Neighbours(start).begin(), set.Neighbours(start).end(), end));
  EXPECT_EQ(set.Around(start, 0), std::vector<int>{start});
  EXPECT_GT(set.Around(start, 2).size(), set.Around(start, 1).size());
  EXPECT_EQ(set.Around(start, 100).size(), set.size());
  EXPECT_EQ(set.KeyframesAround(start, 100).size(), db.size());
  EXPECT_EQ(set.Nearest(Eigen::Vector3d(0.1, 0.0, 0.0)), start);
  EXPECT_EQ(set.Nearest(Eigen::Vector3d(10.2, 0.0, 0.0)), end);
}

TEST(ClusterSetTest, WithoutPosesKeyframesGroupByTime) {
  const Database db = DatabaseAt(std::vector<Eigen::Vector3d>(23, Eigen::Vector3d::Zero()), false);
  ClusterOptions options;
  options.time_keyframes = 5;
  const ClusterSet set = ClusterSet::Make(db, options);
  EXPECT_FALSE(set.by_pose());
  ASSERT_EQ(set.size(), 5u);
  EXPECT_EQ(set.Members(4), (std::vector<uint32_t>{20, 21, 22}));
  EXPECT_EQ(set.Neighbours(2), (std::vector<int>{1, 3}));
  EXPECT_EQ(set.Nearest(Eigen::Vector3d::Zero()), -1);
  EXPECT_EQ(set.KeyframesAround(0, 1).size(), 10u);
}

TEST(ClusterSetTest, OptionsAreChecked) {
  ClusterOptions o;
  o.radius_m = 0.0;
  EXPECT_FALSE(o.Check().empty());
  o.radius_m = std::nan("");
  EXPECT_FALSE(o.Check().empty());
  o = ClusterOptions();
  o.time_keyframes = 0;
  EXPECT_FALSE(o.Check().empty());
  RetrievalOptions r;
  r.bow_candidates = 0;
  EXPECT_FALSE(r.Check().empty());
  r = RetrievalOptions();
  r.cluster_hops = 65;
  EXPECT_FALSE(r.Check().empty());
  EXPECT_EQ(ParseRetrievalMethod("bow"), RetrievalMethod::kBow);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([] { ParseRetrievalMethod("dbow"); },
                                          "exhaustive, bow or cluster"));
}

}  // namespace
}  // namespace placedb
