// Stability bounds of the linear test problem M x'' + R D^{2α} x + K x = 0
// (docs/theory/stability.md).
#pragma once

#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {

/// λ_max(M⁻¹R), the largest eigenvalue of the pencil (R, M). Exact (generalized symmetric
/// eigensolver) for dense d ≤ 2000 and for diagonal M and R; otherwise estimated from below by
/// 300 steps of the power iteration on M⁻¹R with Rayleigh quotients (relative change < 1e-10
/// stops it earlier).
double damping_spectral_radius(const MechanicalModel& model);
/// λ_max(M⁻¹A) for a symmetric A (the same methods; damping_spectral_radius is A = R). For an
/// indefinite A the power iteration's Rayleigh quotient tracks the largest |λ|, so the result is
/// then a lower bound of max |λ| rather than of λ_max.
double pencil_spectral_radius(const ModelMatrix& matrix, const ModelMatrix& mass);

/// The bound of a scheme whose damping sum R h^{−2α} Σ ω_m x_{k−m} (the CQ `damping_sum` of order
/// 2α) is evaluated at known states inside the midpoint step (the `DiscEqs` family): the root of
/// the characteristic equation at ζ = −1 leaves the unit disc when
///     λ_max(M⁻¹R) · h^{2−2α} · δ(−1)^{2α} / 4 ≥ 1,
/// i.e. λ (h/2)^{2−2α} < 1 for GL (δ(−1) = 2) and λ h^{2−2α} 4^{2α−1} < 1 for BDF2 (δ(−1) = 4).
/// For 2α = 2 the bound does not involve h ("added mass"): λ δ(−1)²/4 < 1 for every h or none.
StabilityBound explicit_memory_bound(const InitialValueProblem& problem,
                                     const ConvolutionQuadrature& damping_sum);

}  // namespace fracvi
