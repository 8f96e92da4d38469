#include "fracvi/model/mechanical_model.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

namespace fracvi {

double roundoff_tolerance(Eigen::Index dimension, double scale) {
  return 100.0 * static_cast<double>(dimension) * std::numeric_limits<double>::epsilon() * scale;
}

std::optional<Convention> parse_convention(std::string_view name) {
  if (name == "riemann-liouville") return Convention::kRiemannLiouville;
  if (name == "caputo") return Convention::kCaputo;
  return std::nullopt;
}

std::string_view to_string(Convention convention) {
  switch (convention) {
    case Convention::kRiemannLiouville: return "riemann-liouville";
    case Convention::kCaputo: return "caputo";
  }
  return "unknown";
}

bool MechanicalModel::is_undamped() const {
  return damping.rows() == 0 || damping.is_zero();
}

namespace {

// Shortest representation that reads back to the same double ("-0.3", not "-0.29999999999999999").
std::string fmt(double value) {
  return format_number(value);
}

template <class Matrix>
std::string shape(const Matrix& m) {
  return std::to_string(m.rows()) + " x " + std::to_string(m.cols());
}

[[noreturn]] void fail(const std::string& message) {
  throw ValidationError(message);
}

double roundoff_tolerance(const Eigen::MatrixXd& m) {
  return fracvi::roundoff_tolerance(m.rows(), m.size() == 0 ? 0.0 : m.cwiseAbs().maxCoeff());
}

void check_square_symmetric(const ModelMatrix& m, Eigen::Index d, const char* field) {
  if (m.rows() != d || m.cols() != d) {
    fail(std::string(field) + " is " + shape(m) + ", must be " + std::to_string(d) + " x " +
         std::to_string(d) + " (the size of model.mass)");
  }
  if (!m.all_finite()) fail(std::string(field) + " has a non-finite entry");
  const double asym = m.max_asymmetry();
  if (asym > fracvi::roundoff_tolerance(d, m.max_abs())) {
    fail(std::string(field) + " is not symmetric (max |A - A^T| = " + fmt(asym) + ")");
  }
}

// Definiteness of a sparse matrix without its spectrum (d may be 10^5): the diagonal of a diagonal
// matrix, otherwise a sparse Cholesky factorisation of A + shift·I.
bool sparse_positive_definite(const ModelMatrix& m, double shift, double& diagonal_min) {
  const ModelMatrix::Sparse sym = m.symmetric_part().sparse();
  diagonal_min = sym.rows() > 0 ? sym.diagonal().minCoeff() : 0.0;
  if (m.is_diagonal()) return diagonal_min + shift > 0.0;
  ModelMatrix::Sparse shifted = sym;
  for (Eigen::Index i = 0; i < shifted.rows(); ++i) shifted.coeffRef(i, i) += shift;
  Eigen::SimplicialLLT<ModelMatrix::Sparse> llt(shifted);
  return llt.info() == Eigen::Success;
}

double smallest_eigenvalue(const Eigen::MatrixXd& m) {
  const Eigen::MatrixXd sym = 0.5 * (m + m.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(sym, Eigen::EigenvaluesOnly);
  return eig.eigenvalues().minCoeff();
}

void check_vector(const Eigen::VectorXd& v, Eigen::Index d, const char* field) {
  if (v.size() != d) {
    fail(std::string(field) + " has size " + std::to_string(v.size()) + ", must be " +
         std::to_string(d) + " (the size of model.mass)");
  }
  if (!v.allFinite()) fail(std::string(field) + " has a non-finite entry");
}

}  // namespace

void validate(const MechanicalModel& model) {
  const Eigen::Index d = model.mass.rows();
  if (d < 1 || model.mass.cols() != d) {
    fail("model.mass is " + shape(model.mass) + ", must be square and non-empty");
  }
  check_square_symmetric(model.mass, d, "model.mass");
  if (model.mass.is_sparse()) {
    double diagonal_min = 0.0;
    if (!sparse_positive_definite(model.mass, 0.0, diagonal_min)) {
      fail(
          "model.mass is not symmetric positive definite (sparse Cholesky factorisation fails; "
          "smallest diagonal entry " +
          fmt(diagonal_min) + ")");
    }
  } else {
    const double mass_min = smallest_eigenvalue(model.mass.dense());
    if (!(mass_min > 0.0) ||
        Eigen::LLT<Eigen::MatrixXd>(model.mass.dense()).info() != Eigen::Success) {
      fail("model.mass is not symmetric positive definite (smallest eigenvalue " + fmt(mass_min) +
           ")");
    }
  }
  check_square_symmetric(model.damping, d, "model.damping");
  if (model.damping.is_sparse()) {
    // R + δI positive definite for a δ at round-off level ⇔ R positive semidefinite (to round-off).
    const double shift = 100.0 * static_cast<double>(d) * std::numeric_limits<double>::epsilon() *
                         std::max(1.0, model.damping.max_abs());
    double diagonal_min = 0.0;
    if (!sparse_positive_definite(model.damping, shift, diagonal_min)) {
      fail(
          "model.damping is not symmetric positive semidefinite (sparse Cholesky factorisation "
          "of R + " +
          fmt(shift) + " I fails; smallest diagonal entry " + fmt(diagonal_min) + ")");
    }
  } else {
    const double damping_min = smallest_eigenvalue(model.damping.dense());
    if (damping_min < -roundoff_tolerance(model.damping.dense())) {
      fail("model.damping is not symmetric positive semidefinite (smallest eigenvalue " +
           fmt(damping_min) + ")");
    }
  }
  if (!std::isfinite(model.alpha) || model.alpha < 0.0 || model.alpha > 1.0) {
    fail("model.alpha = " + fmt(model.alpha) +
         " is outside [0, 1] (alpha is the Lagrangian order; the damping order 2*alpha must lie "
         "in [0, 2])");
  }
  if (model.alpha > 0.0 && model.alpha < kMinPositiveAlpha) {
    fail("model.alpha = " + fmt(model.alpha) + " is positive but below " + fmt(kMinPositiveAlpha) +
         ": so small an order differs from alpha = 0 (D^0 x = x) by less than 1e-10 relative, and "
         "its memory weights approach the subnormal range; use alpha = 0");
  }
  if (model.convention != Convention::kCaputo &&
      model.convention != Convention::kRiemannLiouville) {
    fail("model.convention has an unknown value");
  }
  if (model.state_force && model.state_force->dimension() != d) {
    fail("model.state_force has dimension " + std::to_string(model.state_force->dimension()) +
         ", must be " + std::to_string(d) + " (the size of model.mass)");
  }
  if (model.potential && model.potential->dimension() != d) {
    fail("model.potential has dimension " + std::to_string(model.potential->dimension()) +
         ", must be " + std::to_string(d) + " (the size of model.mass)");
  }
}

void validate(const InitialValueProblem& problem) {
  validate(problem.model);
  const Eigen::Index d = problem.model.dimension();
  check_vector(problem.x0, d, "x0");
  check_vector(problem.v0, d, "v0");
  if (!std::isfinite(problem.t0)) fail("t0 = " + fmt(problem.t0) + " must be finite");
  if (!std::isfinite(problem.t_end) || !(problem.t_end > problem.t0)) {
    fail("t_end = " + fmt(problem.t_end) +
         " must be finite and greater than t0 = " + fmt(problem.t0));
  }
  if (problem.steps < 1) fail("steps = 0, must be >= 1");
  if (!std::isfinite(problem.t_end - problem.t0)) {
    fail("time.end - time.start = " + fmt(problem.t_end - problem.t0) +
         " (t0 = " + fmt(problem.t0) + ", t_end = " + fmt(problem.t_end) +
         ") overflows: the interval must have a finite length");
  }
  const double h = problem.step_size();
  if (!(h > 0.0) || !std::isfinite(h) || problem.t0 + h == problem.t0) {
    fail("steps = " + std::to_string(problem.steps) + " gives step size h = " + fmt(h) +
         ", too small to advance time from t0 = " + fmt(problem.t0));
  }
  const double order = problem.model.damping_order();
  if (problem.model.convention == Convention::kRiemannLiouville && order > 1.0 &&
      !problem.model.is_undamped() && (problem.x0.array() != 0.0).any()) {
    fail("model.convention = riemann-liouville with damping order 2*alpha = " + fmt(order) +
         " > 1 and x0 != 0 is ill-posed: " + riemann_liouville_obstruction(order) +
         ". Use convention = caputo (the memory then acts on x - x0 - t v0), or start from x0 = 0");
  }
}

std::string riemann_liouville_obstruction(double damping_order) {
  if (damping_order >= 2.0) {
    return "at damping order 2 the force of the constant x(0) vanishes pointwise (1/Gamma(-1) = "
           "0), but the memory sums x extended by 0 before t = 0 and at order 2 its weights form a "
           "second difference, which kicks "
           "the first step with -R x(0)/h^2, an impulse -R x(0)/h that grows without bound as "
           "h -> 0 (the discrete x(0) delta'(t)): the discrete solution does not converge";
  }
  return "the Riemann-Liouville damping force of the constant x(0), x(0) t^(-2 alpha) / "
         "Gamma(1 - 2 alpha), is not integrable at t = 0, so the discrete solution does not "
         "converge as h -> 0";
}

}  // namespace fracvi
