#include "fracvi/lagrangian/continuous_residual.hpp"

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <unordered_map>

#include "fracvi/expression/expression.hpp"
#include "fracvi/fractional/riemann_liouville.hpp"

namespace fracvi {

Curve make_expression_curve(const std::vector<std::string>& formulas) {
  struct Parts {
    std::vector<Expression> f, df, d2f;
  };
  auto parts = std::make_shared<Parts>();
  parts->f = parse_expressions(formulas, {"t"});
  for (const auto& e : parts->f) {
    parts->df.push_back(e.derivative(0));
    parts->d2f.push_back(parts->df.back().derivative(0));
  }
  Curve c;
  c.dimension = static_cast<Eigen::Index>(formulas.size());
  c.evaluate = [parts](double t, int order, Eigen::Ref<Eigen::MatrixXd> out) {
    const double args[] = {t};
    for (std::size_t i = 0; i < parts->f.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      out(r, 0) = parts->f[i](args);
      if (order >= 1) out(r, 1) = parts->df[i](args);
      if (order >= 2) out(r, 2) = parts->d2f[i](args);
    }
  };
  return c;
}

namespace {

// 1/Γ(−α), zero at the poles α = 0 and α = 1.
double reciprocal_gamma_negative(double alpha) {
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
  }

  struct Node {
    double dist_a = 0.0, dist_b = 0.0;  // τ − a and b − τ, each exact where it matters
    Eigen::VectorXd z;                  // V(τ), 6d
    Eigen::VectorXd rate;               // V'(τ), 6d; fractional blocks only if rate_fractional
    bool rate_fractional = false;
    LagrangianDerivatives der;  // only with a Lagrangian
  };

  /// The node at distance s from a (key of the x-equation's outer quadrature).
  Node& from_a(double s) { return lookup(from_a_, s, length_ - s, true); }
  /// The node at distance r from b (key of the y-equation's outer quadrature).
  Node& from_b(double r) { return lookup(from_b_, length_ - r, r, false); }

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
    if (inserted) fill(dist_a, dist_b, keyed_by_a, it->second);
    return it->second;
  }

  // Component i of the order-th derivative of x̂(σ) = x(a + σ) or y̌(ρ) = y(b − ρ).
  double x_hat(int order, Eigen::Index i, double sigma) const {
    Eigen::MatrixXd v(d_, order + 1);
    x_.evaluate(a_ + sigma, order, v);
    return v(i, order);
  }
  double y_check(int order, Eigen::Index i, double rho) const {
    Eigen::MatrixXd v(d_, order + 1);
    y_.evaluate(b_ - rho, order, v);
    return order % 2 == 0 ? v(i, order) : -v(i, order);  // d/dρ = −d/dτ
  }

