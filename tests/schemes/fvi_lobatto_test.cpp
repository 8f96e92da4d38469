// Scheme-specific tests of fvi-lobatto2/3/4 (issue 11; docs/theory/fvi_lobatto.md), beyond the
// method-parameterised suite (tests/schemes/scheme_suite_test.cpp):
//
//   1. Energy account O(h^{2s−2}), not exact (§6): the order of max_n |E_n + W_n − E_0| on the
//      published damped 2-D oscillator (2α = 1), on a Caputo fractional oscillator (2α = 0.5), and
//      with forcing and a time-dependent U (the work of f and the ∂_tU term enter W), with
//      negative controls (the account without W, and a time-dependent U declared
//      time-independent, do not converge).
//   2. Stability thresholds where the bound is sharp (§8.2), hand-stepped through the Stepper:
//      undamped κ* = 4, 8, 30 (0.98 κ* bounded, 1.02 κ* blown up); the measured damping bound
//      ρ* for 2α = 0.5 (and 0.9, 0.25) at 0.9 ρ* / 1.1 ρ*; the registry's bound between the table
//      points (0.97 of it bounded); the issue's grid (2α = 1, 1.5 always bounded; 2α = 0.5 bounded
//      where the registry admits it, blown up where it refuses); 0.999 of the registry's damping
//      bound stays bounded over 40000 steps (it did not before the 3 % margin, see the test).
//   3. The sparse and the dense stage solver give the same trajectories on a d = 200 chain.
//   4. Riemann–Liouville data (the exact moments of the x0 load), and 2α = 1.5 with v0 ≠ 0,
//      against the Laplace-inversion reference: observed orders.
//   5. method.split = "series" (§13): orders with and without against the Laplace inversion, the
//      mirror and the energy account with it, and its refusals.
//   6. The same with a power-law forcing given as formulas (§13.5): the issue's Bagley–Torvik
//      problems exact to round-off, with nonzero data orders with and without against the Laplace
//      inversion, mirror, energy account and the refusals of other forces.
//
// Every test prints its measured numbers (and stores the main ones with RecordProperty).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <boost/math/special_functions/gamma.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "../integrate/integrate_test_support.hpp"
#include "../support/linear_oscillator_reference.hpp"
#include "../support/order_fit.hpp"
#include "../support/stepper_growth.hpp"
#include "../support/test_problems.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "fracvi/schemes/stepper.hpp"

namespace fracvi {
namespace {

/// "1.234e-15" for RecordProperty.
std::string sci(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4e", value);
  return buf;
}

const SchemeInfo& lobatto(int s) {
  const SchemeInfo* info = find_scheme("fvi-lobatto" + std::to_string(s));
  if (info == nullptr)
    throw std::logic_error("fvi-lobatto" + std::to_string(s) + " not registered");
  return *info;
}

/// "RL 2a = 0.6, x0 = 1" → "RL_2a_06_x0_1" (a RecordProperty key).
std::string test_key(const std::string& label) {
  std::string key;
  for (const char c : label) {
    if (std::isalnum(static_cast<unsigned char>(c)) != 0) {
      key += c;
    } else if (!key.empty() && key.back() != '_') {
      key += '_';
    }
  }
  return key;
}

std::string scheme_name(int s) {
  return "fvi-lobatto" + std::to_string(s);
}

// =============================================================================================
// 1. Energy account.

/// U(x, t) = ½ (1 + 0.4 sin 1.1t) xᵀKx (time-dependent, quadratic in x). `declare_time_dependent`
/// false makes it lie about that: the negative control (the stepper then books no ∂_tU work).
class PulsingSpring final : public Potential {
 public:
  PulsingSpring(Eigen::MatrixXd stiffness, bool declare_time_dependent)
      : k_(std::move(stiffness)), declared_(declare_time_dependent) {}
  [[nodiscard]] Eigen::Index dimension() const override { return k_.rows(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    return 0.5 * factor(t) * x.dot(k_ * x);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g.noalias() = factor(t) * (k_ * x);
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>&, double t,
               Eigen::Ref<Eigen::MatrixXd> h) const override {
    h = factor(t) * k_;
  }
  [[nodiscard]] bool is_time_dependent() const override { return declared_; }

 private:
  static double factor(double t) { return 1.0 + 0.4 * std::sin(1.1 * t); }
  Eigen::MatrixXd k_;
  bool declared_;
};

using test::published_oscillator_2d;

/// x'' + r D^β x + k x = 0 (scalar, Caputo unless told), x0, v0, on [0, t_end].
InitialValueProblem scalar_oscillator(double beta, double r, double k, double x0, double v0,
                                      double t_end, std::size_t steps,
                                      Convention convention = Convention::kCaputo) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, r);
  p.model.alpha = 0.5 * beta;
  p.model.convention = convention;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Constant(1, 1, k));
  p.x0 = Eigen::VectorXd::Constant(1, x0);
  p.v0 = Eigen::VectorXd::Constant(1, v0);
  p.t_end = t_end;
  p.steps = steps;
  return p;
}

/// The coupled d = 2 system of the integrate tests (non-diagonal M, R, K), forced with
/// f = (0.3 sin 2t, −0.2 cos t), with the pulsing spring U = ½(1 + 0.4 sin 1.1t) xᵀKx or the
/// constant one; damping order β (R = 0 when !damped), Caputo, on [0, 10].
InitialValueProblem forced_system(double beta, bool damped, bool forced, bool pulsing,
                                  bool declare_time_dependent, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = test::pendula_mass();
  p.model.damping = damped ? test::pendula_damping() : Eigen::MatrixXd::Zero(2, 2);
  p.model.alpha = 0.5 * beta;
  p.model.convention = Convention::kCaputo;
  const Eigen::MatrixXd k{{3.0, -1.0}, {-1.0, 2.0}};
  if (pulsing) {
    p.model.potential = std::make_shared<const PulsingSpring>(k, declare_time_dependent);
  } else {
    p.model.potential = make_quadratic_potential(k);
  }
  if (forced) {
    p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
      f(0) = 0.3 * std::sin(2.0 * t);
      f(1) = -0.2 * std::cos(t);
    };
  }
  p.x0 = Eigen::VectorXd{{1.0, -0.5}};
  p.v0 = Eigen::VectorXd{{0.2, 0.7}};
  p.t_end = 10.0;
  p.steps = steps;
  return p;
}

struct BalanceRun {
  double balance = 0.0;       ///< max_n |E_n + W_n − E_0|
  double energy_drift = 0.0;  ///< max_n |E_n − E_0| (the account without W)
  double energy_scale = 0.0;  ///< max_n |E_n|
};

