// The forcing as exact moments against a scheme's interpolant (method.load = "moments",
// IntegratorOptions::load; internal to the schemes).
#pragma once

#include <Eigen/Dense>
#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"

namespace fracvi::internal {

// The Galerkin moments of the forcing on interval n (method.load = "moments"): for the basis
// polynomials ℓ_k of a scheme's interpolant on [t_n, t_{n+1}] (given by their monomial
// coefficients), the d × K blocks
//   value(:, k) = ∫_0^1 ℓ_k(σ) f(t_n + σh) dσ,   slope(:, k) = ∫_0^1 ℓ_k'(σ) f(t_n + σh) dσ.
// The Lobatto schemes use their s Lagrange polynomials; the midpoint schemes the constant 1 (the
// cell average of f, their midpoint force).
// The first interval by tanh–sinh quadrature (Boost.Math), per component and basis function: it
// never evaluates f at the end points and converges for integrable end-point singularities such as
// f ~ t^{−1/2} at t_0. Beyond, f is analytic near [t_n, t_{n+1}] for the forcings in question
// (a singularity at t_0 lies one interval away), and 20-point Gauss–Legendre (f at 20 points,
// combined with the precomputed ℓ_k and ℓ_k' values) is exact to round-off.
class ForcingMoments {
 public:
  static constexpr int kPoints = 20;

  /// basis(k, m), slope(k, m): the coefficients of σ^m in ℓ_k and ℓ_k'. `forcing` must outlive
  /// this.
  ForcingMoments(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& slope, const Forcing& forcing,
                 Eigen::Index d)
      : basis_(basis), slope_(slope), forcing_(forcing), samples_(d, kPoints), scratch_(d) {
    const Eigen::Index functions = basis.rows();
    using Rule = boost::math::quadrature::gauss<double, kPoints>;
    const auto& abscissa = Rule::abscissa();
    const auto& weights = Rule::weights();
    std::vector<std::pair<double, double>> rule;  // on [−1, 1]: ±x_i (20 points, even: no 0)
    for (std::size_t i = 0; i < abscissa.size(); ++i) {
      rule.emplace_back(-abscissa[i], weights[i]);
      if (abscissa[i] != 0.0) rule.emplace_back(abscissa[i], weights[i]);
    }
    value_weights_.setZero(kPoints, functions);
    slope_weights_.setZero(kPoints, functions);
    for (int q = 0; q < kPoints; ++q) {
      sigma_(q) = 0.5 * (rule[static_cast<std::size_t>(q)].first + 1.0);
      const double w = 0.5 * rule[static_cast<std::size_t>(q)].second;
      for (Eigen::Index k = 0; k < functions; ++k) {
        value_weights_(q, k) = w * polynomial(basis_, k, sigma_(q));
        slope_weights_(q, k) = w * polynomial(slope_, k, sigma_(q));
      }
    }
  }

  void operator()(double tn, double h, bool first, Eigen::Ref<Eigen::MatrixXd> value,
                  Eigen::Ref<Eigen::MatrixXd> slope) {
    if (!first) {
      for (int q = 0; q < kPoints; ++q) forcing_(tn + sigma_(q) * h, samples_.col(q));
      value.noalias() = samples_ * value_weights_;
      slope.noalias() = samples_ * slope_weights_;
      return;
    }
    for (Eigen::Index k = 0; k < basis_.rows(); ++k) {
      for (Eigen::Index i = 0; i < samples_.rows(); ++i) {
        auto component = [&](const Eigen::MatrixXd& coefficients) {
          return tanh_sinh_.integrate(
              [&](double sigma) {
                forcing_(tn + sigma * h, scratch_);
                return polynomial(coefficients, k, sigma) * scratch_(i);
              },
              0.0, 1.0);
        };
        value(i, k) = component(basis_);
        slope(i, k) = component(slope_);
      }
    }
  }

 private:
  // Σ_m coefficients(k, m) σ^m (Horner).
  static double polynomial(const Eigen::MatrixXd& coefficients, Eigen::Index k, double sigma) {
    double value = 0.0;
    for (Eigen::Index m = coefficients.cols() - 1; m >= 0; --m)
      value = value * sigma + coefficients(k, m);
    return value;
  }
  Eigen::MatrixXd basis_, slope_;
  const Forcing& forcing_;
  Eigen::Matrix<double, kPoints, 1> sigma_;
  Eigen::MatrixXd value_weights_, slope_weights_, samples_;
  Eigen::VectorXd scratch_;
  boost::math::quadrature::tanh_sinh<double> tanh_sinh_;
};

/// The cell average f̄_k = ∫_0^1 f(t_k + σh) dσ of the midpoint schemes, as a ForcingMoments with
/// the single basis function 1.
inline ForcingMoments cell_average(const Forcing& forcing, Eigen::Index d) {
  return ForcingMoments(Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1), forcing, d);
}

/// f at the midpoint t_k + h/2 (load = "pointwise") or its cell average over [t_k, t_{k+1}]
/// (load = "moments") into `out`: the midpoint schemes' force of cell k.
class MidpointForce {
 public:
  MidpointForce(const InitialValueProblem& problem, ForcingLoad load)
      : problem_(problem), value_(problem.model.dimension(), 1), slope_(value_) {
    if (load == ForcingLoad::kMoments && problem.model.forcing) {
      average_ = std::make_unique<ForcingMoments>(
          cell_average(problem.model.forcing, problem.model.dimension()));
    }
  }
  /// Cell k (in x-time), whose midpoint time the caller computes (each scheme its own way, so
  /// that the pointwise path is unchanged to the last bit).
  void operator()(std::size_t k, double midpoint_time, Eigen::Ref<Eigen::VectorXd> out) {
    if (!average_) {
      problem_.model.forcing(midpoint_time, out);
      return;
    }
    (*average_)(problem_.time(static_cast<double>(k)), problem_.step_size(), k == 0, value_,
                slope_);
    out = value_.col(0);
  }

 private:
  const InitialValueProblem& problem_;
  std::unique_ptr<ForcingMoments> average_;
  Eigen::MatrixXd value_, slope_;
};

}  // namespace fracvi::internal
