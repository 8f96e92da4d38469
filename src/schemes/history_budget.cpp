#include "fracvi/schemes/history_budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iterator>

#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/stability.hpp"

namespace fracvi {

double history_error_constant(double beta) {
  // (β, max_k |Ŝ_k − S_k| / (ε max|x̃|)), measured as documented in the header.
  struct Point {
    double beta, constant;
  };
  static constexpr Point kMeasured[] = {{0.3, 4.8e-4},  {0.5, 5.9e-4}, {0.75, 4.3e-5},
                                        {1.25, 3.3e-6}, {1.5, 2.4e-6}, {1.8, 2.2e-7}};
  if (beta <= kMeasured[0].beta) return kMeasured[0].constant;
  for (std::size_t i = 1; i < std::size(kMeasured); ++i) {
    const Point& a = kMeasured[i - 1];
    const Point& b = kMeasured[i];
    if (beta == b.beta) return b.constant;  // the measured value itself, not its log–exp image
    if (beta < b.beta) {
      const double s = (beta - a.beta) / (b.beta - a.beta);
      return std::exp((1.0 - s) * std::log(a.constant) + s * std::log(b.constant));
    }
  }
  return kMeasured[std::size(kMeasured) - 1].constant;
}

double stepper_history_tolerance(const IntegratorOptions& options) {
  return options.history_tolerance == kAutoHistoryTolerance ? kUnbudgetedHistoryTolerance
                                                            : options.history_tolerance;
}

HistoryBudget history_budget(const InitialValueProblem& problem, int order, double user_tolerance,
                             double ceiling) {
  HistoryBudget budget;
  budget.tolerance = budget.requested = ceiling;
  if (user_tolerance != kAutoHistoryTolerance) {
    budget.tolerance = budget.requested = user_tolerance;
    budget.automatic = false;
    return budget;
  }
  const double beta = problem.model.damping_order();
  // Integer orders use the local history and R = 0 none: no fit, nothing to budget.
  if (problem.model.is_undamped() || beta == std::round(beta)) return budget;
  const double r = damping_spectral_radius(problem.model);
  if (!(r > 0.0)) return budget;
  const double h = problem.step_size();
  const int p = std::max(order, 1);
  // e_H = c_H(β) r ε h^{−β} X ≤ φ κ_r h^p X with κ_r = κ r/λ_ref below λ_ref and κ λ_ref/r above
  // (history_budget.hpp; fast_history.md §10), in logs so that h^{p+β} cannot underflow.
  const double ratio = r / kHistoryBudgetReferenceDamping;
  const double damping = kHistoryBudgetReferenceDamping * std::max(1.0, ratio * ratio);
  const double log_eps = std::log(kHistoryBudgetShare * kHistoryBudgetDiscretisation /
                                  (history_error_constant(beta) * damping)) +
                         (p + beta) * std::log(h);
  budget.requested = std::exp(log_eps);
  budget.tolerance = std::clamp(budget.requested, kMinHistoryTolerance, ceiling);
  budget.limited = budget.requested < kMinHistoryTolerance;
  return budget;
}

}  // namespace fracvi
