// Work over degrees of freedom split across OpenMP threads (internal).
//
// OpenMP because it ships with the compiler (libgomp), needs no package and states the one pattern
// we use — a loop over d split into contiguous blocks, one per thread — in one pragma; TBB or the
// std::execution policies (which need TBB under libstdc++) would add a dependency for the same
// thing. With one thread nothing calls into OpenMP, so small systems pay nothing and stay
// allocation-free; libgomp allocates its thread team once, at the first parallel region.
#pragma once

#include <omp.h>

#include <Eigen/Core>
#include <chrono>

#include "fracvi/internal/float_environment.hpp"
#include "fracvi/internal/team_chooser.hpp"

namespace fracvi::internal {

/// Threads for a loop: 1 when `work` is below `threshold`, else `requested` (0 = OpenMP's default,
/// i.e. all cores or OMP_NUM_THREADS).
inline int team_size(int requested, Eigen::Index work, Eigen::Index threshold) {
  if (work < threshold) return 1;
  return requested > 0 ? requested : omp_get_max_threads();
}

/// Starts OpenMP's thread team for `threads` threads (libgomp allocates it at the first parallel
/// region and reuses it afterwards): call during set-up so that the step loop does not allocate.
inline void start_threads(int threads) {
  if (threads <= 1) return;
  // A body the compiler cannot drop: GCC removes an empty region, and then the team was first
  // created (malloc, pthread_create) by the step loop's first parallel region
  // (tests/integrate/allocation_test.cpp, BandedChainWithMeasuredThreadCount).
  int started = 0;
#pragma omp parallel num_threads(threads)
  {
#pragma omp atomic
    started += 1;
  }
#if defined(__GNUC__)
  asm volatile("" : : "r"(started) : "memory");
#endif
}

/// body(lo, hi) on contiguous blocks covering [0, n), one per thread.
template <class Body>
void for_blocks(Eigen::Index n, int threads, Body&& body) {
  if (threads <= 1) {
    body(Eigen::Index{0}, n);
    return;
  }
  const unsigned flush = flush_bits();  // the team computes as the caller does
#pragma omp parallel num_threads(threads)
  {
    adopt_flush_bits(flush);
    const Eigen::Index parts = omp_get_num_threads(), part = omp_get_thread_num();
    body(n * part / parts, n * (part + 1) / parts);
  }
}

/// Σ over blocks of body(lo, hi) (a double).
template <class Body>
double sum_blocks(Eigen::Index n, int threads, Body&& body) {
  if (threads <= 1) return body(Eigen::Index{0}, n);
  double total = 0.0;
  const unsigned flush = flush_bits();  // the team computes as the caller does
#pragma omp parallel num_threads(threads) reduction(+ : total)
  {
    adopt_flush_bits(flush);
    const Eigen::Index parts = omp_get_num_threads(), part = omp_get_thread_num();
    total += body(n * part / parts, n * (part + 1) / parts);
  }
  return total;
}

/// for_blocks on the thread count `team` chooses (team_chooser.hpp), timing the call for it when
/// it measures.
template <class Body>
void for_blocks(Eigen::Index n, TeamChooser& team, Body&& body) {
  const int threads = team.next();
  if (!team.measuring()) {
    for_blocks(n, threads, body);
    return;
  }
  const auto start = std::chrono::steady_clock::now();
  for_blocks(n, threads, body);
  team.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

}  // namespace fracvi::internal
