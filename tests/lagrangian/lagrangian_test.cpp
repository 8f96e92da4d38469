// Lagrangians on the fractional phase space: automatic derivatives against central differences,
// the expression form against the functor form, the mechanical model (`PartLagrangian`) against
// its Lagrangian written out by hand, bad input, and the forward-steppable class.
#include "fracvi/lagrangian/lagrangian.hpp"

#include <gtest/gtest.h>

#include <cstdio>

#include "fracvi/model/expression_potential.hpp"
#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;

constexpr Eigen::Index kDim = 2;
constexpr Eigen::Index kN = 6 * kDim;

// Central differences with step δ: truncation δ²|f'''|/6 plus rounding ε|f|/δ. With δ = 1e-5 and
// |f|, |f'''| = O(10) on the test points both are ≈ 1e-9; the bound 2e-8 leaves a factor 10.
constexpr double kFdStep = 1e-5;
constexpr double kFdTolerance = 2e-8;

TEST(AutodiffLagrangian, DerivativesMatchCentralDifferences) {
  const auto L = make_autodiff_lagrangian(test::Coupled{}, kDim);
  std::mt19937_64 rng(42);
  double worst_g = 0.0, worst_h = 0.0, worst_t = 0.0;
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd z = test::random_vector(rng, kN, 1.5);
    const double t = 0.3 + 0.4 * trial;
    LagrangianDerivatives der;
    L->derivatives(t, z, der);
    Eigen::VectorXd g(kN);
    const double v = L->gradient(t, z, g);
    EXPECT_EQ(v, L->value(t, z));
    EXPECT_EQ(der.value, v);
    EXPECT_LE((der.gradient - g).cwiseAbs().maxCoeff(), 4 * kEps * g.cwiseAbs().maxCoeff());
    for (Eigen::Index i = 0; i < kN; ++i) {
      Eigen::VectorXd zp = z, zm = z;
      zp(i) += kFdStep;
      zm(i) -= kFdStep;
      const double fd = (L->value(t, zp) - L->value(t, zm)) / (2 * kFdStep);
      worst_g = std::max(worst_g, std::abs(fd - g(i)));
      Eigen::VectorXd gp(kN), gm(kN);
      L->gradient(t, zp, gp);
      L->gradient(t, zm, gm);
      const Eigen::VectorXd col = (gp - gm) / (2 * kFdStep);
      worst_h = std::max(worst_h, (col - der.hessian.col(i)).cwiseAbs().maxCoeff());
    }
    Eigen::VectorXd gp(kN), gm(kN);
    L->gradient(t + kFdStep, z, gp);
    L->gradient(t - kFdStep, z, gm);
    const Eigen::VectorXd gt = ((gp - gm) / (2 * kFdStep)).tail(4 * kDim);
    worst_t = std::max(worst_t, (gt - der.time_gradient).cwiseAbs().maxCoeff());
    EXPECT_EQ(der.hessian, der.hessian.transpose());
  }
  std::printf("  central differences: gradient %.2e, Hessian %.2e, d/dt gradient %.2e\n", worst_g,
              worst_h, worst_t);
  EXPECT_LE(worst_g, kFdTolerance);
  EXPECT_LE(worst_h, kFdTolerance);
  EXPECT_LE(worst_t, kFdTolerance);
}

struct Constant {
  template <class T>
  T operator()(const PhasePoint<T>&) const {
    return T(2.5);
  }
};

TEST(AutodiffLagrangian, ConstantLagrangianHasZeroDerivatives) {
  const auto L = make_autodiff_lagrangian(Constant{}, 3);
  LagrangianDerivatives der;
  L->derivatives(0.0, Eigen::VectorXd::Ones(18), der);
  EXPECT_EQ(der.value, 2.5);
  EXPECT_TRUE(der.gradient.isZero(0.0));
  EXPECT_TRUE(der.hessian.isZero(0.0));
  EXPECT_THROW(make_autodiff_lagrangian(Constant{}, 0), std::invalid_argument);
}

