#include "placedb/query/query.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>
#include <sstream>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/feature/testing.h"
#include "placedb/feature/whole_image.h"
#include "placedb/query/ranking.h"
#include "placedb/util/testing.h"
#include "placedb/util/thread_pool.h"

namespace placedb {
namespace {
using testing_util::TempDir;
using testing_util::ThrowsWith;
namespace fs = std::filesystem;
using testing_util::RtabmapImage;

// query id -> ids of its true matches.
std::map<int, std::set<int>> ReadTruth() {
  std::ifstream in(PLACEDB_DATA_DIR "/rtabmap_loop/ground_truth.csv");
  std::map<int, std::set<int>> truth;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const size_t comma = line.find(',');
    std::istringstream ids(line.substr(comma + 1));
    std::set<int>& matches = truth[std::stoi(line.substr(0, comma))];
    for (int id; ids >> id;) matches.insert(id);
  }
  return truth;
}

// ORB features of images 1..84 extracted once; a database of 1..40
// assembled from them.
class QueryTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    extractor_ = FeatureExtractor::Create(testing::ModelFreeExtractorOptions()).release();
    features_ = new std::map<int, FeatureSet>();
    db_ = new Database(FeatureType::kOrb, 32, WholeImageDims(testing::ModelFreeExtractorOptions()));
    for (int i = 1; i <= 84; ++i) {
      const cv::Mat image = cv::imread(RtabmapImage(i));
      ASSERT_FALSE(image.empty()) << RtabmapImage(i);
      (*features_)[i] = extractor_->Extract(image);
      if (i <= 40) {
        Keyframe k;
        k.id = i;
        k.original_size = image.size();
        k.crop = cv::Rect(0, 0, image.cols, image.rows);
        k.stored_size = image.size();
        k.source = RtabmapImage(i);
        db_->AddKeyframe(k, (*features_)[i]);
      }
    }
  }
  static void TearDownTestSuite() {
    delete db_;
    delete features_;
    delete extractor_;
  }
  static const FeatureSet& Features(int i) { return features_->at(i); }

  static FeatureExtractor* extractor_;
  static std::map<int, FeatureSet>* features_;
  static Database* db_;
};
FeatureExtractor* QueryTest::extractor_ = nullptr;
std::map<int, FeatureSet>* QueryTest::features_ = nullptr;
Database* QueryTest::db_ = nullptr;

QueryOptions Unverified() {
  QueryOptions o;
  o.verify.enabled = false;
  return o;
}

// The verify stage skips candidates that cannot reach the top k (fewer
// matches than the k-th best inlier count): the ranked list is the one that
// verifying every candidate gives, on one thread or four, for every query.
// With the whole-image channel scoring too (the bound is then matches plus
// the bonus).
TEST_F(QueryTest, SkippedVerificationsNeverChangeTheRankedList) {
  ThreadPool pool(4);
  size_t skipped = 0;
  for (int q = 41; q <= 84; ++q) {
    for (const int top_k : {1, 3, 5}) {
      for (const double weight : {0.0, 10.0}) {
        QueryOptions all;
        all.top_k = 10;  // = verify.num_candidates: nothing can be skipped
        all.whole_image_weight = weight;
        const QueryResult every = QueryDatabase(*db_, Features(q), all);
        QueryOptions options;
        options.top_k = top_k;
        options.whole_image_weight = weight;
        QueryContext threaded;
        threaded.pool = &pool;
        for (const QueryResult& r : {QueryDatabase(*db_, Features(q), options),
                                     QueryDatabase(*db_, Features(q), options, threaded)}) {
          const size_t n = std::min<size_t>(top_k, every.ranked.size());
          ASSERT_EQ(r.ranked.size(), n) << "query " << q << " top " << top_k;
          for (size_t i = 0; i < n; ++i)
            EXPECT_EQ(r.ranked[i], every.ranked[i])
                << "query " << q << " top " << top_k << " #" << i;
          EXPECT_EQ(r.matched, every.matched) << "query " << q;
          EXPECT_LE(r.num_verified, every.num_verified);
          skipped += every.num_verified - r.num_verified;
        }
      }
    }
  }
  EXPECT_GT(skipped, 0u);  // the rule did skip some
  std::printf("verifications skipped over 44 queries x 3 top-k x 2: %zu\n", skipped);
}

