// The built-in chain: d masses on a line joined by nearest-neighbour springs with the
// Fermi–Pasta–Ulam–Tsingou nonlinearity, optionally pinned on site,
//
//     U(x) = Σ_bonds V(x_j − x_i) + Σ_i ½ c x_i²,     V(r) = ½ k r² + (a/3) r³ + (b/4) r⁴,
//
// (a = 0: the β-FPUT chain; b = 0: the α-FPUT chain; a = b = 0: a linear chain). Boundary:
//   fixed     walls at both ends, x_0 = x_{d+1} = 0: bonds (wall, 1), (i, i+1), (d, wall) — d + 1
//   free      bonds (i, i+1) only — d − 1 bonds
//   periodic  bonds (i, i+1) and (d, 1) — d bonds (d ≥ 3)
//
// ∇²U is tridiagonal (plus the corners (1, d) when periodic): the potential declares that pattern
// (has_sparse_hessian), so with a diagonal mass matrix a Newton iteration is one band Cholesky of
// bandwidth 1 (fixed, free) and every step costs O(d). Value, gradient and Hessian are exact,
// allocation-free, and split over OpenMP threads from kChainParallelDofs degrees of freedom.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "fracvi/model/potential.hpp"

namespace fracvi {

enum class ChainBoundary { kFixed, kFree, kPeriodic };
std::optional<ChainBoundary> parse_chain_boundary(std::string_view name);
std::string_view to_string(ChainBoundary boundary);

struct ChainOptions {
  Eigen::Index dimension = 0;  ///< d, the number of masses (≥ 1; ≥ 2 free, ≥ 3 periodic)
  double stiffness = 1.0;      ///< k, linear spring constant
  double cubic = 0.0;          ///< a, the α-FPUT coefficient of r³/3
  double quartic = 0.0;        ///< b, the β-FPUT coefficient of r⁴/4
  double onsite = 0.0;         ///< c, the on-site (pinning) stiffness
  ChainBoundary boundary = ChainBoundary::kFixed;
  /// OpenMP threads for the loops over d (0 = OpenMP's default); used from kChainParallelDofs.
  int threads = 0;
};

/// Degrees of freedom from which the chain's loops run on several threads.
/// A gradient or Hessian costs ~10 flops per degree of freedom, so a parallel region (a barrier,
/// and on a busy machine a wait for a time slice) only pays for very long chains.
inline constexpr Eigen::Index kChainParallelDofs = 65536;

class ChainPotential final : public Potential {
 public:
  /// Throws std::invalid_argument naming the field for d too small for the boundary, non-finite
  /// coefficients or threads < 0.
  explicit ChainPotential(const ChainOptions& options);

  [[nodiscard]] Eigen::Index dimension() const override { return options_.dimension; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override;
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override;
  /// Rows [lo, hi) of the gradient on this thread (gradient() splits d over its threads).
  [[nodiscard]] bool has_gradient_rows() const override { return true; }
  void gradient_rows(const Eigen::Ref<const Eigen::VectorXd>& x, double t, double* g,
                     Eigen::Index lo, Eigen::Index hi) const override;
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override;
  [[nodiscard]] bool has_constant_hessian() const override {
    return options_.cubic == 0.0 && options_.quartic == 0.0;
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }
  [[nodiscard]] bool has_sparse_hessian() const override { return true; }
  /// Diagonal entries first (i, i), then the bonds (i, i+1), then (0, d−1) when periodic.
  [[nodiscard]] std::vector<HessianEntry> hessian_pattern() const override;
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                      std::span<double> values) const override;

  [[nodiscard]] const ChainOptions& options() const { return options_; }

 private:
  ChainOptions options_;
};

std::shared_ptr<const Potential> make_chain_potential(const ChainOptions& options);

}  // namespace fracvi
