// From a parsed problem to something that can be integrated: every check `fracvi run` applies
// before its first step, in one place, shared by the CLI (run, convergence) and the Python module.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <string>

#include "fracvi/analysis/comparison.hpp"
#include "fracvi/analysis/convergence.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/lagrangian/bvp.hpp"

namespace fracvi {

/// A validated initial value problem with its scheme and integrator options.
struct PreparedRun {
  ProblemSpec spec;
  InitialValueProblem problem;
  Method method;  ///< [method] scheme
  IntegratorOptions options;
};

/// Builds the initial value problem of `spec` — the mechanical model, or a general Lagrangian of
/// mechanical form (fracvi/io/lagrangian_problem.hpp) — and validates it with its options. Every
/// failure is a ProblemFileError with one line "<source>: <what>": a boundary-value-only file (use
/// fracvi bvp), a malformed formula (with its column), a Lagrangian that cannot be stepped
/// forward, a scheme that does not apply or a step beyond its stability bound, or a model/option
/// rule.
PreparedRun prepare_run(ProblemSpec spec);

/// What `fracvi run` computes for a prepared run, in one place for the CLI, sweeps and Python:
/// with method.tolerance > 0 the doubling of integrate_to_tolerance(), otherwise one integration
/// (`on_step(k)` after each step k, for progress) followed by its error estimate
/// (estimate_error). `integrator`, if given, was built from `prepared` beforehand (the CLI builds
/// it before preparing its output directory, so that set-up failures come first); null builds it
/// here. Throws ValidationError for a problem the Integrator refuses.
Solution solve_prepared(const PreparedRun& prepared, std::unique_ptr<Integrator> integrator = {},
                        const std::function<void(std::size_t)>& on_step = {});

/// A validated boundary value problem (`fracvi bvp`, Python's fracvi.solve_bvp) with its options.
struct PreparedBvp {
  ProblemSpec spec;
  BoundaryValueProblem problem;
  BvpOptions options;
};

/// Builds the boundary value problem of `spec` (make_boundary_value_problem: [boundary] required,
/// Δ^α_± of `[method] scheme`, the Lagrangian checked at the starting iterate) and its options
/// (make_bvp_options). Every failure is a ProblemFileError with one line "<source>: <what>": no
/// [boundary], a scheme without a boundary value form, a malformed formula, a model rule.
PreparedBvp prepare_bvp(ProblemSpec spec);

/// The convergence study (fracvi/analysis/convergence.hpp) of `spec`: runs it (prepare_run, every
/// step stored, without the mirror run) with each step count (ascending) and measures the error
/// against `exact` (d formulas in t) or, if that is empty, against a run with `reference_steps`
/// steps (a multiple of every entry of `steps`). Throws std::invalid_argument for inconsistent
/// arguments and std::runtime_error if the reference run fails.
ConvergenceStudy convergence_study(const ProblemSpec& spec, std::span<const std::size_t> steps,
                                   std::span<const std::string> exact,
                                   std::size_t reference_steps = 0);

/// How `fracvi compare` / fracvi.compare find their reference (comparison.hpp).
struct ComparisonSetup {
  std::vector<std::string> schemes;  ///< registry names
  std::vector<std::size_t> steps;    ///< ascending
  /// Exact x(t), d formulas in t; empty: spec.reference, and without that a fine run.
  std::vector<std::string> exact;
  std::size_t reference_steps = 0;  ///< the fine run's N (a multiple of every step count)
  /// The fine run's scheme; empty: dopri5 with tolerances 1e-13 where it applies (2α = 1 or
  /// R = 0: an independent adaptive Runge–Kutta code), otherwise the first of fvi-lobatto4,
  /// fvi-lobatto3, fvi-midpoint, the problem's scheme that applies.
  std::string reference_scheme;
  ComparisonOptions options;
};

/// The comparison of `setup.schemes` on `spec` (prepare_run for each scheme and N; a refusal is
/// a "not applicable" row). With an exact solution the energy reference is
/// E(t) = ½ ẋᵀMẋ + U(x, t) from the formulas and their exact t-derivatives; with a fine run, that
/// run's E_k. Throws std::invalid_argument for bad arguments (malformed formulas, reference_steps
/// not a multiple, no reference) and std::runtime_error if the reference run fails.
Comparison compare_schemes(const ProblemSpec& spec, const ComparisonSetup& setup);

}  // namespace fracvi
