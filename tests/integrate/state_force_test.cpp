// Non-conservative forces g(x, v, t) (model/state_force.hpp, docs/theory/forces.md): the exact
// Jacobians of formula forces and of the midpoint Newton step (against Eigen's AutoDiff), the
// order of every scheme that takes g on nonlinear problems with a velocity-dependent force against
// high-accuracy references, the energy balance with g's work, the mirror run, and the refusals.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "fracvi/core/error.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

using test::fit_order;
using test::kEps;

// ---------------------------------------------------------------------------------------------
// The test force, twice: as formulas (ExpressionForce) and as a templated C++ function for AD.
//   g1 = μ (1 − x1²) v1 − c x2 v2² + 0.3 sin(t),   g2 = −k x1 x2 v1 + cos(x2) v2 t
constexpr double kMu = 1.3, kC = 0.7, kK = 0.4;
const std::vector<std::string> kForce2 = {"1.3*(1 - x1^2)*v1 - 0.7*x2*v2^2 + 0.3*sin(t)",
                                          "-0.4*x1*x2*v1 + cos(x2)*v2*t"};

template <class T>
Eigen::Matrix<T, 2, 1> force2(const Eigen::Matrix<T, 2, 1>& x, const Eigen::Matrix<T, 2, 1>& v,
                              double t) {
  using std::cos;
  Eigen::Matrix<T, 2, 1> g;
  g(0) = kMu * (1.0 - x(0) * x(0)) * v(0) - kC * x(1) * v(1) * v(1) + 0.3 * std::sin(t);
  g(1) = -kK * x(0) * x(1) * v(0) + cos(x(1)) * v(1) * t;
  return g;
}

// U = x1²/2 + x2⁴/4 + x1 x2 for the Newton-step test.
struct Quartic {
  template <class T>
  T operator()(const Eigen::Matrix<T, 2, 1>& x, T) const {
    return T(0.5) * x(0) * x(0) + T(0.25) * x(1) * x(1) * x(1) * x(1) + x(0) * x(1);
  }
};

using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, 4, 1>>;
using Dual2 = Eigen::Matrix<Dual, 2, 1>;

// ε-level tolerance for a d × d Jacobian of O(1) entries built from a few operations.
constexpr double kJacobianTolerance = 64 * kEps;

TEST(StateForce, FormulaJacobiansMatchAutoDiff) {
  const ExpressionForce g(2, kForce2);
  const Eigen::Vector2d x{0.7, -1.1}, v{0.4, 2.3};
  const double t = 0.9;
  Eigen::VectorXd value(2);
  Eigen::MatrixXd dx(2, 2), dv(2, 2);
  g.jacobians(x, v, t, value, dx, dv);

  Dual2 xd, vd;
  for (int i = 0; i < 2; ++i) {
    xd(i) = Dual(x(i), 4, i);
    vd(i) = Dual(v(i), 4, 2 + i);
  }
  const Dual2 ad = force2<Dual>(xd, vd, t);
  double worst = 0.0;
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(value(i), ad(i).value(), kJacobianTolerance);
    for (int j = 0; j < 2; ++j) {
      worst = std::max({worst, std::abs(dx(i, j) - ad(i).derivatives()(j)),
                        std::abs(dv(i, j) - ad(i).derivatives()(2 + j))});
    }
  }
  std::printf("[ jacobian ] formula force vs AutoDiff: max |error| = %.2e\n", worst);
  EXPECT_LE(worst, kJacobianTolerance);
  Eigen::VectorXd only(2);
  g.value(x, v, t, only);
  EXPECT_EQ(only, value);  // value() and jacobians() evaluate the same tape
}

