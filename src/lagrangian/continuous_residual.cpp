#include "fracvi/lagrangian/continuous_residual.hpp"

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <unordered_map>

#include "fracvi/core/error.hpp"
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
  return PhasePoint<double>::from_flat(t, curve.whole(t - a).z);
}

namespace {

std::string vector_text(const Eigen::VectorXd& v) {
  std::string out = "(";
  for (Eigen::Index i = 0; i < v.size(); ++i) out += (i ? ", " : "") + format_number(v(i));
  return out + ")";
}

[[noreturn]] void unbounded(const std::string& what, double t) {
  throw std::domain_error("fractional_el_residual: " + what + " at t = " + format_number(t) +
                          ". The functions under D^alpha in FracEL must be finite at the "
                          "operator's terminal once the endpoint singularities x(a)(t-a)^(-alpha)/"
                          "Gamma(1-alpha) and y(b)(b-t)^(-alpha)/Gamma(1-alpha) are split off");
}

// The endpoint singularity of one equation of `FracEL` (Riemann–Liouville, 0 < α < 1).
//
// For x(a) ≠ 0, D^α_−x = S(τ) + D^α_−(x − x(a)) with S(τ) = x(a)(τ−a)^{−α}/Γ(1−α) unbounded at a
// and the second part bounded. The x-equation needs D^α_− of G = ∂L/∂D^α_+y. If G is affine in
// D^α_−x with a coefficient block C = ∂²L/∂D^α_+y∂D^α_−x that is constant along the curve (the
// mechanical L: C = −R), then G(V) = G(V_reg) + C S, V_reg the phase point with D^α_−x replaced
// by its regular part, and by linearity and the closed form of `RL` on powers
// (D^α_−(τ−a)^{−α} = Γ(1−α)/Γ(1−2α) (t−a)^{−2α}),
//
//   D^α_− G(t) = D^α_− [G(V_reg)](t) + C x(a) (t−a)^{−2α}/Γ(1−2α).
//
// The first term is bounded data for rl_derivative() again; the second is exact (and vanishes at
// α = 1/2, where D^{1/2}_−D^{1/2}_− x = ẋ for bounded x: `DoubleFracInt`). The y-equation is the
// mirror: D^α_+ of ∂L/∂D^α_−x, y(b) and (b−t)^{−2α}. The structure is checked, not assumed: at
// every node of the outer quadrature C must equal its value at the terminal, and at t the split
// must reproduce G(V).
class EndpointSingularity {
 public:
  // rows: the block of G (5d for the x-equation, 4d for the y-equation); cols: the singular block.
  EndpointSingularity(bool active, const char* equation, const char* curve_name, const char* block,
                      Eigen::Index d, Eigen::Index rows, Eigen::Index cols,
                      const Eigen::VectorXd& terminal_value, double alpha)
      : active_(active),
        equation_(equation),
        curve_name_(curve_name),
        block_(block),
        d_(d),
        rows_(rows),
        cols_(cols),
        terminal_value_(terminal_value),
        alpha_(alpha) {}

  [[nodiscard]] bool active() const { return active_; }
  [[nodiscard]] bool coupled() const {
    return coupling_.size() > 0 && coupling_.cwiseAbs().maxCoeff() != 0.0;
  }

  // At its own terminal (dist = 0) the outer operator is a limit. Where G depends on the singular
  // block, G − G(terminal) behaves like C·ẋ(a)(t−a)^{1−α}/Γ(2−α) (not C¹), and D^α of that tends
  // to 0, C·ẋ(a) or ∞ for α below, at or above 1/2: the quadrature form, which assumes G ∈ C¹,
  // cannot take it. Refuse rather than print a wrong value (the earlier code returned 0 there,
  // missing R ẋ(a) in the damped oscillator at α = 1/2).
  void check_not_at_terminal(double dist, double t) const {
    if (dist != 0.0 || !coupled() || alpha_ <= 0.0 || alpha_ >= 1.0) return;
    throw std::domain_error(
        std::string("fractional_el_residual: t = ") + format_number(t) +
        " is the terminal of the outer D^alpha in the " + equation_ +
        ", whose argument depends on " + block_ +
        " (which behaves like (distance)^(1 - alpha) there): its value at the terminal is "
        "a limit the quadrature cannot take; evaluate at t strictly inside (a, b)");
  }

