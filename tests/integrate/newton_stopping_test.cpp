// Newton's stopping rule (newton_converged, core/newton_options.hpp) and MidpointNewton under it:
// a slowly contracting iteration must not stop with more than the tolerance left.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <vector>

#include "fracvi/core/newton_options.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "fracvi/solve/vector_passes.hpp"

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

// A time-independent potential of d uncoupled sites: its Hessian pattern is the diagonal, so the
// banded path can factor its Newton matrix.
class DiagonalHessianPotential : public Potential {
 public:
  explicit DiagonalHessianPotential(Eigen::Index d) : d_(d) {}
  [[nodiscard]] Eigen::Index dimension() const override { return d_; }
  [[nodiscard]] bool is_time_dependent() const override { return false; }
  [[nodiscard]] bool has_sparse_hessian() const override { return true; }
  [[nodiscard]] std::vector<HessianEntry> hessian_pattern() const override {
    std::vector<HessianEntry> pattern;
    for (Eigen::Index i = 0; i < d_; ++i) pattern.push_back({i, i});
    return pattern;
  }

 protected:
  Eigen::Index d_;
};

// The fused passes of a step (solve/vector_passes.hpp), inlined below 32 elements and in their
// kernels above (both tested): each finiteness check must notice one ∞ or NaN anywhere, in any
// element the pass writes (a fast max may drop a NaN), the max is exact, and the values are the
// expressions' (to one rounding: the x86-64-v3 clone fuses products into FMAs).
TEST(VectorisedPasses, FusedPassesNoticeOneBadEntryAnywhereAndGiveTheirValues) {
  for (const Eigen::Index n : {1, 2, 33, 1000, 1001}) {
    const Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(n, -1e300, 3.0);
    const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(n, 2.0, -5.0);
    const Eigen::VectorXd m = Eigen::VectorXd::LinSpaced(n, 1.0, 4.0);
    const Eigen::VectorXd g =
        Eigen::VectorXd::LinSpaced(n, 3.0, -7.0);  // max|g_i| at a negative g_i
    const double s = 0.375;
    Eigen::VectorXd out(n), mid(n);
    EXPECT_TRUE(internal::all_finite_pass(v.data(), n)) << n;
    EXPECT_TRUE(internal::add_and_check(v.data(), w.data(), out.data(), n)) << n;
    EXPECT_EQ(out, v + w) << n;  // one addition: no product to fuse
    EXPECT_TRUE(
        internal::diagonal_residual(m.data(), w.data(), s, g.data(), v.data(), out.data(), n));
    const Eigen::VectorXd residual = (m.array() * w.array() + s * g.array()) - v.array();
    const Eigen::VectorXd scale =
        (m.array() * w.array()).abs() + (s * g.array()).abs() + v.array().abs();
    EXPECT_LE(((out - residual).array().abs() - 4e-16 * scale.array()).maxCoeff(), 0.0) << n;
    out = m;
    EXPECT_TRUE(internal::general_residual(s, g.data(), v.data(), out.data(), n));
    const Eigen::VectorXd general = (m.array() + s * g.array()) - v.array();
    EXPECT_LE(((out - general).array().abs() -
               4e-16 * (m.array().abs() + (s * g.array()).abs() + v.array().abs()))
                  .maxCoeff(),
              0.0)
        << n;
    for (const bool with_next : {false, true}) {
      Eigen::VectorXd increment = w;
      const internal::CorrectionPass pass = internal::apply_correction_pass(
          g.data(), v.data(), increment.data(), mid.data(), n, with_next);
      EXPECT_EQ(increment, w - g);
      EXPECT_EQ(pass.size, g.cwiseAbs().maxCoeff()) << n;
      EXPECT_TRUE(pass.finite);
      if (with_next) {
        EXPECT_EQ(pass.scale, (v + increment).cwiseAbs().maxCoeff()) << n;
        EXPECT_EQ(mid, v + 0.5 * increment) << n;
      }
    }
    // The passes without a check: each element within one rounding of its expression.
    auto near = [n](const Eigen::VectorXd& got, const Eigen::VectorXd& want,
                    const Eigen::VectorXd& size) {
      EXPECT_LE(((got - want).array().abs() - 4e-16 * size.array()).maxCoeff(), 0.0) << n;
    };
    const double t = 0.625;
    EXPECT_EQ(internal::midpoint_pass(v.data(), w.data(), out.data(), n), 0.0) << n;
    EXPECT_EQ(out, v + 0.5 * w) << n;
    out.setZero();
    EXPECT_EQ(internal::midpoint_pass(v.data(), w.data(), out.data(), n, true),
              v.cwiseAbs().maxCoeff())
        << n;  // max|v_i| at a negative v_i
    EXPECT_EQ(out, v + 0.5 * w) << n;
    Eigen::VectorXd rhs(n);
    internal::start_momentum_pass(v.data(), g.data(), t, s, out.data(), rhs.data(), n);
    near(out, v - t * g, v.cwiseAbs() + t * g.cwiseAbs());
    EXPECT_EQ(rhs, s * out) << n;
    out = m;
    internal::scale_and_subtract_pass(t, g.data(), out.data(), n);
    near(out, m * t - g, t * m.cwiseAbs() + g.cwiseAbs());
    internal::subtract_scaled_pass(w.data(), t, g.data(), out.data(), n);
    near(out, w - t * g, w.cwiseAbs() + t * g.cwiseAbs());
    internal::shifted_pass(v.data(), w.data(), t, g.data(), out.data(), n);
    near(out, (v - w) - t * g, v.cwiseAbs() + w.cwiseAbs() + t * g.cwiseAbs());
    internal::shifted_pass(v.data(), nullptr, t, g.data(), out.data(), n);
    near(out, v - t * g, v.cwiseAbs() + t * g.cwiseAbs());
    internal::shifted_pass(v.data(), w.data(), t, nullptr, out.data(), n);
    EXPECT_EQ(out, v - w) << n;
    internal::shifted_pass(v.data(), nullptr, t, nullptr, out.data(), n);
    EXPECT_EQ(out, v) << n;
    const double squares = internal::weighted_squares_pass(m.data(), g.data(), n);
    EXPECT_LE(std::abs(squares - (m.array() * g.array()).square().sum()),
              4e-16 * static_cast<double>(n) * (m.array() * g.array()).square().sum())
        << n;
    const double dot = internal::dot_pass(w.data(), g.data(), n);
    EXPECT_LE(std::abs(dot - w.dot(g)),
              4e-16 * static_cast<double>(n) * w.cwiseAbs().dot(g.cwiseAbs()))
        << n;
    for (const double bad : {kInf, -kInf, std::nan("")}) {
      for (const Eigen::Index at : {Eigen::Index{0}, n / 2, n - 1}) {
        Eigen::VectorXd x = w;
        x[at] = bad;
        EXPECT_FALSE(internal::all_finite_pass(x.data(), n)) << n << " " << at << " " << bad;
        EXPECT_FALSE(internal::add_and_check(m.data(), x.data(), out.data(), n)) << n << " " << at;
        EXPECT_FALSE(
            internal::diagonal_residual(m.data(), w.data(), s, x.data(), g.data(), out.data(), n))
            << n << " " << at;
        out = m;
        EXPECT_FALSE(internal::general_residual(s, g.data(), x.data(), out.data(), n))
            << n << " " << at;
        Eigen::VectorXd increment = m;
        EXPECT_FALSE(internal::apply_correction_pass(x.data(), g.data(), increment.data(),
                                                     mid.data(), n, true)
                         .finite)
            << n << " " << at;
      }
    }
  }
  EXPECT_TRUE(internal::all_finite_pass(nullptr, 0));
}

