// Continuous Riemann–Liouville derivatives D^α_− and D^α_+ on [a, b] (the paper's `RL`).
//
// The definition `RL` differentiates a weakly singular integral, which is useless numerically.
// For f ∈ C¹[a, b] it is equivalent (integrate once by parts, then subtract f'(t) from the
// derivative under the integral) to
//
//   D^α_− f(t) =  f(a) (t−a)^{−α}/Γ(1−α) + f'(t) (t−a)^{1−α}/Γ(2−α)
//                 + 1/Γ(1−α) ∫_0^{t−a} u^{−α} (f'(t−u) − f'(t)) du,
//   D^α_+ f(t) =  f(b) (b−t)^{−α}/Γ(1−α) − f'(t) (b−t)^{1−α}/Γ(2−α)
//                 − 1/Γ(1−α) ∫_0^{b−t} u^{−α} (f'(t+u) − f'(t)) du,
//
// (the second is the first under the reflection t ↦ a+b−t). Every term stays bounded as α → 1
// (1/Γ(1−α) → 0 while the integral stays finite), so the form is well conditioned on all of
// [0, 1]: α = 1 gives ±f'(t) exactly, α = 0 gives f(t). The remaining integrand behaves like
// u^{1−α} at u = 0, an algebraic endpoint singularity that tanh–sinh (double-exponential)
// quadrature integrates to near machine precision; it is fed exact distances u (Boost's
// two-argument integrand form), never differences t − τ that have cancelled.
//
// Conventions.
//  * Side::kLeft is the paper's D^α_− (retarded: memory of the past, lower terminal a),
//    Side::kRight is D^α_+ (advanced: memory of the future, terminal b), with the minus sign of
//    `RL`, so D^1_+ f = −f' and D^{1/2}_+ D^{1/2}_+ f = −f' (`DoubleFracInt`).
//  * α ∈ [0, 1] is the paper's order (the Lagrangian order; the damping term has order 2α).
//  * At the terminal (t = a for kLeft, t = b for kRight) and 0 < α < 1 the derivative of a
//    function with f(terminal) ≠ 0 is infinite: the functions return ±∞ with the sign of
//    f(terminal). If f(terminal) = 0 they return the limit, 0. At α = 1 they return ±f'(t), at
//    α = 0 f(t) (also at the terminal).
//
// Accuracy: for smooth f the tanh–sinh quadrature converges doubly exponentially, and the result
// is at round-off level: measured ≤ 3e-15 relative to max(1, |D^α f|) against closed forms
// (powers, Mittag-Leffler and sine series) and ≤ 7e-16 for `DoubleFracInt` and
// `IntegrationByParts` (tests/fractional/riemann_liouville_test.cpp, which hold it to 1e-12).
// Functions whose derivative has an integrable singularity at the terminal (f ~ (t−a)^p,
// 0 < p < 1) also work, but f' is evaluated at abscissas τ = a + δ rounded to the grid of a,
// which costs about |c|·ulp(a)^p; it is exact when a = 0 (resp. b = 0). Quadrature points that
// round onto the terminal itself are skipped (their measure is below ulp(a)). Points t very
// close to a terminal c ≠ 0 inherit the rounding of t − c (relative ulp(c)/|t − c|).
//
// Cost: one tanh–sinh quadrature per point, typically 100–800 evaluations of f' (a few thousand
// when α is near 1 and the tolerance is below the integrand's round-off), about 3.5 μs for
// f = exp on [0, 2]. Use the discrete operators (fracvi/fractional/weights.hpp) on grids; these
// functions are the reference they are tested against and the tool for residuals of `FracEL`
// along given smooth curves. Thread-safe (one quadrature table per thread) and reentrant (f may
// itself call rl_derivative).
#pragma once

#include <Eigen/Core>  // must precede the unsupported module in Eigen 3.4
#include <concepts>
#include <functional>
#include <unsupported/Eigen/AutoDiff>