  // C from the node at the terminal (its singular block holds the regular part, 0 there).
  void set_coupling(const PhaseCurve::Node& terminal) {
    coupling_ = terminal.der.hessian.block(rows_, cols_, d_, d_);
    tolerance_ = kStructureTolerance * (1.0 + coupling_.cwiseAbs().maxCoeff());
  }

  // Throws unless the coupling block at the node equals C.
  void check_node(const PhaseCurve::Node& n, double t) const {
    const Eigen::MatrixXd c = n.der.hessian.block(rows_, cols_, d_, d_);
    const double change = (c - coupling_).cwiseAbs().maxCoeff();
    if (change > tolerance_) {
      structure_error(
          "the second derivative of L coupling the two fractional blocks is constant along the "
          "curve",
          "it changes by " + format_number(change), t);
    }
  }

  // C x(a) (resp. C y(b)), component i.
  [[nodiscard]] double coefficient(Eigen::Index i) const {
    return coupling_.row(i).dot(terminal_value_);
  }

  // The closed-form part C x(a) dist^{−2α}/Γ(1−2α) of the outer operator, component i.
  [[nodiscard]] double closed_form(Eigen::Index i, double dist, double length, double t) const {
    const double k = coefficient(i);
    if (k == 0.0) return 0.0;
    // rl_derivative_power(α, ·, −α) = Γ(1−α)/Γ(1−2α) dist^{−2α}, exactly 0 at α = 1/2.
    const double value = k / boost::math::tgamma(1.0 - alpha_) *
                         rl_derivative_power(alpha_, Side::kLeft, -alpha_, 0.0, length, dist);
    if (!std::isfinite(value)) {
      throw std::domain_error(
          std::string("fractional_el_residual: the ") + equation_ + " is unbounded at t = " +
          format_number(t) + ": " + curve_name_ + " = " + vector_text(terminal_value_) +
          " != 0 gives " + block_ + " the Riemann-Liouville term " + format_number(k) +
          " * dist^(-2 alpha)/Gamma(1 - 2 alpha) (alpha = " + format_number(alpha_) +
          "), infinite at the terminal" +
          (alpha_ > 0.5 ? "; with 2 alpha > 1 it is not even integrable there, so the "
                          "Riemann-Liouville problem with this initial value is ill-posed"
                        : "") +
          ". It is finite for t strictly inside (a, b)");
    }
    return value;
  }

  // At t: G(V) must equal G(V_reg) + C S.
  void check_split(double whole, double regular, double singular_part, Eigen::Index i,
                   double t) const {
    const double scale = std::abs(whole) + std::abs(regular) + std::abs(singular_part);
    const double mismatch = std::abs(whole - regular - singular_part);
    if (mismatch > kStructureTolerance * (1.0 + scale)) {
      structure_error(
          "the function under the outer D^alpha is affine in it",
          "component " + std::to_string(i + 1) + ", mismatch " + format_number(mismatch), t);
    }
  }

 private:
  [[noreturn]] void structure_error(const std::string& rule, const std::string& found,
                                    double t) const {
    throw std::domain_error(std::string("fractional_el_residual: ") + curve_name_ + " = " +
                            vector_text(terminal_value_) + " != 0 makes the " + block_ +
                            " argument unbounded at its terminal; the " + equation_ +
                            " treats that singularity in closed form only if " + rule +
                            ", and here it is not (" + found + ", t = " + format_number(t) +
                            "). Use curves with " + curve_name_ + " = 0");
  }