// Query 42 revisits the place of keyframes 1-4: verified, a true match ranks
// first with many inliers; every stage reports its time and its counts.
TEST_F(QueryTest, Image42RanksATrueMatchFirst) {
  ASSERT_EQ(db_->size(), 40u);
  const QueryResult result = QueryDatabase(*db_, Features(42), QueryOptions());
  ASSERT_TRUE(result.matched);
  ASSERT_NE(result.best(), nullptr);
  EXPECT_EQ(result.ranked.size(), 5u);
  const std::set<int> truth = {1, 2, 3, 4};
  EXPECT_EQ(truth.count(result.best()->keyframe_id), 1u) << "best " << result.best()->keyframe_id;
  EXPECT_GT(result.num_query_features, 300);
  EXPECT_EQ(result.num_keyframes, 40u);
  EXPECT_EQ(result.num_examined, 40u);
  // At most VerifyOptions().num_candidates; at least the top k (the rest
  // only when they could still rank among them).
  EXPECT_LE(result.num_verified, 10u);
  EXPECT_GE(result.num_verified, 5u);
  EXPECT_TRUE(result.best()->verified());
  EXPECT_GE(result.best()->num_inliers, 40);
  EXPECT_LE(result.best()->num_inliers, result.best()->num_matches);
  EXPECT_EQ(result.best()->score, result.best()->num_inliers);
  EXPECT_EQ(result.best()->source, RtabmapImage(result.best()->keyframe_id));
  EXPECT_GT(result.times.match_ms, 0.0);
  EXPECT_GT(result.times.verify_ms, 0.0);
  EXPECT_GE(result.times.total_ms, result.times.match_ms + result.times.verify_ms);
  for (size_t i = 1; i < result.ranked.size(); ++i) {
    EXPECT_GE(result.ranked[i - 1].score, result.ranked[i].score);
  }
}

// Queries 41..84 against keyframes 1..40, with and without verification:
// verification does not lower recall@1. Image 46 has no ORB features at all
// (no answer, not an error). Measured: 43 / 44 both ways.
TEST_F(QueryTest, RecallAtOneOnTheLoopWithAndWithoutVerification) {
  const auto truth = ReadTruth();
  ASSERT_EQ(truth.size(), 44u);
  int verified = 0, unverified = 0;
  for (int q = 41; q <= 84; ++q) {
    const QueryResult v = QueryDatabase(*db_, Features(q), QueryOptions());
    const QueryResult u = QueryDatabase(*db_, Features(q), Unverified());
    if (q == 46) {
      EXPECT_EQ(v.num_query_features, 0);
      EXPECT_TRUE(v.ranked.empty());
      EXPECT_FALSE(v.matched);
      continue;
    }
    ASSERT_FALSE(v.ranked.empty()) << "query " << q;
    verified += truth.at(q).count(v.ranked[0].keyframe_id) > 0;
    unverified += truth.at(q).count(u.ranked[0].keyframe_id) > 0;
    for (const RankedKeyframe& k : u.ranked) EXPECT_FALSE(k.verified());
  }
  std::printf("R@1 verified %d/44, unverified %d/44\n", verified, unverified);
  EXPECT_GE(verified, 43);
  EXPECT_GE(unverified, 43);
  EXPECT_GE(verified, unverified);
}

