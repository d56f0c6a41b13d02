// End-to-end: the paper's experiment on the shipped sample data.
#include "placedb/eval/evaluate.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/dataset/tum.h"
#include "placedb/eval/baseline.h"
#include "placedb/index/builder.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;

const std::string kRtabmap = PLACEDB_DATA_DIR "/rtabmap_loop";

// A scratch directory; db() is where a test's database goes.
class TempDir : public testing_util::TempDir {
 public:
  std::string db() const { return Path("db"); }
};

EvalReport EvaluateRtabmapSplit(const BuildOptions& options, const std::string& db_dir) {
  const auto train = ListImageFolder(kRtabmap + "/images", 1, 40);
  const auto queries = ListImageFolder(kRtabmap + "/images", 41, 84);
  BuildDatabase(train, options, db_dir, "rtabmap 1..40");
  const Database db = Database::Load(db_dir);
  const auto extractor = FeatureExtractor::Create(ExtractorOptionsFromManifest(db.info()));
  EvalOptions eval;
  eval.all = true;
  eval.progress = false;
  return Evaluate(db, db_dir, *extractor, queries,
                  GroundTruth::FromMatchList(ReadMatchTruth(kRtabmap + "/ground_truth.csv")), eval,
                  QueryOptions());
}

BuildOptions Defaults() {
  BuildOptions options;
  options.progress = false;
  options.threads = 2;
  return options;
}

