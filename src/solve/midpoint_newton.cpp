#include "fracvi/solve/midpoint_newton.hpp"

#include "fracvi/solve/vector_passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace fracvi::internal {

namespace {

// The factorisation for J = A + (h²/4)∇²U: kAuto looks at the structure only when both parts can
// be sparse (A stored sparse, the potential absent or with a sparse Hessian); a dense M or a
// dense-only Hessian means a dense J anyway.
LinearSolver resolve(LinearSolver solver, const ModelMatrix& A, const Potential* potential,
                     std::shared_ptr<SymmetricPattern>& pattern) {
  const bool structured_possible =
      A.is_sparse() && (potential == nullptr || potential->has_sparse_hessian());
  if (solver == LinearSolver::kDense || (solver == LinearSolver::kAuto && !structured_possible)) {
    return LinearSolver::kDense;
  }
  pattern = std::make_shared<SymmetricPattern>(A.rows());
  pattern->add(A);
  if (potential != nullptr) pattern->add(*potential);
  pattern->finalize();
  return solver == LinearSolver::kAuto ? choose_factorization(*pattern) : solver;
}

// Simplified Newton (MidpointNewton::solve) keeps the factorisation while each correction is at
// most this fraction of the previous one.
constexpr double kKeptFactorContraction = 0.25;
// … and carries it into the next call (the next step) after a call that converged at its second
// correction or earlier, that correction at most kCarriedFactorMargin × the tolerance: the next
// step, whose state is O(h) away, is then expected to converge at its second correction with the
// same J, as full Newton would, without a factorisation. When a carried J needs more (the state
// moves too fast for it), J is formed afresh for the next 1, 2, 4, … kMaxCarryBackoff calls, the
// wait doubling with every miss and reset by a hit: a carry that keeps missing trades one
// factorisation for a correction (its gradient and solve), a loss for small systems. Measured on
// examples/fput_chain.toml with fvi-gl (d = 50, 6000 steps; full Newton 12 000 corrections):
// carrying whenever the corrections contracted by 100× took 20 948 corrections, carrying after
// every fast call without the wait 14 962 (every other step a miss, and slower), with the wait
// 12 094 (stepping the same within noise); the β-FPUT chain of bench/RESULTS.md factors once in
// 10^5 steps.
constexpr double kCarriedFactorMargin = 0.5;
constexpr std::size_t kMaxCarryBackoff = 64;
// The carried J's contraction θ is observed at a call's second correction; every call that starts
// from it without observing it raises the estimate to θ̂^0.8 (from ε at least), so that a stale
// estimate grows towards 1 and a second correction measures θ again within a few calls (the
// η_old^0.8 of Hairer & Wanner, Solving ODEs II, §IV.8, and RADAU5's FACCON). Measured on the
// β-FPUT chain of bench/RESULTS.md (d = 1000, h = 0.01): θ ≈ 6e-11 against ‖δ_1‖ ≈ 1.3e-10 and a
// round-off level of ≈ 4e-16, so about three calls in four stop at their first correction (1.26
// corrections a step instead of 2.00).
constexpr double kContractionAging = 0.8;

}  // namespace

