#include "placedb/eval/metrics.h"

#include <algorithm>
#include <cmath>
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

}  // namespace placedb
