// `placedb bench` on small databases of the shipped sample data: the report
// is complete and both methods rank alike.
#include "placedb/eval/bench.h"
#include "placedb/eval/report_json.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "placedb/dataset/image_folder.h"
#include "placedb/builder/builder.h"
#include "placedb/session/place_database.h"
#include "placedb/util/testing.h"
#include "placedb/session/storage_view.h"

namespace placedb {
namespace {

const std::string kRtabmapImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";

// Builds rtabmap images first..last with `options` into `dir` and opens it.
PlaceDatabase BuildRtabmap(int first, int last, BuildOptions options, const std::string& dir) {
  options.progress = false;
  options.threads = 2;
  BuildDatabase(ListImageFolder(kRtabmapImages, first, last), options, dir, "rtabmap");
  return PlaceDatabase::Open(dir);
}

BenchOptions Quick() {
  BenchOptions options;
  options.num_queries = 0;  // all the frames given
  options.repeat = 1;
  options.threads = 2;
  return options;
}

void PrintBench(const char* what, const BenchReport& r) {
  std::printf("%s:\n%s", what, FormatBenchReport(r).c_str());
}

// An ORB database of 10 keyframes and 6 queries: every time is measured, the
// counts are the database's and the queries', the BFMatcher loop ranks every
// query like our match stage, and the JSON and the table carry it all.
TEST(BenchTest, OrbReportIsCompleteAndRankingsAgree) {
  testing_util::TempDir tmp;
  const PlaceDatabase db = BuildRtabmap(1, 10, BuildOptions(), tmp.Path("db"));
  const BenchReport r =
      RunBench(db, ListImageFolder(kRtabmapImages, 41, 46), Quick(), QueryOptions());
  PrintBench("orb", r);
  EXPECT_EQ(r.rankings_that_differ, 0);
  EXPECT_EQ(r.num_queries, 6);
  EXPECT_EQ(r.repeat, 1);
  EXPECT_EQ(r.threads, 2);
  EXPECT_EQ(r.num_keyframes, 10u);
  EXPECT_EQ(r.num_db_descriptors, StorageView(db).database().num_features());
  EXPECT_GT(r.num_db_descriptors, 0u);
  EXPECT_EQ(r.feature_type, "orb");
  EXPECT_FALSE(r.kernel.empty());
  EXPECT_GT(r.extract_ms, 0.0);
  EXPECT_GT(r.placedb_ms, 0.0);
  EXPECT_GT(r.placedb_mt_ms, 0.0);
  EXPECT_GT(r.bfmatcher_ms, 0.0);
  EXPECT_GT(r.placedb_verified_ms, 0.0);
  EXPECT_GT(r.speedup(), 0.0);
  EXPECT_GT(r.speedup_mt(), 0.0);

  const nlohmann::json j = BenchReportToJson(r);
  for (const char* key :
       {"num_keyframes", "num_db_descriptors", "feature_type", "distance_kernel", "num_queries",
        "repeat", "extract_ms_per_query", "placedb_ms_per_query", "placedb_threads",
        "placedb_mt_ms_per_query", "bfmatcher_ms_per_query", "placedb_verified_ms_per_query",
        "speedup_vs_bfmatcher", "speedup_mt_vs_bfmatcher", "rankings_that_differ"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["num_queries"].get<int>(), 6);
  EXPECT_EQ(j["rankings_that_differ"].get<int>(), 0);
  EXPECT_DOUBLE_EQ(j["bfmatcher_ms_per_query"].get<double>(), r.bfmatcher_ms);

  const std::string table = FormatBenchReport(r);
  EXPECT_NE(table.find("BFMatcher"), std::string::npos) << table;
  EXPECT_NE(table.find("rankings that differ"), std::string::npos) << table;

  // num_queries picks that many of the frames.
  BenchOptions three = Quick();
  three.num_queries = 3;
  EXPECT_EQ(
      RunBench(db, ListImageFolder(kRtabmapImages, 41, 46), three, QueryOptions()).num_queries, 3);
}

// Out-of-range options are reported by Check() and refused by RunBench
// before any work.
TEST(BenchTest, CheckRejectsBadOptions) {
  EXPECT_EQ(BenchOptions().Check(), "");
  EXPECT_EQ(Quick().Check(), "");
  BenchOptions repeat = Quick();
  repeat.repeat = 0;
  BenchOptions queries = Quick();
  queries.num_queries = -4;
  BenchOptions negative_threads = Quick();
  negative_threads.threads = -1;
  BenchOptions many_threads = Quick();
  many_threads.threads = 2000;
  const std::vector<std::pair<BenchOptions, std::string>> bad = {{repeat, "repeat"},
                                                                 {queries, "queries"},
                                                                 {negative_threads, "threads"},
                                                                 {many_threads, "threads"}};
  testing_util::TempDir tmp;
  const PlaceDatabase db = BuildRtabmap(1, 2, BuildOptions(), tmp.Path("db"));
  const std::vector<Frame> frames = ListImageFolder(kRtabmapImages, 41, 42);
  for (const auto& [options, field] : bad) {
    const std::string reason = options.Check();
    EXPECT_NE(reason.find(field), std::string::npos) << "'" << reason << "' lacks " << field;
    EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
        [&] { RunBench(db, frames, options, QueryOptions()); }, field));
  }
  // No readable query image is an error too.
  Frame missing;
  missing.id = 1;
  missing.image_path = tmp.Path("no_such_image.jpg");
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { RunBench(db, {missing}, Quick(), QueryOptions()); }, "no readable query image"));
}

// SURF (slower: 5 keyframes, 3 queries): the BFMatcher loop, which knows no
// Laplacian sign, still ranks like our match stage without it.
TEST(BenchTest, SurfRankingsAgree) {
  testing_util::TempDir tmp;
  BuildOptions options;
  options.features.type = FeatureType::kSurf;
  const PlaceDatabase db = BuildRtabmap(1, 5, options, tmp.Path("db"));
  ASSERT_EQ(db.feature_type(), FeatureType::kSurf);
  const BenchReport r =
      RunBench(db, ListImageFolder(kRtabmapImages, 41, 43), Quick(), QueryOptions());
  PrintBench("surf", r);
  EXPECT_EQ(r.rankings_that_differ, 0);
  EXPECT_EQ(r.num_queries, 3);
  EXPECT_EQ(r.num_keyframes, 5u);
  EXPECT_EQ(r.feature_type, "surf");
  EXPECT_GT(r.placedb_ms, 0.0);
  EXPECT_GT(r.bfmatcher_ms, 0.0);
}

}  // namespace
}  // namespace placedb
