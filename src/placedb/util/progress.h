// A progress bar for long work (database builds, evaluations) on stderr.
// Draws only when stderr is a terminal and it is enabled; otherwise it stays
// silent so logs and CI output are not flooded with carriage returns.
#pragma once

#include <cstddef>
#include <mutex>
#include <string>

#include "placedb/util/timer.h"

namespace placedb {

class ProgressBar {
 public:
  // `total` units of work; `label` is printed before the bar.
  ProgressBar(std::string label, size_t total, bool enabled = true);
  ~ProgressBar();

  // Adds `n` finished units; thread-safe.
  void Advance(size_t n = 1);
  // Ends the bar with a newline (called by the destructor if needed).
  void Finish();

  // True when a bar would be drawn (enabled and stderr is a terminal).
  bool active() const { return active_; }
  size_t done() const { return done_; }

  // Whether stderr is an interactive terminal.
  static bool StderrIsTerminal();

 private:
  void Draw();

  std::string label_;
  size_t total_;
  size_t done_ = 0;
  bool active_;
  bool finished_ = false;
  int last_permille_ = -1;
  Timer timer_;
  std::mutex mutex_;
};

}  // namespace placedb
