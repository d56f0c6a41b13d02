#include "placedb/util/thread_pool.h"

#include <algorithm>
#include <atomic>
#include <exception>

namespace placedb {
namespace {
// The pool whose worker runs on this thread (nullptr elsewhere).
thread_local const ThreadPool* current_pool = nullptr;
}  // namespace

int ThreadPool::HardwareThreads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

ThreadPool::ThreadPool(int num_threads) {
  const int n = num_threads <= 0 ? HardwareThreads() : num_threads;
  workers_.reserve(n);
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  for (auto& w : workers_) w.join();
}

void ThreadPool::WorkerLoop() {
  current_pool = this;
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
      if (stop_ && tasks_.empty()) return;
      task = std::move(tasks_.front());
      tasks_.pop();
    }
    task();
  }
}

void ThreadPool::ParallelFor(size_t n, const std::function<void(size_t)>& fn) {
  if (n == 0) return;
  if (n == 1 || workers_.size() <= 1 || current_pool == this) {
    // Inline: one item, one worker, or called from one of this pool's own
    // tasks, where waiting for the other workers could deadlock (they may all
    // be waiting the same way).
    std::exception_ptr error;
    for (size_t i = 0; i < n; ++i) {
      try {
        fn(i);
      } catch (...) {
        if (!error) error = std::current_exception();
      }
    }
    if (error) std::rethrow_exception(error);
    return;
  }
  std::atomic<size_t> next{0};
  std::mutex done_mutex;
  std::condition_variable done_cv;
  size_t running = 0;
  std::exception_ptr error;
  const size_t jobs = std::min(n, workers_.size());
  auto body = [&] {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) break;
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(done_mutex);
        if (!error) error = std::current_exception();
      }
    }
    std::lock_guard<std::mutex> lock(done_mutex);
    if (--running == 0) done_cv.notify_all();
  };
  {
    std::lock_guard<std::mutex> lock(done_mutex);
    running = jobs;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t j = 0; j < jobs; ++j) tasks_.push(body);
  }
  cv_.notify_all();
  std::unique_lock<std::mutex> lock(done_mutex);
  done_cv.wait(lock, [&] { return running == 0; });
  if (error) std::rethrow_exception(error);
}

void ForEach(ThreadPool* pool, size_t n, const std::function<void(size_t)>& fn) {
  if (pool != nullptr) {
    pool->ParallelFor(n, fn);
  } else {
    for (size_t i = 0; i < n; ++i) fn(i);
  }
}

size_t UsefulThreads(const ThreadPool* pool, size_t n) {
  if (pool == nullptr) return 1;
  return std::max<size_t>(1, std::min(n, static_cast<size_t>(pool->size())));
}

}  // namespace placedb