  void fill(double dist_a, double dist_b, bool keyed_by_a, Node& n) {
    const Eigen::Index d = d_;
    const double tau = keyed_by_a ? a_ + dist_a : b_ - dist_b;
    n.dist_a = dist_a;
    n.dist_b = dist_b;
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
          alpha_, Side::kLeft, [&](double s) { return x_hat(0, i, s); },
          [&](double s) { return x_hat(1, i, s); }, 0.0, length_, dist_a, tol_);
      n.z(5 * d + i) = rl_derivative(
          alpha_, Side::kLeft, [&](double r) { return y_check(0, i, r); },
          [&](double r) { return y_check(1, i, r); }, 0.0, length_, dist_b, tol_);
    }
    if (lagrangian_ != nullptr) lagrangian_->derivatives(tau, n.z, n.der);
  }

  // d/dτ D^α_−x = D^α_−(x') + x(a)(τ−a)^{−1−α}/Γ(−α) and d/dτ D^α_+y = D^α_+(y') −
  // y(b)(b−τ)^{−1−α}/Γ(−α) (header comment), both with the terminal at 0 as above.
  void add_fractional_rate(Node& n) {
    const Eigen::Index d = d_;
    for (Eigen::Index i = 0; i < d; ++i) {
      double left = rl_derivative(
          alpha_, Side::kLeft, [&](double s) { return x_hat(1, i, s); },
          [&](double s) { return x_hat(2, i, s); }, 0.0, length_, n.dist_a, tol_);
      if (rgamma_ != 0.0 && x_at_a_(i) != 0.0)
        left += x_at_a_(i) * std::pow(n.dist_a, -1.0 - alpha_) * rgamma_;
      // D^α_+(y')(τ) = D^α_−[ρ ↦ y'(b − ρ)](r) = −D^α_−(y̌')(r).
      double right = -rl_derivative(
          alpha_, Side::kLeft, [&](double r) { return y_check(1, i, r); },
          [&](double r) { return y_check(2, i, r); }, 0.0, length_, n.dist_b, tol_);
      if (rgamma_ != 0.0 && y_at_b_(i) != 0.0)
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
  // Node-based containers: references to nodes stay valid while the caches grow.
  std::unordered_map<double, Node> from_a_, from_b_;
};

void check_arguments(const char* where, const Lagrangian* lagrangian, double alpha, const Curve& x,
                     const Curve& y, double a, double b, double t,
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

}  // namespace

PhasePoint<double> phase_point_on_curves(double alpha, const Curve& x, const Curve& y, double a,
                                         double b, double t,
                                         const ContinuousResidualOptions& options) {
  check_arguments("phase_point_on_curves", nullptr, alpha, x, y, a, b, t, options);
  PhaseCurve curve(nullptr, alpha, x, y, a, b, options.tolerance);
  return PhasePoint<double>::from_flat(t, curve.from_a(t - a).z);
}

namespace {

[[noreturn]] void unbounded(const std::string& what, double t) {
  throw std::domain_error(
      "fractional_el_residual: " + what + " at t = " + std::to_string(t) +
      ". With Riemann-Liouville operators D^alpha_- x is unbounded at t = a unless x(a) = 0 "
      "(D^alpha_+ y at t = b unless y(b) = 0); the functions under D^alpha in FracEL must be "
      "finite there (shift the coordinates so that x(a) = y(b) = 0)");
}

}  // namespace

ContinuousElResidual fractional_el_residual(const Lagrangian& lagrangian, double alpha,
                                            const Curve& x, const Curve& y, double a, double b,
                                            double t, const ContinuousResidualOptions& options) {
  check_arguments("fractional_el_residual", &lagrangian, alpha, x, y, a, b, t, options);
  const Eigen::Index d = x.dimension;
  PhaseCurve curve(&lagrangian, alpha, x, y, a, b, options.tolerance);
  const double s = t - a, r = b - t, len = curve.length();
  ContinuousElResidual res;
  res.x_equation.resize(d);
  res.y_equation.resize(d);
  try {
    PhaseCurve::Node& here = curve.from_a(s);
    res.point = PhasePoint<double>::from_flat(t, here.z);
    const Eigen::VectorXd g = here.der.gradient;
    for (Eigen::Index i = 0; i < d; ++i) {
      // FracEL:-  ∂L/∂x − d/dt ∂L/∂ẋ + D^α_−(∂L/∂D^α_+y), the outer operator at distance s from a.
      const Eigen::Index row_dy = 5 * d + i;
      const double memory_x = rl_derivative(
          alpha, Side::kLeft, [&](double u) { return curve.from_a(u).der.gradient(row_dy); },
          [&](double u) { return curve.gradient_rate(curve.from_a(u), row_dy); }, 0.0, len, s,
          options.tolerance);
      res.x_equation(i) = g(i) - curve.gradient_rate(here, 2 * d + i) + memory_x;
      // FracEL:+  ∂L/∂y − d/dt ∂L/∂ẏ + D^α_+(∂L/∂D^α_−x), reflected: D^α_− in ρ = b − τ.
      const Eigen::Index row_dx = 4 * d + i;
      const double memory_y = rl_derivative(
          alpha, Side::kLeft, [&](double u) { return curve.from_b(u).der.gradient(row_dx); },
          [&](double u) { return -curve.gradient_rate(curve.from_b(u), row_dx); }, 0.0, len, r,
          options.tolerance);
      res.y_equation(i) = g(d + i) - curve.gradient_rate(here, 3 * d + i) + memory_y;
    }
  } catch (const std::runtime_error& e) {  // Boost's quadrature met a non-finite integrand
    unbounded(std::string("a quadrature failed (") + e.what() + ")", t);
  }
  for (Eigen::Index i = 0; i < d; ++i) {
    if (!std::isfinite(res.x_equation(i)))
      unbounded("the x-equation, component " + std::to_string(i + 1) + ", is not finite", t);
    if (!std::isfinite(res.y_equation(i)))
      unbounded("the y-equation, component " + std::to_string(i + 1) + ", is not finite", t);
  }
  return res;
}

}  // namespace fracvi
