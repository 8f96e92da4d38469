#include "fracvi/analysis/convergence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fracvi {

double least_squares_order(std::span<const double> h, std::span<const double> error) {
  if (h.size() != error.size() || h.size() < 2) {
    throw std::invalid_argument("least_squares_order: need at least two (h, error) pairs");
  }
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(h.size());
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double lx = std::log(h[i]), ly = std::log(error[i]);
    sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

std::vector<Expression> parse_reference(std::span<const std::string> formulas) {
  return parse_expressions(formulas, {"t"});
}

double max_error(const Solution& solution, std::span<const Expression> reference) {
  if (static_cast<Eigen::Index>(reference.size()) != solution.x.cols()) {
    throw std::invalid_argument("max_error: " + std::to_string(reference.size()) +
                                " reference components for dimension " +
                                std::to_string(solution.x.cols()));
  }
  double worst = 0.0;
  for (Eigen::Index k = 0; k < solution.t.size(); ++k) {
    for (Eigen::Index i = 0; i < solution.x.cols(); ++i) {
      const double e =
          std::abs(solution.x(k, i) - reference[static_cast<std::size_t>(i)]({solution.t[k]}));
      worst = std::isnan(e) ? e : std::max(worst, e);
    }
  }
  return worst;
}

double max_error(const Solution& coarse, const Solution& fine) {
  const auto nc = static_cast<Eigen::Index>(coarse.steps_done);
  const auto nf = static_cast<Eigen::Index>(fine.steps_done);
  if (nc == 0 || nf % nc != 0 || coarse.x.cols() != fine.x.cols()) {
    throw std::invalid_argument("max_error: the fine run's " + std::to_string(nf) +
                                " steps are not a multiple of the coarse run's " +
                                std::to_string(nc));
  }
  const Eigen::Index r = nf / nc;
  double worst = 0.0;
  for (Eigen::Index k = 0; k <= nc; ++k)
    worst = std::max(worst, (coarse.x.row(k) - fine.x.row(k * r)).cwiseAbs().maxCoeff());
  return worst;
}

void check_step_counts(std::span<const std::size_t> steps, std::size_t minimum) {
  if (steps.size() < minimum) {
    throw std::invalid_argument("--steps: give at least " + std::to_string(minimum) +
                                (minimum == 1 ? " step count" : " step counts"));
  }
  for (std::size_t i = 0; i < steps.size(); ++i) {
    if (steps[i] < 1) throw std::invalid_argument("--steps: step counts must be positive");
    if (i > 0 && steps[i] <= steps[i - 1]) {
      throw std::invalid_argument("--steps: step counts must increase (" +
                                  std::to_string(steps[i]) + " after " +
                                  std::to_string(steps[i - 1]) + ")");
    }
  }
}

void check_reference_steps(std::size_t reference_steps, std::span<const std::size_t> steps) {
  if (reference_steps == 0) {
    throw std::invalid_argument(
        "no reference: give [reference] position in the file, --reference or --reference-steps");
  }
  for (std::size_t n : steps) {
    if (n == 0 || reference_steps % n != 0 || reference_steps <= n) {
      throw std::invalid_argument("--reference-steps = " + std::to_string(reference_steps) +
                                  " must be a larger multiple of every --steps entry (" +
                                  std::to_string(n) + " is not a divisor)");
    }
  }
}

ConvergenceStudy convergence_study(const std::string& problem, double interval,
                                   const RunWithSteps& run, std::span<const std::size_t> steps,
                                   std::span<const std::string> exact,
                                   std::size_t reference_steps) {
  check_step_counts(steps, 2);
  ConvergenceStudy study;
  study.problem = problem;
  std::vector<Expression> reference;
  Solution fine;
  if (!exact.empty()) {
    reference = parse_reference(exact);
    study.reference = "exact solution";
  } else {
    check_reference_steps(reference_steps, steps);
    fine = run(reference_steps);
    if (!fine.ok()) throw std::runtime_error("the reference run failed: " + fine.message);
    study.reference = "fine run with " + std::to_string(reference_steps) + " steps";
  }
  std::vector<double> hs, errors;
  for (std::size_t n : steps) {
    const Solution s = run(n);
    study.declared_order = s.declared_order;
    ConvergenceRow row;
    row.steps = n;
    row.h = interval / static_cast<double>(n);
    row.status = s.ok() ? "success" : std::string(to_string(s.status));
    row.wall_seconds = s.wall_time_seconds;
    row.error = !s.ok()             ? std::numeric_limits<double>::quiet_NaN()
                : reference.empty() ? max_error(s, fine)
                                    : max_error(s, reference);
    row.observed_order = study.rows.empty() ? std::numeric_limits<double>::quiet_NaN()
                                            : std::log(study.rows.back().error / row.error) /
                                                  std::log(study.rows.back().h / row.h);
    study.rows.push_back(row);
    if (std::isfinite(row.error) && row.error > 0) hs.push_back(row.h), errors.push_back(row.error);
  }
  study.fitted_order =
      hs.size() >= 2 ? least_squares_order(hs, errors) : std::numeric_limits<double>::quiet_NaN();
  return study;
}

}  // namespace fracvi
