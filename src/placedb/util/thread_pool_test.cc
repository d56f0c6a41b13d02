#include "placedb/util/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

namespace placedb {
namespace {

TEST(ThreadPoolTest, RunsEveryIndexOnce) {
  ThreadPool pool(3);
  std::vector<std::atomic<int>> hits(1000);
  for (int round = 0; round < 3; ++round) {
    pool.ParallelFor(hits.size(), [&](size_t i) { hits[i]++; });
  }
  for (const auto& h : hits) EXPECT_EQ(h.load(), 3);
}

TEST(ThreadPoolTest, RethrowsFirstError) {
  ThreadPool pool(2);
  std::atomic<int> ran{0};
  EXPECT_THROW(pool.ParallelFor(50,
                                [&](size_t i) {
                                  ran++;
                                  if (i == 7) throw std::runtime_error("boom");
                                }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 50);  // the others still ran
  // The pool is still usable.
  std::atomic<int> after{0};
  pool.ParallelFor(10, [&](size_t) { after++; });
  EXPECT_EQ(after.load(), 10);
}

// A task of the pool that calls ParallelFor on the same pool (a server passing
// its pool down to a query) finishes instead of deadlocking, with every inner
// index run once.
TEST(ThreadPoolTest, NestedParallelForDoesNotDeadlock) {
  ThreadPool pool(2);
  std::vector<std::atomic<int>> hits(4 * 100);
  pool.ParallelFor(4, [&](size_t outer) {
    pool.ParallelFor(100, [&](size_t inner) { hits[outer * 100 + inner]++; });
  });
  for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
}

// Two threads outside the pool may share it.
TEST(ThreadPoolTest, ConcurrentCallersShareThePool) {
  ThreadPool pool(2);
  std::atomic<int> total{0};
  std::thread a([&] { pool.ParallelFor(500, [&](size_t) { total++; }); });
  std::thread b([&] { pool.ParallelFor(500, [&](size_t) { total++; }); });
  a.join();
  b.join();
  EXPECT_EQ(total.load(), 1000);
}

}  // namespace
}  // namespace placedb
