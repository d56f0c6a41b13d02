// The paper's experiment, automated: N random validation queries (or all)
// against a database, each judged against ground truth; recall@1/@5,
// precision-recall over the decision threshold, latency per stage, database
// size. Queries run through the session API (PlaceDatabase), as any client's.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "placedb/eval/classic_baselines.h"
#include "placedb/eval/ground_truth.h"
#include "placedb/eval/metrics.h"
#include "placedb/query/sequence.h"
#include "placedb/session/place_database.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct EvalOptions {
  // Number of random queries (the paper's 50). Range [1, 1000000]. Default 50.
  int num_queries = 50;
  // Use every query that has ground truth instead. Default false.
  bool all = false;
  // Seed of the random selection: the same seed picks the same queries for
  // every database. Default 1.
  uint64_t seed = 1;
  // Draw a progress bar on a terminal. Default true.
  bool progress = true;
  // Replay the queries in sequence (id) order, each with the previous
  // query's answer as its prior (QueryOptions::prior.keyframe_id), as a
  // robot moving through the map would: realistic priors for cluster
  // search. Default false (every query without a prior).
  bool sequence = false;
  // With `sequence`: the sequence evidence's options (query/sequence.h).
  SequenceOptions sequence_options;
  // Refuse, instead of warning about, an evaluation that cannot mean
  // anything (EvaluationDoubts). Default false.
  bool strict = false;
  // The classic whole-image methods (eval/classic_baselines.h) computed on
  // the same queries against the keyframes' whole frames (their stored
  // images, or their sources when the stored ones are cropped), reported
  // beside placedb's answers. Default kNone.
  EvalBaseline baseline = EvalBaseline::kNone;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<EvalOptions>& Table();
  std::string Check() const;
};

struct QueryRecord {
  int query_id = 0;
  std::string image;
  QueryResult result;
  bool correct_at_1 = false;          // ranked[0] is a true match (whatever the decision)
  bool correct_at_5 = false;          // one of the first five is
  // 1-based rank of the first true match in the ranked list (top_k long);
  // 0 when none is: recall@k curves.
  int first_correct_rank = 0;
  bool has_true_match_in_db = false;  // whether any keyframe could be right
  // With sequence evidence: whether the frame's own answer (before the
  // sequence) was right at rank 1; `result` is the sequence's answer.
  bool frame_correct_at_1 = false;
  int32_t true_keyframe_id = 0;  // a keyframe that would have been right (0: none)
  bool unreadable = false;
};

struct EvalReport {
  int num_queries = 0;  // evaluated (readable, with ground truth)
  int num_correct = 0;  // correct at rank 1
  int num_correct_at_5 = 0;
  int num_answerable = 0;  // queries with a true match in the database
  int num_unreadable = 0;
  // Of the answerable queries: num_correct / num_answerable (a query whose
  // place is not in the database has nothing to retrieve).
  double recall_at_1 = 0.0;
  double recall_at_5 = 0.0;
  // Over the decision threshold (QueryOptions::min_score); at_threshold is
  // the operating point of the options used.
  PrecisionRecall precision_recall;
  double min_score = 0.0;
  bool verified = false;    // whether the verify stage ran
  LatencyStats latency_ms;  // whole queries, extraction included
  LatencyStats extract_ms;
  LatencyStats match_ms;
  LatencyStats verify_ms;
  // How the queries searched (QueryResult::search): "cluster" (the prior's
  // clusters were enough), "cluster+fallback", "cluster+global", "bow",
  // "exhaustive", with counts.
  std::map<std::string, int> searches;
  double mean_coverage = 0.0;  // of the database, per query
  int num_deadline_reached = 0;
  uint64_t image_bytes = 0;        // stored PNGs
  uint64_t feature_bytes = 0;      // the keyframe file
  uint64_t full_png_bytes = 0;     // every database frame stored whole as PNG
  double reduction_vs_full = 0.0;  // 1 - image_bytes / full_png_bytes
  std::string truth;               // how correctness was decided
  // Why the numbers may mean nothing (EvaluationDoubts), warned about.
  std::vector<std::string> doubts;
  std::vector<QueryRecord> queries;
  // With sequence evidence (EvalOptions::sequence), the numbers above are the
  // sequence's answers and these the same frames' own answers, from the
  // same queries.
  struct SingleFrame {
    int num_correct = 0;
    int num_correct_at_5 = 0;
    double recall_at_1 = 0.0;
    double recall_at_5 = 0.0;
    PrecisionRecall precision_recall;
  };
  std::optional<SingleFrame> single_frame;
  // With EvalOptions::baseline: "hog" and/or "seqslam", judged as the
  // single-frame answers are (their score: eval/classic_baselines.h).
  std::map<std::string, SingleFrame> baselines;
  int num_decided_by_sequence = 0;
  double sequence_min_score = 0.0;
  double sequence_ms_mean = 0.0;  // SequenceMatcher::Feed per frame
};

// A random subset of `frames`: n of them (all when n <= 0 or n >= size),
// chosen by `seed` with a fixed algorithm (the same everywhere), in id order.
std::vector<Frame> SampleFrames(std::vector<Frame> frames, int n, uint64_t seed);

// Chooses the queries: those with ground truth, shuffled by `seed`, the
// first num_queries (all of them with options.all), in id order.
std::vector<Frame> SelectQueries(const std::vector<Frame>& frames, const GroundTruth& truth,
                                 const EvalOptions& options);

// What makes an evaluation of `keyframes` on `queries` mean nothing, found
// before any query runs, one sentence each (empty: nothing to say):
// - query frames that are database frames (the same image file: the same
//   path, or the same file name and bytes): they find themselves;
// - a truth that can judge no keyframe: a match list naming none of the
//   keyframes' ids, pose truth against keyframes without poses;
// - no query has a true match among the keyframes: recall and precision
//   would be 0/0.
std::vector<std::string> EvaluationDoubts(const std::vector<Frame>& queries,
                                          const std::vector<Keyframe>& keyframes,
                                          const GroundTruth& truth);
// Warns about each doubt (one line each, "meaningless evaluation: ..."), or
// with `strict` throws InvalidArgument naming them all.
void ReportEvaluationDoubts(const std::vector<std::string>& doubts, bool strict);

// Runs the evaluation of `db` on `query_frames`. The doubts of
// EvaluationDoubts are warned about (refused with eval_options.strict).
// `check_doubts` false: the caller checked them already (an experiment,
// once for all its settings); the report lists them all the same.
EvalReport Evaluate(const PlaceDatabase& db, const std::vector<Frame>& query_frames,
                    const GroundTruth& truth, const EvalOptions& eval_options,
                    const QueryOptions& query_options, bool check_doubts = true);

// The report as JSON: num_queries, num_correct, recall_at_1, recall_at_5,
// precision_recall {average_precision, recall_at_full_precision,
// at_threshold, curve}, latency_ms {mean, p50, p99, max} and per stage,
// database_bytes {images, features}, reduction_vs_full, and per-query records
// with each query's full QueryResult.
std::string EvalReportJson(const EvalReport& report, int indent = -1);

// A human-readable table of the report.
std::string FormatEvalReport(const EvalReport& report);

}  // namespace placedb
