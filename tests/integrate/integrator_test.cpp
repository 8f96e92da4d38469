// The Integrator's contract: hand stepping = one call; observer; history variants and convention
// identities that must hold bit for bit; numerical failure as a status with the partial
// trajectory; Method values.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

InitialValueProblem pendula(double alpha, Convention convention, Eigen::VectorXd x0,
                            Eigen::VectorXd v0, std::size_t steps = 200) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
  p.model.alpha = alpha;
  p.model.convention = convention;
  p.model.potential =
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = 0.1;
  };
  p.x0 = std::move(x0);
  p.v0 = std::move(v0);
  p.t_end = 2.0;
  p.steps = steps;
  return p;
}

const Eigen::VectorXd kX0{{1.2, -0.4}};
const Eigen::VectorXd kV0{{0.5, 0.8}};

TEST(Integrator, HandSteppingEqualsOneCall) {
  const InitialValueProblem p = pendula(0.75, Convention::kCaputo, kX0, kV0);
  const Solution one = integrate(p);
  Integrator integ(p);
  EXPECT_EQ(integ.steps_total(), p.steps);
  EXPECT_EQ(integ.status(), Status::kRunning);
  EXPECT_EQ(integ.time(), p.t0);
  EXPECT_EQ(integ.position(), p.x0);
  EXPECT_EQ(integ.velocity(), p.v0);
  std::size_t steps = 0;
  Status s = Status::kRunning;
  while (s == Status::kRunning) {
    s = integ.step();
    ++steps;
    EXPECT_EQ(integ.steps_done(), steps);
    EXPECT_EQ(integ.position(), one.x.row(static_cast<Eigen::Index>(steps)).transpose());
  }
  EXPECT_EQ(s, Status::kSuccess);
  EXPECT_EQ(steps, p.steps);
  EXPECT_EQ(integ.step(), Status::kSuccess);  // finished: a no-op
  EXPECT_EQ(integ.steps_done(), p.steps);
  const Solution hand = integ.take_solution();
  EXPECT_TRUE((hand.x.array() == one.x.array()).all());
  EXPECT_TRUE((hand.v.array() == one.v.array()).all());
  EXPECT_TRUE((hand.energy.array() == one.energy.array()).all());
  EXPECT_TRUE((hand.balance.array() == one.balance.array()).all());
  EXPECT_EQ(hand.mirror_error, one.mirror_error);
  EXPECT_EQ(hand.t.size(), static_cast<Eigen::Index>(p.steps + 1));
  EXPECT_DOUBLE_EQ(hand.t(static_cast<Eigen::Index>(p.steps)), p.t_end);
  EXPECT_EQ(hand.method, "fvi-gl");
  EXPECT_EQ(hand.declared_order, 1);
}

TEST(Integrator, ObserverSeesEveryState) {
  const InitialValueProblem p = pendula(0.5, Convention::kCaputo, kX0, kV0, 50);
  std::vector<std::size_t> ks;
  std::vector<double> energies;
  const Solution sol = integrate(p, fvi_gl(), IntegratorOptions{}, [&](const StepView& view) {
    ks.push_back(view.k);
    energies.push_back(view.energy);
    EXPECT_EQ(view.x.size(), 2);
    EXPECT_DOUBLE_EQ(view.balance, view.energy + view.dissipated - energies.front());
  });
  ASSERT_EQ(ks.size(), p.steps + 1);
  for (std::size_t k = 0; k <= p.steps; ++k) {
    EXPECT_EQ(ks[k], k);
    EXPECT_EQ(energies[k], sol.energy(static_cast<Eigen::Index>(k)));
  }
}

