// The discrete action sum (`DiscActSum`) for a general Lagrangian and the residual of the
// restricted discrete fractional Euler–Lagrange equations (`DiscFracEL`, Theorem 5.2).
//
// Grid t_k = a + k h, h = (b − a)/N. Discrete curves are d × (N+1) matrices, column k = x_k
// (fracvi/discrete/operators.hpp). L(k) is L evaluated at time t_{k+½} and at the phase point
//
//     z_k = (S x_k, S y_k, Δ_−x_k, −Δ_+y_k, Δ^α_−x_k, Δ^α_+y_k)           (`AllSequencs`)
//
// — the midpoint S x_k = (x_k + x_{k+1})/2 paired with the *backward* difference
// Δ_−x_k = (x_k − x_{k−1})/h (Δ_−x_0 := 0), and in the ẏ slot the forward difference
// −Δ_+y_k = (y_{k+1} − y_k)/h. The paper puts Δ_+y_k = −(y_{k+1} − y_k)/h there, calling it an
// approximation of ẏ; it approximates −ẏ, and with it the discrete solutions of a Lagrangian odd in
// ẏ converge to FracEL of L(x, y, ẋ, −ẏ, …) (docs/theory/misprints.md). For L even in ẏ (the
// mechanical L among them) the two give the same equations.
//
// Δ^α_∓ are convolution quadratures h^{−α} Σ ω_n (·): ω_n = cq_weights(grid.quadrature, α, ·).
// The default δ(ζ) = 1 − ζ gives the paper's Grünwald–Letnikov α_n (`AlphaDef`, scheme `fvi-gl`);
// CqScheme::kBdf2 gives the action sum of `fvi-bdf2` (docs/theory/fvi_bdf2.md). Everything below
// holds verbatim for any weights: the derivation uses only that Δ^α_− is lower and Δ^α_+ upper
// triangular Toeplitz.
//
// Two action sums (docs/theory/discrete_euler_lagrange.md derives both and the difference):
//
//  * ActionSum::kPrinted, the paper's `DiscActSum`: A_d = h Σ_{k=0}^{N−1} L(k). Its exact
//    restricted gradient is `DiscFracEL` with D_3L(N) := 0 and D_5L(N) := 0. The paper's proof
//    shifts sums to k = N using δx_N = 0, but Δ_−δx_N = −δx_{N−1}/h and Δ^α_−δx_N ≠ 0, so the
//    printed equations contain terms D_3L(N), D_5L(N) of a point L(N) that the sum does not have:
//    at k = N − 1 in the x-equation, and at every k (weight α_{N−k}) in the y-equation.
//  * ActionSum::kExtended: A_d⁺ = A_d + h L(N), with the point N completed by the paper's own
//    boundary convention mirrored (S x_N := x_N, S y_N := y_N, ẏ slot := 0, t_N = b; the other
//    three entries are defined by `AllSequencs`). Its exact restricted gradient *is* the printed
//    `DiscFracEL`, and for the mechanical Lagrangian the printed `DiscEqs` that the integrator
//    steps. Only D_3L(N), D_5L(N) enter, so the completion of S x_N, S y_N and the ẏ slot matters
//    only for Lagrangians whose ∂L/∂ẋ or ∂L/∂D^α_−x depends on them.
//
// kPrinted's equations are not a consistent discretisation at t = b (the last kinetic interval
// [t_{N−1}, t_N] of x is missing from A_d, so its x-equation at k = N − 1 imposes a natural
// boundary condition ẋ(b) ≈ 0 instead of using x_N); kExtended is the default of the solvers.
//
// The split into an x- and a y-equation is the paper's sufficient condition: the restricted
// variation δx_k = δy_k only gives their sum, (1/h) ∂A/∂η_k = x-equation_k + y-equation_k.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/discrete/operators.hpp"
#include "fracvi/fractional/convolution.hpp"
#include "fracvi/fractional/weights.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/lagrangian/phase_point.hpp"

namespace fracvi {

/// Which discrete action (see the file comment).
enum class ActionSum {
  kPrinted,   ///< `DiscActSum` as printed, k = 0..N−1
  kExtended,  ///< k = 0..N with L(N) completed: its gradient is `DiscFracEL` as printed
};

/// "printed" / "extended".
std::string_view to_string(ActionSum sum);

/// The uniform grid of the discrete setting, the Lagrangian order α and the convolution
/// quadrature of Δ^α_±.
struct DiscreteGrid {
  double a = 0.0;
  double b = 1.0;
  Eigen::Index steps = 1;  ///< N ≥ 1
  double alpha = 0.5;      ///< the Lagrangian order α ∈ [0, 1]
  /// The generating function δ of Δ^α_± (weights cq_weights(quadrature, α, ·)): the paper's
  /// Grünwald–Letnikov weights by default; a scheme's own δ via SchemeInfo::variational_quadrature.
  CqScheme quadrature = CqScheme::kGrunwaldLetnikov;

