#include "placedb/match/hamming.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace placedb {
namespace {

std::vector<uint8_t> RandomBytes(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> v(n);
  for (auto& b : v) b = static_cast<uint8_t>(rng() & 0xff);
  return v;
}

TEST(HammingTest, KnownDistances) {
  uint8_t a[32] = {0};
  uint8_t b[32] = {0};
  EXPECT_EQ(HammingReference(a, b, 32), 0u);
  b[0] = 0xff;
  b[31] = 0x01;
  EXPECT_EQ(HammingReference(a, b, 32), 9u);
  EXPECT_EQ(Hamming(a, b, 32), 9u);
  EXPECT_EQ(Hamming(a, b, 3), 8u);  // tail bytes handled
}

TEST(HammingTest, EveryKernelEqualsReferenceOnRandomData) {
  for (const int bytes : {32, 16, 8, 61, 64}) {
    for (const int count : {0, 1, 3, 4, 5, 17, 500}) {
      const auto db = RandomBytes(static_cast<size_t>(count) * bytes, 7 + count + bytes);
      const auto queries = RandomBytes(static_cast<size_t>(20) * bytes, 99 + bytes);
      for (int q = 0; q < 20; ++q) {
        const uint8_t* query = queries.data() + q * bytes;
        const TwoNearest ref = TwoNearestHammingReference(query, db.data(), count, bytes);
        for (const auto kernel :
             {HammingKernel::kReference, HammingKernel::kPopcnt, HammingKernel::kAvx2}) {
          if (!HammingKernelAvailable(kernel)) continue;
          const TwoNearest got = TwoNearestHammingWith(kernel, query, db.data(), count, bytes);
          EXPECT_EQ(got.best, ref.best) << "bytes " << bytes << " count " << count;
          EXPECT_EQ(got.second, ref.second);
          EXPECT_EQ(got.best_index, ref.best_index);
        }
        if (count > 0) {
          EXPECT_EQ(Hamming(query, db.data(), bytes), HammingReference(query, db.data(), bytes));
        }
      }
    }
  }
}

TEST(HammingTest, TiesKeepLowerIndexAndEmptyInput) {
  std::vector<uint8_t> db(96, 0);  // three identical descriptors
  const uint8_t query[32] = {1};
  const TwoNearest nn = TwoNearestHamming(query, db.data(), 3, 32);
  EXPECT_EQ(nn.best, 1u);
  EXPECT_EQ(nn.second, 1u);
  EXPECT_EQ(nn.best_index, 0);
  const TwoNearest none = TwoNearestHamming(query, db.data(), 0, 32);
  EXPECT_EQ(none.best_index, -1);
  EXPECT_NE(std::string(HammingKernelName()), "");
}

}  // namespace
}  // namespace placedb
