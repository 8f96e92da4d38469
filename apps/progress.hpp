// A progress bar on stderr for long runs: only when stderr is a terminal, only after the run has
// taken about a second, at most ten redraws a second, and never with --quiet (so logs and CI
// output stay clean).
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdio>

namespace fracvi::cli {

class ProgressBar {
 public:
  ProgressBar(std::size_t total, bool enabled)
      : total_(total), enabled_(enabled && isatty(STDERR_FILENO) == 1) {}
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  ~ProgressBar() { finish(); }

  /// Called after step k (cheap: looks at the clock every 256 steps).
  void update(std::size_t k) {
    if (!enabled_ || (k & 255U) != 0) return;
    const auto now = Clock::now();
    const double elapsed = seconds(now - start_);
    if (elapsed < kDelaySeconds || seconds(now - last_draw_) < 0.1) return;
    last_draw_ = now;
    drawn_ = true;
    const double fraction = total_ ? static_cast<double>(k) / static_cast<double>(total_) : 1.0;
    const double rate = static_cast<double>(k) / elapsed;
    const double eta = rate > 0 ? static_cast<double>(total_ - k) / rate : 0.0;
    constexpr int kWidth = 30;
    char bar[kWidth + 1];
    const int filled = static_cast<int>(fraction * kWidth);
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
    bar[kWidth] = '\0';
    std::fprintf(stderr, "\r[%s] %3.0f%%  %zu/%zu steps  %.3g steps/s  ETA %d:%02d ", bar,
                 100.0 * fraction, k, total_, rate, static_cast<int>(eta) / 60,
                 static_cast<int>(eta) % 60);
    std::fflush(stderr);
  }

  /// Clears the bar's line (if one was drawn).
  void finish() {
    if (drawn_) std::fprintf(stderr, "\r%80s\r", "");
    drawn_ = false;
  }

 private:
  using Clock = std::chrono::steady_clock;
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  static constexpr double kDelaySeconds = 1.0;

  std::size_t total_;
  bool enabled_;
  bool drawn_ = false;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_draw_{};
};

}  // namespace fracvi::cli