// U = ½ k Σ x_i², whose hessian() reports s·k instead of k: the Newton matrix is then off by a
// known factor, and the iteration contracts linearly at θ = |1 − J/Ĵ| with J = A + (h²/4) k the
// true and Ĵ = A + (h²/4) s k the used matrix — what a kept (stale) factorisation does, with a
// rate chosen by the test.
class MisreportedHessian final : public DiagonalHessianPotential {
 public:
  MisreportedHessian(Eigen::Index d, double k, double s)
      : DiagonalHessianPotential(d), k_(k), s_(s) {}
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
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>&, double,
                      std::span<double> values) const override {
    for (double& v : values) v = s_ * k_;
  }

 private:
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

// U = Σ (k/2) x_i² + (b/4) x_i⁴ with its true (diagonal) Hessian: a nonlinear potential whose
// Newton matrix the banded path may keep from call to call.
class QuarticSites final : public DiagonalHessianPotential {
 public:
  QuarticSites(Eigen::Index d, double k, double b) : DiagonalHessianPotential(d), k_(k), b_(b) {}
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    return (0.5 * k_ * x.array().square() + 0.25 * b_ * x.array().pow(4)).sum();
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g = (k_ * x.array() + b_ * x.array().cube()).matrix();
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    H = (k_ + 3.0 * b_ * x.array().square()).matrix().asDiagonal();
  }
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                      std::span<double> values) const override {
    for (Eigen::Index i = 0; i < d_; ++i)
      values[static_cast<std::size_t>(i)] = k_ + 3.0 * b_ * x[i] * x[i];
  }

 private:
  double k_, b_;
};