// Verified, the ranked list is the num_candidates best by matches,
// re-ranked by inliers.
TEST_F(QueryTest, VerificationReranksTheBestCandidatesByInliers) {
  QueryOptions all = Unverified();
  all.top_k = 40;
  QueryOptions verified;
  verified.top_k = 10;
  for (int q : {44, 60, 77}) {
    const QueryResult u = QueryDatabase(*db_, Features(q), all);
    const QueryResult v = QueryDatabase(*db_, Features(q), verified);
    ASSERT_GE(u.ranked.size(), 10u);
    std::set<int32_t> best_by_matches, verified_ids;
    for (size_t i = 0; i < 10; ++i) best_by_matches.insert(u.ranked[i].keyframe_id);
    for (const RankedKeyframe& k : v.ranked) {
      verified_ids.insert(k.keyframe_id);
      EXPECT_TRUE(k.verified());
    }
    EXPECT_EQ(verified_ids, best_by_matches) << "query " << q;
    for (size_t i = 1; i < v.ranked.size(); ++i) {
      const RankedKeyframe &a = v.ranked[i - 1], &b = v.ranked[i];
      EXPECT_TRUE(a.num_inliers > b.num_inliers ||
                  (a.num_inliers == b.num_inliers && a.num_matches >= b.num_matches))
          << "query " << q << " rank " << i;
    }
  }
}

// One thread or N: the same answer, verified or not, top 5 or everything.
TEST_F(QueryTest, MultiThreadedEqualsSingleThreaded) {
  QueryOptions top5;
  QueryOptions all = Unverified();
  all.top_k = 40;
  std::map<int, QueryResult> single_top5, single_all;
  for (int q = 41; q <= 84; ++q) {
    single_top5[q] = QueryDatabase(*db_, Features(q), top5);
    single_all[q] = QueryDatabase(*db_, Features(q), all);
  }
  int compared = 0;
  for (int threads : {2, 3, 4}) {
    ThreadPool pool(threads);
    QueryContext context;
    context.pool = &pool;
    for (int q = 41; q <= 84; ++q) {
      EXPECT_EQ(QueryDatabase(*db_, Features(q), top5, context).ranked, single_top5[q].ranked)
          << threads << " threads, query " << q;
      ++compared;
    }
    for (int q = 41; q <= 84; q += 7) {
      EXPECT_EQ(QueryDatabase(*db_, Features(q), all, context).ranked, single_all[q].ranked)
          << threads << " threads, query " << q << ", full list";
    }
  }
  EXPECT_EQ(compared, 3 * 44);
  // More threads than keyframes: a 3-keyframe database with 4 threads.
  Database small(FeatureType::kOrb, 32);
  for (int i = 1; i <= 3; ++i) {
    Keyframe k;
    k.id = i;
    small.AddKeyframe(k, Features(i));
  }
  ThreadPool pool(4);
  QueryContext context;
  context.pool = &pool;
  EXPECT_EQ(QueryDatabase(small, Features(42), all, context).ranked,
            QueryDatabase(small, Features(42), all).ranked);
  EXPECT_EQ(QueryDatabase(small, Features(42), all).ranked.size(), 3u);
}

