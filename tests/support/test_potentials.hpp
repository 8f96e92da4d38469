// Potentials shared by the integrator tests (tests/integrate) and the method-parameterised suite
// (tests/schemes): hand-written ones (allocation-free) and the two Duffing functors for
// make_autodiff_potential (fixed size: allocation-free; dynamic size: allocates, the allocation
// tests' control).
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "fracvi/model/potential.hpp"

namespace fracvi::test {

/// Σ_i (1 − cos x_i) g_i + ½ Σ_{i<d−1} k (x_{i+1} − x_i)²: a chain of coupled pendula,
/// hand-written (allocation-free), time-independent.
class PendulumChain final : public Potential {
 public:
  PendulumChain(Eigen::VectorXd gravity, double coupling) : g_(std::move(gravity)), k_(coupling) {}
  [[nodiscard]] Eigen::Index dimension() const override { return g_.size(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    double u = 0.0;
    for (Eigen::Index i = 0; i < x.size(); ++i) u += g_(i) * (1.0 - std::cos(x(i)));
    for (Eigen::Index i = 0; i + 1 < x.size(); ++i)
      u += 0.5 * k_ * (x(i + 1) - x(i)) * (x(i + 1) - x(i));
    return u;
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    for (Eigen::Index i = 0; i < x.size(); ++i) g(i) = g_(i) * std::sin(x(i));
    for (Eigen::Index i = 0; i + 1 < x.size(); ++i) {
      const double s = k_ * (x(i + 1) - x(i));
      g(i + 1) += s;
      g(i) -= s;
    }
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    H.setZero();
    for (Eigen::Index i = 0; i < x.size(); ++i) H(i, i) = g_(i) * std::cos(x(i));
    for (Eigen::Index i = 0; i + 1 < x.size(); ++i) {
      H(i, i) += k_;
      H(i + 1, i + 1) += k_;
      H(i, i + 1) -= k_;
      H(i + 1, i) -= k_;
    }
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }

 private:
  Eigen::VectorXd g_;
  double k_;
};

/// The d = 2 pendula of the integrate tests: g = (9.81, 4), coupling k = 2.
inline std::shared_ptr<const Potential> pendulum_pair() {
  return std::make_shared<const PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0);
}

// A potential (with a sparse Hessian) whose gradient throws from time `from` on: a user's callback
// failing in the middle of a run.
class ThrowingAfter final : public Potential {
 public:
  ThrowingAfter(std::shared_ptr<const Potential> inner, double from)
      : inner_(std::move(inner)), from_(from) {}
  [[nodiscard]] Eigen::Index dimension() const override { return inner_->dimension(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    return inner_->value(x, t);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    if (t > from_) throw std::runtime_error("out of range");
    inner_->gradient(x, t, g);
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> h) const override {
    inner_->hessian(x, t, h);
  }
  [[nodiscard]] bool has_sparse_hessian() const override { return true; }
  [[nodiscard]] std::vector<HessianEntry> hessian_pattern() const override {
    return inner_->hessian_pattern();
  }
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                      std::span<double> values) const override {
    inner_->hessian_values(x, t, values);
  }

 private:
  std::shared_ptr<const Potential> inner_;
  double from_;
};

/// U∘Λ for Theorem 4.3: value U(Λz), gradient Λᵀ∇U(Λz), Hessian Λᵀ∇²U(Λz)Λ.
class TransformedPotential final : public Potential {
 public:
  TransformedPotential(std::shared_ptr<const Potential> inner, Eigen::MatrixXd lambda)
      : inner_(std::move(inner)), lambda_(std::move(lambda)) {}
  [[nodiscard]] Eigen::Index dimension() const override { return lambda_.cols(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& z, double t) const override {
    const Eigen::VectorXd x = lambda_ * z;
    return inner_->value(x, t);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& z, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    const Eigen::VectorXd x = lambda_ * z;
    Eigen::VectorXd gx(x.size());
    inner_->gradient(x, t, gx);
    g.noalias() = lambda_.transpose() * gx;
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& z, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    const Eigen::VectorXd x = lambda_ * z;
    Eigen::MatrixXd hx(x.size(), x.size());
    inner_->hessian(x, t, hx);
    H.noalias() = lambda_.transpose() * hx * lambda_;
  }
  [[nodiscard]] bool has_constant_hessian() const override {
    return inner_->has_constant_hessian();
  }
  [[nodiscard]] bool is_time_dependent() const override { return inner_->is_time_dependent(); }

 private:
  std::shared_ptr<const Potential> inner_;
  Eigen::MatrixXd lambda_;
};

/// U(x) = ½ xᵀKx + (ε/4) Σ x_i⁴ (the power-law problems' cubic spring), hand-written
/// (allocation-free, time-independent).
class CubicSpringPotential final : public Potential {
 public:
  CubicSpringPotential(Eigen::MatrixXd stiffness, double cubic)
      : k_(std::move(stiffness)), eps_(cubic) {}
  [[nodiscard]] Eigen::Index dimension() const override { return k_.rows(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    return 0.5 * x.dot(k_ * x) + 0.25 * eps_ * x.array().pow(4).sum();
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    g.noalias() = k_ * x;
    g.array() += eps_ * x.array().cube();
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
               Eigen::Ref<Eigen::MatrixXd> h) const override {
    h = k_;
    h.diagonal().array() += 3.0 * eps_ * x.array().square();
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }

 private:
  Eigen::MatrixXd k_;
  double eps_;
};

/// ½ (2 + cos t) |x|² + ¼ x_0⁴, d = 2, for make_autodiff_potential<2>: fixed-size duals, so its
/// evaluations do not allocate.
struct Duffing2 {
  template <class T>
  T operator()(const Eigen::Matrix<T, 2, 1>& x, T t) const {
    using std::cos;
    return T(0.5) * (T(2.0) + cos(t)) * (x(0) * x(0) + x(1) * x(1)) +
           T(0.25) * x(0) * x(0) * x(0) * x(0);
  }
};

/// ½ |x|² + ¼ x_0⁴ on dynamic-size vectors, for make_autodiff_potential(…, 2): its duals allocate
/// in every evaluation (autodiff_potential.hpp), the allocation tests' control.
struct DuffingDynamic {
  template <class T>
  T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>& x, T) const {
    return T(0.5) * (x(0) * x(0) + x(1) * x(1)) + T(0.25) * x(0) * x(0) * x(0) * x(0);
  }
};

}  // namespace fracvi::test
