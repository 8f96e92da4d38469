// Newton's stopping rule, shared by the time steppers and the boundary value solver: one default
// per field, here (DESIGN §4, "one schema").
#pragma once

namespace fracvi {

struct NewtonOptions {
  /// Converged when ‖δ‖_∞ ≤ absolute_tolerance + relative_tolerance · max(‖x_{k+1}‖_∞, ‖x_k‖_∞),
  /// δ the last Newton correction (already applied). Quadratic convergence makes the accepted
  /// iterate far more accurate than the tolerance; tolerances near machine epsilon may fail to be
  /// reached because of round-off in the residual.
  double relative_tolerance = 1e-12;
  double absolute_tolerance = 0.0;
  /// Per step (per solve for the boundary value problem); ≥ 1. One default for the C++ API,
  /// problem files and Python.
  int max_iterations = 50;
};

/// Throws ValidationError naming the offending field (prefix, e.g. "options.newton").
void validate(const NewtonOptions& options, const char* prefix = "options.newton");

}  // namespace fracvi
