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

}  // namespace placedb
