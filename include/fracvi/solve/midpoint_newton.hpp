// Newton's method for the implicit equation of one midpoint step (internal; public only so that
// benchmarks and baselines can use the very same solver).
//
// Every implicit step in fracvi has the form
//
//     A Δ + (h²/2) [∇U(a + Δ/2, τ) − f(τ)] = c,
//
// for the increment Δ = u − a from the known point a to the unknown point u: A = M for the x- and
// y-equations of `DiscEqs` (c = h p⁺_k in the momentum form, integrator.hpp), A = M + (h/2)R for
// the implicit midpoint rule with midpoint damping (c = h M v_k). Its Jacobian is
// J = A + (h²/4) ∇²U(a + Δ/2, τ).
//
// A non-conservative force g(x, v, t) (model/state_force.hpp) enters the same way as f(τ), by the
// midpoint rule of the discrete Lagrange–d'Alembert principle (docs/theory/forces.md §2): f(τ) is
// replaced by f(τ) + g(a + Δ/2, Δ/h, τ), so that J gains −(h²/4) ∂g/∂x − (h/2) ∂g/∂v. That
// Jacobian is not symmetric: with a state force J is always factored dense by LU (the banded and
// sparse factorisations are LDLᵀ); the constructor refuses a forced banded or sparse solver.
//
// Solving for the increment rather than for u keeps round-off out of the momenta: the right-hand
// side c = O(h) carries no large cancelling terms (solving A u = A a + c would leave a residual of
// ε‖A a‖, i.e. a momentum error ε‖a‖/h per step).
//
// J is factored dense, banded or sparse (symmetric_factor.hpp), chosen from the storage of A and
// the potential's Hessian pattern: a chain with diagonal M costs O(d) per iteration.
//
// All workspace is allocated in the constructor; solve() does not allocate (for the dense and
// banded factorisations; Eigen's sparse LDLᵀ allocates inside). It throws only what the potential
// throws (the integrator turns that into Status::kCallbackError).
#pragma once

#include <Eigen/Dense>
#include <limits>
#include <memory>
#include <string_view>
#include <utility>
#include <vector>

#include "fracvi/core/error.hpp"
#include "fracvi/core/newton_options.hpp"
#include "fracvi/core/state_archive.hpp"
#include "fracvi/core/status.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/model/state_force.hpp"
#include "fracvi/solve/symmetric_factor.hpp"
#include "fracvi/solve/vector_passes.hpp"

namespace fracvi::internal {

/// Largest d the dense path accepts (its three d × d matrices take 6 GB at this size); larger
/// systems must state their structure (docs/large-systems.md). The constructor throws
/// ValidationError beyond it.
inline constexpr Eigen::Index kMaxDenseDimension = 16384;

struct NewtonReport {
  Status status = Status::kSuccess;  ///< kSuccess, kNewtonFailure or kNonFinite
  int iterations = 0;
  double correction = 0.0;  ///< ‖δ‖_∞ of the last correction
  double tolerance = 0.0;   ///< the bound it had to meet
  bool singular = false;    ///< the Newton matrix could not be factored (status kNewtonFailure)
};

class MidpointNewton {
 public:
  /// potential may be null (U ≡ 0). If it is null or has a constant Hessian, J is formed and
  /// factored here, once (Hessian taken at (0, t_hessian)), and solve() takes exactly one
  /// correction from the initial guess: the equation is linear, so that is its exact solution.
  /// solver picks the factorisation of J (kAuto: from the structure, see
  /// SymmetricFactor); A must be symmetric. Throws ValidationError when the dense path would need
  /// d > kMaxDenseDimension.
  /// state_force (may be null) is the non-conservative force g(x, v, t), evaluated at the midpoint
  /// a + Δ/2 with the velocity Δ/h.
  MidpointNewton(ModelMatrix A, double h, const Potential* potential, const NewtonOptions& options,
                 double t_hessian = 0.0, LinearSolver solver = LinearSolver::kAuto,
                 const StateForce* state_force = nullptr);

  /// Solves for the increment Δ, starting from the guess in `increment`. forcing_tau is f(τ) or
  /// null (f ≡ 0). Convergence: ‖δ‖_∞ ≤ atol + rtol · max(‖a + Δ‖_∞, ‖a‖_∞), δ the last
  /// correction (already applied), and newton_converged()'s bound on a slow contraction.
  /// On the banded and sparse backends with a nonlinear U, J is kept from call to call (from
  /// step to step) while the corrections contract fast: see solve()'s comment. With such a
  /// carried J, the first correction also stops the iteration when the contraction estimated from
  /// the calls before predicts the next correction below round-off (4ε max(‖a + Δ‖_∞, ‖a‖_∞)).
  /// The vectors are Eigen::VectorXd, not Eigen::Ref as elsewhere: every caller holds VectorXd
  /// members, and GCC built each Ref parameter with Eigen's out-of-line constructor (two 8-byte
  /// stores) and then copied it with one 16-byte load, a store the CPU cannot forward — 74 % of
  /// effective_gradient's samples at d = 1 (perf); d = 1 run 167 → 160 ns per step.
  NewtonReport solve(const Eigen::VectorXd& a, double tau, const Eigen::VectorXd& c,
                     const Eigen::VectorXd* forcing_tau, Eigen::VectorXd& increment);