MidpointNewton::MidpointNewton(ModelMatrix A, double h, const Potential* potential,
                               const NewtonOptions& options, double t_hessian, LinearSolver solver,
                               const StateForce* state_force)
    : A_(std::move(A)),
      half_h2_(0.5 * h * h),
      quarter_h2_(0.25 * h * h),
      h_(h),
      potential_(potential),
      state_force_(state_force),
      options_(options),
      linear_(state_force == nullptr &&
              (potential == nullptr || potential->has_constant_hessian())),
      mid_(A_.rows()),
      grad_(A_.rows()),
      residual_(A_.rows()),
      delta_(A_.rows()) {
  const Eigen::Index d = A_.rows();
  std::shared_ptr<SymmetricPattern> pattern;
  if (state_force_ != nullptr) {
    // ∂g/∂v makes J non-symmetric: only the dense LU factorises it.
    if (solver == LinearSolver::kBanded || solver == LinearSolver::kSparse) {
      throw ValidationError(
          std::string("method.linear_solver = \"") +
          (solver == LinearSolver::kBanded ? "banded" : "sparse") +
          "\" cannot factor the Newton matrix of a model with a force g(x, v, t) (model.force "
          "in x or v): its Jacobian makes the matrix non-symmetric, and the banded and sparse "
          "factorisations are symmetric (LDL^T); use linear_solver = \"dense\" or \"auto\"");
    }
    solver = LinearSolver::kDense;
    velocity_.setZero(d);
    force_value_.setZero(d);
    force_dx_.setZero(d, d);
    force_dv_.setZero(d, d);
  }
  backend_ = resolve(solver, A_, potential_, pattern);
  if (backend_ == LinearSolver::kDense) {
    if (d > kMaxDenseDimension) {
      throw ValidationError(
          "the Newton matrix M + (h^2/4) Hess U would be factored dense (d = " + std::to_string(d) +
          ", " + std::to_string(static_cast<double>(d) * static_cast<double>(d) * 8e-9 * 3) +
          " GB for the matrix, its factor and the Hessian): use linear_solver = auto, banded or "
          "sparse with a sparse mass matrix and a potential with a sparse Hessian "
          "(docs/large-systems.md)");
    }
    if (A_.is_sparse()) A_ = ModelMatrix(A_.to_dense());
    hessian_ = Eigen::MatrixXd::Zero(d, d);
    jacobian_.resize(d, d);
    lu_ = Eigen::PartialPivLU<Eigen::MatrixXd>(d);
  } else {
    a_scatter_ = scatter_upper(*pattern, A_);
    dense_hessian_in_pattern_ = potential_ != nullptr && !potential_->has_sparse_hessian();
    if (dense_hessian_in_pattern_) {
      hessian_ = Eigen::MatrixXd::Zero(d, d);
    } else if (potential_ != nullptr) {
      for (const auto& e : potential_->hessian_pattern())
        hessian_at_.push_back(pattern->index_of(e.row, e.col));
      hessian_values_.assign(hessian_at_.size(), 0.0);
    }
    factor_ = std::make_unique<SymmetricFactor>(std::move(pattern), backend_);
  }
  factored_mid_.setZero(d);
  if (A_.is_diagonal()) {
    a_diagonal_.resize(d);
    for (Eigen::Index i = 0; i < d; ++i) a_diagonal_[i] = A_.coeff(i, i);
  }
  if (linear_) {
    mid_.setZero();
    constant_factor_ok_ = factor_jacobian(t_hessian);
  }
}

bool MidpointNewton::factor_jacobian(double tau) {
  ++factorizations_;
  if (backend_ == LinearSolver::kDense) {
    if (potential_ != nullptr) potential_->hessian(mid_, tau, hessian_);
    jacobian_ = A_.dense();
    jacobian_ += quarter_h2_ * hessian_;
    // ∂/∂Δ of −(h²/2) g(a + Δ/2, Δ/h): the Jacobians were taken with the residual (solve()).
    if (state_force_ != nullptr) {
      jacobian_ -= quarter_h2_ * force_dx_;
      jacobian_ -= (0.5 * h_) * force_dv_;
    }
    lu_.compute(jacobian_);
    return true;  // PartialPivLU does not report singularity; it shows as inf/NaN in δ
  }
  std::span<double> j = factor_->values();
  std::fill(j.begin(), j.end(), 0.0);
  for (const auto& [at, value] : a_scatter_) j[at] += value;
  if (dense_hessian_in_pattern_) {
    potential_->hessian(mid_, tau, hessian_);
    const SymmetricPattern& p = factor_->pattern();
    for (std::size_t e = 0; e < p.size(); ++e) {
      const auto& entry = p.entries()[e];
      j[e] += quarter_h2_ * hessian_(entry.row, entry.col);
    }
  } else if (potential_ != nullptr) {
    potential_->hessian_values(mid_, tau, hessian_values_);
    for (std::size_t e = 0; e < hessian_at_.size(); ++e)
      j[hessian_at_[e]] += quarter_h2_ * hessian_values_[e];
  }
  const bool factored = factor_->factor();
  if (!linear_) {
    factored_mid_ = mid_;
    factored_time_ = tau;
  }
  if (!factored) carry_ = false;
  return factored;
}

