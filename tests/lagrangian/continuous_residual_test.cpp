// The residual of `FracEL` (Theorem 4.2) along smooth curves.
//
// * Corollary 4.4 / Remark 4.5: for the mechanical Lagrangian with α = 1/2 the exact solution of
//   the damped oscillator M x'' + R x' + K x = 0 with y(t) = x(a + b − t) makes both residuals
//   vanish to quadrature accuracy; a curve that is not a solution (or a y that is not the mirror)
//   gives a residual of order one (negative controls).
// * Theorem 4.3: under x = Λz, y = Λz̃ (Λ full rank) the residual of the transformed Lagrangian
//   L̃(z, z̃, ż, …) = L(Λz, Λz̃, Λż, …) is Λᵀ times the original one, for a non-mechanical L.
#include "fracvi/lagrangian/continuous_residual.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>

#include "fracvi/model/potential.hpp"
#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;

// Two decoupled damped oscillators m ẍ + r ẋ + k x = 0 with x(0) = 0 (so that D^{1/2}_−x is
// bounded at a = 0): x(t) = A e^{−γt} sin(ωt), γ = r/(2m), ω = √(k/m − γ²).
constexpr double kM[2] = {1.5, 0.8}, kR[2] = {0.6, 0.3}, kK[2] = {6.0, 2.0}, kAmp[2] = {1.0, 0.7};
constexpr double kA = 0.0, kB = 2.0;

struct Oscillator {
  bool mirrored;  // y(t) = x(a + b − t)
  template <class T>
  Eigen::Matrix<T, Eigen::Dynamic, 1> operator()(T t) const {
    using std::exp;
    using std::sin;
    Eigen::Matrix<T, Eigen::Dynamic, 1> v(2);
    const T s = mirrored ? T(kA + kB) - t : t;
    for (int i = 0; i < 2; ++i) {
      const double g = kR[i] / (2 * kM[i]), w = std::sqrt(kK[i] / kM[i] - g * g);
      v(i) = T(kAmp[i]) * exp(T(-g) * s) * sin(T(w) * s);
    }
    return v;
  }
};

MechanicalModel oscillator_model() {
  MechanicalModel m;
  m.mass = Eigen::Vector2d(kM[0], kM[1]).asDiagonal();
  m.damping = Eigen::Vector2d(kR[0], kR[1]).asDiagonal();
  m.alpha = 0.5;
  m.potential = make_quadratic_potential(Eigen::Vector2d(kK[0], kK[1]).asDiagonal());
  return m;
}

// Quadrature accuracy. Every tanh–sinh quadrature runs to the relative tolerance 1e-12 and the
// nested ones (the outer D^α_± of ∂L/∂D^α, whose integrand holds inner quadratures) inherit the
// inner errors; with terms of size O(10) that is ≤ 1e-10. The residual moves every terminal to 0
// (exact distances), so the rounding limit of riemann_liouville.hpp at a terminal c ≠ 0 (b = 2
// here; it cost 1.5e-8 in the y-equation before) does not apply. Measured: ~1e-15 (printed).
constexpr double kQuadratureBound = 1e-10;