// The midpoint step's residual r(Δ) = MΔ + (h²/2)[∇U(a + Δ/2) − g(a + Δ/2, Δ/h, τ)] − c with its
// AutoDiff Jacobian; one Newton iteration of MidpointNewton from Δ0 must be Δ0 − J⁻¹ r(Δ0) with J
// this Jacobian (an exact Jacobian), and differs by O(h |∂g/∂v|) from the step that leaves out
// g's Jacobian (negative control).
TEST(StateForce, NewtonStepUsesTheExactResidualJacobian) {
  const double h = 0.1, tau = 0.35;
  const Eigen::Matrix2d mass{{2.0, 0.3}, {0.3, 1.0}};
  const auto potential = make_autodiff_potential<2>(Quartic{});
  const auto force = std::make_shared<const ExpressionForce>(2, kForce2);
  const Eigen::Vector2d a{0.7, -1.1}, c{0.05, -0.2}, start{0.08, 0.15};

  NewtonOptions one;
  one.max_iterations = 1;
  internal::MidpointNewton newton(ModelMatrix(Eigen::MatrixXd(mass)), h, potential.get(), one, 0.0,
                                  LinearSolver::kAuto, force.get());
  Eigen::VectorXd step = start;
  newton.solve(a, tau, c, nullptr, step);

  auto residual = [&](const Eigen::Matrix<Dual, 2, 1>& delta, bool with_force) {
    const Dual2 mid = a.cast<Dual>() + 0.5 * delta;
    Dual2 grad;
    grad(0) = mid(0) + mid(1);
    grad(1) = mid(1) * mid(1) * mid(1) + mid(0);
    const Dual2 vel = delta / h;
    Dual2 g = force2<Dual>(mid, vel, tau);
    if (!with_force) {  // g's value, not its derivatives
      for (int i = 0; i < 2; ++i) g(i) = Dual(g(i).value(), Eigen::Vector4d::Zero());
    }
    return Dual2(mass.cast<Dual>() * delta + (0.5 * h * h) * (grad - g) - c.cast<Dual>());
  };
  auto newton_step = [&](bool with_force) {
    Dual2 delta;
    for (int i = 0; i < 2; ++i) delta(i) = Dual(start(i), 4, i);
    const Dual2 r = residual(delta, with_force);
    Eigen::Matrix2d jac;
    Eigen::Vector2d rv;
    for (int i = 0; i < 2; ++i) {
      rv(i) = r(i).value();
      jac.row(i) = r(i).derivatives().head<2>().transpose();
    }
    return Eigen::Vector2d(start - jac.lu().solve(rv));
  };
  const Eigen::Vector2d exact = newton_step(true), without = newton_step(false);
  const double error = (step - exact).cwiseAbs().maxCoeff();
  const double control = (without - exact).cwiseAbs().maxCoeff();
  std::printf("[ jacobian ] Newton step vs AutoDiff: %.2e; without dg/dx, dg/dv: %.2e\n", error,
              control);
  EXPECT_LE(error, kJacobianTolerance * start.cwiseAbs().maxCoeff());
  EXPECT_GE(control, 1e6 * kJacobianTolerance);  // the control is visible
}

// ---------------------------------------------------------------------------------------------
// Problems.

// van der Pol x'' − μ(1 − x²)x' + x = 0 (R = 0), from (2, 0) over [0, 4].
constexpr double kVdpMu = 1.0, kVdpEnd = 4.0;

