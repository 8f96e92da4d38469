// Loop annotations and the x86-64-v3 clones of the hand-vectorised kernels, and the size from which
// the steps' per-element passes are vectorised (internal).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstring>

// GCC does not vectorise loops over several columns of one array given as restrict pointers
// ("no vectype"), but does with the promise that the iterations are independent.
#if defined(__GNUC__) && !defined(__clang__)
#define FRACVI_INDEPENDENT_ITERATIONS _Pragma("GCC ivdep")
#else
#define FRACVI_INDEPENDENT_ITERATIONS
#endif

// The kernels that are most of a large system's step (bench/RESULTS.md) carry an x86-64-v3 clone
// (AVX2 + FMA) that the dynamic loader picks on CPUs that have it (GCC's target_clones: an ifunc
// resolved once at load time, no per-call dispatch); the README's build is portable x86-64 (SSE2,
// no FMA), and other compilers and architectures get the portable loop.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__AVX2__)
#define FRACVI_HOT_KERNEL __attribute__((target_clones("default", "arch=x86-64-v3")))
#else
#define FRACVI_HOT_KERNEL
#endif

namespace fracvi::internal {

// Per-element passes that carry a reduction (a max, a finiteness check) do not vectorise as plain
// loops (GCC keeps a floating-point max or an `&=` of isfinite scalar: ≈ 3 cycles per element at
// d = 1000). From this size on the steps use vectorised passes (Eigen's, or the fused kernels of
// solve/vector_passes.hpp with OpenMP simd reductions); below it one fused plain loop, where an
// Eigen expression's set-up (≈ 30 instructions a pass) or a kernel's call costs more than its
// work. Both forms do the same operations per element.
inline constexpr Eigen::Index kVectorPassesFrom = 32;

/// to_i = from_i, i < n: the library's memcpy from kVectorPassesFrom on (an Eigen copy in the
/// portable build was ≈ 2.5 instructions per element at d = 1000), a plain loop below it (at d = 1
/// a call costs more than the copy). The same values either way; `to == from` is allowed.
inline void copy_elements(const double* from, double* to, Eigen::Index n) {
  if (n < kVectorPassesFrom) {
    for (Eigen::Index i = 0; i < n; ++i) to[i] = from[i];
  } else if (to != from) {
    std::memcpy(to, from, sizeof(double) * static_cast<std::size_t>(n));
  }
}

}  // namespace fracvi::internal
