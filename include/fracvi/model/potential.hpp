// Potentials U(x, t) of the mechanical model M x'' + R D^{2α} x + ∇U(x, t) = f(t).
//
// The integrator of `DiscEqs` evaluates U, ∇U and ∇²U only at midpoints (x_k + x_{k+1})/2 and
// needs the Hessian for Newton's method. A potential is therefore an object with value, gradient
// and Hessian at one point (x, t); how it gets them (hand-written, automatic differentiation,
// symbolic derivatives of a parsed expression) is its own business.
//
// Thread safety: all methods are const and must be safe to call concurrently (several integrators
// may share one potential).
//
// Allocation: the integrator's step loop does not allocate; it passes contiguous vectors and
// preallocated outputs. A potential whose methods do not allocate keeps the whole loop free of
// heap traffic (QuadraticPotential, fixed-size autodiff potentials); dynamic-size autodiff
// potentials allocate inside their own evaluations.
//
// Sparse Hessians (chains, lattices): a potential may also declare the structure of ∇²U once
// (hessian_pattern(), upper triangle) and fill only those entries (hessian_values()). With a
// sparse mass matrix the integrator then factors its Newton matrix banded or sparse and a step
// costs O(d) instead of O(d³) (solve/symmetric_factor.hpp). The dense hessian() stays
// required: small problems, tests and the dense path use it.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <span>
#include <vector>

namespace fracvi {

/// U : R^d × R → R. Subclass it for a hand-written potential, or use QuadraticPotential /
/// make_autodiff_potential() (autodiff_potential.hpp).
class Potential {
 public:
  virtual ~Potential() = default;

  /// The dimension d of x (must equal the size of the model's mass matrix).
  [[nodiscard]] virtual Eigen::Index dimension() const = 0;

  /// U(x, t).
  [[nodiscard]] virtual double value(const Eigen::Ref<const Eigen::VectorXd>& x,
                                     double t) const = 0;
  /// g = ∇_x U(x, t); g has size d on entry.
  virtual void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                        Eigen::Ref<Eigen::VectorXd> g) const = 0;
  /// H = ∇²_x U(x, t) (symmetric); H is d × d on entry.
  virtual void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                       Eigen::Ref<Eigen::MatrixXd> H) const = 0;

  /// True when ∇²U does not depend on (x, t) (U quadratic in x up to terms linear in x): the
  /// problem is linear, the integrator factors its Newton matrix once and takes exactly one
  /// linear solve per step.
  [[nodiscard]] virtual bool has_constant_hessian() const { return false; }

  /// True when U is built with functions whose derivative jumps in x (abs, sign, min, max,
  /// floor, heaviside of a position): where ∇U jumps, a step's implicit equation can have no
  /// solution, and a Newton failure there names that cause (integrator.cpp). The default: no.
  [[nodiscard]] virtual bool has_kinks() const { return false; }

  /// False when U does not depend on t. Only the energy bookkeeping uses it: for a time-dependent
  /// U the work of the explicit time dependence, Σ [U(x̄_k, t_{k+1}) − U(x̄_k, t_k)], enters the
  /// dissipated work (two extra value() calls per step). The default is the safe answer.
  [[nodiscard]] virtual bool is_time_dependent() const { return true; }

  /// True when the potential provides gradient_rows().
  [[nodiscard]] virtual bool has_gradient_rows() const { return false; }
  /// g[i] = ∂U/∂x_i(x, t) for lo ≤ i < hi, each the same number as gradient()'s (g points to d
  /// entries; the others are left alone): threads can split one gradient by rows, calling this
  /// at once on disjoint ranges of the same x. Must not allocate or throw. The default throws
  /// std::logic_error (a potential without it).
  virtual void gradient_rows(const Eigen::Ref<const Eigen::VectorXd>& x, double t, double* g,
                             Eigen::Index lo, Eigen::Index hi) const;

  /// One structurally non-zero entry of the upper triangle of ∇²U (row ≤ col).
  struct HessianEntry {
    Eigen::Index row;
    Eigen::Index col;
  };
  /// True when the potential provides hessian_pattern() and hessian_values().
  [[nodiscard]] virtual bool has_sparse_hessian() const { return false; }
  /// The entries of the upper triangle of ∇²U that can be non-zero, each once (any order). Called
  /// once at set-up. Default: empty (only meaningful when has_sparse_hessian()).
  [[nodiscard]] virtual std::vector<HessianEntry> hessian_pattern() const { return {}; }
  /// values[e] = ∂²U/∂x_row ∂x_col at (x, t) for the e-th entry of hessian_pattern(). Called in the
  /// step loop: must not allocate if the loop is to stay allocation-free. The default throws
  /// std::logic_error (a potential without a sparse Hessian).
  virtual void hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                              std::span<double> values) const;
};

/// U(x) = ½ xᵀ K x − bᵀ x with K symmetric (not necessarily definite). Time-independent, constant
/// Hessian. Allocation-free.
class QuadraticPotential final : public Potential {
 public:
  /// Throws std::invalid_argument if K is not square and symmetric, b has the wrong size, or any
  /// entry is not finite. b defaults to zero.
  explicit QuadraticPotential(Eigen::MatrixXd stiffness);
  QuadraticPotential(Eigen::MatrixXd stiffness, Eigen::VectorXd linear);

  [[nodiscard]] Eigen::Index dimension() const override { return stiffness_.rows(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override;
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override;
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override;
  [[nodiscard]] bool has_constant_hessian() const override { return true; }
  [[nodiscard]] bool is_time_dependent() const override { return false; }

  [[nodiscard]] const Eigen::MatrixXd& stiffness() const { return stiffness_; }
  [[nodiscard]] const Eigen::VectorXd& linear() const { return linear_; }

 private:
  Eigen::MatrixXd stiffness_;
  Eigen::VectorXd linear_;
};

/// Convenience: std::make_shared<const QuadraticPotential>(K, b).
std::shared_ptr<const Potential> make_quadratic_potential(Eigen::MatrixXd stiffness);
std::shared_ptr<const Potential> make_quadratic_potential(Eigen::MatrixXd stiffness,
                                                          Eigen::VectorXd linear);

}  // namespace fracvi
