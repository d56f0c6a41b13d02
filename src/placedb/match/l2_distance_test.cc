#include "placedb/match/l2_distance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace placedb {
namespace {

TEST(L2DistanceTest, KernelMatchesReferenceOnRandomData) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  std::printf("L2Squared kernel: %s\n", L2SquaredKernelName());
  for (int n : {1, 2, 3, 4, 7, 8, 9, 15, 16, 17, 31, 33, 63, 64, 65, 100, 127, 128, 129, 1000}) {
    for (int trial = 0; trial < 50; ++trial) {
      // +1 so that unaligned starts are exercised too.
      std::vector<float> a(n + 1), b(n + 1);
      for (float& v : a) v = dist(rng);
      for (float& v : b) v = dist(rng);
      const int off = trial % 2;
      const float ref = L2SquaredReference(a.data() + off, b.data() + off, n);
      const float fast = L2Squared(a.data() + off, b.data() + off, n);
      ASSERT_NEAR(fast, ref, 1e-5f * std::max(1.f, ref)) << "n=" << n << " trial=" << trial;
    }
  }
}

TEST(L2DistanceTest, KnownValues) {
  const float a[3] = {1.f, 2.f, 3.f};
  const float b[3] = {4.f, 6.f, 3.f};
  EXPECT_FLOAT_EQ(L2SquaredReference(a, b, 3), 25.f);
  EXPECT_FLOAT_EQ(L2Squared(a, b, 3), 25.f);
  EXPECT_FLOAT_EQ(L2Squared(a, a, 3), 0.f);
  EXPECT_FLOAT_EQ(L2Squared(a, b, 0), 0.f);
  EXPECT_FLOAT_EQ(L2SquaredReference(a, b, 0), 0.f);
}

TEST(L2DistanceTest, IdenticalVectorsGiveZeroForAllSizes) {
  std::vector<float> a(300);
  for (size_t i = 0; i < a.size(); ++i) a[i] = static_cast<float>(i) * 0.37f - 20.f;
  for (int n = 0; n <= 300; ++n) EXPECT_EQ(L2Squared(a.data(), a.data(), n), 0.f) << n;
}

}  // namespace
}  // namespace placedb
