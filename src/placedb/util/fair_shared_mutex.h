// A readers-writer lock under which a waiting writer goes before readers
// that arrive after it. std::shared_mutex (glibc's rwlock) lets new readers
// in while a writer waits, so queries run back to back would starve an
// online-mapping thread forever. Here a writer holds the gate while it waits
// for the readers in flight to finish; new readers queue behind it. Works
// with std::shared_lock and std::unique_lock, and a reader can give up at a
// time point (std::shared_lock's time_point constructor): a query under a
// deadline waits for a writer no longer than its deadline.
#pragma once

#include <chrono>
#include <mutex>
#include <shared_mutex>

namespace placedb {

class FairSharedMutex {
 public:
  void lock_shared() {
    std::lock_guard<std::timed_mutex> gate(gate_);
    state_.lock_shared();
  }
  template <typename Clock, typename Duration>
  bool try_lock_shared_until(const std::chrono::time_point<Clock, Duration>& until) {
    std::unique_lock<std::timed_mutex> gate(gate_, until);
    if (!gate.owns_lock()) return false;
    return state_.try_lock_shared_until(until);
  }
  void unlock_shared() { state_.unlock_shared(); }
  void lock() {
    gate_.lock();
    state_.lock();
  }
  void unlock() {
    state_.unlock();
    gate_.unlock();
  }

 private:
  std::timed_mutex gate_;
  std::shared_timed_mutex state_;
};

}  // namespace placedb
