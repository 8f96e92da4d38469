// The fast history's accuracy budget (fracvi/schemes/history_budget.hpp,
// docs/theory/fast_history.md §10) on the problem: the Caputo fractional oscillator
// y'' + 0.5 D^{3/2}y + y = 0, y(0) = 1, y'(0) = 0 on [0, 20], against the published exact
// y(20) = −0.061964539893443569 (Garrappa 2018; checked against the Laplace inversion of
// tests/support in published_numbers_test). With the former fixed ε = 1e-10 fvi-gl stalled near
// N = 2.6·10^7 and the second-order schemes near N = 2.5·10^5; with "auto" the error keeps its
// declared order. The 10^8-step runs are recorded in docs/theory/fast_history.md §10 (too long
// for the suite); here the trend to N = 10^7 (fvi-gl) and 8·10^5 (fvi-midpoint).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "../support/test_problems.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {
namespace {

constexpr double kExact = test::kCaputoOscillatorExact;
using test::caputo_oscillator;

Solution run(const std::string& scheme, std::size_t steps, double tolerance,
             HistoryKind kind = HistoryKind::kFast, double damping = 0.5) {
  IntegratorOptions o;
  o.history = kind;
  o.history_tolerance = tolerance;
  o.mirror = false;
  o.diagnostics = false;
  o.save_every = steps;
  InitialValueProblem problem = caputo_oscillator(steps);
  problem.model.damping = Eigen::MatrixXd::Constant(1, 1, damping);
  Solution sol = integrate(problem, *parse_method(scheme), o);
  EXPECT_TRUE(sol.ok()) << sol.message;
  return sol;
}

double final_x(const Solution& s) {
  return s.x(s.x.rows() - 1, 0);
}

// Least-squares slope of log(error) against log(N), negated: the observed order. Every point
// counts (no plateau dropping): a stall is exactly what these tests must see.
double observed_order(const std::vector<double>& n, const std::vector<double>& error) {
  const auto count = static_cast<double>(n.size());
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < n.size(); ++i) {
    mx += std::log(n[i]) / count;
    my += std::log(error[i]) / count;
  }
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < n.size(); ++i) {
    sxy += (std::log(n[i]) - mx) * (std::log(error[i]) - my);
    sxx += (std::log(n[i]) - mx) * (std::log(n[i]) - mx);
  }
  return -sxy / sxx;
}

struct Sweep {
  std::vector<double> n, x, error, tolerance;
  std::vector<bool> limited;  // Solution::history_limited: ε at its floor, short of the budget
  std::string table;
};

Sweep sweep(const std::string& scheme, const std::vector<std::size_t>& steps, double tolerance) {
  Sweep s;
  for (const std::size_t n : steps) {
    const Solution sol = run(scheme, n, tolerance);
    s.n.push_back(static_cast<double>(n));
    s.x.push_back(final_x(sol));
    s.error.push_back(std::abs(s.x.back() - kExact));
    s.tolerance.push_back(sol.history_tolerance);
    s.limited.push_back(sol.history_limited);
    char row[160];
    std::snprintf(row, sizeof row, "  %s N = %9zu  error %.4e  eps %.2e (%s%s)\n", scheme.c_str(),
                  n, s.error.back(), sol.history_tolerance,
                  sol.history_tolerance_auto ? "auto" : "user",
                  sol.history_limited ? ", limited" : "");
    s.table += row;
  }
  return s;
}

TEST(HistoryBudget, UserValueIsHonouredExactlyAndRecorded) {
  const HistoryBudget user = history_budget(caputo_oscillator(100'000'000), 1, 3e-9);
  EXPECT_EQ(user.tolerance, 3e-9);
  EXPECT_FALSE(user.automatic);
  EXPECT_FALSE(user.limited);
  const Solution sol = run("fvi-gl", 8192, 3e-9);
  EXPECT_EQ(sol.history, "fast");
  EXPECT_EQ(sol.history_tolerance, 3e-9);
  EXPECT_FALSE(sol.history_tolerance_auto);
  // No fast history, nothing recorded.
  const Solution direct = run("fvi-gl", 100, kAutoHistoryTolerance, HistoryKind::kDirect);
  EXPECT_TRUE(std::isnan(direct.history_tolerance));
}

