// SIGINT, SIGTERM and SIGHUP during `fracvi run` (issue 14): the handler only records the signal
// in a sig_atomic_t (the one thing a handler may safely do); the integrator polls it before every
// step (IntegratorOptions::interrupt), stops there with status `interrupted`, and the command
// writes everything computed so far and exits 130, as for a numerical failure. The previous
// handlers are restored when the guard goes out of scope.
#pragma once

#include <csignal>

namespace fracvi::cli {

class InterruptGuard {
 public:
  InterruptGuard() {
    received_ = 0;
    struct sigaction action {};
    action.sa_handler = [](int signal) { received_ = signal; };
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;  // system calls in progress (file writes) go on
    for (int i = 0; i < kSignals; ++i) sigaction(kHandled[i], &action, &previous_[i]);
  }
  ~InterruptGuard() {
    for (int i = 0; i < kSignals; ++i) sigaction(kHandled[i], &previous_[i], nullptr);
  }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  /// The signal received since the guard was made, or 0. Stays set (the hook must latch).
  static int received() { return received_; }

 private:
  static constexpr int kSignals = 3;
  static constexpr int kHandled[kSignals] = {SIGINT, SIGTERM, SIGHUP};
  static inline volatile std::sig_atomic_t received_ = 0;
  struct sigaction previous_[kSignals] {};
};

}  // namespace fracvi::cli
