// Fused per-element passes of a step (internal).
//
// A step of a chain runs about twenty O(d) passes besides the history (bench/RESULTS.md): the
// Newton residual, the correction, the new position, the momenta, x̃, the energy account. Each
// function here is one such pass, fused with the check or the sum that follows it (a finiteness
// check Σ 0·v_i and a max are exact in any order, so they are OpenMP simd reductions):
//
//   - below kVectorPassesFrom elements, the loop is inlined into the caller (at d = 1 a call
//     costs more than its work), compiled like the caller, and not vectorised (kSimd = false):
//     GCC's simd loop keeps a reduction's vector on the stack, and at d = 1 its scalar remainder
//     writes one 8-byte lane that the final 16-byte load then reads — a store the CPU cannot
//     forward, ≈ 12 % of MidpointNewton::solve's samples (perf); the scalar loops took the
//     d = 1 run (examples/viscoelastic_caputo.toml) from 176 to 167 ns per step, the same bits;
//   - from kVectorPassesFrom on, the same loop runs in a kernel with an x86-64-v3 clone
//     (internal/vectorize.hpp, GCC's target_clones).
//
// The default build's operations are those the steps did before these passes existed, so the
// numbers are the same on a CPU without AVX2 (but dot_pass's sum, in the simd reduction's order);
// the x86-64-v3 clones fuse a·b + c into FMAs, like the history kernels' clones, so a large
// system's results differ in the last bits on CPUs with AVX2.
//
// The kernels are plain loops and call nothing: a call from inside a clone after its 256-bit loop
// can leave the upper halves of the vector registers dirty (GCC 12 put no vzeroupper before such a
// call in the chain potential's kernel), and every SSE instruction after it then runs slow.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "fracvi/internal/vectorize.hpp"

