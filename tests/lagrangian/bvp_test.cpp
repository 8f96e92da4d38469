// The variational boundary value problem: the structured Jacobian against central differences,
// Newton to 1e-10 for a non-mechanical L coupling x and y (dense LU and preconditioned GMRES), the
// mechanical L reproducing an integrator trajectory from its end points (fvi-gl with the
// Grünwald–Letnikov Δ^α_±, fvi-bdf2 with the BDF2 ones), and failures as status.
#include "fracvi/lagrangian/bvp.hpp"

#include <gtest/gtest.h>

#include <cstdio>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;

constexpr Eigen::Index kDim = 2;

Eigen::VectorXd pack(const DiscreteElResidual& r) {
  const Eigen::Index n = r.x_equation.cols() - 1, d = r.x_equation.rows();
  Eigen::VectorXd v(2 * (n - 1) * d);
  for (Eigen::Index j = 1; j < n; ++j) {
    v.segment(2 * d * (j - 1), d) = r.x_equation.col(j);
    v.segment(2 * d * (j - 1) + d, d) = r.y_equation.col(j);
  }
  return v;
}

void curves(std::mt19937_64& rng, Eigen::Index n, Sequence& x, Sequence& y) {
  x.resize(kDim, n + 1);
  y.resize(kDim, n + 1);
  for (Eigen::Index k = 0; k <= n; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(n);
    x.col(k) = Eigen::Vector2d(std::sin(2 * s), 0.5 - s) + test::random_vector(rng, 2, 0.05);
    y.col(k) = Eigen::Vector2d(0.3 * std::cos(3 * s), s) + test::random_vector(rng, 2, 0.05);
  }
}

TEST(DiscreteElJacobian, MatchesCentralDifferencesAndItsOwnProduct) {
  const auto L = make_autodiff_lagrangian(test::Coupled{}, kDim);
  const DiscreteGrid g{0.0, 1.2, 10, 0.6};
  std::mt19937_64 rng(5);
  Sequence x, y;
  curves(rng, g.steps, x, y);
  for (ActionSum sum : {ActionSum::kPrinted, ActionSum::kExtended}) {
    const DiscreteElJacobian jac(*L, g, sum, x, y);
    const Eigen::MatrixXd j = jac.dense();
    // Central differences of the residual: truncation δ²|F'''| and rounding ε|F|/δ, with |F| up to
    // ~1e2/h and δ = 1e-6: ≈ 1e-12·1e2 + 1e-16·1e3/1e-6 ≈ 1e-7 relative to max|J| ≈ 1e2.
    const double delta = 1e-6;
    Eigen::MatrixXd fd(j.rows(), j.cols());
    for (Eigen::Index c = 0; c < j.cols(); ++c) {
      const Eigen::Index point = c / (2 * kDim) + 1, comp = c % kDim;
      const bool is_y = (c / kDim) % 2 == 1;
      Sequence xp = x, xm = x, yp = y, ym = y;
      (is_y ? yp : xp)(comp, point) += delta;
      (is_y ? ym : xm)(comp, point) -= delta;
      fd.col(c) = (pack(discrete_el_residual(*L, xp, yp, g, sum)) -
                   pack(discrete_el_residual(*L, xm, ym, g, sum))) /
                  (2 * delta);
    }
    const double scale = j.cwiseAbs().maxCoeff();
    const double err = (fd - j).cwiseAbs().maxCoeff();
    std::printf("  %s: |J_fd - J| = %.2e (max |J| = %.2e)\n", std::string(to_string(sum)).c_str(),
                err, scale);
    EXPECT_LE(err, 1e-6 * scale);
    // apply() and banded(N) are the same linear map to round-off.
    const Eigen::VectorXd v = test::random_vector(rng, j.cols());
    EXPECT_LE((jac.apply(v) - j * v).cwiseAbs().maxCoeff(),
              64 * kEps * scale * static_cast<double>(j.cols()));
    EXPECT_LE((Eigen::MatrixXd(jac.banded(g.steps)) - j).cwiseAbs().maxCoeff(), 16 * kEps * scale);
    // A narrow band drops the memory tail: a different matrix (not a test of accuracy).
    EXPECT_GT((Eigen::MatrixXd(jac.banded(1)) - j).cwiseAbs().maxCoeff(), 1e-6 * scale);
  }
}

