#include "fracvi/integrate/midpoint_newton.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace fracvi::internal {

MidpointNewton::MidpointNewton(Eigen::MatrixXd A, double h, const Potential* potential,
                               const NewtonOptions& options, double t_hessian)
    : A_(std::move(A)),
      half_h2_(0.5 * h * h),
      quarter_h2_(0.25 * h * h),
      potential_(potential),
      options_(options),
      linear_(potential == nullptr || potential->has_constant_hessian()),
      hessian_(Eigen::MatrixXd::Zero(A_.rows(), A_.rows())),
      jacobian_(A_.rows(), A_.rows()),
      lu_(A_.rows()),
      mid_(A_.rows()),
      grad_(A_.rows()),
      residual_(A_.rows()),
      delta_(A_.rows()) {
  if (linear_) {
    if (potential_ != nullptr) {
      potential_->hessian(Eigen::VectorXd::Zero(A_.rows()), t_hessian, hessian_);
    }
    jacobian_ = A_ + quarter_h2_ * hessian_;
    lu_.compute(jacobian_);
  }
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
                                   Eigen::Ref<Eigen::VectorXd> increment) noexcept {
  NewtonReport report;
  const int max_iterations = linear_ ? 1 : options_.max_iterations;
  const double a_norm = a.cwiseAbs().maxCoeff();
  for (int it = 1; it <= max_iterations; ++it) {
    mid_ = a + 0.5 * increment;
    effective_gradient(mid_, tau, forcing_tau, grad_);
    residual_.noalias() = A_ * increment;
    residual_ += half_h2_ * grad_;
    residual_ -= c;
    report.iterations = it;
    if (!residual_.allFinite()) {
      report.status = Status::kNonFinite;
      return report;
    }
    if (!linear_) {
      potential_->hessian(mid_, tau, hessian_);
      jacobian_ = A_;
      jacobian_ += quarter_h2_ * hessian_;
      lu_.compute(jacobian_);
    }
    delta_ = lu_.solve(residual_);
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