InitialValueProblem van_der_pol(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = ModelMatrix(Eigen::MatrixXd::Identity(1, 1));
  p.model.damping = ModelMatrix(Eigen::MatrixXd::Zero(1, 1));
  p.model.alpha = 0.5;
  p.model.potential = std::make_shared<const ExpressionPotential>(1, "x1^2/2");
  p.model.state_force =
      std::make_shared<const ExpressionForce>(1, std::vector<std::string>{"1.0*(1 - x1^2)*v1"});
  p.x0 = Eigen::VectorXd::Constant(1, 2.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = kVdpEnd;
  p.steps = steps;
  return p;
}

// The van der Pol reference at t = j·T/4 by Boost.Odeint's controlled Runge–Kutta–Fehlberg 7(8)
// at 1e-13 (absolute and relative).
std::vector<double> van_der_pol_reference() {
  namespace odeint = boost::numeric::odeint;
  using State = std::vector<double>;
  auto rhs = [](const State& z, State& dz, double) {
    dz[0] = z[1];
    dz[1] = kVdpMu * (1.0 - z[0] * z[0]) * z[1] - z[0];
  };
  std::vector<double> out;
  State z{2.0, 0.0};
  double t = 0.0;
  using Stepper78 = odeint::runge_kutta_fehlberg78<State>;
  odeint::controlled_runge_kutta<Stepper78> stepper(
      odeint::default_error_checker<double, odeint::range_algebra, odeint::default_operations>(
          1e-13, 1e-13));
  for (int j = 1; j <= 4; ++j) {
    const double t_next = kVdpEnd * j / 4.0;
    odeint::integrate_adaptive(stepper, rhs, z, t, t_next, 1e-3);
    t = t_next;
    out.push_back(z[0]);
  }
  return out;
}

// max_j |x(t_j) − reference_j| over t_j = j·T/4 (N a multiple of 4).
double error_at_quarters(const Solution& sol, const std::vector<double>& reference) {
  const auto n = static_cast<std::size_t>(sol.x.rows() - 1);
  double err = 0.0;
  for (std::size_t j = 1; j <= 4; ++j) {
    err =
        std::max(err, std::abs(sol.x(static_cast<Eigen::Index>(j * n / 4), 0) - reference[j - 1]));
  }
  return err;
}

const std::vector<std::string> kMidpointSchemes = {"fvi-gl", "fvi-bdf2", "fvi-midpoint"};
const std::vector<std::string> kLobattoSchemes = {"fvi-lobatto2", "fvi-lobatto3", "fvi-lobatto4"};

std::vector<std::string> variational_schemes() {
  std::vector<std::string> all = kMidpointSchemes;
  all.insert(all.end(), kLobattoSchemes.begin(), kLobattoSchemes.end());
  return all;
}

// Newton to a few ulps: the default relative tolerance 1e-12, accumulated over N steps, would be
// the plateau of the sixth-order scheme (measured: 5e-11 … 1.4e-10 at N = 160 … 1280).
IntegratorOptions quiet() {
  IntegratorOptions o;
  o.error_estimate = ErrorEstimateKind::kNone;
  o.newton.relative_tolerance = 1e-15;
  return o;
}

// N = first, 2 first, …, last.
std::vector<std::size_t> halvings(std::size_t first, std::size_t last) {
  std::vector<std::size_t> counts;
  for (std::size_t n = first; n <= last; n *= 2) counts.push_back(n);
  return counts;
}

// The step counts of the order studies (multiples of 4): the higher orders start coarser so that
// their errors stay above the reference's accuracy for at least four halvings, but not so coarse
// that they are pre-asymptotic (van der Pol with fvi-lobatto4 at h = 0.5: local order 5.1).
std::vector<std::size_t> step_counts(const std::string& scheme, bool fractional) {
  if (scheme == "fvi-lobatto3") return fractional ? halvings(8, 128) : halvings(8, 256);
  if (scheme == "fvi-lobatto4") return fractional ? halvings(4, 64) : halvings(16, 128);
  return fractional ? halvings(32, 512) : halvings(32, 1024);
}

TEST(StateForce, VanDerPolOrderAgainstFehlberg78) {
  const std::vector<double> reference = van_der_pol_reference();
  for (const std::string& name : variational_schemes()) {
    const Method method = *parse_method(name);
    std::vector<double> hs, errors;
    for (const std::size_t n : step_counts(name, false)) {
      const InitialValueProblem p = van_der_pol(n);
      const Solution sol = integrate(p, method, quiet());
      ASSERT_TRUE(sol.ok()) << name << ": " << sol.message;
      hs.push_back(p.step_size());
      errors.push_back(error_at_quarters(sol, reference));
    }
    const auto fit = fit_order(hs, errors, {.floor = test::round_off_floor(2.0)});
    std::printf("%s", fit.table(name + ", van der Pol mu = 1, R = 0").c_str());
    const int declared = method.declared_order(van_der_pol(8).model);
    EXPECT_TRUE(fit.valid) << fit.table();
    EXPECT_GE(fit.used.size(), 4u) << fit.table();
    EXPECT_NEAR(fit.slope, declared, 0.15) << fit.table();
  }
}

TEST(StateForce, VanDerPolDopri5FollowsItsTolerance) {
  const std::vector<double> reference = van_der_pol_reference();
  IntegratorOptions o = quiet();
  o.abs_tolerance = o.rel_tolerance = 1e-11;
  const Solution sol = integrate(van_der_pol(80), *parse_method("dopri5"), o);
  ASSERT_TRUE(sol.ok()) << sol.message;
  const double err = error_at_quarters(sol, reference);
  std::printf("[ dopri5 ] van der Pol at tolerance 1e-11: error %.2e\n", err);
  // A controlled fifth-order method's global error is the local tolerance times a modest factor
  // (the error growth of the flow over [0, 4]); 100x leaves room for it, and a force missing from
  // the right-hand side would be an O(1) error.
  EXPECT_LE(err, 1e-9);
}

// dopri5 books g's work by ½(g_k + g_{k+1})·Δx_k on the output grid: O(h²) whatever its
// tolerance, so quartering the output step divides the balance error by about 16.
TEST(StateForce, Dopri5BalanceIsSecondOrderInTheOutputStep) {
  IntegratorOptions o = quiet();
  o.abs_tolerance = o.rel_tolerance = 1e-12;
  const Solution coarse = integrate(van_der_pol(80), *parse_method("dopri5"), o);
  const Solution fine = integrate(van_der_pol(320), *parse_method("dopri5"), o);
  ASSERT_TRUE(coarse.ok() && fine.ok()) << coarse.message << fine.message;
  const double ratio = coarse.max_balance_error / fine.max_balance_error;
  std::printf("[ balance ] dopri5 van der Pol: %.2e (N = 80), %.2e (N = 320), ratio %.1f\n",
              coarse.max_balance_error, fine.max_balance_error, ratio);
  EXPECT_GE(ratio, 16.0 / 1.5);
  EXPECT_GE(fine.max_balance_error, test::round_off_floor(1.0));
}

// Duffing with nonlinear velocity feedback and fractional damping of order 2α = 0.6 (Caputo):
//   x'' + 0.5 D^{0.6} x + x + x³ = −0.4 x² x' + 0.3 cos(t),   x(0) = 1, v(0) = 0, on [0, 2].
InitialValueProblem fractional_duffing(std::size_t steps, double order) {
  InitialValueProblem p;
  p.model.mass = ModelMatrix(Eigen::MatrixXd::Identity(1, 1));
  p.model.damping = ModelMatrix(Eigen::MatrixXd::Constant(1, 1, 0.5));
  p.model.alpha = order / 2.0;
  p.model.convention = Convention::kCaputo;
  p.model.potential = std::make_shared<const ExpressionPotential>(1, "x1^2/2 + x1^4/4");
  p.model.state_force = std::make_shared<const ExpressionForce>(
      1, std::vector<std::string>{"-0.4*x1^2*v1 + 0.3*cos(t)"});
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 2.0;
  p.steps = steps;
  return p;
}

// For the fractional cases there is no ODE reference: a fine-grid run of a different scheme
// (fvi-midpoint for fvi-gl, fvi-bdf2 and fvi-lobatto2, fvi-bdf2 for fvi-midpoint, N = 16384;
// fvi-lobatto4 for fvi-lobatto3 and the reverse, N = 2048), Richardson-checked: its own error is
// estimated from the run with half the steps, |x_N − x_{N/2}|/3 (conservative for the Lobatto
// schemes, whose error falls faster), and the order fit's floor is ten times that.
struct FineReference {
  std::vector<double> x;
  double error = 0.0;
};

FineReference fine_reference(const std::string& scheme, double order, std::size_t kFine = 16384) {
  const Solution fine = integrate(fractional_duffing(kFine, order), *parse_method(scheme), quiet());
  const Solution half =
      integrate(fractional_duffing(kFine / 2, order), *parse_method(scheme), quiet());
  EXPECT_TRUE(fine.ok() && half.ok()) << fine.message << half.message;
  FineReference ref;
  for (std::size_t j = 1; j <= 4; ++j) {
    const double x = fine.x(static_cast<Eigen::Index>(j * kFine / 4), 0);
    const double xh = half.x(static_cast<Eigen::Index>(j * kFine / 8), 0);
    ref.x.push_back(x);
    ref.error = std::max(ref.error, std::abs(x - xh) / 3.0);
  }
  return ref;
}

class FractionalStateForce : public ::testing::TestWithParam<double> {};

TEST_P(FractionalStateForce, OrderAgainstFineRichardsonReference) {
  const double order = GetParam();
  const FineReference by_midpoint = fine_reference("fvi-midpoint", order);
  const FineReference by_bdf2 = fine_reference("fvi-bdf2", order);
  // The two references, from different schemes, agree within their Richardson estimates.
  double between = 0.0;
  for (std::size_t j = 0; j < 4; ++j)
    between = std::max(between, std::abs(by_midpoint.x[j] - by_bdf2.x[j]));
  std::printf("[ reference ] 2alpha = %.1f: Richardson %.1e (midpoint), %.1e (bdf2), apart %.1e\n",
              order, by_midpoint.error, by_bdf2.error, between);
  EXPECT_LE(between, 10.0 * (by_midpoint.error + by_bdf2.error) + test::round_off_floor(1.0));
  const FineReference by_lobatto3 = fine_reference("fvi-lobatto3", order, 2048);
  const FineReference by_lobatto4 = fine_reference("fvi-lobatto4", order, 2048);
  double lobatto_between = 0.0;
  for (std::size_t j = 0; j < 4; ++j)
    lobatto_between = std::max(lobatto_between, std::abs(by_lobatto3.x[j] - by_lobatto4.x[j]));
  std::printf(
      "[ reference ] 2alpha = %.1f: Richardson %.1e (lobatto3), %.1e (lobatto4), apart %.1e\n",
      order, by_lobatto3.error, by_lobatto4.error, lobatto_between);
  EXPECT_LE(lobatto_between,
            10.0 * (by_lobatto3.error + by_lobatto4.error) + test::round_off_floor(1.0));

  for (const std::string& name : variational_schemes()) {
    const FineReference& ref = name == "fvi-midpoint"   ? by_bdf2
                               : name == "fvi-lobatto3" ? by_lobatto4
                               : name == "fvi-lobatto4" ? by_lobatto3
                                                        : by_midpoint;
    const Method method = *parse_method(name);
    std::vector<double> hs, errors;
    for (const std::size_t n : step_counts(name, true)) {
      const InitialValueProblem p = fractional_duffing(n, order);
      const Solution sol = integrate(p, method, quiet());
      ASSERT_TRUE(sol.ok()) << name << ": " << sol.message;
      hs.push_back(p.step_size());
      errors.push_back(error_at_quarters(sol, ref.x));
    }
    const auto fit =
        fit_order(hs, errors, {.floor = std::max(10.0 * ref.error, test::round_off_floor(1.0))});
    char label[120];
    std::snprintf(label, sizeof label, "%s, Duffing + feedback, 2alpha = %.1f", name.c_str(),
                  order);
    std::printf("%s", fit.table(label).c_str());
    const int declared = method.declared_order(fractional_duffing(8, order).model);
    EXPECT_TRUE(fit.valid) << fit.table();
    EXPECT_GE(fit.used.size(), 4u) << fit.table();
    EXPECT_GE(fit.slope, declared - 0.15) << fit.table();
  }
}

INSTANTIATE_TEST_SUITE_P(Orders, FractionalStateForce, ::testing::Values(0.6, 1.5));

// ---------------------------------------------------------------------------------------------
// Energy account: for quadratic U the midpoint schemes balance exactly (SchemeInfo::exact_balance)
// once g's discrete work Σ g(x̄_k, Δ_k/h)·Δ_k is booked; that work is O(1) here, so a missing or
// wrong term would show far above the round-off bound.
TEST(StateForce, EnergyBalanceIncludesTheWorkOfTheForce) {
  for (const std::string& name : kMidpointSchemes) {
    for (const double order : {0.0, 0.6, 1.0, 1.5}) {
      InitialValueProblem p = fractional_duffing(400, order);
      if (order == 0.0) p.model.damping = ModelMatrix(Eigen::MatrixXd::Zero(1, 1));
      p.model.potential = std::make_shared<const ExpressionPotential>(1, "x1^2");
      const Solution sol = integrate(p, *parse_method(name), quiet());
      ASSERT_TRUE(sol.ok()) << name << ": " << sol.message;
      const double tolerance = test::balance_tolerance(sol);
      std::printf("[ balance ] %s 2alpha = %.1f: max |E + W - E0| = %.2e (bound %.2e), |W| %.2f\n",
                  name.c_str(), order, sol.max_balance_error, tolerance,
                  sol.dissipated.cwiseAbs().maxCoeff());
      EXPECT_LE(sol.max_balance_error, tolerance) << name << " 2alpha = " << order;
      EXPECT_GE(sol.dissipated.cwiseAbs().maxCoeff(), 0.1);
    }
  }
}

// A nonquadratic U: the balance error is the midpoint quadrature defect, O(h²) (a consistency
// check): quartering h divides it by about 16.
TEST(StateForce, EnergyBalanceAtTheSchemesConsistencyLevel) {
  for (const std::string& name : kMidpointSchemes) {
    const Solution coarse = integrate(fractional_duffing(200, 0.6), *parse_method(name), quiet());
    const Solution fine = integrate(fractional_duffing(800, 0.6), *parse_method(name), quiet());
    ASSERT_TRUE(coarse.ok() && fine.ok());
    const double ratio = coarse.max_balance_error / fine.max_balance_error;
    std::printf("[ balance ] %s Duffing: %.2e (N = 200), %.2e (N = 800), ratio %.1f\n",
                name.c_str(), coarse.max_balance_error, fine.max_balance_error, ratio);
    EXPECT_GE(ratio, 16.0 / 1.5) << name;  // second order, with a margin for the constant
  }
}

// The Lobatto FVIs' balance is not exact but O(h^{2s−2}) (docs/theory/fvi_lobatto.md), with g's
// work h Σ_a b_a g_a·V_a booked: quartering h divides it by 4^{2s−2} (with a margin of 1.5 for the
// constant), as long as it stays above round-off. On van der Pol (R = 0), where the full order
// holds; with fractional damping the regularity at t_0 caps it (fvi-lobatto4 on the Duffing
// problem at 2α = 0.6: ratio 2203, local order 5.6).
TEST(StateForce, LobattoBalanceConvergesAtItsOrder) {
  for (const std::string& name : kLobattoSchemes) {
    const int s = name.back() - '0';
    const std::size_t n = s == 4 ? 32 : 40;  // fvi-lobatto4: round-off from N = 256 on
    const Solution coarse = integrate(van_der_pol(n), *parse_method(name), quiet());
    const Solution fine = integrate(van_der_pol(4 * n), *parse_method(name), quiet());
    ASSERT_TRUE(coarse.ok() && fine.ok());
    const double ratio = coarse.max_balance_error / fine.max_balance_error;
    std::printf("[ balance ] %s van der Pol: %.2e (N = %zu), %.2e (N = %zu), ratio %.1f\n",
                name.c_str(), coarse.max_balance_error, n, fine.max_balance_error, 4 * n, ratio);
    EXPECT_GE(fine.max_balance_error, test::round_off_floor(1.0)) << name;
    EXPECT_GE(ratio, std::pow(4.0, 2 * s - 2) / 1.5) << name;
  }
}

// The mirror run evaluates g at the mirrored cells' physical state and reproduces the trajectory.
TEST(StateForce, MirrorRunReproducesTheTrajectory) {
  for (const std::string& name : variational_schemes()) {
    IntegratorOptions o = quiet();
    o.mirror = true;
    const Solution sol = integrate(fractional_duffing(200, 0.6), *parse_method(name), o);
    ASSERT_TRUE(sol.ok()) << sol.message;
    std::printf("[ mirror ] %s: %.2e\n", name.c_str(), sol.mirror_error);
    EXPECT_LE(sol.mirror_error, 1e-9) << name;
  }
}

// The stage Jacobians with g: for a force linear in (x, v) and a quadratic U the step equations
// are linear, so Newton with the exact Jacobian takes one correction and one iteration to see it
// converged (a correction at round-off). Leaving out ∂g/∂v or ∂g/∂x would cost a linearly
// converging iteration per digit instead. All schemes that take g, with fractional damping.
TEST(StateForce, LinearForceConvergesInTwoNewtonIterations) {
  for (const std::string& name : variational_schemes()) {
    InitialValueProblem p = fractional_duffing(64, 0.6);
    p.model.potential = std::make_shared<const ExpressionPotential>(1, "x1^2/2");
    p.model.state_force = std::make_shared<const ExpressionForce>(
        1, std::vector<std::string>{"-0.8*v1 + 0.6*x1 + 0.3*cos(t)"});
    IntegratorOptions o = quiet();
    o.newton.relative_tolerance = 1e-12;
    const Solution sol = integrate(p, *parse_method(name), o);
    ASSERT_TRUE(sol.ok()) << name << ": " << sol.message;
    std::printf("[ newton ] %s, linear g: at most %zu iterations per step\n", name.c_str(),
                sol.max_newton_iterations_per_step);
    EXPECT_LE(sol.max_newton_iterations_per_step, 2u) << name;
  }
}

// ---------------------------------------------------------------------------------------------
// Refusals and failures.

TEST(StateForce, SchemesWithoutItRefuseBeforeStepOne) {
  const InitialValueProblem p = van_der_pol(80);
  for (const SchemeInfo* info : registered_schemes()) {
    if (info->no_state_force.empty()) continue;
    try {
      check_applicable(p, Method(*info), {});
      ADD_FAILURE() << info->name << " accepted a state force";
    } catch (const ValidationError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string(info->name)), std::string::npos) << what;
      EXPECT_NE(what.find("g(x, v, t)"), std::string::npos) << what;
      EXPECT_NE(what.find(std::string(info->no_state_force)), std::string::npos) << what;
    }
  }
}

