// Shared Lagrangians for the tests of fracvi/lagrangian.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/model/expression_potential.hpp"

namespace fracvi::test {

inline constexpr double kEps = std::numeric_limits<double>::epsilon();

/// A genuinely non-mechanical Lagrangian in d = 2 that couples x and y nonlinearly in every block:
/// position-dependent mass, a gyroscopic x–ẏ term, a non-bilinear memory coupling, explicit time
/// dependence. Its text form is kCoupledText (same formula, for the expression engine).
struct Coupled {
  template <class T>
  T operator()(const PhasePoint<T>& p) const {
    using std::cos;
    using std::sin;
    const T mx = T(1.0) + T(0.3) * p.x(0) * p.x(0);
    const T my = T(1.0) + T(0.2) * sin(p.y(1));
    const T kin = T(0.5) * mx * (p.xdot(0) * p.xdot(0) + p.xdot(1) * p.xdot(1)) +
                  T(0.5) * my * (p.ydot(0) * p.ydot(0) + p.ydot(1) * p.ydot(1));
    const T pot = T(1.0) - cos(p.x(0)) + T(0.5) * p.x(1) * p.x(1) + T(1.0) - cos(p.y(0)) +
                  T(0.5) * p.y(1) * p.y(1) + T(0.1) * sin(p.t) * p.x(1) * p.y(0);
    const T bil = T(0.4) * p.dx_alpha(0) * p.dy_alpha(0) + T(0.1) * p.dx_alpha(0) * p.dy_alpha(1) +
                  T(0.1) * p.dx_alpha(1) * p.dy_alpha(0) + T(0.3) * p.dx_alpha(1) * p.dy_alpha(1);
    const T dot = p.dx_alpha(0) * p.dy_alpha(0) + p.dx_alpha(1) * p.dy_alpha(1);
    return kin - pot - bil + T(0.05) * dot * dot + T(0.2) * p.x(0) * p.ydot(1) +
           T(0.1) * p.xdot(0) * p.dx_alpha(1) + T(0.1) * cos(p.t) * p.xdot(1) * p.dy_alpha(0);
  }
};

inline const std::string kCoupledText =
    "0.5*(1 + 0.3*x1^2)*(xdot1^2 + xdot2^2) + 0.5*(1 + 0.2*sin(y2))*(ydot1^2 + ydot2^2)"
    " - (1 - cos(x1) + 0.5*x2^2 + 1 - cos(y1) + 0.5*y2^2 + 0.1*sin(t)*x2*y1)"
    " - (0.4*dx1*dy1 + 0.1*dx1*dy2 + 0.1*dx2*dy1 + 0.3*dx2*dy2)"
    " + 0.05*(dx1*dy1 + dx2*dy2)^2 + 0.2*x1*ydot2 + 0.1*xdot1*dx2 + 0.1*cos(t)*xdot2*dy1";

/// Uniform random vector in [−1, 1]^n (fixed-seed generator passed in).
inline Eigen::VectorXd random_vector(std::mt19937_64& rng, Eigen::Index n, double scale = 1.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v(i) = scale * u(rng);
  return v;
}

/// Two coupled pendula with full M, R, a time-dependent potential and forcing, Riemann–Liouville,
/// on [0.5, t_end]: the mechanical IVP whose trajectory the discrete EL tests and the BVP tests
/// compare against.
inline InitialValueProblem mechanical_ivp(double alpha, double t_end, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
  p.model.alpha = alpha;
  p.model.convention = Convention::kRiemannLiouville;
  p.model.potential = std::make_shared<const ExpressionPotential>(
      2, "9.81*(1 - cos(x1)) + 4*(1 - cos(x2)) + (x2 - x1)^2 + 0.1*t*x1^2");
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = 0.1 * t;
  };
  p.x0 = Eigen::Vector2d(0.4, -0.3);
  p.v0 = Eigen::Vector2d(0.5, 0.8);
  p.t0 = 0.5;
  p.t_end = t_end;
  p.steps = steps;
  return p;
}

}  // namespace fracvi::test
