// A progress bar on stderr for long runs: only when stderr is a terminal, only after the run has
// taken about a second, at most ten redraws a second, and never with --quiet (so logs and CI
// output stay clean).
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <string>

namespace fracvi::cli {

class ProgressBar {
 public:
  ProgressBar(std::size_t total, bool enabled)
      : total_(total), enabled_(enabled && isatty(STDERR_FILENO) == 1) {}
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  ~ProgressBar() { finish(); }

  /// Whether it draws at all (a terminal, not --quiet).
  [[nodiscard]] bool enabled() const { return enabled_; }

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
    std::fprintf(stderr, "\r%s  %zu/%zu steps  %.3g steps/s  ETA %d:%02d ",
                 bar_text(fraction).c_str(), k, total_, rate, static_cast<int>(eta) / 60,
                 static_cast<int>(eta) % 60);
    std::fflush(stderr);
  }

  /// "[#####.....]  50%"
  static std::string bar_text(double fraction) {
    constexpr int kWidth = 30;
    std::string bar = "[";
    const int filled = static_cast<int>(fraction * kWidth);
    for (int i = 0; i < kWidth; ++i) bar += i < filled ? '#' : '.';
    char percent[8];
    std::snprintf(percent, sizeof percent, "] %3.0f%%", 100.0 * fraction);
    return bar + percent;
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

/// The progress of a sweep on stderr: cases done / total, failures, time left. Same rules as
/// ProgressBar (a terminal, not --quiet, after a second, at most ten redraws a second).
class CaseProgress {
 public:
  CaseProgress(std::size_t total, bool enabled)
      : total_(total), enabled_(enabled && isatty(STDERR_FILENO) == 1) {}
  CaseProgress(const CaseProgress&) = delete;
  CaseProgress& operator=(const CaseProgress&) = delete;
  ~CaseProgress() {
    if (drawn_) std::fprintf(stderr, "\r%100s\r", "");
  }

  /// Called as each case finishes; `failures` so far.
  void add(std::size_t failures) {
    ++done_;
    if (!enabled_) return;
    const auto now = Clock::now();
    const double elapsed = seconds(now - start_);
    if (elapsed < 1.0 || (seconds(now - last_draw_) < 0.1 && done_ < total_)) return;
    last_draw_ = now;
    drawn_ = true;
    const double fraction = total_ ? static_cast<double>(done_) / static_cast<double>(total_) : 1.0;
    const double eta = elapsed / static_cast<double>(done_) * static_cast<double>(total_ - done_);
    std::fprintf(stderr, "\r%s  %zu/%zu cases  %zu failed  %.3g cases/s  ETA %d:%02d ",
                 ProgressBar::bar_text(fraction).c_str(), done_, total_, failures,
                 static_cast<double>(done_) / elapsed, static_cast<int>(eta) / 60,
                 static_cast<int>(eta) % 60);
    std::fflush(stderr);
  }

 private:
  using Clock = std::chrono::steady_clock;
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

  std::size_t total_, done_ = 0;
  bool enabled_;
  bool drawn_ = false;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_draw_{};
};

}  // namespace fracvi::cli