// The voting step: partial results of disjoint partitions (contiguous or
// interleaved, 2 to 5 parts), each computed with ForPartition() options on
// just its keyframes, merge into exactly the whole database's answer.
TEST_F(QueryTest, MergedPartitionsEqualTheWholeDatabase) {
  int compared = 0;
  for (const bool verify : {true, false})
    for (const double weight : {0.0, 10.0}) {
      QueryOptions options;
      options.whole_image_weight = weight;
      options.verify.enabled = verify;
      options.verify.num_candidates = 6;
      options.top_k = 4;
      for (int q : {41, 46, 52, 63, 70, 81}) {
        const QueryResult whole = QueryDatabase(*db_, Features(q), options);
        for (const PartitionScheme scheme :
             {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
          for (int parts = 2; parts <= 5; ++parts) {
            std::vector<QueryResult> partial;
            for (int p = 0; p < parts; ++p) {
              std::vector<uint32_t> among;
              for (uint32_t i = 0; i < db_->size(); ++i) {
                if (InPartition(i, db_->size(), p, parts, scheme)) among.push_back(i);
              }
              QueryContext context;
              context.among = &among;
              partial.push_back(QueryDatabase(*db_, Features(q), options.ForPartition(), context));
              EXPECT_EQ(partial.back().num_keyframes, among.size());
            }
            const QueryResult merged = MergeQueryResults(partial, options);
            EXPECT_EQ(merged.ranked, whole.ranked)
                << "query " << q << ", " << parts << " parts, verify " << verify;
            EXPECT_EQ(merged.matched, whole.matched);
            EXPECT_EQ(merged.num_keyframes, 40u);
            EXPECT_EQ(merged.num_examined, 40u);
            ++compared;
          }
        }
      }
    }
  EXPECT_EQ(compared, 2 * 2 * 6 * 2 * 4);
}

// The whole-image channel: each ranked keyframe carries its similarity and
// its standardisation over every keyframe of the database (their mean and
// deviation), and its score adds weight x max(0, z - floor); a featureless
// query is still ranked by it; features without a descriptor (from
// elsewhere) leave it out; a descriptor of the wrong size is refused.
TEST_F(QueryTest, TheWholeImageChannelScoresByItsRule) {
  QueryOptions options;
  options.whole_image_weight = 10.0;
  options.whole_image_floor = 0.5;
  const QueryResult r = QueryDatabase(*db_, Features(42), options);
  ASSERT_FALSE(r.ranked.empty());
  const cv::Mat& q = Features(42).whole_image;
  ASSERT_EQ(q.cols, db_->whole_image_dims());
  std::vector<double> all;
  for (size_t i = 0; i < db_->size(); ++i)
    all.push_back(WholeImageSimilarity(q.ptr<int8_t>(), db_->WholeImage(i), db_->whole_image_dims()));
  double mean = 0, var = 0;
  for (const double v : all) mean += v / all.size();
  for (const double v : all) var += (v - mean) * (v - mean) / all.size();
  ASSERT_GT(var, 0.0);
  bool some_bonus = false;
  for (const RankedKeyframe& k : r.ranked) {
    ASSERT_TRUE(k.whole_image.has_value());
    ASSERT_TRUE(k.whole_image_z.has_value());
    const double s = all[static_cast<size_t>(k.keyframe_id - 1)];
    EXPECT_NEAR(*k.whole_image, s, 1e-5);
    EXPECT_NEAR(*k.whole_image_z, (s - mean) / std::sqrt(var), 1e-4);
    EXPECT_DOUBLE_EQ(k.score, k.num_inliers + 10.0 * std::max(0.0, *k.whole_image_z - 0.5));
    some_bonus = some_bonus || *k.whole_image_z > 0.5;
  }
  EXPECT_TRUE(some_bonus);  // the rule is exercised, not only its floor
  // Weight 0 and no whole-image candidates: no similarity is computed.
  QueryOptions off;
  off.whole_image_weight = 0.0;
  off.whole_image_candidates = 0;
  for (const RankedKeyframe& k : QueryDatabase(*db_, Features(42), off).ranked) {
    EXPECT_FALSE(k.whole_image.has_value());
    EXPECT_FALSE(k.whole_image_z.has_value());
  }
  // No features at all, only the thumbnail: ranked by it.
  FeatureSet thumb = Features(42);
  thumb.keypoints.clear();
  thumb.descriptors = cv::Mat(0, 32, CV_8U);
  const QueryResult by_thumb = QueryDatabase(*db_, thumb, options);
  ASSERT_FALSE(by_thumb.ranked.empty());
  for (size_t i = 1; i < by_thumb.ranked.size(); ++i)
    EXPECT_GE(*by_thumb.ranked[i - 1].whole_image, *by_thumb.ranked[i].whole_image);
  for (const RankedKeyframe& k : by_thumb.ranked) EXPECT_GT(*k.whole_image_z, 0.5);
  FeatureSet bare = Features(42);
  bare.whole_image = cv::Mat();
  for (const RankedKeyframe& k : QueryDatabase(*db_, bare, options).ranked)
    EXPECT_FALSE(k.whole_image.has_value());
  FeatureSet wrong = Features(42);
  wrong.whole_image = cv::Mat(1, 7, CV_8S, cv::Scalar(1));
  EXPECT_THROW(QueryDatabase(*db_, wrong, options), InvalidArgument);
  wrong.whole_image = Features(42).whole_image.clone();
  wrong.whole_image.at<int8_t>(0, 3) = -128;
  EXPECT_THROW(QueryDatabase(*db_, wrong, options), InvalidArgument);
}

// A keyframe in two parts, or verified entries merged with verification off,
// are caller errors.
TEST(MergeQueryResultsTest, RejectsOverlapAndMixedVerification) {
  RankedKeyframe k;
  k.keyframe_id = 3;
  k.num_matches = 10;
  k.num_inliers = 8;
  k.score = 8;
  QueryResult a, b;
  a.ranked = {k};
  b.ranked = {k};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        MergeQueryResults({a, b}, QueryOptions());
      },
      "is in two partial results"));
  QueryOptions off;
  off.verify.enabled = false;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { MergeQueryResults({a}, off); }, "is verified"));
  EXPECT_TRUE(MergeQueryResults({}, QueryOptions()).ranked.empty());
  EXPECT_FALSE(MergeQueryResults({}, QueryOptions()).matched);
}

