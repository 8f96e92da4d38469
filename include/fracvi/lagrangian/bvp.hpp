// The variational boundary value problem of the restricted discrete principle (DESIGN §3.3):
// given x(a) = x_a and x(b) = x_b, with the mirrored end points y(a) = x_b, y(b) = x_a (the path
// space of §4 of the paper), find all interior x_k, y_k (k = 1..N−1) such that `DiscFracEL` holds
// (action_sum.hpp; default ActionSum::kExtended, the printed equations).
//
// Newton's method with the exact Jacobian. The residual is F = Cᵀ ∇L(A u) (src/lagrangian/
// discrete_system.hpp): A maps the unknowns to the phase points z_k — a banded local part (S, Δ_±)
// plus lower/upper triangular Toeplitz CQ sums (Δ^α_∓, weights of grid.quadrature) — and C is A
// with the fractional blocks routed to the other equation. So J = Cᵀ diag(∇²L(z_k)) A exactly, and
//
//  * J·v costs four CQ sums (direct O(N²d) up to 256 points, real FFT O(N log N · d) above) and
//    one 6d × 6d product per point, with O(N d) memory: J is never formed for large N·d. (For a
//    general L, J is dense: the x-equation at k sees every y_j through Δ^α_+y inside ∂L/∂D^α_+y.)
//  * Linear solves: for n = 2(N−1)d ≤ dense_limit, J is assembled densely (O(N³d²) worst case)
//    and LU-factored (O(n³)). Above that, restarted GMRES on the exact J·v, right-preconditioned by
//    the band of J obtained by truncating every CQ sum after `preconditioner_width` lags (its local
//    part exact), assembled in O(N w² d²) and factored by SparseLU. GMRES stops at
//    ‖r‖ ≤ max(krylov_tolerance·‖F‖, residual_tolerance/10) (inexact Newton).
//  * Globalisation: backtracking on ‖F‖₂; the best iterate (smallest max |F|) is kept and returned
//    whatever happens. Numerical failure is a status, never an exception. Newton stops early when
//    three steps in a row fail to halve max |F| and reports the round-off floor of the equations
//    (they scale like 1/h², so an absolute tolerance of 1e-10 is out of reach for small h).
// Measured iterations and costs: docs/theory/discrete_euler_lagrange.md §4.
#pragma once

#include "fracvi/core/newton_options.hpp"

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "fracvi/integrate/solution.hpp"
#include "fracvi/lagrangian/action_sum.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"

namespace fracvi {

struct BoundaryValueProblem {
  std::shared_ptr<const Lagrangian> lagrangian;
  DiscreteGrid grid;        ///< [a, b], N, α and the quadrature of Δ^α_±
  Eigen::VectorXd x_start;  ///< x_a = x(a) = y(b)
  Eigen::VectorXd x_end;    ///< x_b = x(b) = y(a)
  ActionSum sum = ActionSum::kExtended;
  /// Optional starting iterates, (N+1) × d each (their end rows are replaced by the boundary
  /// data). Empty: the straight lines x_a → x_b and x_b → x_a.
  RowMatrixXd x_guess, y_guess;
};

enum class BvpLinearSolver {
  kAuto,    ///< dense LU up to dense_limit unknowns, preconditioned GMRES above
  kDense,   ///< always the dense LU of the assembled exact Jacobian
  kKrylov,  ///< always GMRES with the banded preconditioner
};

struct BvpOptions {
  /// Converged when max_k |x-equation_k|, |y-equation_k| ≤ residual_tolerance (or the round-off
  /// floor, below).
  double residual_tolerance = 1e-10;
  /// Converge at max(residual_tolerance, the round-off floor 2ε‖J‖_∞‖u‖_∞ of the last Jacobian)
  /// (BvpSolution::residual_floor): the equations scale like 1/h², and a fixed tolerance falls
  /// below what double precision can resolve as N grows (1e-10 against a floor of 1.3e-8 for a
  /// linear BVP at N = 5000: Newton stagnated at 2.5e-9 and the run failed). The default; an
  /// explicit tolerance (`fracvi bvp --tolerance`, Python's tolerance=) sets it false and is
  /// taken as given.
  bool above_round_off = true;
  int max_iterations = NewtonOptions{}.max_iterations;  ///< Newton iterations, ≥ 1 (one default)
  BvpLinearSolver linear_solver = BvpLinearSolver::kAuto;
  Eigen::Index dense_limit = 200;         ///< kAuto: unknowns 2(N−1)d up to this use dense LU
  Eigen::Index preconditioner_width = 8;  ///< CQ lags kept in the banded preconditioner, ≥ 1
  /// Relative residual of each GMRES solve; it also stops at the absolute 2-norm
  /// residual_tolerance/10 (inexact Newton) or when a restart cycle gains less than 10%.
  double krylov_tolerance = 1e-12;
  int krylov_restart = 50;          ///< GMRES(m)
  int krylov_max_iterations = 500;  ///< per linear solve
};

/// Throws ValidationError (model/mechanical_model.hpp) naming the field.
void validate(const BoundaryValueProblem& problem);
void validate(const BvpOptions& options);

struct BvpSolution {
  Eigen::VectorXd t;                   ///< t_k, k = 0..N
  RowMatrixXd x;                       ///< (N+1) × d, the best iterate
  RowMatrixXd y;                       ///< (N+1) × d
  RowMatrixXd x_residual, y_residual;  ///< the equations at the returned iterate (rows 0, N zero)

