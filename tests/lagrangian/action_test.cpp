// The action `ActFunc`, its exact first variation and Theorem `ConsFraEL` (issue 13 item 1).
//
// * The identity of the theorem's proof (`RestVar`): for restricted variations δx = δy = η with
//   η(a) = η(b) = 0, δA = ∫(E_x + E_y)·η dt, E_x, E_y the `FracEL` residuals, checked at
//   α = 0.3, 0.5, 0.8 for two general Lagrangians along curves that are not solutions (so that
//   both sides are O(1)): test::Coupled (d = 2, every block coupled nonlinearly, x(a) = y(b) = 0)
//   and a d = 1 Lagrangian with position-dependent mass, a gyroscopic ẋ·D^α_+y term, explicit time
//   dependence and x(a), y(b) ≠ 0 (the endpoint singularities of issue 13 item 2).
// * Negative control: an unrestricted variation (δx ≠ δy) breaks the identity by O(0.1–1).
// * The action itself against a closed form, and δA against the derivative of a closed-form
//   action in ε (independent of the quadrature machinery).
#include "fracvi/lagrangian/action.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// d = 1, nonlinear mass and potential, gyroscopic ẋ·D^α_+y and sin(t) ẏ·D^α_−x terms, explicit
// time dependence; ∂L/∂D^α_+y = −0.6 D^α_−x + 0.45 ẋ is affine in D^α_−x with a constant
// coefficient, so curves with x(a) ≠ 0 are admissible (continuous_residual.hpp).
const std::string kGyroscopic =
    "0.5*(1 + 0.3*x1^2)*xdot1^2 + 0.5*ydot1^2 - (1 - cos(x1)) - 0.5*y1^2 - 0.6*dx1*dy1"
    " + 0.45*xdot1*dy1 + 0.35*t*x1*ydot1 + 0.2*sin(t)*ydot1*dx1";

// d = 1, non-bilinear memory coupling (D^α_−x·D^α_+y)², position-dependent masses, gyroscopic
// x·ẏ and ẋ·D^α_±x terms, explicit time dependence. ∂L/∂D^α_+y is not affine in D^α_−x, so the
// curves start (x) and end (y) at 0.
const std::string kNonlinearCoupling =
    "0.5*(1 + 0.3*x1^2)*xdot1^2 + 0.5*(1 + 0.2*sin(y1))*ydot1^2 - (1 - cos(x1)) - 0.5*y1^2"
    " - 0.4*dx1*dy1 + 0.05*(dx1*dy1)^2 + 0.2*x1*ydot1 + 0.1*xdot1*dx1 + 0.1*cos(t)*xdot1*dy1";

struct Case {
  const char* name;
  std::shared_ptr<const Lagrangian> lagrangian;
  Curve x, y;
  Variation restricted, unrestricted;  // (η, η) and (η, ζ), ζ ≠ η
  double a, b;
};

Case nonlinear_case() {
  const Curve eta = make_expression_curve({"t^2*(1.5 - t)^2*(1 + t)"});
  const Curve zeta = make_expression_curve({"sin(pi*t/1.5)^2"});
  return {"(dx dy)^2 coupling, x(a) = y(b) = 0",
          std::make_shared<const ExpressionLagrangian>(1, kNonlinearCoupling),
          make_expression_curve({"0.5*t*cos(t)"}),
          make_expression_curve({"0.4*(1.5 - t)*(1 + 0.2*t)"}),
          {eta, eta},
          {eta, zeta},
          0.0,
          1.5};
}

Case gyroscopic_case() {
  const Curve eta = make_expression_curve({"(t - 0.2)^2*(1.7 - t)^2*(1 + t)"});
  const Curve zeta = make_expression_curve({"sin(pi*(t - 0.2)/1.5)^2"});
  return {"gyroscopic, x(a), y(b) != 0",
          std::make_shared<const ExpressionLagrangian>(1, kGyroscopic),
          make_expression_curve({"0.8 + 0.5*(t - 0.2) + (t - 0.2)^2.5"}),
          make_expression_curve({"-0.6 + (1.7 - t)^2.25 + 0.3*sin(1.7 - t)"}),
          {eta, eta},
          {eta, zeta},
          0.2,
          1.7};
}

