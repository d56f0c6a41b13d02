#include "placedb/match/hamming.h"

#include <gtest/gtest.h>

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
void PrintTo(HammingKernel kernel, std::ostream* os) { *os << HammingKernelName(kernel); }

namespace {

constexpr int kCounts[] = {0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 31, 32, 33, 100, 257, 500};

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
  std::memset(b, 0xff, sizeof(b));
  EXPECT_EQ(Hamming(a, b, 32), 256u);
  EXPECT_EQ(HammingReference(a, b, 32), 256u);
}

TEST(HammingTest, ReferenceTwoNearestTiesAndEmptyInput) {
  std::vector<uint8_t> db(96, 0);  // three identical descriptors
  const uint8_t query[32] = {1};
  const TwoNearest nn = TwoNearestHamming(query, db.data(), 3, 32);
  EXPECT_EQ(nn.best, 1u);
  EXPECT_EQ(nn.second, 1u);
  EXPECT_EQ(nn.best_index, 0);
  const TwoNearest none = TwoNearestHamming(query, db.data(), 0, 32);
  EXPECT_EQ(none.best_index, -1);
  EXPECT_EQ(none.best, UINT32_MAX);
  EXPECT_EQ(none.second, UINT32_MAX);
  const TwoNearest one = TwoNearestHamming(query, db.data(), 1, 32);
  EXPECT_EQ(one.best_index, 0);
  EXPECT_EQ(one.best, 1u);
  EXPECT_EQ(one.second, UINT32_MAX);
  EXPECT_NE(std::string(HammingKernelName()), "");
}

// ---------------------------------------------------------------------------
// Every kernel against the reference. Kernels this CPU cannot run are
// skipped (only those).
class HammingKernelTest : public ::testing::TestWithParam<HammingKernel> {
 protected:
  void SetUp() override {
    if (!HammingKernelAvailable(GetParam())) {
      GTEST_SKIP() << HammingKernelName(GetParam()) << " is not available on this CPU";
    }
  }
  TwoNearest Run(const uint8_t* query, const uint8_t* db, int count, int bytes) const {
    return TwoNearestHammingWith(GetParam(), query, db, count, bytes);
  }
  // Same result as the reference, with a readable message.
  void ExpectSame(const uint8_t* query, const uint8_t* db, int count, int bytes,
                  const std::string& what) const {
    const TwoNearest ref = TwoNearestHammingReference(query, db, count, bytes);
    const TwoNearest got = Run(query, db, count, bytes);
    EXPECT_EQ(got.best, ref.best) << what << " bytes " << bytes << " count " << count;
    EXPECT_EQ(got.second, ref.second) << what << " bytes " << bytes << " count " << count;
    EXPECT_EQ(got.best_index, ref.best_index) << what << " bytes " << bytes << " count " << count;
  }
};

TEST_P(HammingKernelTest, EqualsReferenceOnRandomData) {
  for (const int bytes : {32, 16, 8, 61, 64}) {
    for (const int count : kCounts) {
      // One spare byte so that unaligned rows are exercised too.
      const auto db = RandomBytes(static_cast<size_t>(count) * bytes + 1, 7 + count + bytes);
      const auto queries = RandomBytes(static_cast<size_t>(10) * bytes, 99 + bytes);
      for (int q = 0; q < 10; ++q) {
        const uint8_t* query = queries.data() + q * bytes;
        ExpectSame(query, db.data() + (q % 2), count, bytes, "random");
      }
    }
  }
}

