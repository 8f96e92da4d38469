// Where a helper thread runs (internal): a fast history's run-ahead thread must not share the
// caller's CPU.
//
// Why: Linux places a woken thread near its waker, and on the 2-vCPU machine the run-ahead thread
// was measured sharing the caller's CPU for whole trials of the thread-count choice
// (TeamChooser) — sched_getcpu() equal on both threads for 256 steps (≈ 5 ms) while the other
// vCPU stayed idle; the β-FPUT chain (d = 1000) then took 14–21 µs per step on the "team"
// against 8.5–10 µs with the threads on two CPUs and 11–12 µs on one thread, so the choice kept
// one thread for the next 0.5 s (2 runs of 8; none of 16 with the move; bench/RESULTS.md).
// A thread cannot ask the scheduler to move it, but it can change its own affinity: without the
// CPU it shares, the kernel migrates it at once; the allowed set is then restored, and the
// scheduler leaves a running thread where it is.
// Nothing is pinned: the user's affinity (taskset, cgroups) is kept, and the kernel stays free to
// move either thread later.
#pragma once

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#endif

namespace fracvi::internal {

/// The CPU the calling thread runs on, or −1 where that is unknown.
inline int current_cpu() noexcept {
#if defined(__linux__)
  return ::sched_getcpu();
#else
  return -1;
#endif
}

/// Moves the calling thread off `cpu` when its allowed set has another CPU: the set without
/// `cpu`, then the set as it was. Returns whether the thread was moved. No allocation.
inline bool move_off_cpu(int cpu) noexcept {
#if defined(__linux__)
  if (cpu < 0 || cpu >= CPU_SETSIZE) return false;
  const pthread_t self = ::pthread_self();
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (::pthread_getaffinity_np(self, sizeof allowed, &allowed) != 0) return false;
  if (!CPU_ISSET(cpu, &allowed) || CPU_COUNT(&allowed) < 2) return false;
  cpu_set_t elsewhere = allowed;
  CPU_CLR(cpu, &elsewhere);
  const bool moved = ::pthread_setaffinity_np(self, sizeof elsewhere, &elsewhere) == 0;
  (void)::pthread_setaffinity_np(self, sizeof allowed, &allowed);
  return moved;
#else
  (void)cpu;
  return false;
#endif
}

}  // namespace fracvi::internal
