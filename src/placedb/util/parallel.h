// Independent pieces of work run at the same time, each on its own thread:
// for the checks that opening a database makes (its files' checksums and
// their consistency), which read hundreds of megabytes once.
#pragma once

#include <exception>
#include <functional>
#include <system_error>
#include <thread>
#include <vector>

namespace placedb {

// Runs every task, the first on the calling thread and each other on a
// thread of its own, and returns when all have finished. When tasks throw,
// the exception of the first of them in `tasks` order is rethrown (so an
// earlier task's diagnosis, e.g. a checksum mismatch, wins over what a
// later one found in the same damaged bytes).
inline void RunTogether(const std::vector<std::function<void()>>& tasks) {
  std::vector<std::exception_ptr> errors(tasks.size());
  std::vector<std::thread> threads;
  threads.reserve(tasks.size());
  const auto run = [&](size_t i) {
    try {
      tasks[i]();
    } catch (...) {
      errors[i] = std::current_exception();
    }
  };
  for (size_t i = 1; i < tasks.size(); ++i) {
    try {
      threads.emplace_back(run, i);
    } catch (const std::system_error&) {
      run(i);  // no thread to be had: here, after the others
    }
  }
  if (!tasks.empty()) run(0);
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace placedb
