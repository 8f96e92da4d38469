// Growth of a hand-stepped run, for the stability tests (tests/schemes/scheme_suite_test.cpp (g),
// tests/schemes/fvi_lobatto_test.cpp): the Stepper is driven directly, so no stability check of the
// Integrator refuses the problem first.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>

#include "fracvi/schemes/registry.hpp"
#include "fracvi/schemes/stepper.hpp"

namespace fracvi::test {

/// max_k ‖x_k‖_∞ / ‖x_0‖_∞ over a hand-stepped run (Stepper, no stability check); +∞ when the
/// state became non-finite or a step failed.
inline double stepper_growth(const SchemeInfo& info, const InitialValueProblem& problem) {
  IntegratorOptions options;
  options.mirror = false;
  options.diagnostics = false;
  const std::unique_ptr<Stepper> stepper = info.make_stepper(problem, options);
  const double x0 = problem.x0.lpNorm<Eigen::Infinity>();
  double growth = 1.0;
  for (std::size_t k = 0; k < problem.steps; ++k) {
    if (stepper->step() != Status::kSuccess) return std::numeric_limits<double>::infinity();
    const double amplitude = stepper->position().lpNorm<Eigen::Infinity>();
    if (!std::isfinite(amplitude)) return std::numeric_limits<double>::infinity();
    growth = std::max(growth, amplitude / x0);
  }
  return growth;
}

}  // namespace fracvi::test
