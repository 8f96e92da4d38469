#include "fracvi/fractional/riemann_liouville.hpp"
#include "fracvi/core/error.hpp"

#include <algorithm>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace fracvi {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Shortest round-trip text of a double, so messages show 1e-08 and not 0.000000.
std::string format(double value) {
  return format_number(value);
}

[[noreturn]] void fail(const char* function, const char* name, double value,
                       const std::string& rule) {
  throw std::invalid_argument(std::string(function) + ": " + name + " = " + format(value) +
                              " violates " + rule);
}

void require_finite(const char* function, const char* name, double value) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(function) + ": " + name + " = " + format(value) +
                                " is not finite");
  }
}

void validate_common(const char* function, double alpha, const RealFunction& f,
                     const RealFunction& df, double a, double b, double tolerance) {
  if (!(alpha >= 0.0 && alpha <= 1.0)) fail(function, "alpha", alpha, "0 <= alpha <= 1");
  require_finite(function, "a", a);
  require_finite(function, "b", b);
  if (!(a < b)) fail(function, "a", a, "a < b (b = " + format(b) + ")");
  if (!(tolerance > 0.0 && std::isfinite(tolerance)))
    fail(function, "tolerance", tolerance, "0 < tolerance < inf");
  if (!f) throw std::invalid_argument(std::string(function) + ": f is an empty std::function");
  if (!df) throw std::invalid_argument(std::string(function) + ": df is an empty std::function");
}

// One quadrature object per thread. Construction is cheap (the first rows are tabulated for
// double), and Boost 1.74 publishes a lazily added refinement row (m_committed_refinements) before
// filling it, so sharing one instance between threads would race. Nested use on one thread (an
// integrand that calls rl_derivative again, as in `DoubleFracInt`) is safe: the table of rows is
// sized once in the constructor, so extending a deeper row never moves the rows an outer call is
// reading. Not const: Boost spells `auto integrate(...) -> decltype(...) const`, which makes the
// return type const, not the member function.
boost::math::quadrature::tanh_sinh<double>& integrator() {
  thread_local boost::math::quadrature::tanh_sinh<double> instance;
  return instance;
}

// The well-conditioned form of `RL` (file comment of the header), with σ = +1 for D^α_− (terminal
// c = a, τ = t − u) and σ = −1 for D^α_+ (terminal c = b, τ = t + u):
//   D^α_σ f(t) = f(c) s^{−α}/Γ(1−α) + σ [ f'(t) s^{1−α}/Γ(2−α) + 1/Γ(1−α) I ],
//   I = ∫_0^s u^{−α} (f'(τ) − f'(t)) du,
// where s = |t − c| is passed by the caller, as exactly as it knows it. t and s are both passed
// because neither can be recomputed from the other without rounding.
double rl_core(double alpha, Side side, const RealFunction& f, const RealFunction& df, double a,
               double b, double t, double s, double tolerance) {
  const bool left = side == Side::kLeft;
  const double sigma = left ? 1.0 : -1.0;
  const double c = left ? a : b;

  if (alpha == 0.0) return f(t);  // D^0 is the identity; skip the quadrature.

  // 1/Γ(1−α) = z/Γ(1+z) and 1/Γ(2−α) = 1/Γ(1+z) with z = 1 − α ∈ [0, 1): no pole at α = 1
  // (boost::math::tgamma would raise one), and Γ(1+z) ∈ [0.88, 1] is harmless. z is exact for
  // α ≥ 1/2 (Sterbenz).
  const double z = 1.0 - alpha;
  const double gamma_1pz = 1.0 + boost::math::tgamma1pm1(z);
  const double rgamma_1ma = z / gamma_1pz;  // 1/Γ(1−α), exactly 0 at α = 1
  const double rgamma_2ma = 1.0 / gamma_1pz;

  const double dft = df(t);
  double result = sigma * dft * std::pow(s, z) * rgamma_2ma;  // 0^0 = 1 gives ±f'(t) at α = 1
  if (rgamma_1ma == 0.0) return result;                       // α = 1: D^1_± f = ±f'

  const double fc = f(c);
  if (s == 0.0) {
    // At the terminal: f(c)·s^{−α} is ±∞ unless f(c) = 0, when the limit of every term is 0.
    return fc == 0.0 ? 0.0 : std::copysign(kInf, fc);
  }
  if (!std::isfinite(fc)) {
    // An integrable singularity at the terminal (log t, t^{−1/2} at c = 0): f(c) does not exist,
    // so the form above does not apply. The Marchaud form needs only f integrable near c and
    // smooth near t (issue 14: D^{1/2} log t at 0.5 was −∞, exit 0; true 0.5531):
    //   D^α_σ f(t) = [f(t) s^{−α} + α ∫_0^s g(u) u^{−1−α} du] / Γ(1−α),  g(u) = f(t) − f(t − σu).
    // On [0, s/2] g cancels (relative error ε/u), so that half is integrated by parts:
    //   α ∫_0^{h} g u^{−1−α} du = −g(h) h^{−α} + σ ∫_0^{h} f'(t − σu) u^{−α} du,  h = s/2;
    // on [s/2, s] the singularity of f at the terminal is integrable as it stands.
    const double ft = f(t);
    const double h = 0.5 * s;
    const double g_h = ft - f(t - sigma * h);
    const auto near_t = [&](double u) -> double { return df(t - sigma * u) * std::pow(u, -alpha); };
    const auto near_c = [&](double x, double xc) -> double {
      // x ∈ (h, s); xc is the distance to the nearer end: to the terminal when x is near s.
      const double u = x;
      double tau = t - sigma * u;
      if (xc > 0.0) {
        tau = c + sigma * xc;
        if (sigma * (tau - c) <= 0.0) return 0.0;
      }
      return (ft - f(tau)) * std::pow(u, -1.0 - alpha);
    };
    const double first = integrator().integrate(near_t, 0.0, h, tolerance);
    double error = 0.0, l1 = 0.0;
    const double second = integrator().integrate(near_c, h, s, tolerance, &error, &l1);
    // A singularity that is not integrable (1/t) leaves tanh–sinh without convergence: refuse it
    // rather than return the number it stopped at.
    if (!(error <= 1e-8 * l1) || !std::isfinite(second)) {
      throw std::domain_error("f is not integrable at the terminal " + format(c) + " (f(" +
                              format(c) + ") = " + format(fc) +
                              "; the quadrature did not converge: error estimate " + format(error) +
                              " against " + format(l1) + ")");
    }
    return rgamma_1ma *
           (ft * std::pow(s, -alpha) - g_h * std::pow(h, -alpha) + sigma * first + alpha * second);
  }
  result += fc * std::pow(s, -alpha) * rgamma_1ma;

  // I by tanh–sinh. Boost's two-argument form gives xc = −u near u = 0 (so u is
  // exact where u^{−α} is large) and xc = s − u near u = s (so τ = c + σ·xc is the exact offset
  // from the terminal, which matters when f' is singular there). Points that round onto the
  // terminal are skipped: for integrable f' their measure is below ulp(c).
  const auto integrand = [&](double x, double xc) -> double {
    double u, tau;
    if (xc < 0.0) {
      u = -xc;
      tau = t - sigma * u;
    } else {
      u = x;
      tau = c + sigma * xc;
      if (sigma * (tau - c) <= 0.0) return 0.0;
    }
    return std::pow(u, -alpha) * (df(tau) - dft);
  };
  const double integral = integrator().integrate(integrand, 0.0, s, tolerance);
  result += sigma * rgamma_1ma * integral;
  return result;
}

}  // namespace