TEST(HistoryBudget, AutoFollowsTheModel) {
  // ε = φ κ h^{p+β} / (c_H λ_ref max(1, (λ/λ_ref)²)), clamped to [1e-13, the ceiling] (λ =
  // λ_ref = 0.5 here).
  const auto expected = [](std::size_t n, int p) {
    const double h = 20.0 / static_cast<double>(n);
    return kHistoryBudgetShare * kHistoryBudgetDiscretisation /
           (history_error_constant(1.5) * 0.5) * std::pow(h, p + 1.5);
  };
  // The measured constants (history_budget.hpp) at their nodes, interpolated between them, held
  // beyond.
  EXPECT_EQ(history_error_constant(1.5), 2.4e-6);
  EXPECT_EQ(history_error_constant(0.5), 5.9e-4);
  EXPECT_EQ(history_error_constant(0.1), 4.8e-4);
  EXPECT_EQ(history_error_constant(1.9), 2.2e-7);
  EXPECT_LT(history_error_constant(1.0), 4.3e-5);
  EXPECT_GT(history_error_constant(1.0), 3.3e-6);
  for (const std::size_t n : {std::size_t{10'000'000}, std::size_t{20'000'000}}) {
    const HistoryBudget b = history_budget(caputo_oscillator(n), 1, kAutoHistoryTolerance);
    EXPECT_TRUE(b.automatic);
    EXPECT_NEAR(b.tolerance, expected(n, 1), 1e-12 * expected(n, 1)) << n;
    EXPECT_FALSE(b.limited);
  }
  const HistoryBudget second = history_budget(caputo_oscillator(400'000), 2, kAutoHistoryTolerance);
  EXPECT_NEAR(second.tolerance, expected(400'000, 2), 1e-12 * expected(400'000, 2));
  // Short runs get the ceiling (by default the former fixed 1e-10; kMeasuredHistoryCeiling for the
  // schemes whose error κ was measured against); very long ones hit the fit's floor.
  EXPECT_EQ(history_budget(caputo_oscillator(10'000), 1, kAutoHistoryTolerance).tolerance,
            kAutoHistoryCeiling);
  const HistoryBudget loose =
      history_budget(caputo_oscillator(10'000), 1, kAutoHistoryTolerance, kMeasuredHistoryCeiling);
  EXPECT_NEAR(loose.requested, expected(10'000, 1), 1e-12 * expected(10'000, 1));
  EXPECT_GT(loose.requested, kMeasuredHistoryCeiling);
  EXPECT_EQ(loose.tolerance, kMeasuredHistoryCeiling);
  const HistoryBudget floor =
      history_budget(caputo_oscillator(1'000'000'000), 1, kAutoHistoryTolerance);
  EXPECT_EQ(floor.tolerance, kMinHistoryTolerance);
  EXPECT_TRUE(floor.limited);
  // Stronger damping, tighter ε: the history error is a force error R h^{−β} δS, and the damped
  // solution's own error shrinks (λ = 5 = 10 λ_ref: 1/100).
  InitialValueProblem strong = caputo_oscillator(1'000'000);
  strong.model.damping = Eigen::MatrixXd::Constant(1, 1, 5.0);
  EXPECT_NEAR(history_budget(strong, 1, kAutoHistoryTolerance).tolerance,
              expected(1'000'000, 1) / 100, 1e-12 * expected(1'000'000, 1));
  // Weaker damping than λ_ref does not loosen ε: the damping's part of the discretisation error
  // falls with λ like the history's error.
  InitialValueProblem weak = caputo_oscillator(10'000'000);
  weak.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.001);
  EXPECT_NEAR(history_budget(weak, 1, kAutoHistoryTolerance).tolerance, expected(10'000'000, 1),
              1e-12 * expected(10'000'000, 1));
  // Nothing to budget without a fractional memory.
  InitialValueProblem viscous = caputo_oscillator(10'000'000);
  viscous.model.alpha = 0.5;
  EXPECT_EQ(history_budget(viscous, 2, kAutoHistoryTolerance).tolerance, kAutoHistoryCeiling);
}

// fvi-gl (order 1) to N = 10^7 with "auto": about 20 s in Release on the shared 2-core VM
// (labelled "long" in tests/CMakeLists.txt).
TEST(HistoryBudget, FviGlKeepsOrderOneToTenMillionSteps) {
  const Sweep s = sweep("fvi-gl", {1'250'000, 2'500'000, 5'000'000, 10'000'000}, 0.0);
  const double order = observed_order(s.n, s.error);
  std::printf("%sobserved order %.4f\n", s.table.c_str(), order);
  EXPECT_NEAR(order, 1.0, 0.02) << s.table;
  // ε tightens with N and is below the former default at 10^7.
  EXPECT_LT(s.tolerance.back(), 1e-11) << s.table;
  // The history's own share at N = 10^7: against the tightest fit, at most a tenth of the error
  // (the budget's φ; the model predicts 0.6 % because its κ is 18× below the measured constant).
  const double tight = final_x(run("fvi-gl", 10'000'000, kMinHistoryTolerance));
  const double share = std::abs(s.x.back() - tight) / s.error.back();
  std::printf("history share at N = 1e7: %.2e\n", share);
  EXPECT_LT(share, kHistoryBudgetShare);
}

// fvi-midpoint (order 2): the former default stalled from N ≈ 2.5·10^5 (bench/RESULTS.md); the
// budget keeps order 2 to 4·10^5 (errors 1.4e-8 … 2.3e-10), the points where it reached its ε.
// At 8·10^5 it needs an ε below the fit's floor 1e-13 (history_limited): the error still falls,
// but the fit's own round-off error shows and differs between machines — the same build gave
// 4.89e-11 (2026-11-26) and 3.82e-11 (2026-12-01, another CPU), against 5.8e-11 extrapolated at
// order 2 from 4·10^5 — so that point is not in the order fit (with it: 2.021 and 2.089). The
// history's share is measured at N = 4·10^5, where the budget's ε (7e-13) differs from the
// tightest fit (1e-13); the former ε = 1e-10 is the negative control: there the history is more
// than the budget's tenth.
TEST(HistoryBudget, MidpointKeepsOrderTwo) {
  const std::vector<std::size_t> steps = {50'000, 100'000, 200'000, 400'000, 800'000};
  const Sweep s = sweep("fvi-midpoint", steps, 0.0);
  constexpr std::size_t kReached = 4;  // the points whose ε the budget reached
  for (std::size_t i = 0; i < steps.size(); ++i) {
    EXPECT_EQ(s.limited[i], i >= kReached) << s.table;
  }
  const std::vector<double> reached_n(s.n.begin(), s.n.begin() + kReached);
  const std::vector<double> error(s.error.begin(), s.error.begin() + kReached);
  const double order = observed_order(reached_n, error);
  std::printf("%sobserved order %.4f over N <= 4e5\n", s.table.c_str(), order);
  EXPECT_NEAR(order, 2.0, 0.05) << s.table;
  EXPECT_LT(s.error[kReached], s.error[kReached - 1] / 2.0) << "the limited point still falls";
  const std::size_t n = steps[3];
  ASSERT_GT(s.tolerance[3], 2.0 * kMinHistoryTolerance) << s.table;
  const double tight = final_x(run("fvi-midpoint", n, kMinHistoryTolerance));
  const double share = std::abs(s.x[3] - tight) / s.error[3];
  const double old_share = std::abs(final_x(run("fvi-midpoint", n, 1e-10)) - tight) / s.error[3];
  std::printf("history share at N = 4e5: auto %.2e, eps = 1e-10 %.2e\n", share, old_share);
  EXPECT_LT(share, kHistoryBudgetShare);
  EXPECT_GT(old_share, kHistoryBudgetShare);
}

// Fast against direct where the direct sum can run (N = 2^15: 1e9 multiply-adds): the history's
// contribution is far below the discretisation error.
TEST(HistoryBudget, FastAgreesWithDirect) {
  for (const char* scheme : {"fvi-gl", "fvi-midpoint"}) {
    const std::size_t n = 32768;
    const Solution fast = run(scheme, n, 0.0, HistoryKind::kFast);
    const Solution direct = run(scheme, n, 0.0, HistoryKind::kDirect);
    const double gap = std::abs(final_x(fast) - final_x(direct));
    const double error = std::abs(final_x(direct) - kExact);
    std::printf("%s N = %zu: |fast - direct| %.2e, error %.2e, eps %.2e\n", scheme, n, gap, error,
                fast.history_tolerance);
    EXPECT_TRUE(fast.history_tolerance_auto);
    EXPECT_LT(gap, kHistoryBudgetShare * error) << scheme;
  }
}

// The damping away from the λ_ref = 0.5 the constants were measured at, where the budget's model
// without the λ_ref terms put ε ∝ 1/λ: for a weak damping that loosened ε (to the ceiling) while
// the damping's error shrank with λ; for a strong one the damped solution's error shrank. Each case
// at the N where that mattered: the history's share of the error (the run with the tightest fit as
// reference, the error from Richardson's estimate against 2N) below the budget's φ with "auto",
// above it with the ε of that model (the negative control, measured 0.73 and 0.16).
TEST(HistoryBudget, TheShareHoldsForWeakAndStrongDamping) {
  struct Case {
    const char* scheme;
    int order;
    double damping;
    std::size_t n;
  };
  for (const Case& c :
       {Case{"fvi-gl", 1, 0.001, 1'000'000}, Case{"fvi-midpoint", 2, 5.0, 10'000}}) {
    const auto x = [&](std::size_t n, double tolerance) {
      return final_x(run(c.scheme, n, tolerance, HistoryKind::kFast, c.damping));
    };
    const double tight = x(c.n, kMinHistoryTolerance);
    const double error = std::abs(tight - x(2 * c.n, kMinHistoryTolerance)) *
                         std::ldexp(1.0, c.order) / (std::ldexp(1.0, c.order) - 1.0);
    const Solution automatic = run(c.scheme, c.n, 0.0, HistoryKind::kFast, c.damping);
    const double share = std::abs(final_x(automatic) - tight) / error;
    const double h = 20.0 / static_cast<double>(c.n);
    const double inverse_lambda_rule =
        std::min(kMeasuredHistoryCeiling, kHistoryBudgetShare * kHistoryBudgetDiscretisation *
                                              std::pow(h, c.order + 1.5) /
                                              (history_error_constant(1.5) * c.damping));
    const double old_share = std::abs(x(c.n, inverse_lambda_rule) - tight) / error;
    std::printf(
        "%s, lambda = %g, N = %zu: error %.2e, history share %.2e (eps %.2e); with "
        "eps = %.2e (1/lambda) %.2e\n",
        c.scheme, c.damping, c.n, error, share, automatic.history_tolerance, inverse_lambda_rule,
        old_share);
    EXPECT_LT(share, kHistoryBudgetShare) << c.scheme;
    EXPECT_GT(old_share, kHistoryBudgetShare) << c.scheme;
  }
}

}  // namespace
}  // namespace fracvi
