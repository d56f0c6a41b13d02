// Wall-clock timing with a monotonic clock.
#pragma once

#include <chrono>

namespace placedb {

class Timer {
 public:
  Timer() : start_(Clock::now()) {}
  void Restart() { start_ = Clock::now(); }
  double ElapsedSeconds() const {
    return std::chrono::duration<double>(Clock::now() - start_).count();
  }
  double ElapsedMs() const { return ElapsedSeconds() * 1e3; }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

// A time budget on a running Timer: passed() once `ms` milliseconds have
// elapsed since the timer started. The default (no timer, or ms <= 0) never
// passes.
class Deadline {
 public:
  Deadline() = default;
  Deadline(const Timer& clock, double ms) : clock_(&clock), ms_(ms) {}
  bool enabled() const { return clock_ != nullptr && ms_ > 0.0; }
  bool passed() const { return enabled() && clock_->ElapsedMs() >= ms_; }
  // Whether work expected to take `ms` milliseconds still ends before the
  // deadline (always, without one).
  bool Fits(double ms) const { return !enabled() || clock_->ElapsedMs() + ms < ms_; }

 private:
  const Timer* clock_ = nullptr;
  double ms_ = 0.0;
};

}  // namespace placedb