TEST(ExpressionLagrangian, MatchesTheFunctorWithExactDerivatives) {
  const auto functor = make_autodiff_lagrangian(test::Coupled{}, kDim);
  const ExpressionLagrangian expr(kDim, test::kCoupledText);
  std::mt19937_64 rng(7);
  double worst = 0.0;
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd z = test::random_vector(rng, kN, 1.5);
    const double t = -0.5 + 0.6 * trial;
    LagrangianDerivatives a, b;
    functor->derivatives(t, z, a);
    expr.derivatives(t, z, b);
    // Two exact evaluation orders of the same formula: they differ by rounding only, a few ulps
    // of the largest term (|terms| ≤ 10 here).
    const double tol = 64 * kEps * 10.0;
    EXPECT_NEAR(a.value, b.value, tol);
    worst = std::max({worst, (a.gradient - b.gradient).cwiseAbs().maxCoeff(),
                      (a.hessian - b.hessian).cwiseAbs().maxCoeff(),
                      (a.time_gradient - b.time_gradient).cwiseAbs().maxCoeff()});
    Eigen::VectorXd g(kN);
    EXPECT_NEAR(expr.gradient(t, z, g), b.value, tol);
    EXPECT_LE((g - b.gradient).cwiseAbs().maxCoeff(), tol);
  }
  std::printf("  functor vs expression: max derivative difference %.2e\n", worst);
  EXPECT_LE(worst, 64 * kEps * 10.0);
}

TEST(ExpressionLagrangian, VariableNamesAndPattern) {
  const auto names = ExpressionLagrangian::variable_names(2);
  const std::vector<std::string> expected{"x1",    "x2",  "y1",  "y2",  "xdot1", "xdot2", "ydot1",
                                          "ydot2", "dx1", "dx2", "dy1", "dy2",   "t"};
  EXPECT_EQ(names, expected);
  const ExpressionLagrangian L(2, "0.5*xdot1^2 + x1*dy2");
  const auto p = *L.hessian_pattern();
  EXPECT_TRUE(p(4, 4));     // xdot1, xdot1
  EXPECT_TRUE(p(0, 11));    // x1, dy2
  EXPECT_TRUE(p(11, 0));    // symmetric
  EXPECT_FALSE(p(0, 0));    // x1, x1
  EXPECT_EQ(p.count(), 3);  // nothing else
}

TEST(ExpressionLagrangian, RejectsVariablesThatDoNotExistForD) {
  // x3 exists only for d >= 3; the message names it and lists the known names.
  try {
    ExpressionLagrangian(2, "0.5*xdot1^2 - x3^2");
    FAIL() << "x3 accepted for d = 2";
  } catch (const ExpressionError& e) {
    EXPECT_NE(e.reason().find("x3"), std::string::npos) << e.reason();
    EXPECT_EQ(e.column(), 14u);
  }
  EXPECT_THROW(ExpressionLagrangian(1, "xdot2"), ExpressionError);
  EXPECT_THROW(ExpressionLagrangian(1, "v1"), ExpressionError);
  EXPECT_NO_THROW(ExpressionLagrangian(3, "0.5*xdot1^2 - x3^2"));
  EXPECT_THROW(ExpressionLagrangian(0, "1"), std::invalid_argument);
}

// `PartLagrangian` with full SPD M, symmetric R, a time-dependent potential and a forcing.
MechanicalModel mechanical_model() {
  MechanicalModel m;
  m.mass = Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
  m.damping = Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
  m.alpha = 0.5;
  m.convention = Convention::kRiemannLiouville;
  m.potential = std::make_shared<const ExpressionPotential>(
      2, "9.81*(1 - cos(x1)) + 4*(1 - cos(x2)) + (x2 - x1)^2 + 0.1*t*x1^2");
  m.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = 0.1 * t;
  };
  return m;
}

