// Test 8: the energy balance E_k + W_k − E_0 behaves as documented (solution.hpp,
// docs/theory/start_step.md §4):
//  * exactly zero (round-off) for a quadratic, time-independent U — for any α, R, f, convention;
//  * O(h²) on a fixed interval otherwise (midpoint-quadrature defect of U, O(h³) per step),
//    measured as a log–log slope; also with an explicitly time-dependent U.
// Negative control: the plain trapezoidal damping work without the (h²/8)FᵀM⁻¹F end terms is
// not exact.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "../support/test_problems.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/autodiff_potential.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

// The problem of every case is test::balance_problem (test_problems.hpp, shared with the scheme
// suite): quadratic time-independent U, forcing, damping; Caputo with x0, v0 ≠ 0 or RL with x0 = 0.
// Round-off: test::balance_tolerance, N ε (max|E| + max|W|) (integrate_test_support.hpp, shared
// with the scheme suite); measured values are printed (≈ 1e-14 … 1e-12).
using test::balance_tolerance;

struct ExactCase {
  double alpha;
  Convention convention;
  const char* label;
};

class ExactBalance : public ::testing::TestWithParam<ExactCase> {};

TEST_P(ExactBalance, QuadraticTimeIndependentPotential) {
  const ExactCase c = GetParam();
  for (const std::size_t n : {50ul, 400ul, 3200ul}) {
    IntegratorOptions opts;
    opts.mirror = false;
    const Solution sol = integrate(test::balance_problem(c.alpha, c.convention, n), fvi_gl(), opts);
    ASSERT_TRUE(sol.ok()) << sol.message;
    std::printf("  %s, N = %4zu: max |E + W - E0| = %.3e (tol %.3e; W_N = %.3f)\n", c.label, n,
                sol.max_balance_error, balance_tolerance(sol),
                sol.dissipated(static_cast<Eigen::Index>(n)));
    EXPECT_LE(sol.max_balance_error, balance_tolerance(sol));
  }
}

INSTANTIATE_TEST_SUITE_P(
    Alphas, ExactBalance,
    ::testing::Values(ExactCase{0.5, Convention::kCaputo, "alpha 0.5"},
                      ExactCase{0.3, Convention::kCaputo, "alpha 0.3 Caputo"},
                      ExactCase{0.75, Convention::kCaputo, "alpha 0.75 Caputo"},
                      ExactCase{1.0, Convention::kCaputo, "alpha 1 Caputo"},
                      ExactCase{0.0, Convention::kCaputo, "alpha 0"},
                      ExactCase{0.75, Convention::kRiemannLiouville, "alpha 0.75 RL, x0 = 0"}));

// Negative control (α = 1/2, where F_k = R(x_k − x_{k−1})/h, F_0 = R v_0 are known in closed form):
// without the end terms (h²/8)(F_kᵀM⁻¹F_k − F_0ᵀM⁻¹F_0) the balance is off by O(h²).
TEST(ExactBalanceControl, TrapezoidalWorkWithoutEndTermsIsNotExact) {
  std::vector<double> hs, errs;
  double scale = 0.0;  // max |E| + max |W|: the round-off scale of the balance
  for (const std::size_t n : {400ul, 800ul, 1600ul, 3200ul}) {
    const InitialValueProblem p = test::balance_problem(0.5, Convention::kCaputo, n);
    IntegratorOptions opts;
    opts.mirror = false;
    const Solution sol = integrate(p, fvi_gl(), opts);
    ASSERT_TRUE(sol.ok());
    const double h = p.step_size();
    const Eigen::MatrixXd R = p.model.damping.to_dense();
    Eigen::VectorXd f(2);
    double w = 0.0, worst = 0.0;
    Eigen::VectorXd force_prev = R * p.v0;
    for (std::size_t k = 0; k < n; ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      const Eigen::VectorXd dx = (sol.x.row(i + 1) - sol.x.row(i)).transpose();
      const Eigen::VectorXd force = R * dx / h;
      w += 0.5 * h * (force_prev.dot(sol.v.row(i)) + force.dot(sol.v.row(i + 1)));
      p.model.forcing(p.time(static_cast<double>(k) + 0.5), f);
      w -= f.dot(dx);
      worst = std::max(worst, std::abs(sol.energy(i + 1) + w - sol.energy(0)));
      force_prev = force;
    }
    hs.push_back(h);
    errs.push_back(worst);
    std::printf("  N = %4zu: trapezoidal-only balance error %.3e (documented W: %.3e)\n", n, worst,
                sol.max_balance_error);
    EXPECT_GT(worst, 1e3 * balance_tolerance(sol));
    scale =
        std::max(scale, sol.energy.cwiseAbs().maxCoeff() + sol.dissipated.cwiseAbs().maxCoeff());
  }
  const test::OrderFit fit = test::fit_order(hs, errs, {.floor = test::round_off_floor(scale)});
  const double slope = fit.slope;
  std::printf("  its order: %.3f\n", slope);
  EXPECT_NEAR(slope, 2.0, 0.1) << fit.table();
}