TEST(StateForce, StructuredSolversAreRefused) {
  IntegratorOptions o = quiet();
  o.linear_solver = LinearSolver::kBanded;
  try {
    integrate(van_der_pol(80), fvi_gl(), o);
    ADD_FAILURE() << "banded accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("non-symmetric"), std::string::npos) << e.what();
  }
}

TEST(StateForce, NanForceEndsTheRunKeepingTheTrajectory) {
  InitialValueProblem p = van_der_pol(200);
  // Real until x1 falls below 1 (the van der Pol solution from 2 does, near t = 1).
  p.model.state_force =
      std::make_shared<const ExpressionForce>(1, std::vector<std::string>{"sqrt(x1 - 1)*v1"});
  for (const std::string& name : variational_schemes()) {
    const Solution sol = integrate(p, *parse_method(name), quiet());
    EXPECT_EQ(sol.status, Status::kNonFinite) << name << ": " << sol.message;
    EXPECT_GT(sol.steps_done, 0u) << name;
    EXPECT_LT(sol.steps_done, p.steps) << name;
    EXPECT_TRUE(sol.x.topRows(static_cast<Eigen::Index>(sol.steps_done) + 1).allFinite());
    EXPECT_NE(sol.message.find("non-finite"), std::string::npos) << sol.message;
  }
}