// A sequence of solves along the motion a(t) = A sin(t + 0.3 i) (a step of dt per call) by the
// banded path, which may keep J from call to call, and by the dense path (full Newton: J formed
// at every iterate), from the same predictor: full Newton's previous increment.
struct KeptRun {
  std::size_t factorizations = 0;  // the banded path's
  double worst = 0.0;              // max |Δ_banded − Δ_dense| / tolerance
  int min_iterations = 1000;       // the banded path's, after the first call
  int iterations = 0, full_iterations = 0;
  int first_stops = 0;  // calls of the banded path that stopped at their first correction
  double worst_first =
      0.0;  // max |Δ_banded − Δ_dense| over those, in units of 4ε max(|a|, |a + Δ|)
};

KeptRun run_kept(double h, double dt, double amplitude, int calls) {
  const Eigen::Index d = 16;
  const QuarticSites potential(d, 1.0, 4.0);
  NewtonOptions options;  // the defaults: rtol 1e-12
  internal::MidpointNewton kept(ModelMatrix::identity(d), h, &potential, options, 0.0,
                                LinearSolver::kBanded);
  internal::MidpointNewton full(ModelMatrix::identity(d), h, &potential, options, 0.0,
                                LinearSolver::kDense);
  EXPECT_EQ(kept.linear_solver(), LinearSolver::kBanded);
  EXPECT_EQ(full.linear_solver(), LinearSolver::kDense);
  Eigen::VectorXd a(d), c(d), inc_kept(d), inc_full(d);
  KeptRun run;
  for (int k = 0; k < calls; ++k) {
    const double t = dt * k;
    for (Eigen::Index i = 0; i < d; ++i) {
      a[i] = amplitude * std::sin(t + 0.3 * static_cast<double>(i));
      c[i] = h * h * amplitude * std::cos(t + 0.3 * static_cast<double>(i));
    }
    // The integrator's predictor, the last increment (the same for both).
    if (k == 0) inc_full.setConstant(h * 0.1);
    inc_kept = inc_full;
    const internal::NewtonReport r = kept.solve(a, t, c, nullptr, inc_kept);
    const internal::NewtonReport f = full.solve(a, t, c, nullptr, inc_full);
    EXPECT_EQ(r.status, Status::kSuccess) << "call " << k;
    EXPECT_EQ(f.status, Status::kSuccess) << "call " << k;
    run.worst = std::max(run.worst, (inc_kept - inc_full).cwiseAbs().maxCoeff() / r.tolerance);
    if (k > 0) run.min_iterations = std::min(run.min_iterations, r.iterations);
    if (r.iterations == 1) {
      ++run.first_stops;
      const double roundoff =
          4.0 * std::numeric_limits<double>::epsilon() *
          std::max(a.cwiseAbs().maxCoeff(), (a + inc_kept).cwiseAbs().maxCoeff());
      run.worst_first =
          std::max(run.worst_first, (inc_kept - inc_full).cwiseAbs().maxCoeff() / roundoff);
    }
    run.iterations += r.iterations;
    run.full_iterations += f.iterations;
  }
  run.factorizations = kept.factorizations();
  return run;
}