namespace fracvi::internal {

/// What a Newton correction Δ −= δ yields.
struct CorrectionPass {
  double size = 0.0;   // max|δ_i|
  double scale = 0.0;  // max|a_i + Δ_i| (with_next only)
  bool finite = true;  // every updated Δ_i finite
};

/// What new_momentum_pass yields.
struct MomentumPass {
  bool finite = true;  // every v_i finite
  double fv = 0.0;     // F·v (with_dots only)
  double fw = 0.0;     // F·M⁻¹F (with_dots only)
  double vp = 0.0;     // v·p, twice the kinetic energy (with_dots only)
};

/// What trapezoid_step_pass yields.
struct TrapezoidPass {
  bool finite_position = true;  // every x_next_i finite
  bool finite_velocity = true;  // every v_i finite
  double work = 0.0;            // G·Δ (with_work only)
};

// The loops, written once: inlined below kVectorPassesFrom as plain loops (kSimd = false), and
// into the kernels' clones as simd loops (kSimd = true). (Every file is compiled with
// -fopenmp-simd, CMakeLists.txt, so the simd pragmas act alike everywhere.) The maxima and the
// finiteness sums are exact in any order, so both forms give the same results; dot and
// weighted_squares would sum in another order, and their callers take Eigen's sums below
// kVectorPassesFrom.
namespace loops {

#define FRACVI_PASS     \
  template <bool kSimd> \
  [[gnu::always_inline]] inline
FRACVI_PASS bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = a[i] + b[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_PASS bool diagonal_residual(const double* m, const double* increment, double s,
                                   const double* g, const double* c, double* out, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = (m[i] * increment[i] + s * g[i]) - c[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_PASS bool general_residual(double s, const double* g, const double* c, double* out,
                                  Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = (out[i] + s * g[i]) - c[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_PASS CorrectionPass apply_correction(const double* delta, const double* a, double* increment,
                                            double* mid, Eigen::Index n, bool with_next) {
  double size = 0.0, scale = 0.0, zero = 0.0;
  if (with_next) {
#pragma omp simd if (simd : kSimd) reduction(max : size, scale) reduction(+ : zero)
    for (Eigen::Index i = 0; i < n; ++i) {
      const double updated = increment[i] - delta[i];
      increment[i] = updated;
      size = std::max(size, std::abs(delta[i]));
      zero += 0.0 * updated;
      scale = std::max(scale, std::abs(a[i] + updated));
      mid[i] = a[i] + 0.5 * updated;
    }
  } else {
#pragma omp simd if (simd : kSimd) reduction(max : size) reduction(+ : zero)
    for (Eigen::Index i = 0; i < n; ++i) {
      const double updated = increment[i] - delta[i];
      increment[i] = updated;
      size = std::max(size, std::abs(delta[i]));
      zero += 0.0 * updated;
    }
  }
  return {size, scale, zero == 0.0};
}

FRACVI_PASS bool all_finite(const double* v, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) zero += 0.0 * v[i];
  return zero == 0.0;
}

FRACVI_PASS double midpoint(const double* a, const double* increment, double* out, Eigen::Index n,
                            bool with_scale) {
  double scale = 0.0;
  if (with_scale) {
#pragma omp simd if (simd : kSimd) reduction(max : scale)
    for (Eigen::Index i = 0; i < n; ++i) {
      out[i] = a[i] + 0.5 * increment[i];
      scale = std::max(scale, std::abs(a[i]));
    }
  } else {
#pragma omp simd if (simd : kSimd)
    for (Eigen::Index i = 0; i < n; ++i) out[i] = a[i] + 0.5 * increment[i];
  }
  return scale;
}

FRACVI_PASS void start_momentum(const double* p, const double* force, double impulse, double h,
                                double* p_plus, double* rhs, Eigen::Index n) {
#pragma omp simd if (simd : kSimd)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = p[i] - impulse * force[i];
    p_plus[i] = value;
    rhs[i] = h * value;
  }
}

FRACVI_PASS void scale_and_subtract(double s, const double* b, double* a, Eigen::Index n) {
#pragma omp simd if (simd : kSimd)
  for (Eigen::Index i = 0; i < n; ++i) a[i] = a[i] * s - b[i];
}

FRACVI_PASS void subtract_scaled(const double* a, double s, const double* b, double* out,
                                 Eigen::Index n) {
#pragma omp simd if (simd : kSimd)
  for (Eigen::Index i = 0; i < n; ++i) out[i] = a[i] - s * b[i];
}

FRACVI_PASS void shifted(const double* x, const double* x0, double t, const double* v0, double* out,
                         Eigen::Index n) {
  // One loop per case (the branches out of the loop); the roundings of x, then −x_0, then −t v_0.
  if (x0 != nullptr && v0 != nullptr) {
#pragma omp simd if (simd : kSimd)
    for (Eigen::Index i = 0; i < n; ++i) out[i] = (x[i] - x0[i]) - t * v0[i];
  } else if (x0 != nullptr) {
#pragma omp simd if (simd : kSimd)
    for (Eigen::Index i = 0; i < n; ++i) out[i] = x[i] - x0[i];
  } else if (v0 != nullptr) {
#pragma omp simd if (simd : kSimd)
    for (Eigen::Index i = 0; i < n; ++i) out[i] = x[i] - t * v0[i];
  } else {
    for (Eigen::Index i = 0; i < n; ++i) out[i] = x[i];  // no call inside a clone (above)
  }
}

// The rest of a step after its increment, for a diagonal M = diag(m) (the chains'):
// p⁻_i = (m_i Δ_i)·s − p⁺_i (Δ_i·s − p⁺_i with kUnitMass: 1·Δ_i is Δ_i), x_next_i = a_i + Δ_i
// and, with kTilde, x̃_i = (x_next_i − x0_i) −
// t v0_i — the roundings of M Δ, then of scale_and_subtract, add_and_check and shifted (a zero x0
// or v0 stands for a term left out: x − 0 and y − t·0 are x and y) — and, with kSquares, the
// health check's Σ (√m_i x_next_i)² summed as weighted_squares sums it (root_mass = √m; for
// kUnitMass 1·x is x). Returns whether every x_next_i is finite.
template <bool kSimd, bool kUnitMass, bool kTilde, bool kSquares>
[[gnu::always_inline]] inline bool new_position_loop(
    const double* m, const double* increment, double s, const double* p_plus, const double* a,
    const double* x0, double t, const double* v0, double* p_minus, double* next, double* tilde,
    const double* root_mass, double* squares, Eigen::Index n) {
  double zero = 0.0, sum = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero, sum)
  for (Eigen::Index i = 0; i < n; ++i) {
    p_minus[i] = (kUnitMass ? increment[i] : m[i] * increment[i]) * s - p_plus[i];
    const double value = a[i] + increment[i];
    next[i] = value;
    zero += 0.0 * value;
    if constexpr (kTilde) tilde[i] = (value - x0[i]) - t * v0[i];
    if constexpr (kSquares) {
      const double y = kUnitMass ? value : root_mass[i] * value;
      sum += y * y;
    }
  }
  if constexpr (kSquares) *squares = sum;
  return zero == 0.0;
}

FRACVI_PASS bool new_position(const double* m, bool unit_mass, const double* increment, double s,
                              const double* p_plus, const double* a, const double* x0, double t,
                              const double* v0, double* p_minus, double* next, double* tilde,
                              const double* root_mass, double* squares, Eigen::Index n) {
#define FRACVI_POSITION_LOOP(unit, with_tilde, with_squares) \
  new_position_loop<kSimd, unit, with_tilde, with_squares>(  \
      m, increment, s, p_plus, a, x0, t, v0, p_minus, next, tilde, root_mass, squares, n)
#define FRACVI_POSITION_TILDE(unit, with_squares)                    \
  (tilde != nullptr ? FRACVI_POSITION_LOOP(unit, true, with_squares) \
                    : FRACVI_POSITION_LOOP(unit, false, with_squares))
  if (unit_mass) {
    return squares != nullptr ? FRACVI_POSITION_TILDE(true, true)
                              : FRACVI_POSITION_TILDE(true, false);
  }
  return squares != nullptr ? FRACVI_POSITION_TILDE(false, true)
                            : FRACVI_POSITION_TILDE(false, false);
#undef FRACVI_POSITION_TILDE
#undef FRACVI_POSITION_LOOP
}

// The damping force and the new momentum and velocity, for diagonal M = diag(m) and R' = diag(r):
// F_i = r_i s_i, p_i = p⁻_i − c F_i, v_i = p_i / m_i (p_i itself with kUnitMass, M = I), with
// kStoreQuotient w_i = F_i / m_i — the roundings of R' s, subtract_scaled and the mass solver's
// quotients — and with kDots the energy account's F·v and F·M⁻¹F (F·F for M = I) and the kinetic
// energy's v·p, summed as dot's simd reduction sums them (tested bit for bit,
// tests/integrate/step_passes_test).
template <bool kSimd, bool kUnitMass, bool kStoreQuotient, bool kDots>
[[gnu::always_inline]] inline MomentumPass new_momentum_loop(const double* r, const double* sum,
                                                             const double* p_minus, double c,
                                                             const double* m, double* force,
                                                             double* p, double* v, double* w,
                                                             Eigen::Index n) {
  double zero = 0.0, fv = 0.0, fw = 0.0, vp = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero, fv, fw, vp)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double f = r[i] * sum[i];
    force[i] = f;
    const double momentum = p_minus[i] - c * f;
    p[i] = momentum;
    const double velocity = kUnitMass ? momentum : momentum / m[i];
    v[i] = velocity;
    zero += 0.0 * velocity;
    const double quotient = kUnitMass ? f : f / m[i];  // M⁻¹F (unused unless stored or summed)
    if constexpr (kStoreQuotient) w[i] = quotient;
    if constexpr (kDots) {
      fv += f * velocity;
      fw += f * quotient;
      vp += velocity * momentum;
    }
  }
  return {zero == 0.0, fv, fw, vp};
}

FRACVI_PASS MomentumPass new_momentum(const double* r, const double* sum, const double* p_minus,
                                      double c, const double* m, bool unit_mass, double* force,
                                      double* p, double* v, double* w, bool with_dots,
                                      Eigen::Index n) {
#define FRACVI_MOMENTUM_LOOP(unit, quotient, dots) \
  new_momentum_loop<kSimd, unit, quotient, dots>(r, sum, p_minus, c, m, force, p, v, w, n)
  if (unit_mass) {
    return with_dots ? FRACVI_MOMENTUM_LOOP(true, false, true)
                     : FRACVI_MOMENTUM_LOOP(true, false, false);
  }
  if (w == nullptr) {
    return with_dots ? FRACVI_MOMENTUM_LOOP(false, false, true)
                     : FRACVI_MOMENTUM_LOOP(false, false, false);
  }
  return with_dots ? FRACVI_MOMENTUM_LOOP(false, true, true)
                   : FRACVI_MOMENTUM_LOOP(false, true, false);
#undef FRACVI_MOMENTUM_LOOP
}

// fvi-midpoint's step before Newton's solve, for R' = diag(r), the operations of its separate
// passes in their order: x̃̄ = (x_k − x_0) − t v_0 (x_k without kSplit), Ĝ = r(w x̃̄ + S) +
// ½(G^P_k + G^P_{k−1}), rhs = hq − h²Ĝ.
template <bool kSimd, bool kSplit>
[[gnu::always_inline]] inline void trapezoid_known_loop(
    const double* r, const double* x, const double* x0, double t, const double* v0, double w,
    const double* sum, const double* g_poly, const double* g_poly_prev, const double* q, double h,
    double* mid_tilde, double* rhs, Eigen::Index n) {
  const double h2 = h * h;
#pragma omp simd if (simd : kSimd)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double mid = kSplit ? (x[i] - x0[i]) - t * v0[i] : x[i];
    mid_tilde[i] = mid;
    const double g_hat = r[i] * (w * mid + sum[i]) + 0.5 * (g_poly[i] + g_poly_prev[i]);
    rhs[i] = h * q[i] - h2 * g_hat;
  }
}

FRACVI_PASS void trapezoid_known(const double* r, const double* x, const double* x0, double t,
                                 const double* v0, double w, const double* sum,
                                 const double* g_poly, const double* g_poly_prev, const double* q,
                                 double h, double* mid_tilde, double* rhs, Eigen::Index n) {
  if (x0 != nullptr) {
    trapezoid_known_loop<kSimd, true>(r, x, x0, t, v0, w, sum, g_poly, g_poly_prev, q, h, mid_tilde,
                                      rhs, n);
  } else {
    trapezoid_known_loop<kSimd, false>(r, x, x0, t, v0, w, sum, g_poly, g_poly_prev, q, h,
                                       mid_tilde, rhs, n);
  }
}

// fvi-midpoint's step after Newton's solve (schemes/fvi_midpoint.cpp) for diagonal M = diag(m)
// and R' = diag(r), the operations of its separate passes in their order: x_{k+1} = x_k + Δ;
// q ← (mΔ)s − q; x̃̄ ← x̃̄ + Δ/2; Ĝ̃ = r(w x̃̄ + S); G̃ ← 2Ĝ̃ − G̃; q ← (q + hĜ̃) + (h/2)(G^P_k +
// G^P_{k−1}); G = G̃ + G^P_k; p = q − (h/2)G; v = p/m (p for kUnitMass: mΔ = Δ and p/1 = p
// exactly); with kWork the energy account's G·Δ in dot's order.
template <bool kSimd, bool kUnitMass, bool kWork>
[[gnu::always_inline]] inline TrapezoidPass trapezoid_step_loop(
    const double* m, const double* r, const double* a, const double* increment, double s, double w,
    const double* sum, const double* g_poly, const double* g_poly_prev, double h, double* next,
    double* q, double* mid_tilde, double* g_tilde, double* g_total, double* p, double* v,
    Eigen::Index n) {
  const double half_h = 0.5 * h;
  double zero_x = 0.0, zero_v = 0.0, work = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : zero_x, zero_v, work)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double dx = increment[i];
    const double x = a[i] + dx;
    next[i] = x;
    zero_x += 0.0 * x;
    const double mdx = kUnitMass ? dx : m[i] * dx;
    const double mid = mid_tilde[i] + 0.5 * dx;
    mid_tilde[i] = mid;
    const double g_hat = r[i] * (w * mid + sum[i]);
    const double g_til = 2.0 * g_hat - g_tilde[i];
    g_tilde[i] = g_til;
    const double q_next = ((mdx * s - q[i]) + h * g_hat) + half_h * (g_poly[i] + g_poly_prev[i]);
    q[i] = q_next;
    const double g = g_til + g_poly[i];
    g_total[i] = g;
    const double momentum = q_next - half_h * g;
    p[i] = momentum;
    const double velocity = kUnitMass ? momentum : momentum / m[i];
    v[i] = velocity;
    zero_v += 0.0 * velocity;
    if constexpr (kWork) work += g * dx;
  }
  return {zero_x == 0.0, zero_v == 0.0, work};
}

