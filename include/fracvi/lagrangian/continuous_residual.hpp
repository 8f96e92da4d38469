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
// Applicability: rl_derivative() needs the outer function to be finite at the operator's terminal.
// With the Riemann–Liouville operators, D^α_−x is unbounded at t = a unless x(a) = 0 (and D^α_+y
// at b unless y(b) = 0) for 0 < α < 1, so for Lagrangians whose ∂L/∂D^α_+y depends on D^α_−x (the
// mechanical one) the curves must start (x) and end (y) at 0 — shift coordinates if needed. A
// non-finite result throws std::domain_error naming the equation and the component.
//
// Accuracy and cost: nested tanh–sinh quadrature, every operator taken with its terminal moved to
// 0 (D^α_+ by reflection) so that distances from the terminals are exact. Measured
// (tests/lagrangian/continuous_residual_test.cpp): ~1e-15 for the damped oscillator of Cor. 4.4 and
// for the Theorem 4.3 identity, 0.5–1 s per time point for d = 2. One evaluation takes some
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
/// std::domain_error if a result is not finite (see the applicability note above).
ContinuousElResidual fractional_el_residual(const Lagrangian& lagrangian, double alpha,
                                            const Curve& x, const Curve& y, double a, double b,
                                            double t,
                                            const ContinuousResidualOptions& options = {});

/// The phase point V(t) = (x, y, ẋ, ẏ, D^α_−x, D^α_+y)(t) of `TotalCoord` for the curves.
PhasePoint<double> phase_point_on_curves(double alpha, const Curve& x, const Curve& y, double a,
                                         double b, double t,
                                         const ContinuousResidualOptions& options = {});

}  // namespace fracvi
