#include "placedb/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>

namespace placedb {

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = std::clamp(p, 0.0, 100.0) / 100.0 * (values.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(rank));
  const size_t hi = std::min(values.size() - 1, lo + 1);
  return values[lo] + (values[hi] - values[lo]) * (rank - lo);
}

LatencyStats ComputeLatencyStats(const std::vector<double>& values_ms) {
  LatencyStats s;
  if (values_ms.empty()) return s;
  s.mean = std::accumulate(values_ms.begin(), values_ms.end(), 0.0) / values_ms.size();
  s.p50 = Percentile(values_ms, 50);
  s.p99 = Percentile(values_ms, 99);
  s.max = *std::max_element(values_ms.begin(), values_ms.end());
  return s;
}

namespace {
PrPoint PointAt(const std::vector<ScoredAnswer>& answers, int positives, double threshold) {
  PrPoint p;
  p.threshold = threshold;
  int correct = 0;
  for (const ScoredAnswer& a : answers) {
    if (!a.has_answer || a.score < threshold) continue;
    ++p.answered;
    correct += a.correct;
  }
  p.precision = p.answered > 0 ? static_cast<double>(correct) / p.answered : 1.0;
  p.recall = positives > 0 ? static_cast<double>(correct) / positives : 0.0;
  return p;
}
}  // namespace

PrecisionRecall ComputePrecisionRecall(const std::vector<ScoredAnswer>& answers, int positives,
                                       double threshold) {
  PrecisionRecall pr;
  std::vector<double> scores;
  for (const ScoredAnswer& a : answers) {
    if (a.has_answer) scores.push_back(a.score);
  }
  std::sort(scores.begin(), scores.end(), std::greater<double>());
  scores.erase(std::unique(scores.begin(), scores.end()), scores.end());
  double previous_recall = 0.0;
  for (const double s : scores) {
    const PrPoint p = PointAt(answers, positives, s);
    pr.average_precision += (p.recall - previous_recall) * p.precision;
    previous_recall = p.recall;
    if (p.precision >= 1.0)
      pr.recall_at_full_precision = std::max(pr.recall_at_full_precision, p.recall);
    pr.curve.push_back(p);
  }
  pr.at_threshold = PointAt(answers, positives, threshold);
  return pr;
}

}  // namespace placedb
