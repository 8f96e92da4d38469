// The fast history's accuracy budget: the per-weight relative accuracy ε of the
// sum-of-exponentials memory chosen from the run, so that the history's share of the global error
// stays a small fraction of the discretisation error as h → 0 (docs/theory/fast_history.md §10,
// "accuracy budget").
//
// A fixed ε stops the convergence: the memory sum S = Σ c_m x̃_{k−m} is multiplied by R h^{−2α},
// so an absolute error of the sum of order ε·|x̃| becomes a force error growing like h^{−2α}
// while the discretisation error falls like h^p (measured on y'' + 0.5 D^{3/2}y + y = 0: fvi-gl
// stalls at 2.5e-7 near N = 2.6·10^7 with ε = 1e-10, the second-order schemes near 3e-10 at
// N ≈ 2.5·10^5). The model, with constants measured on that problem (§10):
//
//     history error        e_H ≈ c_H(2α) · λ_max(M⁻¹R) · ε · h^{−2α} · X,
//     discretisation error e_D ≈ κ · h^p · X,                           κ = 1e-2 (conservative),
//
// (c_H from 2.2e-7 at 2α = 1.8 to 5.9e-4 at 2α = 0.5: history_error_constant()), and the budget
// e_H ≤ φ·e_D with φ = 0.1 gives ε = φ κ h^{p+2α} / (c_H λ_ref max(1, (λ/λ_ref)²)), λ =
// λ_max(M⁻¹R), clamped to [kMinHistoryTolerance, the scheme's ceiling]. κ was measured at
// λ_ref = 0.5, and e_D changes with λ: below λ_ref the damping's part of it shrinks like λ, as e_H
// does (fvi-gl: e_D 1.8e-5, 6.6e-6, 6.6e-7 at λ = 0.5, 0.01, 0.001, N = 10^5), so a weak damping
// does not loosen ε; above λ_ref the damped solution and its error shrink (λ = 5: 2.8× for fvi-gl
// at N = 10^5, 14× for fvi-bdf2 and 26× for fvi-midpoint at 10^4), so ε tightens like 1/λ², not
// 1/λ.
#pragma once

#include <cstddef>

#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"

namespace fracvi {

/// The loosest ε "auto" chooses for a scheme whose error the model's κ h^p was not measured
/// against (SchemeInfo::history_budget_ceiling): the former fixed default. Such a scheme may be far
/// more accurate than κ h^p says — fvi-lobatto3 at 2α = 1.5 reaches 8.7e-10 at h = 1.25e-3, 1/18
/// of κ h² — and a looser ε would let the history dominate its error (measured with 1e-6: a
/// plateau at 3.7e-10 in the order tests, docs/theory/fast_history.md §10.3).
inline constexpr double kAutoHistoryCeiling = 1e-10;
/// The loosest ε "auto" chooses for fvi-gl, fvi-bdf2 and fvi-midpoint, whose error constants κ is
/// 9–18× below (measured on the test problem). Looser than 1e-10 where the budget allows it: at
/// d = 1000, N = 10^5, h = 0.01 the fit needs K = 28 exponentials instead of 41, ≈ 20 % of the
/// chain's step on one thread; the model's own estimate is not trusted further (it was 55× low on
/// a chain with slow modes over a long run, where e_H was still 1.3e-4 of e_D at ε = 1e-3).
inline constexpr double kMeasuredHistoryCeiling = 1e-6;
/// λ_ref: the damping λ_max(M⁻¹R) of the problem κ was measured on (the budget's use of it: above).
inline constexpr double kHistoryBudgetReferenceDamping = 0.5;
/// The ε of a stepper built without a budget (SchemeInfo::make_stepper with "auto"), which knows
/// nothing of the run: the former fixed default.
inline constexpr double kUnbudgetedHistoryTolerance = 1e-10;
/// The model's constants (docs/theory/fast_history.md §10): φ, the share of the discretisation
/// error estimate the history may take; κ, the constant of that a-priori estimate κ h^p (measured
/// 0.18 for fvi-gl, 0.16 for fvi-bdf2 and 0.087 for fvi-midpoint on the test problem: κ is 9–18×
/// below them).
inline constexpr double kHistoryBudgetShare = 0.1;
inline constexpr double kHistoryBudgetDiscretisation = 1e-2;

/// c_H(β): the history error per unit λ_max(M⁻¹R)·ε·h^{−β}·max|x̃|. The mean error of the fitted
/// tail seen by a smooth x̃, max_k |Ŝ_k − S_k| / (ε max|x̃|), measured (bench/history_budget_probe,
/// x̃ = cos t − 1, N = 10^6, ε = 1e-6 and 1e-8, the larger taken) at β = 0.3, 0.5, 0.75, 1.25, 1.5,
/// 1.8, interpolated linearly in log c_H between them and held constant beyond; on the test
/// problem (ω = 1) the trajectory's own constant is 2.2e-6–2.4e-6 at β = 1.5 (this gives 2.4e-6)
/// and 3.4e-4 at β = 0.5 (this gives 5.9e-4).
double history_error_constant(double beta);

/// The ε a run uses and how it was chosen (recorded in Solution and summary.json).
struct HistoryBudget {
  double tolerance = kAutoHistoryCeiling;  ///< ε passed to the fast history
  /// The budget's ε before clamping (equal to tolerance for a user value).
  double requested = kAutoHistoryCeiling;
  bool automatic = true;  ///< chosen by the budget (IntegratorOptions::history_tolerance = auto)
  /// The budget asked for less than the fit can deliver (requested < kMinHistoryTolerance): the
  /// history may then limit the accuracy of the run.
  bool limited = false;
};

/// The ε a stepper passes to its fast history: the number in `options`, or for
/// kAutoHistoryTolerance — which the Integrator replaces by history_budget() before it constructs
/// the stepper — kUnbudgetedHistoryTolerance (a stepper built directly, SchemeInfo::make_stepper).
double stepper_history_tolerance(const IntegratorOptions& options);

/// The budget for `problem` run by a scheme of order `order` (Method::declared_order for the
/// model); `user_tolerance` is IntegratorOptions::history_tolerance: a number is honoured exactly,
/// kAutoHistoryTolerance (0) asks for the budget, clamped to [kMinHistoryTolerance, `ceiling`]
/// (SchemeInfo::history_budget_ceiling). Undamped and integer-order problems have no fast history
/// and get the ceiling.
HistoryBudget history_budget(const InitialValueProblem& problem, int order, double user_tolerance,
                             double ceiling = kAutoHistoryCeiling);

}  // namespace fracvi