FRACVI_PASS TrapezoidPass trapezoid_step(const double* m, bool unit_mass, const double* r,
                                         const double* a, const double* increment, double s,
                                         double w, const double* sum, const double* g_poly,
                                         const double* g_poly_prev, double h, double* next,
                                         double* q, double* mid_tilde, double* g_tilde,
                                         double* g_total, double* p, double* v, bool with_work,
                                         Eigen::Index n) {
#define FRACVI_TRAPEZOID_LOOP(unit, with)                                                       \
  trapezoid_step_loop<kSimd, unit, with>(m, r, a, increment, s, w, sum, g_poly, g_poly_prev, h, \
                                         next, q, mid_tilde, g_tilde, g_total, p, v, n)
  if (unit_mass) {
    return with_work ? FRACVI_TRAPEZOID_LOOP(true, true) : FRACVI_TRAPEZOID_LOOP(true, false);
  }
  return with_work ? FRACVI_TRAPEZOID_LOOP(false, true) : FRACVI_TRAPEZOID_LOOP(false, false);
#undef FRACVI_TRAPEZOID_LOOP
}

FRACVI_PASS double dot(const double* a, const double* b, Eigen::Index n) {
  double sum = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : sum)
  for (Eigen::Index i = 0; i < n; ++i) sum += a[i] * b[i];
  return sum;
}

