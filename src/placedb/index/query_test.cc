#include "placedb/index/query.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>

#include "placedb/dataset/image_folder.h"
#include "placedb/index/builder.h"
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
    extractor_ = FeatureExtractor::Create(ExtractorOptions()).release();
    features_ = new std::map<int, FeatureSet>();
    db_ = new Database(FeatureType::kOrb, 32);
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

TEST_F(QueryTest, Image42RanksATrueMatchFirst) {
  ASSERT_EQ(db_->size(), 40u);
  const cv::Mat image = cv::imread(RtabmapImage(42));
  const QueryResult result = QueryImage(*db_, *extractor_, image, QueryOptions());
  ASSERT_TRUE(result.found());
  EXPECT_EQ(result.ranked.size(), 5u);
  const std::set<int> truth = {1, 2, 3, 4};
  EXPECT_EQ(truth.count(result.ranked[0].keyframe_id), 1u)
      << "best " << result.ranked[0].keyframe_id;
  EXPECT_GT(result.num_query_features, 300);
  EXPECT_GE(result.ranked[0].score, 20.0);
  EXPECT_GE(result.total_ms, result.match_ms);
  EXPECT_GE(result.extract_ms, 0.0);
  for (size_t i = 1; i < result.ranked.size(); ++i) {
    EXPECT_TRUE(RanksBefore(result.ranked[i - 1], result.ranked[i]));
  }
}

TEST_F(QueryTest, RecallAtOneOnTheLoop) {
  // Queries 41..84 against keyframes 1..40: the best keyframe is a true
  // match for all but two of them. Image 46 has no ORB features at all (an
  // empty list, not an error); query 80 (99 features) ranks keyframe 36
  // first. Measured: 42 / 44 correct.
  const auto truth = ReadTruth();
  ASSERT_EQ(truth.size(), 44u);
  int correct = 0;
  for (int q = 41; q <= 84; ++q) {
    const QueryResult result = QueryFeatures(*db_, Features(q), QueryOptions());
    if (q == 46) {
      EXPECT_EQ(result.num_query_features, 0);
      EXPECT_FALSE(result.found());
      continue;
    }
    ASSERT_TRUE(result.found()) << "query " << q;
    if (truth.at(q).count(result.ranked[0].keyframe_id)) ++correct;
  }
  EXPECT_GE(correct, 41) << "R@1 = " << correct << "/44";
}

TEST_F(QueryTest, RankingEqualsBruteForceCount) {
  QueryOptions options;
  options.top_k = 40;
  for (int q : {41, 55, 70, 84}) {
    std::vector<int8_t> lap;
    const DescriptorBlock block = MakeDescriptorBlock(Features(q), &lap);
    std::vector<ScoredKeyframe> expected;
    for (size_t i = 0; i < db_->size(); ++i) {
      const int good = CountRatioMatches(block, db_->Descriptors(i), options.match);
      if (good >= 1) expected.push_back({db_->keyframe(i).id, static_cast<double>(good)});
    }
    std::sort(expected.begin(), expected.end(), RanksBefore);
    EXPECT_EQ(QueryFeatures(*db_, Features(q), options).ranked, expected) << "query " << q;
  }
}

TEST_F(QueryTest, MultiThreadedEqualsSingleThreaded) {
  std::map<int, std::vector<ScoredKeyframe>> single_top5, single_all;
  QueryOptions top5;
  QueryOptions all;
  all.top_k = 40;
  for (int q = 41; q <= 84; ++q) {
    single_top5[q] = QueryFeatures(*db_, Features(q), top5).ranked;
    single_all[q] = QueryFeatures(*db_, Features(q), all).ranked;
    ASSERT_EQ(single_top5[q].size(), q == 46 ? 0u : 5u) << q;  // 46: no features
  }
  int compared = 0;
  for (int threads : {2, 3, 4}) {
    ThreadPool pool(threads);
    for (int q = 41; q <= 84; ++q) {
      EXPECT_EQ(QueryFeatures(*db_, Features(q), top5, &pool).ranked, single_top5[q])
          << threads << " threads, query " << q;
      ++compared;
    }
    for (int q = 41; q <= 84; q += 7) {
      EXPECT_EQ(QueryFeatures(*db_, Features(q), all, &pool).ranked, single_all[q])
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
  EXPECT_EQ(QueryFeatures(small, Features(42), all, &pool).ranked,
            QueryFeatures(small, Features(42), all).ranked);
  EXPECT_EQ(QueryFeatures(small, Features(42), all).ranked.size(), 3u);
}

TEST_F(QueryTest, SurfQueryAgainstOrbDatabaseThrows) {
  ExtractorOptions surf;
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 100;
  const auto surf_extractor = FeatureExtractor::Create(surf);
  const cv::Mat image = cv::imread(RtabmapImage(42));
  const FeatureSet features = surf_extractor->Extract(image);
  ASSERT_FALSE(features.empty());
  EXPECT_TRUE(
      ThrowsWith<std::invalid_argument>([&] { QueryFeatures(*db_, features, QueryOptions()); },
                                        "the query has surf features but the database holds orb"));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
      [&] { QueryImage(*db_, *surf_extractor, image, QueryOptions()); },
      "the query has surf features but the database holds orb"));
  ThreadPool pool(2);
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
      [&] { QueryFeatures(*db_, features, QueryOptions(), &pool); }, "surf features"));
}

