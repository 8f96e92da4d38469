#include "fracvi/lagrangian/continuous_residual.hpp"

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <unordered_map>

#include "fracvi/core/error.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/fractional/riemann_liouville.hpp"
#include "phase_curve.hpp"

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

using internal::check_arguments;
using internal::PhaseCurve;

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
  return internal::fractional_el_residual_at(lagrangian, alpha, x, y, a, b, t - a, b - t, options);
}

ContinuousElResidual internal::fractional_el_residual_at(const Lagrangian& lagrangian, double alpha,
                                                         const Curve& x, const Curve& y, double a,
                                                         double b, double s, double r,
                                                         const ContinuousResidualOptions& options) {
  const Eigen::Index d = x.dimension;
  PhaseCurve curve(&lagrangian, alpha, x, y, a, b, options.tolerance);
  const double len = curve.length();
  const double t = s <= r ? a + s : b - r;
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
    PhaseCurve::Node here = s <= r ? curve.whole(s) : curve.whole_from_b(r);
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
