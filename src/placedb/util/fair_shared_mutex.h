// A readers-writer lock under which a waiting writer goes before readers
// that arrive after it. std::shared_mutex (glibc's rwlock) lets new readers
// in while a writer waits, so queries run back to back would starve an
// online-mapping thread forever. Here a writer holds the gate while it waits
// for the readers in flight to finish; new readers queue behind it. Works
// with std::shared_lock and std::unique_lock.
//
// - A reader can give up at a time point (std::shared_lock's time_point
//   constructor, try_lock_shared_until): a query under a deadline waits for
//   a writer no longer than its deadline. The wait polls non-blocking tries
//   (yields, then sleeps of 50 us): timed mutexes are not used, because
//   ThreadSanitizer does not see glibc's clock-based locks
//   (pthread_mutex_clocklock) and reports their unlocks as errors.
// - A thread that already holds the lock shared may take it shared again
//   (a View held while calling an accessor): it skips the gate, so it never
//   waits for a writer that waits for it. A shared hold is released on the
//   thread that took it.
#pragma once

#include <algorithm>
#include <chrono>
#include <mutex>
#include <shared_mutex>
#include <thread>
#include <utility>
#include <vector>

namespace placedb {

class FairSharedMutex {
 public:
  void lock_shared() {
    if (HeldHere() == 0) {
      std::lock_guard<std::mutex> gate(gate_);
      state_.lock_shared();
    } else {
      state_.lock_shared();  // glibc's rwlock lets a reader in beside a waiting writer
    }
    ++HeldHere();
  }

  bool try_lock_shared() {
    if (HeldHere() == 0) {
      std::unique_lock<std::mutex> gate(gate_, std::try_to_lock);
      if (!gate.owns_lock() || !state_.try_lock_shared()) return false;
    } else if (!state_.try_lock_shared()) {
      return false;
    }
    ++HeldHere();
    return true;
  }

  template <typename Clock, typename Duration>
  bool try_lock_shared_until(const std::chrono::time_point<Clock, Duration>& until) {
    for (int attempt = 0;; ++attempt) {
      if (try_lock_shared()) return true;
      if (Clock::now() >= until) return false;
      if (attempt < 16) {
        std::this_thread::yield();
      } else {
        std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
    }
  }

  void unlock_shared() {
    state_.unlock_shared();
    --HeldHere();
  }

  void lock() {
    gate_.lock();
    state_.lock();
  }
  void unlock() {
    state_.unlock();
    gate_.unlock();
  }

 private:
  // How many shared holds this thread has on this mutex (an entry per mutex
  // the thread has held; a thread holds few).
  int& HeldHere() {
    thread_local std::vector<std::pair<const FairSharedMutex*, int>> held;
    for (auto& entry : held) {
      if (entry.first == this) return entry.second;
    }
    // Entries that dropped to zero are reused before the list grows.
    for (auto& entry : held) {
      if (entry.second == 0) {
        entry.first = this;
        return entry.second;
      }
    }
    held.emplace_back(this, 0);
    return held.back().second;
  }

  std::mutex gate_;
  std::shared_mutex state_;
};

}  // namespace placedb