BalanceRun balance_run(const SchemeInfo& info, const InitialValueProblem& p) {
  IntegratorOptions options;
  options.mirror = false;
  options.newton.relative_tolerance = 1e-14;
  const Solution sol = integrate(p, Method(info), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  BalanceRun r;
  r.balance = sol.max_balance_error;
  r.energy_drift = (sol.energy.array() - sol.energy(0)).abs().maxCoeff();
  r.energy_scale = sol.energy.cwiseAbs().maxCoeff();
  return r;
}

/// The balance error over `steps` and its fitted order (printed).
struct BalanceStudy {
  test::OrderFit balance, drift;
};

BalanceStudy balance_study(const SchemeInfo& info, const std::string& label,
                           const std::function<InitialValueProblem(std::size_t)>& make,
                           const std::vector<std::size_t>& steps) {
  std::vector<double> hs, balance, drift;
  double scale = 0.0;
  for (const std::size_t n : steps) {
    const InitialValueProblem p = make(n);
    const BalanceRun r = balance_run(info, p);
    hs.push_back(p.step_size());
    balance.push_back(r.balance);
    drift.push_back(r.energy_drift);
    scale = std::max(scale, r.energy_scale);
  }
  BalanceStudy study;
  study.balance = test::fit_order(hs, balance, {.floor = test::round_off_floor(scale)});
  study.drift = test::fit_order(hs, drift, {.floor = test::round_off_floor(scale)});
  std::printf("%s",
              study.balance.table(std::string(info.name) + ", " + label + ": max|E_n + W_n - E_0|")
                  .c_str());
  return study;
}

// (a) The published damped 2-D oscillator, 2α = 1 (the RKCQ is exact and local: the solution is
// smooth). Prototype (fvi_lobatto.md §6): orders 2.0, 4.0, 6.0 over N = 32 … 256. Required: the
// fitted order ≥ 2s − 2 − 0.2 (the same margin the suite gives, doubled: the balance is a maximum
// over a long run of an oscillating error, whose local orders wobble by ±0.1 in the prototype).
// Negative control: max|E_n − E_0| (the account without W) does not converge at all (the damping
// removes an O(1) part of the energy).
TEST(LobattoEnergyAccount, DampedOscillator2DOrder2sMinus2) {
  for (const int s : {2, 3, 4}) {
    // s = 4 reaches 1e-12 at N = 256 (the round-off floor ≈ 1e4 ε max|E|): start coarser.
    const std::vector<std::size_t> steps = s == 4 ? std::vector<std::size_t>{16, 32, 64, 128, 256}
                                                  : std::vector<std::size_t>{32, 64, 128, 256};
    const BalanceStudy st =
        balance_study(lobatto(s), "damped 2-D oscillator (2a = 1)", published_oscillator_2d, steps);
    ::testing::Test::RecordProperty("balance_order_oscillator_s" + std::to_string(s),
                                    std::to_string(st.balance.slope));
    EXPECT_TRUE(st.balance.valid) << st.balance.table();
    EXPECT_GE(st.balance.slope, 2 * s - 2 - 0.2) << st.balance.table();
    // Not exact: the balance error is far above round-off (exact_balance = false in the registry).
    EXPECT_GT(st.balance.error.back(), 1e3 * test::round_off_floor(1.0, 1.0)) << s;
    EXPECT_FALSE(lobatto(s).exact_balance);
    // Control: without W the "balance" stays O(1).
    std::printf("    control: max|E_n - E_0| = %.3e … %.3e (no W: does not converge)\n",
                st.drift.error.front(), st.drift.error.back());
    EXPECT_GT(st.drift.error.back(), 0.1);
  }
}

// (b) x'' + 0.5 D^{0.5} x + x = 0, x0 = 1, v0 = 0, T = 20 (Caputo). Prototype (§6): orders 1.95,
// 4.03, 5.3–5.5 over N = 40 … 320. With Caputo data and 0 < 2α < 1 the Taylor split leaves
// x̃ = O(t²) with non-smooth t^{2+…} terms and the prescribed force R D^β P = 0 (v0 = 0), so the
// energy account keeps 2s − 2 for s = 2, 3, while for s = 4 the prototype's 5.3–5.5 is below 6
// (the CQ's saturation on the non-smooth x̃ near t0 shows in the stage damping forces).
// Expectations: s = 2: ≥ 1.8, s = 3: ≥ 3.8 (2s − 2 − 0.2); s = 4: ≥ 5.1 (the prototype's lowest
// local order 5.31 minus 0.2).
TEST(LobattoEnergyAccount, FractionalOscillatorCaputoHalfOrder) {
  const std::vector<std::size_t> steps{40, 80, 160, 320};
  for (const int s : {2, 3, 4}) {
    const BalanceStudy st = balance_study(
        lobatto(s), "x'' + 0.5 D^0.5 x + x = 0 (Caputo x0 = 1, T = 20)",
        [](std::size_t n) { return scalar_oscillator(0.5, 0.5, 1.0, 1.0, 0.0, 20.0, n); }, steps);
    ::testing::Test::RecordProperty("balance_order_fractional_s" + std::to_string(s),
                                    std::to_string(st.balance.slope));
    const double expected = s == 4 ? 5.1 : 2 * s - 2 - 0.2;
    EXPECT_TRUE(st.balance.valid) << st.balance.table();
    EXPECT_GE(st.balance.slope, expected) << st.balance.table();
    std::printf("    control: max|E_n - E_0| = %.3e … %.3e (no W)\n", st.drift.error.front(),
                st.drift.error.back());
    EXPECT_GT(st.drift.error.back(), 0.1);
  }
}

// (c) Forcing and a time-dependent U: the work of f (−h Σ b_a f(t_a)·V_a) and of ∂_tU
// (−h Σ b_a ∂_tU(X_a, t_a), a central difference in t) enter W. Three problems on the coupled
// d = 2 system (non-diagonal M, K), all smooth (R = 0, or 2α = 1): forcing alone (R = 0),
// pulsing U alone (R = 0), and both with damping 2α = 1. Expected: the order 2s − 2 − 0.2 as in
// (a). Controls: (i) forcing alone without W, max|E_n − E_0|, is O(0.1) — so the convergent balance
// is W booking f's work; (ii) the pulsing spring declared time-independent: the stepper books no
// ∂_tU work and the balance stays O(0.1) at every N.
TEST(LobattoEnergyAccount, ForcingAndTimeDependentPotentialEnterTheWork) {
  struct Case {
    const char* label;
    bool damped, forced, pulsing;
  };
  for (const int s : {2, 3, 4}) {
    const std::vector<std::size_t> steps = s == 4 ? std::vector<std::size_t>{20, 40, 80, 160}
                                                  : std::vector<std::size_t>{40, 80, 160, 320};
    for (const Case c : {Case{"forcing, R = 0", false, true, false},
                         Case{"U(x, t) = (1 + 0.4 sin 1.1t) xKx/2, R = 0", false, false, true},
                         Case{"forcing + U(x, t) + R, 2a = 1", true, true, true}}) {
      const BalanceStudy st = balance_study(
          lobatto(s), c.label,
          [c](std::size_t n) { return forced_system(1.0, c.damped, c.forced, c.pulsing, true, n); },
          steps);
      EXPECT_TRUE(st.balance.valid) << c.label << "\n" << st.balance.table();
      EXPECT_GE(st.balance.slope, 2 * s - 2 - 0.2) << c.label << "\n" << st.balance.table();
      std::printf("    control: max|E_n - E_0| = %.3e … %.3e (no W)\n", st.drift.error.front(),
                  st.drift.error.back());
      EXPECT_GT(st.drift.error.back(), 1e-2) << c.label;
    }
    // Control (ii): ∂_tU not booked — the balance then does not converge (N = 40 → 320).
    const BalanceRun lie_coarse =
        balance_run(lobatto(s), forced_system(1.0, false, false, true, false, 40));
    const BalanceRun lie =
        balance_run(lobatto(s), forced_system(1.0, false, false, true, false, 320));
    const BalanceRun truth =
        balance_run(lobatto(s), forced_system(1.0, false, false, true, true, 320));
    std::printf(
        "  %s: max|E + W - E0| = %.3e at N = 320 with the dU/dt work; with U declared "
        "time-independent (control) %.3e at N = 40, %.3e at N = 320\n",
        scheme_name(s).c_str(), truth.balance, lie_coarse.balance, lie.balance);
    EXPECT_GT(lie.balance, 1e-2);
    EXPECT_GT(lie.balance, 0.5 * lie_coarse.balance);
    EXPECT_GT(lie.balance, 100.0 * truth.balance);
  }
}

// =============================================================================================
// 2. Stability thresholds.

// Bounded / blown up, as in the suite (scheme_suite_test.cpp (g)): bounded is max_k |x_k| ≤ 10
// |x_0| (the exact solutions are damped relaxations below |x_0| plus velocity transients); blown up
// is a growth of at least 1e3 (or a non-finite state), the growing root of the characteristic
// function at 2–10 % past the threshold multiplies |x| by a fixed factor per step.
constexpr double kBoundedFactor = 10.0;
constexpr double kBlowUpFactor = 1e3;

using test::stepper_growth;

/// m x'' + r D^β x + k x = 0 with m = 1, x0 = 1, v0 = 0 (Caputo), step h, `steps` steps.
InitialValueProblem test_problem(double beta, double r, double k, double h, std::size_t steps) {
  InitialValueProblem p =
      scalar_oscillator(beta, r, k, 1.0, 0.0, h * static_cast<double>(steps), steps);
  if (r == 0.0) p.model.damping = Eigen::MatrixXd::Zero(1, 1);
  return p;
}

// (a) Undamped (R = 0): the Lobatto IIIA–IIIB method, κ = k h² < κ* = 4, 8, 30 (s = 2, 3, 4;
// fvi_lobatto.md §8.1: a root crosses the unit circle at κ*). M = K = 1, h = √(f κ*).
TEST(LobattoStability, UndampedThresholdIsSharp) {
  constexpr std::size_t kSteps = 3000;
  for (const int s : {2, 3, 4}) {
    const double kappa_star = s == 2 ? 4.0 : (s == 3 ? 8.0 : 30.0);
    const InitialValueProblem below =
        test_problem(1.0, 0.0, 1.0, std::sqrt(0.98 * kappa_star), kSteps);
    const InitialValueProblem above =
        test_problem(1.0, 0.0, 1.0, std::sqrt(1.02 * kappa_star), kSteps);
    const StabilityBound bound_below = lobatto(s).stability(below);
    const StabilityBound bound_above = lobatto(s).stability(above);
    const double growth_below = stepper_growth(lobatto(s), below);
    const double growth_above = stepper_growth(lobatto(s), above);
    std::printf(
        "  %s, R = 0, kappa* = %g: h* = %.6f (registry); max|x_k|/|x_0| over %zu steps: %.4e at "
        "0.98 kappa*, %.4e at 1.02 kappa*\n",
        scheme_name(s).c_str(), kappa_star, bound_below.largest_step, kSteps, growth_below,
        growth_above);
    ::testing::Test::RecordProperty("undamped_growth_s" + std::to_string(s) + "_below",
                                    sci(growth_below));
    ::testing::Test::RecordProperty("undamped_growth_s" + std::to_string(s) + "_above",
                                    sci(growth_above));
    EXPECT_NEAR(bound_below.largest_step, std::sqrt(kappa_star), 1e-9 * std::sqrt(kappa_star));
    EXPECT_TRUE(bound_below.sharp);
    EXPECT_TRUE(bound_below.stable);
    EXPECT_FALSE(bound_above.stable);
    EXPECT_LE(growth_below, kBoundedFactor) << s;
    EXPECT_GE(growth_above, kBlowUpFactor) << s;
  }
}

// (b) 0 < 2α < 1: the measured damping bound ρ* on ρ = (R/M) h^{2−2α} at κ = 1e-4 (h = 0.01,
// M = K = 1), the table of fvi_lobatto.md §8.2 (first column, κ = 1e-4): at 0.9 ρ* bounded, at
// 1.1 ρ* blown up (3000 steps), and the registry says stable below, not stable above.
TEST(LobattoStability, FractionalDampingThresholdAtTablePoints) {
  constexpr std::size_t kSteps = 3000;
  constexpr double kH = 0.01;
  struct Point {
    int s;
    double beta, rho_star;
  };
  for (const Point pt : {Point{2, 0.5, 4.92}, Point{3, 0.5, 19.5}, Point{4, 0.5, 46.5},
                         Point{2, 0.9, 18.1}, Point{4, 0.25, 55.0}}) {
    const double h_power = std::pow(kH, 2.0 - pt.beta);
    const InitialValueProblem below =
        test_problem(pt.beta, 0.9 * pt.rho_star / h_power, 1.0, kH, kSteps);
    const InitialValueProblem above =
        test_problem(pt.beta, 1.1 * pt.rho_star / h_power, 1.0, kH, kSteps);
    const StabilityBound bound_below = lobatto(pt.s).stability(below);
    const StabilityBound bound_above = lobatto(pt.s).stability(above);
    const double growth_below = stepper_growth(lobatto(pt.s), below);
    const double growth_above = stepper_growth(lobatto(pt.s), above);
    std::printf(
        "  %s, 2a = %.2f, rho* = %.3g (R/M = %.4g at 0.9, %.4g at 1.1; kappa = 1e-4): "
        "max|x_k|/|x_0| = %.4e at 0.9 rho*, %.4e at 1.1 rho*; registry: %s / %s\n",
        scheme_name(pt.s).c_str(), pt.beta, pt.rho_star, 0.9 * pt.rho_star / h_power,
        1.1 * pt.rho_star / h_power, growth_below, growth_above,
        bound_below.stable ? "stable" : "refused", bound_above.stable ? "stable" : "refused");
    char key[48];
    std::snprintf(key, sizeof key, "damping_growth_s%d_2a_%02d", pt.s,
                  static_cast<int>(std::lround(100.0 * pt.beta)));
    ::testing::Test::RecordProperty(std::string(key) + "_below", sci(growth_below));
    ::testing::Test::RecordProperty(std::string(key) + "_above", sci(growth_above));
    EXPECT_TRUE(bound_below.stable) << bound_below.rule;
    EXPECT_FALSE(bound_above.stable) << bound_above.rule;
    EXPECT_LE(growth_below, kBoundedFactor);
    EXPECT_GE(growth_above, kBlowUpFactor);
  }
}

// (b') Between the table points the registry uses the smaller neighbouring ρ* (and the β = 0.9
// value above 0.9): that must still be a sufficient bound. For 2α = β between and beyond the table
// points, κ = 1e-4 (h = 0.01, M = K = 1), R at 0.97 of the largest R the registry admits (found by
// bisection on stability(problem).stable) is hand-stepped for 3000 steps and must stay bounded.
// Printed for information: the growth at 1.1 and 2 times that R (the bound is not sharp there, so
// nothing is required of them). 3000 steps see only modes growing by ≥ 1.0023 per step (1e3 in
// 3000 steps): a coarse check, 3 % below the bound; the test below (disabled: it fails) looks
// 0.1 % below it with 40000 steps.
TEST(LobattoStability, RegistryDampingBoundHoldsBetweenTablePoints) {
  constexpr std::size_t kSteps = 3000;
  constexpr double kH = 0.01;
  for (const int s : {2, 3, 4}) {
    for (const double beta : {0.05, 0.15, 0.2, 0.3, 0.4, 0.6, 0.7, 0.8, 0.85, 0.95, 0.99}) {
      // Largest admitted R at this h: bisection in log R.
      double lo = 1e-3, hi = 1e9;
      for (int it = 0; it < 100; ++it) {
        const double mid = std::sqrt(lo * hi);
        (lobatto(s).stability(test_problem(beta, mid, 1.0, kH, kSteps)).stable ? lo : hi) = mid;
      }
      const double r_star = lo;
      const double rho_star = r_star * std::pow(kH, 2.0 - beta);
      const double below =
          stepper_growth(lobatto(s), test_problem(beta, 0.97 * r_star, 1.0, kH, kSteps));
      const double above =
          stepper_growth(lobatto(s), test_problem(beta, 1.1 * r_star, 1.0, kH, kSteps));
      const double far =
          stepper_growth(lobatto(s), test_problem(beta, 2.0 * r_star, 1.0, kH, kSteps));
      std::printf(
          "  %s, 2a = %.2f: registry rho* = %.4g (R/M = %.4g); max|x_k|/|x_0| = %.4e at 0.97, "
          "%.4e at 1.1, %.4e at 2 times the bound\n",
          scheme_name(s).c_str(), beta, rho_star, r_star, below, above, far);
      EXPECT_LE(below, kBoundedFactor) << scheme_name(s) << ", 2a = " << beta;
    }
  }
}

// (b'') The registry's damping bound is sufficient just below it. It was not, before the 3 % margin
// (kDampingBoundMargin in fvi_lobatto.cpp) was added for the reason measured here: damping_bound()
// in src/schemes/fvi_lobatto.cpp holds the prototype's ρ* (fvi_lobatto.md §8.2), found by counting
// the zeros of the characteristic function in |ζ| < 0.995, i.e. only modes growing by ≥ 1/0.995 per
// step; the weakly growing modes just past the true threshold are missed, and the table (and its
// use, ρ*_0 (1 − κ/κ*)) carries no safety margin although StabilityBound::sharp = false promises a
// sufficient condition. Measured by bisection with hand-stepped runs (growth ≥ 1e3 within N steps;
// the estimate decreases with N and converges): M = K = 1, κ = 1e-4, s = 2, 2α = 0.9: threshold
// 0.9920, 0.9840, 0.9819, 0.9814 × 18.1 for N = 1e4, 4e4, 1.6e5, 6.4e5 (true ρ* ≈ 17.76); s = 2, 2α
// = 0.5: 0.9957 × 4.92 (ρ* ≈ 4.899). With N = 40000, as fractions of the registry's bound (κ = 1e-4
// / 0.1 / 1): s = 2, 2α = 0.5: 0.9961 / 0.9960 / 0.9960; s = 3, 2α = 0.5: 0.9989 / ok / ok; s = 4,
// 2α = 0.5: 0.9975 / 0.9994 / ok; s = 2, 2α = 0.9: 0.9840 / 0.9833 / 0.9831; s = 4, 2α = 0.25:
// 0.9994 / ok / ok; s = 2, 2α = 0.25: 0.9976; s = 2, 2α = 0.75: 0.9934; s = 3, 2α = 0.9: 0.9880; s
// = 4, 2α = 0.9: 0.9861 ("ok": the bound lies below the threshold, by 0.1–9 %). E.g. s = 2, 2α =
// 0.5, κ = 0.1 (h = 0.3162, R = 0.999 × 4.797/h^1.5): admitted, max|x_k| = 7.5e80 after 40000
// steps. With the margin the largest admitted ρ is 0.97 × the table, below every measured
// threshold.
TEST(LobattoStability, RegistryDampingBoundIsSufficientJustBelowIt) {
  constexpr std::size_t kSteps = 40000;
  struct Point {
    int s;
    double beta;
  };
  for (const Point pt :
       {Point{2, 0.5}, Point{3, 0.5}, Point{4, 0.5}, Point{2, 0.9}, Point{4, 0.25}}) {
    for (const double kappa : {1e-4, 0.1, 1.0}) {
      const double h = std::sqrt(kappa);
      double lo = 1e-3, hi = 1e12;
      for (int it = 0; it < 100; ++it) {
        const double mid = std::sqrt(lo * hi);
        (lobatto(pt.s).stability(test_problem(pt.beta, mid, 1.0, h, kSteps)).stable ? lo : hi) =
            mid;
      }
      const InitialValueProblem p = test_problem(pt.beta, 0.999 * lo, 1.0, h, kSteps);
      ASSERT_TRUE(lobatto(pt.s).stability(p).stable);
      const double growth = stepper_growth(lobatto(pt.s), p);
      std::printf("  %s, 2a = %.2f, kappa = %g: rho = 0.999 x registry bound = %.5g: growth %.3e\n",
                  scheme_name(pt.s).c_str(), pt.beta, kappa,
                  0.999 * lo * std::pow(h, 2.0 - pt.beta), growth);
      EXPECT_LE(growth, kBoundedFactor)
          << scheme_name(pt.s) << ", 2a = " << pt.beta << ", kappa = " << kappa;
    }
  }
}

// (c) The issue's grid: M = K = 1, x0 = 1, v0 = 0, R/M ∈ {1, 10², 10⁴}, h ∈ {10⁻², 10⁻¹, 1},
// 2000 steps. K = 1 is admissible everywhere (κ = h² ≤ 1 < 0.9 κ* for every s). 2α ∈ {1, 1.5}:
// the registry admits every case and every case stays bounded (fvi_lobatto.md §8.2: no damping
// bound for 1 ≤ 2α < 2). 2α = 0.5 in addition: the cases the registry admits stay bounded, and the
// ones it refuses (printed) are hand-stepped as the negative control and blow up — the refused set
// is the prototype's blown-up set (s = 2: (10², 1), (10⁴, 10⁻²), (10⁴, 10⁻¹), (10⁴, 1); s = 3, 4:
// (10², 1), (10⁴, 10⁻¹), (10⁴, 1)).
TEST(LobattoStability, IssueGridOfDampingAndSteps) {
  constexpr std::size_t kSteps = 2000;
  for (const int s : {2, 3, 4}) {
    double worst = 0.0, least_refused = std::numeric_limits<double>::infinity();
    int admitted = 0, refused = 0;
    for (const double beta : {0.5, 1.0, 1.5}) {
      for (const double r : {1.0, 1e2, 1e4}) {
        for (const double h : {1e-2, 1e-1, 1.0}) {
          const InitialValueProblem p = test_problem(beta, r, 1.0, h, kSteps);
          const StabilityBound bound = lobatto(s).stability(p);
          const double growth = stepper_growth(lobatto(s), p);
          const double rho = r * std::pow(h, 2.0 - beta);
          std::printf(
              "  %s, 2a = %.1f, R/M = %6.0e, h = %5.0e (rho = %9.3e): %-8s max|x_k|/|x_0| = %.4e\n",
              scheme_name(s).c_str(), beta, r, h, rho, bound.stable ? "admitted" : "REFUSED",
              growth);
          if (bound.stable) {
            ++admitted;
            worst = std::max(worst, growth);
            EXPECT_LE(growth, kBoundedFactor)
                << "2a = " << beta << ", R/M = " << r << ", h = " << h;
          } else {
            ++refused;
            least_refused = std::min(least_refused, growth);
            // Only the damping bound of 0 < 2α < 1 can refuse here (κ ≤ 1 < κ*).
            EXPECT_EQ(beta, 0.5) << bound.rule;
            EXPECT_GE(growth, kBlowUpFactor)
                << "refused but bounded: 2a = " << beta << ", R/M = " << r << ", h = " << h;
          }
        }
      }
    }
    std::printf(
        "  %s: %d admitted runs, largest max|x_k|/|x_0| = %.4f; %d refused, smallest growth %.3e\n",
        scheme_name(s).c_str(), admitted, worst, refused, least_refused);
    ::testing::Test::RecordProperty("grid_worst_growth_s" + std::to_string(s), sci(worst));
    EXPECT_EQ(refused, s == 2 ? 4 : 3);
  }
}

// =============================================================================================
// 3. Sparse vs dense stage solver.

/// d masses, M = I (sparse identity), R tridiagonal sparse (0.3 on the diagonal, −0.1 beside:
/// SPD), the fixed-end chain U = Σ ½ r² (+ ¼ r⁴ when fput), damping order β, Caputo, on [0, 0.05
/// N].
InitialValueProblem chain_problem(Eigen::Index d, double beta, bool fput, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = ModelMatrix::identity(d, 1.0);
  std::vector<Eigen::Triplet<double>> triplets;
  for (Eigen::Index i = 0; i < d; ++i) {
    const int ii = static_cast<int>(i);
    triplets.emplace_back(ii, ii, 0.3);
    if (i + 1 < d) {
      triplets.emplace_back(ii, ii + 1, -0.1);
      triplets.emplace_back(ii + 1, ii, -0.1);
    }
  }
  ModelMatrix::Sparse damping(d, d);
  damping.setFromTriplets(triplets.begin(), triplets.end());
  p.model.damping = ModelMatrix(damping);
  p.model.alpha = 0.5 * beta;
  p.model.convention = Convention::kCaputo;
  ChainOptions chain;
  chain.dimension = d;
  chain.stiffness = 1.0;
  chain.quartic = fput ? 1.0 : 0.0;
  p.model.potential = make_chain_potential(chain);
  p.x0.resize(d);
  p.v0.resize(d);
  for (Eigen::Index i = 0; i < d; ++i) {
    const double xi = M_PI * static_cast<double>(i + 1) / static_cast<double>(d + 1);
    p.x0[i] = 0.6 * std::sin(xi) + 0.3 * std::sin(41.0 * xi);  // bonds stretched by up to 0.2
    p.v0[i] = 0.3 * std::sin(2.0 * xi);
  }
  p.t_end = 0.05 * static_cast<double>(steps);
  p.steps = steps;
  return p;
}

Solution chain_run(const SchemeInfo& info, const InitialValueProblem& p, LinearSolver solver) {
  IntegratorOptions options;
  options.mirror = false;
  options.linear_solver = solver;
  options.newton.relative_tolerance = 1e-14;
  Solution sol = integrate(p, Method(info), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  return sol;
}

double relative_difference(const RowMatrixXd& a, const RowMatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// Chain d = 200: (s − 1)d = 400, 600 > 96, so kAuto takes the band LU (M, R stored sparse, the
// chain declares its tridiagonal Hessian: band 3 or 5 with the stages interleaved). kDense,
// kBanded, kSparse and kAuto must give the same positions and velocities to ≤ 1e-12 relative (each
// stops Newton at 1e-14 relative; the factorisations differ only in rounding). Negative control:
// x0 perturbed by 1e-10 relative is seen by the same measure.
//
// Eigen's dense LU runs its blocked products on OpenMP threads (all cores; IntegratorOptions::
// threads does not limit them). On the shared 2-vCPU machine with other jobs running, that
// oversubscription made the dense runs of the FPUT chains (60 factorisations of 400 × 400 or
// 600 × 600 each) take 1.3–8.9 s against 0.3–1.1 s with one thread: this test uses one Eigen thread
// (the trajectories do not depend on it beyond rounding).
TEST(LobattoStageSolver, SparseAndDenseAgreeOnChain) {
  Eigen::setNbThreads(1);
  constexpr Eigen::Index kD = 200;
  constexpr std::size_t kSteps = 20;  // h = 0.05: κ ≈ 4 h² = 0.01, ρ = 0.3 h^{2−β} small
  constexpr double kTolerance = 1e-12;
  for (const int s : {3, 4}) {
    for (const bool fput : {false, true}) {
      for (const double beta : {0.5, 1.5}) {
        const InitialValueProblem p = chain_problem(kD, beta, fput, kSteps);
        const Solution dense = chain_run(lobatto(s), p, LinearSolver::kDense);
        const Solution banded = chain_run(lobatto(s), p, LinearSolver::kBanded);
        const Solution sparse = chain_run(lobatto(s), p, LinearSolver::kSparse);
        const Solution automatic = chain_run(lobatto(s), p, LinearSolver::kAuto);
        ASSERT_TRUE(dense.ok() && banded.ok() && sparse.ok() && automatic.ok());
        const double bx = relative_difference(banded.x, dense.x);
        const double bv = relative_difference(banded.v, dense.v);
        const double dx = relative_difference(sparse.x, dense.x);
        const double dv = relative_difference(sparse.v, dense.v);
        const double ax = relative_difference(automatic.x, dense.x);
        const double av = relative_difference(automatic.v, dense.v);
        std::printf(
            "  %s, %s chain d = %ld, 2a = %.1f: solvers %s/%s/%s/%s; banded vs dense: x %.3e, v "
            "%.3e; sparse vs dense: x %.3e, v %.3e; auto vs dense: x %.3e, v %.3e; Newton/step "
            "%.2f; %.3f s dense, %.3f s banded, %.3f s sparse\n",
            scheme_name(s).c_str(), fput ? "beta-FPUT" : "linear", static_cast<long>(kD), beta,
            dense.linear_solver.c_str(), banded.linear_solver.c_str(), sparse.linear_solver.c_str(),
            automatic.linear_solver.c_str(), bx, bv, dx, dv, ax, av,
            static_cast<double>(sparse.newton_iterations) / static_cast<double>(kSteps),
            dense.wall_time_seconds, banded.wall_time_seconds, sparse.wall_time_seconds);
        EXPECT_EQ(dense.linear_solver, "dense");
        EXPECT_EQ(banded.linear_solver, "banded");
        EXPECT_EQ(sparse.linear_solver, "sparse");
        EXPECT_EQ(automatic.linear_solver, "banded");
        for (const double difference : {bx, bv, dx, dv, ax, av}) EXPECT_LE(difference, kTolerance);
      }
    }
  }
  // Control: a 1e-10 relative change of the data is visible to the measure.
  InitialValueProblem p = chain_problem(kD, 1.5, true, kSteps);
  const Solution base = chain_run(lobatto(3), p, LinearSolver::kSparse);
  p.x0 *= 1.0 + 1e-10;
  const Solution perturbed = chain_run(lobatto(3), p, LinearSolver::kSparse);
  const double control = relative_difference(perturbed.x, base.x);
  std::printf("  control: x0 scaled by 1 + 1e-10: relative difference %.3e\n", control);
  EXPECT_GT(control, 10.0 * kTolerance);
}

// With a diagonal M and R (stored sparse) and no state force, the interval forces are formed in one
// pass over the rows (IntervalKernel, fvi_lobatto.cpp); with the same M and R stored dense, by the
// general path's Eigen expressions. The two must give the same trajectory to round-off (≤ 1e-12
// relative; the one pass contracts products and sums to multiply–adds, and the dense matrices take
// another stage solver): s = 2, 3, 4; linear and β-FPUT chains of 41 uneven masses with a
// pointwise load f; Caputo 2α = 1.5 (X̃ = X − x_0 − τ v_0, no moments of P: the pass without
// loads), Riemann–Liouville 2α = 0.6 (the moments of P's x_0 and v_0: with loads) and no damping;
// 60 steps, the memory's window filled. Control: x_0 scaled by 1 + 1e-10 is seen by the same
// measure.
TEST(LobattoIntervalRows, OnePassAgreesWithTheGeneralPath) {
  Eigen::setNbThreads(1);
  constexpr Eigen::Index kD = 41;
  constexpr double kTolerance = 1e-12;
  struct Case {
    double beta;
    Convention convention;
    double quartic;
  };
  auto problem = [&](const Case& c, bool dense) {
    InitialValueProblem p =
        test::forced_chain(kD, false, 60, 0.5, 3.0, c.convention, 0.5 * c.beta, c.quartic);
    Eigen::VectorXd masses(kD);
    for (Eigen::Index i = 0; i < kD; ++i) masses[i] = p.model.mass.coeff(i, i);
    const Eigen::VectorXd damping = Eigen::VectorXd::Constant(kD, c.beta > 0.0 ? 0.4 : 0.0);
    p.model.mass =
        dense ? ModelMatrix(Eigen::MatrixXd(masses.asDiagonal())) : ModelMatrix::diagonal(masses);
    p.model.damping =
        dense ? ModelMatrix(Eigen::MatrixXd(damping.asDiagonal())) : ModelMatrix::diagonal(damping);
    return p;
  };
  auto run = [](int s, const InitialValueProblem& p) {
    IntegratorOptions options;
    options.mirror = false;
    options.history = HistoryKind::kFast;
    options.newton.relative_tolerance = 1e-14;
    Solution sol = integrate(p, Method(lobatto(s)), options);
    EXPECT_TRUE(sol.ok()) << sol.message;
    return sol;
  };
  for (const int s : {2, 3, 4}) {
    for (const Case c :
         {Case{1.5, Convention::kCaputo, 0.0}, Case{1.5, Convention::kCaputo, 2.0},
          Case{0.6, Convention::kRiemannLiouville, 0.0}, Case{0.0, Convention::kCaputo, 2.0}}) {
      const Solution one_pass = run(s, problem(c, false));
      const Solution general = run(s, problem(c, true));
      ASSERT_TRUE(one_pass.ok() && general.ok());
      const double dx = relative_difference(one_pass.x, general.x);
      const double dv = relative_difference(one_pass.v, general.v);
      std::printf("  %s, 2a = %.1f %s, quartic %.0f: one pass vs general x %.3e, v %.3e\n",
                  scheme_name(s).c_str(), c.beta,
                  c.convention == Convention::kCaputo ? "Caputo" : "RL", c.quartic, dx, dv);
      EXPECT_LE(dx, kTolerance);
      EXPECT_LE(dv, kTolerance);
    }
  }
  InitialValueProblem p = problem({1.5, Convention::kCaputo, 2.0}, false);
  const Solution base = run(3, p);
  p.x0 *= 1.0 + 1e-10;
  const Solution perturbed = run(3, p);
  EXPECT_GT(relative_difference(perturbed.x, base.x), 10.0 * kTolerance);
}

// On the chain of examples/fractional_chain.toml with quartic springs and h = 0.5, band and sparse
// LU must give the same trajectory (≤ 1e-13 relative), the same Newton iterations (±1 %), and a
// round-off mirror error (max |y_k − x_{N−k}|; measured 1.4e-15 and 8.4e-15 for s = 3, 4). Until
// 2026-12-02 dgbtrf interchanged rows here (U's band one wider than ku), and this test was the
// band solve's widened U inside a scheme (negative control then: U cut to ku made the trajectories
// differ by 2.5e-12 and Newton take 3200 and 2800 iterations instead of 1200). Since StageMatrix
// numbers the stages in the order whose elimination needs no interchange, the band here has none
// (checked); the widened U's solve is covered by BandLu.SolvesLikeDgbtrsAndDenseLu (three shapes
// with interchanges).
TEST(LobattoStageSolver, BandAndSparseLuAgreeOnTheQuarticChain) {
  for (const int s : {3, 4}) {
    // examples/fractional_chain.toml with d = 200 and the quartic springs, h = 0.5.
    constexpr Eigen::Index kD = 200;
    InitialValueProblem p;
    p.model.mass = ModelMatrix::identity(kD, 1.0);
    p.model.damping = ModelMatrix::identity(kD, 0.05);
    p.model.alpha = 0.75;
    p.model.convention = Convention::kCaputo;
    ChainOptions chain;
    chain.dimension = kD;
    chain.onsite = 0.1;
    chain.quartic = 1.0;
    p.model.potential = make_chain_potential(chain);
    p.x0 = Eigen::VectorXd::LinSpaced(kD, 0.0, kD - 1.0).unaryExpr([](double i) {
      return std::exp(-std::pow((i - 0.5 * kD) / 15.0, 2));
    });
    p.v0 = Eigen::VectorXd::Zero(kD);
    p.t_end = 200.0;
    p.steps = 400;
    IntegratorOptions options;
    options.mirror = true;
    options.linear_solver = LinearSolver::kBanded;
    const Solution banded = integrate(p, Method(lobatto(s)), options);
    options.linear_solver = LinearSolver::kSparse;
    const Solution sparse = integrate(p, Method(lobatto(s)), options);
    ASSERT_TRUE(banded.ok() && sparse.ok()) << banded.message << sparse.message;
    std::printf(
        "  %s: mirror error band %.3e, sparse %.3e; trajectories %.3e relative; Newton %zu / %zu, "
        "factorisations %zu / %zu\n",
        scheme_name(s).c_str(), banded.mirror_error, sparse.mirror_error,
        relative_difference(banded.x, sparse.x), banded.newton_iterations, sparse.newton_iterations,
        banded.jacobian_factorizations, sparse.jacobian_factorizations);
    EXPECT_LE(banded.mirror_error, 1e-13);
    EXPECT_LE(sparse.mirror_error, 1e-13);
    EXPECT_LE(relative_difference(banded.x, sparse.x), 1e-13);
    EXPECT_NEAR(static_cast<double>(banded.newton_iterations),
                static_cast<double>(sparse.newton_iterations),
                0.01 * static_cast<double>(sparse.newton_iterations));
  }
}

// A periodic chain's Hessian couples x_0 and x_{d−1}: bandwidth d − 1, so kAuto takes the sparse
// LU; a forced band LU still solves it (its band spans the matrix) and agrees, and one whose band
// storage would exceed 2 GB is refused by name.
TEST(LobattoStageSolver, PeriodicChainTakesSparseLuAndRefusesAHugeBand) {
  auto periodic = [](Eigen::Index d, std::size_t steps) {
    InitialValueProblem p = chain_problem(d, 1.5, true, steps);
    p.model.potential = test::periodic_fput_chain(d);
    return p;
  };
  const InitialValueProblem p = periodic(100, 10);
  const Solution automatic = chain_run(lobatto(3), p, LinearSolver::kAuto);
  const Solution banded = chain_run(lobatto(3), p, LinearSolver::kBanded);
  EXPECT_EQ(automatic.linear_solver, "sparse");
  EXPECT_EQ(banded.linear_solver, "banded");
  EXPECT_LE(relative_difference(banded.x, automatic.x), 1e-12);
  IntegratorOptions options;
  options.linear_solver = LinearSolver::kBanded;
  try {
    Integrator integ(periodic(6000, 10), Method(lobatto(3)), options);
    ADD_FAILURE() << "a 6000-mass periodic chain's band LU was accepted";
  } catch (const ValidationError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("method.linear_solver = \"banded\""), std::string::npos) << message;
    EXPECT_NE(message.find(" GB ("), std::string::npos) << message;
  }
  options.linear_solver = LinearSolver::kAuto;
  EXPECT_EQ(Integrator(periodic(6000, 10), Method(lobatto(3)), options).linear_solver(),
            LinearSolver::kSparse);
}

// =============================================================================================
// 4. Riemann–Liouville data and 2α = 1.5 with v0 ≠ 0, against the Laplace-inversion reference.

struct ReferenceStudy {
  std::string label;
  std::function<InitialValueProblem(std::size_t)> make;
  test::LinearOscillator reference;
  /// Required fitted orders for s = 2, 3, 4: at the sample times, and over all nodes.
  std::array<double, 3> at_samples{}, over_nodes{};
  std::size_t samples = 4;
  double t_end = 2.0;
};

/// N = 16 … 256 for s = 2, 8 … 128 for s = 3, 4 … 64 for s = 4 (the higher orders reach the
/// round-off floor ≈ 1e4 ε max|x| within four halvings from N = 16).
std::vector<std::size_t> reference_steps(int s) {
  const std::size_t first = s == 2 ? 16 : (s == 3 ? 8 : 4);
  std::vector<std::size_t> steps;
  for (std::size_t n = first; n <= 16 * first; n *= 2) steps.push_back(n);
  return steps;
}

/// The fitted orders of max over the sample times t_end j/samples of |x_k − x(t_k)| and of max
/// over all grid nodes (printed). The grids nest (N doubles), so the reference is evaluated once on
/// the finest grid.
struct ReferenceOrders {
  test::OrderFit samples, nodes;
};

ReferenceOrders reference_orders(const SchemeInfo& info, int s, const ReferenceStudy& study) {
  const test::LaplaceInversion inversion(study.reference);
  const std::vector<std::size_t> steps = reference_steps(s);
  const std::size_t finest = steps.back();
  std::vector<double> exact(finest + 1);
  double scale = 0.0;
  for (std::size_t k = 0; k <= finest; ++k) {
    exact[k] = inversion(study.t_end * static_cast<double>(k) / static_cast<double>(finest))(0);
    scale = std::max(scale, std::abs(exact[k]));
  }
  std::vector<double> hs, sample_errors, node_errors;
  IntegratorOptions options;
  options.mirror = false;
  for (const std::size_t n : steps) {
    const InitialValueProblem p = study.make(n);
    const Solution sol = integrate(p, Method(info), options);
    EXPECT_TRUE(sol.ok()) << sol.message;
    double sample_error = 0.0, node_error = 0.0;
    for (std::size_t k = 0; k <= n; ++k) {
      const double e = std::abs(sol.x(static_cast<Eigen::Index>(k), 0) - exact[k * (finest / n)]);
      node_error = std::max(node_error, e);
      if (k % (n / study.samples) == 0) sample_error = std::max(sample_error, e);
    }
    hs.push_back(p.step_size());
    sample_errors.push_back(sample_error);
    node_errors.push_back(node_error);
  }
  ReferenceOrders orders;
  orders.samples = test::fit_order(hs, sample_errors, {.floor = test::round_off_floor(scale)});
  orders.nodes = test::fit_order(hs, node_errors, {.floor = test::round_off_floor(scale)});
  const std::string label = std::string(info.name) + ", " + study.label;
  std::printf("%s", orders.samples.table(label + ": max|x err| at t = 0.5, 1, 1.5, 2").c_str());
  std::printf("%s", orders.nodes.table(label + ": max|x err| over all nodes").c_str());
  return orders;
}

// x'' + 0.5 D^β x + x = 0 on [0, 2] against the Laplace inversion (poles + branch cut,
// tests/support/linear_oscillator_reference.hpp; it supports RL for β < 1, and RL with β = 1.5,
// x0 = 0 as the Caputo problem with the power-law forcing −R v0 τ^{−0.5}/Γ(0.5)). Two measures: the
// error at t = 0.5, 1, 1.5, 2 (the global error) and the maximum over all nodes (which sees the
// local error near t0, where the data are not smooth). N = 16·2^k (s = 2), 8·2^k (s = 3),
// 4·2^k (s = 4), k = 0 … 4.
//
// Measured when this was written (fitted slope; asymptotic local order from a run to N = 128·N_0):
//
//   case                        | at t = 0.5 … 2: s = 2, 3, 4 | over all nodes: s = 2, 3, 4
//   RL 2α = 0.6, x0 = 1, v0 = ½ | 2.05, 3.43, 4.44           | 2.05, 2.92 (→ 2.84), 2.95 (→ 2.79)
//   Caputo 2α = 0.6, same data  | 2.02, 4.03, 5.52           | 2.02, 3.79 (→ 3.43), 3.66 (→ 3.42)
//   Caputo 2α = 1.5, same data  | 1.97, 3.54, 5.14 (→ 4.64)  | 1.96, 2.61 (→ 2.46), 2.46 (→ 2.47)
//   RL 2α = 1.5, x0 = 0, v0 = ½ | 1.98, 3.55, 5.20 (→ 4.72)  | 1.99, 1.90 (→ 2.00), 1.99 (→ 2.02)
//
// (the all-nodes orders of the Caputo cases agree with fvi_lobatto.md §7.4: 3.5 for 2α = 0.6,
// 2.1–2.4 for 2α = 1.5). The declared order for fractional 2α is 2 (no correction weights): every
// case meets it. Required: s = 2: 1.85 (declared − 0.15); s = 3, 4: the asymptotic local order
// minus ≈ 0.2, rounded down (2.6 where the local orders still drift down from 2.9 towards 2.8;
// 1.8 for RL 2α = 1.5, s = 3, whose coarsest point is pre-asymptotic: local orders 1.71, 1.90,
// 1.97, 2.00), so that a lost order (≥ 0.4 for these exponents) fails.
TEST(LobattoRiemannLiouville, AgainstLaplaceInversion) {
  constexpr double kR = 0.5, kX0 = 1.0, kV0 = 0.5, kT = 2.0;
  std::vector<ReferenceStudy> studies;
  // RL, 2α = 0.6, x0 ≠ 0: the load x0 τ^{−0.6}/Γ(0.4) enters by its exact Galerkin moments.
  studies.push_back({"RL 2a = 0.6, x0 = 1, v0 = 0.5",
                     [=](std::size_t n) {
                       return scalar_oscillator(0.6, kR, 1.0, kX0, kV0, kT, n,
                                                Convention::kRiemannLiouville);
                     },
                     test::LinearOscillator::scalar(1.0, kR, 1.0, 0.6, kX0, kV0,
                                                    test::ReferenceConvention::kRiemannLiouville),
                     {1.85, 3.2, 4.2},
                     {1.85, 2.6, 2.6}});
  // The same data, Caputo (for comparison: fvi_lobatto.md §7.4 measured 2.0 / 3.5 / 3.5).
  studies.push_back(
      {"Caputo 2a = 0.6, x0 = 1, v0 = 0.5",
       [=](std::size_t n) { return scalar_oscillator(0.6, kR, 1.0, kX0, kV0, kT, n); },
       test::LinearOscillator::scalar(1.0, kR, 1.0, 0.6, kX0, kV0),
       {1.85, 3.8, 5.2},
       {1.85, 3.2, 3.2}});
  // Caputo 2α = 1.5, x0, v0 ≠ 0.
  studies.push_back(
      {"Caputo 2a = 1.5, x0 = 1, v0 = 0.5",
       [=](std::size_t n) { return scalar_oscillator(1.5, kR, 1.0, kX0, kV0, kT, n); },
       test::LinearOscillator::scalar(1.0, kR, 1.0, 1.5, kX0, kV0),
       {1.85, 3.3, 4.3},
       {1.85, 2.2, 2.2}});
  // RL 2α = 1.5 with x0 = 0, v0 ≠ 0: D^β_RL x = D^β_C x + v0 τ^{1−β}/Γ(2−β), i.e. the Caputo
  // problem with the forcing −R v0 τ^{−0.5}/Γ(0.5) (the reference accepts power-law forcings but
  // not the RL convention for β ≥ 1).
  {
    test::LinearOscillator ref = test::LinearOscillator::scalar(1.0, kR, 1.0, 1.5, 0.0, kV0);
    ref.forcing.push_back(
        {Eigen::VectorXd::Constant(1, -kR * kV0 / boost::math::tgamma(0.5)), -0.5});
    studies.push_back({"RL 2a = 1.5, x0 = 0, v0 = 0.5",
                       [=](std::size_t n) {
                         return scalar_oscillator(1.5, kR, 1.0, 0.0, kV0, kT, n,
                                                  Convention::kRiemannLiouville);
                       },
                       ref,
                       {1.85, 3.3, 4.3},
                       {1.85, 1.8, 1.8}});
  }
  for (const ReferenceStudy& study : studies) {
    for (const int s : {2, 3, 4}) {
      const ReferenceOrders orders = reference_orders(lobatto(s), s, study);
      const auto i = static_cast<std::size_t>(s - 2);
      std::printf("    required: >= %.2f at the sample times, >= %.2f over all nodes\n",
                  study.at_samples[i], study.over_nodes[i]);
      ::testing::Test::RecordProperty("order_" + test_key(study.label) + "_s" + std::to_string(s),
                                      sci(orders.samples.slope) + " / " + sci(orders.nodes.slope));
      EXPECT_TRUE(orders.samples.valid) << study.label << "\n" << orders.samples.table();
      EXPECT_GE(orders.samples.slope, study.at_samples[i]) << study.label << "\n"
                                                           << orders.samples.table();
      EXPECT_TRUE(orders.nodes.valid) << study.label << "\n" << orders.nodes.table();
      EXPECT_GE(orders.nodes.slope, study.over_nodes[i]) << study.label << "\n"
                                                         << orders.nodes.table();
    }
  }
  // Controls: RL and Caputo differ at O(0.1) here (the convention is honoured), and RL with
  // 2α > 1 and x0 ≠ 0 is refused by validation.
  const InitialValueProblem rl =
      scalar_oscillator(0.6, kR, 1.0, kX0, kV0, kT, 256, Convention::kRiemannLiouville);
  const InitialValueProblem caputo = scalar_oscillator(0.6, kR, 1.0, kX0, kV0, kT, 256);
  IntegratorOptions options;
  options.mirror = false;
  const double convention_gap = (integrate(rl, Method(lobatto(3)), options).x -
                                 integrate(caputo, Method(lobatto(3)), options).x)
                                    .cwiseAbs()
                                    .maxCoeff();
  std::printf("  control: max|x_RL - x_Caputo| = %.3e (2a = 0.6, fvi-lobatto3, N = 256)\n",
              convention_gap);
  EXPECT_GT(convention_gap, 1e-2);
  EXPECT_THROW((void)integrate(
                   scalar_oscillator(1.5, kR, 1.0, kX0, kV0, kT, 64, Convention::kRiemannLiouville),
                   Method(lobatto(3)), options),
               ValidationError);
}

// =============================================================================================
// 5. method.split = "series" (fvi_lobatto.md §13): the fractional Taylor terms of a linear
//    problem join P in the memory's split. Orders with and without against the Laplace inversion.

struct SplitStudy {
  std::string label;
  std::function<InitialValueProblem(std::size_t)> make;
  test::LinearOscillator reference;
  /// Required orders with the series, s = 2, 3, 4 (at the sample times and over all nodes).
  std::array<double, 3> required{};
  double t_end = 2.0;
  /// How the forcing enters without the series (with it, the remainder's is always by moments).
  ForcingLoad load = ForcingLoad::kPointwise;
};

struct SplitOrders {
  test::OrderFit samples, nodes;
};

/// Max over the 8 sample times t_end j/8 and over all nodes of max_i |x_{k,i} − x_i(t_k)|, with the
/// given split, fitted over `steps` (nested grids: the reference once on the finest).
SplitOrders split_orders(int s, const SplitStudy& study, TaylorSplit split,
                         const std::vector<std::size_t>& steps) {
  const test::LaplaceInversion inversion(study.reference);
  const std::size_t finest = steps.back();
  std::vector<Eigen::VectorXd> exact(finest + 1);
  double scale = 0.0;
  for (std::size_t k = 0; k <= finest; ++k) {
    exact[k] = inversion(study.t_end * static_cast<double>(k) / static_cast<double>(finest));
    scale = std::max(scale, exact[k].cwiseAbs().maxCoeff());
  }
  std::vector<double> hs, sample_errors, node_errors;
  IntegratorOptions options;
  options.mirror = false;
  options.split = split;
  options.load = study.load;
  for (const std::size_t n : steps) {
    const InitialValueProblem p = study.make(n);
    const Solution sol = integrate(p, Method(lobatto(s)), options);
    EXPECT_TRUE(sol.ok()) << sol.message;
    double sample_error = 0.0, node_error = 0.0;
    for (std::size_t k = 0; k <= n; ++k) {
      const double e =
          (sol.x.row(static_cast<Eigen::Index>(k)).transpose() - exact[k * (finest / n)])
              .cwiseAbs()
              .maxCoeff();
      node_error = std::max(node_error, e);
      if (k % (n / 8) == 0) sample_error = std::max(sample_error, e);
    }
    hs.push_back(p.step_size());
    sample_errors.push_back(sample_error);
    node_errors.push_back(node_error);
  }
  SplitOrders orders;
  orders.samples = test::fit_order(hs, sample_errors, {.floor = test::round_off_floor(scale)});
  orders.nodes = test::fit_order(hs, node_errors, {.floor = test::round_off_floor(scale)});
  const std::string label =
      scheme_name(s) + ", " + study.label + ", split = " + std::string(to_string(split));
  std::printf("%s", orders.samples.table(label + ": at the 8 sample times").c_str());
  std::printf("%s", orders.nodes.table(label + ": over all nodes").c_str());
  return orders;
}

/// For each study and s = 2, 3, 4: the orders without (split = "taylor") and with the series,
/// N = 8 … 128 (s = 2: 16 … 256); with the series at least the study's required order at the
/// sample times and over all nodes, and over all nodes not below the order without (less 0.15).
void expect_split_orders(const std::vector<SplitStudy>& studies) {
  for (const SplitStudy& study : studies) {
    for (const int s : {2, 3, 4}) {
      const std::vector<std::size_t> steps = s == 2 ? std::vector<std::size_t>{16, 32, 64, 128, 256}
                                                    : std::vector<std::size_t>{8, 16, 32, 64, 128};
      const SplitOrders without = split_orders(s, study, TaylorSplit::kTaylor, steps);
      const SplitOrders with = split_orders(s, study, TaylorSplit::kSeries, steps);
      std::printf("  %s, %s: samples %.2f -> %.2f, all nodes %.2f -> %.2f\n",
                  scheme_name(s).c_str(), study.label.c_str(), without.samples.slope,
                  with.samples.slope, without.nodes.slope, with.nodes.slope);
      ::testing::Test::RecordProperty("order_" + test_key(study.label) + "_s" + std::to_string(s),
                                      sci(without.samples.slope) + " / " +
                                          sci(without.nodes.slope) + " -> " +
                                          sci(with.samples.slope) + " / " + sci(with.nodes.slope));
      ASSERT_TRUE(without.nodes.valid && with.nodes.valid && with.samples.valid);
      const double required = study.required[static_cast<std::size_t>(s - 2)];
      std::printf("    required with the series: >= %.2f\n", required);
      EXPECT_GE(with.samples.slope, required) << study.label << with.samples.table();
      EXPECT_GE(with.nodes.slope, required) << study.label << with.nodes.table();
      EXPECT_GE(with.nodes.slope, without.nodes.slope - 0.15) << study.label << with.nodes.table();
    }
  }
}

// Measured when this was written (fitted slopes, at the sample times / over all nodes; N = 8 …
// 128, s = 2: 16 … 256), without → with the series:
//
//   Caputo d = 2, 2α = 1.5:  s = 3 3.69/3.43 → 4.43/4.43,  s = 4 4.86/2.60 → 4.39/4.39
//   Caputo d = 2, 2α = 0.6:  s = 3 4.02/4.02 → 4.00/4.00,  s = 4 5.96/3.70 → 4.29/4.29
//   RL 2α = 0.6, x0 = 0:     s = 3 3.97/3.97 → 3.92/3.92,  s = 4 5.38/3.95 → 5.19/5.19
//   RL 2α = 0.6, x0 = 1:     s = 3 3.31/2.92 → 3.93/3.93,  s = 4 4.65/2.83 → 5.21/5.21
//   (s = 2: 1.99 … 2.05 without and with; v0 = ½ throughout)
//
// Without the series the error over all nodes is the first steps' local error; with it every node
// converges with the order the smooth part allows, min(2s − 2, s + 2 − 2α) for fractional 2α
// (fvi_lobatto.md §13.1: 4.5 at 2α = 1.5, 5.4 at 0.6, measured even for data that vanish to all
// orders at t_0), the sample-time error with it (smooth in time) included. 2α = 0.6, s = 4: the fit
// has 3 points above the round-off floor and its local orders still rise (4.20, 4.38, 4.94, 5.17
// with the two masked points): required 4.1. The sample-time errors with the series are 2–4
// times those without at equal N in the Caputo cases (the same order; §13.3). Required: the
// measured orders less ≈ 0.2, and over all nodes nowhere below the order without it (less 0.15).
TEST(LobattoSeriesSplit, RecoversTheStartUpOrderAgainstLaplaceInversion) {
  std::vector<SplitStudy> studies;
  for (const double beta : {1.5, 0.6}) {
    const test::LinearOscillator ref = test::fractional_oscillator(beta, Convention::kCaputo);
    char label[64];
    std::snprintf(label, sizeof label, "Caputo d = 2, 2a = %.1f", beta);
    studies.push_back({label,
                       [ref](std::size_t n) {
                         return test::oscillator_problem(ref, Convention::kCaputo, n, 2.0);
                       },
                       ref,
                       beta == 1.5 ? std::array<double, 3>{1.85, 3.3, 4.2}
                                   : std::array<double, 3>{1.85, 3.8, 4.1}});
  }
  {
    for (const double x0 : {0.0, 1.0}) {
      const test::LinearOscillator ref = test::LinearOscillator::scalar(
          1.0, 0.5, 1.0, 0.6, x0, 0.5, test::ReferenceConvention::kRiemannLiouville);
      studies.push_back(
          {x0 == 0.0 ? "RL 2a = 0.6, x0 = 0, v0 = 0.5" : "RL 2a = 0.6, x0 = 1, v0 = 0.5",
           [x0](std::size_t n) {
             return scalar_oscillator(0.6, 0.5, 1.0, x0, 0.5, 2.0, n,
                                      Convention::kRiemannLiouville);
           },
           ref,
           {1.85, 3.7, 4.9}});
    }
  }
  expect_split_orders(studies);
}

// The series split keeps the structure (§13.3): the mirror is still exact (the y-equation
// subtracts the same Q at the mirrored times), the energy account converges, and the chain
// (sparse M and R) takes it too. Refused with the field, the value and the rule outside its domain.
TEST(LobattoSeriesSplit, MirrorEnergyAccountAndRefusals) {
  const test::LinearOscillator ref = test::fractional_oscillator(1.5, Convention::kCaputo);
  IntegratorOptions options;
  options.split = TaylorSplit::kSeries;
  for (const int s : {2, 3, 4}) {
    std::vector<double> balance;
    for (const std::size_t n : {32, 64, 128}) {
      const Solution sol = integrate(test::oscillator_problem(ref, Convention::kCaputo, n, 2.0),
                                     Method(lobatto(s)), options);
      ASSERT_TRUE(sol.ok()) << sol.message;
      std::printf("  %s, split = series, N = %zu: mirror error %.3e, max balance error %.3e\n",
                  scheme_name(s).c_str(), n, sol.mirror_error, sol.max_balance_error);
      EXPECT_LE(sol.mirror_error, 1e-12);
      balance.push_back(sol.max_balance_error);
    }
    // O(h^{2s−2}) on smooth solutions, 1.4 … 2.9 with 2α = 1.5 (§6): at least a factor 2 per
    // halving.
    EXPECT_LT(balance[1], 0.5 * balance[0]);
    EXPECT_LT(balance[2], 0.5 * balance[1]);
  }
  {
    const Solution sol =
        integrate(chain_problem(8, 1.5, /*fput=*/false, 40), Method(lobatto(3)), options);
    EXPECT_TRUE(sol.ok()) << sol.message;
    EXPECT_LE(sol.mirror_error, 1e-12);
  }
  auto refusal = [&](const InitialValueProblem& p, const SchemeInfo& info) -> std::string {
    try {
      (void)integrate(p, Method(info), options);
    } catch (const ValidationError& e) {
      return e.what();
    }
    return "(accepted)";
  };
  const InitialValueProblem oscillator =
      test::oscillator_problem(ref, Convention::kCaputo, 64, 2.0);
  const std::string other = refusal(oscillator, *find_scheme("fvi-bdf2"));
  // A force given as a function (not formulas): its power laws cannot be read.
  const std::string forced = refusal(forced_system(1.5, true, true, false, false, 40), lobatto(3));
  const std::string nonlinear = refusal(chain_problem(8, 1.5, /*fput=*/true, 40), lobatto(3));
  const std::string growing =
      refusal(test::oscillator_problem(ref, Convention::kCaputo, 2000, 40.0), lobatto(4));
  for (const std::string* message : {&other, &forced, &nonlinear, &growing})
    std::printf("  refused: %s\n", message->c_str());
  EXPECT_NE(other.find("method.split = \"series\" is not available for method.scheme = "
                       "\"fvi-bdf2\""),
            std::string::npos);
  EXPECT_NE(forced.find("needs the force as formulas in t"), std::string::npos);
  EXPECT_NE(nonlinear.find("is for linear problems"), std::string::npos);
  EXPECT_NE(growing.find("more than 10^3 times the size the data and the forcing give x"),
            std::string::npos);
}

// =============================================================================================
// 6. method.split = "series" with a power-law forcing (fvi_lobatto.md §13.5): the issue's (c)
//    Bagley–Torvik problems, q'' + D^{2α}q + q = f, zero data, the force as formulas (as a
//    problem file gives it), max over all nodes against the exact solution (the published
//    measure).

struct BagleyTorvikCase {
  const char* label;
  double alpha;
  const char* force;        // formula in t − t0
  double (*exact)(double);  // of τ = t − t0
  /// The order over all nodes without the series required by PowerLawForcingBagleyTorvik, s = 2,
  /// 3, 4 (the measured slope less 0.15).
  std::array<double, 3> without{};
};

const std::array<BagleyTorvikCase, 2> kBagleyTorvik{{
    {"D^1/2, q = t^3",
     0.25,
     "t^3 + 6*t + 16/(5*sqrt(pi))*t^2.5",
     [](double tau) { return tau * tau * tau; },
     {1.77, 3.81, 4.25}},
    {"D^3/2, q = t^5/2",
     0.75,
     "15/4*sqrt(t) + 15*sqrt(pi)/8*t + t^(5/2)",
     [](double tau) { return std::pow(tau, 2.5); },
     {1.74, 2.85, 2.86}},
}};

/// The Bagley–Torvik problem on [t0, t0 + span] with `force` (in t) as the model's formulas.
InitialValueProblem bagley_torvik(double alpha, const std::string& force, std::size_t steps,
                                  double t0 = 0.0, double x0 = 0.0, double v0 = 0.0,
                                  double span = 1.0) {
  InitialValueProblem p = scalar_oscillator(2.0 * alpha, 1.0, 1.0, x0, v0, /*t_end=*/1.0, steps);
  ExpressionForces forces = make_expression_forces(1, {force});
  p.model.forcing = std::move(forces.forcing);
  p.model.forcing_formulas = std::move(forces.forcing_formulas);
  p.t0 = t0;
  p.t_end = t0 + span;
  return p;
}

/// Max over all nodes of |q_k − q(t_k)|.
double bagley_torvik_error(const BagleyTorvikCase& c, int s, std::size_t steps, TaylorSplit split,
                           double t0 = 0.0, const std::string& force = "") {
  IntegratorOptions options;
  options.mirror = false;
  options.load = ForcingLoad::kMoments;
  options.split = split;
  const InitialValueProblem p = bagley_torvik(c.alpha, force.empty() ? c.force : force, steps, t0);
  const Solution sol = integrate(p, Method(lobatto(s)), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  double error = 0.0;
  for (Eigen::Index k = 0; k < sol.x.rows(); ++k)
    error = std::max(error, std::abs(sol.x(k, 0) - c.exact(sol.t(k) - t0)));
  return error;
}

// Without the series (split = "taylor", the forcing by its exact moments: the best the scheme does
// without) the first steps cap the order over all nodes (§13.2); with it, S is the exact solution
// (the series of t³ and t^{5/2} terminate: every other term's load cancels in f_w) and the error is
// round-off at every N. Measured when this was written, fitted over N = 8 … 128 (without → the
// largest error with the series over all N):
//
//   problem            | s = 2          | s = 3          | s = 4
//   D^1/2, q = t³      | 1.92 → 0       | 3.96 → 0       | 4.40 (3 points) → 0
//   D^3/2, q = t^{5/2} | 1.89 → 1.1e-16 | 3.00 → 1.1e-16 | 3.01 → 1.1e-16
//
// Required without: the measured slope less 0.15; with: every error ≤ 1e-14 (≈ 45 ε·max|q|), on
// [0, 1] and shifted to [1, 2] with the force written in (t − 1) (the power laws are read in
// t − t0).
TEST(LobattoSeriesSplit, PowerLawForcingBagleyTorvik) {
  const std::vector<std::size_t> steps{8, 16, 32, 64, 128};
  for (const BagleyTorvikCase& c : kBagleyTorvik) {
    for (const int s : {2, 3, 4}) {
      std::vector<double> hs, without, with;
      for (const std::size_t n : steps) {
        hs.push_back(1.0 / static_cast<double>(n));
        without.push_back(bagley_torvik_error(c, s, n, TaylorSplit::kTaylor));
        with.push_back(bagley_torvik_error(c, s, n, TaylorSplit::kSeries));
      }
      const test::OrderFit fit =
          test::fit_order(hs, without, {.floor = test::round_off_floor(1.0)});
      const double worst_with = *std::max_element(with.begin(), with.end());
      std::printf("%s", fit.table(scheme_name(s) + ", " + c.label + ", split = taylor").c_str());
      std::printf("  %s, %s, split = series: max error over N = 8 ... 128: %.3e\n",
                  scheme_name(s).c_str(), c.label, worst_with);
      ::testing::Test::RecordProperty("order_" + test_key(c.label) + "_s" + std::to_string(s),
                                      sci(fit.slope) + " -> max error " + sci(worst_with));
      EXPECT_TRUE(fit.valid) << fit.table();
      EXPECT_GE(fit.slope, c.without[static_cast<std::size_t>(s - 2)]) << fit.table();
      EXPECT_LE(worst_with, 1e-14) << c.label << ", " << scheme_name(s);
    }
  }
  // The origin: the same problem on [1, 2] with the force in t − 1.
  const double shifted = bagley_torvik_error(kBagleyTorvik[0], 3, 16, TaylorSplit::kSeries, 1.0,
                                             "(t - 1)^3 + 6*(t - 1) + 16/(5*sqrt(pi))*(t - 1)^2.5");
  std::printf("  fvi-lobatto3, D^1/2 on [1, 2], force in t - 1, split = series: %.3e\n", shifted);
  EXPECT_LE(shifted, 1e-14);
}

// With nonzero data, x0 = 1, v0 = ½, the series no longer terminates: S holds the terms up to
// τ^{2s−1} and w = x − S the rest. Against the Laplace inversion with the power-law forcing
// (tests/support), on [0, 2] (on [0, 1] fvi-lobatto4 with the series is at the round-off floor
// from N = 16), at the 8 sample times / over all nodes, without (split = "taylor",
// forcing by moments) → with. Measured when this was written (N = 8 … 128, s = 2: 16 … 256):
//
//   problem                | s = 2                 | s = 3                 | s = 4
//   D^1/2 forcing of t³    | 2.00/2.00 → 2.01/2.01 | 3.99/3.99 → 3.95/3.95 | 5.43¹/3.79
//   → 5.51¹/5.50¹ D^3/2 forcing of t^5/2 | 1.99/1.99 → 2.05/2.05 | 3.38/3.03 → 3.16/3.16
//   | 4.90/3.38 → 4.46/4.45
//
// ¹ three points above the round-off floor (local orders 5.44, 5.42; 5.57, 5.44; 5.54, 5.47).
// The series lifts the order over all nodes to the order at the sample times, near the cap
// min(2s − 2, s + 2 − 2α) (4 and 5.5 at 2α = ½; 3.5 and 4.5 at 2α = 3/2); at the sample times
// s = 3, 4 at 2α = 3/2 show a lower fitted slope with the series (the unsplit scheme's sample-time
// slope is pre-asymptotically above the cap, §13.2). Required with the series: the measured orders
// less ≈ 0.2, and over all nodes nowhere below the order without it (less 0.15), as in
// RecoversTheStartUpOrderAgainstLaplaceInversion.
TEST(LobattoSeriesSplit, PowerLawForcingWithDataAgainstLaplaceInversion) {
  constexpr double kX0 = 1.0, kV0 = 0.5;
  std::vector<SplitStudy> studies;
  const std::array<std::vector<test::PowerTerm>, 2> laws{{
      {{Eigen::VectorXd::Constant(1, 1.0), 3.0},
       {Eigen::VectorXd::Constant(1, 6.0), 1.0},
       {Eigen::VectorXd::Constant(1, 16.0 / (5.0 * std::sqrt(M_PI))), 2.5}},
      {{Eigen::VectorXd::Constant(1, 3.75), 0.5},
       {Eigen::VectorXd::Constant(1, 15.0 * std::sqrt(M_PI) / 8.0), 1.0},
       {Eigen::VectorXd::Constant(1, 1.0), 2.5}},
  }};
  const std::array<std::array<double, 3>, 2> required{{{1.85, 3.75, 5.25}, {1.85, 2.95, 4.25}}};
  for (std::size_t i = 0; i < kBagleyTorvik.size(); ++i) {
    const BagleyTorvikCase& c = kBagleyTorvik[i];
    test::LinearOscillator ref =
        test::LinearOscillator::scalar(1.0, 1.0, 1.0, 2.0 * c.alpha, kX0, kV0);
    ref.forcing = laws[i];
    const std::string force = c.force;
    const double alpha = c.alpha;
    SplitStudy study{
        std::string(c.label) + " forcing, x0 = 1, v0 = 0.5",
        [=](std::size_t n) { return bagley_torvik(alpha, force, n, 0.0, kX0, kV0, /*span=*/4.0); },
        ref,
        required[i],
        /*t_end=*/4.0,
        ForcingLoad::kMoments};
    studies.push_back(study);
  }
  expect_split_orders(studies);
}

// The structure with a power-law forcing (§13.3): the mirror is exact and the energy account
// converges (the remainder's, which books f_w), on the data case above. Refused with the field,
// the value and the rule: a force that is not a sum of power laws in t − t0, a negative power, a
// power law around another origin.
TEST(LobattoSeriesSplit, PowerLawForcingMirrorEnergyAccountAndRefusals) {
  IntegratorOptions options;
  options.split = TaylorSplit::kSeries;
  for (const BagleyTorvikCase& c : kBagleyTorvik) {
    for (const int s : {2, 3, 4}) {
      std::vector<double> balance;
      for (const std::size_t n : {16, 32, 64}) {
        const Solution sol = integrate(bagley_torvik(c.alpha, c.force, n, 0.0, 1.0, 0.5),
                                       Method(lobatto(s)), options);
        ASSERT_TRUE(sol.ok()) << sol.message;
        std::printf(
            "  %s, %s, x0 = 1, v0 = 0.5, N = %zu: mirror error %.3e, max balance error %.3e\n",
            scheme_name(s).c_str(), c.label, n, sol.mirror_error, sol.max_balance_error);
        EXPECT_LE(sol.mirror_error, 1e-12);
        balance.push_back(sol.max_balance_error);
      }
      if (s == 4) {
        // At the round-off level from N = 16 (the remainder is O(τ^8)).
        EXPECT_LE(balance[0], 1e-13) << c.label;
        continue;
      }
      EXPECT_LT(balance[1], 0.5 * balance[0]) << c.label << ", " << scheme_name(s);
      EXPECT_LT(balance[2], 0.5 * balance[1]) << c.label << ", " << scheme_name(s);
    }
  }
  auto refusal = [&](const std::string& force, double t0) -> std::string {
    try {
      (void)integrate(bagley_torvik(0.25, force, 16, t0), Method(lobatto(3)), options);
    } catch (const ValidationError& e) {
      return e.what();
    }
    return "(accepted)";
  };
  const std::string periodic = refusal("sin(t)", 0.0);
  const std::string shifted_sum = refusal("sqrt(1 + t)", 0.0);
  const std::string negative = refusal("t^-0.5", 0.0);
  const std::string other_origin = refusal("t^2.5", 1.0);
  for (const std::string* message : {&periodic, &shifted_sum, &negative, &other_origin})
    std::printf("  refused: %s\n", message->c_str());
  EXPECT_NE(periodic.find("model.force component 1 = \"sin(t)\" must be a finite sum of "
                          "c*(t - t0)^g"),
            std::string::npos);
  EXPECT_NE(shifted_sum.find("\"sqrt(1 + t)\" must be a finite sum"), std::string::npos);
  EXPECT_NE(negative.find("has the power (t - t0)^-0.5"), std::string::npos);
  EXPECT_NE(other_origin.find("t0 = 1"), std::string::npos);
  // The integer powers of t expand around any t0: t^3 on [1, 2] is accepted.
  EXPECT_EQ(refusal("t^3 + 6*t", 1.0), "(accepted)");
  // A C++ caller that replaces the force but not its formulas is refused, not integrated with the
  // formulas' force.
  InitialValueProblem stale = bagley_torvik(0.25, "t^3", 16);
  stale.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> out) { out(0) = t * t * t + 0.5; };
  try {
    (void)integrate(stale, Method(lobatto(3)), options);
    ADD_FAILURE() << "a force that differs from its formulas was accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(
        std::string(e.what()).find("model.forcing differs from model.forcing_formulas at t = 0 "
                                   "(max difference 0.5)"),
        std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace fracvi