void MidpointNewton::visit_state(StateArchive& archive, std::string_view prefix) {
  const std::string name(prefix);
  archive.flag(name + ".carry", carry_);
  archive.dense(name + ".factored_mid", factored_mid_);
  archive.number(name + ".factored_time", factored_time_);
  archive.count(name + ".carry_wait", carry_wait_);
  archive.count(name + ".carry_backoff", carry_backoff_);
  archive.number(name + ".kept_contraction", kept_contraction_);
  std::size_t factorizations = factorizations_;
  archive.count(name + ".factorizations", factorizations);
  // Only the structured backends carry J between calls (a linear J is the constructor's).
  if (archive.loading() && carry_ && !linear_ && backend_ != LinearSolver::kDense) {
    mid_ = factored_mid_;
    if (!factor_jacobian(factored_time_)) {
      throw CheckpointError("checkpoint record '" + name +
                            ".factored_mid': the Newton matrix M + (h^2/4) Hess U at the recorded "
                            "point could not be factored (singular)");
    }
    carry_ = true;
  }
  // The recorded count: forming the carried J again is not a factorisation of the run's.
  if (archive.loading()) factorizations_ = factorizations;
}

void MidpointNewton::update_carry(bool carried, bool fast) {
  if (carried) {
    if (fast) {
      carry_ = true;
      carry_backoff_ = 0;
      return;
    }
    carry_backoff_ = std::min(std::max<std::size_t>(1, 2 * carry_backoff_), kMaxCarryBackoff);
    carry_wait_ = carry_backoff_;
    carry_ = false;
  } else if (carry_wait_ > 0) {
    --carry_wait_;
    carry_ = false;
  } else {
    carry_ = fast;
  }
}

void MidpointNewton::effective_gradient(const Eigen::VectorXd& z, double tau,
                                        const Eigen::VectorXd* forcing_tau,
                                        Eigen::VectorXd& g) const {
  if (potential_ != nullptr) {
    potential_->gradient(z, tau, g);
  } else {
    g.setZero();
  }
  if (forcing_tau != nullptr) g -= *forcing_tau;
}

bool MidpointNewton::solves_by_rows() const {
  return linear_ && a_diagonal_.size() > 0 && state_force_ == nullptr &&
         (potential_ == nullptr || potential_->has_gradient_rows()) &&
         backend_ != LinearSolver::kDense;
}

// solve()'s passes of a linear step on rows [lo, hi): each element's operations are solve()'s.
void MidpointNewton::rows_midpoint(const double* a, const double* increment, Eigen::Index lo,
                                   Eigen::Index hi) {
  midpoint_pass(a + lo, increment + lo, mid_.data() + lo, hi - lo);
}

bool MidpointNewton::rows_residual(double tau, const double* forcing_tau, const double* c,
                                   const double* increment, Eigen::Index lo, Eigen::Index hi) {
  double* g = grad_.data();
  if (potential_ != nullptr) {
    potential_->gradient_rows(mid_, tau, g, lo, hi);
  } else {
    std::fill(g + lo, g + hi, 0.0);
  }
  if (forcing_tau != nullptr) {
    for (Eigen::Index i = lo; i < hi; ++i) g[i] -= forcing_tau[i];  // effective_gradient's g −= f
  }
  return diagonal_residual(a_diagonal_.data() + lo, increment + lo, half_h2_, g + lo, c + lo,
                           residual_.data() + lo, hi - lo);
}

void MidpointNewton::solve_residual() {
  factor_->solve_in_place(residual_);
}

CorrectionPass MidpointNewton::rows_correction(const double* a, double* increment, Eigen::Index lo,
                                               Eigen::Index hi) {
  return apply_correction_pass(residual_.data() + lo, a + lo, increment + lo, mid_.data() + lo,
                               hi - lo, false);
}

void MidpointNewton::state_force(const Eigen::Ref<const Eigen::VectorXd>& z,
                                 const Eigen::Ref<const Eigen::VectorXd>& increment, double tau,
                                 Eigen::Ref<Eigen::VectorXd> out) {
  if (state_force_ == nullptr) {
    out.setZero();
    return;
  }
  velocity_ = increment * (1.0 / h_);
  state_force_->value(z, velocity_, tau, out);
}