FRACVI_PASS double weighted_squares(const double* w, const double* x, Eigen::Index n) {
  double sum = 0.0;
#pragma omp simd if (simd : kSimd) reduction(+ : sum)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double y = w[i] * x[i];
    sum += y * y;
  }
  return sum;
}

#undef FRACVI_PASS

}  // namespace loops

// The kernels: the loops above in x86-64-v3 clones (vector_passes.cpp).
namespace kernels {
bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n);
bool diagonal_residual(const double* m, const double* increment, double s, const double* g,
                       const double* c, double* out, Eigen::Index n);
bool general_residual(double s, const double* g, const double* c, double* out, Eigen::Index n);
CorrectionPass apply_correction(const double* delta, const double* a, double* increment,
                                double* mid, Eigen::Index n, bool with_next);
bool all_finite(const double* v, Eigen::Index n);
double midpoint(const double* a, const double* increment, double* out, Eigen::Index n,
                bool with_scale);
void start_momentum(const double* p, const double* force, double impulse, double h, double* p_plus,
                    double* rhs, Eigen::Index n);
void scale_and_subtract(double s, const double* b, double* a, Eigen::Index n);
void subtract_scaled(const double* a, double s, const double* b, double* out, Eigen::Index n);
void shifted(const double* x, const double* x0, double t, const double* v0, double* out,
             Eigen::Index n);
