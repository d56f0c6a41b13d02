#include "placedb/eval/metrics.h"

#include <gtest/gtest.h>

namespace placedb {
namespace {

TEST(MetricsTest, PercentilesInterpolateLikeNumpy) {
  // numpy.percentile([1, 2, 3, 4], [50, 99]) = [2.5, 3.97]
  EXPECT_DOUBLE_EQ(Percentile({4, 1, 3, 2}, 50), 2.5);
  EXPECT_NEAR(Percentile({4, 1, 3, 2}, 99), 3.97, 1e-12);
  EXPECT_DOUBLE_EQ(Percentile({7}, 99), 7.0);
  EXPECT_DOUBLE_EQ(Percentile({}, 50), 0.0);
}

TEST(MetricsTest, LatencyStats) {
  const LatencyStats s = ComputeLatencyStats({10, 20, 30, 40, 100});
  EXPECT_DOUBLE_EQ(s.mean, 40.0);
  EXPECT_DOUBLE_EQ(s.p50, 30.0);
  EXPECT_DOUBLE_EQ(s.max, 100.0);
  EXPECT_NEAR(s.p99, 97.6, 1e-9);
}

}  // namespace
}  // namespace placedb