TEST_F(QueryTest, EmptyDatabaseGivesEmptyList) {
  const Database empty(FeatureType::kOrb, 32);
  QueryResult result = QueryFeatures(empty, Features(42), QueryOptions());
  EXPECT_FALSE(result.found());
  EXPECT_TRUE(result.ranked.empty());
  EXPECT_EQ(result.num_query_features, static_cast<int>(Features(42).size()));
  ThreadPool pool(3);
  result = QueryImage(empty, *extractor_, cv::imread(RtabmapImage(42)), QueryOptions(), &pool);
  EXPECT_FALSE(result.found());
  // A database whose keyframes have no features: nothing to rank either.
  Database featureless(FeatureType::kOrb, 32);
  Keyframe k;
  k.id = 7;
  featureless.AddKeyframe(k, FeatureSet());
  EXPECT_FALSE(QueryFeatures(featureless, Features(42), QueryOptions(), &pool).found());
}

TEST_F(QueryTest, ImageWithoutFeaturesGivesEmptyList) {
  const cv::Mat flat(384, 512, CV_8UC3, cv::Scalar(90, 90, 90));
  QueryResult result = QueryImage(*db_, *extractor_, flat, QueryOptions());
  EXPECT_EQ(result.num_query_features, 0);
  EXPECT_FALSE(result.found());
  cv::Mat tiny(15, 20, CV_8UC3);
  cv::randu(tiny, 0, 255);
  ThreadPool pool(2);
  result = QueryImage(*db_, *extractor_, tiny, QueryOptions(), &pool);
  EXPECT_EQ(result.num_query_features, 0);
  EXPECT_FALSE(result.found());
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
      [&] { QueryImage(*db_, *extractor_, cv::Mat(), QueryOptions()); }, "query image is empty"));
}

TEST_F(QueryTest, TopKIsRespected) {
  QueryOptions options;
  options.top_k = 40;
  const std::vector<ScoredKeyframe> full = QueryFeatures(*db_, Features(60), options).ranked;
  ASSERT_GE(full.size(), 20u);
  ThreadPool pool(3);
  for (int k : {1, 2, 3, 7, 10, 40, 100}) {
    options.top_k = k;
    const size_t want = std::min<size_t>(k, full.size());
    const std::vector<ScoredKeyframe> expected(full.begin(), full.begin() + want);
    EXPECT_EQ(QueryFeatures(*db_, Features(60), options).ranked, expected) << "k " << k;
    EXPECT_EQ(QueryFeatures(*db_, Features(60), options, &pool).ranked, expected) << "k " << k;
  }
}

TEST_F(QueryTest, MinMatchesIsRespected) {
  QueryOptions options;
  options.top_k = 40;
  const std::vector<ScoredKeyframe> full = QueryFeatures(*db_, Features(45), options).ranked;
  ASSERT_GE(full.size(), 10u);
  ThreadPool pool(2);
  for (size_t cut : {size_t{0}, size_t{2}, size_t{5}, size_t{9}}) {
    options.min_matches = static_cast<int>(full[cut].score);
    std::vector<ScoredKeyframe> expected;
    for (const ScoredKeyframe& s : full) {
      if (s.score >= options.min_matches) expected.push_back(s);
    }
    ASSERT_GE(expected.size(), cut + 1);
    const std::vector<ScoredKeyframe> got = QueryFeatures(*db_, Features(45), options).ranked;
    EXPECT_EQ(got, expected) << "min_matches " << options.min_matches;
    EXPECT_EQ(QueryFeatures(*db_, Features(45), options, &pool).ranked, expected);
  }
  options.min_matches = static_cast<int>(full[0].score) + 1;  // above the best
  EXPECT_FALSE(QueryFeatures(*db_, Features(45), options).found());
}

TEST(QueryOptionsTest, CheckRejectsBadValues) {
  QueryOptions options;
  EXPECT_EQ(options.Check(), "");
  options.top_k = 0;
  EXPECT_EQ(options.Check(), "top_k must be >= 1");
  const Database empty(FeatureType::kOrb, 32);
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
      [&] { QueryFeatures(empty, FeatureSet(), options); }, "top_k must be >= 1"));
  options.top_k = 5;
  options.min_matches = 0;
  EXPECT_EQ(options.Check(), "min_matches must be >= 1");
  options.min_matches = 1;
  options.match.ratio = 1.5;
  EXPECT_NE(options.Check().find("ratio"), std::string::npos);
}

// The whole pipeline from disk: a built (chroma crop, 1/4 area) database
// still finds a true match for query 42 with a full, uncropped query frame.
TEST(QueryBuiltDatabaseTest, BuiltDatabaseAnswersQuery42) {
  const fs::path dir =
      fs::temp_directory_path() / ("placedb_index_query_" + std::to_string(::getpid()) + "_built");
  fs::remove_all(dir);
  BuildOptions build;
  build.crop = CropMode::kChroma;
  build.resize = 4;
  build.threads = 2;
  build.progress = false;
  BuildDatabase(ListImageFolder(PLACEDB_DATA_DIR "/rtabmap_loop/images", 1, 20), build,
                (dir / "db").string(), "rtabmap 1..20");
  const Database db = Database::Load((dir / "db").string());
  ASSERT_EQ(db.size(), 20u);
  const auto extractor = FeatureExtractor::Create(ExtractorOptionsFromManifest(db.info()));
  const QueryResult result =
      QueryImage(db, *extractor, cv::imread(RtabmapImage(42)), QueryOptions());
  fs::remove_all(dir);
  ASSERT_TRUE(result.found());
  const std::set<int> truth = {1, 2, 3, 4};
  EXPECT_EQ(truth.count(result.ranked[0].keyframe_id), 1u)
      << "best " << result.ranked[0].keyframe_id;
}

}  // namespace
}  // namespace placedb
