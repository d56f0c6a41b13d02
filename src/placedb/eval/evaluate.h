// The paper's experiment, automated: N random validation queries (or all)
// against a database, each judged against ground truth; recall, latency,
// database size.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "placedb/eval/ground_truth.h"
#include "placedb/eval/metrics.h"
#include "placedb/index/query.h"

namespace placedb {

struct EvalOptions {
  // Number of random queries (the paper's 50). Default 50.
  int num_queries = 50;
  // Use every query that has ground truth instead. Default false.
  bool all = false;
  // Seed of the random selection: the same seed picks the same queries for
  // every database. Default 1.
  uint64_t seed = 1;
  // Threads matching each query (partitions of the database). Default 1.
  int threads = 1;
  // Draw a progress bar on a terminal. Default true.
  bool progress = true;

  std::string Check() const;
};

struct QueryRecord {
  int query_id = 0;
  std::string image;
  std::vector<ScoredKeyframe> ranked;
  bool correct_at_1 = false;
  bool correct_at_5 = false;
  bool has_true_match_in_db = false;  // whether any keyframe could be right
  int num_features = 0;
  double latency_ms = 0.0;  // extraction + matching
  double extract_ms = 0.0;
  double match_ms = 0.0;
  bool unreadable = false;
};

struct EvalReport {
  int num_queries = 0;  // evaluated (readable, with ground truth)
  int num_correct = 0;  // correct at rank 1
  int num_correct_at_5 = 0;
  int num_answerable = 0;  // queries with a true match in the database
  int num_unreadable = 0;
  double recall_at_1 = 0.0;
  double recall_at_5 = 0.0;
  LatencyStats latency_ms;
  LatencyStats match_ms;
  uint64_t image_bytes = 0;        // stored PNGs
  uint64_t feature_bytes = 0;      // keyframes.bin
  uint64_t full_png_bytes = 0;     // every database frame stored whole as PNG
  double reduction_vs_full = 0.0;  // 1 - image_bytes / full_png_bytes
  std::string truth;               // how correctness was decided
  std::vector<QueryRecord> queries;
};

// A random subset of `frames`: n of them (all when n <= 0 or n >= size),
// chosen by `seed` with a fixed algorithm (the same everywhere), in id order.
std::vector<Frame> SampleFrames(std::vector<Frame> frames, int n, uint64_t seed);

// Chooses the queries: those with ground truth, shuffled by `seed`, the
// first num_queries (all of them with options.all), in id order.
std::vector<Frame> SelectQueries(const std::vector<Frame>& frames, const GroundTruth& truth,
                                 const EvalOptions& options);

// Runs the evaluation. `db_dir` is where the database lives (for its sizes).
EvalReport Evaluate(const Database& db, const std::string& db_dir,
                    const FeatureExtractor& extractor, const std::vector<Frame>& query_frames,
                    const GroundTruth& truth, const EvalOptions& eval_options,
                    const QueryOptions& query_options);

// The report as JSON: num_queries, num_correct, recall_at_1, recall_at_5,
// latency_ms {mean, p50, p99, max}, database_bytes {images, features},
// reduction_vs_full, and per-query records.
nlohmann::json EvalReportToJson(const EvalReport& report);

// A human-readable table of the report.
std::string FormatEvalReport(const EvalReport& report);

}  // namespace placedb
