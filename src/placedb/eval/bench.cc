#include "placedb/eval/bench.h"
#include "placedb/eval/report_json.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/eval/baseline.h"
#include "placedb/eval/evaluate.h"
#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"
#include "placedb/session/storage_view.h"

namespace placedb {

namespace {

std::vector<ScoredKeyframe> AsScored(const QueryResult& r) {
  std::vector<ScoredKeyframe> out;
  for (const RankedKeyframe& k : r.ranked)
    out.push_back({k.keyframe_id, static_cast<double>(k.num_matches)});
  return out;
}

// OpenCV on one thread while the benchmark runs (the baseline on one core,
// as ours), restored afterwards; left alone when it already runs on one.
class OpenCvOnOneThread {
 public:
  OpenCvOnOneThread() : saved_(cv::getNumThreads()) {
    if (saved_ > 1) cv::setNumThreads(1);
  }
  ~OpenCvOnOneThread() {
    if (saved_ > 1) cv::setNumThreads(saved_);
  }

 private:
  int saved_;
};

}  // namespace

BenchReport RunBench(const PlaceDatabase& db, const std::vector<Frame>& frames,
                     const BenchOptions& options, const QueryOptions& query_options) {
  PLACEDB_CHECK_OPTIONS(options);
  PLACEDB_CHECK_OPTIONS(query_options);
  if (db.empty()) PLACEDB_THROW_INVALID("the database is empty: nothing to benchmark");
  const StorageView view(db);
  const Database& database = view.database();
  std::vector<FeatureSet> features;
  double extract_ms = 0;
  for (const Frame& f : SampleFrames(frames, options.num_queries, options.seed)) {
    const cv::Mat image = LoadFrameImage(f);
    if (image.empty()) {
      spdlog::warn("skipped unreadable query image {}", f.image_path);
      continue;
    }
    Timer t;
    features.push_back(db.Extract(image));
    extract_ms += t.ElapsedMs();
  }
  if (features.empty()) PLACEDB_THROW_INVALID("no readable query image to benchmark with");
  const int n = static_cast<int>(features.size());

  // Local matching, as the paper's loop does it: the whole-image channel
  // off (its scan is sequence_bench's and scale_bench's to time).
  QueryOptions match_only = query_options;
  match_only.verify.enabled = false;
  match_only.whole_image_weight = 0.0;
  match_only.whole_image_candidates = 0;
  QueryOptions verified = match_only;
  verified.verify.enabled = true;
  const OpenCvOnOneThread one_opencv_thread;
  BenchReport r;
  r.threads = options.threads == 0 ? ThreadPool::HardwareThreads() : options.threads;
  ThreadPool pool(r.threads);
  QueryContext parallel;
  parallel.pool = &pool;
  r.placedb_ms = r.placedb_mt_ms = r.bfmatcher_ms = r.placedb_verified_ms = 1e300;
  for (int rep = 0; rep < options.repeat; ++rep) {
    std::vector<std::vector<ScoredKeyframe>> ours(n), base(n);
    Timer t;
    for (int i = 0; i < n; ++i)
      ours[i] = AsScored(QueryDatabase(database, features[i], match_only));
    r.placedb_ms = std::min(r.placedb_ms, t.ElapsedMs() / n);
    t.Restart();
    for (int i = 0; i < n; ++i) QueryDatabase(database, features[i], match_only, parallel);
    r.placedb_mt_ms = std::min(r.placedb_mt_ms, t.ElapsedMs() / n);
    t.Restart();
    for (int i = 0; i < n; ++i) base[i] = BfMatcherQuery(database, features[i], match_only);
    r.bfmatcher_ms = std::min(r.bfmatcher_ms, t.ElapsedMs() / n);
    t.Restart();
    for (int i = 0; i < n; ++i) QueryDatabase(database, features[i], verified);
    r.placedb_verified_ms = std::min(r.placedb_verified_ms, t.ElapsedMs() / n);
    if (rep == 0) {
      // BFMatcher knows no Laplacian sign: compare SURF rankings without it.
      QueryOptions same = match_only;
      same.match.use_laplacian_sign = false;
      for (int i = 0; i < n; ++i) {
        const std::vector<ScoredKeyframe> comparable =
            database.feature_type() == FeatureType::kSurf
                ? AsScored(QueryDatabase(database, features[i], same))
                : ours[i];
        r.rankings_that_differ += comparable != base[i];
      }
    }
  }
  r.num_keyframes = database.size();
  r.num_db_descriptors = database.num_features();
  r.feature_type = FeatureTypeName(database.feature_type());
  r.kernel =
      database.feature_type() == FeatureType::kOrb ? HammingKernelName() : L2KernelName();
  r.num_queries = n;
  r.repeat = options.repeat;
  r.extract_ms = extract_ms / n;
  return r;
}

std::string BenchReportJson(const BenchReport& report, int indent) {
  return DumpJson(BenchReportToJson(report), indent);
}

nlohmann::json BenchReportToJson(const BenchReport& r) {
  return {{"num_keyframes", r.num_keyframes},
          {"num_db_descriptors", r.num_db_descriptors},
          {"feature_type", r.feature_type},
          {"distance_kernel", r.kernel},
          {"num_queries", r.num_queries},
          {"repeat", r.repeat},
          {"extract_ms_per_query", r.extract_ms},
          {"placedb_ms_per_query", r.placedb_ms},
          {"placedb_threads", r.threads},
          {"placedb_mt_ms_per_query", r.placedb_mt_ms},
          {"bfmatcher_ms_per_query", r.bfmatcher_ms},
          {"placedb_verified_ms_per_query", r.placedb_verified_ms},
          {"speedup_vs_bfmatcher", r.speedup()},
          {"speedup_mt_vs_bfmatcher", r.speedup_mt()},
          {"rankings_that_differ", r.rankings_that_differ}};
}

std::string FormatBenchReport(const BenchReport& r) {
  std::string out;
  out += fmt::format("{} keyframes, {} {} descriptors, {} queries x {} repeats\n", r.num_keyframes,
                     r.num_db_descriptors, r.feature_type, r.num_queries, r.repeat);
  out += fmt::format("distance kernel              {}\n", r.kernel);
  out += fmt::format("query extraction          {:8.3f} ms/query\n", r.extract_ms);
  out += fmt::format("placedb match, 1 thread   {:8.3f} ms/query\n", r.placedb_ms);
  out += fmt::format("placedb match, {} threads  {:8.3f} ms/query\n", r.threads, r.placedb_mt_ms);
  out += fmt::format("BFMatcher loop (paper)    {:8.3f} ms/query\n", r.bfmatcher_ms);
  out += fmt::format("speed-up vs BFMatcher     {:8.2f}x (1 thread), {:.2f}x ({} threads)\n",
                     r.speedup(), r.speedup_mt(), r.threads);
  out +=
      fmt::format("placedb match + verify    {:8.3f} ms/query (1 thread)\n", r.placedb_verified_ms);
  out +=
      fmt::format("rankings that differ      {:8} of {}\n", r.rankings_that_differ, r.num_queries);
  return out;
}

}  // namespace placedb
