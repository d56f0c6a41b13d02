// A fixed pool of worker threads and a blocking parallel-for on it. One pool
// serves database builds, multi-threaded queries and evaluations.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <queue>
#include <thread>
#include <vector>

namespace placedb {

class ThreadPool {
 public:
  // `num_threads` <= 0 means one per hardware thread.
  explicit ThreadPool(int num_threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()); }

  // Runs fn(i) for i in [0, n) on the pool and waits for all of them. The
  // first exception thrown by any call is rethrown here (the others finish).
  // Safe to call from several threads at once, and from inside a task of this
  // pool (a nested call runs its items inline on the calling worker).
  void ParallelFor(size_t n, const std::function<void(size_t)>& fn);

  // Number of hardware threads (at least 1).
  static int HardwareThreads();

 private:
  void WorkerLoop();

  std::vector<std::thread> workers_;
  std::queue<std::function<void()>> tasks_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
};

// Runs fn(i) for i in [0, n) on `pool` (ParallelFor), or in order on the
// calling thread when there is no pool (the first exception then stops it).
void ForEach(ThreadPool* pool, size_t n, const std::function<void(size_t)>& fn);

// How many threads n items can keep busy: the pool's size, at most n, at
// least 1 (1 without a pool).
size_t UsefulThreads(const ThreadPool* pool, size_t n);

}  // namespace placedb