// Rows drawn from a few distinct descriptors: many equal distances, so the
// tie rule (lower index; second == best on a tie at the minimum) decides.
TEST_P(HammingKernelTest, EqualsReferenceWithManyTies) {
  for (const int pool_size : {1, 2, 3, 5}) {
    const auto pool = RandomBytes(static_cast<size_t>(pool_size) * 32, 1000 + pool_size);
    std::mt19937 rng(pool_size);
    for (const int count : kCounts) {
      std::vector<uint8_t> db(static_cast<size_t>(count) * 32);
      for (int j = 0; j < count; ++j) {
        std::memcpy(db.data() + j * 32, pool.data() + (rng() % pool_size) * 32, 32);
      }
      for (int p = 0; p < pool_size; ++p) {
        ExpectSame(pool.data() + p * 32, db.data(), count, 32, "pool query");
      }
      const auto other = RandomBytes(32, 5000 + count);
      ExpectSame(other.data(), db.data(), count, 32, "other query");
    }
  }
  // Sparse bits: distances in a tiny range, lots of equal values.
  std::mt19937 rng(77);
  for (const int count : kCounts) {
    std::vector<uint8_t> db(static_cast<size_t>(count) * 32, 0);
    for (int j = 0; j < count; ++j) {
      const int bit = static_cast<int>(rng() % 256);
      db[j * 32 + bit / 8] = static_cast<uint8_t>(1 << (bit % 8));
      if (rng() % 3 == 0) db[j * 32 + (rng() % 32)] |= 0x80;
    }
    const uint8_t zero[32] = {0};
    ExpectSame(zero, db.data(), count, 32, "sparse");
  }
}

TEST_P(HammingKernelTest, AllEqualRows) {
  const auto row = RandomBytes(32, 3);
  const auto query = RandomBytes(32, 4);
  const uint32_t d = HammingReference(query.data(), row.data(), 32);
  for (const int count : kCounts) {
    std::vector<uint8_t> db(static_cast<size_t>(count) * 32);
    for (int j = 0; j < count; ++j) std::memcpy(db.data() + j * 32, row.data(), 32);
    const TwoNearest got = Run(query.data(), db.data(), count, 32);
    if (count == 0) {
      EXPECT_EQ(got.best_index, -1);
      EXPECT_EQ(got.best, UINT32_MAX);
      EXPECT_EQ(got.second, UINT32_MAX);
      continue;
    }
    EXPECT_EQ(got.best_index, 0) << count;
    EXPECT_EQ(got.best, d) << count;
    EXPECT_EQ(got.second, count >= 2 ? d : UINT32_MAX) << count;
    // The query itself as every row: distance 0 everywhere.
    std::vector<uint8_t> same(static_cast<size_t>(count) * 32);
    for (int j = 0; j < count; ++j) std::memcpy(same.data() + j * 32, query.data(), 32);
    const TwoNearest zero = Run(query.data(), same.data(), count, 32);
    EXPECT_EQ(zero.best_index, 0);
    EXPECT_EQ(zero.best, 0u);
    EXPECT_EQ(zero.second, count >= 2 ? 0u : UINT32_MAX);
  }
}

// Two rows tie at the minimum at every pair of positions (same or different
// vector lanes, in the tail or not): the lower one wins, second == best.
TEST_P(HammingKernelTest, TieAtMinimumAnywhere) {
  const int count = 37;
  uint8_t query[32] = {0};
  std::vector<uint8_t> db(static_cast<size_t>(count) * 32, 0xff);  // distance 256
  for (int i = 0; i < count; ++i) {
    for (int k = i + 1; k < count; ++k) {
      std::vector<uint8_t> rows = db;
      rows[i * 32 + 5] = 0x0f;  // distance 252 at i and k
      rows[k * 32 + 5] = 0xf0;
      const TwoNearest got = Run(query, rows.data(), count, 32);
      ASSERT_EQ(got.best_index, i) << i << " " << k;
      ASSERT_EQ(got.best, 252u);
      ASSERT_EQ(got.second, 252u);
      // A strictly better row later still wins.
      rows[k * 32 + 6] = 0x00;
      const TwoNearest later = Run(query, rows.data(), count, 32);
      ASSERT_EQ(later.best_index, k) << i << " " << k;
      ASSERT_EQ(later.best, 244u);
      ASSERT_EQ(later.second, 252u);
    }
  }
}

