// Manufactured power-law solutions x(t) = c t^p with zero initial data (p > 2, so x(0) = x'(0) = 0
// and the RL and Caputo derivatives coincide, DESIGN §2) for
//
//     M x'' + R D^β x + K x + ε x∘x∘x = f(t),
//
// using the closed form D^β t^p = Γ(p+1)/Γ(p+1−β) t^{p−β} (valid for both conventions when
// p > 1 ≥ ⌈β⌉ − 1). The forcing is chosen so that x is exact:
//     f(t) = M c p(p−1) t^{p−2} + R c Γ(p+1)/Γ(p+1−β) t^{p−β} + K c t^p + ε c³ t^{3p}.
// ε = 0 is the linear problem; ε ≠ 0 gives the cubic potential U(x) = ½xᵀKx + (ε/4) Σ x_i⁴.
#pragma once

#include <Eigen/Dense>
#include <cmath>

namespace fracvi::test {

struct PowerLawSolution {
  Eigen::MatrixXd mass;
  Eigen::MatrixXd damping;
  Eigen::MatrixXd stiffness;
  double beta = 0.5;   ///< damping order 2α
  double cubic = 0.0;  ///< ε
  double p = 3.0;      ///< exponent, p > 2
  Eigen::VectorXd c;   ///< amplitude

  [[nodiscard]] Eigen::VectorXd x(double t) const { return c * std::pow(t, p); }
  [[nodiscard]] Eigen::VectorXd v(double t) const { return c * (p * std::pow(t, p - 1.0)); }

  /// ∇U(x) = K x + ε x∘x∘x.
  [[nodiscard]] Eigen::VectorXd grad_potential(const Eigen::VectorXd& y) const {
    return stiffness * y + cubic * y.array().cube().matrix();
  }

  /// D^β x(t) = c Γ(p+1)/Γ(p+1−β) t^{p−β}.
  [[nodiscard]] Eigen::VectorXd fractional_derivative(double t) const {
    return c * (std::tgamma(p + 1.0) / std::tgamma(p + 1.0 - beta) * std::pow(t, p - beta));
  }

  [[nodiscard]] Eigen::VectorXd forcing(double t) const {
    return mass * c * (p * (p - 1.0) * std::pow(t, p - 2.0)) + damping * fractional_derivative(t) +
           grad_potential(x(t));
  }
};

}  // namespace fracvi::test
