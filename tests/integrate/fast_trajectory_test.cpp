// Whole trajectories with the fast history (sum-of-exponentials tail, DESIGN §6) against the
// direct history: a nonlinear fractional oscillator must agree to 1e-10 relative, `auto` must pick
// the fast history above the crossover, and the mirror check must stay at round-off.
#include <gtest/gtest.h>

#include <cstdio>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/memory/fast_history.hpp"
#include "fracvi/model/autodiff_potential.hpp"

namespace fracvi {
namespace {

struct Duffing {
  template <class T>
  T operator()(const Eigen::Matrix<T, 1, 1>& x, T) const {
    return T(0.5) * x(0) * x(0) + T(0.25) * x(0) * x(0) * x(0) * x(0);
  }
};

InitialValueProblem oscillator(double alpha, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Constant(1, 1, 1.0);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.4);
  p.model.alpha = alpha;
  p.model.convention = Convention::kCaputo;
  p.model.potential = make_autodiff_potential<1>(Duffing{}, 1, {.time_dependent = false});
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) { f(0) = 0.3 * std::cos(1.1 * t); };
  p.x0 = Eigen::VectorXd::Constant(1, 1.5);
  p.v0 = Eigen::VectorXd::Constant(1, -0.2);
  p.t_end = 200.0;
  p.steps = steps;
  return p;
}

Solution run(const InitialValueProblem& p, HistoryKind kind, bool mirror = false) {
  IntegratorOptions o;
  o.history = kind;
  o.mirror = mirror;
  o.newton.relative_tolerance = 1e-14;
  return integrate(p, fvi_gl(), o);
}

TEST(FastHistoryTrajectory, NonlinearFractionalOscillatorAgreesWithDirectHistory) {
  for (double alpha : {0.3, 0.75}) {
    const InitialValueProblem p = oscillator(alpha, 20000);
    const Solution direct = run(p, HistoryKind::kDirect);
    const Solution fast = run(p, HistoryKind::kFast);
    ASSERT_TRUE(direct.ok() && fast.ok()) << direct.message << fast.message;
    const double scale = direct.x.cwiseAbs().maxCoeff();
    const double diff = (fast.x - direct.x).cwiseAbs().maxCoeff() / scale;
    const double vdiff = (fast.v - direct.v).cwiseAbs().maxCoeff() / direct.v.cwiseAbs().maxCoeff();
    std::printf(
        "[measured] alpha = %.2f, N = 20000: max|x_fast - x_direct|/max|x| = %.2e, "
        "velocities %.2e; wall %.3f s (fast) vs %.3f s (direct)\n",
        alpha, diff, vdiff, fast.wall_time_seconds, direct.wall_time_seconds);
    EXPECT_LE(diff, 1e-10) << "alpha = " << alpha;
    EXPECT_LE(vdiff, 1e-10) << "alpha = " << alpha;
  }
}

TEST(FastHistoryTrajectory, AutoChoosesFastAboveTheCrossoverAndDirectBelow) {
  const InitialValueProblem large = oscillator(0.75, 2 * kFastHistoryCrossover);
  const Solution automatic = run(large, HistoryKind::kAuto);
  const Solution fast = run(large, HistoryKind::kFast);
  EXPECT_EQ((automatic.x - fast.x).cwiseAbs().maxCoeff(), 0.0);  // the same object, bitwise
  const InitialValueProblem small = oscillator(0.75, kFastHistoryCrossover / 4);
  const Solution automatic_small = run(small, HistoryKind::kAuto);
  const Solution direct_small = run(small, HistoryKind::kDirect);
  EXPECT_EQ((automatic_small.x - direct_small.x).cwiseAbs().maxCoeff(), 0.0);
}

TEST(FastHistoryTrajectory, MirrorErrorStaysAtRoundOff) {
  // The y-run uses the same cached fit, so it is the exact mirror of the x-run's equations.
  const Solution fast = run(oscillator(0.75, 8000), HistoryKind::kFast, /*mirror=*/true);
  ASSERT_TRUE(fast.ok()) << fast.message;
  std::printf("[measured] mirror error with the fast history: %.2e\n", fast.mirror_error);
  EXPECT_LT(fast.mirror_error, 1e-11);
}

TEST(FastHistoryTrajectory, ToleranceIsValidated) {
  IntegratorOptions o;
  o.history_tolerance = 0.1;
  EXPECT_THROW(validate(o), ValidationError);
}

}  // namespace
}  // namespace fracvi
