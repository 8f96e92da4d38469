// Large systems: the FPUT chain with sparse mass and damping matrices through the banded and sparse
// Newton factorisations.
//
//  * the three factorisations (and dense storage of M) give the same trajectory to round-off;
//  * the automatic choice follows the structure (fixed chain → banded, periodic → sparse);
//  * orders on the chain against independent references: undamped and viscous nonlinear FPUT vs
//    Boost.Odeint dopri5 at 1e-12 (2 and 1), the fractional (2α = 3/2, Caputo) linear chain vs the
//    Laplace-inversion reference (1);
//  * storage every n-th step: the stored rows are the full run's rows bitwise, a failure keeps the
//    last completed step.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "../support/linear_oscillator_reference.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "fracvi/solve/vector_passes.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

struct ChainSetup {
  Eigen::Index d = 8;
  ChainBoundary boundary = ChainBoundary::kFixed;
  double alpha = 0.75;
  double damping = 0.2;
  double cubic = 0.5, quartic = 1.0;
  double t_end = 2.0;
  std::size_t steps = 200;
};

InitialValueProblem chain_problem(const ChainSetup& s) {
  InitialValueProblem p;
  Eigen::VectorXd masses(s.d);
  for (Eigen::Index i = 0; i < s.d; ++i) masses[i] = 1.0 + 0.02 * static_cast<double>(i);
  p.model.mass = ModelMatrix::diagonal(masses);
  p.model.damping = ModelMatrix::identity(s.d, s.damping);
  p.model.alpha = s.alpha;
  ChainOptions c;
  c.dimension = s.d;
  c.stiffness = 1.5;
  c.cubic = s.cubic;
  c.quartic = s.quartic;
  c.boundary = s.boundary;
  p.model.potential = make_chain_potential(c);
  p.x0.resize(s.d);
  p.v0.resize(s.d);
  for (Eigen::Index i = 0; i < s.d; ++i) {
    const double xi = M_PI * static_cast<double>(i + 1) / static_cast<double>(s.d + 1);
    p.x0[i] = 0.4 * std::sin(xi);
    p.v0[i] = 0.3 * std::sin(2.0 * xi);
  }
  p.t_end = s.t_end;
  p.steps = s.steps;
  return p;
}

Solution run(const InitialValueProblem& p, LinearSolver solver, std::size_t save_every = 1) {
  IntegratorOptions o;
  o.linear_solver = solver;
  o.save_every = save_every;
  Solution sol = integrate(p, fvi_gl(), o);
  EXPECT_TRUE(sol.ok()) << sol.message;
  return sol;
}

TEST(Chain, FactorisationsAgree) {
  ChainSetup s;
  s.d = 60;
  s.steps = 300;
  const InitialValueProblem p = chain_problem(s);
  const Solution banded = run(p, LinearSolver::kBanded);
  const Solution sparse = run(p, LinearSolver::kSparse);
  const Solution dense = run(p, LinearSolver::kDense);
  const Solution automatic = run(p, LinearSolver::kAuto);
  InitialValueProblem dense_storage = p;
  dense_storage.model.mass = p.model.mass.to_dense();
  dense_storage.model.damping = p.model.damping.to_dense();
  const Solution dense_model = run(dense_storage, LinearSolver::kAuto);
  EXPECT_EQ(banded.linear_solver, "banded");
  EXPECT_EQ(sparse.linear_solver, "sparse");
  EXPECT_EQ(dense.linear_solver, "dense");
  EXPECT_EQ(automatic.linear_solver, "banded");
  EXPECT_EQ(dense_model.linear_solver, "dense");
  const double scale = banded.x.cwiseAbs().maxCoeff();
  for (const Solution* other : {&sparse, &dense, &dense_model}) {
    EXPECT_LE((other->x - banded.x).cwiseAbs().maxCoeff(), 1e-12 * scale) << other->linear_solver;
    EXPECT_LE((other->v - banded.v).cwiseAbs().maxCoeff(), 1e-11 * scale) << other->linear_solver;
  }
  EXPECT_EQ(automatic.x, banded.x);
  EXPECT_LE(banded.mirror_error, 1e-11 * scale);
  EXPECT_GE(banded.max_newton_iterations_per_step, 2u);  // nonlinear: Newton really iterates
}