  /// The linear solve split by rows (CqMidpointStepper's row-split step): solve()'s one
  /// correction of a linear problem in four parts — rows_midpoint() for disjoint row ranges
  /// covering [0, d), then (once every range's midpoint is written: the potential's gradient reads
  /// neighbouring rows) rows_residual() for the same ranges, then solve_residual() on one thread,
  /// then rows_correction() for the ranges — from several threads at once: the same numbers as
  /// solve(). Where solves_by_rows(): linear, A diagonal, no state force, a potential with
  /// gradient_rows() (or none), a structured factorisation (banded or sparse).
  [[nodiscard]] bool solves_by_rows() const;
  /// Rows [lo, hi) of the midpoint a + Δ/2.
  void rows_midpoint(const double* a, const double* increment, Eigen::Index lo, Eigen::Index hi);
  /// Rows [lo, hi) of the residual A Δ + (h²/2) g − c, g = ∇U(midpoint, τ) − f(τ) (forcing_tau
  /// null: f ≡ 0); whether they are finite.
  bool rows_residual(double tau, const double* forcing_tau, const double* c,
                     const double* increment, Eigen::Index lo, Eigen::Index hi);
  /// Whether J was factored (else solve() reports kNewtonFailure, singular).
  [[nodiscard]] bool factor_ok() const { return constant_factor_ok_; }
  /// The correction δ = J⁻¹ r in place of the residual (one thread). Only when factor_ok().
  void solve_residual();
  /// Rows [lo, hi) of Δ −= δ, with max|δ_i| and whether Δ stays finite.
  CorrectionPass rows_correction(const double* a, double* increment, Eigen::Index lo,
                                 Eigen::Index hi);

  /// g = ∇U(z, τ) − f(τ) (zero potential and forcing allowed).
  void effective_gradient(const Eigen::VectorXd& z, double tau, const Eigen::VectorXd* forcing_tau,
                          Eigen::VectorXd& g) const;

  /// out = g(z, Δ/h, τ), the state force of a cell with midpoint z and increment Δ (zero without
  /// one). Allocation-free.
  void state_force(const Eigen::Ref<const Eigen::VectorXd>& z,
                   const Eigen::Ref<const Eigen::VectorXd>& increment, double tau,
                   Eigen::Ref<Eigen::VectorXd> out);
  /// g(a + Δ/2, Δ/h, τ)·Δ, the discrete work of the state force over the cell with start a and
  /// increment Δ (docs/theory/forces.md §3); 0 without one. Allocation-free.
  double state_force_work(const Eigen::Ref<const Eigen::VectorXd>& a,
                          const Eigen::Ref<const Eigen::VectorXd>& increment, double tau);
  [[nodiscard]] bool has_state_force() const { return state_force_ != nullptr; }

  [[nodiscard]] bool is_linear() const { return linear_; }
  /// The factorisation in use: kDense, kBanded or kSparse.
  [[nodiscard]] LinearSolver linear_solver() const { return backend_; }

  /// How many times J has been formed and factored (the constructor's included).
  [[nodiscard]] std::size_t factorizations() const { return factorizations_; }

  /// The kept Jacobian's point and whether the next call starts from it (a checkpoint's part of
  /// the solver: it changes the iterates, hence the last bits of a nonlinear step). Records
  /// `<prefix>.carry`, `.factored_mid`, `.factored_time`, `.carry_wait`, `.carry_backoff`,
  /// `.kept_contraction` (the kept J's estimated contraction) and `.factorizations` (the count so
  /// far);
  /// loading forms and factors J at the recorded point again when it is carried.
  void visit_state(StateArchive& archive, std::string_view prefix);

 private:
  // J = A + (h²/4)∇²U(mid, τ) into the dense matrix or the structured factor; false if singular.
  bool factor_jacobian(double tau);
  // After a converged call on a structured backend: whether the next call starts from this J
  // (carried: the call started from a carried J; fast: it converged at its second correction or
  // earlier, well inside the tolerance).
  void update_carry(bool carried, bool fast);

  ModelMatrix A_;
  double half_h2_;     // h²/2
  double quarter_h2_;  // h²/4
  double h_;
  const Potential* potential_;
  const StateForce* state_force_;
  NewtonOptions options_;
  bool linear_;
  LinearSolver backend_;
  // kDense
  Eigen::MatrixXd hessian_, jacobian_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  // kBanded / kSparse: J's values = A's (scattered once) + (h²/4) × Hessian values.
  std::unique_ptr<SymmetricFactor> factor_;
  std::vector<std::pair<std::size_t, double>> a_scatter_;
  std::vector<std::size_t> hessian_at_;  // pattern index of each hessian_values() entry
  std::vector<double> hessian_values_;
  bool dense_hessian_in_pattern_ = false;
  bool constant_factor_ok_ = true;  // linear problems: J factored once in the constructor  //
                                    // potential without a sparse Hessian, forced structured
  Eigen::VectorXd mid_, grad_, residual_, delta_;
  Eigen::VectorXd a_diagonal_;  // A's diagonal when A is diagonal (empty otherwise)
  // The kept J of the structured backends (nonlinear U), formed at (factored_mid_,
  // factored_time_): an earlier iterate, of an earlier step when carry_. A carried J that missed
  // (update_carry) waits carry_wait_ calls, a wait of carry_backoff_ that doubles per miss.
  bool carry_ = false;
  Eigen::VectorXd factored_mid_;
  double factored_time_ = 0.0;
  std::size_t carry_wait_ = 0, carry_backoff_ = 0;
  // The kept J's contraction θ, last observed (two corrections with it in one call) and aged at
  // every call since (solve()); +∞ until observed, and again after every factorisation.
  double kept_contraction_ = std::numeric_limits<double>::infinity();
  std::size_t factorizations_ = 0;
  // The state force at the current iterate and its Jacobians (dense path only).
  Eigen::VectorXd velocity_, force_value_;
  Eigen::MatrixXd force_dx_, force_dv_;
};

}  // namespace fracvi::internal
