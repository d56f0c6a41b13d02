#include "placedb/match/l2_distance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "placedb/util/testing.h"

namespace placedb {

// Readable test parameters ("avx512" rather than "4-byte object").
void PrintTo(L2Kernel kernel, std::ostream* os) { *os << L2KernelName(kernel); }

namespace {

constexpr int kCounts[] = {0, 1, 2, 3, 7, 8, 9, 15, 16, 17, 31, 32, 33, 100, 257};

TEST(L2DistanceTest, KernelMatchesReferenceOnRandomData) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  std::printf("L2 kernel: %s\n", L2KernelName());
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

// ---------------------------------------------------------------------------
// Every kernel against the reference. Kernels this CPU cannot run are
// skipped (only those).
class L2KernelTest : public ::testing::TestWithParam<L2Kernel> {
 protected:
  void SetUp() override {
    if (!L2KernelAvailable(GetParam())) {
      GTEST_SKIP() << L2KernelName(GetParam()) << " is not available on this CPU";
    }
  }
  TwoNearestL2Result Run(const float* query, const float* db, int count, int dims,
                         const int8_t* signs, int8_t qs) const {
    return TwoNearestL2With(GetParam(), query, db, count, dims, signs, qs);
  }
  // Bitwise the same result as the reference: for data whose distances are
  // exact in float (small integers), whatever the summation order.
  void ExpectExact(const float* query, const float* db, int count, int dims, const int8_t* signs,
                   int8_t qs, const std::string& what) const {
    const auto ref = TwoNearestL2Reference(query, db, count, dims, signs, qs);
    const auto got = Run(query, db, count, dims, signs, qs);
    const std::string where = what + " dims " + std::to_string(dims) + " count " +
                              std::to_string(count) + (signs ? " signs" : "");
    EXPECT_EQ(got.best_index, ref.best_index) << where;
    EXPECT_EQ(got.best, ref.best) << where;
    EXPECT_EQ(got.second, ref.second) << where;
  }
};

std::vector<int8_t> RandomSigns(int count, std::mt19937& rng) {
  std::vector<int8_t> signs(count);
  for (auto& s : signs) s = (rng() & 1) ? 1 : -1;
  return signs;
}

// Every entry point returns with the upper vector state clean (see
// testing_util::DirtyUpperState).
TEST_P(L2KernelTest, LeavesTheUpperVectorStateClean) {
  if (!testing_util::DirtyUpperStateKnown()) GTEST_SKIP() << "XGETBV(1) not supported";
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> value(-1.0f, 1.0f);
  for (const int dims : {64, 128, 37}) {
    std::vector<float> db(static_cast<size_t>(dims) * 50), query(dims);
    for (float& v : db) v = value(rng);
    for (float& v : query) v = value(rng);
    const std::vector<int8_t> signs = RandomSigns(50, rng);
    for (const int count : {1, 7, 16, 50}) {
      volatile float sink = L2SquaredWith(GetParam(), query.data(), db.data(), dims);
      EXPECT_FALSE(testing_util::DirtyUpperState()) << "distance, dims " << dims;
      sink = Run(query.data(), db.data(), count, dims, nullptr, 0).best;
      EXPECT_FALSE(testing_util::DirtyUpperState()) << "two nearest, dims " << dims;
      sink = Run(query.data(), db.data(), count, dims, signs.data(), 1).best;
      EXPECT_FALSE(testing_util::DirtyUpperState()) << "two nearest with signs, dims " << dims;
      (void)sink;
    }
  }
}

TEST_P(L2KernelTest, DistanceEqualsReference) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  for (int n = 0; n <= 140; ++n) {
    std::vector<float> a(n + 1), b(n + 1);
    for (float& v : a) v = dist(rng);
    for (float& v : b) v = dist(rng);
    const float ref = L2SquaredReference(a.data() + 1, b.data(), n);
    const float got = L2SquaredWith(GetParam(), a.data() + 1, b.data(), n);
    ASSERT_NEAR(got, ref, 1e-5f * std::max(1.f, ref)) << n;
    EXPECT_EQ(L2SquaredWith(GetParam(), a.data(), a.data(), n), 0.f) << n;
  }
}

TEST_P(L2KernelTest, TwoNearestEqualsReferenceOnRandomData) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  for (const int dims : {64, 128, 7, 16, 32, 65}) {
    for (const int count : kCounts) {
      std::vector<float> db(static_cast<size_t>(count) * dims + 1), query(dims);
      for (float& v : db) v = dist(rng);
      for (float& v : query) v = dist(rng);
      const auto signs = RandomSigns(count, rng);
      for (const bool use_signs : {false, true}) {
        const int8_t* sp = use_signs ? signs.data() : nullptr;
        for (const int8_t qs : {int8_t{1}, int8_t{-1}}) {
          for (const int off : {0, 1}) {  // unaligned rows too
            const float* rows = db.data() + off;
            const auto ref = TwoNearestL2Reference(query.data(), rows, count, dims, sp, qs);
            const auto got = Run(query.data(), rows, count, dims, sp, qs);
            const std::string where = "dims " + std::to_string(dims) + " count " +
                                      std::to_string(count) + (use_signs ? " signs" : "");
            ASSERT_EQ(got.best_index, ref.best_index) << where;
            if (ref.best_index < 0) {
              EXPECT_TRUE(std::isinf(got.best)) << where;
              EXPECT_TRUE(std::isinf(got.second)) << where;
              continue;
            }
            EXPECT_NEAR(got.best, ref.best, 1e-4f * std::max(1.f, ref.best)) << where;
            if (std::isinf(ref.second)) {
              EXPECT_TRUE(std::isinf(got.second)) << where;
            } else {
              EXPECT_NEAR(got.second, ref.second, 1e-4f * std::max(1.f, ref.second)) << where;
            }
          }
        }
      }
    }
  }
}

