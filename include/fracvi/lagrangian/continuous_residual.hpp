// The residual of the restricted fractional Euler–Lagrange equations (`FracEL`, Theorem 4.2)
// along given smooth curves x(t), y(t) on [a, b]:
//
//   x-equation:  ∂L/∂x − d/dt(∂L/∂ẋ) + D^α_−(∂L/∂D^α_+y)    (`FracEL:-`)
//   y-equation:  ∂L/∂y − d/dt(∂L/∂ẏ) + D^α_+(∂L/∂D^α_−x)    (`FracEL:+`)
//
// all evaluated along the phase curve V(τ) = (x, y, ẋ, ẏ, D^α_−x, D^α_+y)(τ) (`TotalCoord`).
//
// How each piece is computed (no finite differences):
//  * D^α_−x(τ), D^α_+y(τ): rl_derivative() (tanh–sinh quadrature, fractional/riemann_liouville.hpp)
//    of each component, with the curve's exact derivative.
//  * d/dτ ∂L/∂ẋ, and the derivative of the functions under D^α_±: the chain rule through the
//    exact Hessian of L, d/dτ ∇L(τ, V(τ)) = ∂_τ∇L + ∇²L · V'(τ), with
//    V' = (ẋ, ẏ, ẍ, ÿ, d/dτ D^α_−x, d/dτ D^α_+y) and
//        d/dτ D^α_− f = D^α_−(f') + f(a) (τ−a)^{−1−α}/Γ(−α),
//        d/dτ D^α_+ f = D^α_+(f') − f(b) (b−τ)^{−1−α}/Γ(−α)
//    (differentiate the well-conditioned form of `RL` term by term; 1/Γ(−α) = 0 at α ∈ {0, 1}).
//    These two extra quadratures per component are only taken where the Hessian couples the row
//    needed to a fractional block.
//  * The outer D^α_± of ∂L/∂D^α_±: rl_derivative() again, its integrand evaluating V (itself by
//    quadrature) at every node; nodes are cached so the d components share them.
//
// Nonzero end values (Riemann–Liouville, 0 < α < 1). D^α_−x = x(a)(τ−a)^{−α}/Γ(1−α) +
// D^α_−(x − x(a)): the first part is unbounded at a, the second bounded. Where ∂L/∂D^α_+y depends
// on D^α_−x (the mechanical L) the x-equation splits it off: if ∂L/∂D^α_+y is affine in D^α_−x
// with a constant coefficient block C = ∂²L/∂D^α_+y∂D^α_−x (checked at every node, and the split
// checked at t), then D^α_−(∂L/∂D^α_+y) = D^α_−[∂L/∂D^α_+y at the regular part] +
// C x(a) (t−a)^{−2α}/Γ(1−2α), the last term by the closed form of `RL` on powers (0 at α = 1/2,
// where D^{1/2}_−D^{1/2}_−x = ẋ for bounded x). The y-equation mirrors it with y(b) and (b−t).
// Otherwise (C not constant, or ∂L/∂D^α_+y not affine) std::domain_error names x(a) and the rule.
// The (t−a)^{−2α} term is finite for t > a; at t = a it is infinite (and for 2α > 1 not even
// integrable: the Riemann–Liouville problem with x(a) ≠ 0 is then ill-posed), and the error says
// so. At its own terminal (t = a for the x-equation) the outer operator is a limit of a function
// behaving like (t−a)^{1−α}, which the quadrature form cannot take: evaluating there throws
// std::domain_error whenever C ≠ 0. A non-finite result throws std::domain_error naming the
// equation and the component.
//
// Accuracy and cost: nested tanh–sinh quadrature, every operator taken with its terminal moved to
// 0 (D^α_+ by reflection) so that distances from the terminals are exact. Measured
// (tests/lagrangian/continuous_residual_test.cpp): ~1e-15 for the damped oscillator of Cor. 4.4
// (also with x(0) = 1, v(0) = 0.5: 3e-16) and for the Theorem 4.3 identity; relative 2e-16
// against closed forms along x = c + (t−a)^p, y = e + (b−t)^q with c, e ≠ 0 at α = 0.3–0.9;
// 0.5–1 s per time point for d = 2. One evaluation takes some
// 10^5–10^6 curve evaluations: a verification tool, not a solver.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <string>
#include <unsupported/Eigen/AutoDiff>
#include <vector>