  [[nodiscard]] double step() const { return (b - a) / static_cast<double>(steps); }
  /// t_k = a + k h (also for half-integer k).
  [[nodiscard]] double time(double k) const { return a + k * step(); }
};

/// Throws std::invalid_argument unless a < b are finite, N ≥ 1 and α ∈ [0, 1].
void validate(const DiscreteGrid& grid);

namespace internal {

/// The phase points z_k, k = 0..N (column k of a 6d × (N+1) matrix); column N is the completion
/// of kExtended. Linear in (x, y); templated so that a test can differentiate the whole action
/// sum automatically. `weights` = cq_weights(quadrature, α) of length ≥ N + 1.
template <class T>
Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic> discrete_phase_points(
    const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& x,
    const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& y, double h, double alpha,
    const std::vector<double>& weights) {
  const Eigen::Index d = x.rows(), n = x.cols() - 1;
  const double inv_h = 1.0 / h, inv_h_alpha = std::pow(h, -alpha);
  Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic> z(6 * d, n + 1);
  // Every entry is built from x and y, never from a bare constant: an Eigen AutoDiffScalar with
  // an empty derivative vector inside a longer expression of sized ones is not supported.
  for (Eigen::Index k = 0; k <= n; ++k) {
    for (Eigen::Index i = 0; i < d; ++i) {
      const bool last = k == n;
      z(i, k) = last ? x(i, k) : T(T(0.5) * (x(i, k) + x(i, k + 1)));
      z(d + i, k) = last ? y(i, k) : T(T(0.5) * (y(i, k) + y(i, k + 1)));
      z(2 * d + i, k) = k == 0 ? T(T(0.0) * x(i, k)) : T((x(i, k) - x(i, k - 1)) * T(inv_h));
      z(3 * d + i, k) = last ? T(T(0.0) * y(i, k)) : T((y(i, k + 1) - y(i, k)) * T(inv_h));
      // Δ^α_−x_k and Δ^α_+y_k: the causal sum, and the causal sum of the reversed y.
      T sx = T(0.0) * x(i, k), sy = T(0.0) * y(i, k);
      const auto ku = static_cast<std::size_t>(k), nu = static_cast<std::size_t>(n);
      accumulate_causal(
          weights, ku, [&](std::size_t j) { return x(i, Eigen::Index(j)); }, sx);
      accumulate_causal(
          weights, nu - ku, [&](std::size_t j) { return y(i, Eigen::Index(nu - j)); }, sy);
      z(4 * d + i, k) = sx * T(inv_h_alpha);
      z(5 * d + i, k) = sy * T(inv_h_alpha);
    }
  }
  return z;
}

}  // namespace internal

/// The phase points z_k of `DiscActSum` (column k, k = 0..N; column N is kExtended's completed
/// point), a 6d × (N+1) matrix. x and y are d × (N+1).
Eigen::MatrixXd discrete_phase_points(const Sequence& x, const Sequence& y,
                                      const DiscreteGrid& grid);

/// A_d (kPrinted) or A_d⁺ (kExtended) for a user functor `T operator()(const PhasePoint<T>&)`,
/// any scalar type T (double, or an AutoDiff type to differentiate the whole sum).
template <class T, class Functor>
T action_sum(const Functor& lagrangian, const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& x,
             const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& y, const DiscreteGrid& grid,
             ActionSum sum = ActionSum::kExtended) {
  const Eigen::Index n = x.cols() - 1;
  const double h = grid.step();
  const auto w = cq_weights(grid.quadrature, grid.alpha, static_cast<std::size_t>(n + 1));
  const auto z = internal::discrete_phase_points<T>(x, y, h, grid.alpha, w);
  const Eigen::Index last = sum == ActionSum::kExtended ? n : n - 1;
  auto term = [&](Eigen::Index k) {
    const double t = k == n ? grid.b : grid.time(static_cast<double>(k) + 0.5);
    const T time = T(0.0) * x(0, 0) + T(t);  // constant, but with a sized derivative vector
    return lagrangian(PhasePoint<T>::from_flat(time, z.col(k)));
  };
  T total = term(0);
  for (Eigen::Index k = 1; k <= last; ++k) total += term(k);
  return T(h) * total;
}

/// The same for a Lagrangian object.
double action_sum(const Lagrangian& lagrangian, const Sequence& x, const Sequence& y,
                  const DiscreteGrid& grid, ActionSum sum = ActionSum::kExtended);

/// The residual of `DiscFracEL` at the interior points k = 1..N−1 (columns 1..N−1; columns 0 and
/// N are zero), for the chosen action sum:
///   x-equation_k = ½(D_1L(k) + D_1L(k−1)) + Δ_+D_3L(k) + Δ^α_−D_6L(k),
///   y-equation_k = ½(D_2L(k) + D_2L(k−1)) − Δ_−D_4L(k) + Δ^α_+D_5L(k),
/// with D_3L(N) = D_5L(N) = 0 for kPrinted and the completed point for kExtended. Their sum at k
/// is (1/h) ∂A/∂η_k along the restricted variation δx_k = δy_k = η_k, exactly.
struct DiscreteElResidual {
  Sequence x_equation;  ///< d × (N+1)
  Sequence y_equation;  ///< d × (N+1)
  /// max over interior k and components of |x-equation|, |y-equation|.
  [[nodiscard]] double max_norm() const;
};

/// x and y are d × (N+1) (d = lagrangian.dimension()); throws std::invalid_argument on a size
/// mismatch or an invalid grid.
DiscreteElResidual discrete_el_residual(const Lagrangian& lagrangian, const Sequence& x,
                                        const Sequence& y, const DiscreteGrid& grid,
                                        ActionSum sum = ActionSum::kExtended);

}  // namespace fracvi