// All quadratures run at relative tolerance 1e-6 (a stopping criterion on successive tanh–sinh
// refinements: with doubly exponential convergence the value returned is far more accurate, and
// the nested residuals carry ~1e-14). Measured agreement ≤ 7e-15 at 1e-7, ≤ 2.1e-13 at 1e-6
// (printed). Asked: 1e-8 relative; the negative control misses by more than 1e-3.
constexpr double kIdentityBound = 1e-8;

// Both sides of the identity for one Lagrangian at α = 0.3, 0.5, 0.8 (some 2–6 s each: one nested
// residual per node of the outer quadrature).
void check_identity(const Case& c) {
  ContinuousResidualOptions options;
  options.tolerance = 1e-6;  // 1e-9: the same digits to ~1e-14, 2–8 times slower
  for (double alpha : {0.3, 0.5, 0.8}) {
    const auto start = std::chrono::steady_clock::now();
    const Lagrangian& L = *c.lagrangian;
    const double delta_r = action_variation(L, alpha, c.x, c.y, c.restricted.delta_x,
                                            c.restricted.delta_y, c.a, c.b, options);
    const double delta_u = action_variation(L, alpha, c.x, c.y, c.unrestricted.delta_x,
                                            c.unrestricted.delta_y, c.a, c.b, options);
    const std::vector<double> pairing =
        fracel_pairing(L, alpha, c.x, c.y, {c.restricted, c.unrestricted}, c.a, c.b, options);
    std::printf(
        "  %s, alpha = %.1f: restricted dA = %.15f, int (E_x + E_y) eta = %.15f "
        "(diff %.1e); unrestricted dA = %.6f, int (E_x eta + E_y zeta) = %.6f "
        "(%.1f s)\n",
        c.name, alpha, delta_r, pairing[0], delta_r - pairing[0], delta_u, pairing[1],
        seconds_since(start));
    EXPECT_GT(std::abs(delta_r), 0.05) << "the identity must not be 0 = 0";
    EXPECT_LE(std::abs(delta_r - pairing[0]), kIdentityBound * (1.0 + std::abs(delta_r)))
        << c.name << ", alpha = " << alpha;
    // Negative control: for δx ≠ δy the identity fails, by far more than its tolerance (5 orders
    // of magnitude; measured 0.0065–0.48).
    EXPECT_GT(std::abs(delta_u - pairing[1]), 1e5 * kIdentityBound * (1.0 + std::abs(delta_u)))
        << c.name << ", alpha = " << alpha;
  }
}

TEST(Action, RestrictedVariationIsThePairingNonlinearCoupling) {
  check_identity(nonlinear_case());
}

TEST(Action, RestrictedVariationIsThePairingGyroscopicNonzeroEnds) {
  check_identity(gyroscopic_case());
}