// A restriction examines only the given keyframes (duplicates and order do
// not matter); an index beyond the database is invalid input.
TEST_F(QueryTest, RestrictionExaminesOnlyTheGivenKeyframes) {
  QueryOptions options = Unverified();
  options.top_k = 40;
  const std::vector<uint32_t> among = {30, 2, 7, 2, 19};  // ids 31, 3, 8, 20
  QueryContext context;
  context.among = &among;
  const QueryResult r = QueryDatabase(*db_, Features(42), options, context);
  EXPECT_EQ(r.num_keyframes, 4u);
  EXPECT_EQ(r.num_examined, 4u);
  for (const RankedKeyframe& k : r.ranked) {
    EXPECT_TRUE(k.keyframe_id == 31 || k.keyframe_id == 3 || k.keyframe_id == 8 ||
                k.keyframe_id == 20)
        << k.keyframe_id;
  }
  ASSERT_FALSE(r.ranked.empty());
  EXPECT_EQ(r.ranked[0].keyframe_id, 3);  // the true match among them
  const std::vector<uint32_t> empty;
  context.among = &empty;
  EXPECT_TRUE(QueryDatabase(*db_, Features(42), options, context).ranked.empty());
  const std::vector<uint32_t> bad = {3, 40};
  context.among = &bad;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { QueryDatabase(*db_, Features(42), options, context); }, "out of range"));
}

// Features from outside (another node, the wire) are checked against the
// database before any descriptor is read.
TEST_F(QueryTest, MalformedFeaturesAreRejected) {
  const FeatureSet good = Features(42);
  FeatureSet fewer_keypoints = good;
  fewer_keypoints.keypoints.pop_back();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { QueryDatabase(*db_, fewer_keypoints, QueryOptions()); }, "descriptor rows"));
  FeatureSet narrow = good;
  narrow.descriptors = good.descriptors.colRange(0, 16).clone();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { QueryDatabase(*db_, narrow, QueryOptions()); },
                                          "16 bytes per row"));
  FeatureSet floats = good;
  good.descriptors.convertTo(floats.descriptors, CV_32F);
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { QueryDatabase(*db_, floats, QueryOptions()); }, "CV_8U"));
  FeatureSet strided = good;
  cv::Mat wide(good.descriptors.rows, 64, CV_8U, cv::Scalar(0));
  strided.descriptors = wide.colRange(0, 32);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { QueryDatabase(*db_, strided, QueryOptions()); },
                                          "contiguously"));
  FeatureSet nan = good;
  nan.keypoints[5].pt.x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { QueryDatabase(*db_, nan, QueryOptions()); }, "non-finite"));
  FeatureSet surf = good;
  surf.type = FeatureType::kSurf;
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { QueryDatabase(*db_, surf, QueryOptions()); },
                                  "the query has surf features but the database holds orb"));
}

// Real SURF features against an ORB database.
TEST_F(QueryTest, SurfQueryAgainstOrbDatabaseThrows) {
  ExtractorOptions surf = testing::ModelFreeExtractorOptions();
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 100;
  const FeatureSet features = FeatureExtractor::Create(surf)->Extract(cv::imread(RtabmapImage(42)));
  ASSERT_FALSE(features.empty());
  ThreadPool pool(2);
  QueryContext context;
  context.pool = &pool;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { QueryDatabase(*db_, features, QueryOptions(), context); }, "surf features"));
}