bool new_position(const double* m, bool unit_mass, const double* increment, double s,
                  const double* p_plus, const double* a, const double* x0, double t,
                  const double* v0, double* p_minus, double* next, double* tilde,
                  const double* root_mass, double* squares, Eigen::Index n);
MomentumPass new_momentum(const double* r, const double* sum, const double* p_minus, double c,
                          const double* m, bool unit_mass, double* force, double* p, double* v,
                          double* w, bool with_dots, Eigen::Index n);
void trapezoid_known(const double* r, const double* x, const double* x0, double t, const double* v0,
                     double w, const double* sum, const double* g_poly, const double* g_poly_prev,
                     const double* q, double h, double* mid_tilde, double* rhs, Eigen::Index n);
TrapezoidPass trapezoid_step(const double* m, bool unit_mass, const double* r, const double* a,
                             const double* increment, double s, double w, const double* sum,
                             const double* g_poly, const double* g_poly_prev, double h,
                             double* next, double* q, double* mid_tilde, double* g_tilde,
                             double* g_total, double* p, double* v, bool with_work, Eigen::Index n);
double dot(const double* a, const double* b, Eigen::Index n);
double weighted_squares(const double* w, const double* x, Eigen::Index n);
}  // namespace kernels

// The passes (n elements each; the pointers may not overlap except where an argument is read and
// written in place).
#define FRACVI_DISPATCH(name, ...) \
  (n < kVectorPassesFrom ? loops::name<false>(__VA_ARGS__) : kernels::name(__VA_ARGS__))