  // Exact structure (symbolic or AD Hessians of the same polynomial) agrees to round-off; a
  // genuine dependence is O(coefficient × change of the argument), far above this.
  static constexpr double kStructureTolerance = 1e-9;

  bool active_;
  const char* equation_;
  const char* curve_name_;
  const char* block_;
  Eigen::Index d_, rows_, cols_;
  Eigen::VectorXd terminal_value_;
  double alpha_;
  Eigen::MatrixXd coupling_;
  double tolerance_ = 0.0;
};

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
  // x-equation: D^α_− of ∂L/∂D^α_+y (rows 5d..), singular through D^α_−x (cols 4d..) at a.
  EndpointSingularity at_a(curve.split_x(), "x-equation", "x(a)", "D^alpha_- x", d, 5 * d, 4 * d,
                           curve.x_at_a(), alpha);
  // y-equation: D^α_+ of ∂L/∂D^α_−x (rows 4d..), singular through D^α_+y (cols 5d..) at b.
  EndpointSingularity at_b(curve.split_y(), "y-equation", "y(b)", "D^alpha_+ y", d, 4 * d, 5 * d,
                           curve.y_at_b(), alpha);
  try {
    if (alpha > 0.0 && alpha < 1.0) {
      at_a.set_coupling(curve.from_a(0.0));
      at_b.set_coupling(curve.from_b(0.0));
      at_a.check_not_at_terminal(s, t);
      at_b.check_not_at_terminal(r, t);
    }
    PhaseCurve::Node here = curve.whole(s);
    res.point = PhasePoint<double>::from_flat(t, here.z);
    const Eigen::VectorXd g = here.der.gradient;
    // The outer integrands read the nodes keyed by the distance from their terminal, whose
    // singular block holds the regular part only (PhaseCurve::from_a/from_b).
    auto node_a = [&](double u) -> PhaseCurve::Node& {
      PhaseCurve::Node& n = curve.from_a(u);
      if (at_a.active()) at_a.check_node(n, a + u);
      return n;
    };
    auto node_b = [&](double u) -> PhaseCurve::Node& {
      PhaseCurve::Node& n = curve.from_b(u);
      if (at_b.active()) at_b.check_node(n, b - u);
      return n;
    };
    const double rgamma_1ma = alpha < 1.0 ? 1.0 / boost::math::tgamma(1.0 - alpha) : 0.0;
    // D^α_∓ of the gradient row `row` at distance `dist` from the terminal (kept as D^α_− in the
    // distance; `sign` = −1 for the reflected D^α_+), with the endpoint singularity in closed form.
    auto memory = [&](EndpointSingularity& end, auto&& node, Eigen::Index row, Eigen::Index i,
                      double dist, double sign) {
      double value = rl_derivative(
          alpha, Side::kLeft, [&](double u) { return node(u).der.gradient(row); },
          [&](double u) { return sign * curve.gradient_rate(node(u), row); }, 0.0, len, dist,
          options.tolerance);
      if (!end.active()) return value;
      if (dist > 0.0) {
        end.check_split(g(row), node(dist).der.gradient(row),
                        end.coefficient(i) * std::pow(dist, -alpha) * rgamma_1ma, i, t);
      }
      return value + end.closed_form(i, dist, len, t);
    };
    for (Eigen::Index i = 0; i < d; ++i) {
      // FracEL:-  ∂L/∂x − d/dt ∂L/∂ẋ + D^α_−(∂L/∂D^α_+y), the outer operator at distance s from a.
      const double memory_x = memory(at_a, node_a, 5 * d + i, i, s, 1.0);
      res.x_equation(i) = g(i) - curve.gradient_rate(here, 2 * d + i) + memory_x;
      // FracEL:+  ∂L/∂y − d/dt ∂L/∂ẏ + D^α_+(∂L/∂D^α_−x), reflected: D^α_− in ρ = b − τ.
      const double memory_y = memory(at_b, node_b, 4 * d + i, i, r, -1.0);
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
