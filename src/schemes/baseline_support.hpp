// Shared parts of the baseline schemes (euler-*, lda-midpoint, conformal-strang, dopri5,
// pi-trapezoid; docs/theory/baselines.md), internal:
//  * the linear test problem of a problem (M, R and K = ∇²U(x_0, t_0)) and the search for the
//    largest stable step of a scheme whose linear recursion is given by its characteristic symbol
//    (argument principle) or by its one-step matrix (spectral radius);
//  * the energy account of a scheme that is not variational: the work of f and of the explicit
//    time dependence of U on the grid, so that E_k + W_k − E_0 is an O(h^p) consistency check.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <cstddef>
#include <functional>
#include <string>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi::internal {

/// The linear test problem M x'' + R D^{2α} x + K x = 0 of `problem`: the symmetric parts of M and
/// R and K = ∇²U(x_0, t_0) (zero without a potential; negative curvature enters with its
/// magnitude). `exact` is false when U is not quadratic (the bound is then that of the
/// linearisation at x_0).
struct LinearTestProblem {
  Eigen::MatrixXd mass, damping, stiffness;
  bool exact = true;
};
LinearTestProblem linear_test_problem(const InitialValueProblem& problem);

/// Beyond this dimension the linear test problem (dense d × d matrices) is not formed: the bound
/// is not checked (unchecked_bound), and the run's own health checks remain.
inline constexpr Eigen::Index kMaxStabilityDimension = 2000;
/// stable, largest_step +∞, sharp false, and a rule saying that nothing was checked.
StabilityBound unchecked_bound(const InitialValueProblem& problem);

/// The characteristic determinant is evaluated densely up to this dimension; beyond it the bound
/// is estimated from the extreme scalar modes (StabilityBound::sharp false).
inline constexpr Eigen::Index kMaxCharacteristicDimension = 16;

/// The symbol A(ξ) (d × d) of a linear recursion Σ_j A_j x_{k−j} = 0, A(ξ) = Σ_j A_j ξ^j,
/// analytic in |ξ| < 1.
using CharacteristicSymbol = std::function<void(std::complex<double> xi, Eigen::MatrixXcd& a)>;

/// Zeros of det A(ξ) in |ξ| < 1 − 1e-7 (amplification factors |ζ| = 1/|ξ| > 1 + 1e-7), by the
/// argument principle on that circle (adaptive in the angle; the circle stays off the branch point
/// ξ = 1 of (1 − ξ)^{2α}, where a singular K leaves a neutral root).
int characteristic_roots_inside(const CharacteristicSymbol& symbol, Eigen::Index d);

/// The largest step for which `stable(h)` holds, assuming stability for h below it and instability
/// above (doubling from `h_start`, then bisection to a relative 1e-10): +∞ when stable up to
/// 2^60 h_start, 0 when unstable down to 2^−60 h_start.
double largest_stable_step(const std::function<bool(double)>& stable, double h_start);

/// A StabilityBound from the largest stable step: the problem's h is stable when h < h*. The rule
/// reads "<what> holds for h < h* (h = …)".
StabilityBound step_bound(const InitialValueProblem& problem, double largest_step, bool sharp,
                          const std::string& what);

/// The work of f and of the explicit time dependence of U over one step of a scheme without a
/// discrete energy balance: f by the trapezoidal rule in time against the increment,
/// ½(f(t_k) + f(t_{k+1}))·(x_{k+1} − x_k), and U(x̄, t_{k+1}) − U(x̄, t_k) at the midpoint x̄. Both
/// are second-order quadratures of ∫ f·v dt and ∫ ∂_t U dt. No allocation after construction.
class ExternalWork {
 public:
  explicit ExternalWork(const InitialValueProblem& problem);
  /// The work put in over step k (x_k → x_{k+1}); f(t_k) is kept from the previous call.
  double step(std::size_t k, const Eigen::VectorXd& x_k, const Eigen::VectorXd& x_next);
  /// Saves or restores f(t_k), the value kept from the previous call (core/state_archive.hpp).
  void visit_state(StateArchive& archive) { archive.dense("external.f", f_now_); }

 private:
  const InitialValueProblem& problem_;
  bool has_forcing_, u_time_dependent_;
  Eigen::VectorXd f_now_, f_next_, mid_;
};

/// R h^{−γ}·(GL sum of order γ) for the Euler schemes and the explicit bound's symbol: the complex
/// power (1 − ξ)^γ on the principal branch (analytic for |ξ| < 1).
inline std::complex<double> one_minus_power(std::complex<double> xi, double gamma) {
  if (gamma == 0.0) return 1.0;
  return std::pow(1.0 - xi, gamma);
}

}  // namespace fracvi::internal