// The structured paths take simplified Newton steps (J kept from the step's first iterate while the
// corrections contract by 4×, refactored otherwise); the dense path takes full Newton steps. With
// large steps and strong quartic springs (h = 0.25, |x| ≈ 0.4, quartic = 200; full Newton takes up
// to 3 iterations a step) both must converge, to the same increments within the Newton tolerance,
// and the banded path needs no more than twice the iterations.
TEST(Chain, SimplifiedNewtonAgreesWithFullNewtonOnLargeSteps) {
  ChainSetup s;
  s.d = 60;
  s.quartic = 200.0;
  s.t_end = 5.0;
  s.steps = 20;
  const InitialValueProblem p = chain_problem(s);
  const Solution banded = run(p, LinearSolver::kBanded);
  const Solution dense = run(p, LinearSolver::kDense);
  ASSERT_EQ(banded.linear_solver, "banded");
  const double scale = banded.x.cwiseAbs().maxCoeff();
  EXPECT_LE((dense.x - banded.x).cwiseAbs().maxCoeff(), 1e-11 * scale);
  EXPECT_GE(dense.max_newton_iterations_per_step, 3u);  // strongly nonlinear steps
  EXPECT_LE(banded.newton_iterations, 2 * dense.newton_iterations);
}

TEST(Chain, PeriodicChainUsesSparseFactorisation) {
  ChainSetup s;
  s.d = 2 * kMaxAutoBandwidth + 10;  // bandwidth d − 1 from the corners
  s.boundary = ChainBoundary::kPeriodic;
  s.steps = 100;
  const InitialValueProblem p = chain_problem(s);
  const Solution automatic = run(p, LinearSolver::kAuto);
  const Solution banded = run(p, LinearSolver::kBanded);
  EXPECT_EQ(automatic.linear_solver, "sparse");
  EXPECT_LE((automatic.x - banded.x).cwiseAbs().maxCoeff(), 1e-12);
}

// Nonlinear FPUT chain against dopri5: order 2 undamped, 1 with viscous damping (declared orders).
TEST(Chain, NonlinearOrdersAgainstOdeint) {
  for (const double damping : {0.0, 0.3}) {
    ChainSetup s;
    s.alpha = 0.5;
    s.damping = damping;
    const InitialValueProblem base = chain_problem(s);
    const Eigen::MatrixXd reference =
        test::dopri5_reference(base.model, base.x0, base.v0, {base.t0, base.t_end});
    std::vector<double> hs, errors;
    for (const std::size_t n : {50u, 100u, 200u, 400u, 800u}) {
      InitialValueProblem p = base;
      p.steps = n;
      const Solution sol = run(p, LinearSolver::kBanded);  // d = 8: kAuto would pick dense
      hs.push_back(p.step_size());
      errors.push_back((sol.x.bottomRows(1) - reference.row(1).head(s.d)).cwiseAbs().maxCoeff());
    }
    const test::OrderFit fit = test::fit_order(
        hs, errors,
        {.floor = test::round_off_floor(reference.row(1).head(s.d).cwiseAbs().maxCoeff())});
    const double slope = fit.slope;
    const int declared = fvi_gl().declared_order(base.model);
    EXPECT_EQ(declared, damping == 0.0 ? 2 : 1);
    EXPECT_NEAR(slope, declared, 0.1) << "damping " << damping << "\n" << fit.table();
    RecordProperty(damping == 0.0 ? "order_undamped" : "order_viscous", std::to_string(slope));
  }
}