#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/lagrangian/phase_point.hpp"

namespace fracvi {

/// A smooth curve c : [a, b] → R^d with its first two derivatives.
struct Curve {
  Eigen::Index dimension = 0;
  /// out (d × (order+1), order ≤ 2): column j = c^{(j)}(t).
  std::function<void(double t, int order, Eigen::Ref<Eigen::MatrixXd> out)> evaluate;
};

namespace internal {
using CurveDual = Eigen::AutoDiffScalar<Eigen::Matrix<double, 1, 1>>;
using CurveDual2 = Eigen::AutoDiffScalar<Eigen::Matrix<CurveDual, 1, 1>>;
}  // namespace internal

/// A curve from a generic callable `Eigen::Matrix<T, Eigen::Dynamic, 1> f(T t)` (a generic lambda
/// or a functor template, maths calls unqualified), differentiated by nested forward AutoDiff.
template <class F>
Curve make_curve(F f, Eigen::Index d) {
  Curve c;
  c.dimension = d;
  c.evaluate = [f = std::move(f), d](double t, int order, Eigen::Ref<Eigen::MatrixXd> out) {
    using D1 = internal::CurveDual;
    using D2 = internal::CurveDual2;
    if (order == 0) {
      const Eigen::VectorXd v = f(t);
      out.col(0) = v;
      return;
    }
    if (order == 1) {
      const Eigen::Matrix<D1, Eigen::Dynamic, 1> v = f(D1(t, 1, 0));
      for (Eigen::Index i = 0; i < d; ++i) {
        out(i, 0) = v(i).value();
        out(i, 1) = v(i).derivatives().size() ? v(i).derivatives()(0) : 0.0;
      }
      return;
    }
    D2 s;
    s.value() = D1(t, 1, 0);
    s.derivatives()(0) = D1(1.0, Eigen::Matrix<double, 1, 1>::Zero());
    const Eigen::Matrix<D2, Eigen::Dynamic, 1> v = f(s);
    for (Eigen::Index i = 0; i < d; ++i) {
      out(i, 0) = v(i).value().value();
      out(i, 1) = v(i).value().derivatives()(0);
      out(i, 2) = v(i).derivatives()(0).derivatives()(0);
    }
  };
  return c;
}

/// A curve from d formulas in t (e.g. "exp(-0.1*t)*sin(t)"), derivatives exact and symbolic.
/// Throws ExpressionError for a malformed formula or one that uses a variable other than t.
Curve make_expression_curve(const std::vector<std::string>& formulas);

struct ContinuousResidualOptions {
  /// Relative tolerance of every tanh–sinh quadrature (inner and outer).
  double tolerance = 1e-12;
};

struct ContinuousElResidual {
  Eigen::VectorXd x_equation;  ///< `FracEL:-`, d components
  Eigen::VectorXd y_equation;  ///< `FracEL:+`, d components
  PhasePoint<double> point;    ///< V(t), the phase point the equations were evaluated at
};

/// Both residuals of `FracEL` at time t ∈ [a, b] for the Lagrangian of order alpha ∈ [0, 1].
/// Throws std::invalid_argument for bad arguments (sizes, order, interval, t outside [a, b]) and
/// std::domain_error where the residual is not computable (see "Nonzero end values" above).
ContinuousElResidual fractional_el_residual(const Lagrangian& lagrangian, double alpha,
                                            const Curve& x, const Curve& y, double a, double b,
                                            double t,
                                            const ContinuousResidualOptions& options = {});

/// The phase point V(t) = (x, y, ẋ, ẏ, D^α_−x, D^α_+y)(t) of `TotalCoord` for the curves.
PhasePoint<double> phase_point_on_curves(double alpha, const Curve& x, const Curve& y, double a,
                                         double b, double t,
                                         const ContinuousResidualOptions& options = {});

}  // namespace fracvi
