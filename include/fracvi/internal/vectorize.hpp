// Loop annotations for the hand-vectorised kernels of the memory layer, and vectorised reductions
// for the per-element passes of the steps (internal).
#pragma once

#include <Eigen/Core>
#include <cmath>

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
// d = 1000). From this size on the steps write them as Eigen's vectorised passes with these
// reductions; below it as one fused plain loop, where an Eigen expression's set-up (≈ 30
// instructions a pass) costs more than its work. Both forms do the same operations per element.
inline constexpr Eigen::Index kVectorPassesFrom = 32;

/// max|v_i| of an expression, evaluated lazily (max_abs(a + b) allocates nothing). Eigen's fast max
/// may drop a NaN: test finiteness with all_finite().
template <class Derived>
double max_abs(const Eigen::MatrixBase<Derived>& v) {
  return v.size() == 0 ? 0.0 : v.cwiseAbs().maxCoeff();
}

/// Whether every v_i is finite, in one vectorised pass: Σ 0·v_i is ±0 when every v_i is finite and
/// NaN otherwise (0·∞ = NaN), exactly, in any order. (Eigen's allFinite() is a scalar loop, and
/// maxCoeff<PropagateNaN> measured 2–3× the time of max_abs and all_finite together.)
template <class Derived>
bool all_finite(const Eigen::MatrixBase<Derived>& v) {
  return std::isfinite((v.array() * 0.0).sum());
}

}  // namespace fracvi::internal