// Nonlinear potentials: balance = Σ midpoint-quadrature defects = O(h²) on [0, T].
struct Duffing2 {
  template <class T>
  T operator()(const Eigen::Matrix<T, 2, 1>& x, T t) const {
    using std::cos;
    // Time-dependent stiffness: U = ½ k(t)(x0² + x1²) + ¼ x0⁴ + ½(x1 − x0)²,  k(t) = 2 + cos t.
    const T k = T(2.0) + cos(t);
    return T(0.5) * k * (x(0) * x(0) + x(1) * x(1)) + T(0.25) * x(0) * x(0) * x(0) * x(0) +
           T(0.5) * (x(1) - x(0)) * (x(1) - x(0));
  }
};

void expect_second_order_balance(const std::shared_ptr<const Potential>& potential, double alpha,
                                 const char* label) {
  std::vector<double> hs, errs;
  double scale = 0.0;  // max |E| + max |W|: the round-off scale of the balance
  for (const std::size_t n : {200ul, 400ul, 800ul, 1600ul, 3200ul}) {
    InitialValueProblem p = test::balance_problem(alpha, Convention::kCaputo, n);
    p.model.potential = potential;
    IntegratorOptions opts;
    opts.mirror = false;
    const Solution sol = integrate(p, fvi_gl(), opts);
    ASSERT_TRUE(sol.ok()) << sol.message;
    hs.push_back(p.step_size());
    errs.push_back(sol.max_balance_error);
    scale =
        std::max(scale, sol.energy.cwiseAbs().maxCoeff() + sol.dissipated.cwiseAbs().maxCoeff());
  }
  const test::OrderFit fit = test::fit_order(hs, errs, {.floor = test::round_off_floor(scale)});
  const double slope = fit.slope;
  std::printf("  %s: max balance error %.3e (h = %.2e) … %.3e (h = %.2e), order %.3f\n", label,
              errs.front(), hs.front(), errs.back(), hs.back(), slope);
  // Measured slopes 1.99–2.00; the tolerance allows for the next term of the defect expansion.
  EXPECT_NEAR(slope, 2.0, 0.05) << fit.table();
}

TEST(NonlinearBalance, SecondOrderPendulaAlphaHalf) {
  expect_second_order_balance(
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0), 0.5,
      "pendula, alpha 0.5");
}

TEST(NonlinearBalance, SecondOrderPendulaAlpha075) {
  expect_second_order_balance(
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0), 0.75,
      "pendula, alpha 0.75");
}

TEST(NonlinearBalance, SecondOrderTimeDependentPotential) {
  expect_second_order_balance(make_autodiff_potential<2>(Duffing2{}), 0.5,
                              "time-dependent Duffing (autodiff), alpha 0.5");
}

// Control for the time-dependence bookkeeping: declaring the same potential time-independent drops
// the Σ[U(x̄, t_{k+1}) − U(x̄, t_k)] work, and the balance error becomes O(1).
TEST(NonlinearBalance, UndeclaredTimeDependenceBreaksTheBalance) {
  InitialValueProblem p = test::balance_problem(0.5, Convention::kCaputo, 800);
  AutodiffPotentialOptions wrong;
  wrong.time_dependent = false;
  p.model.potential = make_autodiff_potential<2>(Duffing2{}, 2, wrong);
  IntegratorOptions opts;
  opts.mirror = false;
  const Solution sol = integrate(p, fvi_gl(), opts);
  ASSERT_TRUE(sol.ok());
  std::printf("  time dependence not declared: max balance error %.3e\n", sol.max_balance_error);
  EXPECT_GT(sol.max_balance_error, 1e-2);
}

}  // namespace
}  // namespace fracvi
