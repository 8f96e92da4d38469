// The phase curve V(τ) = (x, y, ẋ, ẏ, D^α_−x, D^α_+y)(τ) of `TotalCoord` along given curves, with
// ∇L and ∇²L cached per quadrature node (internal; shared by the residual of `FracEL` and the
// action `ActFunc` with its first variation).
#pragma once

#include <Eigen/Dense>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "fracvi/fractional/riemann_liouville.hpp"
#include "fracvi/lagrangian/continuous_residual.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"

namespace fracvi::internal {

// 1/Γ(−α), zero at the poles α = 0 and α = 1.
inline double reciprocal_gamma_negative(double alpha) {
  if (alpha <= 0.0 || alpha >= 1.0) return 0.0;
  return 1.0 / boost::math::tgamma(-alpha);
}

// The phase curve V(τ), its derivative V'(τ) where needed, and ∇L, ∇²L along it, cached per node.
//
// Every fractional derivative is taken with its terminal moved to 0 (reflected for D^α_+):
//   D^α_− f(τ) = D^α_− f̂(s), f̂(σ) = f(a + σ), s = τ − a;
//   D^α_+ f(τ) = D^α_− f̌(r), f̌(ρ) = f(b − ρ), r = b − τ        (substitute τ' = b − ρ in `RL`).
// rl_derivative() is exact about distances from a terminal at 0 (riemann_liouville.hpp: abscissas
// a + δ are rounded to the grid of a otherwise, costing |c|·ulp(a)^{1−α} ≈ 1e-8 for α = 1/2).
// The outer quadrature of each equation hands out exact distances from its own terminal, and the
// nodes keep both distances, so the singular behaviour near either terminal is resolved exactly.
class PhaseCurve {
 public:
  PhaseCurve(const Lagrangian* lagrangian, double alpha, const Curve& x, const Curve& y, double a,
             double b, double tolerance)
      : lagrangian_(lagrangian),
        alpha_(alpha),
        x_(x),
        y_(y),
        a_(a),
        b_(b),
        length_(b - a),
        tol_(tolerance),
        d_(x.dimension),
        rgamma_(reciprocal_gamma_negative(alpha)) {
    Eigen::MatrixXd va(d_, 1), vb(d_, 1);
    x_.evaluate(a, 0, va);
    y_.evaluate(b, 0, vb);
    x_at_a_ = va.col(0);
    y_at_b_ = vb.col(0);
    // The endpoint singularities exist only for 0 < α < 1: D^0 is the identity and D^1_± = ±d/dt.
    const bool fractional = alpha > 0.0 && alpha < 1.0;
    split_x_ = fractional && x_at_a_.cwiseAbs().maxCoeff() != 0.0;
    split_y_ = fractional && y_at_b_.cwiseAbs().maxCoeff() != 0.0;
  }

  /// Which fractional blocks of a node hold the regular part only (see EndpointSingularity).
  enum class Split { kNone, kX, kY };

  struct Node {
    double dist_a = 0.0, dist_b = 0.0;  // τ − a and b − τ, each exact where it matters
    Split split = Split::kNone;
    Eigen::VectorXd z;     // V(τ), 6d
    Eigen::VectorXd rate;  // V'(τ), 6d; fractional blocks only if rate_fractional
    bool rate_fractional = false;
    LagrangianDerivatives der;  // only with a Lagrangian
  };

  /// The node at distance s from a (key of the x-equation's outer quadrature). Its D^α_−x block
  /// is the regular part D^α_−(x − x(a)) (the whole of D^α_−x when x(a) = 0).
  Node& from_a(double s) { return lookup(from_a_, s, length_ - s, true); }
  /// The node at distance r from b (key of the y-equation's outer quadrature). Its D^α_+y block
  /// is the regular part D^α_+(y − y(b)).
  Node& from_b(double r) { return lookup(from_b_, length_ - r, r, false); }
  /// The whole phase point V(τ) at distance s from a, both singular parts included.
  Node whole(double s) {
    Node n;
    fill(s, length_ - s, true, Split::kNone, n);
    return n;
  }
  /// The same at distance r from b (exact distance to b, where D^α_+y is singular).
  Node whole_from_b(double r) {
    Node n;
    fill(length_ - r, r, false, Split::kNone, n);
    return n;
  }

