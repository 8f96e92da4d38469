#include "fracvi/solve/midpoint_newton.hpp"

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

// increment −= δ; returns max|δ_i| and clears `finite` when some updated entry is not finite.
double apply_correction(const Eigen::VectorXd& delta, Eigen::Ref<Eigen::VectorXd> increment,
                        bool& finite) {
  double correction = 0.0;
  bool all_finite = true;
  for (Eigen::Index i = 0; i < delta.size(); ++i) {
    const double updated = increment[i] - delta[i];
    increment[i] = updated;
    correction = std::max(correction, std::abs(delta[i]));
    all_finite &= std::isfinite(updated);
  }
  finite = all_finite;
  return correction;
}

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
  if (linear_) {
    mid_.setZero();
    constant_factor_ok_ = factor_jacobian(t_hessian);
  }
}

bool MidpointNewton::factor_jacobian(double tau) {
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
  return factor_->factor();
}

void MidpointNewton::effective_gradient(const Eigen::Ref<const Eigen::VectorXd>& z, double tau,
                                        const Eigen::VectorXd* forcing_tau,
                                        Eigen::Ref<Eigen::VectorXd> g) const {
  if (potential_ != nullptr) {
    potential_->gradient(z, tau, g);
  } else {
    g.setZero();
  }
  if (forcing_tau != nullptr) g -= *forcing_tau;
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

NewtonReport MidpointNewton::solve(const Eigen::Ref<const Eigen::VectorXd>& a, double tau,
                                   const Eigen::Ref<const Eigen::VectorXd>& c,
                                   const Eigen::VectorXd* forcing_tau,
                                   Eigen::Ref<Eigen::VectorXd> increment) {
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
  const bool keep_factor = !linear_ && backend_ != LinearSolver::kDense;
  bool factor_now = true;
  double previous_correction = std::numeric_limits<double>::infinity();
  // The scale of the convergence test; a linear step has none (one pass fewer per step).
  const double a_norm = linear_ ? 0.0 : a.cwiseAbs().maxCoeff();
  for (int it = 1; it <= max_iterations; ++it) {
    // A plain loop, the same roundings as the Eigen expression, whose set-up costs more than its
    // work at d = 1.
    for (Eigen::Index i = 0; i < mid_.size(); ++i) mid_[i] = a[i] + 0.5 * increment[i];
    effective_gradient(mid_, tau, forcing_tau, grad_);
    if (state_force_ != nullptr) {
      velocity_ = increment * (1.0 / h_);
      state_force_->jacobians(mid_, velocity_, tau, force_value_, force_dx_, force_dv_);
      grad_ -= force_value_;
    }
    A_.multiply(increment, residual_);
    // One pass with its finiteness check, the same roundings as += then −=: (M Δ + (h²/2) g) − c
    // element by element (a plain loop: Eigen's two passes cost ≈ 30 instructions at d = 1).
    bool residual_finite = true;
    for (Eigen::Index i = 0; i < residual_.size(); ++i) {
      residual_[i] = (residual_[i] + half_h2_ * grad_[i]) - c[i];
      residual_finite &= std::isfinite(residual_[i]);
    }
    report.iterations = it;
    if (!residual_finite) {
      report.status = Status::kNonFinite;
      return report;
    }
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
    bool finite = true;
    report.correction = apply_correction(*delta, increment, finite);
    if (!finite || !std::isfinite(report.correction)) {
      report.status = Status::kNonFinite;
      return report;
    }
    // The equation is linear: one correction from any guess is its solution.
    if (linear_) return report;
    const double contraction = report.correction / previous_correction;  // 0 at it = 1
    factor_now = !keep_factor || contraction > kKeptFactorContraction;
    previous_correction = report.correction;
    const double scale = std::max((a + increment).cwiseAbs().maxCoeff(), a_norm);
    report.tolerance = options_.absolute_tolerance + options_.relative_tolerance * scale;
    const double roundoff = 4.0 * std::numeric_limits<double>::epsilon() * scale;
    if (newton_converged(report.correction, report.tolerance, contraction, roundoff)) return report;
  }
  report.status = Status::kNewtonFailure;
  return report;
}

}  // namespace fracvi::internal
