// Loop annotations, the x86-64-v3 clones and x86-64-v4 variants of the hand-vectorised kernels, and
// the size from which the steps' per-element passes are vectorised (internal).
#pragma once

#include <Eigen/Core>
#include <atomic>
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

// A kernel whose loop invariants do not fit AVX2's 16 vector registers (the block history's four
// recursions hold 4(2s + 1) coefficients) can carry a second variant for CPUs with AVX-512
// (x86-64-v4): the same 256-bit operations with 32 registers (EVEX encoding; no 512-bit
// instruction, so no lower clock than the AVX2 clone's), chosen by the caller where
// wide_registers() holds. target_clones cannot limit the width, hence the caller's choice.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__AVX512F__)
#define FRACVI_WIDE_REGISTERS_KERNEL \
  __attribute__((target("arch=x86-64-v4,prefer-vector-width=256")))
#define FRACVI_HAS_WIDE_REGISTERS_KERNEL 1
#else
#define FRACVI_WIDE_REGISTERS_KERNEL FRACVI_HOT_KERNEL
#define FRACVI_HAS_WIDE_REGISTERS_KERNEL 0
#endif

namespace fracvi::internal {

/// Whether this build and CPU can run the FRACVI_WIDE_REGISTERS_KERNEL variants (x86-64-v4).
inline bool wide_registers_available() {
#if FRACVI_HAS_WIDE_REGISTERS_KERNEL
  static const bool has = __builtin_cpu_supports("x86-64-v4") != 0;
  return has;
#else
  return false;
#endif
}

/// Tests turn the wide variants off to run the AVX2 kernels on a CPU that has both.
inline std::atomic<bool> wide_registers_allowed{true};

/// Whether the FRACVI_WIDE_REGISTERS_KERNEL variants run here: available and allowed. (Without
/// them the variants are the hot kernels themselves.)
inline bool wide_registers() {
  return wide_registers_available() && wide_registers_allowed.load(std::memory_order_relaxed);
}

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