TEST_F(QueryTest, EmptyDatabaseGivesNoMatch) {
  const Database empty(FeatureType::kOrb, 32);
  ThreadPool pool(3);
  QueryContext context;
  context.pool = &pool;
  for (const QueryContext& c : {QueryContext(), context}) {
    const QueryResult result = QueryDatabase(empty, Features(42), QueryOptions(), c);
    EXPECT_FALSE(result.matched);
    EXPECT_TRUE(result.ranked.empty());
    EXPECT_EQ(result.best(), nullptr);
    EXPECT_EQ(result.num_query_features, static_cast<int>(Features(42).size()));
  }
  // A database whose keyframes have no features: nothing to rank either.
  Database featureless(FeatureType::kOrb, 32);
  Keyframe k;
  k.id = 7;
  featureless.AddKeyframe(k, FeatureSet());
  EXPECT_FALSE(QueryDatabase(featureless, Features(42), QueryOptions(), context).matched);
  EXPECT_TRUE(QueryDatabase(*db_, FeatureSet(), QueryOptions()).ranked.empty());
}

TEST_F(QueryTest, TopKIsRespected) {
  QueryOptions options = Unverified();
  options.top_k = 40;
  const std::vector<RankedKeyframe> full = QueryDatabase(*db_, Features(60), options).ranked;
  ASSERT_GE(full.size(), 20u);
  ThreadPool pool(3);
  QueryContext context;
  context.pool = &pool;
  for (int k : {1, 2, 3, 7, 10, 40, 100}) {
    options.top_k = k;
    const size_t want = std::min<size_t>(k, full.size());
    const std::vector<RankedKeyframe> expected(full.begin(), full.begin() + want);
    EXPECT_EQ(QueryDatabase(*db_, Features(60), options).ranked, expected) << "k " << k;
    EXPECT_EQ(QueryDatabase(*db_, Features(60), options, context).ranked, expected) << "k " << k;
  }
}

TEST_F(QueryTest, MinMatchesIsRespected) {
  QueryOptions options = Unverified();
  options.top_k = 40;
  const std::vector<RankedKeyframe> full = QueryDatabase(*db_, Features(45), options).ranked;
  ASSERT_GE(full.size(), 10u);
  for (size_t cut : {size_t{0}, size_t{2}, size_t{5}, size_t{9}}) {
    options.min_matches = full[cut].num_matches;
    std::vector<RankedKeyframe> expected;
    for (const RankedKeyframe& s : full) {
      if (s.num_matches >= options.min_matches) expected.push_back(s);
    }
    ASSERT_GE(expected.size(), cut + 1);
    EXPECT_EQ(QueryDatabase(*db_, Features(45), options).ranked, expected)
        << "min_matches " << options.min_matches;
  }
  options.min_matches = full[0].num_matches + 1;  // above the best
  EXPECT_TRUE(QueryDatabase(*db_, Features(45), options).ranked.empty());
}

// The decide stage: the same ranking, matched or "no match" by min_score.
TEST_F(QueryTest, MinScoreDecidesNoMatch) {
  QueryOptions options;
  const QueryResult r = QueryDatabase(*db_, Features(42), options);
  ASSERT_TRUE(r.matched);
  options.min_score = r.ranked[0].score;
  EXPECT_TRUE(QueryDatabase(*db_, Features(42), options).matched);
  options.min_score = r.ranked[0].score + 1;
  const QueryResult none = QueryDatabase(*db_, Features(42), options);
  EXPECT_FALSE(none.matched);
  EXPECT_EQ(none.best(), nullptr);
  EXPECT_EQ(none.ranked, r.ranked);  // still reported, for the caller to see
}