TEST(EvaluateTest, RtabmapSplitUncroppedRecall) {
  TempDir tmp;
  const EvalReport r = EvaluateRtabmapSplit(Defaults(), tmp.db());
  std::printf("uncropped: recall@1 %.3f recall@5 %.3f (%d/%d), %.2f ms/query\n", r.recall_at_1,
              r.recall_at_5, r.num_correct, r.num_queries, r.latency_ms.mean);
  EXPECT_EQ(r.num_queries, 44);
  EXPECT_EQ(r.num_answerable, 44);
  EXPECT_GE(r.recall_at_1, 0.90);
  EXPECT_GE(r.recall_at_5, r.recall_at_1);
  EXPECT_GT(r.feature_bytes, 0u);
  EXPECT_GT(r.image_bytes, 0u);
  // Uncropped, full size: the stored images are the frames themselves.
  EXPECT_EQ(r.image_bytes, r.full_png_bytes);
  EXPECT_NEAR(r.reduction_vs_full, 0.0, 1e-12);
  const nlohmann::json j = EvalReportToJson(r);
  for (const char* key : {"num_queries", "num_correct", "recall_at_1", "recall_at_5", "latency_ms",
                          "database_bytes", "reduction_vs_full"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  for (const char* key : {"mean", "p50", "p99"}) EXPECT_TRUE(j["latency_ms"].contains(key));
  for (const char* key : {"images", "features"}) EXPECT_TRUE(j["database_bytes"].contains(key));
  EXPECT_EQ(j["queries"].size(), 44u);
}

TEST(EvaluateTest, RtabmapSplitCroppedRecallAndSavings) {
  TempDir tmp;
  BuildOptions options = Defaults();
  options.crop = CropMode::kChroma;
  const EvalReport r = EvaluateRtabmapSplit(options, tmp.db());
  std::printf("cropped: recall@1 %.3f recall@5 %.3f (%d/%d), images %llu of %llu bytes\n",
              r.recall_at_1, r.recall_at_5, r.num_correct, r.num_queries,
              static_cast<unsigned long long>(r.image_bytes),
              static_cast<unsigned long long>(r.full_png_bytes));
  EXPECT_GE(r.recall_at_1, 0.90);
  // The point of cropping: far less image data.
  EXPECT_GT(r.reduction_vs_full, 0.4);
}

TEST(EvaluateTest, RtabmapSplitSurfRecall) {
  TempDir tmp;
  BuildOptions options = Defaults();
  options.features.type = FeatureType::kSurf;
  const EvalReport r = EvaluateRtabmapSplit(options, tmp.db());
  std::printf("surf uncropped: recall@1 %.3f recall@5 %.3f (%d/%d), %.2f ms/query\n", r.recall_at_1,
              r.recall_at_5, r.num_correct, r.num_queries, r.latency_ms.mean);
  const Database db = Database::Load(tmp.db());
  EXPECT_EQ(db.feature_type(), FeatureType::kSurf);
  EXPECT_EQ(db.descriptor_bytes(), 64 * 4);
  EXPECT_GE(r.recall_at_1, 0.90);
}

TEST(EvaluateTest, SameSeedSameQueries) {
  const auto frames = ListImageFolder(kRtabmap + "/images", 41, 84);
  const GroundTruth truth =
      GroundTruth::FromMatchList(ReadMatchTruth(kRtabmap + "/ground_truth.csv"));
  EvalOptions a;
  a.num_queries = 10;
  a.seed = 7;
  const auto qa = SelectQueries(frames, truth, a);
  const auto qb = SelectQueries(frames, truth, a);
  ASSERT_EQ(qa.size(), 10u);
  for (size_t i = 0; i < qa.size(); ++i) EXPECT_EQ(qa[i].id, qb[i].id);
  for (size_t i = 1; i < qa.size(); ++i) EXPECT_LT(qa[i - 1].id, qa[i].id);
  a.seed = 8;
  const auto qc = SelectQueries(frames, truth, a);
  bool differs = false;
  for (size_t i = 0; i < qa.size(); ++i) differs |= qa[i].id != qc[i].id;
  EXPECT_TRUE(differs);
  a.all = true;
  EXPECT_EQ(SelectQueries(frames, truth, a).size(), 44u);
}

TEST(EvaluateTest, TumPosesJudgeMatches) {
  // Database and queries from the same 5 pioneer frames: every query finds
  // itself, whose pose is trivially within the thresholds.
  TempDir tmp;
  const auto frames = ReadTumSequence(PLACEDB_DATA_DIR "/tum_fr2_pioneer_mini");
  ASSERT_EQ(frames.size(), 5u);
  BuildDatabase(frames, Defaults(), tmp.db(), "pioneer");
  const Database db = Database::Load(tmp.db());
  for (const Keyframe& k : db.keyframes()) EXPECT_TRUE(k.pose.has_value());
  const auto extractor = FeatureExtractor::Create(ExtractorOptionsFromManifest(db.info()));
  EvalOptions eval;
  eval.progress = false;
  const EvalReport r = Evaluate(db, tmp.db(), *extractor, frames,
                                GroundTruth::FromPoses(PoseThresholds()), eval, QueryOptions());
  EXPECT_EQ(r.num_queries, 5);
  EXPECT_EQ(r.num_answerable, 5);
  EXPECT_EQ(r.num_correct, 5);

  // A database of frames 1-2 only: frames far from both cannot be answered,
  // and whatever they retrieve is judged wrong by the poses.
  TempDir tmp2;
  BuildDatabase({frames[0], frames[1]}, Defaults(), tmp2.db(), "pioneer 1-2");
  const Database small = Database::Load(tmp2.db());
  const EvalReport r2 = Evaluate(small, tmp2.db(), *extractor, frames,
                                 GroundTruth::FromPoses(PoseThresholds()), eval, QueryOptions());
  EXPECT_EQ(r2.num_queries, 5);
  EXPECT_LT(r2.num_answerable, 5);
  EXPECT_GE(r2.num_answerable, 2);
  EXPECT_LE(r2.num_correct, r2.num_answerable);
  EXPECT_TRUE(r2.queries[0].correct_at_1);
  EXPECT_TRUE(r2.queries[1].correct_at_1);
  for (const QueryRecord& q : r2.queries) {
    if (!q.has_true_match_in_db) {
      EXPECT_FALSE(q.correct_at_1) << q.query_id;
    }
  }
}

TEST(EvaluateTest, BaselineRanksLikeOurs) {
  TempDir tmp;
  const auto train = ListImageFolder(kRtabmap + "/images", 1, 20);
  BuildDatabase(train, Defaults(), tmp.db(), "rtabmap 1..20");
  const Database db = Database::Load(tmp.db());
  const auto extractor = FeatureExtractor::Create(ExtractorOptionsFromManifest(db.info()));
  QueryOptions options;
  for (int id : {41, 45, 50}) {
    const FeatureSet q = extractor->Extract(cv::imread(testing_util::RtabmapImage(id)));
    const auto ours = QueryFeatures(db, q, options).ranked;
    const auto base = BfMatcherQuery(db, q, options);
    ASSERT_FALSE(ours.empty());
    EXPECT_EQ(ours, base) << "query " << id;
  }
}

TEST(EvaluateTest, EmptySelectionAndEmptyDatabaseAreErrors) {
  TempDir tmp;
  const auto train = ListImageFolder(kRtabmap + "/images", 1, 3);
  BuildDatabase(train, Defaults(), tmp.db(), "tiny");
  const Database db = Database::Load(tmp.db());
  const auto extractor = FeatureExtractor::Create(ExtractorOptions());
  EvalOptions eval;
  eval.progress = false;
  // No query has truth in an empty list.
  EXPECT_THROW(Evaluate(db, tmp.db(), *extractor, train, GroundTruth::FromMatchList({}), eval,
                        QueryOptions()),
               std::invalid_argument);
  const Database empty(FeatureType::kOrb, 32);
  EXPECT_THROW(Evaluate(empty, tmp.db(), *extractor, train, GroundTruth::FromMatchList({{1, {1}}}),
                        eval, QueryOptions()),
               std::invalid_argument);
}

}  // namespace
}  // namespace placedb
