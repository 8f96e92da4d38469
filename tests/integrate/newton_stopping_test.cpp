// Newton's stopping rule (newton_converged, core/newton_options.hpp) and MidpointNewton under it:
// a slowly contracting iteration must not stop with more than the tolerance left.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <span>
#include <vector>

#include "fracvi/core/newton_options.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/solve/midpoint_newton.hpp"

namespace fracvi {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(NewtonConverged, TheCorrectionMustMeetTheTolerance) {
  EXPECT_TRUE(newton_converged(1e-12, 1e-12, 0.0, 0.0));
  EXPECT_FALSE(newton_converged(1.0000001e-12, 1e-12, 0.0, 0.0));
  EXPECT_FALSE(newton_converged(std::nan(""), 1e-12, 0.0, 0.0));
  EXPECT_TRUE(newton_converged(0.0, 1e-12, kInf, 0.0));  // the iterate solves the equation
}

TEST(NewtonConverged, SlowContractionMustAlsoBoundTheErrorLeft) {
  // θ ≤ ½: θ/(1 − θ) ≤ 1, the correction bounds the error left.
  EXPECT_TRUE(newton_converged(1e-12, 1e-12, 0.5, 0.0));
  // θ = 0.9: the error left is ≈ 9 ‖δ‖.
  EXPECT_FALSE(newton_converged(1e-12, 1e-12, 0.9, 0.0));
  EXPECT_FALSE(newton_converged(0.12e-12, 1e-12, 0.9, 0.0));
  EXPECT_TRUE(newton_converged(0.11e-12, 1e-12, 0.9, 0.0));
  // No contraction (θ ≥ 1) or unknown (a matrix from an earlier step, θ = +∞): not converged
  // above the round-off level, converged at it.
  EXPECT_FALSE(newton_converged(1e-14, 1e-12, 1.0, 1e-16));
  EXPECT_FALSE(newton_converged(1e-14, 1e-12, kInf, 1e-16));
  EXPECT_TRUE(newton_converged(1e-16, 1e-12, 1.3, 1e-16));
}

// U = ½ k Σ x_i², whose hessian() reports s·k instead of k: the Newton matrix is then off by a
// known factor, and the iteration contracts linearly at θ = |1 − J/Ĵ| with J = A + (h²/4) k the
// true and Ĵ = A + (h²/4) s k the used matrix — what a kept (stale) factorisation does, with a
// rate chosen by the test. Diagonal Hessian pattern, so the banded path can factor it too.
class MisreportedHessian final : public Potential {
 public:
  MisreportedHessian(Eigen::Index d, double k, double s) : d_(d), k_(k), s_(s) {}
  [[nodiscard]] Eigen::Index dimension() const override { return d_; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    return 0.5 * k_ * x.squaredNorm();
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g = k_ * x;
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>&, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    H = (s_ * k_) * Eigen::MatrixXd::Identity(d_, d_);
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }
  [[nodiscard]] bool has_sparse_hessian() const override { return true; }
  [[nodiscard]] std::vector<HessianEntry> hessian_pattern() const override {
    std::vector<HessianEntry> pattern;
    for (Eigen::Index i = 0; i < d_; ++i) pattern.push_back({i, i});
    return pattern;
  }
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>&, double,
                      std::span<double> values) const override {
    for (double& v : values) v = s_ * k_;
  }

 private:
  Eigen::Index d_;
  double k_, s_;
};

// A = I, h = 1, k = 4: J = 2; s = 9 gives Ĵ = 10 and θ = 0.8, so the error left after δ_k is
// 4 ‖δ_k‖. From a = 1, c = 0 the solution is Δ = −a (a + Δ = 0, so the tolerance is rtol·1);
// the old rule (‖δ‖ ≤ tol alone) stopped with an error in (3.2, 4] × tol.
void expect_error_within_tolerance(Eigen::Index d, LinearSolver solver) {
  const double h = 1.0, k = 4.0;
  const MisreportedHessian potential(d, k, 9.0);
  NewtonOptions options;
  options.relative_tolerance = 1e-12;
  options.max_iterations = 1000;
  internal::MidpointNewton newton(ModelMatrix::identity(d), h, &potential, options, 0.0, solver);
  ASSERT_EQ(newton.linear_solver(), solver);
  const Eigen::VectorXd a = Eigen::VectorXd::Ones(d), c = Eigen::VectorXd::Zero(d);
  Eigen::VectorXd increment = Eigen::VectorXd::Zero(d);
  const internal::NewtonReport report = newton.solve(a, 0.5, c, nullptr, increment);
  ASSERT_EQ(report.status, Status::kSuccess);
  // The solution of I Δ + (h²/2) k (a + Δ/2) = c is Δ = (c − (h²/2) k a)/(1 + (h²/4) k) = −a.
  const double error = (increment + a).cwiseAbs().maxCoeff();
  EXPECT_GT(report.iterations, 100);  // 0.8^k from 1 down to ≈ 2.5e-13
  EXPECT_LE(error, report.tolerance * (1.0 + 1e-3))
      << "iterations " << report.iterations << ", last correction " << report.correction;
  // The rule stops as soon as it may: one correction earlier the estimate 4‖δ‖ was above it.
  EXPECT_GT(error, 0.8 * 0.8 * report.tolerance);
}

TEST(MidpointNewtonStopping, SlowContractionLeavesAtMostTheToleranceDense) {
  expect_error_within_tolerance(1, LinearSolver::kDense);
}

TEST(MidpointNewtonStopping, SlowContractionLeavesAtMostTheToleranceBanded) {
  expect_error_within_tolerance(8, LinearSolver::kBanded);
}

}  // namespace
}  // namespace fracvi