/// out_i = a_i + b_i; returns whether every out_i is finite.
inline bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n) {
  return FRACVI_DISPATCH(add_and_check, a, b, out, n);
}
/// out_i = (m_i Δ_i + s g_i) − c_i, the residual of A Δ + s g = c for a diagonal A = diag(m);
/// returns whether every out_i is finite.
inline bool diagonal_residual(const double* m, const double* increment, double s, const double* g,
                              const double* c, double* out, Eigen::Index n) {
  return FRACVI_DISPATCH(diagonal_residual, m, increment, s, g, c, out, n);
}
/// out_i = (out_i + s g_i) − c_i (out holds A Δ); returns whether every out_i is finite.
inline bool general_residual(double s, const double* g, const double* c, double* out,
                             Eigen::Index n) {
  return FRACVI_DISPATCH(general_residual, s, g, c, out, n);
}
/// Δ_i −= δ_i, and with `with_next` the next iterate's midpoint mid_i = a_i + Δ_i/2 and the scale
/// max|a_i + Δ_i| of the convergence test (`mid` is not touched without).
inline CorrectionPass apply_correction_pass(const double* delta, const double* a, double* increment,
                                            double* mid, Eigen::Index n, bool with_next) {
  return FRACVI_DISPATCH(apply_correction, delta, a, increment, mid, n, with_next);
}
/// Whether every v_i is finite.
inline bool all_finite_pass(const double* v, Eigen::Index n) {
  return FRACVI_DISPATCH(all_finite, v, n);
}
/// out_i = a_i + Δ_i/2; with `with_scale` returns max|a_i| (the scale of Newton's convergence
/// test), else 0.
inline double midpoint_pass(const double* a, const double* increment, double* out, Eigen::Index n,
                            bool with_scale = false) {
  return FRACVI_DISPATCH(midpoint, a, increment, out, n, with_scale);
}
/// p⁺_i = p_i − w F_i and rhs_i = h p⁺_i.
inline void start_momentum_pass(const double* p, const double* force, double impulse, double h,
                                double* p_plus, double* rhs, Eigen::Index n) {
  FRACVI_DISPATCH(start_momentum, p, force, impulse, h, p_plus, rhs, n);
}
/// a_i = a_i s − b_i.
inline void scale_and_subtract_pass(double s, const double* b, double* a, Eigen::Index n) {
  FRACVI_DISPATCH(scale_and_subtract, s, b, a, n);
}
/// out_i = a_i − s b_i.
inline void subtract_scaled_pass(const double* a, double s, const double* b, double* out,
                                 Eigen::Index n) {
  FRACVI_DISPATCH(subtract_scaled, a, s, b, out, n);
}
/// out_i = x_i − x0_i − t v0_i, a null x0 or v0 leaving its term out.
inline void shifted_pass(const double* x, const double* x0, double t, const double* v0, double* out,
                         Eigen::Index n) {
  FRACVI_DISPATCH(shifted, x, x0, t, v0, out, n);
}
/// For M = diag(m): p⁻_i = (m_i Δ_i) s − p⁺_i, x_next_i = a_i + Δ_i and (unless `tilde` is
/// null) x̃_i = (x_next_i − x0_i) − t v0_i; `unit_mass` (m = 1) skips the products by 1. Unless
/// `squares` is null, *squares = Σ (√m_i x_next_i)² in weighted_squares_pass's order (root_mass =
/// √m, not read for `unit_mass`; n ≥ kVectorPassesFrom, where the health check takes that pass).
/// Returns whether every x_next_i is finite.
inline bool new_position_pass(const double* m, bool unit_mass, const double* increment, double s,
                              const double* p_plus, const double* a, const double* x0, double t,
                              const double* v0, double* p_minus, double* next, double* tilde,
                              Eigen::Index n, const double* root_mass = nullptr,
                              double* squares = nullptr) {
  return FRACVI_DISPATCH(new_position, m, unit_mass, increment, s, p_plus, a, x0, t, v0, p_minus,
                         next, tilde, root_mass, squares, n);
}
/// For M = diag(m), R' = diag(r): F_i = r_i s_i, p_i = p⁻_i − c F_i, v_i = p_i / m_i (p_i for
/// `unit_mass`), unless `w` is null w_i = F_i / m_i (not written for `unit_mass`), and with
/// `with_dots` F·v, F·M⁻¹F and v·p in dot_pass's order (n ≥ kVectorPassesFrom; smaller systems keep
/// Eigen's sums).
inline MomentumPass new_momentum_pass(const double* r, const double* sum, const double* p_minus,
                                      double c, const double* m, bool unit_mass, double* force,
                                      double* p, double* v, double* w, bool with_dots,
                                      Eigen::Index n) {
  return FRACVI_DISPATCH(new_momentum, r, sum, p_minus, c, m, unit_mass, force, p, v, w, with_dots,
                         n);
}
/// fvi-midpoint's step before Newton's solve for R' = diag(r), with w = ω̂_0: x̃̄ = (x − x0) − t v0
/// (x itself for a null x0: no Taylor split; v0 is read with x0), Ĝ = r(w x̃̄ + S) + ½(G^P_k +
/// G^P_{k−1}) and rhs = hq − h²Ĝ. The default build makes the roundings of the separate Eigen
/// expressions; the x86-64-v3 clone fuses a·b + c into FMAs.
inline void trapezoid_known_pass(const double* r, const double* x, const double* x0, double t,
                                 const double* v0, double w, const double* sum,
                                 const double* g_poly, const double* g_poly_prev, const double* q,
                                 double h, double* mid_tilde, double* rhs, Eigen::Index n) {
  FRACVI_DISPATCH(trapezoid_known, r, x, x0, t, v0, w, sum, g_poly, g_poly_prev, q, h, mid_tilde,
                  rhs, n);
}
/// fvi-midpoint's step after Newton's solve for M = diag(m) (`unit_mass`: m = 1, not read) and
/// R' = diag(r), with s = 2/h and w = ω̂_0: next = a + Δ, q ← (mΔ)s − q + hĜ̃ + (h/2)(G^P_k +
/// G^P_{k−1}) with Ĝ̃ = r(w x̃̄ + S) and x̃̄ ← x̃̄ + Δ/2 (in place), G̃ ← 2Ĝ̃ − G̃ (in place),
/// G = G̃ + G^P_k, p = q − (h/2)G, v = p/m; with `with_work` G·Δ in dot_pass's order
/// (n ≥ kVectorPassesFrom; smaller systems keep Eigen's dot). The default build makes the roundings
/// of the separate Eigen expressions; the x86-64-v3 clone fuses a·b + c into FMAs.
inline TrapezoidPass trapezoid_step_pass(const double* m, bool unit_mass, const double* r,
                                         const double* a, const double* increment, double s,
                                         double w, const double* sum, const double* g_poly,
                                         const double* g_poly_prev, double h, double* next,
                                         double* q, double* mid_tilde, double* g_tilde,
                                         double* g_total, double* p, double* v, bool with_work,
                                         Eigen::Index n) {
  return FRACVI_DISPATCH(trapezoid_step, m, unit_mass, r, a, increment, s, w, sum, g_poly,
                         g_poly_prev, h, next, q, mid_tilde, g_tilde, g_total, p, v, with_work, n);
}