  /// Whether D^α_−x (resp. D^α_+y) has an endpoint singularity to split off: 0 < α < 1 and
  /// x(a) ≠ 0 (resp. y(b) ≠ 0).
  [[nodiscard]] bool split_x() const { return split_x_; }
  [[nodiscard]] bool split_y() const { return split_y_; }
  [[nodiscard]] const Eigen::VectorXd& x_at_a() const { return x_at_a_; }
  [[nodiscard]] const Eigen::VectorXd& y_at_b() const { return y_at_b_; }

  /// d/dτ of ∇L component `row` (row ≥ 2d) along the curve at the node.
  double gradient_rate(Node& n, Eigen::Index row) {
    const auto h_row = n.der.hessian.row(row);
    if (!n.rate_fractional && h_row.tail(2 * d_).cwiseAbs().maxCoeff() != 0.0) {
      add_fractional_rate(n);
    }
    double s = n.der.time_gradient(row - 2 * d_);
    for (Eigen::Index j = 0; j < 6 * d_; ++j) {
      if (h_row(j) != 0.0) s += h_row(j) * n.rate(j);
    }
    return s;
  }

  [[nodiscard]] double length() const { return length_; }

 private:
  Node& lookup(std::unordered_map<double, Node>& cache, double dist_a, double dist_b,
               bool keyed_by_a) {
    auto [it, inserted] = cache.try_emplace(keyed_by_a ? dist_a : dist_b);
    if (inserted) {
      const Split split = keyed_by_a ? (split_x_ ? Split::kX : Split::kNone)
                                     : (split_y_ ? Split::kY : Split::kNone);
      fill(dist_a, dist_b, keyed_by_a, split, it->second);
    }
    return it->second;
  }

  // Component i of the order-th derivative of x̂(σ) = x(a + σ) or y̌(ρ) = y(b − ρ). With
  // `regular`, the value (order 0) is taken relative to the terminal value, x̂(σ) − x(a) resp.
  // y̌(ρ) − y(b): rl_derivative() reads f only at its terminal, so D^α of the shifted function is
  // the regular part D^α_−(x − x(a)) exactly, without subtracting the singular term numerically.
  double x_hat(int order, Eigen::Index i, double sigma, bool regular = false) const {
    Eigen::MatrixXd v(d_, order + 1);
    x_.evaluate(a_ + sigma, order, v);
    return order == 0 && regular ? v(i, 0) - x_at_a_(i) : v(i, order);
  }
  double y_check(int order, Eigen::Index i, double rho, bool regular = false) const {
    Eigen::MatrixXd v(d_, order + 1);
    y_.evaluate(b_ - rho, order, v);
    if (order == 0) return regular ? v(i, 0) - y_at_b_(i) : v(i, 0);
    return order % 2 == 0 ? v(i, order) : -v(i, order);  // d/dρ = −d/dτ
  }

  void fill(double dist_a, double dist_b, bool keyed_by_a, Split split, Node& n) {
    const Eigen::Index d = d_;
    const double tau = keyed_by_a ? a_ + dist_a : b_ - dist_b;
    const bool regular_x = split == Split::kX, regular_y = split == Split::kY;
    n.dist_a = dist_a;
    n.dist_b = dist_b;
    n.split = split;
    Eigen::MatrixXd xv(d, 3), yv(d, 3);
    x_.evaluate(tau, 2, xv);
    y_.evaluate(tau, 2, yv);
    n.z.resize(6 * d);
    n.rate.setZero(6 * d);
    n.z.segment(0, d) = xv.col(0);
    n.z.segment(d, d) = yv.col(0);
    n.z.segment(2 * d, d) = xv.col(1);
    n.z.segment(3 * d, d) = yv.col(1);
    n.rate.segment(0, d) = xv.col(1);
    n.rate.segment(d, d) = yv.col(1);
    n.rate.segment(2 * d, d) = xv.col(2);
    n.rate.segment(3 * d, d) = yv.col(2);
    for (Eigen::Index i = 0; i < d; ++i) {
      n.z(4 * d + i) = rl_derivative(
          alpha_, Side::kLeft, [&](double s) { return x_hat(0, i, s, regular_x); },
          [&](double s) { return x_hat(1, i, s); }, 0.0, length_, dist_a, tol_);
      n.z(5 * d + i) = rl_derivative(
          alpha_, Side::kLeft, [&](double r) { return y_check(0, i, r, regular_y); },
          [&](double r) { return y_check(1, i, r); }, 0.0, length_, dist_b, tol_);
    }
    if (lagrangian_ != nullptr) lagrangian_->derivatives(tau, n.z, n.der);
  }

