// Validation before step 1: every message names the field, its value and the rule.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {
namespace {

InitialValueProblem valid() {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{2.0, 0.5}, {0.5, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.4, 0.1}, {0.1, 0.3}};
  p.model.alpha = 0.75;
  p.model.convention = Convention::kCaputo;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(2, 2));
  p.x0 = Eigen::VectorXd{{1.0, 0.0}};
  p.v0 = Eigen::VectorXd{{0.0, 1.0}};
  p.t_end = 1.0;
  p.steps = 10;
  return p;
}

// Expects validate(p) and the Integrator constructor to throw ValidationError whose message
// contains every one of the given fragments.
void expect_rejected(const InitialValueProblem& p, std::initializer_list<const char*> fragments) {
  try {
    validate(p);
    FAIL() << "validate() accepted the problem";
  } catch (const ValidationError& e) {
    const std::string msg = e.what();
    for (const char* f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << msg;
  }
  EXPECT_THROW(Integrator{p}, ValidationError);
  EXPECT_THROW(Integrator{p}, std::invalid_argument);  // ValidationError is-an invalid_argument
}

TEST(Validation, ValidProblemPasses) {
  EXPECT_NO_THROW(validate(valid()));
  EXPECT_NO_THROW(Integrator{valid()});
}

TEST(Validation, MassNotPositiveDefinite) {
  InitialValueProblem p = valid();
  p.model.mass = Eigen::MatrixXd{{1.0, 0.0}, {0.0, -0.3}};
  expect_rejected(p, {"model.mass is not symmetric positive definite (smallest eigenvalue -0.3"});
  p.model.mass = Eigen::MatrixXd::Zero(2, 2);
  expect_rejected(p, {"model.mass is not symmetric positive definite (smallest eigenvalue 0"});
}

TEST(Validation, MassNotSymmetric) {
  InitialValueProblem p = valid();
  p.model.mass.dense()(0, 1) = 0.7;
  expect_rejected(p, {"model.mass is not symmetric (max |A - A^T| = 0.19999999999999996)"});
}

TEST(Validation, MassShape) {
  InitialValueProblem p = valid();
  p.model.mass = Eigen::MatrixXd::Identity(2, 3);
  expect_rejected(p, {"model.mass is 2 x 3"});
}

TEST(Validation, DampingNotSemidefinite) {
  InitialValueProblem p = valid();
  p.model.damping = Eigen::MatrixXd{{0.5, 0.0}, {0.0, -0.5}};
  expect_rejected(
      p, {"model.damping is not symmetric positive semidefinite", "smallest eigenvalue -0.5"});
  // Singular PSD damping (rank one, built as a product) is fine.
  p.model.damping = Eigen::VectorXd{{0.3, 0.7}} * Eigen::RowVectorXd{{0.3, 0.7}};
  EXPECT_NO_THROW(validate(p));
}

TEST(Validation, DampingShape) {
  InitialValueProblem p = valid();
  p.model.damping = Eigen::MatrixXd::Identity(3, 3);
  expect_rejected(p, {"model.damping is 3 x 3, must be 2 x 2"});
}

TEST(Validation, AlphaOutsideUnitInterval) {
  for (const double a : {-0.1, 1.5}) {
    InitialValueProblem p = valid();
    p.model.alpha = a;
    expect_rejected(p, {"model.alpha =", "is outside [0, 1]", "damping order 2*alpha"});
  }
  InitialValueProblem p = valid();
  p.model.alpha = std::nan("");
  expect_rejected(p, {"model.alpha = nan"});
}

TEST(Validation, RiemannLiouvilleIllPosed) {
  InitialValueProblem p = valid();
  p.model.convention = Convention::kRiemannLiouville;
  p.model.alpha = 0.75;
  expect_rejected(p, {"riemann-liouville", "2*alpha = 1.5", "x0 != 0", "ill-posed",
                      "not integrable", "convention = caputo"});
  // At 2α = 2 the pointwise force x0 t^{−2α}/Γ(1−2α) is 0 (1/Γ(−1) = 0): the reason given is the
  // memory's impulse, not non-integrability (issue 13 item 5).
  p.model.alpha = 1.0;
  expect_rejected(p, {"ill-posed", "1/Gamma(-1) = 0", "-R x(0)/h^2"});
  try {
    validate(p);
  } catch (const ValidationError& e) {
    EXPECT_EQ(std::string(e.what()).find("not integrable"), std::string::npos) << e.what();
  }
  // Well-posed cases: zero x0, 2α ≤ 1, or no damping at all.
  p.model.alpha = 0.75;
  p.x0.setZero();
  EXPECT_NO_THROW(validate(p));
  p.x0 = Eigen::VectorXd{{1.0, 0.0}};
  p.model.alpha = 0.5;
  EXPECT_NO_THROW(validate(p));
  p.model.alpha = 0.3;
  EXPECT_NO_THROW(validate(p));
  p.model.alpha = 0.75;
  p.model.damping.dense().setZero();
  EXPECT_NO_THROW(validate(p));
}

TEST(Validation, InitialDataAndGrid) {
  InitialValueProblem p = valid();
  p.x0 = Eigen::VectorXd::Zero(3);
  expect_rejected(p, {"x0 has size 3, must be 2"});
  p = valid();
  p.v0(1) = std::nan("");
  expect_rejected(p, {"v0 has a non-finite entry"});
  p = valid();
  p.steps = 0;
  expect_rejected(p, {"steps = 0"});
  p = valid();
  p.t_end = p.t0;
  expect_rejected(p, {"t_end = 0", "greater than t0"});
}

TEST(Validation, PotentialDimension) {
  InitialValueProblem p = valid();
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(3, 3));
  expect_rejected(p, {"model.potential has dimension 3, must be 2"});
}

TEST(Validation, IntegratorOptions) {
  IntegratorOptions o;
  o.newton.max_iterations = 0;
  EXPECT_THROW(validate(o), ValidationError);
  EXPECT_THROW(Integrator(valid(), fvi_gl(), o), ValidationError);
  o = IntegratorOptions{};
  o.newton.relative_tolerance = -1.0;
  EXPECT_THROW(validate(o), ValidationError);
  o = IntegratorOptions{};
  o.newton.relative_tolerance = 0.0;
  try {
    validate(o);
    FAIL();
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("both 0"), std::string::npos);
  }
}

}  // namespace
}  // namespace fracvi