double MidpointNewton::state_force_work(const Eigen::Ref<const Eigen::VectorXd>& a,
                                        const Eigen::Ref<const Eigen::VectorXd>& increment,
                                        double tau) {
  if (state_force_ == nullptr) return 0.0;
  mid_ = a + 0.5 * increment;
  state_force(mid_, increment, tau, force_value_);
  return force_value_.dot(increment);
}

NewtonReport MidpointNewton::solve(const Eigen::VectorXd& a, double tau, const Eigen::VectorXd& c,
                                   const Eigen::VectorXd* forcing_tau, Eigen::VectorXd& increment) {
  NewtonReport report;
  const int max_iterations = linear_ ? 1 : options_.max_iterations;
  // Simplified Newton on the structured backends: J is factored at the step's first iterate and
  // kept while the corrections contract, ‖δ_k‖ ≤ kKeptFactorContraction ‖δ_{k−1}‖ (the kept J
  // differs from the current one by O(‖Δ_k − Δ_1‖), so the contraction is linear with a rate of
  // that order; a step that converges in two iterations then costs one factorisation and two
  // solves instead of two of each). Otherwise J is refactored at the current iterate: a full
  // Newton iteration. The stopping rule (newton_converged) also bounds the error a slowly
  // contracting iterate leaves, θ/(1 − θ)·‖δ‖, by the tolerance. The dense path
  // (small systems, and every system with a state force, whose Jacobians would be stale) keeps
  // full Newton.
  //
  // The kept J also carries over from the previous call, i.e. from the previous step (as
  // fvi-lobatto keeps its stage matrix): it was formed at the previous step's first iterate, which
  // differs from this step's by O(h), so the contraction rate is O(h³ ∇³U) — for a smooth motion
  // two corrections, as with a fresh J, and no factorisation (measured on the β-FPUT chain,
  // bench/RESULTS.md) — as long as the calls converge that fast (kCarriedFactorMargin).
  // A J from an earlier step has no observed contraction at the first correction (θ = ∞ there),
  // so that correction alone meets the tolerance only through the estimate θ̂ carried from the
  // calls before, and only when it predicts the next correction below round-off (below).
  const bool keep_factor = !linear_ && backend_ != LinearSolver::kDense;
  const bool kept_from_earlier_call = keep_factor && carry_;
  carry_ = false;  // until this call converges (update_carry)
  // The carried J's contraction as last observed, aged by this call (kContractionAging): the
  // estimate that lets its first correction stop the iteration (below).
  double estimated_contraction = std::numeric_limits<double>::infinity();
  if (kept_from_earlier_call && std::isfinite(kept_contraction_)) {
    estimated_contraction = std::pow(
        std::max(kept_contraction_, std::numeric_limits<double>::epsilon()), kContractionAging);
    kept_contraction_ = estimated_contraction;
  }
  bool factor_now = !kept_from_earlier_call;
  double previous_correction = std::numeric_limits<double>::infinity();
  // The first iterate's midpoint (later ones come out of the correction pass) and, in the same
  // pass, the scale of the convergence test max|a_i| (a linear step has none).
  const Eigen::Index d = mid_.size();
  const double a_norm = midpoint_pass(a.data(), increment.data(), mid_.data(), d, !linear_);
  for (int it = 1; it <= max_iterations; ++it) {
    effective_gradient(mid_, tau, forcing_tau, grad_);
    if (state_force_ != nullptr) {
      velocity_ = increment * (1.0 / h_);
      state_force_->jacobians(mid_, velocity_, tau, force_value_, force_dx_, force_dv_);
      grad_ -= force_value_;
    }
    // (A Δ + (h²/2) g) − c element by element with its finiteness check, in one pass
    // (vector_passes.hpp): the same roundings as A Δ, += and −=; a diagonal A (the chains' mass)
    // multiplies in the same pass.
    bool residual_finite = true;
    if (a_diagonal_.size() > 0) {
      residual_finite = diagonal_residual(a_diagonal_.data(), increment.data(), half_h2_,
                                          grad_.data(), c.data(), residual_.data(), d);
    } else {
      A_.multiply(increment, residual_);
      residual_finite = general_residual(half_h2_, grad_.data(), c.data(), residual_.data(), d);
    }
    report.iterations = it;
    if (!residual_finite) {
      report.status = Status::kNonFinite;
      return report;
    }
    const bool refactored = !linear_ && factor_now;
    if (refactored) kept_contraction_ = std::numeric_limits<double>::infinity();  // a new J
    if (linear_ ? !constant_factor_ok_ : factor_now && !factor_jacobian(tau)) {
      report.status = Status::kNewtonFailure;
      report.singular = true;
      report.correction = std::numeric_limits<double>::infinity();
      return report;
    }
    // δ overwrites the residual in place (no copy pass); the update, the size of the correction
    // and the finiteness check share one pass (max is exact: the same correction as before).
    Eigen::VectorXd* delta = &residual_;
    if (backend_ == LinearSolver::kDense && residual_.size() == 1) {
      // d = 1: the LU solve is the quotient by the one pivot (the permutation is the identity,
      // the unit lower factor empty), without Eigen's general triangular-solve set-up (≈ 5 % of
      // a d = 1 step, perf). The same division, so the same bits.
      residual_[0] /= lu_.matrixLU()(0, 0);
    } else if (backend_ == LinearSolver::kDense) {
      delta_ = lu_.solve(residual_);
      delta = &delta_;
    } else {
      factor_->solve_in_place(residual_);
    }
    // The update Δ −= δ, the size of δ and the finiteness of Δ, and for a nonlinear step the next
    // iterate's midpoint and the scale of the convergence test, in one pass (vector_passes.hpp).
    const CorrectionPass applied =
        apply_correction_pass(delta->data(), a.data(), increment.data(), mid_.data(), d, !linear_);
    report.correction = applied.size;
    if (!applied.finite || !std::isfinite(report.correction)) {
      report.status = Status::kNonFinite;
      return report;
    }
    // The equation is linear: one correction from any guess is its solution.
    if (linear_) return report;
    const double contraction = report.correction / previous_correction;  // 0 at it = 1
    factor_now = !keep_factor || contraction > kKeptFactorContraction;
    // Two corrections with the same J carried from an earlier call: its contraction, observed.
    // (Not that of a J formed in this call: formed at this step's first iterate, it contracts far
    // better than it will once carried a step on — measured 50× the round-off left by a first
    // correction that such an estimate let stop, tests/integrate/newton_stopping_test.cpp.)
    if (kept_from_earlier_call && it >= 2 && !refactored) kept_contraction_ = contraction;
    const double observed_contraction =
        it == 1 && kept_from_earlier_call ? std::numeric_limits<double>::infinity() : contraction;
    previous_correction = report.correction;
    const double scale = std::max(applied.scale, a_norm);
    report.tolerance = options_.absolute_tolerance + options_.relative_tolerance * scale;
    const double roundoff = 4.0 * std::numeric_limits<double>::epsilon() * scale;
    // The first correction with a carried J stops the iteration when the next one is predicted
    // below round-off: θ̂/(1 − θ̂)·‖δ_1‖ ≤ roundoff, θ̂ the aged estimate (Hairer & Wanner II,
    // §IV.8: the contraction of the previous step stands for this one's). The iterate is then the
    // solution to round-off, as after a second correction, which would change Δ by less than its
    // last bits.
    const bool next_below_roundoff =
        it == 1 && estimated_contraction < 0.5 &&
        estimated_contraction / (1.0 - estimated_contraction) * report.correction <= roundoff;
    if (next_below_roundoff ||
        newton_converged(report.correction, report.tolerance, observed_contraction, roundoff)) {
      if (keep_factor) {
        update_carry(kept_from_earlier_call,
                     next_below_roundoff ||
                         (it <= 2 && report.correction <= kCarriedFactorMargin * report.tolerance));
      }
      return report;
    }
  }
  report.status = Status::kNewtonFailure;
  return report;
}

}  // namespace fracvi::internal