// More rows than one pass of a kernel handles at a time (the AVX-512 kernel
// works in chunks of 65536 rows): ties and minima across chunk borders.
TEST_P(HammingKernelTest, LargeCounts) {
  const int count = 2 * 65536 + 100;
  std::vector<uint8_t> db = RandomBytes(static_cast<size_t>(count) * 32, 41);
  const auto query = RandomBytes(32, 42);
  const auto near = [&](int index, int flips) {
    std::memcpy(db.data() + static_cast<size_t>(index) * 32, query.data(), 32);
    for (int f = 0; f < flips; ++f) db[static_cast<size_t>(index) * 32 + f] ^= 1;
  };
  ExpectSame(query.data(), db.data(), count, 32, "random");
  near(65537, 1);
  near(131100, 1);  // tie in the next chunk: the first one wins
  ExpectSame(query.data(), db.data(), count, 32, "tie across chunks");
  const TwoNearest tie = Run(query.data(), db.data(), count, 32);
  EXPECT_EQ(tie.best_index, 65537);
  EXPECT_EQ(tie.second, 1u);
  near(5, 2);
  near(65535, 1);  // last row of the first chunk ties with 65537
  ExpectSame(query.data(), db.data(), count, 32, "tie at the border");
  EXPECT_EQ(Run(query.data(), db.data(), count, 32).best_index, 65535);
  near(131071, 0);  // exact match late
  ExpectSame(query.data(), db.data(), count, 32, "late best");
  EXPECT_EQ(Run(query.data(), db.data(), count, 32).best_index, 131071);
  EXPECT_EQ(Run(query.data(), db.data(), count, 32).second, 1u);
}