// Small integer values: every distance is exact in float whatever the
// summation order, so ties are real ties in every kernel. Rows drawn from a
// few distinct vectors, and all-equal rows.
TEST_P(L2KernelTest, TiesOnIntegerData) {
  std::mt19937 rng(23);
  for (const int dims : {64, 128, 7, 32}) {
    for (const int pool_size : {1, 2, 3, 5}) {
      std::vector<float> pool(static_cast<size_t>(pool_size) * dims);
      for (float& v : pool) v = static_cast<float>(static_cast<int>(rng() % 5) - 2);
      for (const int count : kCounts) {
        std::vector<float> db(static_cast<size_t>(count) * dims);
        for (int j = 0; j < count; ++j) {
          const int p = static_cast<int>(rng() % pool_size);
          std::memcpy(db.data() + static_cast<size_t>(j) * dims, pool.data() + p * dims,
                      dims * sizeof(float));
        }
        const auto signs = RandomSigns(count, rng);
        std::vector<float> other(dims);
        for (float& v : other) v = static_cast<float>(static_cast<int>(rng() % 5) - 2);
        for (const int8_t* sp : {static_cast<const int8_t*>(nullptr), signs.data()}) {
          for (const int8_t qs : {int8_t{1}, int8_t{-1}}) {
            for (int p = 0; p < pool_size; ++p) {
              ExpectExact(pool.data() + p * dims, db.data(), count, dims, sp, qs, "pool query");
            }
            ExpectExact(other.data(), db.data(), count, dims, sp, qs, "other query");
          }
        }
      }
    }
  }
}

TEST_P(L2KernelTest, AllEqualRows) {
  for (const int dims : {64, 128, 7}) {
    std::vector<float> row(dims), query(dims);
    for (int i = 0; i < dims; ++i) {
      row[i] = static_cast<float>(i % 3);
      query[i] = static_cast<float>(i % 2);
    }
    const float d = L2SquaredReference(query.data(), row.data(), dims);
    for (const int count : kCounts) {
      std::vector<float> db(static_cast<size_t>(count) * dims);
      for (int j = 0; j < count; ++j) {
        std::memcpy(db.data() + static_cast<size_t>(j) * dims, row.data(), dims * sizeof(float));
      }
      const auto got = Run(query.data(), db.data(), count, dims, nullptr, 0);
      if (count == 0) {
        EXPECT_EQ(got.best_index, -1);
        EXPECT_TRUE(std::isinf(got.best));
        EXPECT_TRUE(std::isinf(got.second));
        continue;
      }
      EXPECT_EQ(got.best_index, 0) << dims << " " << count;
      EXPECT_EQ(got.best, d) << dims << " " << count;
      if (count >= 2) {
        EXPECT_EQ(got.second, d) << dims << " " << count;
      } else {
        EXPECT_TRUE(std::isinf(got.second));
      }
      // Only the last row has the query's sign: it is the only candidate.
      std::vector<int8_t> signs(count, -1);
      signs[count - 1] = 1;
      const auto one = Run(query.data(), db.data(), count, dims, signs.data(), 1);
      EXPECT_EQ(one.best_index, count - 1);
      EXPECT_EQ(one.best, d);
      EXPECT_TRUE(std::isinf(one.second));
      // No row has it: no candidate.
      const auto none = Run(query.data(), db.data(), count, dims, signs.data(), 7);
      EXPECT_EQ(none.best_index, -1);
      EXPECT_TRUE(std::isinf(none.best));
    }
  }
}

