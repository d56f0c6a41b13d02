#include "placedb/util/progress.h"

#include <unistd.h>

#include <cstdio>

namespace placedb {

ProgressBar::ProgressBar(std::string label, size_t total, bool enabled)
    : label_(std::move(label)), total_(total), active_(enabled && StderrIsTerminal()) {
  if (active_) Draw();
}

ProgressBar::~ProgressBar() { Finish(); }

bool ProgressBar::StderrIsTerminal() { return isatty(fileno(stderr)) != 0; }

void ProgressBar::Advance(size_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ += n;
  if (active_) Draw();
}

void ProgressBar::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (active_ && !finished_) {
    last_permille_ = -1;
    Draw();
    std::fputc('\n', stderr);
    std::fflush(stderr);
  }
  finished_ = true;
}

void ProgressBar::Draw() {
  const size_t total = total_ == 0 ? 1 : total_;
  const int permille = static_cast<int>(1000.0 * static_cast<double>(done_) / total);
  if (permille == last_permille_) return;
  last_permille_ = permille;
  constexpr int kWidth = 30;
  const int filled = permille * kWidth / 1000;
  std::string bar(filled, '#');
  bar.append(kWidth - filled, '.');
  const double elapsed = timer_.ElapsedSeconds();
  const double eta = done_ > 0 && done_ < total_ ? elapsed * (total_ - done_) / done_ : 0.0;
  std::fprintf(stderr, "\r%s [%s] %zu/%zu (%.0f%%) %.1fs, ETA %.1fs ", label_.c_str(), bar.c_str(),
               done_, total_, permille / 10.0, elapsed, eta);
  std::fflush(stderr);
}

}  // namespace placedb