// Lemma 5.3: for α = 1/2 the full GL double sum collapses to x_k − x_{k−1}. The weights of
// (1 − ζ)^1 are exactly (1, −1, 0, 0, …), so the direct history gives the same numbers bit for bit.
TEST(Integrator, LemmaFiveThreeLocalEqualsDirectHistory) {
  for (const double alpha : {0.5, 1.0, 0.0}) {
    const InitialValueProblem p = pendula(alpha, Convention::kCaputo, kX0, kV0);
    IntegratorOptions direct;
    direct.history = HistoryKind::kDirect;
    const Solution a = integrate(p), b = integrate(p, fvi_gl(), direct);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_TRUE((a.x.array() == b.x.array()).all()) << "alpha = " << alpha;
    EXPECT_TRUE((a.v.array() == b.v.array()).all()) << "alpha = " << alpha;
  }
}

// DESIGN §2: with zero initial data Riemann–Liouville and Caputo coincide (x̃ = x − 0 − t·0 = x
// exactly), and for 2α = 1 they coincide for any data (the shift cancels in x_k − x_{k−1}).
TEST(Integrator, ConventionsCoincideWhereTheyShould) {
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(2);
  for (const double alpha : {0.3, 0.75}) {
    const Solution rl = integrate(pendula(alpha, Convention::kRiemannLiouville, zero, zero));
    const Solution cap = integrate(pendula(alpha, Convention::kCaputo, zero, zero));
    EXPECT_TRUE((rl.x.array() == cap.x.array()).all()) << "alpha = " << alpha;
  }
  const Solution rl = integrate(pendula(0.5, Convention::kRiemannLiouville, kX0, kV0));
  const Solution cap = integrate(pendula(0.5, Convention::kCaputo, kX0, kV0));
  EXPECT_TRUE((rl.x.array() == cap.x.array()).all());
  // …and differ with nonzero data where they should (2α < 1, x0 ≠ 0: RL feels x0 t^{−2α}).
  const Solution rl3 = integrate(pendula(0.3, Convention::kRiemannLiouville, kX0, kV0));
  const Solution cap3 = integrate(pendula(0.3, Convention::kCaputo, kX0, kV0));
  EXPECT_GT((rl3.x - cap3.x).cwiseAbs().maxCoeff(), 1e-3);
}

// A saturating potential U = c log cosh x with a large step: Newton's iteration for
// Δ + (h²c/2) tanh(x_k + Δ/2) = h p⁺ cycles once the root lies in the steep part of tanh.
class LogCosh final : public Potential {
 public:
  explicit LogCosh(double c) : c_(c) {}
  [[nodiscard]] Eigen::Index dimension() const override { return 1; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    return c_ * std::log(std::cosh(x(0)));
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g(0) = c_ * std::tanh(x(0));
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    const double s = 1.0 / std::cosh(x(0));
    H(0, 0) = c_ * s * s;
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }

 private:
  double c_;
};

