// Newton's stopping rule, shared by the time steppers and the boundary value solver: one default
// per field, here (DESIGN §4, "one schema").
#pragma once

namespace fracvi {

struct NewtonOptions {
  /// Converged when ‖δ‖_∞ ≤ absolute_tolerance + relative_tolerance · max(‖x_{k+1}‖_∞, ‖x_k‖_∞),
  /// δ the last Newton correction (already applied), and, where the corrections contract slowly,
  /// the error they leave is below that bound too (newton_converged()). Quadratic convergence
  /// makes the accepted iterate far more accurate than the tolerance; tolerances near machine
  /// epsilon may fail to be reached because of round-off in the residual. (The time steppers'
  /// simplified Newton with a matrix carried from the previous step also stops after one
  /// correction when the next is predicted below round-off: MidpointNewton::solve.)
  double relative_tolerance = 1e-12;
  double absolute_tolerance = 0.0;
  /// Per step (per solve for the boundary value problem); ≥ 1. One default for the C++ API,
  /// problem files and Python.
  int max_iterations = 50;
};

/// The stopping rule of every Newton loop (full or simplified: a matrix kept from an earlier
/// iterate), given the last correction ‖δ_k‖, the bound it must meet, the observed contraction
/// θ = ‖δ_k‖/‖δ_{k−1}‖ (0 for a first correction with the matrix formed at the guess; +∞ for a
/// first correction with a matrix from an earlier step, whose contraction is unknown) and the
/// round-off level of the corrections (a few ulps of the iterate's size). A linearly contracting
/// iteration leaves ≈ θ/(1 − θ)·‖δ_k‖ after δ_k (the geometric tail of the remaining corrections;
/// Hairer & Wanner, Solving ODEs II, §IV.8), which exceeds ‖δ_k‖ when θ > ½: then that estimate
/// must meet the bound as well, so a kept matrix that contracts poorly cannot stop the iteration
/// with up to θ/(1 − θ) times the tolerance left (9× at θ = 0.9). At the round-off level the
/// ratio of two corrections is noise, not a contraction: there ‖δ_k‖ ≤ tolerance suffices.
[[nodiscard]] inline bool newton_converged(double correction, double tolerance, double contraction,
                                           double roundoff) {
  if (!(correction <= tolerance)) return false;
  if (correction <= roundoff || contraction <= 0.5) return true;
  return contraction < 1.0 && contraction / (1.0 - contraction) * correction <= tolerance;
}

/// Throws ValidationError naming the offending field (prefix, e.g. "options.newton").
void validate(const NewtonOptions& options, const char* prefix = "options.newton");

}  // namespace fracvi