// QueryResult round-trips through JSON; malformed JSON is a clear error
// naming the field, never a crash or a silent conversion.
TEST_F(QueryTest, ResultJsonRoundTripAndValidation) {
  QueryResult r = QueryDatabase(*db_, Features(42), QueryOptions());
  Pose pose;
  pose.translation = Eigen::Vector3d(1.5, -2, 0.25);
  pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  r.ranked[0].pose = pose;
  r.ranked[0].stored_image = "db/images/000003.png";
  const nlohmann::json j = r;
  EXPECT_EQ(j["best"]["keyframe_id"], r.ranked[0].keyframe_id);
  const QueryResult back = nlohmann::json::parse(j.dump()).get<QueryResult>();
  ASSERT_EQ(back.ranked.size(), r.ranked.size());
  EXPECT_EQ(back.ranked[0].keyframe_id, r.ranked[0].keyframe_id);
  EXPECT_EQ(back.ranked[0].num_inliers, r.ranked[0].num_inliers);
  EXPECT_EQ(back.ranked[0].stored_image, r.ranked[0].stored_image);
  ASSERT_TRUE(back.ranked[0].pose);
  EXPECT_LT((back.ranked[0].pose->translation - pose.translation).norm(), 1e-12);
  EXPECT_EQ(back.matched, r.matched);
  EXPECT_EQ(back.num_examined, r.num_examined);
  EXPECT_EQ(back.times.total_ms, r.times.total_ms);
  ASSERT_TRUE(r.ranked[0].whole_image_z.has_value());  // the default channel's
  EXPECT_EQ(back.ranked[0].whole_image, r.ranked[0].whole_image);
  EXPECT_EQ(back.ranked[0].whole_image_z, r.ranked[0].whole_image_z);
  EXPECT_EQ(back.ranked, r.ranked);
  EXPECT_EQ(nlohmann::json(back), j);

  auto fails = [&](const std::function<void(nlohmann::json&)>& edit, const std::string& part) {
    nlohmann::json bad = j;
    edit(bad);
    return ThrowsWith<InvalidArgument>([&] { bad.get<QueryResult>(); }, part);
  };
  EXPECT_TRUE(fails([](nlohmann::json& b) { b.erase("ranked"); }, "ranked is missing"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["matched"] = 1; }, "matched is not true or false"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["keyframe_id"] = true; },
                    "ranked[0].keyframe_id is not an integer"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["keyframe_id"] = 2147483648LL; },
                    "out of range"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["num_matches"] = 1.5; },
                    "num_matches is not an integer"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["num_inliers"] = 100000; },
                    "exceeds num_matches"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["whole_image"] = nullptr; },
                    "whole_image_z is given without whole_image"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b["ranked"][0]["whole_image_z"] = "high"; },
                    "whole_image_z is not a number"));
  EXPECT_TRUE(fails(
      [](nlohmann::json& b) {
        b["ranked"][0]["pose"]["quaternion_xyzw"] = {0, 0, 0, 0};
      },
      "unit quaternion"));
  EXPECT_TRUE(
      fails([](nlohmann::json& b) { b["times_ms"] = "fast"; }, "times_ms is not a JSON object"));
  EXPECT_TRUE(
      fails([](nlohmann::json& b) { b["ranked"] = nlohmann::json::array(); }, "nothing is ranked"));
  EXPECT_TRUE(fails([](nlohmann::json& b) { b = nlohmann::json::array(); }, "not a JSON object"));
}

// Every option is range-checked (NaN included) with a message naming it.
TEST(QueryOptionsTest, CheckRejectsBadValues) {
  QueryOptions options;
  EXPECT_EQ(options.Check(), "");
  options.top_k = 0;
  EXPECT_EQ(options.Check(), "`top_k` must be in [1, 10000] (got 0)");
  const Database empty(FeatureType::kOrb, 32);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { QueryDatabase(empty, FeatureSet(), options); },
                                          "top_k must be in [1, 10000]"));
  options = QueryOptions();
  options.min_matches = 0;
  EXPECT_NE(options.Check().find("min_matches"), std::string::npos);
  options = QueryOptions();
  options.match.ratio = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(options.Check().find("`ratio`"), std::string::npos);
  options = QueryOptions();
  options.verify.num_candidates = 0;
  EXPECT_NE(options.Check().find("`verify_candidates`"), std::string::npos);
  options = QueryOptions();
  options.min_score = -1;
  EXPECT_NE(options.Check().find("min_score"), std::string::npos);
  options.min_score = std::numeric_limits<double>::infinity();
  EXPECT_NE(options.Check().find("min_score"), std::string::npos);
}

}  // namespace
}  // namespace placedb
