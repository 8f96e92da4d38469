// A convolution quadrature (Lubich) as a value: the generating function δ(ζ) and the order β of
// the operator s^β it discretises. For a step h the discrete operator is
//
//     (∂_h^β z)_k = h^{−β} Σ_{m=0}^{k} ω_m z_{k−m},     Σ_m ω_m ζ^m = δ(ζ)^β,
//
// and composing two of them adds the orders (δ^α · δ^α = δ^{2α}): the damping sum of a
// variational scheme built from Δ^α_± with this δ is the CQ of order 2α (DESIGN §3.1, §6).
// Histories (fracvi/memory/history.hpp) are keyed by this value, not by the order alone, so that
// one history interface serves every scheme's weights. Runge–Kutta CQ (s × s block weights) will
// extend this value with a stage count; today every quadrature here is scalar (stages() == 1).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "fracvi/fractional/weights.hpp"

namespace fracvi {

struct ConvolutionQuadrature {
  CqScheme scheme = CqScheme::kGrunwaldLetnikov;
  double order = 1.0;  ///< β (the damping sum of the mechanical schemes uses β = 2α)
  /// The first `lag` weights are left out: weights(count)[m] = ω_{m+lag}. A scheme whose current
  /// weight ω_0 acts on the unknown (and sits in Newton's matrix) keeps the known values in a
  /// history with lag 1.
  std::size_t lag = 0;

  /// ω_lag … ω_{lag+count−1} (cq_weights()).
  [[nodiscard]] std::vector<double> weights(std::size_t count) const;

  /// True when the weights terminate: δ is a polynomial (GL, BDF2) and β ∈ {0, 1, 2}. The
  /// history then keeps only the last local_weights().size() values.
  [[nodiscard]] bool is_local() const;
  /// The nonzero weights of a local quadrature, exactly (the coefficients of the polynomial δ^β,
  /// all dyadic rationals: GL (1, −1), (1, −2, 1); BDF2 (3/2, −2, 1/2), (9/4, −6, 11/2, −2, 1/4);
  /// without the first `lag` of them; empty when the lag removes every nonzero weight).
  /// Throws std::invalid_argument unless is_local().
  [[nodiscard]] std::vector<double> local_weights() const;

  /// δ(−1)^β, the symbol of the sum at the highest grid frequency (ζ = −1): 2^β for GL, 4^β for
  /// BDF2, +∞ for the trapezoidal rule (β > 0). It fixes the stability bound of a scheme that
  /// evaluates this sum at known states (docs/theory/stability.md).
  [[nodiscard]] double symbol_at_minus_one() const;

  [[nodiscard]] int stages() const { return 1; }

  /// e.g. "bdf2 CQ of order 1.5", "gl CQ of order 0.6 from lag 1".
  [[nodiscard]] std::string describe() const;

  friend bool operator==(const ConvolutionQuadrature&, const ConvolutionQuadrature&) = default;
};

/// The paper's weights: Grünwald–Letnikov, the coefficients of (1 − ζ)^order (`AlphaDef`).
inline ConvolutionQuadrature grunwald_letnikov(double order) {
  return {CqScheme::kGrunwaldLetnikov, order};
}

}  // namespace fracvi