// A[x, y] against the closed form for L = ½ẋ² − ρ D^α_−x D^α_+y along x = c + (t−a)^p,
// y = e + (b−t)^q (c, e ≠ 0): with s = t − a, ℓ = b − a,
//   D^α_−x = c s^{−α}/Γ(1−α) + Γ(p+1)/Γ(p+1−α) s^{p−α},   D^α_+y likewise in ℓ − s,
//   ∫_0^ℓ s^μ (ℓ−s)^ν ds = ℓ^{μ+ν+1} B(μ+1, ν+1),
// std::tgamma and std::beta only (independent of the library's RL code).
TEST(Action, ClosedFormAlongPowerCurves) {
  const double a = 0.2, b = 1.7, len = b - a, c = 0.8, p = 2.5, e = -0.6, q = 2.25, rho = 0.7;
  const Curve x = make_expression_curve({"0.8 + (t - 0.2)^2.5"});
  const Curve y = make_expression_curve({"-0.6 + (1.7 - t)^2.25"});
  const ExpressionLagrangian L(1, "0.5*xdot1^2 - 0.7*dx1*dy1");
  for (double alpha : {0.3, 0.5, 0.7}) {
    // D^α_−x = Σ coefficient·s^exponent (two terms), D^α_+y likewise in ℓ − s.
    const double cx[2] = {c / std::tgamma(1 - alpha),
                          std::tgamma(p + 1) / std::tgamma(p + 1 - alpha)};
    const double ex[2] = {-alpha, p - alpha};
    const double cy[2] = {e / std::tgamma(1 - alpha),
                          std::tgamma(q + 1) / std::tgamma(q + 1 - alpha)};
    const double ey[2] = {-alpha, q - alpha};
    double memory = 0.0;
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        memory +=
            cx[i] * cy[j] * std::pow(len, ex[i] + ey[j] + 1) * std::beta(ex[i] + 1, ey[j] + 1);
      }
    }
    const double kinetic = 0.5 * p * p * std::pow(len, 2 * p - 1) / (2 * p - 1);
    const double expected = kinetic - rho * memory;
    const double computed = action(L, alpha, x, y, a, b);
    std::printf("  A closed form, alpha = %.1f: %.16f vs %.16f (rel. %.1e)\n", alpha, computed,
                expected, std::abs(computed - expected) / std::abs(expected));
    // tanh–sinh at 1e-12 on an integrand with (t−a)^{−α} and (b−t)^{−α} end behaviour.
    EXPECT_LE(std::abs(computed - expected), 1e-11 * std::abs(expected)) << "alpha = " << alpha;
  }
}

// δA against the action itself: for a Lagrangian quadratic in V the action along x + εη is
// A + ε δA + ε² A₂[η], so δA = (A[x + η, y + η] − A[x − η, y − η])/2 exactly (polarisation, no
// truncation). Checked with a gyroscopic, time-dependent quadratic L at α = 0.3, 0.8, restricted
// and unrestricted.
TEST(Action, VariationIsTheExactDerivativeOfTheAction) {
  const ExpressionLagrangian L(1,
                               "0.5*xdot1^2 + 0.5*ydot1^2 - 0.5*x1^2 - 0.3*t*x1*y1"
                               " - 0.6*dx1*dy1 + 0.45*xdot1*dy1 + 0.2*ydot1*dx1");
  const double a = 0.0, b = 1.5;
  const std::string xs = "(0.5 + 0.5*t*cos(t))", ys = "(0.4*(1.5 - t)*(1 + 0.2*t) - 0.3)";
  const std::string eta = "(t*(1.5 - t)*(1 + t))", zeta = "(sin(pi*t/1.5))";
  auto curve = [](const std::string& text) { return make_expression_curve({text}); };
  for (double alpha : {0.3, 0.8}) {
    for (const std::string& eta_y : {eta, zeta}) {
      const double delta =
          action_variation(L, alpha, curve(xs), curve(ys), curve(eta), curve(eta_y), a, b);
      const double plus =
          action(L, alpha, curve(xs + " + " + eta), curve(ys + " + " + eta_y), a, b);
      const double minus =
          action(L, alpha, curve(xs + " - " + eta), curve(ys + " - " + eta_y), a, b);
      const double polarised = 0.5 * (plus - minus);
      std::printf("  alpha = %.1f, delta y = %s: dA = %.15f, (A+ - A-)/2 = %.15f\n", alpha,
                  eta_y.c_str(), delta, polarised);
      EXPECT_GT(std::abs(delta), 1e-3);  // not 0 = 0 (measured 0.009–0.76)
      EXPECT_LE(std::abs(delta - polarised), 1e-11 * (1.0 + std::abs(plus) + std::abs(minus)));
    }
  }
}

}  // namespace
}  // namespace fracvi