// Small steps along a slow motion (h = 0.01, the state moving 10× slower than a step's
// increment: the predictor's error is small): a J kept from the last call contracts by ≈ 1e-5, and
// the banded path factors in a small fraction of the calls (32 of 200 when written) while taking as
// many corrections as full Newton (401), every increment within the tolerance of full Newton's.
// A first correction leaves ≈ 1e-5 of itself here, far above round-off: no call stops at it.
TEST(MidpointNewtonKeptJacobian, FactorsRarelyAlongASmoothMotionAndMeetsTheTolerance) {
  const KeptRun run = run_kept(0.01, 0.001, 0.8, 200);
  std::printf("h = 0.01: %zu factorisations, %d / %d iterations (banded / dense), worst %.3g\n",
              run.factorizations, run.iterations, run.full_iterations, run.worst);
  EXPECT_LE(run.factorizations, 40u);
  EXPECT_LE(run.worst, 2.0);  // each within its tolerance of the exact increment
  EXPECT_EQ(run.first_stops, 0);
  EXPECT_LE(run.worst_first, 1.0);  // were one to stop there, round-off would be all it left
  EXPECT_LE(run.iterations, run.full_iterations + 10);
}

// A motion 100× slower (dt = 1e-5, amplitude 0.1): the carried J contracts so well that its
// contraction, observed at a second correction and aged (θ̂^0.8 per call), predicts the next
// correction below round-off, and half the calls stop at their first correction (200 of 400 when
// written). Those increments are full Newton's to round-off: 0.015 round-off units (4ε max|a|)
// when written. (Taking the estimate from a J formed in the same call, which contracts far better
// than it will once carried, let first corrections stop with 54 units left in the test above.)
TEST(MidpointNewtonKeptJacobian, StopsAtItsFirstCorrectionOnlyAtRoundOff) {
  const KeptRun run = run_kept(0.01, 1e-5, 0.1, 400);
  std::printf(
      "dt = 1e-5: %d / %d iterations (banded / dense), %d calls stopped at their first "
      "correction, worst %.3g round-off units\n",
      run.iterations, run.full_iterations, run.first_stops, run.worst_first);
  EXPECT_GE(run.first_stops, 100);
  EXPECT_LE(run.worst_first, 1.0);
  EXPECT_LE(run.worst, 2.0);
  EXPECT_LT(run.iterations, run.full_iterations);
}

// Large steps (h = 0.2: (h²/4)∇²U up to 9 % of J; full Newton takes three corrections a call):
// no call converges at its second correction, so J is never carried into the next call — one
// factorisation per call, as before J was carried — and every increment meets the tolerance.
TEST(MidpointNewtonKeptJacobian, ASlowlyConvergingJacobianIsNotCarriedOver) {
  const KeptRun run = run_kept(0.2, 0.02, 0.8, 200);
  std::printf("h = 0.2: %zu factorisations, %d / %d iterations (banded / dense), worst %.3g\n",
              run.factorizations, run.iterations, run.full_iterations, run.worst);
  EXPECT_EQ(run.factorizations, 200u);
  EXPECT_LE(run.worst, 2.0);
}

}  // namespace
}  // namespace fracvi
