// The checks that run beside a run on threads of their own (internal): the mirror run
// (integrator.cpp's AlongsideMirror) and the error estimate's companion runs
// (ConcurrentErrorEstimate). They lower their own scheduling priority, so that the run they check
// keeps a core.
//
// Why: on two cores the run, the mirror run and the companions are three threads that share the
// cores equally under Linux's scheduler, so the run — the longest of the three, and the one the
// user waits for — gets two thirds of a core while all three run. Measured on
// examples/viscoelastic_caputo.toml with 10^7 steps (bench/RESULTS.md): the run alone 1.6 s of
// CPU, the mirror run 0.9 s, the companions (N/2 and N/4) 0.9 s; all three took 2.1 s at equal
// priority, where the run on one core and the two checks on the other would take 1.8 s. The
// priorities change when each thread runs, never what it computes.
#pragma once

#include <algorithm>
#include <cerrno>
#include <optional>

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace fracvi::internal {

/// How much the checks' threads raise their nice value (lower their priority) above the run's.
/// Under Linux's CFS a nice difference of 10 gives the run ≈ 90 % of a core it shares with a
/// check (weights 1024 and 110), yet a check still progresses on a busy machine (19 would leave it
/// 1.5 %, a real wait for a run whose result waits for its checks).
inline constexpr int kBackgroundNice = 10;

/// The calling thread's nice value (Linux: per thread), or nullopt where it cannot be read.
inline std::optional<int> this_thread_nice() noexcept {
#if defined(__linux__)
  errno = 0;
  const int nice = ::getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)));
  if (errno == 0) return nice;
#endif
  return std::nullopt;
}

/// Lowers the calling thread's priority by kBackgroundNice, to at most nice 19 (Linux: the nice
/// value is per thread, and threads it creates inherit it). Elsewhere, or if the system refuses,
/// nothing changes: a check then runs at the run's priority, as before.
inline void lower_this_thread_priority() noexcept {
#if defined(__linux__)
  if (const std::optional<int> nice = this_thread_nice()) {
    (void)::setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)),
                        std::min(*nice + kBackgroundNice, 19));
  }
#endif
}

}  // namespace fracvi::internal
