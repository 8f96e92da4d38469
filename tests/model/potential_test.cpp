// Potentials: QuadraticPotential exactly; autodiff gradients and Hessians (Eigen AutoDiff, nested)
// against central differences, for a dynamic- and a fixed-size functor.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/model/potential.hpp"

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

TEST(QuadraticPotential, ValueGradientHessian) {
  const Eigen::MatrixXd K{{3.0, -1.0}, {-1.0, 2.0}};
  const Eigen::VectorXd b{{0.5, -0.25}};
  const QuadraticPotential U(K, b);
  const Eigen::VectorXd x{{0.7, -1.1}};
  EXPECT_NEAR(U.value(x, 0.0), 0.5 * x.dot(K * x) - b.dot(x), 4 * kEps);
  Eigen::VectorXd g(2);
  U.gradient(x, 0.0, g);
  EXPECT_LE((g - (K * x - b)).cwiseAbs().maxCoeff(), 4 * kEps);
  Eigen::MatrixXd H(2, 2);
  U.hessian(x, 0.0, H);
  EXPECT_EQ(H, K);
  EXPECT_TRUE(U.has_constant_hessian());
  EXPECT_FALSE(U.is_time_dependent());
  EXPECT_EQ(U.dimension(), 2);
}

// A quadratic formula's gradient is formed as b + Kx (ExpressionPotential::has_affine_gradient):
// against QuadraticPotential with the same K and b, and against the exact gradient in long double
// for springs displaced far from the origin, where b + Kx and the formula's differences round
// differently (both to round-off of the terms' sizes).
TEST(ExpressionPotential, QuadraticFormulaHasAnAffineGradient) {
  const ExpressionPotential U(2, "1.5*x1^2 - x1*x2 + x2^2 - 0.5*x1 + 0.25*x2 + 7");
  EXPECT_TRUE(U.has_affine_gradient());
  const Eigen::MatrixXd K{{3.0, -1.0}, {-1.0, 2.0}};
  const QuadraticPotential reference(K, Eigen::VectorXd{{0.5, -0.25}});
  std::mt19937 rng(3u);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::VectorXd x{{u(rng), u(rng)}};
    Eigen::VectorXd g(2), expected(2);
    U.gradient(x, 0.0, g);
    reference.gradient(x, 0.0, expected);
    EXPECT_LE((g - expected).cwiseAbs().maxCoeff(),
              8 * kEps * (K.cwiseAbs() * x.cwiseAbs()).maxCoeff() + 8 * kEps);
    EXPECT_NEAR(U.value(x, 0.0), reference.value(x, 0.0) + 7.0, 64 * kEps);
  }
  // Springs (x2 − x1)² / 2 + x1²/2 at x ≈ 10^3 with differences ≈ 10^−3.
  const ExpressionPotential springs(2, "0.5*(x2 - x1)^2 + 0.5*x1^2");
  EXPECT_TRUE(springs.has_affine_gradient());
  const Eigen::VectorXd x{{1000.0 + 1e-3, 1000.0 + 3e-3}};
  Eigen::VectorXd g(2);
  springs.gradient(x, 0.0, g);
  const long double x1 = x(0), x2 = x(1);
  const long double exact[2] = {-(x2 - x1) + x1, x2 - x1};
  for (int i = 0; i < 2; ++i) {
    EXPECT_LE(std::abs(static_cast<double>(g(i) - exact[i])), 4 * kEps * 2.0 * 1000.0) << i;
  }
}

// What keeps the tape: t in the formula, a non-quadratic U, a kink.
TEST(ExpressionPotential, NonQuadraticFormulasKeepTheTape) {
  const ExpressionPotential with_t(1, "x1^2 + t*x1");
  EXPECT_FALSE(with_t.has_affine_gradient());
  Eigen::VectorXd g(1);
  with_t.gradient(Eigen::VectorXd{{0.5}}, 3.0, g);
  EXPECT_DOUBLE_EQ(g(0), 1.0 + 3.0);
  EXPECT_FALSE(ExpressionPotential(1, "x1^4").has_affine_gradient());
  EXPECT_FALSE(ExpressionPotential(1, "abs(x1) + x1^2").has_affine_gradient());
  EXPECT_FALSE(ExpressionPotential(2, "x1^2*x2").has_affine_gradient());
  EXPECT_TRUE(ExpressionPotential(3, "x1 + 2*x3").has_affine_gradient());  // K = 0
}

TEST(QuadraticPotential, RejectsBadInput) {
  EXPECT_THROW(QuadraticPotential(Eigen::MatrixXd{{1.0, 2.0}, {0.0, 1.0}}), std::invalid_argument);
  EXPECT_THROW(QuadraticPotential(Eigen::MatrixXd(2, 3)), std::invalid_argument);
  EXPECT_THROW(QuadraticPotential(Eigen::MatrixXd::Identity(2, 2), Eigen::VectorXd(3)),
               std::invalid_argument);
  Eigen::MatrixXd nan = Eigen::MatrixXd::Identity(2, 2);
  nan(0, 0) = std::nan("");
  EXPECT_THROW(QuadraticPotential{nan}, std::invalid_argument);
  // Round-off asymmetry (from a product ΛᵀKΛ) is accepted.
  const Eigen::MatrixXd L{{1.0, 0.3}, {-0.7, 1.9}};
  const Eigen::MatrixXd K = L.transpose() * Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}} * L;
  EXPECT_NO_THROW(QuadraticPotential{K});
}