// Fractional damping 2α = 3/2 (Caputo, non-zero x0 and v0) on a linear chain: K tridiagonal, the
// Laplace-inversion reference works with the full matrices.
TEST(Chain, FractionalLinearChainOrderAgainstLaplaceInversion) {
  ChainSetup s;
  s.d = 6;
  s.alpha = 0.75;
  s.damping = 0.3;
  s.cubic = s.quartic = 0.0;
  s.t_end = 3.0;
  const InitialValueProblem base = chain_problem(s);
  test::LinearOscillator reference_problem;
  reference_problem.mass = base.model.mass.to_dense();
  reference_problem.damping = base.model.damping.to_dense();
  reference_problem.stiffness = Eigen::MatrixXd(s.d, s.d);
  base.model.potential->hessian(Eigen::VectorXd::Zero(s.d), 0.0, reference_problem.stiffness);
  reference_problem.beta = 1.5;
  reference_problem.x0 = base.x0;
  reference_problem.v0 = base.v0;
  const test::LaplaceInversion exact(reference_problem);
  const Eigen::VectorXd x_end = exact(s.t_end);
  std::vector<double> hs, errors;
  for (const std::size_t n : {100u, 200u, 400u, 800u, 1600u}) {
    InitialValueProblem p = base;
    p.steps = n;
    const Solution sol = run(p, LinearSolver::kBanded);  // d = 6: kAuto would pick dense
    hs.push_back(p.step_size());
    errors.push_back((sol.x.bottomRows(1).transpose() - x_end).cwiseAbs().maxCoeff());
  }
  const test::OrderFit fit =
      test::fit_order(hs, errors, {.floor = test::round_off_floor(x_end.cwiseAbs().maxCoeff())});
  const double slope = fit.slope;
  EXPECT_NEAR(slope, fvi_gl().declared_order(base.model), 0.1) << fit.table();
  RecordProperty("order_fractional_chain", std::to_string(slope));
}

TEST(Chain, StoringEveryNthStepKeepsTheSameRows) {
  ChainSetup s;
  s.d = 20;
  s.steps = 100;
  const InitialValueProblem p = chain_problem(s);
  const Solution full = run(p, LinearSolver::kAuto);
  const Solution thin = run(p, LinearSolver::kAuto, 7);
  ASSERT_EQ(thin.t.size(), 16);  // 0, 7, …, 98 and the last step 100
  EXPECT_EQ(thin.save_every, 7u);
  for (Eigen::Index i = 0; i < thin.t.size(); ++i) {
    const std::size_t k = thin.step[static_cast<std::size_t>(i)];
    EXPECT_EQ(k, i + 1 < thin.t.size() ? static_cast<std::size_t>(7 * i) : 100u);
    const auto kk = static_cast<Eigen::Index>(k);
    EXPECT_EQ(thin.t(i), full.t(kk));
    EXPECT_EQ(thin.x.row(i), full.x.row(kk));
    EXPECT_EQ(thin.v.row(i), full.v.row(kk));
    EXPECT_EQ(thin.energy(i), full.energy(kk));
    EXPECT_EQ(thin.balance(i), full.balance(kk));
  }
  EXPECT_EQ(thin.max_balance_error, full.max_balance_error);  // every step, not only stored ones
  EXPECT_TRUE(std::isfinite(thin.mirror_error));
  EXPECT_LE(thin.mirror_error, full.mirror_error);
}

// A potential that throws from t = 0.0655 on (test::ThrowingAfter): the run stops at step 7, the
// stored rows are the steps 0 and 5 and the last completed one (7).

TEST(Chain, FailureBetweenStoredRowsKeepsTheLastStep) {
  ChainSetup s;
  s.d = 10;
  s.t_end = 1.0;
  s.steps = 100;  // h = 0.01: step k evaluates ∇U at t_{k+½}
  InitialValueProblem p = chain_problem(s);
  p.model.potential = std::make_shared<const test::ThrowingAfter>(p.model.potential, 0.0655);
  IntegratorOptions o;
  o.save_every = 5;
  const Solution sol = integrate(p, fvi_gl(), o);
  EXPECT_EQ(sol.status, Status::kCallbackError);
  EXPECT_EQ(sol.steps_done, 7u);
  ASSERT_EQ(sol.step, (std::vector<std::size_t>{0, 5, 7}));
  EXPECT_NE(sol.message.find("out of range"), std::string::npos) << sol.message;
  EXPECT_TRUE(sol.x.allFinite());
  EXPECT_DOUBLE_EQ(sol.t(2), 0.07);
}

