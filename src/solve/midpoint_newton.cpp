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

}  // namespace

MidpointNewton::MidpointNewton(ModelMatrix A, double h, const Potential* potential,
                               const NewtonOptions& options, double t_hessian, LinearSolver solver)
    : A_(std::move(A)),
      half_h2_(0.5 * h * h),
      quarter_h2_(0.25 * h * h),
      potential_(potential),
      options_(options),
      linear_(potential == nullptr || potential->has_constant_hessian()),
      mid_(A_.rows()),
      grad_(A_.rows()),
      residual_(A_.rows()),
      delta_(A_.rows()) {
  const Eigen::Index d = A_.rows();
  std::shared_ptr<SymmetricPattern> pattern;
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

NewtonReport MidpointNewton::solve(const Eigen::Ref<const Eigen::VectorXd>& a, double tau,
                                   const Eigen::Ref<const Eigen::VectorXd>& c,
                                   const Eigen::VectorXd* forcing_tau,
                                   Eigen::Ref<Eigen::VectorXd> increment) {
  NewtonReport report;
  const int max_iterations = linear_ ? 1 : options_.max_iterations;
  const double a_norm = a.cwiseAbs().maxCoeff();
  for (int it = 1; it <= max_iterations; ++it) {
    mid_ = a + 0.5 * increment;
    effective_gradient(mid_, tau, forcing_tau, grad_);
    A_.multiply(increment, residual_);
    residual_ += half_h2_ * grad_;
    residual_ -= c;
    report.iterations = it;
    if (!residual_.allFinite()) {
      report.status = Status::kNonFinite;
      return report;
    }
    if (linear_ ? !constant_factor_ok_ : !factor_jacobian(tau)) {
      report.status = Status::kNewtonFailure;
      report.singular = true;
      report.correction = std::numeric_limits<double>::infinity();
      return report;
    }
    if (backend_ == LinearSolver::kDense) {
      delta_ = lu_.solve(residual_);
    } else {
      delta_ = residual_;
      factor_->solve_in_place(delta_);
    }
    increment -= delta_;
    report.correction = delta_.cwiseAbs().maxCoeff();
    if (!std::isfinite(report.correction) || !increment.allFinite()) {
      report.status = Status::kNonFinite;
      return report;
    }
    // The equation is linear: one correction from any guess is its solution.
    if (linear_) return report;
    const double scale = std::max((a + increment).cwiseAbs().maxCoeff(), a_norm);
    report.tolerance = options_.absolute_tolerance + options_.relative_tolerance * scale;
    if (report.correction <= report.tolerance) return report;
  }
  report.status = Status::kNewtonFailure;
  return report;
}

}  // namespace fracvi::internal