InitialValueProblem log_cosh_problem() {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Ones(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.1);
  p.model.potential = std::make_shared<const LogCosh>(100.0);
  p.x0 = Eigen::VectorXd::Constant(1, 40.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.steps = 40;
  p.t_end = 16.0;  // h = 0.4
  return p;
}

TEST(Integrator, NewtonFailureKeepsPartialTrajectory) {
  const InitialValueProblem p = log_cosh_problem();
  const Solution sol = integrate(p);
  EXPECT_EQ(sol.status, Status::kNewtonFailure);
  EXPECT_FALSE(sol.ok());
  std::printf("  message: %s\n", sol.message.c_str());
  EXPECT_EQ(sol.steps_done, 5u);  // measured: the iteration first cycles when computing x_6
  EXPECT_NE(sol.message.find("Newton did not converge"), std::string::npos);
  EXPECT_NE(sol.message.find("step 6"), std::string::npos);
  EXPECT_NE(sol.message.find("t = 2.4"), std::string::npos);
  EXPECT_EQ(sol.message.find("kinks"), std::string::npos);  // a smooth U: no such hint
  ASSERT_EQ(sol.x.rows(), 6);
  EXPECT_TRUE(sol.x.allFinite());
  EXPECT_TRUE(sol.v.allFinite());
  EXPECT_TRUE(sol.energy.allFinite());
  EXPECT_EQ(sol.x(0, 0), 40.0);
  EXPECT_TRUE(std::isnan(sol.mirror_error));  // not computed for a failed run
  // The same run with a smaller step succeeds: the failure is the step size, not a bug.
  InitialValueProblem fine = p;
  fine.steps = 400;
  EXPECT_TRUE(integrate(fine).ok());
}

// A piecewise-linear potential is not a linear problem: abs(x1) has a Hessian of 0 wherever it
// exists, but its gradient jumps, so a step whose midpoint lands near the kink has no solution of
// the midpoint equation. The run must say so (newton-failure at that step, the steps before it
// kept), not take one linear solve without a residual check and report success: before the fix
// this run "succeeded" with a mirror error of 7.3e-2 (docs/problem-file.md).
TEST(Integrator, AKinkedPotentialIsSolvedAndCheckedLikeANonlinearOne) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.3);
  p.model.alpha = 0.75;
  p.model.convention = Convention::kCaputo;
  p.model.potential = std::make_shared<const ExpressionPotential>(1, "abs(x1)");
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 20.0;
  p.steps = 1000;
  EXPECT_FALSE(p.model.potential->has_constant_hessian());
  const Solution sol = integrate(p, *parse_method("fvi-gl"));
  EXPECT_EQ(sol.status, Status::kNewtonFailure) << sol.message;
  EXPECT_EQ(sol.steps_done, 211u);  // measured: x_212's midpoint is at the kink
  EXPECT_NE(sol.message.find("Newton did not converge"), std::string::npos) << sol.message;
  EXPECT_NE(sol.message.find("the potential has kinks in x"), std::string::npos) << sol.message;
  EXPECT_TRUE(sol.x.allFinite());
  // The steps before the kink are the linear path's: away from it both solve the same equation.
  InitialValueProblem smooth = p;
  smooth.model.potential = std::make_shared<const ExpressionPotential>(1, "sqrt(x1^2 + 1e-8)");
  const Solution reference = integrate(smooth, *parse_method("fvi-gl"));
  ASSERT_TRUE(reference.ok()) << reference.message;
  EXPECT_LT((sol.x.topRows(100) - reference.x.topRows(100)).cwiseAbs().maxCoeff(), 1e-6);
}

// A potential whose gradient becomes NaN after t = 1: the run stops with kNonFinite.
class NanAfter final : public Potential {
 public:
  [[nodiscard]] Eigen::Index dimension() const override { return 1; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    return 0.5 * x(0) * x(0);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g(0) = t > 1.0 ? std::nan("") : x(0);
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>&, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    H(0, 0) = 1.0;
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }
};

TEST(Integrator, NonFiniteStopsTheRun) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Ones(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.1);
  p.model.potential = std::make_shared<const NanAfter>();
  p.x0 = Eigen::VectorXd::Ones(1);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 2.0;
  p.steps = 20;  // t_{k+½} > 1 first for k = 10
  const Solution sol = integrate(p);
  EXPECT_EQ(sol.status, Status::kNonFinite);
  EXPECT_EQ(sol.steps_done, 10u);
  EXPECT_NE(sol.message.find("step 11"), std::string::npos) << sol.message;
  EXPECT_TRUE(sol.x.allFinite());
}

TEST(Integrator, ThrowingForcingIsReportedNotPropagated) {
  InitialValueProblem p = pendula(0.5, Convention::kCaputo, kX0, kV0, 20);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    if (t > 1.0) throw std::runtime_error("forcing table ends at t = 1");
    f.setZero();
  };
  const Solution sol = integrate(p);
  EXPECT_EQ(sol.status, Status::kCallbackError);
  EXPECT_EQ(sol.steps_done, 10u);
  EXPECT_NE(sol.message.find("forcing table ends at t = 1"), std::string::npos) << sol.message;
}