#if defined(__linux__)
// Rows that end right before an unreadable page: no kernel reads past the
// last row.
TEST_P(HammingKernelTest, DoesNotReadPastTheLastRow) {
  const size_t page = static_cast<size_t>(sysconf(_SC_PAGESIZE));
  void* mem = mmap(nullptr, 2 * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(mem, MAP_FAILED);
  uint8_t* base = static_cast<uint8_t*>(mem);
  ASSERT_EQ(mprotect(base + page, page, PROT_NONE), 0);
  const auto fill = RandomBytes(page, 11);
  std::memcpy(base, fill.data(), page);
  const auto query = RandomBytes(64, 12);
  for (const int bytes : {32, 61}) {
    for (const int count : {1, 2, 3, 7, 9, 15, 17, 31, 33, 100}) {
      if (static_cast<size_t>(count) * bytes > page) continue;
      const uint8_t* db = base + page - static_cast<size_t>(count) * bytes;
      ExpectSame(query.data(), db, count, bytes, "page end");
    }
  }
  munmap(mem, 2 * page);
}
#endif

// The batch and both-directions forms give, row by row, what the
// one-query form gives: random rows and rows with many ties, every count
// class (masked steps below 32 rows, a last partial step, whole steps).
TEST_P(HammingKernelTest, BatchAndBothEqualOneAtATime) {
  const HammingKernel kernel = GetParam();
  const auto same = [](const TwoNearest& a, const TwoNearest& b) {
    return a.best == b.best && a.second == b.second && a.best_index == b.best_index;
  };
  for (const bool ties : {false, true}) {
    for (const int bytes : {32, 61}) {
      for (const int num_queries : {1, 2, 7, 33, 120}) {
        for (const int count : kCounts) {
          std::vector<uint8_t> db = RandomBytes(static_cast<size_t>(count) * bytes, 3 + count);
          std::vector<uint8_t> queries =
              RandomBytes(static_cast<size_t>(num_queries) * bytes, 5 + num_queries);
          if (ties) {  // rows drawn from three descriptors
            const auto pool = RandomBytes(static_cast<size_t>(3) * bytes, 9);
            for (int j = 0; j < count; ++j)
              std::memcpy(db.data() + j * bytes, pool.data() + (j * 7 % 3) * bytes, bytes);
            for (int i = 0; i < num_queries; ++i)
              std::memcpy(queries.data() + i * bytes, pool.data() + (i * 5 % 3) * bytes, bytes);
          }
          const std::string what = std::string(ties ? "ties" : "random") + " bytes " +
                                   std::to_string(bytes) + " queries " +
                                   std::to_string(num_queries) + " count " + std::to_string(count);
          std::vector<TwoNearest> batch(num_queries), forward(num_queries), backward(count);
          TwoNearestHammingBatchWith(kernel, queries.data(), num_queries, db.data(), count, bytes,
                                     batch.data());
          TwoNearestHammingBothWith(kernel, queries.data(), num_queries, db.data(), count, bytes,
                                    forward.data(), backward.data());
          for (int i = 0; i < num_queries; ++i) {
            const TwoNearest ref =
                TwoNearestHammingReference(queries.data() + i * bytes, db.data(), count, bytes);
            EXPECT_TRUE(same(batch[i], ref)) << what << " batch row " << i;
            EXPECT_TRUE(same(forward[i], ref)) << what << " forward row " << i;
          }
          for (int j = 0; j < count; ++j) {
            const TwoNearest ref = TwoNearestHammingReference(db.data() + j * bytes, queries.data(),
                                                              num_queries, bytes);
            EXPECT_TRUE(same(backward[j], ref)) << what << " backward row " << j;
          }
        }
      }
    }
  }
}

// Every entry point returns with the upper vector state clean (see
// testing_util::DirtyUpperState).
TEST_P(HammingKernelTest, LeavesTheUpperVectorStateClean) {
  if (!testing_util::DirtyUpperStateKnown()) GTEST_SKIP() << "XGETBV(1) not supported";
  const auto db = RandomBytes(500 * 32, 21);
  const auto queries = RandomBytes(40 * 32, 22);
  std::vector<TwoNearest> a(40), b(500);
  for (const int count : {5, 12, 20, 32, 100, 500}) {
    volatile uint32_t sink =
        TwoNearestHammingWith(GetParam(), queries.data(), db.data(), count, 32).best;
    (void)sink;
    EXPECT_FALSE(testing_util::DirtyUpperState()) << "one query, count " << count;
    TwoNearestHammingBatchWith(GetParam(), queries.data(), 40, db.data(), count, 32, a.data());
    EXPECT_FALSE(testing_util::DirtyUpperState()) << "batch, count " << count;
    TwoNearestHammingBothWith(GetParam(), queries.data(), 40, db.data(), count, 32, a.data(),
                              b.data());
    EXPECT_FALSE(testing_util::DirtyUpperState()) << "both, count " << count;
  }
}

INSTANTIATE_TEST_SUITE_P(AllKernels, HammingKernelTest,
                         ::testing::Values(HammingKernel::kReference, HammingKernel::kPopcnt,
                                           HammingKernel::kAvx2, HammingKernel::kAvx512),
                         [](const ::testing::TestParamInfo<HammingKernel>& info) {
                           return std::string(HammingKernelName(info.param));
                         });

// ---------------------------------------------------------------------------
// Kernel selection.

// HammingBothIsOnePass answers for the sizes asked about: only the AVX-512
// kernel, 32-byte rows and the kernel's limits take one pass.
TEST(HammingKernelSelectionTest, BothIsOnePassOnlyWithinTheKernelsLimits) {
  const bool avx512 = ActiveHammingKernel() == HammingKernel::kAvx512;
  EXPECT_EQ(HammingBothIsOnePass(500, 400, 32), avx512);
  EXPECT_EQ(HammingBothIsOnePass(1, 65536, 32), avx512);
  EXPECT_FALSE(HammingBothIsOnePass(500, 400, 61));
  EXPECT_FALSE(HammingBothIsOnePass(500, 65537, 32));
  EXPECT_FALSE(HammingBothIsOnePass(65536, 400, 32));
  EXPECT_FALSE(HammingBothIsOnePass(0, 400, 32));
  EXPECT_FALSE(HammingBothIsOnePass(500, 0, 32));
}

TEST(HammingKernelSelectionTest, NamesRoundTrip) {
  for (int k = 0; k < kNumHammingKernels; ++k) {
    const auto kernel = static_cast<HammingKernel>(k);
    const auto parsed = HammingKernelFromName(HammingKernelName(kernel));
    ASSERT_TRUE(parsed.has_value()) << k;
    EXPECT_EQ(*parsed, kernel);
  }
  EXPECT_EQ(HammingKernelFromName("avx512"), HammingKernel::kAvx512);
  EXPECT_EQ(HammingKernelFromName("reference"), HammingKernel::kReference);
  EXPECT_FALSE(HammingKernelFromName("AVX2").has_value());
  EXPECT_FALSE(HammingKernelFromName("sse2").has_value());
  EXPECT_FALSE(HammingKernelFromName("").has_value());
  EXPECT_FALSE(HammingKernelFromName(nullptr).has_value());
}

TEST(HammingKernelSelectionTest, ReferenceAlwaysAvailableAndBestIsAvailable) {
  EXPECT_TRUE(HammingKernelAvailable(HammingKernel::kReference));
  EXPECT_TRUE(HammingKernelAvailable(BestHammingKernel()));
  EXPECT_TRUE(HammingKernelAvailable(ActiveHammingKernel()));
  // Availability is monotonic: the best kernel is the last available one.
  for (int k = static_cast<int>(BestHammingKernel()) + 1; k < kNumHammingKernels; ++k) {
    EXPECT_FALSE(HammingKernelAvailable(static_cast<HammingKernel>(k)));
  }
}

TEST(HammingKernelSelectionTest, ChooseHonoursRequestsTheCpuRuns) {
  const HammingKernel best = BestHammingKernel();
  EXPECT_EQ(ChooseHammingKernel(nullptr), best);
  EXPECT_EQ(ChooseHammingKernel(""), best);
  EXPECT_EQ(ChooseHammingKernel("no-such-kernel"), best);  // logs a warning
  for (int k = 0; k < kNumHammingKernels; ++k) {
    const auto kernel = static_cast<HammingKernel>(k);
    const HammingKernel chosen = ChooseHammingKernel(HammingKernelName(kernel));
    EXPECT_EQ(chosen, HammingKernelAvailable(kernel) ? kernel : best) << HammingKernelName(kernel);
  }
}

// Under `PLACEDB_HAMMING_KERNEL=<name> match_test` the active kernel is the
// requested one (when the CPU runs it).
TEST(HammingKernelSelectionTest, ActiveKernelFollowsEnvironment) {
  const char* env = std::getenv("PLACEDB_HAMMING_KERNEL");
  EXPECT_EQ(ActiveHammingKernel(), ChooseHammingKernel(env));
  EXPECT_STREQ(HammingKernelName(), HammingKernelName(ActiveHammingKernel()));
  std::printf("Hamming kernel: %s (best on this CPU: %s)\n", HammingKernelName(),
              HammingKernelName(BestHammingKernel()));
  // TwoNearestHamming is the active kernel.
  const auto db = RandomBytes(257 * 32, 5);
  const auto query = RandomBytes(32, 6);
  const TwoNearest a = TwoNearestHamming(query.data(), db.data(), 257, 32);
  const TwoNearest b =
      TwoNearestHammingWith(ActiveHammingKernel(), query.data(), db.data(), 257, 32);
  EXPECT_EQ(a.best, b.best);
  EXPECT_EQ(a.second, b.second);
  EXPECT_EQ(a.best_index, b.best_index);
  EXPECT_EQ(Hamming(query.data(), db.data(), 32), HammingReference(query.data(), db.data(), 32));
}

}  // namespace
}  // namespace placedb
