#include "fracvi/schemes/stepper.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <exception>
#include <limits>
#include <utility>

#include "fracvi/solve/midpoint_newton.hpp"

namespace fracvi {

Eigen::VectorXd Stepper::health_weights(const ModelMatrix& mass) {
  const Eigen::Index d = mass.rows();
  Eigen::VectorXd w(d);
  for (Eigen::Index i = 0; i < d; ++i) w[i] = std::sqrt(std::max(0.0, mass.coeff(i, i)));
  return w;
}

Status Stepper::step() noexcept {
  message_[0] = '\0';
  detail_[0] = '\0';
  step_sums_ = {};
  const char* detail = "unknown exception";
  try {
    return advance();
  } catch (const std::exception& e) {
    std::snprintf(detail_.data(), detail_.size(), "%s", e.what());
    detail = nullptr;
  } catch (...) {
  }
  if (detail != nullptr) std::snprintf(detail_.data(), detail_.size(), "%s", detail);
  return fail(Status::kCallbackError, "the potential or the forcing threw");
}

void Stepper::visit_state(StateArchive&) {
  throw CheckpointError("this scheme's stepper cannot save its state (no checkpoints)");
}

void Stepper::visit_step_index(StateArchive& archive, Eigen::Index dimension, std::size_t steps,
                               std::size_t& k) {
  archive.expect("stepper.dimension", static_cast<std::size_t>(dimension));
  archive.expect("stepper.steps", steps);
  archive.count("stepper.k", k);
  if (k > steps) throw CheckpointError("checkpoint record 'stepper.k' exceeds stepper.steps");
}

Status Stepper::fail(Status status, const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  std::vsnprintf(message_.data(), message_.size(), format, args);
  va_end(args);
  return status;
}

Status Stepper::newton_outcome(const internal::NewtonReport& report, const char* matrix) noexcept {
  set_iterations(report.iterations);
  if (report.status == Status::kNonFinite) {
    return fail(Status::kNonFinite, "non-finite Newton residual or iterate");
  }
  if (report.singular) {
    return fail(Status::kNewtonFailure, "the Newton matrix %s could not be factored (singular)",
                matrix);
  }
  if (report.status == Status::kNewtonFailure) {
    return fail(Status::kNewtonFailure,
                "Newton did not converge within %d iterations (last correction %.3e > tolerance "
                "%.3e)",
                report.iterations, report.correction, report.tolerance);
  }
  return Status::kSuccess;
}

MirrorComparison::MirrorComparison(const RowMatrixXd& x, std::span<const std::size_t> steps,
                                   std::function<bool()> interrupt) noexcept
    : MirrorRows(steps.first(std::min(steps.size(), static_cast<std::size_t>(x.rows())))),
      x_(x),
      interrupt_(std::move(interrupt)) {}

void MirrorComparison::put(std::size_t row, const Eigen::VectorXd& y) {
  const Eigen::Map<const Eigen::VectorXd> x_row(x_.row(static_cast<Eigen::Index>(row)).data(),
                                                x_.cols());
  error_ = std::max(error_, (y - x_row).cwiseAbs().maxCoeff());
}

bool MirrorComparison::stop() {
  if (!interrupt_) return false;
  try {
    return interrupt_();
  } catch (...) {
    return true;  // a hook that cannot answer is taken as a request to stop
  }
}

double Stepper::mirror_error(const RowMatrixXd& x, std::span<const std::size_t> steps,
                             const std::function<bool()>& interrupt) const {
  MirrorComparison rows(x, steps, interrupt);
  return mirror_run(rows) ? rows.error() : std::numeric_limits<double>::quiet_NaN();
}

bool Stepper::mirror_run(MirrorRows&) const {
  return false;
}

}  // namespace fracvi
