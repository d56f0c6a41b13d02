#include "placedb/builder/tracks.h"

#include <gtest/gtest.h>

#include <optional>
#include <random>
#include <vector>

namespace placedb {
namespace {

std::optional<Pose> At(double x, double y) {
  Pose p;
  p.translation = Eigen::Vector3d(x, y, 0.0);
  return p;
}

TEST(TrackNeighboursTest, NearestByPositionWhenEveryKeyframeHasAPose) {
  // 0 and 3 stand together, 1 and 2 apart; 4 is far on y alone.
  const std::vector<std::optional<Pose>> poses = {At(0, 0), At(5, 0), At(5.5, 0), At(0.1, 0),
                                                  At(0.2, 9)};
  const std::vector<std::vector<size_t>> n = TrackNeighbours(poses, 2);
  ASSERT_EQ(n.size(), 5u);
  EXPECT_EQ(n[0], (std::vector<size_t>{3, 1}));
  EXPECT_EQ(n[1], (std::vector<size_t>{2, 3}));
  EXPECT_EQ(n[2], (std::vector<size_t>{1, 3}));
  EXPECT_EQ(n[3], (std::vector<size_t>{0, 1}));
  EXPECT_EQ(n[4], (std::vector<size_t>{3, 0}));
  // Ties go to the lower index; never more than the others.
  const std::vector<std::optional<Pose>> same = {At(1, 1), At(1, 1), At(1, 1)};
  EXPECT_EQ(TrackNeighbours(same, 5)[1], (std::vector<size_t>{0, 2}));
}

TEST(TrackNeighboursTest, NearestInOrderWithoutPoses) {
  std::vector<std::optional<Pose>> poses = {At(0, 0), std::nullopt, At(1, 0), At(2, 0)};
  const std::vector<std::vector<size_t>> n = TrackNeighbours(poses, 3);
  EXPECT_EQ(n[0], (std::vector<size_t>{1, 2, 3}));
  EXPECT_EQ(n[1], (std::vector<size_t>{0, 2, 3}));
  EXPECT_EQ(n[2], (std::vector<size_t>{1, 3, 0}));
  EXPECT_EQ(n[3], (std::vector<size_t>{2, 1, 0}));
  EXPECT_TRUE(TrackNeighbours({At(0, 0)}, 4)[0].empty());
  EXPECT_TRUE(TrackNeighbours({}, 4).empty());
  EXPECT_TRUE(TrackNeighbours(poses, 0)[2].empty());
}

TEST(TrackNeighboursTest, ANewKeyframesNeighbours) {
  const std::vector<std::optional<Pose>> poses = {At(0, 0), At(5, 0), At(1, 0), At(9, 0)};
  EXPECT_EQ(TrackNeighboursOfNew(poses, At(4, 0), 2), (std::vector<size_t>{1, 2}));
  // Without its pose, or another's: the last ones.
  EXPECT_EQ(TrackNeighboursOfNew(poses, std::nullopt, 3), (std::vector<size_t>{3, 2, 1}));
  std::vector<std::optional<Pose>> partly = poses;
  partly[0].reset();
  EXPECT_EQ(TrackNeighboursOfNew(partly, At(4, 0), 2), (std::vector<size_t>{3, 2}));
  EXPECT_EQ(TrackNeighboursOfNew(poses, At(4, 0), 9).size(), 4u);
  EXPECT_TRUE(TrackNeighboursOfNew({}, At(4, 0), 2).empty());
}

// n ORB-like features with random descriptors.
FeatureSet Random(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  FeatureSet f;
  f.descriptors = cv::Mat(n, 32, CV_8U);
  for (int i = 0; i < n; ++i) {
    f.keypoints.emplace_back(cv::Point2f(static_cast<float>(i), 0.0f), 31.0f);
    for (int b = 0; b < 32; ++b) f.descriptors.at<uint8_t>(i, b) = static_cast<uint8_t>(rng());
  }
  return f;
}

TEST(TrackCountsTest, CountsTheNeighboursAFeatureMatchesIn) {
  const FeatureSet f = Random(40, 1);
  // Neighbour one holds features 0..19 (a few bits flipped), neighbour two
  // 10..29; an unrelated set matches nothing.
  FeatureSet one = Random(20, 2), two = Random(20, 3);
  for (int i = 0; i < 20; ++i) {
    f.descriptors.row(i).copyTo(one.descriptors.row(i));
    f.descriptors.row(i + 10).copyTo(two.descriptors.row(i));
    one.descriptors.at<uint8_t>(i, 5) ^= 0x11;
    two.descriptors.at<uint8_t>(i, 7) ^= 0x03;
  }
  const FeatureSet unrelated = Random(50, 4);
  const std::vector<int> counts = TrackCounts(f, {&one, &two, &unrelated});
  ASSERT_EQ(counts.size(), 40u);
  for (int i = 0; i < 40; ++i) {
    const int expected = (i < 20) + (i >= 10 && i < 30);
    EXPECT_EQ(counts[static_cast<size_t>(i)], expected) << i;
  }
  const FeatureSet empty;
  EXPECT_EQ(TrackCounts(f, {&empty}), std::vector<int>(40, 0));
  EXPECT_TRUE(TrackCounts(empty, {&one}).empty());
}

}  // namespace
}  // namespace placedb
