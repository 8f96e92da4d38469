// From a parsed problem to something that can be integrated: every check `fracvi run` applies
// before its first step, in one place, shared by the CLI (run, convergence) and the Python module.
#pragma once

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

/// A validated initial value problem with its integrator options.
struct PreparedRun {
  ProblemSpec spec;
  InitialValueProblem problem;
  IntegratorOptions options;
};

/// Builds the initial value problem of `spec` — the mechanical model, or a general Lagrangian of
/// mechanical form (fracvi/lagrangian/problem.hpp) — and validates it with its options. Every
/// failure is a ProblemFileError with one line "<source>: <what>": a boundary-value-only file (use
/// fracvi bvp), a malformed formula (with its column), a Lagrangian that cannot be stepped
/// forward, or a model/option rule.
PreparedRun prepare_run(ProblemSpec spec);

}  // namespace fracvi
