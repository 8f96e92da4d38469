#include "fracvi/model/potential.hpp"

#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace fracvi {

namespace {

std::string shape(const Eigen::MatrixXd& m) {
  return std::to_string(m.rows()) + " x " + std::to_string(m.cols());
}

}  // namespace

void Potential::gradient_rows(const Eigen::Ref<const Eigen::VectorXd>&, double, double*,
                              Eigen::Index, Eigen::Index) const {
  throw std::logic_error("Potential::gradient_rows called on a potential without it");
}

void Potential::hessian_values(const Eigen::Ref<const Eigen::VectorXd>&, double,
                               std::span<double>) const {
  throw std::logic_error(
      "Potential::hessian_values called on a potential without a sparse Hessian "
      "(has_sparse_hessian() is false)");
}

QuadraticPotential::QuadraticPotential(Eigen::MatrixXd stiffness)
    : QuadraticPotential(stiffness, Eigen::VectorXd::Zero(stiffness.rows())) {}

QuadraticPotential::QuadraticPotential(Eigen::MatrixXd stiffness, Eigen::VectorXd linear)
    : stiffness_(std::move(stiffness)), linear_(std::move(linear)) {
  if (stiffness_.rows() < 1 || stiffness_.rows() != stiffness_.cols()) {
    throw std::invalid_argument("QuadraticPotential: stiffness is " + shape(stiffness_) +
                                ", must be square and non-empty");
  }
  if (linear_.size() != stiffness_.rows()) {
    throw std::invalid_argument("QuadraticPotential: linear term has size " +
                                std::to_string(linear_.size()) + ", must be " +
                                std::to_string(stiffness_.rows()));
  }
  if (!stiffness_.allFinite() || !linear_.allFinite()) {
    throw std::invalid_argument("QuadraticPotential: stiffness and linear term must be finite");
  }
  // Round-off asymmetry (e.g. from ΛᵀKΛ) is tolerated and removed; real asymmetry is an error,
  // because only the symmetric part of K is a potential's Hessian.
  const double scale = stiffness_.cwiseAbs().maxCoeff();
  const double asym = (stiffness_ - stiffness_.transpose()).cwiseAbs().maxCoeff();
  const double tol = 100.0 * static_cast<double>(stiffness_.rows()) *
                     std::numeric_limits<double>::epsilon() * scale;
  if (asym > tol) {
    throw std::invalid_argument("QuadraticPotential: stiffness is not symmetric (max |K - K^T| = " +
                                std::to_string(asym) + ")");
  }
  stiffness_ = 0.5 * (stiffness_ + stiffness_.transpose()).eval();
}

double QuadraticPotential::value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const {
  // Column by column so that no temporary vector K x is allocated.
  double quad = 0.0;
  for (Eigen::Index j = 0; j < x.size(); ++j) quad += x(j) * stiffness_.col(j).dot(x);
  return 0.5 * quad - linear_.dot(x);
}

void QuadraticPotential::gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                                  Eigen::Ref<Eigen::VectorXd> g) const {
  g.noalias() = stiffness_ * x;
  g -= linear_;
}

void QuadraticPotential::hessian(const Eigen::Ref<const Eigen::VectorXd>&, double,
                                 Eigen::Ref<Eigen::MatrixXd> H) const {
  H = stiffness_;
}

std::shared_ptr<const Potential> make_quadratic_potential(Eigen::MatrixXd stiffness) {
  return std::make_shared<const QuadraticPotential>(std::move(stiffness));
}

std::shared_ptr<const Potential> make_quadratic_potential(Eigen::MatrixXd stiffness,
                                                          Eigen::VectorXd linear) {
  return std::make_shared<const QuadraticPotential>(std::move(stiffness), std::move(linear));
}

}  // namespace fracvi