TEST(Integrator, StoppedByTheCallerKeepsWhatWasComputed) {
  Integrator integ(pendula(0.75, Convention::kCaputo, kX0, kV0, 100));
  for (int i = 0; i < 7; ++i) integ.step();
  const Solution sol = integ.take_solution();
  EXPECT_EQ(sol.status, Status::kRunning);
  EXPECT_EQ(sol.steps_done, 7u);
  EXPECT_EQ(sol.x.rows(), 8);
  EXPECT_NE(sol.message.find("7 of 100"), std::string::npos);
}

// snapshot() is take_solution() now, without ending the run: between stored rows (every = 3) it
// ends with the current state, and the Integrator goes on to the same trajectory as one call.
TEST(Integrator, SnapshotIsTheSolutionSoFarAndTheRunGoesOn) {
  const InitialValueProblem p = pendula(0.75, Convention::kCaputo, kX0, kV0, 20);
  IntegratorOptions options;
  options.save_every = 3;
  const Solution one = integrate(p, fvi_gl(), options);
  Integrator integ(p, fvi_gl(), options);
  for (int i = 0; i < 7; ++i) integ.step();
  const Solution part = integ.snapshot();
  EXPECT_EQ(part.status, Status::kRunning);
  EXPECT_EQ(part.steps_done, 7u);
  EXPECT_EQ(part.step, (std::vector<std::size_t>{0, 3, 6, 7}));
  EXPECT_EQ(part.x.rows(), 4);
  EXPECT_EQ(part.x.row(3), integ.position().transpose());
  EXPECT_EQ(part.x.row(2), one.x.row(2));  // step 6
  EXPECT_EQ(part.t[3], integ.time());
  EXPECT_NE(part.message.find("7 of 20"), std::string::npos) << part.message;
  EXPECT_TRUE(std::isnan(part.mirror_error));
  integ.run();
  const Solution end = integ.snapshot();
  EXPECT_EQ(end.status, Status::kSuccess);
  EXPECT_EQ(end.step, one.step);
  EXPECT_TRUE((end.x.array() == one.x.array()).all());
  EXPECT_TRUE((end.balance.array() == one.balance.array()).all());
  const Solution taken = integ.take_solution();
  EXPECT_TRUE((taken.x.array() == one.x.array()).all());
  EXPECT_EQ(taken.mirror_error, one.mirror_error);
}

TEST(Integrator, DiagnosticsOffLeavesTrajectoryUnchanged) {
  for (const double alpha : {0.5, 0.75}) {
    const InitialValueProblem p = pendula(alpha, Convention::kCaputo, kX0, kV0);
    IntegratorOptions off;
    off.diagnostics = false;
    const Solution a = integrate(p), b = integrate(p, fvi_gl(), off);
    ASSERT_TRUE(b.ok());
    EXPECT_TRUE((a.x.array() == b.x.array()).all());
    EXPECT_TRUE((a.v.array() == b.v.array()).all());
    EXPECT_TRUE(b.energy.array().isNaN().all());
    EXPECT_TRUE(std::isnan(b.max_balance_error));
    EXPECT_EQ(a.mirror_error, b.mirror_error);
  }
}

TEST(Integrator, SingleStepProblem) {
  InitialValueProblem p = pendula(0.75, Convention::kCaputo, kX0, kV0, 1);
  p.t_end = 0.05;
  const Solution sol = integrate(p);
  EXPECT_TRUE(sol.ok()) << sol.message;
  EXPECT_EQ(sol.x.rows(), 2);
  EXPECT_EQ(sol.mirror_error, 0.0);
}

