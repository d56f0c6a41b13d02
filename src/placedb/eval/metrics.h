// Summary statistics of evaluation runs.
#pragma once

#include <vector>

namespace placedb {

struct LatencyStats {
  double mean = 0.0;
  double p50 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
};

// Percentile by linear interpolation between closest ranks (numpy's
// default), p in [0, 100]; 0 for an empty list.
double Percentile(std::vector<double> values, double p);

LatencyStats ComputeLatencyStats(const std::vector<double>& values_ms);

// One query's answer for precision-recall: the best keyframe's score (absent
// when nothing was ranked) and whether that keyframe is correct.
struct ScoredAnswer {
  bool has_answer = false;
  double score = 0.0;
  bool correct = false;
};

struct PrPoint {
  double threshold = 0.0;  // answers with score >= threshold are given
  double precision = 1.0;  // correct given / given (1 when none is given)
  double recall = 0.0;     // correct given / positives
  int answered = 0;        // answers given
};

// Precision-recall over the decision threshold. `positives` is the number of
// queries that have a true match in the database (what recall divides by); a
// wrong answer and an answer to a query without any true match both count
// against precision.
struct PrecisionRecall {
  std::vector<PrPoint> curve;             // one point per distinct score, threshold descending
  double average_precision = 0.0;         // area under the curve: sum of (R_i - R_{i-1}) P_i
  double recall_at_full_precision = 0.0;  // the largest recall with precision 1
  PrPoint at_threshold;                   // the operating point at `threshold`
};
PrecisionRecall ComputePrecisionRecall(const std::vector<ScoredAnswer>& answers, int positives,
                                       double threshold);

}  // namespace placedb
