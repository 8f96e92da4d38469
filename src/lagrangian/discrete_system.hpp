// The linear maps around `DiscFracEL` (internal; shared by the residual and the BVP solver).
//
// Everything in the discrete equations is linear except ∇L at each point:
//
//     Z = A (x, y)          the phase points z_k (`AllSequencs`): banded S, Δ_± and the lower /
//                           upper triangular Toeplitz CQ sums Δ^α_∓ (weights
//                           cq_weights(grid.quadrature, α): GL by default),
//     G_k = ∇L(t_k+½, z_k)  one gradient per point (the only nonlinearity),
//     F = Cᵀ G              the equations: F = (x-equation_k, y-equation_k)_{k=1..N−1}.
//
// C has the same entries as A with the fractional blocks routed to the other equation (D_5 from
// x goes to the y-equation, D_6 from y to the x-equation: the paper's split). So the exact
// Jacobian is J = Cᵀ diag(∇²L(z_k)) A, applied in O(N² d + N (6d)²) without forming it.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "fracvi/fractional/convolution.hpp"
#include "fracvi/lagrangian/action_sum.hpp"

namespace fracvi::internal {

class DiscreteElSystem {
 public:
  DiscreteElSystem(Eigen::Index d, const DiscreteGrid& grid, ActionSum sum);

  [[nodiscard]] Eigen::Index dimension() const { return d_; }
  [[nodiscard]] Eigen::Index steps() const { return n_; }
  [[nodiscard]] ActionSum sum() const { return sum_; }
  [[nodiscard]] const DiscreteGrid& grid() const { return grid_; }
  /// Points whose gradient enters the equations: k = 0..point_count()−1 (N or N+1).
  [[nodiscard]] Eigen::Index point_count() const {
    return sum_ == ActionSum::kExtended ? n_ + 1 : n_;
  }
  /// The time at which L(k) is evaluated: t_{k+½}, and b for the completed point k = N.
  [[nodiscard]] double point_time(Eigen::Index k) const {
    return k == n_ ? grid_.b : grid_.time(static_cast<double>(k) + 0.5);
  }
  [[nodiscard]] const std::vector<double>& weights() const { return memory_.weights(); }

  /// Z (6d × (N+1)) from x, y (d × (N+1)). Linear: also maps perturbations to perturbations.
  void phase_points(const Sequence& x, const Sequence& y, Eigen::MatrixXd& z) const;
  /// The equations from the gradients G (6d × (N+1); columns ≥ point_count() are ignored):
  /// x_eq, y_eq are d × (N+1) with columns 0 and N zero. Linear in G.
  void assemble(const Eigen::MatrixXd& g, Sequence& x_eq, Sequence& y_eq) const;

  /// out_k = h^{−α} Σ_{m=0}^{k} ω_m s_k−m, k = 0..N, for a series s of length N+1 (`reverse`:
  /// s and out indexed backwards, i.e. the anti-causal Σ_{m=0}^{N−k} ω_m s_{k+m}); ω = weights().
  void cq_sum(const double* s, Eigen::Index stride, double* out, Eigen::Index out_stride,
              bool reverse) const {
    memory_.apply(s, stride, out, out_stride, reverse);
  }

 private:
  Eigen::Index d_, n_;
  DiscreteGrid grid_;
  ActionSum sum_;
  double h_, inv_h_, inv_h_alpha_;
  SeriesConvolution memory_;  // h^{−α} · ω_0 … ω_N (GL: α_0 … α_N), direct or FFT
};

}  // namespace fracvi::internal
