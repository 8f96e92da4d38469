// Published numbers of the higher-order FVIs, reproduced digit for digit (issue: "Reproduce the
// published numbers"; the tables are in docs/verification.md).
//
// fvi-midpoint: x'' + 0.25 x' + x = 0, x(0) = 1, x'(0) = 0.5 on [0, 16], h = 16/N, error = max over
// the grid nodes of |x_k − x(t_k)| against the closed form
//   x(t) = e^{−t/8} (cos ωt + (0.5 + 1/8)/ω sin ωt),  ω = √(1 − 1/64);
// published (Hariz, Jiménez, Ober-Blöbaum; the RKCQ paper's public data): 2.5317e-1 at N = 16 and
// 1.7690e-5 at N = 2048, order 2. The comparison is of the five printed digits.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {
namespace {

std::string five_digits(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4e", value);
  return buf;
}

double midpoint_oscillator_error(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.25);
  p.model.alpha = 0.5;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Constant(1, 0.5);
  p.t_end = 16.0;
  p.steps = steps;
  IntegratorOptions options;
  options.mirror = false;
  const Solution sol = integrate(p, *parse_method("fvi-midpoint"), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  const double omega = std::sqrt(1.0 - 1.0 / 64.0);
  double err = 0.0;
  for (Eigen::Index k = 0; k < sol.x.rows(); ++k) {
    const double t = sol.t(k);
    const double exact =
        std::exp(-t / 8.0) * (std::cos(omega * t) + (0.5 + 0.125) / omega * std::sin(omega * t));
    err = std::max(err, std::abs(sol.x(k, 0) - exact));
  }
  return err;
}

TEST(PublishedNumbers, MidpointFviDampedOscillator) {
  const double coarse = midpoint_oscillator_error(16);
  const double fine = midpoint_oscillator_error(2048);
  std::printf("  fvi-midpoint: %s (published 2.5317e-01) at N = 16, %s (1.7690e-05) at N = 2048\n",
              five_digits(coarse).c_str(), five_digits(fine).c_str());
  EXPECT_EQ(five_digits(coarse), "2.5317e-01");
  EXPECT_EQ(five_digits(fine), "1.7690e-05");
  // Order 2 between them: log(coarse/fine)/log(128).
  EXPECT_NEAR(std::log(coarse / fine) / std::log(128.0), 2.0, 0.05);
}

}  // namespace
}  // namespace fracvi