TEST(Integrator, UnforcedWithoutPotential) {
  // Free particle with viscous damping: x(t) = x0 + v0 (1 − e^{−t r/m}) m/r. First order.
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Constant(1, 1, 2.0);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 1.0);
  p.x0 = Eigen::VectorXd::Constant(1, 0.5);
  p.v0 = Eigen::VectorXd::Constant(1, 1.0);
  p.t_end = 1.0;
  const double exact = 0.5 + 2.0 * (1.0 - std::exp(-0.5));
  std::vector<double> hs, errs;
  for (const std::size_t n : {100ul, 200ul, 400ul, 800ul}) {
    p.steps = n;
    const Solution sol = integrate(p);
    ASSERT_TRUE(sol.ok());
    EXPECT_EQ(sol.newton_iterations, n);
    hs.push_back(p.step_size());
    errs.push_back(std::abs(sol.x(static_cast<Eigen::Index>(n), 0) - exact));
  }
  const test::OrderFit fit = test::fit_order(hs, errs, {.floor = test::round_off_floor(exact)});
  EXPECT_NEAR(fit.slope, 1.0, 0.05) << fit.table();
}

TEST(MethodValue, NameOrderParse) {
  const Method m = fvi_gl();
  EXPECT_EQ(m.name(), "fvi-gl");
  MechanicalModel model;
  model.mass = Eigen::MatrixXd::Identity(2, 2);
  model.damping = Eigen::MatrixXd::Zero(2, 2);
  EXPECT_EQ(m.declared_order(model), 2);
  model.damping.dense()(1, 1) = 0.1;
  EXPECT_EQ(m.declared_order(model), 1);
  ASSERT_TRUE(parse_method("fvi-gl").has_value());
  EXPECT_FALSE(parse_method("fvi").has_value());
  EXPECT_EQ(to_string(Status::kNewtonFailure), "newton-failure");
  EXPECT_EQ(parse_convention("caputo"), Convention::kCaputo);
  EXPECT_EQ(parse_convention("riemann-liouville"), Convention::kRiemannLiouville);
  EXPECT_FALSE(parse_convention("rl").has_value());
}

// Solution::jacobian_factorizations counts the Newton matrices formed and factored: the set-up's
// one for a linear problem (none after it), none for an explicit scheme, one per Newton iteration
// on the dense path of a nonlinear problem (full Newton), and for a Lobatto FVI's simplified
// Newton at least one and at most one per iteration. (The banded path's carried J:
// newton_stopping_test.)
TEST(Integrator, CountsJacobianFactorizations) {
  InitialValueProblem linear = pendula(0.75, Convention::kCaputo, kX0, kV0);
  linear.model.potential = make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}});
  const Solution gl = integrate(linear, fvi_gl());
  ASSERT_TRUE(gl.ok()) << gl.message;
  EXPECT_EQ(gl.jacobian_factorizations, 1u);
  EXPECT_EQ(gl.newton_iterations, linear.steps);
  const Solution euler = integrate(linear, *parse_method("euler-explicit"));
  ASSERT_TRUE(euler.ok()) << euler.message;
  EXPECT_EQ(euler.jacobian_factorizations, 0u);

  const Solution dense = integrate(pendula(0.75, Convention::kCaputo, kX0, kV0), fvi_gl());
  ASSERT_TRUE(dense.ok()) << dense.message;
  EXPECT_EQ(dense.linear_solver, "dense");
  EXPECT_GT(dense.newton_iterations, 200u);
  EXPECT_EQ(dense.jacobian_factorizations, dense.newton_iterations);

  const Solution lobatto =
      integrate(pendula(0.75, Convention::kCaputo, kX0, kV0), *parse_method("fvi-lobatto3"));
  ASSERT_TRUE(lobatto.ok()) << lobatto.message;
  std::printf("  fvi-lobatto3: %zu factorisations in %zu Newton iterations\n",
              lobatto.jacobian_factorizations, lobatto.newton_iterations);
  EXPECT_GE(lobatto.jacobian_factorizations, 1u);
  EXPECT_LE(lobatto.jacobian_factorizations, lobatto.newton_iterations);
}

}  // namespace
}  // namespace fracvi
