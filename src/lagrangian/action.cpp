#include "fracvi/lagrangian/action.hpp"

#include <algorithm>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "fracvi/core/error.hpp"
#include "phase_curve.hpp"

namespace fracvi {
namespace {

using internal::PhaseCurve;

constexpr double kEndSkip = 4.0 * std::numeric_limits<double>::epsilon();
// Round-off of a formula such as sin(pi*t/1.5) at t = 1.5.
constexpr double kEndTolerance = 1e-12;

// ∫_a^b f(s, r) dt over [a, b] by tanh–sinh, f given the exact distances s = t − a and r = b − t
// of each abscissa (Boost's two-argument integrand: the complement xc is the signed distance to
// the nearer end). The quadrature object is local: f itself runs the nested quadratures of
// rl_derivative(), which keep their own per-thread object.
template <class F>
double integrate_over(const char* where, double a, double b, double tolerance, F&& f) {
  const double length = b - a;
  boost::math::quadrature::tanh_sinh<double> quadrature;
  const auto integrand = [&](double /*u*/, double uc) {
    // The abscissa u ∈ (0, length) is the distance from a; its complement uc is −u near a and
    // length − u near b, each exact where it is small.
    const double s = uc < 0.0 ? -uc : length - uc;
    const double r = uc < 0.0 ? length - s : uc;
    return f(s, r);
  };
  double value = 0.0;
  try {
    value = quadrature.integrate(integrand, 0.0, length, tolerance);
  } catch (const std::runtime_error& e) {  // Boost met a non-finite integrand value
    throw std::domain_error(std::string(where) +
                            ": the integrand is not finite on (a, b) (the integral does not "
                            "exist as computed): " +
                            e.what());
  }
  if (!std::isfinite(value)) {
    throw std::domain_error(std::string(where) + ": the integral over [" + format_number(a) + ", " +
                            format_number(b) + "] is not finite (" + format_number(value) + ")");
  }
  return value;
}

void check_variations(const char* where, const Curve& x, const Curve& delta_x,
                      const Curve& delta_y) {
  if (!delta_x.evaluate || !delta_y.evaluate || delta_x.dimension != x.dimension ||
      delta_y.dimension != x.dimension) {
    throw std::invalid_argument(std::string(where) + ": the variations delta_x (dimension " +
                                std::to_string(delta_x.dimension) + ") and delta_y (dimension " +
                                std::to_string(delta_y.dimension) +
                                ") must be set and have the curves' dimension " +
                                std::to_string(x.dimension));
  }
}

// fracel_pairing() leaves out end layers of width kEndSkip·(b − a) (see there), which is
// accurate only if the variations vanish to second order at the ends: value and first derivative.
void check_end_layer(const Variation& v, double a, double b) {
  Eigen::MatrixXd value(v.delta_x.dimension, 2);
  for (const auto& [curve, name] : {std::pair{&v.delta_x, "delta_x"}, {&v.delta_y, "delta_y"}}) {
    for (double t : {a, b}) {
      curve->evaluate(t, 1, value);
      const double worst = value.cwiseAbs().maxCoeff();
      if (worst > kEndTolerance) {
        throw std::invalid_argument(
            std::string("fracel_pairing: ") + name + " or its derivative is " +
            format_number(worst) + " at t = " + format_number(t) +
            "; the pairing needs variations that vanish to second order at a and b (value and "
            "first derivative within " +
            format_number(kEndTolerance) +
            "), because the residual, singular like (t-a)^(-1-alpha) there, is integrated "
            "without the last few ulps of [a, b]");
      }
    }
  }
}

}  // namespace

double action(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y, double a,
              double b, const ContinuousResidualOptions& options) {
  internal::check_arguments("action", &lagrangian, alpha, x, y, a, b, a, options);
  PhaseCurve curve(nullptr, alpha, x, y, a, b, options.tolerance);
  return integrate_over("action", a, b, options.tolerance, [&](double s, double r) {
    const PhaseCurve::Node n = s <= r ? curve.whole(s) : curve.whole_from_b(r);
    return lagrangian.value(s <= r ? a + s : b - r, n.z);
  });
}

double action_variation(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y,
                        const Curve& delta_x, const Curve& delta_y, double a, double b,
                        const ContinuousResidualOptions& options) {
  internal::check_arguments("action_variation", &lagrangian, alpha, x, y, a, b, a, options);
  check_variations("action_variation", x, delta_x, delta_y);
  PhaseCurve curve(nullptr, alpha, x, y, a, b, options.tolerance);
  // δV is the phase point of the variation curves: the same linear maps (`HatGamma`).
  PhaseCurve variation(nullptr, alpha, delta_x, delta_y, a, b, options.tolerance);
  Eigen::VectorXd gradient(kPhaseBlockCount * x.dimension);
  return integrate_over("action_variation", a, b, options.tolerance, [&](double s, double r) {
    const bool near_a = s <= r;
    const PhaseCurve::Node n = near_a ? curve.whole(s) : curve.whole_from_b(r);
    const PhaseCurve::Node dn = near_a ? variation.whole(s) : variation.whole_from_b(r);
    // d/dε L(t, V + ε δV) at ε = 0 = ∇L(t, V)·δV, exact (V is affine in ε).
    lagrangian.gradient(near_a ? a + s : b - r, n.z, gradient);
    return gradient.dot(dn.z);
  });
}

std::vector<double> fracel_pairing(const Lagrangian& lagrangian, double alpha, const Curve& x,
                                   const Curve& y, const std::vector<Variation>& variations,
                                   double a, double b, const ContinuousResidualOptions& options) {
  internal::check_arguments("fracel_pairing", &lagrangian, alpha, x, y, a, b, a, options);
  const Eigen::Index d = x.dimension;
  for (const Variation& v : variations) {
    check_variations("fracel_pairing", x, v.delta_x, v.delta_y);
    check_end_layer(v, a, b);
  }
  // The residual at a node does not depend on the variation: one cache for all of them (the
  // quadratures of the same integrand family visit largely the same nodes).
  std::unordered_map<double, ContinuousElResidual> residuals;
  Eigen::MatrixXd dx(d, 1), dy(d, 1);
  std::vector<double> out;
  for (const Variation& v : variations) {
    out.push_back(
        integrate_over("fracel_pairing", a, b, options.tolerance, [&](double s, double r) {
          // The end layers of width kEndSkip·(b − a) are left out: there the residual's inner
          // quadratures (of the equation whose operator runs to the far end) can no longer tell the
          // near end from t, as distances (b − a) − distance have lost all digits. With variations
          // vanishing to second order at the ends (check_end_layer) the layer holds at most
          // ~ δ^{2−α} |c| of the integral (E ~ (t−a)^{−1−α} at worst, through the rate of
          // D^α_−x): below 1e-18 at α ≤ 0.9.
          if (std::min(s, r) <= kEndSkip * (b - a)) return 0.0;
          const double t = s <= r ? a + s : b - r;
          v.delta_x.evaluate(t, 0, dx);
          v.delta_y.evaluate(t, 0, dy);
          auto [it, inserted] = residuals.try_emplace(s <= r ? s : -r);
          if (inserted) {
            it->second =
                internal::fractional_el_residual_at(lagrangian, alpha, x, y, a, b, s, r, options);
          }
          return it->second.x_equation.dot(dx.col(0)) + it->second.y_equation.dot(dy.col(0));
        }));
  }
  return out;
}

double fracel_pairing(const Lagrangian& lagrangian, double alpha, const Curve& x, const Curve& y,
                      const Curve& delta_x, const Curve& delta_y, double a, double b,
                      const ContinuousResidualOptions& options) {
  return fracel_pairing(lagrangian, alpha, x, y, {Variation{delta_x, delta_y}}, a, b, options)
      .front();
}

}  // namespace fracvi