// Two rows tie at the minimum at every pair of positions (same or different
// vector lanes, in the tail or not): the lower one wins, second == best.
TEST_P(L2KernelTest, TieAtMinimumAnywhere) {
  const int count = 37;
  for (const int dims : {64, 128}) {
    const std::vector<float> query(dims, 0.f);
    std::vector<float> db(static_cast<size_t>(count) * dims, 3.f);  // 9 * dims
    std::vector<int8_t> signs(count, 1);
    for (int i = 0; i < count; ++i) {
      for (int k = i + 1; k < count; k += 3) {
        std::vector<float> rows = db;
        rows[static_cast<size_t>(i) * dims + 1] = 1.f;  // 9 * dims - 8 at i and k
        rows[static_cast<size_t>(k) * dims + 2] = 1.f;
        for (const int8_t* sp :
             {static_cast<const int8_t*>(nullptr), static_cast<const int8_t*>(signs.data())}) {
          const auto got = Run(query.data(), rows.data(), count, dims, sp, 1);
          ASSERT_EQ(got.best_index, i) << i << " " << k;
          ASSERT_EQ(got.best, 9.f * dims - 8.f);
          ASSERT_EQ(got.second, 9.f * dims - 8.f);
        }
        // A strictly better row later still wins.
        rows[static_cast<size_t>(k) * dims + 3] = 0.f;
        const auto later = Run(query.data(), rows.data(), count, dims, nullptr, 0);
        ASSERT_EQ(later.best_index, k) << i << " " << k;
        ASSERT_EQ(later.best, 9.f * dims - 17.f);
        ASSERT_EQ(later.second, 9.f * dims - 8.f);
      }
    }
  }
}

