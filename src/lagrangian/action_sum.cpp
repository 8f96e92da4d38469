#include "fracvi/lagrangian/action_sum.hpp"

#include <cmath>

#include "discrete_system.hpp"

namespace fracvi {

std::string_view to_string(ActionSum sum) {
  switch (sum) {
    case ActionSum::kPrinted: return "printed";
    case ActionSum::kExtended: return "extended";
  }
  return "unknown";
}

void validate(const DiscreteGrid& grid) {
  if (!(std::isfinite(grid.a) && std::isfinite(grid.b) && grid.a < grid.b)) {
    throw std::invalid_argument("DiscreteGrid: [a, b] = [" + std::to_string(grid.a) + ", " +
                                std::to_string(grid.b) + "] must be finite with a < b");
  }
  if (grid.steps < 1) {
    throw std::invalid_argument("DiscreteGrid: steps = " + std::to_string(grid.steps) +
                                " must be >= 1");
  }
  if (!(grid.alpha >= 0.0 && grid.alpha <= 1.0)) {
    throw std::invalid_argument("DiscreteGrid: alpha = " + std::to_string(grid.alpha) +
                                " must be in [0, 1] (the Lagrangian order)");
  }
}

namespace internal {

DiscreteElSystem::DiscreteElSystem(Eigen::Index d, const DiscreteGrid& grid, ActionSum sum)
    : d_(d), n_(grid.steps), grid_(grid), sum_(sum) {
  validate(grid);
  h_ = grid.step();
  inv_h_ = 1.0 / h_;
  inv_h_alpha_ = std::pow(h_, -grid.alpha);
  memory_ = SeriesConvolution(
      cq_weights(grid.quadrature, grid.alpha, static_cast<std::size_t>(n_ + 1)), inv_h_alpha_);
}

void DiscreteElSystem::phase_points(const Sequence& x, const Sequence& y,
                                    Eigen::MatrixXd& z) const {
  const Eigen::Index d = d_, n = n_;
  z.resize(6 * d, n + 1);
  for (Eigen::Index k = 0; k <= n; ++k) {
    auto zk = z.col(k);
    if (k == n) {
      // The completed point of ActionSum::kExtended (S z_N := z_N, ẏ slot := 0).
      zk.segment(0, d) = x.col(n);
      zk.segment(d, d) = y.col(n);
      zk.segment(3 * d, d).setZero();
    } else {
      zk.segment(0, d) = 0.5 * (x.col(k) + x.col(k + 1));
      zk.segment(d, d) = 0.5 * (y.col(k) + y.col(k + 1));
      zk.segment(3 * d, d) = (y.col(k + 1) - y.col(k)) * inv_h_;
    }
    if (k == 0) {
      zk.segment(2 * d, d).setZero();  // Δ_−x_0 := 0 (`DiscDerDef:1`)
    } else {
      zk.segment(2 * d, d) = (x.col(k) - x.col(k - 1)) * inv_h_;
    }
  }
  // Δ^α_−x_k = h^{−α} Σ_{m=0}^{k} ω_m x_{k−m},  Δ^α_+y_k = h^{−α} Σ_{m=0}^{N−k} ω_m y_{k+m}.
  const Eigen::Index zs = z.rows();
  for (Eigen::Index i = 0; i < d; ++i) {
    cq_sum(x.data() + i, d, z.data() + 4 * d + i, zs, false);
    cq_sum(y.data() + i, d, z.data() + 5 * d + i, zs, true);
  }
}

void DiscreteElSystem::assemble(const Eigen::MatrixXd& g, Sequence& x_eq, Sequence& y_eq) const {
  const Eigen::Index d = d_, n = n_;
  x_eq.setZero(d, n + 1);
  y_eq.setZero(d, n + 1);
  const bool extended = sum_ == ActionSum::kExtended;
  for (Eigen::Index j = 1; j < n; ++j) {
    auto xe = x_eq.col(j);
    auto ye = y_eq.col(j);
    // ½(D_1L(j) + D_1L(j−1)) and ½(D_2L(j) + D_2L(j−1)): from S x_j−1 ∋ x_j and S x_j ∋ x_j.
    xe = 0.5 * (g.col(j).segment(0, d) + g.col(j - 1).segment(0, d));
    ye = 0.5 * (g.col(j).segment(d, d) + g.col(j - 1).segment(d, d));
    // Δ_+D_3L(j) = (D_3L(j) − D_3L(j+1))/h, with D_3L(N) = 0 for the printed sum (Δ_−x_N is not
    // in A_d), the completed point's value for the extended one.
    xe += g.col(j).segment(2 * d, d) * inv_h_;
    if (j + 1 < n || extended) xe -= g.col(j + 1).segment(2 * d, d) * inv_h_;
    // −Δ_−D_4L(j) = (D_4L(j−1) − D_4L(j))/h: the ẏ slot holds the forward difference
    // (y_{k+1} − y_k)/h = −Δ_+y_k (docs/theory/misprints.md, `DiscDerDef:2`).
    ye += (g.col(j - 1).segment(3 * d, d) - g.col(j).segment(3 * d, d)) * inv_h_;
  }
  // Δ^α_−D_6L(j) (x-equation, from the y-variation) and Δ^α_+D_5L(j) (y-equation, from the
  // x-variation), with D_5L(N) = 0 for the printed sum. Columns 0 and N are cleared afterwards.
  Eigen::MatrixXd tail = g.middleRows(4 * d, 2 * d);
  if (!extended) tail.col(n).setZero();
  Eigen::MatrixXd memory_x(d, n + 1), memory_y(d, n + 1);
  for (Eigen::Index i = 0; i < d; ++i) {
    cq_sum(tail.data() + d + i, 2 * d, memory_x.data() + i, d, false);
    cq_sum(tail.data() + i, 2 * d, memory_y.data() + i, d, true);
  }
  x_eq.middleCols(1, n - 1) += memory_x.middleCols(1, n - 1);
  y_eq.middleCols(1, n - 1) += memory_y.middleCols(1, n - 1);
}

}  // namespace internal

namespace {

void check_curves(const Lagrangian& lagrangian, const Sequence& x, const Sequence& y,
                  const DiscreteGrid& grid, const char* where) {
  validate(grid);
  const Eigen::Index d = lagrangian.dimension();
  if (x.rows() != d || y.rows() != d || x.cols() != grid.steps + 1 || y.cols() != grid.steps + 1) {
    throw std::invalid_argument(std::string(where) + ": x is " + std::to_string(x.rows()) + " x " +
                                std::to_string(x.cols()) + ", y is " + std::to_string(y.rows()) +
                                " x " + std::to_string(y.cols()) + "; both must be d x (N+1) = " +
                                std::to_string(d) + " x " + std::to_string(grid.steps + 1));
  }
}

}  // namespace

Eigen::MatrixXd discrete_phase_points(const Sequence& x, const Sequence& y,
                                      const DiscreteGrid& grid) {
  validate(grid);
  if (x.rows() != y.rows() || x.cols() != grid.steps + 1 || y.cols() != grid.steps + 1) {
    throw std::invalid_argument("discrete_phase_points: x and y must both be d x (N+1)");
  }
  internal::DiscreteElSystem system(x.rows(), grid, ActionSum::kExtended);
  Eigen::MatrixXd z;
  system.phase_points(x, y, z);
  return z;
}

double action_sum(const Lagrangian& lagrangian, const Sequence& x, const Sequence& y,
                  const DiscreteGrid& grid, ActionSum sum) {
  check_curves(lagrangian, x, y, grid, "action_sum");
  internal::DiscreteElSystem system(lagrangian.dimension(), grid, sum);
  Eigen::MatrixXd z;
  system.phase_points(x, y, z);
  double total = 0.0;
  for (Eigen::Index k = 0; k < system.point_count(); ++k)
    total += lagrangian.value(system.point_time(k), z.col(k));
  return grid.step() * total;
}

double DiscreteElResidual::max_norm() const {
  const Eigen::Index n = x_equation.cols() - 1;
  if (n < 2) return 0.0;
  return std::max(x_equation.middleCols(1, n - 1).cwiseAbs().maxCoeff(),
                  y_equation.middleCols(1, n - 1).cwiseAbs().maxCoeff());
}

DiscreteElResidual discrete_el_residual(const Lagrangian& lagrangian, const Sequence& x,
                                        const Sequence& y, const DiscreteGrid& grid,
                                        ActionSum sum) {
  check_curves(lagrangian, x, y, grid, "discrete_el_residual");
  internal::DiscreteElSystem system(lagrangian.dimension(), grid, sum);
  Eigen::MatrixXd z, g;
  system.phase_points(x, y, z);
  g.setZero(z.rows(), z.cols());
  Eigen::VectorXd gk(z.rows());
  for (Eigen::Index k = 0; k < system.point_count(); ++k) {
    lagrangian.gradient(system.point_time(k), z.col(k), gk);
    g.col(k) = gk;
  }
  DiscreteElResidual r;
  system.assemble(g, r.x_equation, r.y_equation);
  return r;
}

}  // namespace fracvi