// The action sum and the boundary value problem are variational: a force without a Lagrangian is
// refused with the reason.
TEST(StateForce, TheLagrangianFormRefusesIt) {
  try {
    MechanicalLagrangian(van_der_pol(10).model, 0.0, 1.0);
    ADD_FAILURE() << "accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("no Lagrangian"), std::string::npos) << e.what();
  }
}

TEST(StateForce, TimeOnlyFormulasKeepTheForcingPath) {
  const ExpressionForces t_only = make_expression_forces(2, {"sin(t)", "1"});
  EXPECT_TRUE(static_cast<bool>(t_only.forcing));
  EXPECT_EQ(t_only.state_force, nullptr);
  // A mention decides, not the simplified dependence: 0*x1 is a (zero) state force.
  EXPECT_NE(make_expression_forces(2, {"sin(t)", "0*x1 + 1"}).state_force, nullptr);
  const ExpressionForces state = make_expression_forces(2, {"sin(t)", "v2"});
  EXPECT_FALSE(static_cast<bool>(state.forcing));
  ASSERT_NE(state.state_force, nullptr);
  EXPECT_EQ(state.state_force->dimension(), 2);
}

TEST(StateForce, BadFormulasNameTheComponentAndTheVariables) {
  try {
    ExpressionForce(2, {"x5", "0"});
    ADD_FAILURE();
  } catch (const ExpressionError& e) {
    EXPECT_NE(e.reason().find("component 1 of 2"), std::string::npos) << e.what();
    EXPECT_NE(e.reason().find("x5"), std::string::npos) << e.what();
    EXPECT_NE(e.reason().find("v2"), std::string::npos) << e.what();  // the known names
  }
  EXPECT_THROW(ExpressionForce(2, {"v1"}), std::invalid_argument);
}

}  // namespace
}  // namespace fracvi