#if defined(__linux__)
// Rows and signs that end right before an unreadable page: no kernel reads
// past the last row or sign.
TEST_P(L2KernelTest, DoesNotReadPastTheLastRow) {
  // [db: 8 pages][guard][signs: 1 page][guard]
  const size_t page = static_cast<size_t>(sysconf(_SC_PAGESIZE));
  const size_t size = 8 * page;
  void* mem =
      mmap(nullptr, size + 3 * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(mem, MAP_FAILED);
  uint8_t* base = static_cast<uint8_t*>(mem);
  ASSERT_EQ(mprotect(base + size, page, PROT_NONE), 0);
  ASSERT_EQ(mprotect(base + size + 2 * page, page, PROT_NONE), 0);
  std::mt19937 rng(29);
  float* floats = reinterpret_cast<float*>(base);
  for (size_t i = 0; i < size / sizeof(float); ++i) {
    floats[i] = static_cast<float>(static_cast<int>(rng() % 7) - 3);
  }
  int8_t* signs_end = reinterpret_cast<int8_t*>(base + size + 2 * page);
  for (size_t i = 1; i <= page; ++i) signs_end[-static_cast<ptrdiff_t>(i)] = (rng() & 1) ? 1 : -1;
  std::vector<float> query(128);
  for (float& v : query) v = static_cast<float>(static_cast<int>(rng() % 7) - 3);
  for (const int dims : {64, 128, 7}) {
    for (const int count : {1, 2, 3, 7, 9, 15, 17, 31, 33}) {
      const float* db =
          reinterpret_cast<const float*>(base + size) - static_cast<size_t>(count) * dims;
      ExpectExact(query.data(), db, count, dims, nullptr, 0, "page end");
      ExpectExact(query.data(), db, count, dims, signs_end - count, 1, "page end signs");
    }
  }
  munmap(mem, size + 3 * page);
}
#endif

INSTANTIATE_TEST_SUITE_P(AllKernels, L2KernelTest,
                         ::testing::Values(L2Kernel::kReference, L2Kernel::kSse2, L2Kernel::kAvx2,
                                           L2Kernel::kAvx512),
                         [](const ::testing::TestParamInfo<L2Kernel>& info) {
                           return std::string(L2KernelName(info.param));
                         });

// ---------------------------------------------------------------------------
// Kernel selection.

TEST(L2KernelSelectionTest, NamesRoundTrip) {
  for (int k = 0; k < kNumL2Kernels; ++k) {
    const auto kernel = static_cast<L2Kernel>(k);
    const auto parsed = L2KernelFromName(L2KernelName(kernel));
    ASSERT_TRUE(parsed.has_value()) << k;
    EXPECT_EQ(*parsed, kernel);
  }
  EXPECT_EQ(L2KernelFromName("sse2"), L2Kernel::kSse2);
  EXPECT_EQ(L2KernelFromName("avx512"), L2Kernel::kAvx512);
  EXPECT_FALSE(L2KernelFromName("avx2+fma").has_value());
  EXPECT_FALSE(L2KernelFromName("popcnt").has_value());
  EXPECT_FALSE(L2KernelFromName("").has_value());
  EXPECT_FALSE(L2KernelFromName(nullptr).has_value());
}

TEST(L2KernelSelectionTest, ReferenceAlwaysAvailableAndBestIsAvailable) {
  EXPECT_TRUE(L2KernelAvailable(L2Kernel::kReference));
  EXPECT_TRUE(L2KernelAvailable(BestL2Kernel()));
  EXPECT_TRUE(L2KernelAvailable(ActiveL2Kernel()));
  for (int k = static_cast<int>(BestL2Kernel()) + 1; k < kNumL2Kernels; ++k) {
    EXPECT_FALSE(L2KernelAvailable(static_cast<L2Kernel>(k)));
  }
}

TEST(L2KernelSelectionTest, ChooseHonoursRequestsTheCpuRuns) {
  const L2Kernel best = BestL2Kernel();
  EXPECT_EQ(ChooseL2Kernel(nullptr), best);
  EXPECT_EQ(ChooseL2Kernel(""), best);
  EXPECT_EQ(ChooseL2Kernel("no-such-kernel"), best);  // logs a warning
  for (int k = 0; k < kNumL2Kernels; ++k) {
    const auto kernel = static_cast<L2Kernel>(k);
    EXPECT_EQ(ChooseL2Kernel(L2KernelName(kernel)), L2KernelAvailable(kernel) ? kernel : best)
        << L2KernelName(kernel);
  }
}

// Under `PLACEDB_L2_KERNEL=<name> match_test` the active kernel is the
// requested one (when the CPU runs it).
TEST(L2KernelSelectionTest, ActiveKernelFollowsEnvironment) {
  const char* env = std::getenv("PLACEDB_L2_KERNEL");
  EXPECT_EQ(ActiveL2Kernel(), ChooseL2Kernel(env));
  EXPECT_STREQ(L2KernelName(), L2KernelName(ActiveL2Kernel()));
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> dist(-1.f, 1.f);
  std::vector<float> db(100 * 64), query(64);
  for (float& v : db) v = dist(rng);
  for (float& v : query) v = dist(rng);
  const auto a = TwoNearestL2(query.data(), db.data(), 100, 64, nullptr, 0);
  const auto b = TwoNearestL2With(ActiveL2Kernel(), query.data(), db.data(), 100, 64, nullptr, 0);
  EXPECT_EQ(a.best, b.best);
  EXPECT_EQ(a.second, b.second);
  EXPECT_EQ(a.best_index, b.best_index);
  EXPECT_EQ(L2Squared(query.data(), db.data(), 64),
            L2SquaredWith(ActiveL2Kernel(), query.data(), db.data(), 64));
}

}  // namespace
}  // namespace placedb