BoundaryValueProblem coupled_problem(Eigen::Index steps) {
  BoundaryValueProblem p;
  p.lagrangian = make_autodiff_lagrangian(test::Coupled{}, kDim);
  p.grid = DiscreteGrid{0.0, 1.5, steps, 0.6};
  p.x_start = Eigen::Vector2d(0.3, -0.2);
  p.x_end = Eigen::Vector2d(-0.4, 0.5);
  return p;
}

TEST(SolveBvp, NonMechanicalCoupledLagrangianDenseAndKrylov) {
  const BoundaryValueProblem p = coupled_problem(60);
  BvpOptions dense;
  dense.linear_solver = BvpLinearSolver::kDense;
  BvpOptions krylov;
  krylov.linear_solver = BvpLinearSolver::kKrylov;
  const BvpSolution a = solve_bvp(p, dense);
  const BvpSolution b = solve_bvp(p, krylov);
  for (const BvpSolution* s : {&a, &b}) {
    ASSERT_TRUE(s->ok()) << s->message;
    std::printf("  %s: %d Newton iterations, %zu GMRES iterations, residual %.2e, %.3f s; history",
                s->linear_solver.c_str(), s->newton_iterations, s->linear_iterations,
                s->residual_norm, s->wall_time_seconds);
    for (double r : s->residual_history) std::printf(" %.1e", r);
    std::printf("\n");
    EXPECT_LE(s->residual_norm, 1e-10);
    EXPECT_LE(s->newton_iterations, 8);
    // The reported residual is the one of the returned curves.
    const DiscreteElResidual r =
        discrete_el_residual(*p.lagrangian, s->x.transpose(), s->y.transpose(), p.grid, p.sum);
    EXPECT_EQ(r.max_norm(), s->residual_norm);
    EXPECT_EQ(s->x.row(0).transpose(), p.x_start);
    EXPECT_EQ(s->y.row(p.grid.steps).transpose(), p.x_start);
  }
  // Same solution from both linear solvers (Newton's fixed point, ‖J⁻¹‖·1e-10 apart at most).
  EXPECT_LE((a.x - b.x).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LE((a.y - b.y).cwiseAbs().maxCoeff(), 1e-9);
  // Not a mirror pair: this L couples x and y, so y is not x reversed.
  EXPECT_GT((a.y - a.x.colwise().reverse()).cwiseAbs().maxCoeff(), 1e-3);
}

InitialValueProblem mechanical_ivp(double alpha) {
  return test::mechanical_ivp(alpha, 1.5, 100);
}

class MechanicalBvp : public ::testing::TestWithParam<double> {};

TEST_P(MechanicalBvp, ReproducesTheIntegratorTrajectoryFromItsEndPoints) {
  const double alpha = GetParam();
  const InitialValueProblem ivp = mechanical_ivp(alpha);
  IntegratorOptions io;
  io.newton.relative_tolerance = 1e-15;
  io.mirror = false;
  const Solution sol = integrate(ivp, fvi_gl(), io);
  ASSERT_TRUE(sol.ok()) << sol.message;
  const auto n = static_cast<Eigen::Index>(ivp.steps);

  BoundaryValueProblem p;
  p.lagrangian = std::make_shared<const MechanicalLagrangian>(ivp.model, ivp.t0, ivp.t_end);
  p.grid = DiscreteGrid{ivp.t0, ivp.t_end, n, alpha};
  p.x_start = sol.x.row(0).transpose();
  p.x_end = sol.x.row(n).transpose();
  const BvpSolution bvp = solve_bvp(p);  // straight-line start
  ASSERT_TRUE(bvp.ok()) << bvp.message;
  const double dx = (bvp.x - sol.x).cwiseAbs().maxCoeff();
  const double dy = (bvp.y - sol.x.colwise().reverse()).cwiseAbs().maxCoeff();
  std::printf(
      "  alpha %.2f: %d Newton iterations, residual %.2e, max|x_bvp - x_ivp| = %.2e, "
      "max|y_bvp - x_ivp(N-k)| = %.2e, %.3f s\n",
      alpha, bvp.newton_iterations, bvp.residual_norm, dx, dy, bvp.wall_time_seconds);
  // Both solve the same equations (`DiscEqs`), the BVP to |F| ≤ 1e-10. The equations are scaled
  // like M/h² = 1e4, so positions agree to ≈ 1e-10·h²·(condition of the discrete BVP ~ N) ≈ 1e-12;
  // 1e-10 leaves room.
  EXPECT_LE(dx, 1e-10);
  EXPECT_LE(dy, 1e-10);

  // The equations of the printed DiscActSum (no L(N)) are a different problem: their x-equation at
  // N−1 is M Δ_−x_{N−1}/h + O(h) = 0, a natural boundary condition ẋ(b) ≈ 0.
  p.sum = ActionSum::kPrinted;
  const BvpSolution other = solve_bvp(p);
  ASSERT_TRUE(other.ok()) << other.message;
  const double diff = (other.x - sol.x).cwiseAbs().maxCoeff();
  const double end_speed =
      (other.x.row(n - 1) - other.x.row(n - 2)).cwiseAbs().maxCoeff() / p.grid.step();
  std::printf("  printed sum: max|x - x_ivp| = %.3f, |x_(N-1) - x_(N-2)|/h = %.2e\n", diff,
              end_speed);
  EXPECT_GT(diff, 1e-2);
}

INSTANTIATE_TEST_SUITE_P(Alphas, MechanicalBvp, ::testing::Values(0.5, 0.3));

// fvi-bdf2 is the same restricted principle with the BDF2 convolution quadrature as Δ^α_±
// (docs/theory/fvi_bdf2.md §2–3). With x_0 = v_0 = 0 its Taylor split is void (P = 0, F^P = 0),
// so its x-equation is exactly `DiscEqs` with the BDF2 weights ω^(2α) = ω^(α) * ω^(α): the BVP of
// the grid with quadrature kBdf2 must return the integrator's trajectory from its end points. The
// forcing drives the motion.
class MechanicalBvpBdf2 : public ::testing::TestWithParam<double> {};

TEST_P(MechanicalBvpBdf2, ReproducesTheIntegratorTrajectoryFromItsEndPoints) {
  const double alpha = GetParam();
  InitialValueProblem ivp = mechanical_ivp(alpha);
  ivp.x0.setZero();
  ivp.v0.setZero();
  IntegratorOptions io;
  io.newton.relative_tolerance = 1e-15;
  io.mirror = false;
  const Solution sol = integrate(ivp, fvi_bdf2(), io);
  ASSERT_TRUE(sol.ok()) << sol.message;
  const auto n = static_cast<Eigen::Index>(ivp.steps);
  const double amplitude = sol.x.cwiseAbs().maxCoeff();
  ASSERT_GT(amplitude, 1e-3);  // the forcing moved the system: the comparison is not 0 = 0

  BoundaryValueProblem p;
  p.lagrangian = std::make_shared<const MechanicalLagrangian>(ivp.model, ivp.t0, ivp.t_end);
  p.grid = DiscreteGrid{ivp.t0, ivp.t_end, n, alpha};
  p.grid.quadrature = boundary_value_quadrature(fvi_bdf2().info());
  ASSERT_EQ(p.grid.quadrature, CqScheme::kBdf2);
  p.x_start = sol.x.row(0).transpose();
  p.x_end = sol.x.row(n).transpose();
  const BvpOptions options;
  const BvpSolution bvp = solve_bvp(p, options);
  ASSERT_TRUE(bvp.ok()) << bvp.message;
  const double dx = (bvp.x - sol.x).cwiseAbs().maxCoeff();
  const double dy = (bvp.y - sol.x.colwise().reverse()).cwiseAbs().maxCoeff();
  // Both solve the same equations: the integrator to round-off (Newton at 1e-15 relative), the BVP
  // to max|F| ≤ residual_tolerance = 1e-10. The equations are M(x_{k+1} − 2x_k + x_{k−1})/h² plus
  // terms with bounded derivatives, so J ≈ (M/h²)·(second difference) and ‖J⁻¹‖_∞ ≈ ‖M⁻¹‖_∞·h²·
  // (N²/8) = ‖M⁻¹‖_∞ (b − a)²/8 ≈ 1.3·1/8 ≈ 0.16 (the discrete Green's function of the second
  // difference; damping and potential perturb it by O(1)). Positions therefore agree to
  // ≈ 0.16·1e-10 ≈ 2e-11 at worst; the tolerance is 1e-10 (the fvi-gl test's), 6× above that.
  const double tol = 1e-10;
  std::printf(
      "  fvi-bdf2, alpha %.2f: max|x| %.2e, %d Newton iterations, residual %.2e, "
      "max|x_bvp - x_ivp| = %.2e, max|y_bvp - x_ivp(N-k)| = %.2e (tol %.0e)\n",
      alpha, amplitude, bvp.newton_iterations, bvp.residual_norm, dx, dy, tol);
  EXPECT_LE(dx, tol);
  EXPECT_LE(dy, tol);

  // Negative control: the same end points with the paper's Grünwald–Letnikov Δ^α_± (fvi-gl's BVP)
  // is a different discretisation — first instead of second order in the memory term — and does
  // not return the fvi-bdf2 trajectory.
  p.grid.quadrature = CqScheme::kGrunwaldLetnikov;
  const BvpSolution gl = solve_bvp(p, options);
  ASSERT_TRUE(gl.ok()) << gl.message;
  const double gl_diff = (gl.x - sol.x).cwiseAbs().maxCoeff();
  std::printf("  Grunwald-Letnikov BVP from the same end points: max|x - x_ivp| = %.2e\n", gl_diff);
  EXPECT_GT(gl_diff, 1e3 * tol);
}

INSTANTIATE_TEST_SUITE_P(Alphas, MechanicalBvpBdf2, ::testing::Values(0.5, 0.3, 0.75));

TEST(BoundaryValueQuadrature, EverySchemeNamesItsOwnOrRefuses) {
  // The registered variational schemes: fvi-gl's Δ^α_± are Grünwald–Letnikov, fvi-bdf2's BDF2.
  EXPECT_EQ(boundary_value_quadrature(fvi_gl().info()), CqScheme::kGrunwaldLetnikov);
  EXPECT_EQ(boundary_value_quadrature(fvi_bdf2().info()), CqScheme::kBdf2);
  EXPECT_EQ(boundary_value_scheme_names(), "fvi-gl, fvi-bdf2");
  // A scheme without a boundary value form (none is registered yet): one line naming the key, the
  // value and the rule.
  SchemeInfo explicit_scheme = fvi_gl().info();
  explicit_scheme.name = "explicit-cq";
  explicit_scheme.variational = false;
  explicit_scheme.variational_quadrature.reset();
  try {
    boundary_value_quadrature(explicit_scheme);
    ADD_FAILURE() << "no exception";
  } catch (const ValidationError& e) {
    EXPECT_EQ(std::string(e.what()),
              "method.scheme = \"explicit-cq\" has no boundary value form (schemes with one: "
              "fvi-gl, fvi-bdf2)");
  }
}

class KrylovBvp : public ::testing::TestWithParam<CqScheme> {};

TEST_P(KrylovBvp, OnALargerGridMatchesDense) {
  // n = 2(N−1)d = 1196 unknowns: GMRES on J·v with the width-8 band as preconditioner, for the
  // Grünwald–Letnikov and the BDF2 Δ^α_± (the band and the FFT take the grid's weights).
  BoundaryValueProblem p = coupled_problem(300);
  p.grid.quadrature = GetParam();
  BvpOptions krylov;
  krylov.linear_solver = BvpLinearSolver::kKrylov;
  const BvpSolution s = solve_bvp(p, krylov);
  ASSERT_TRUE(s.ok()) << s.message;
  std::printf("  N = 300, %s: %s, %d Newton, %zu GMRES iterations, residual %.2e, %.2f s\n",
              std::string(to_string(p.grid.quadrature)).c_str(), s.linear_solver.c_str(),
              s.newton_iterations, s.linear_iterations, s.residual_norm, s.wall_time_seconds);
  EXPECT_LE(s.residual_norm, 1e-10);
  EXPECT_LE(s.linear_iterations, 20u * static_cast<std::size_t>(s.newton_iterations));
  // N + 1 > 256: the GL sums of J·v (and of the residual) run by FFT. Against the exact sparse
  // assembly (direct sums): the FFT error is ≈ ε·log₂(L)·(largest term), L = 1024 here.
  const DiscreteElJacobian jac(*p.lagrangian, p.grid, p.sum, s.x.transpose(), s.y.transpose());
  std::mt19937_64 rng(17);
  const Eigen::VectorXd v = test::random_vector(rng, jac.size());
  const Eigen::VectorXd exact = jac.banded(p.grid.steps) * v;
  const double fft_error = (jac.apply(v) - exact).cwiseAbs().maxCoeff();
  std::printf("  FFT J*v vs exact assembly: %.2e (max |J v| %.2e)\n", fft_error,
              exact.cwiseAbs().maxCoeff());
  EXPECT_LE(fft_error, 64 * kEps * 10 * exact.cwiseAbs().maxCoeff());
}

INSTANTIATE_TEST_SUITE_P(Quadratures, KrylovBvp,
                         ::testing::Values(CqScheme::kGrunwaldLetnikov, CqScheme::kBdf2));

struct Throwing {
  template <class T>
  T operator()(const PhasePoint<T>& q) const {
    if (q.x(0) > T(0.5)) throw std::runtime_error("x1 left the chart");
    return T(0.5) * q.xdot(0) * q.xdot(0) + T(0.5) * q.ydot(0) * q.ydot(0);
  }
};

TEST(SolveBvp, FailuresAreStatusesWithTheBestIterate) {
  // Too few iterations: kNewtonFailure, the best iterate and its residual returned.
  BvpOptions o;
  o.max_iterations = 1;
  const BvpSolution s = solve_bvp(coupled_problem(40), o);
  EXPECT_EQ(s.status, Status::kNewtonFailure);
  EXPECT_NE(s.message.find("no convergence in 1 iterations"), std::string::npos) << s.message;
  EXPECT_GT(s.residual_norm, 1e-10);
  EXPECT_LT(s.residual_norm, s.residual_history.front());
  EXPECT_EQ(s.x.rows(), 41);

  // A Lagrangian whose gradient is NaN at the start (sqrt of a negative position): kNonFinite.
  BoundaryValueProblem p;
  p.lagrangian = std::make_shared<const ExpressionLagrangian>(
      1, "0.5*xdot1^2 + 0.5*ydot1^2 - sqrt(x1) - sqrt(y1) - dx1*dy1");
  p.grid = DiscreteGrid{0.0, 1.0, 20, 0.5};
  p.x_start = Eigen::VectorXd::Constant(1, 1.0);
  p.x_end = Eigen::VectorXd::Constant(1, -1.0);
  const BvpSolution nan = solve_bvp(p);
  EXPECT_EQ(nan.status, Status::kNonFinite);
  EXPECT_FALSE(nan.message.empty());

  // A Lagrangian that throws: kCallbackError with its message.
  p.lagrangian = make_autodiff_lagrangian(Throwing{}, 1);
  const BvpSolution thrown = solve_bvp(p);
  EXPECT_EQ(thrown.status, Status::kCallbackError);
  EXPECT_NE(thrown.message.find("x1 left the chart"), std::string::npos) << thrown.message;

  // Bad input is an exception before anything runs.
  p.x_end = Eigen::VectorXd::Zero(2);
  EXPECT_THROW(solve_bvp(p), ValidationError);
  p.x_end = Eigen::VectorXd::Zero(1);
  p.grid.steps = 1;
  EXPECT_THROW(solve_bvp(p), ValidationError);
}

}  // namespace
}  // namespace fracvi
