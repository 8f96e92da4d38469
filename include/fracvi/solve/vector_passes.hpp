// Fused per-element passes of a large system's step (internal).
//
// A step of a chain runs about twenty O(d) passes besides the history (bench/RESULTS.md): the
// Newton residual, the correction, the new position, each followed by a finiteness check (and the
// correction by its size) that Eigen would make a pass of its own. These kernels make each such
// pair one pass over plain arrays, with the reductions written as OpenMP simd reductions (the
// finiteness sum Σ 0·v_i and the max are exact in any order), and carry an x86-64-v3 clone
// (internal/vectorize.hpp). The default clone does the same operations as the Eigen expressions
// they replace, so the same numbers; the x86-64-v3 clone fuses a·b + c into FMAs, like the history
// kernels' clones.
//
// The kernels are plain loops and call nothing: a call from inside a clone after its 256-bit loop
// can leave the upper halves of the vector registers dirty (GCC 12 put no vzeroupper before such a
// call in the chain potential's kernel), and every SSE instruction after it then runs slow.
#pragma once

#include <Eigen/Core>

namespace fracvi::internal {

/// out_i = a_i + b_i; returns whether every out_i is finite.
bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n);

/// out_i = (m_i Δ_i + s g_i) − c_i, the residual of A Δ + s g = c for a diagonal A = diag(m);
/// returns whether every out_i is finite.
bool diagonal_residual(const double* m, const double* increment, double s, const double* g,
                       const double* c, double* out, Eigen::Index n);

/// out_i = (out_i + s g_i) − c_i (out holds A Δ); returns whether every out_i is finite.
bool general_residual(double s, const double* g, const double* c, double* out, Eigen::Index n);

/// What a Newton correction Δ −= δ yields.
struct CorrectionPass {
  double size = 0.0;   // max|δ_i|
  double scale = 0.0;  // max|a_i + Δ_i| (with_next only)
  bool finite = true;  // every updated Δ_i finite
};

/// Δ_i −= δ_i, and with `with_next` the next iterate's midpoint mid_i = a_i + Δ_i/2 and the scale
/// max|a_i + Δ_i| of the convergence test.
CorrectionPass apply_correction_pass(const double* delta, const double* a, double* increment,
                                     double* mid, Eigen::Index n, bool with_next);

/// Whether every v_i is finite (Σ 0·v_i, vectorised).
bool all_finite_pass(const double* v, Eigen::Index n);

}  // namespace fracvi::internal
