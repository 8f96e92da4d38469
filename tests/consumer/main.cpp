// Downstream use of an installed fracvi: x'' + 0.2 x' + x = 0 against its closed form.
#include <cmath>
#include <cstdio>
#include <fracvi/integrate/integrator.hpp>

int main() {
  fracvi::InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.2);
  p.model.alpha = 0.5;
  p.model.potential = fracvi::make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 10.0;
  p.steps = 10000;
  const fracvi::Solution s = fracvi::integrate(p);
  const double w = std::sqrt(1.0 - 0.01);  // damped frequency
  const double exact = std::exp(-0.1 * 10.0) * (std::cos(w * 10.0) + 0.1 / w * std::sin(w * 10.0));
  const double error = std::abs(s.x(static_cast<Eigen::Index>(p.steps), 0) - exact);
  std::printf("consumer: %s, |x(10) - exact| = %.3e\n", s.ok() ? "success" : "failure", error);
  return s.ok() && error < 1e-3 ? 0 : 1;  // first order, h = 1e-3
}
