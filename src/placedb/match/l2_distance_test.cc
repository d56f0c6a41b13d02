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

TEST(L2DistanceTest, TwoNearestEqualsReference) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  for (const int dims : {64, 128, 7, 32}) {
    for (const int count : {0, 1, 2, 5, 300}) {
      std::vector<float> db(static_cast<size_t>(count) * dims), query(dims);
      for (float& v : db) v = dist(rng);
      for (float& v : query) v = dist(rng);
      std::vector<int8_t> signs(count);
      for (auto& s : signs) s = (rng() & 1) ? 1 : -1;
      for (const bool use_signs : {false, true}) {
        const int8_t* sp = use_signs ? signs.data() : nullptr;
        for (const int8_t qs : {int8_t{1}, int8_t{-1}}) {
          const auto ref = TwoNearestL2Reference(query.data(), db.data(), count, dims, sp, qs);
          const auto got = TwoNearestL2(query.data(), db.data(), count, dims, sp, qs);
          ASSERT_EQ(got.best_index, ref.best_index) << dims << " " << count;
          if (ref.best_index < 0) {
            EXPECT_TRUE(std::isinf(got.best));
            continue;
          }
          EXPECT_NEAR(got.best, ref.best, 1e-4f * std::max(1.f, ref.best));
          if (std::isinf(ref.second)) {
            EXPECT_TRUE(std::isinf(got.second));
          } else {
            EXPECT_NEAR(got.second, ref.second, 1e-4f * std::max(1.f, ref.second));
          }
          if (use_signs) {
            EXPECT_EQ(signs[ref.best_index], qs);
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace placedb
