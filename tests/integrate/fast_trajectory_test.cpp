// Whole trajectories with the fast history (sum-of-exponentials tail, DESIGN §6) against the
// direct history, for every registered scheme with a fast history (SchemeInfo::fast_history): a
// nonlinear fractional oscillator must agree to 1e-10 relative, `auto` must pick the fast history
// above the crossover, and the mirror check must stay at round-off.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "../support/test_problems.hpp"
#include "fracvi/fractional/exponential_fit.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/memory/fast_history.hpp"
#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {
namespace {

InitialValueProblem oscillator(double alpha, std::size_t steps) {
  return test::forced_duffing(alpha, steps);
}

Solution run(const InitialValueProblem& p, const Method& method, HistoryKind kind,
             bool mirror = false, double tolerance = kDefaultFitTolerance) {
  IntegratorOptions o;
  o.history = kind;
  o.history_tolerance = tolerance;
  o.mirror = mirror;
  o.newton.relative_tolerance = 1e-14;
  return integrate(p, method, o);
}

/// The registered schemes with a fast history.
// The schemes with a fast history that run this file's oscillator (α = 0.3 and 0.75, N = 20000)
// within their stability bound at its coarsest grid (euler-explicit's bound is h < 0.066 there,
// h = 0.2: it is left out).
std::vector<Method> fast_schemes() {
  std::vector<Method> out;
  for (const SchemeInfo* info : registered_schemes()) {
    if (!info->fast_history) continue;
    if (!info->stability(oscillator(0.75, 1024)).stable) continue;
    out.emplace_back(*info);
  }
  return out;
}

TEST(FastHistoryTrajectory, NonlinearFractionalOscillatorAgreesWithDirectHistory) {
  for (const Method& method : fast_schemes()) {
    for (double alpha : {0.3, 0.75}) {
      const InitialValueProblem p = oscillator(alpha, 20000);
      const Solution direct = run(p, method, HistoryKind::kDirect);
      const Solution fast = run(p, method, HistoryKind::kFast);
      ASSERT_TRUE(direct.ok() && fast.ok()) << direct.message << fast.message;
      const double scale = direct.x.cwiseAbs().maxCoeff();
      const double diff = (fast.x - direct.x).cwiseAbs().maxCoeff() / scale;
      const double vdiff =
          (fast.v - direct.v).cwiseAbs().maxCoeff() / direct.v.cwiseAbs().maxCoeff();
      std::printf(
          "[measured] %s, alpha = %.2f, N = 20000: max|x_fast - x_direct|/max|x| = %.2e, "
          "velocities %.2e; wall %.3f s (fast) vs %.3f s (direct)\n",
          std::string(method.name()).c_str(), alpha, diff, vdiff, fast.wall_time_seconds,
          direct.wall_time_seconds);
      EXPECT_LE(diff, 1e-10) << method.name() << ", alpha = " << alpha;
      // The velocities see the positions also through the damping force in the momenta, a CQ
      // with weights ω (SchemeInfo::momentum_quadrature). For GL and BDF2 Σ|ω| ≤ 4^{2α}; the
      // trapezoidal weights of fvi-midpoint grow like (−1)^m m^{2α−1} (theory/fvi_midpoint.md §9),
      // so for 2α > 1 any two equivalent computations (fast or direct, or two summation orders)
      // differ in v by round-off of the positions amplified at the highest grid frequency: 3e-10
      // here, whatever the fit tolerance (1.4e-10 at ε = 1e-12). That component alternates in
      // sign from step to step; the two-step averages (v_k + v_{k+1})/2, in which it cancels,
      // must agree to 1e-10 like everything else.
      const double beta = 2.0 * alpha;
      const bool trapezoidal_momenta = method.info().momentum_quadrature == CqScheme::kTrapezoidal;
      if (trapezoidal_momenta && beta > 1.0) {
        const Eigen::Index rows = direct.v.rows();
        const Eigen::MatrixXd avg_fast =
            0.5 * (fast.v.topRows(rows - 1) + fast.v.bottomRows(rows - 1));
        const Eigen::MatrixXd avg_direct =
            0.5 * (direct.v.topRows(rows - 1) + direct.v.bottomRows(rows - 1));
        const double vavg =
            (avg_fast - avg_direct).cwiseAbs().maxCoeff() / direct.v.cwiseAbs().maxCoeff();
        std::printf("[measured] %s, alpha = %.2f: two-step averaged velocities %.2e\n",
                    std::string(method.name()).c_str(), alpha, vavg);
        EXPECT_LE(vavg, 1e-10) << method.name() << ", alpha = " << alpha;
      } else {
        EXPECT_LE(vdiff, 1e-10) << method.name() << ", alpha = " << alpha;
      }
    }
  }
}

TEST(FastHistoryTrajectory, AutoChoosesFastAboveTheCrossoverAndDirectBelow) {
  for (const Method& method : fast_schemes()) {
    const InitialValueProblem large = oscillator(0.75, 2 * kFastHistoryCrossover);
    const Solution automatic = run(large, method, HistoryKind::kAuto);
    const Solution fast = run(large, method, HistoryKind::kFast);
    // The same objects, bitwise.
    EXPECT_EQ((automatic.x - fast.x).cwiseAbs().maxCoeff(), 0.0) << method.name();
    // Below every scheme's crossover (pi-trapezoid's FFT sums start at 512 steps).
    const InitialValueProblem small = oscillator(0.75, 500);
    const Solution automatic_small = run(small, method, HistoryKind::kAuto);
    const Solution direct_small = run(small, method, HistoryKind::kDirect);
    EXPECT_EQ((automatic_small.x - direct_small.x).cwiseAbs().maxCoeff(), 0.0) << method.name();
  }
}

TEST(FastHistoryTrajectory, MirrorErrorStaysAtRoundOff) {
  // The y-run uses the same cached fits, so it is the exact mirror of the x-run's equations.
  for (const Method& method : fast_schemes()) {
    if (!method.info().has_mirror) continue;
    const Solution fast = run(oscillator(0.75, 8000), method, HistoryKind::kFast, /*mirror=*/true);
    ASSERT_TRUE(fast.ok()) << fast.message;
    std::printf("[measured] %s: mirror error with the fast history: %.2e\n",
                std::string(method.name()).c_str(), fast.mirror_error);
    EXPECT_LT(fast.mirror_error, 1e-11) << method.name();
  }
}

TEST(FastHistoryTrajectory, ToleranceIsValidated) {
  IntegratorOptions o;
  o.history_tolerance = 0.1;
  EXPECT_THROW(validate(o), ValidationError);
}

}  // namespace
}  // namespace fracvi