  Status status = Status::kRunning;
  std::string message;  ///< empty on success; otherwise the cause and the iteration

  double residual_norm = 0.0;  ///< max |x_residual|, |y_residual|
  /// Estimated rounding level of the equations, 2ε‖J‖_∞ max|x, y| (≈ ε|∂²L/∂ẋ²| |x|/h²) at the
  /// last Jacobian: a residual_tolerance below it cannot be met. 0 if no Jacobian was formed.
  double residual_floor = 0.0;
  double residual_tolerance = 0.0;       ///< the tolerance it was solved to (floor included)
  std::vector<double> residual_history;  ///< max-norm before each Newton iteration, and the last
  int newton_iterations = 0;
  std::size_t linear_iterations = 0;  ///< GMRES iterations in total (0 for dense LU)
  std::string linear_solver;          ///< e.g. "dense LU (n = 396)"
  std::string sum;                    ///< "extended" or "printed"
  double wall_time_seconds = 0.0;

  [[nodiscard]] bool ok() const { return status == Status::kSuccess; }
};

/// Validates (throws ValidationError for bad input) and solves. Never throws for numerical
/// failure: see BvpSolution::status.
BvpSolution solve_bvp(const BoundaryValueProblem& problem, const BvpOptions& options = {});

/// The exact Jacobian of the `DiscFracEL` residual with respect to the interior unknowns, at given
/// curves, in structured form. Unknowns and equations are ordered point by point:
/// (x_1, y_1, x_2, y_2, …, x_{N−1}, y_{N−1}), each a block of d, i.e. row/column 2d(k−1) + i is
/// x_k component i and 2d(k−1) + d + i is y_k component i.
class DiscreteElJacobian {
 public:
  /// x, y: d × (N+1). Evaluates ∇²L at every point (throws whatever the Lagrangian throws).
  DiscreteElJacobian(const Lagrangian& lagrangian, const DiscreteGrid& grid, ActionSum sum,
                     const Sequence& x, const Sequence& y);
  ~DiscreteElJacobian();
  DiscreteElJacobian(DiscreteElJacobian&&) noexcept;
  DiscreteElJacobian& operator=(DiscreteElJacobian&&) noexcept;

  [[nodiscard]] Eigen::Index size() const;  ///< n = 2(N−1)d
  /// J v, O(N²d + N(6d)²), no matrix formed.
  [[nodiscard]] Eigen::VectorXd apply(const Eigen::VectorXd& v) const;
  /// J as a dense matrix (n × n).
  [[nodiscard]] Eigen::MatrixXd dense() const;
  /// J with every CQ sum truncated after `width` lags (exact when width ≥ N), sparse.
  [[nodiscard]] Eigen::SparseMatrix<double> banded(Eigen::Index width) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fracvi