TEST(ContinuousResidual, DampedOscillatorSolvesFracElWithMirror) {
  const MechanicalLagrangian L(oscillator_model(), kA, kB);
  const Curve x = make_curve(Oscillator{false}, 2), y = make_curve(Oscillator{true}, 2);
  double worst_x = 0.0, worst_y = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (double t : {0.3, 1.0, 1.7}) {
    const ContinuousElResidual r = fractional_el_residual(L, 0.5, x, y, kA, kB, t);
    worst_x = std::max(worst_x, r.x_equation.cwiseAbs().maxCoeff());
    worst_y = std::max(worst_y, r.y_equation.cwiseAbs().maxCoeff());
    // The named phase point: D^{1/2}_+ y at t is D^{1/2}_− x at a + b − t (mirror).
    const PhasePoint<double> q = phase_point_on_curves(0.5, x, y, kA, kB, kA + kB - t);
    EXPECT_LE((r.point.dy_alpha - q.dx_alpha).cwiseAbs().maxCoeff(), kQuadratureBound);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("  Cor. 4.4: max |x-residual| = %.2e, max |y-residual| = %.2e (%.2f s)\n", worst_x,
              worst_y, seconds);
  EXPECT_LE(worst_x, kQuadratureBound);
  EXPECT_LE(worst_y, kQuadratureBound);
}

// The undamped oscillator (ω = √(k/m)): not a solution once R ≠ 0.
struct Undamped {
  bool mirrored;
  template <class T>
  Eigen::Matrix<T, Eigen::Dynamic, 1> operator()(T t) const {
    using std::sin;
    Eigen::Matrix<T, Eigen::Dynamic, 1> v(2);
    const T s = mirrored ? T(kA + kB) - t : t;
    for (int i = 0; i < 2; ++i) v(i) = T(kAmp[i]) * sin(T(std::sqrt(kK[i] / kM[i])) * s);
    return v;
  }
};

TEST(ContinuousResidual, NonSolutionsGiveOrderOneResiduals) {
  const MechanicalLagrangian L(oscillator_model(), kA, kB);
  // Negative control 1: x = the undamped oscillator (ω = √(k/m)), y its mirror.
  const ContinuousElResidual r = fractional_el_residual(L, 0.5, make_curve(Undamped{false}, 2),
                                                        make_curve(Undamped{true}, 2), kA, kB, 1.0);
  // The residual is the missing damping force ∓R ẋ: O(0.1–1).
  std::printf("  undamped curve: |x-residual| = %.3f, |y-residual| = %.3f\n",
              r.x_equation.cwiseAbs().maxCoeff(), r.y_equation.cwiseAbs().maxCoeff());
  EXPECT_GT(r.x_equation.cwiseAbs().maxCoeff(), 0.1);
  EXPECT_GT(r.y_equation.cwiseAbs().maxCoeff(), 0.1);
  // Negative control 2: the right x with a wrong y (the mirrored undamped curve): the x-equation
  // does not see y for the mechanical L and still vanishes, the y-equation does not.
  const ContinuousElResidual r2 = fractional_el_residual(
      L, 0.5, make_curve(Oscillator{false}, 2), make_curve(Undamped{true}, 2), kA, kB, 1.0);
  EXPECT_LE(r2.x_equation.cwiseAbs().maxCoeff(), kQuadratureBound);  // x still solves its equation
  EXPECT_GT(r2.y_equation.cwiseAbs().maxCoeff(), 0.1);
}

TEST(ContinuousResidual, ExpressionCurvesMatchAutodiffCurves) {
  // The same damped oscillator written as formulas (derivatives symbolic instead of AD).
  auto formula = [](int i, bool mirrored) {
    const double g = kR[i] / (2 * kM[i]), w = std::sqrt(kK[i] / kM[i] - g * g);
    const std::string s = mirrored ? "(2 - t)" : "t";
    char buf[200];
    std::snprintf(buf, sizeof buf, "%.17g*exp(-%.17g*%s)*sin(%.17g*%s)", kAmp[i], g, s.c_str(), w,
                  s.c_str());
    return std::string(buf);
  };
  const Curve xe = make_expression_curve({formula(0, false), formula(1, false)});
  const Curve ye = make_expression_curve({formula(0, true), formula(1, true)});
  const Curve xa = make_curve(Oscillator{false}, 2);
  Eigen::MatrixXd ve(2, 3), va(2, 3);
  for (double t : {0.0, 0.4, 1.9}) {
    xe.evaluate(t, 2, ve);
    xa.evaluate(t, 2, va);
    EXPECT_LE((ve - va).cwiseAbs().maxCoeff(), 64 * kEps * 10);
  }
  const MechanicalLagrangian L(oscillator_model(), kA, kB);
  const ContinuousElResidual r = fractional_el_residual(L, 0.5, xe, ye, kA, kB, 0.8);
  EXPECT_LE(r.x_equation.cwiseAbs().maxCoeff(), kQuadratureBound);
  EXPECT_LE(r.y_equation.cwiseAbs().maxCoeff(), kQuadratureBound);
  EXPECT_THROW(make_expression_curve({"sin(s)"}), ExpressionError);
}

// Theorem 4.3 with a non-mechanical L (test::Coupled) and a full, non-symmetric Λ.
const Eigen::Matrix2d kLambda{{1.2, -0.7}, {0.4, 0.9}};

struct TransformedCoupled {
  template <class T>
  static Eigen::Matrix<T, Eigen::Dynamic, 1> map(const Eigen::Matrix<T, Eigen::Dynamic, 1>& v) {
    Eigen::Matrix<T, Eigen::Dynamic, 1> out(2);
    for (int i = 0; i < 2; ++i) out(i) = T(kLambda(i, 0)) * v(0) + T(kLambda(i, 1)) * v(1);
    return out;
  }
  template <class T>
  T operator()(const PhasePoint<T>& p) const {
    PhasePoint<T> q;
    q.t = p.t;
    q.x = map(p.x);
    q.y = map(p.y);
    q.xdot = map(p.xdot);
    q.ydot = map(p.ydot);
    q.dx_alpha = map(p.dx_alpha);
    q.dy_alpha = map(p.dy_alpha);
    return test::Coupled{}(q);
  }
};

// z(0) = 0 and z̃(b) = 0, so that the memory terms are bounded at their terminals.
struct ZCurve {
  bool tilde;
  bool mapped;  // return Λ z instead of z
  template <class T>
  Eigen::Matrix<T, Eigen::Dynamic, 1> operator()(T t) const {
    using std::cos;
    using std::sin;
    Eigen::Matrix<T, Eigen::Dynamic, 1> v(2);
    if (!tilde) {
      v(0) = T(0.5) * t * cos(t);
      v(1) = T(0.3) * sin(T(2) * t);
    } else {
      const T s = T(1.5) - t;
      v(0) = T(0.4) * s * (T(1) + T(0.2) * t);
      v(1) = T(0.6) * sin(s) * cos(T(0.5) * t);
    }
    return mapped ? TransformedCoupled::map(v) : v;
  }
};

TEST(ContinuousResidual, Theorem43LinearChangeOfVariables) {
  const double a = 0.0, b = 1.5, alpha = 0.6;
  const auto L = make_autodiff_lagrangian(test::Coupled{}, 2);
  const auto Lz = make_autodiff_lagrangian(TransformedCoupled{}, 2);
  const Curve x = make_curve(ZCurve{false, true}, 2), y = make_curve(ZCurve{true, true}, 2);
  const Curve z = make_curve(ZCurve{false, false}, 2), zt = make_curve(ZCurve{true, false}, 2);
  double worst = 0.0, size = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (double t : {0.4, 1.1}) {
    const ContinuousElResidual rx = fractional_el_residual(*L, alpha, x, y, a, b, t);
    const ContinuousElResidual rz = fractional_el_residual(*Lz, alpha, z, zt, a, b, t);
    worst = std::max({worst,
                      (rz.x_equation - kLambda.transpose() * rx.x_equation).cwiseAbs().maxCoeff(),
                      (rz.y_equation - kLambda.transpose() * rx.y_equation).cwiseAbs().maxCoeff()});
    size =
        std::max({size, rx.x_equation.cwiseAbs().maxCoeff(), rx.y_equation.cwiseAbs().maxCoeff()});
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("  Thm 4.3: max |E_z - Lambda^T E_x| = %.2e, |E_x| up to %.2f (%.2f s)\n", worst,
              size, seconds);
  EXPECT_GT(size, 0.1);  // the curves are not solutions: the identity is not 0 = 0
  EXPECT_LE(worst, kQuadratureBound);
}

TEST(ContinuousResidual, RejectsBadInputAndUnboundedMemory) {
  const MechanicalLagrangian L(oscillator_model(), kA, kB);
  const Curve x = make_curve(Oscillator{false}, 2), y = make_curve(Oscillator{true}, 2);
  EXPECT_THROW(fractional_el_residual(L, 0.5, x, y, kA, kB, 2.5), std::invalid_argument);
  EXPECT_THROW(fractional_el_residual(L, 1.5, x, y, kA, kB, 1.0), std::invalid_argument);
  EXPECT_THROW(fractional_el_residual(L, 0.5, x, y, kB, kA, 1.0), std::invalid_argument);
  EXPECT_THROW(fractional_el_residual(L, 0.5, make_expression_curve({"t"}), y, kA, kB, 1.0),
               std::invalid_argument);
  // x(a) ≠ 0: D^{1/2}_−x ~ x(a)(t−a)^{−1/2} is unbounded at a, so D^{1/2}_−(−R D^{1/2}_−x) cannot
  // be formed by the quadrature: a clear error, not a NaN.
  const Curve shifted = make_expression_curve({"1 + t", "0.5"});
  const Curve mirror = make_expression_curve({"0", "0"});
  try {
    fractional_el_residual(L, 0.5, shifted, mirror, kA, kB, 1.0);
    FAIL() << "no error for x(a) != 0";
  } catch (const std::domain_error& e) {
    EXPECT_NE(std::string(e.what()).find("x(a) = 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fracvi