  // d/dτ D^α_−x = D^α_−(x') + x(a)(τ−a)^{−1−α}/Γ(−α) and d/dτ D^α_+y = D^α_+(y') −
  // y(b)(b−τ)^{−1−α}/Γ(−α) (header comment), both with the terminal at 0 as above. The second
  // terms are the rates of the singular parts: a block that holds the regular part only omits it.
  void add_fractional_rate(Node& n) {
    const Eigen::Index d = d_;
    for (Eigen::Index i = 0; i < d; ++i) {
      double left = rl_derivative(
          alpha_, Side::kLeft, [&](double s) { return x_hat(1, i, s); },
          [&](double s) { return x_hat(2, i, s); }, 0.0, length_, n.dist_a, tol_);
      if (rgamma_ != 0.0 && x_at_a_(i) != 0.0 && n.split != Split::kX)
        left += x_at_a_(i) * std::pow(n.dist_a, -1.0 - alpha_) * rgamma_;
      // D^α_+(y')(τ) = D^α_−[ρ ↦ y'(b − ρ)](r) = −D^α_−(y̌')(r).
      double right = -rl_derivative(
          alpha_, Side::kLeft, [&](double r) { return y_check(1, i, r); },
          [&](double r) { return y_check(2, i, r); }, 0.0, length_, n.dist_b, tol_);
      if (rgamma_ != 0.0 && y_at_b_(i) != 0.0 && n.split != Split::kY)
        right -= y_at_b_(i) * std::pow(n.dist_b, -1.0 - alpha_) * rgamma_;
      n.rate(4 * d + i) = left;
      n.rate(5 * d + i) = right;
    }
    n.rate_fractional = true;
  }

  const Lagrangian* lagrangian_;
  double alpha_;
  const Curve& x_;
  const Curve& y_;
  double a_, b_, length_, tol_;
  Eigen::Index d_;
  double rgamma_;
  Eigen::VectorXd x_at_a_, y_at_b_;
  bool split_x_ = false, split_y_ = false;
  // Node-based containers: references to nodes stay valid while the caches grow.
  std::unordered_map<double, Node> from_a_, from_b_;
};

inline void check_arguments(const char* where, const Lagrangian* lagrangian, double alpha,
                            const Curve& x, const Curve& y, double a, double b, double t,
                            const ContinuousResidualOptions& options) {
  const std::string w(where);
  if (!(alpha >= 0.0 && alpha <= 1.0)) {
    throw std::invalid_argument(w + ": alpha = " + std::to_string(alpha) + " must be in [0, 1]");
  }
  if (!(std::isfinite(a) && std::isfinite(b) && a < b)) {
    throw std::invalid_argument(w + ": [a, b] = [" + std::to_string(a) + ", " + std::to_string(b) +
                                "] must be finite with a < b");
  }
  if (!(t >= a && t <= b)) {
    throw std::invalid_argument(w + ": t = " + std::to_string(t) + " is outside [a, b] = [" +
                                std::to_string(a) + ", " + std::to_string(b) + "]");
  }
  if (!x.evaluate || !y.evaluate || x.dimension < 1 || x.dimension != y.dimension) {
    throw std::invalid_argument(w + ": the curves x (dimension " + std::to_string(x.dimension) +
                                ") and y (dimension " + std::to_string(y.dimension) +
                                ") must be set and have the same dimension >= 1");
  }
  if (lagrangian != nullptr && lagrangian->dimension() != x.dimension) {
    throw std::invalid_argument(w + ": the curves have dimension " + std::to_string(x.dimension) +
                                ", the Lagrangian " + std::to_string(lagrangian->dimension()));
  }
  if (!(options.tolerance > 0.0)) {
    throw std::invalid_argument(w + ": tolerance = " + std::to_string(options.tolerance) +
                                " must be positive");
  }
}

/// fractional_el_residual() at the point given by its distances s = t − a and r = b − t (both
/// exact as far as the caller knows them; arguments not checked). For outer quadratures over
/// [a, b] whose abscissas near an end are known only as distances.
ContinuousElResidual fractional_el_residual_at(const Lagrangian& lagrangian, double alpha,
                                               const Curve& x, const Curve& y, double a, double b,
                                               double s, double r,
                                               const ContinuousResidualOptions& options);

}  // namespace fracvi::internal
