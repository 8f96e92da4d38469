// The action `ActFunc` of a Lagrangian along given curves, its first variation, and the pairing of
// the `FracEL` residuals with a variation that Theorem `ConsFraEL` equates with it (`RestVar`).
//
//   A[x, y]      = ∫_a^b L(V(t)) dt,  V = (x, y, ẋ, ẏ, D^α_−x, D^α_+y)        (`ActFunc`)
//   δA[δx, δy]   = d/dε A[x + ε δx, y + ε δy] at ε = 0
//   ⟨E, δ⟩       = ∫_a^b (E_x·δx + E_y·δy) dt,  E_x, E_y the `FracEL:-`, `FracEL:+` residuals.
//
// The first variation is the exact derivative in ε, not a difference quotient: every entry of V is
// linear in the curves, so V(ε) = V + ε δV with δV = (δx, δy, δẋ, δẏ, D^α_−δx, D^α_+δy)
// (`HatGamma`, whose printed last two entries D^α_−x, D^α_+y are a misprint for these), and d/dε
// L(t, V + ε δV) = ∇L(t, V)·δV exactly, ∇L by automatic differentiation (functors) or exact
// symbolic differentiation (formulas) at one point. The integrals are tanh–sinh quadratures over
// [a, b] fed exact distances from both ends (the phase point is singular like (t−a)^{−α} at a when
// x(a) ≠ 0, and like (b−t)^{−α} at b when y(b) ≠ 0).
//
// Theorem `ConsFraEL` (its proof): for restricted variations δx = δy = η with η(a) = η(b) = 0
// (`ConsVariations`), δA = ⟨E, (η, η)⟩ = ∫(E_x + E_y)·η dt. For an unrestricted variation
// (δx ≠ δy) it does not hold in general: the fractional integration by parts moves ∂L/∂D^α_−x onto
// δx but the equations pair D^α_+(∂L/∂D^α_−x) with y (tests/lagrangian/action_test.cpp measures
// both).
//
// Cost: action() and action_variation() take one phase point (2d, resp. 4d inner quadratures) per
// outer node, some 10–100 ms. fracel_pairing() takes one full residual per node (itself nested
// quadratures): seconds; a verification tool.
#pragma once

#include <vector>

#include "fracvi/lagrangian/continuous_residual.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"

namespace fracvi {

/// A[x, y] = ∫_a^b L(V) dt for the Lagrangian of order alpha ∈ [0, 1] on [a, b].
/// Throws std::invalid_argument for bad arguments (as fractional_el_residual()) and
/// std::domain_error if the integral does not converge (e.g. L quadratic in D^α_−x with
/// x(a) ≠ 0 and α ≥ 1/2: L ~ (t−a)^{−2α} is not integrable).
double action(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y, double a,
              double b, const ContinuousResidualOptions& options = {});

/// δA = d/dε A[x + ε delta_x, y + ε delta_y] at ε = 0, exactly (file comment). The variations
/// are any curves of the same dimension; restricted ones have delta_x = delta_y vanishing at a, b.
double action_variation(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y,
                        const Curve& delta_x, const Curve& delta_y, double a, double b,
                        const ContinuousResidualOptions& options = {});

/// ∫_a^b (E_x·delta_x + E_y·delta_y) dt with E_x, E_y the residuals of fractional_el_residual().
/// Equals action_variation() for delta_x = delta_y = η, η(a) = η(b) = 0 (`ConsFraEL`).
/// The variations must vanish to second order at a and b (value and first derivative, to 1e-12):
/// the residual is singular like (t−a)^{−1−α} at a (and mirrored at b) and is not evaluated in
/// the last few ulps of [a, b] (see action.cpp); std::invalid_argument otherwise. Throws as
/// fractional_el_residual() where the residual is not computable.
double fracel_pairing(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y,
                      const Curve& delta_x, const Curve& delta_y, double a, double b,
                      const ContinuousResidualOptions& options = {});

/// A variation (δx, δy) of the pair of curves.
struct Variation {
  Curve delta_x, delta_y;
};

/// fracel_pairing() for several variations at once, the residuals computed once per node.
std::vector<double> fracel_pairing(const Lagrangian& lagrangian, double alpha, const Curve& x,
                                   const Curve& y, const std::vector<Variation>& variations,
                                   double a, double b,
                                   const ContinuousResidualOptions& options = {});

}  // namespace fracvi
