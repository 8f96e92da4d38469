// Non-conservative forces f(x, v, t) of the mechanical model M x'' + R D^{2α} x + ∇U(x, t) =
// f(t) + f(x, x', t): feedback control, van der Pol's negative damping, nonlinear friction,
// follower forces.
//
// They have no potential, so the discrete variational principle cannot produce them; the schemes
// add them the discrete Lagrange–d'Alembert way (Marsden & West 2001, §3.2): the virtual work
// ∫ f·δx dt over a step is replaced by a quadrature along the scheme's interpolant, which gives
// the left and right discrete forces f⁻_k, f⁺_k added to the discrete Euler–Lagrange equations
// (docs/theory/forces.md derives them for each scheme). Newton's method on those equations needs
// the exact Jacobians ∂f/∂x and ∂f/∂v at one point, which is what this interface provides.
//
// Thread safety and allocation as for Potential (potential.hpp): const methods, safe to call
// concurrently; the step loop stays allocation-free when they do not allocate.
#pragma once

#include <Eigen/Dense>

namespace fracvi {

/// f : R^d × R^d × R → R^d, with its Jacobians.
class StateForce {
 public:
  virtual ~StateForce() = default;

  /// The dimension d of x, v and f.
  [[nodiscard]] virtual Eigen::Index dimension() const = 0;
  /// out = f(x, v, t); out has size d on entry.
  virtual void value(const Eigen::Ref<const Eigen::VectorXd>& x,
                     const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                     Eigen::Ref<Eigen::VectorXd> out) const = 0;
  /// out = f(x, v, t), dx = ∂f/∂x, dv = ∂f/∂v (d × d, row i the gradient of f_i; exact).
  virtual void jacobians(const Eigen::Ref<const Eigen::VectorXd>& x,
                         const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                         Eigen::Ref<Eigen::VectorXd> out, Eigen::Ref<Eigen::MatrixXd> dx,
                         Eigen::Ref<Eigen::MatrixXd> dv) const = 0;
};

}  // namespace fracvi