#undef FRACVI_DISPATCH

/// Σ a_i b_i for n ≥ kVectorPassesFrom, in the order of an OpenMP simd reduction (not Eigen's dot:
/// smaller systems keep Eigen's, whose bits their outputs were checked with).
inline double dot_pass(const double* a, const double* b, Eigen::Index n) {
  return kernels::dot(a, b, n);
}
/// a·b as the steps have always formed it: dot_pass from kVectorPassesFrom on, Eigen's dot below
/// (whose bits the small systems' outputs were checked with), and at n = 1 the one product, the
/// same bits as Eigen's dot without its set-up for a dynamic size (three calls a d = 1 step: 27
/// of its ≈ 1750 instructions fewer, callgrind).
inline double step_dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const Eigen::Index n = a.size();
  if (n >= kVectorPassesFrom) return dot_pass(a.data(), b.data(), n);
  return n == 1 ? a[0] * b[0] : a.dot(b);
}
/// Σ (w_i x_i)² for n ≥ kVectorPassesFrom (the health check's ‖x‖²_M for a diagonal M, w = √m),
/// in the order of an OpenMP simd reduction.
inline double weighted_squares_pass(const double* w, const double* x, Eigen::Index n) {
  return kernels::weighted_squares(w, x, n);
}

}  // namespace fracvi::internal
