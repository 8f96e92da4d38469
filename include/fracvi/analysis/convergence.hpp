// Errors against references and convergence studies (observed orders of a method).
//
// An order is the least-squares slope of log(error) against log(h) over several step sizes; the
// error of one run is the maximum over its grid of ‖x_k − x_ref(t_k)‖_∞. The reference is an
// exact solution given as formulas in t, or a much finer run of the same problem whose grid
// contains the coarse one (its step count is a multiple of the coarse one).
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "fracvi/expression/expression.hpp"
#include "fracvi/integrate/solution.hpp"

namespace fracvi {

/// Least-squares slope of log(error) against log(h) (needs at least two points, all positive).
double least_squares_order(std::span<const double> h, std::span<const double> error);

/// max_k ‖x_k − ref(t_k)‖_∞ over the computed rows; `reference` holds d formulas in t.
double max_error(const Solution& solution, std::span<const Expression> reference);

/// max_k ‖x_k − x^fine_{k·r}‖_∞ where r = fine steps / coarse steps must be a whole number and both
/// runs cover the same interval.
double max_error(const Solution& coarse, const Solution& fine);

/// Parses d reference formulas in t (ExpressionError on a malformed one).
std::vector<Expression> parse_reference(std::span<const std::string> formulas);

/// The step counts of a study (convergence, comparison): at least `minimum` of them, positive and
/// increasing. Throws std::invalid_argument naming --steps and the offending entries.
void check_step_counts(std::span<const std::size_t> steps, std::size_t minimum);

/// A fine reference run's step count: nonzero (else "no reference: …") and a larger multiple of
/// every study step count, so that its grid contains theirs. Throws std::invalid_argument naming
/// --reference-steps.
void check_reference_steps(std::size_t reference_steps, std::span<const std::size_t> steps);

struct ConvergenceRow {
  std::size_t steps = 0;
  double h = 0.0;
  double error = 0.0;
  double observed_order = 0.0;  ///< against the previous row; NaN for the first
  double wall_seconds = 0.0;
  std::string status;  ///< "success" or the failure status of that run
};

struct ConvergenceStudy {
  std::string problem;
  std::string reference;  ///< "exact: …" or "fine run with N steps"
  int declared_order = 0;
  std::vector<ConvergenceRow> rows;
  double fitted_order = 0.0;  ///< least-squares slope over all rows
};

/// One run of the studied problem on its fixed interval with the given number of steps, every
/// step stored.
using RunWithSteps = std::function<Solution(std::size_t steps)>;

/// Runs `run` with each step count (ascending; h = interval / steps) and measures the error against
/// `exact` (d formulas in t) or, if that is empty, against a run with `reference_steps` steps (a
/// multiple of every entry of `steps`). `problem` names the study. Throws std::invalid_argument for
/// inconsistent arguments and std::runtime_error if the reference run fails. The convergence study
/// of a problem file is convergence_study(const ProblemSpec&, …) in fracvi/io/run.hpp.
ConvergenceStudy convergence_study(const std::string& problem, double interval,
                                   const RunWithSteps& run, std::span<const std::size_t> steps,
                                   std::span<const std::string> exact,
                                   std::size_t reference_steps = 0);

}  // namespace fracvi