TEST(Chain, OptionsAreValidated) {
  const InitialValueProblem p = chain_problem(ChainSetup{});
  IntegratorOptions o;
  // A forced dense factorisation of a 10^5-mass chain would need 240 GB: refused up front.
  ChainSetup big;
  big.d = 100000;
  o.linear_solver = LinearSolver::kDense;
  try {
    Integrator integ(chain_problem(big), fvi_gl(), o);
    ADD_FAILURE() << "accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("d = 100000"), std::string::npos) << e.what();
  }
  o = IntegratorOptions{};
  o.save_every = 0;
  EXPECT_THROW(Integrator(p, fvi_gl(), o), ValidationError);
  o = IntegratorOptions{};
  o.threads = -2;
  EXPECT_THROW(Integrator(p, fvi_gl(), o), ValidationError);
}

// The sums a CQ midpoint step forms in its fused passes for the Integrator (Stepper::step_sums:
// v·p for the kinetic energy, ‖x‖²_M for the health check) are bit for bit those of the passes the
// Integrator would run, at every step, for diagonal M ≠ I and M = I, with and without
// diagnostics; below kVectorPassesFrom (where the Integrator keeps Eigen's sums) none are formed,
// and neither by fvi-midpoint's step (TrapezoidalMidpointStepper, no fused passes).
TEST(Chain, StepSumsAreTheIntegratorsPassesBitForBit) {
  for (const char* scheme : {"fvi-gl", "fvi-bdf2", "fvi-midpoint"}) {
    const bool fused = std::string(scheme) != "fvi-midpoint";
    for (const Eigen::Index d : {Eigen::Index{8}, Eigen::Index{101}}) {
      for (const bool unit_mass : {false, true}) {
        for (const bool diagnostics : {true, false}) {
          ChainSetup s;
          s.d = d;
          s.steps = 20;
          InitialValueProblem p = chain_problem(s);
          if (unit_mass) p.model.mass = ModelMatrix::identity(d);
          IntegratorOptions o;
          o.diagnostics = diagnostics;
          o.mirror = false;
          const std::unique_ptr<Stepper> stepper = find_scheme(scheme)->make_stepper(p, o);
          Eigen::VectorXd root_mass(d);
          for (Eigen::Index i = 0; i < d; ++i) root_mass[i] = std::sqrt(p.model.mass.coeff(i, i));
          const bool vector = d >= internal::kVectorPassesFrom;
          for (std::size_t k = 1; k <= s.steps; ++k) {
            ASSERT_EQ(stepper->step(), Status::kSuccess) << stepper->failure_message();
            const Stepper::StepSums& sums = stepper->step_sums();
            const std::string where =
                std::string(scheme) + ", d = " + std::to_string(d) + ", step " + std::to_string(k);
            if (!vector || !fused) {
              EXPECT_FALSE(sums.has_mass_squares || sums.has_velocity_momentum) << where;
              continue;
            }
            // Step 1 of fvi-gl's paper start runs the Euler start, outside the fused passes.
            if (!sums.has_mass_squares) {
              EXPECT_EQ(k, 1u) << where;
              continue;
            }
            EXPECT_EQ(sums.step, k) << where;
            const Eigen::VectorXd &x = stepper->position(), &v = stepper->velocity(),
                                  &mom = stepper->momentum();
            EXPECT_EQ(sums.mass_squares,
                      internal::weighted_squares_pass(root_mass.data(), x.data(), d))
                << where;
            EXPECT_EQ(sums.has_velocity_momentum, diagnostics) << where;
            if (diagnostics) {
              EXPECT_EQ(sums.velocity_momentum, internal::dot_pass(v.data(), mom.data(), d))
                  << where;
            }
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace fracvi