double rl_derivative(double alpha, Side side, const RealFunction& f, const RealFunction& df,
                     double a, double b, double t, double tolerance) {
  constexpr const char* kFunction = "rl_derivative";
  validate_common(kFunction, alpha, f, df, a, b, tolerance);
  require_finite(kFunction, "t", t);
  if (!(t >= a && t <= b))
    fail(kFunction, "t", t, "a <= t <= b (a = " + format(a) + ", b = " + format(b) + ")");
  const double s = side == Side::kLeft ? t - a : b - t;
  return rl_core(alpha, side, f, df, a, b, t, s, tolerance);
}

double rl_derivative_at_distance(double alpha, Side side, const RealFunction& f,
                                 const RealFunction& df, double a, double b, double distance,
                                 double tolerance) {
  constexpr const char* kFunction = "rl_derivative_at_distance";
  validate_common(kFunction, alpha, f, df, a, b, tolerance);
  require_finite(kFunction, "distance", distance);
  if (!(distance >= 0.0 && distance <= b - a))
    fail(kFunction, "distance", distance, "0 <= distance <= b - a = " + format(b - a));
  // Rounding of c ± distance can step over the other end by an ulp; clamp.
  const double t = side == Side::kLeft ? std::min(a + distance, b) : std::max(b - distance, a);
  return rl_core(alpha, side, f, df, a, b, t, distance, tolerance);
}

namespace {

void validate_power(const char* function, double order, double p) {
  require_finite(function, "order", order);
  require_finite(function, "p", p);
  if (!(order >= 0.0)) fail(function, "order", order, "order >= 0");
  if (!(p > -1.0)) fail(function, "p", p, "p > -1 (the power must be integrable at the terminal)");
}

}  // namespace

double rl_power_coefficient(double order, double p) {
  validate_power("rl_power_coefficient", order, p);
  const double z = p + 1.0 - order;
  // Γ(p+1)/Γ(p+1−order) as one ratio: accurate and free of overflow for large p.
  if (z > 0.0) return boost::math::tgamma_delta_ratio(p + 1.0, -order);
  if (std::floor(z) == z) return 0.0;  // a zero of 1/Γ
  // z ∈ (−n, −n+1): 1/Γ(z) = z(z+1)···(z+n−1)/Γ(z+n) with z + n ∈ (0, 1).
  const double n = std::ceil(-z);
  double rising = 1.0;
  for (double k = 0.0; k < n; k += 1.0) rising *= z + k;
  return boost::math::tgamma(p + 1.0) * rising / boost::math::tgamma(z + n);
}

double rl_derivative_power(double order, Side side, double p, double a, double b, double t) {
  constexpr const char* kFunction = "rl_derivative_power";
  validate_power(kFunction, order, p);
  require_finite(kFunction, "a", a);
  require_finite(kFunction, "b", b);
  require_finite(kFunction, "t", t);
  if (!(a < b)) fail(kFunction, "a", a, "a < b (b = " + format(b) + ")");
  if (!(t >= a && t <= b))
    fail(kFunction, "t", t, "a <= t <= b (a = " + format(a) + ", b = " + format(b) + ")");
  const double coefficient = rl_power_coefficient(order, p);
  if (coefficient == 0.0) return 0.0;
  const double d = side == Side::kLeft ? t - a : b - t;
  const double exponent = p - order;
  if (d == 0.0) {
    if (exponent > 0.0) return 0.0;
    if (exponent == 0.0) return coefficient;
    return std::copysign(kInf, coefficient);
  }
  return coefficient * std::pow(d, exponent);
}

}  // namespace fracvi