namespace fracvi {

/// Which Riemann–Liouville derivative of `RL`.
enum class Side {
  kLeft,   ///< D^α_−: retarded, memory of the past, terminal a
  kRight,  ///< D^α_+: advanced, memory of the future, terminal b; D^1_+ f = −f'
};

using RealFunction = std::function<double(double)>;

/// Default relative tolerance of the tanh–sinh quadrature (Boost's criterion: successive
/// refinements differ by less than tolerance × ∫|integrand|).
inline constexpr double kRlDefaultTolerance = 1e-12;

/// D^α_σ f(t) on [a, b] for α ∈ [0, 1], from f and its derivative df (see the file comment for
/// the formula, the conventions and the values at the terminal).
///
/// Throws std::invalid_argument (message names the argument, its value and the rule) if alpha
/// is outside [0, 1], a >= b, t is outside [a, b], any of them is not finite, tolerance is not
/// positive, or f/df is empty. A non-finite value of df inside the interval makes Boost's
/// quadrature throw boost::math::evaluation_error (a std::runtime_error).
double rl_derivative(double alpha, Side side, const RealFunction& f, const RealFunction& df,
                     double a, double b, double t, double tolerance = kRlDefaultTolerance);

/// Same as rl_derivative(), with the point given by its distance from the operator's terminal:
/// t = a + distance for kLeft, t = b − distance for kRight, distance ∈ [0, b − a].
///
/// The terms f(a)(t−a)^{−α} and (t−a)^{1−α} then use the exact distance. Use this inside an
/// outer quadrature whose abscissas near the terminal are only known as distances (tanh_sinh's
/// two-argument integrands): at a ≠ 0, t − a for an abscissa t = a + δ is wrong in every digit
/// once δ < ulp(a), and the mass of (t−a)^{−α} below ulp(a) is ulp(a)^{1−α}/(1−α) — 3e-3 for
/// α = 0.8, a = 0.3. Integrals such as ∫ g D^α_− f dt (`IntegrationByParts`, the action
/// `ActFunc`) need this form to be accurate.
double rl_derivative_at_distance(double alpha, Side side, const RealFunction& f,
                                 const RealFunction& df, double a, double b, double distance,
                                 double tolerance = kRlDefaultTolerance);

namespace internal {

/// Forward-mode dual number used to differentiate user functions at one point.
using RlAutoDiff = Eigen::AutoDiffScalar<Eigen::Matrix<double, 1, 1>>;

/// f'(t) by forward automatic differentiation of a generic callable. A result that is a plain
/// number (f ignores its argument) converts to a dual number with zero derivative.
template <class F>
double autodiff_derivative(const F& f, double t) {
  const RlAutoDiff y = f(RlAutoDiff(t, 1, 0));
  return y.derivatives()(0);
}

}  // namespace internal

/// A user function that can be evaluated at double and at the dual number
/// internal::RlAutoDiff. Write it as a generic lambda with unqualified maths calls so that
/// Eigen's overloads are found: `[](auto t) { using std::sin; return sin(t) * t; }`.
template <class F>
concept AutoDiffFunction = requires(const F& f, double t, internal::RlAutoDiff x) {
  { f(t) } -> std::convertible_to<double>;
  { f(x) } -> std::convertible_to<internal::RlAutoDiff>;
};

/// rl_derivative() with f' obtained by forward automatic differentiation of f at each point.
template <AutoDiffFunction F>
double rl_derivative(double alpha, Side side, const F& f, double a, double b, double t,
                     double tolerance = kRlDefaultTolerance) {
  return rl_derivative(alpha, side,
                       RealFunction([&f](double s) { return static_cast<double>(f(s)); }),
                       RealFunction([&f](double s) { return internal::autodiff_derivative(f, s); }),
                       a, b, t, tolerance);
}

/// rl_derivative_at_distance() with f' obtained by automatic differentiation.
template <AutoDiffFunction F>
double rl_derivative_at_distance(double alpha, Side side, const F& f, double a, double b,
                                 double distance, double tolerance = kRlDefaultTolerance) {
  return rl_derivative_at_distance(
      alpha, side, RealFunction([&f](double s) { return static_cast<double>(f(s)); }),
      RealFunction([&f](double s) { return internal::autodiff_derivative(f, s); }), a, b, distance,
      tolerance);
}

/// Γ(p+1)/Γ(p+1−order), the coefficient of the closed form D^order (t−a)^p = coefficient ·
/// (t−a)^{p−order}. Exactly 0 when p+1−order is a non-positive integer (1/Γ has a zero there;
/// e.g. D^{1/2}(t−a)^{−1/2} = 0). Requires p > −1 (integrable) and order ≥ 0, both finite; any
/// order is allowed because the closed form holds for the RL derivative of every order (the
/// damping term has order 2α ∈ [0, 2]).
double rl_power_coefficient(double order, double p);

/// Closed forms: D^order_− (t−a)^p (kLeft) and D^order_+ (b−t)^p (kRight), both equal to
/// rl_power_coefficient(order, p) · d^{p−order} with d = t−a resp. b−t. At the terminal
/// (d = 0) this is 0 for p > order, the coefficient for p = order, and ±∞ (sign of the
/// coefficient) for p < order unless the coefficient is 0. For order ≤ 1 this is the same
/// operator as rl_derivative(); for order > 1 it is the RL derivative of order n = ⌈order⌉,
/// (d/dt)^n I^{n−order}_− resp. (−d/dt)^n I^{n−order}_+ (I the RL integrals).
double rl_derivative_power(double order, Side side, double p, double a, double b, double t);

}  // namespace fracvi
