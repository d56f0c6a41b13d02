// A readers-writer lock under which a waiting writer goes before readers
// that arrive after it. std::shared_mutex (glibc's rwlock) lets new readers
// in while a writer waits, so queries run back to back would starve an
// online-mapping thread forever. Here a writer holds the gate while it waits
// for the readers in flight to finish; new readers queue behind it. Works
// with std::shared_lock and std::unique_lock.
#pragma once

#include <mutex>
#include <shared_mutex>

namespace placedb {

class FairSharedMutex {
 public:
  void lock_shared() {
    std::lock_guard<std::mutex> gate(gate_);
    state_.lock_shared();
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
  std::mutex gate_;
  std::shared_mutex state_;
};

}  // namespace placedb