// The same Lagrangian written out by hand on [a, b] = [0, 3]: the y-part at time a + b − t.
const std::string kMechanicalByHand =
    "0.5*(1.5*xdot1^2 + 2*0.3*xdot1*xdot2 + 1.0*xdot2^2)"
    " + 0.5*(1.5*ydot1^2 + 2*0.3*ydot1*ydot2 + 1.0*ydot2^2)"
    " - (9.81*(1 - cos(x1)) + 4*(1 - cos(x2)) + (x2 - x1)^2 + 0.1*t*x1^2"
    "    - 0.3*sin(2*t)*x1 - 0.1*t*x2)"
    " - (9.81*(1 - cos(y1)) + 4*(1 - cos(y2)) + (y2 - y1)^2 + 0.1*(3 - t)*y1^2"
    "    - 0.3*sin(2*(3 - t))*y1 - 0.1*(3 - t)*y2)"
    " - (0.6*dx1*dy1 - 0.2*dx1*dy2 - 0.2*dx2*dy1 + 0.4*dx2*dy2)";

TEST(MechanicalLagrangian, EqualsItsLagrangianWrittenByHand) {
  const MechanicalLagrangian mech(mechanical_model(), 0.0, 3.0);
  const ExpressionLagrangian hand(2, kMechanicalByHand);
  std::mt19937_64 rng(11);
  double worst = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    const Eigen::VectorXd z = test::random_vector(rng, kN, 2.0);
    const double t = 0.37 * trial;
    LagrangianDerivatives a, b;
    mech.derivatives(t, z, a);
    hand.derivatives(t, z, b);
    worst = std::max(
        {worst, std::abs(a.value - b.value), (a.gradient - b.gradient).cwiseAbs().maxCoeff(),
         (a.hessian - b.hessian).cwiseAbs().maxCoeff(),
         (a.time_gradient.head(2 * kDim) - b.time_gradient.head(2 * kDim)).cwiseAbs().maxCoeff(),
         (a.time_gradient.tail(2 * kDim) - b.time_gradient.tail(2 * kDim)).cwiseAbs().maxCoeff()});
  }
  // Same formula, different rounding order; terms are ≤ 50 in size.
  std::printf("  mechanical vs by hand: max difference %.2e\n", worst);
  EXPECT_LE(worst, 64 * kEps * 50.0);
  // Hessian patterns: the mechanical one is the structural truth (a subset of the expression's).
  const auto pm = *mech.hessian_pattern(), ph = *hand.hessian_pattern();
  EXPECT_TRUE((pm == ph).all());
}

TEST(ForwardStepClass, MechanicalTypeIsSteppableCoupledIsNot) {
  EXPECT_TRUE(
      forward_step_class(MechanicalLagrangian(mechanical_model(), 0.0, 3.0)).forward_steppable);
  EXPECT_TRUE(forward_step_class(ExpressionLagrangian(2, kMechanicalByHand)).forward_steppable);
  // Velocity-dependent damping coefficient and a memory term in x alone are still steppable.
  EXPECT_TRUE(forward_step_class(
                  ExpressionLagrangian(1,
                                       "0.5*xdot1^2*(1 + 0.1*xdot1^2) - x1^4 + 0.5*ydot1^2 - "
                                       "y1^4 - (1 + dx1^2)*dy1 + xdot1*dx1"))
                  .forward_steppable);
  const auto coupled = forward_step_class(ExpressionLagrangian(2, test::kCoupledText));
  EXPECT_FALSE(coupled.forward_steppable);
  EXPECT_NE(coupled.reason.find("boundary value problem"), std::string::npos) << coupled.reason;
  // Position-dependent mass alone (no x–y coupling): not a one-step recursion.
  const auto pdm =
      forward_step_class(ExpressionLagrangian(1, "0.5*(1 + x1^2)*xdot1^2 + 0.5*ydot1^2 - dx1*dy1"));
  EXPECT_FALSE(pdm.forward_steppable);
  EXPECT_NE(pdm.reason.find("dL/dxdot1 depends on x1"), std::string::npos) << pdm.reason;
  // A functor's structure is unknown.
  EXPECT_FALSE(forward_step_class(*make_autodiff_lagrangian(test::Coupled{}, 2)).forward_steppable);
}

}  // namespace
}  // namespace fracvi
