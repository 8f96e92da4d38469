// Test 7: Theorem 4.3, discrete. With x = Λz (Λ invertible, non-orthogonal) the scheme in z with
// ΛᵀMΛ, ΛᵀRΛ, U∘Λ, forcing Λᵀf and data Λ⁻¹x0, Λ⁻¹v0 is Λᵀ times the scheme in x, so Λz_k = x_k
// for every k (up to round-off), for α = 1/2 and fractional α, with nonlinear U.
#include <gtest/gtest.h>

#include <cstdio>

#include "../support/test_problems.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;

constexpr std::size_t kN = 400;

// The x-problem: test::forced_pendula (nonlinear, forced, Caputo with x0, v0 ≠ 0); the z-problem:
// test::transformed_problem (both in test_problems.hpp, shared with the scheme suite).
InitialValueProblem x_problem(double alpha) {
  return test::forced_pendula(alpha, kN);
}

// Round-off budget: the two runs differ by rounding in every matrix product, amplified at most by
// cond(Λ)² (the z-equations are Λᵀ(x-equations) evaluated at Λz) and accumulated over N steps as a
// random walk: 16ε · cond(Λ)² · √N · max‖x‖.
void check(double alpha) {
  const Eigen::MatrixXd lambda{{1.0, 0.7}, {-0.4, 2.0}};
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(lambda);
  const double cond = svd.singularValues()(0) / svd.singularValues()(1);
  IntegratorOptions opts;
  opts.newton.relative_tolerance = 1e-14;
  opts.mirror = false;
  const InitialValueProblem px = x_problem(alpha);
  const Solution sx = integrate(px, fvi_gl(), opts);
  const Solution sz = integrate(test::transformed_problem(px, lambda), fvi_gl(), opts);
  ASSERT_TRUE(sx.ok() && sz.ok());
  const RowMatrixXd mapped = sz.x * lambda.transpose();  // rows: (Λ z_k)ᵀ
  const double err = (mapped - sx.x).cwiseAbs().maxCoeff();
  const RowMatrixXd mapped_v = sz.v * lambda.transpose();
  const double err_v = (mapped_v - sx.v).cwiseAbs().maxCoeff();
  const double tol =
      16.0 * kEps * cond * cond * std::sqrt(static_cast<double>(kN)) * sx.x.cwiseAbs().maxCoeff();
  const double tol_v =
      16.0 * kEps * cond * cond * std::sqrt(static_cast<double>(kN)) * sx.v.cwiseAbs().maxCoeff();
  std::printf(
      "  alpha %.2f: max |Λz - x| = %.3e (tol %.3e), max |Λż - v| = %.3e (tol %.3e), "
      "cond(Λ) = %.2f\n",
      alpha, err, tol, err_v, tol_v, cond);
  EXPECT_LE(err, tol);
  EXPECT_LE(err_v, tol_v);
}

TEST(Theorem43, LinearChangeOfVariablesAlphaHalf) {
  check(0.5);
}

// Negative control: leaving R untransformed (R instead of ΛᵀRΛ) breaks the equivalence far above
// round-off, so the comparison above does detect a wrong transformation.
TEST(Theorem43, WrongTransformationIsDetected) {
  const Eigen::MatrixXd lambda{{1.0, 0.7}, {-0.4, 2.0}};
  IntegratorOptions opts;
  opts.mirror = false;
  const InitialValueProblem px = x_problem(0.75);
  const InitialValueProblem pz = test::transformed_problem(px, lambda, /*transform_damping=*/false);
  const Solution sx = integrate(px, fvi_gl(), opts);
  const Solution sz = integrate(pz, fvi_gl(), opts);
  ASSERT_TRUE(sx.ok() && sz.ok());
  const RowMatrixXd mapped = sz.x * lambda.transpose();
  const double err = (mapped - sx.x).cwiseAbs().maxCoeff();
  std::printf("  untransformed R: max |Λz - x| = %.3e\n", err);
  EXPECT_GT(err, 1e-3);
}
TEST(Theorem43, LinearChangeOfVariablesAlpha075) {
  check(0.75);
}
TEST(Theorem43, LinearChangeOfVariablesAlpha03) {
  check(0.3);
}

}  // namespace
}  // namespace fracvi
