#include "placedb/eval/evaluate.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"

namespace placedb {
namespace fs = std::filesystem;

std::string EvalOptions::Check() const {
  if (!all && num_queries < 1) return "num_queries must be >= 1";
  if (threads < 1) return "threads must be >= 1";
  return "";
}

std::vector<Frame> SampleFrames(std::vector<Frame> frames, int n, uint64_t seed) {
  if (n > 0 && static_cast<size_t>(n) < frames.size()) {
    // Our own Fisher-Yates with mt19937_64: std::shuffle's algorithm is not
    // specified, and the same seed must pick the same frames everywhere.
    std::mt19937_64 rng(seed);
    for (size_t i = frames.size() - 1; i > 0; --i) {
      const size_t j = static_cast<size_t>(rng() % (i + 1));
      std::swap(frames[i], frames[j]);
    }
    frames.resize(n);
  }
  std::sort(frames.begin(), frames.end(),
            [](const Frame& a, const Frame& b) { return a.id < b.id; });
  return frames;
}

std::vector<Frame> SelectQueries(const std::vector<Frame>& frames, const GroundTruth& truth,
                                 const EvalOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::vector<Frame> candidates;
  for (const Frame& f : frames) {
    if (truth.HasTruth(f)) candidates.push_back(f);
  }
  return SampleFrames(std::move(candidates), options.all ? 0 : options.num_queries, options.seed);
}

EvalReport Evaluate(const Database& db, const std::string& db_dir,
                    const FeatureExtractor& extractor, const std::vector<Frame>& query_frames,
                    const GroundTruth& truth, const EvalOptions& eval_options,
                    const QueryOptions& query_options) {
  PLACEDB_CHECK_OPTIONS(eval_options);
  PLACEDB_CHECK_OPTIONS(query_options);
  if (db.empty()) PLACEDB_THROW_INVALID("the database is empty: no keyframes to match against");
  const std::vector<Frame> queries = SelectQueries(query_frames, truth, eval_options);
  if (queries.empty()) {
    PLACEDB_THROW_INVALID("no query frame has ground truth (", truth.Describe(),
                          "); nothing to evaluate");
  }
  if (!eval_options.all && static_cast<size_t>(eval_options.num_queries) > queries.size()) {
    spdlog::info("only {} queries have ground truth; evaluating all of them", queries.size());
  }
  EvalReport report;
  report.truth = truth.Describe();
  std::unique_ptr<ThreadPool> pool;
  if (eval_options.threads > 1) pool = std::make_unique<ThreadPool>(eval_options.threads);
  ProgressBar progress("evaluating", queries.size(), eval_options.progress);
  std::vector<double> latencies, match_times;
  for (const Frame& q : queries) {
    QueryRecord rec;
    rec.query_id = q.id;
    rec.image = q.image_path;
    rec.has_true_match_in_db = truth.AnyCorrectIn(q, db);
    const cv::Mat image = cv::imread(q.image_path, cv::IMREAD_COLOR);
    if (image.empty()) {
      spdlog::warn("skipped unreadable query image {} (frame {})", q.image_path, q.id);
      rec.unreadable = true;
      ++report.num_unreadable;
      report.queries.push_back(rec);
      progress.Advance();
      continue;
    }
    const QueryResult result = QueryImage(db, extractor, image, query_options, pool.get());
    rec.ranked = result.ranked;
    rec.num_features = result.num_query_features;
    rec.latency_ms = result.total_ms;
    rec.extract_ms = result.extract_ms;
    rec.match_ms = result.match_ms;
    for (size_t r = 0; r < rec.ranked.size() && r < 5; ++r) {
      const int index = db.IndexOfId(rec.ranked[r].keyframe_id);
      if (index >= 0 && truth.IsCorrect(q, db.keyframe(index))) {
        if (r == 0) rec.correct_at_1 = true;
        rec.correct_at_5 = true;
      }
    }
    ++report.num_queries;
    report.num_correct += rec.correct_at_1;
    report.num_correct_at_5 += rec.correct_at_5;
    report.num_answerable += rec.has_true_match_in_db;
    latencies.push_back(rec.latency_ms);
    match_times.push_back(rec.match_ms);
    report.queries.push_back(std::move(rec));
    progress.Advance();
  }
  progress.Finish();
  if (report.num_queries > 0) {
    report.recall_at_1 = static_cast<double>(report.num_correct) / report.num_queries;
    report.recall_at_5 = static_cast<double>(report.num_correct_at_5) / report.num_queries;
  }
  report.latency_ms = ComputeLatencyStats(latencies);
  report.match_ms = ComputeLatencyStats(match_times);
  report.image_bytes = DirectorySize((fs::path(db_dir) / "images").string());
  report.feature_bytes = FileSize((fs::path(db_dir) / Database::kKeyframesFile).string());
  const nlohmann::json& info = db.info();
  if (info.contains("bytes"))
    report.full_png_bytes = info["bytes"].value("full_frames_png", uint64_t{0});
  if (report.full_png_bytes > 0) {
    report.reduction_vs_full =
        1.0 - static_cast<double>(report.image_bytes) / static_cast<double>(report.full_png_bytes);
  }
  return report;
}

nlohmann::json EvalReportToJson(const EvalReport& r) {
  nlohmann::json j;
  j["num_queries"] = r.num_queries;
  j["num_correct"] = r.num_correct;
  j["num_correct_at_5"] = r.num_correct_at_5;
  j["num_answerable"] = r.num_answerable;
  j["num_unreadable"] = r.num_unreadable;
  j["recall_at_1"] = r.recall_at_1;
  j["recall_at_5"] = r.recall_at_5;
  j["latency_ms"] = {{"mean", r.latency_ms.mean},
                     {"p50", r.latency_ms.p50},
                     {"p99", r.latency_ms.p99},
                     {"max", r.latency_ms.max}};
  j["match_ms"] = {{"mean", r.match_ms.mean}, {"p50", r.match_ms.p50}, {"p99", r.match_ms.p99}};
  j["database_bytes"] = {{"images", r.image_bytes}, {"features", r.feature_bytes}};
  j["full_frames_png_bytes"] = r.full_png_bytes;
  j["reduction_vs_full"] = r.reduction_vs_full;
  j["truth"] = r.truth;
  nlohmann::json queries = nlohmann::json::array();
  for (const QueryRecord& q : r.queries) {
    nlohmann::json e;
    e["query_id"] = q.query_id;
    e["image"] = q.image;
    e["unreadable"] = q.unreadable;
    e["correct_at_1"] = q.correct_at_1;
    e["correct_at_5"] = q.correct_at_5;
    e["has_true_match_in_db"] = q.has_true_match_in_db;
    e["num_features"] = q.num_features;
    e["latency_ms"] = q.latency_ms;
    nlohmann::json ranked = nlohmann::json::array();
    for (const auto& s : q.ranked)
      ranked.push_back({{"keyframe_id", s.keyframe_id}, {"score", s.score}});
    e["ranked"] = ranked;
    queries.push_back(e);
  }
  j["queries"] = queries;
  return j;
}

std::string FormatEvalReport(const EvalReport& r) {
  std::string out;
  out += fmt::format("  queries           {:>10}   (ground truth: {})\n", r.num_queries, r.truth);
  if (r.num_unreadable > 0) out += fmt::format("  unreadable        {:>10}\n", r.num_unreadable);
  out += fmt::format("  answerable        {:>10}   (a true match is in the database)\n",
                     r.num_answerable);
  out += fmt::format("  correct @1        {:>10}\n", r.num_correct);
  out += fmt::format("  recall@1          {:>10.3f}\n", r.recall_at_1);
  out += fmt::format("  recall@5          {:>10.3f}\n", r.recall_at_5);
  out += fmt::format("  latency ms        {:>10.2f}   mean  (p50 {:.2f}, p99 {:.2f})\n",
                     r.latency_ms.mean, r.latency_ms.p50, r.latency_ms.p99);
  out += fmt::format("  matching ms       {:>10.2f}   mean  (of the latency)\n", r.match_ms.mean);
  out += fmt::format("  stored images     {:>10} bytes\n", r.image_bytes);
  out += fmt::format("  features          {:>10} bytes\n", r.feature_bytes);
  out += fmt::format("  whole frames PNG  {:>10} bytes\n", r.full_png_bytes);
  out += fmt::format("  image reduction   {:>9.1f}%   vs storing every frame whole\n",
                     100.0 * r.reduction_vs_full);
  return out;
}

}  // namespace placedb