// A smooth, non-polynomial, time-dependent test function in d = 3.
struct Wavy {
  template <class T>
  T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>& x, T t) const {
    using std::cos;
    using std::exp;
    using std::sin;
    using std::sqrt;
    return cos(x(0)) * x(1) * x(1) + exp(T(0.3) * x(0) * x(2)) + t * x(0) * x(0) * x(1) +
           sqrt(T(1.0) + x(2) * x(2)) + sin(t) * x(1) * x(2);
  }
};

struct Wavy2 {
  template <class T>
  T operator()(const Eigen::Matrix<T, 2, 1>& x, T t) const {
    using std::cos;
    using std::log;
    return log(T(2.0) + cos(x(0) * x(1))) + t * x(1) * x(1) * x(1) +
           T(0.25) * x(0) * x(0) * x(0) * x(0);
  }
};

// Central differences with step δ: truncation δ²|f'''|/6, rounding ε|f|/δ. With δ = 1e-5 and
// |f|, |f'''| = O(10) at these points both are ≤ 1e-9; kFdTolerance leaves a factor 10.
constexpr double kFdStep = 1e-5;
constexpr double kFdTolerance = 1e-8;

void check_against_differences(const Potential& U, const Eigen::VectorXd& x, double t) {
  const Eigen::Index d = U.dimension();
  Eigen::VectorXd g(d);
  Eigen::MatrixXd H(d, d);
  U.gradient(x, t, g);
  U.hessian(x, t, H);
  for (Eigen::Index i = 0; i < d; ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp(i) += kFdStep;
    xm(i) -= kFdStep;
    const double fd = (U.value(xp, t) - U.value(xm, t)) / (2 * kFdStep);
    EXPECT_NEAR(g(i), fd, kFdTolerance) << "gradient component " << i;
    Eigen::VectorXd gp(d), gm(d);
    U.gradient(xp, t, gp);
    U.gradient(xm, t, gm);
    const Eigen::VectorXd col = (gp - gm) / (2 * kFdStep);
    for (Eigen::Index j = 0; j < d; ++j) {
      EXPECT_NEAR(H(j, i), col(j), kFdTolerance) << "Hessian entry " << j << "," << i;
    }
  }
  // Forward-over-forward gives an exactly symmetric Hessian up to the order of operations.
  EXPECT_LE((H - H.transpose()).cwiseAbs().maxCoeff(), 16 * kEps * H.cwiseAbs().maxCoeff());
}

TEST(AutodiffPotential, DynamicSizeMatchesCentralDifferences) {
  const auto U = make_autodiff_potential(Wavy{}, 3);
  EXPECT_EQ(U->dimension(), 3);
  EXPECT_TRUE(U->is_time_dependent());
  EXPECT_FALSE(U->has_constant_hessian());
  std::mt19937 gen(2024u);
  std::uniform_real_distribution<double> dist(-1.5, 1.5);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd x{{dist(gen), dist(gen), dist(gen)}};
    check_against_differences(*U, x, dist(gen));
  }
}

TEST(AutodiffPotential, FixedSizeMatchesCentralDifferences) {
  const auto U = make_autodiff_potential<2>(Wavy2{});
  EXPECT_EQ(U->dimension(), 2);
  std::mt19937 gen(77u);
  std::uniform_real_distribution<double> dist(-1.5, 1.5);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd x{{dist(gen), dist(gen)}};
    check_against_differences(*U, x, dist(gen));
  }
}

struct Quad {
  template <class T>
  T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>& x, T) const {
    return T(1.5) * x(0) * x(0) - x(0) * x(1) + x(1) * x(1) - T(0.5) * x(0);
  }
};

struct Constant {
  template <class T>
  T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>&, T) const {
    return T(2.0);
  }
};

TEST(AutodiffPotential, ExactOnAQuadratic) {
  AutodiffPotentialOptions o;
  o.constant_hessian = true;
  o.time_dependent = false;
  const auto U = make_autodiff_potential(Quad{}, 2, o);
  EXPECT_TRUE(U->has_constant_hessian());
  EXPECT_FALSE(U->is_time_dependent());
  Eigen::MatrixXd H(2, 2);
  U->hessian(Eigen::VectorXd{{0.3, -2.0}}, 0.0, H);
  EXPECT_EQ(H, (Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}}));
  Eigen::VectorXd g(2);
  U->gradient(Eigen::VectorXd{{1.0, 2.0}}, 0.0, g);
  EXPECT_EQ(g, (Eigen::VectorXd{{3.0 - 2.0 - 0.5, -1.0 + 4.0}}));
}

TEST(AutodiffPotential, ConstantFunctionHasZeroDerivatives) {
  const auto U = make_autodiff_potential(Constant{}, 2);
  Eigen::VectorXd g = Eigen::VectorXd::Ones(2);
  Eigen::MatrixXd H = Eigen::MatrixXd::Ones(2, 2);
  U->gradient(Eigen::VectorXd::Zero(2), 0.0, g);
  U->hessian(Eigen::VectorXd::Zero(2), 0.0, H);
  EXPECT_TRUE(g.isZero(0.0));
  EXPECT_TRUE(H.isZero(0.0));
}

TEST(AutodiffPotential, DimensionErrors) {
  EXPECT_THROW(make_autodiff_potential(Wavy{}), std::invalid_argument);  // dim required
  EXPECT_THROW(make_autodiff_potential<2>(Wavy2{}, 3), std::invalid_argument);
}

}  // namespace
}  // namespace fracvi
