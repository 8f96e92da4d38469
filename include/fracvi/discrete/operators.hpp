// The paper's discrete operators on sequences {z_k}_{0:N} of vectors in R^d (`AllSequencs`).
//
// A sequence is stored as a d × (N+1) matrix whose column k is z_k (each z_k contiguous).
// Every operator returns a d × (N+1) matrix indexed by k, so that code reads like the paper;
// entries outside the paper's index range are zero and documented per operator:
//
//   S z_k      = (z_k + z_{k+1})/2           k = 0..N−1   (`MidpointRule`; column N is 0)
//   Δ_− z_k    = (z_k − z_{k−1})/h           k = 1..N     (`DiscDerDef:1`; Δ_− z_0 := 0)
//   Δ_+ z_k    = −(z_{k+1} − z_k)/h          k = 0..N−1   (`DiscDerDef:2`; column N is 0)
//   Δ^α_− z_k  = h^{−α} Σ_{n=0}^{k}   α_n z_{k−n}   k = 0..N  (`DiscFracDerDef:1`)
//   Δ^α_+ z_k  = h^{−α} Σ_{n=0}^{N−k} α_n z_{k+n}   k = 0..N  (`DiscFracDerDef:2`)
//
// The fractional differences take an optional generating function: the paper's Grünwald–Letnikov
// α_n by default (bit for bit), or the weights ω_n = cq_weights(quadrature, α, ·) of another
// convolution quadrature (CqScheme::kBdf2: the Δ^α_± of the scheme `fvi-bdf2`).
//
// These allocate their results: they serve action sums, residuals and tests, not the time-step
// loop (the integrator keeps its own allocation-free history).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "fracvi/fractional/convolution.hpp"
#include "fracvi/fractional/weights.hpp"

namespace fracvi {

/// A discrete curve {z_k}_{0:N} in R^d: column k is z_k.
using Sequence = Eigen::MatrixXd;

namespace internal {
inline void require_step(double h, const char* op) {
  if (!(h > 0.0)) {
    throw std::invalid_argument(std::string(op) + ": step h = " + std::to_string(h) +
                                " must be positive");
  }
}
inline void require_weights(std::span<const double> w, Eigen::Index columns, const char* op) {
  if (w.size() < static_cast<std::size_t>(columns)) {
    throw std::invalid_argument(std::string(op) + ": " + std::to_string(w.size()) +
                                " weights given, the sequence needs " + std::to_string(columns));
  }
}
}  // namespace internal

namespace internal {
/// Row by row: scale · (w ⋆ z) (causal) or its mirror (anti-causal, `reverse`), direct or by FFT
/// (SeriesConvolution, the one convolution of the library).
inline Sequence convolve_rows(std::span<const double> w, const Sequence& z, double scale,
                              bool reverse, const char* op) {
  require_weights(w, z.cols(), op);
  const SeriesConvolution convolution(
      std::vector<double>(w.begin(), w.begin() + static_cast<std::ptrdiff_t>(z.cols())), scale);
  Sequence out(z.rows(), z.cols());
  for (Eigen::Index i = 0; i < z.rows(); ++i)
    convolution.apply(z.data() + i, z.rows(), out.data() + i, out.rows(), reverse);
  return out;
}
}  // namespace internal

/// Σ_{m=0}^{k} w_m z_{k−m} for k = 0..N (the causal, "retarded" convolution).
inline Sequence convolve_past(std::span<const double> w, const Sequence& z) {
  return internal::convolve_rows(w, z, 1.0, false, "convolve_past");
}

/// Σ_{m=0}^{N−k} w_m z_{k+m} for k = 0..N (the anti-causal, "advanced" convolution).
inline Sequence convolve_future(std::span<const double> w, const Sequence& z) {
  return internal::convolve_rows(w, z, 1.0, true, "convolve_future");
}

/// S z_k = (z_k + z_{k+1})/2, k = 0..N−1 (`MidpointRule`); column N is zero.
inline Sequence midpoint(const Sequence& z) {
  Sequence out = Sequence::Zero(z.rows(), z.cols());
  if (z.cols() > 1) {
    const Eigen::Index n = z.cols() - 1;
    out.leftCols(n) = 0.5 * (z.leftCols(n) + z.rightCols(n));
  }
  return out;
}

/// Δ_− z_k = (z_k − z_{k−1})/h, k = 1..N, and Δ_− z_0 := 0 (`DiscDerDef:1`).
inline Sequence delta_minus(const Sequence& z, double h) {
  internal::require_step(h, "delta_minus");
  Sequence out = Sequence::Zero(z.rows(), z.cols());
  if (z.cols() > 1) {
    const Eigen::Index n = z.cols() - 1;
    out.rightCols(n) = (z.rightCols(n) - z.leftCols(n)) / h;
  }
  return out;
}

/// Δ_+ z_k = −(z_{k+1} − z_k)/h, k = 0..N−1 (`DiscDerDef:2`; note the minus sign); column N is 0.
inline Sequence delta_plus(const Sequence& z, double h) {
  internal::require_step(h, "delta_plus");
  Sequence out = Sequence::Zero(z.rows(), z.cols());
  if (z.cols() > 1) {
    const Eigen::Index n = z.cols() - 1;
    out.leftCols(n) = -(z.rightCols(n) - z.leftCols(n)) / h;
  }
  return out;
}

/// Δ^α_− z_k = h^{−α} Σ_{n=0}^{k} α_n z_{k−n}, k = 0..N (`DiscFracDerDef:1`); with `quadrature`
/// the weights are cq_weights(quadrature, α, N+1) (the default gives gl_weights exactly).
inline Sequence frac_delta_minus(const Sequence& z, double h, double alpha,
                                 CqScheme quadrature = CqScheme::kGrunwaldLetnikov) {
  internal::require_step(h, "frac_delta_minus");
  const auto w = cq_weights(quadrature, alpha, static_cast<std::size_t>(z.cols()));
  return internal::convolve_rows(w, z, std::pow(h, -alpha), false, "frac_delta_minus");
}

/// Δ^α_+ z_k = h^{−α} Σ_{n=0}^{N−k} α_n z_{k+n}, k = 0..N (`DiscFracDerDef:2`); `quadrature` as
/// for frac_delta_minus.
inline Sequence frac_delta_plus(const Sequence& z, double h, double alpha,
                                CqScheme quadrature = CqScheme::kGrunwaldLetnikov) {
  internal::require_step(h, "frac_delta_plus");
  const auto w = cq_weights(quadrature, alpha, static_cast<std::size_t>(z.cols()));
  return internal::convolve_rows(w, z, std::pow(h, -alpha), true, "frac_delta_plus");
}

}  // namespace fracvi
