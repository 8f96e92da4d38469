// Shared helpers for the integrator tests: reference solutions; the potentials are in
// ../support/test_potentials.hpp, the problem set-ups shared with the scheme suite in
// ../support/test_problems.hpp; observed orders come from the one shared fit, test::fit_order
// (../support/order_fit.hpp).
#pragma once

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/model/potential.hpp"

#include "../support/order_fit.hpp"
#include "../support/test_potentials.hpp"

namespace fracvi::test {

inline constexpr double kEps = std::numeric_limits<double>::epsilon();

/// Least-squares slope of y against x (plain linear fit).
inline double linear_slope(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/// Round-off bound of the energy balance error max_k |E_k + W_k − E_0|: W is a sum of N terms and
/// the momenta carry O(ε‖p‖) errors per step, so the error grows at most like N ε (max|E| +
/// max|W|).
inline double balance_tolerance(const Solution& sol) {
  const double scale = sol.energy.cwiseAbs().maxCoeff() + sol.dissipated.cwiseAbs().maxCoeff();
  return static_cast<double>(sol.steps_done) * kEps * scale;
}

/// Exact solution of M x'' + R x' + K x = f̂ cos(ωt) (α = 1/2, linear) at times t: the matrix
/// exponential of the first-order system augmented with the harmonic oscillator (cos ωt, sin ωt).
/// Returns a (times × 2d) matrix of (x, v).
inline Eigen::MatrixXd damped_oscillator_exact(const Eigen::MatrixXd& M, const Eigen::MatrixXd& R,
                                               const Eigen::MatrixXd& K,
                                               const Eigen::VectorXd& fhat, double omega,
                                               const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                                               const std::vector<double>& times) {
  const Eigen::Index d = M.rows();
  const Eigen::MatrixXd minv = M.inverse();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * d + 2, 2 * d + 2);
  A.block(0, d, d, d).setIdentity();
  A.block(d, 0, d, d) = -minv * K;
  A.block(d, d, d, d) = -minv * R;
  A.block(d, 2 * d, d, 1) = minv * fhat;
  A(2 * d, 2 * d + 1) = -omega;
  A(2 * d + 1, 2 * d) = omega;
  Eigen::VectorXd z0(2 * d + 2);
  z0 << x0, v0, 1.0, 0.0;
  Eigen::MatrixXd out(static_cast<Eigen::Index>(times.size()), 2 * d);
  for (std::size_t i = 0; i < times.size(); ++i) {
    const Eigen::MatrixXd e = (A * times[i]).exp();
    out.row(static_cast<Eigen::Index>(i)) = (e * z0).head(2 * d).transpose();
  }
  return out;
}

/// Reference for α = 1/2 models with a time-independent potential: Boost.Odeint dopri5 with
/// dense output at abs/rel tolerance `tol`, sampled at `times`. Returns (times × 2d) of (x, v).
inline Eigen::MatrixXd dopri5_reference(const MechanicalModel& model, const Eigen::VectorXd& x0,
                                        const Eigen::VectorXd& v0, const std::vector<double>& times,
                                        double tol = 1e-12) {
  using State = std::vector<double>;
  namespace odeint = boost::numeric::odeint;
  const Eigen::Index d = x0.size();
  const Eigen::LLT<Eigen::MatrixXd> llt(model.mass.to_dense());
  const Eigen::MatrixXd damping = model.damping.to_dense();
  auto rhs = [&](const State& z, State& dz, double t) {
    const Eigen::Map<const Eigen::VectorXd> x(z.data(), d), v(z.data() + d, d);
    Eigen::VectorXd force = -damping * v;
    if (model.potential) {
      Eigen::VectorXd g(d);
      model.potential->gradient(x, t, g);
      force -= g;
    }
    if (model.forcing) {
      Eigen::VectorXd f(d);
      model.forcing(t, f);
      force += f;
    }
    Eigen::Map<Eigen::VectorXd>(dz.data(), d) = v;
    Eigen::Map<Eigen::VectorXd>(dz.data() + d, d) = llt.solve(force);
  };
  State z(static_cast<std::size_t>(2 * d));
  Eigen::Map<Eigen::VectorXd>(z.data(), d) = x0;
  Eigen::Map<Eigen::VectorXd>(z.data() + d, d) = v0;
  Eigen::MatrixXd out(static_cast<Eigen::Index>(times.size()), 2 * d);
  std::size_t row = 0;
  auto observer = [&](const State& s, double) {
    out.row(static_cast<Eigen::Index>(row++)) =
        Eigen::Map<const Eigen::VectorXd>(s.data(), 2 * d).transpose();
  };
  odeint::integrate_times(odeint::make_dense_output(tol, tol, odeint::runge_kutta_dopri5<State>()),
                          rhs, z, times.begin(), times.end(), 1e-3, observer);
  return out;
}

/// max over the rows of `reference` (sampled at every `stride`-th grid point) of ‖x_k − x(t_k)‖_∞.
inline double max_position_error(const Solution& sol, const Eigen::MatrixXd& reference,
                                 std::size_t stride) {
  const Eigen::Index d = sol.x.cols();
  double err = 0.0;
  for (Eigen::Index i = 0; i < reference.rows(); ++i) {
    const auto k = static_cast<Eigen::Index>(static_cast<std::size_t>(i) * stride);
    err = std::max(err, (sol.x.row(k) - reference.row(i).head(d)).cwiseAbs().maxCoeff());
  }
  return err;
}

inline double max_velocity_error(const Solution& sol, const Eigen::MatrixXd& reference,
                                 std::size_t stride) {
  const Eigen::Index d = sol.x.cols();
  double err = 0.0;
  for (Eigen::Index i = 0; i < reference.rows(); ++i) {
    const auto k = static_cast<Eigen::Index>(static_cast<std::size_t>(i) * stride);
    err = std::max(err, (sol.v.row(k) - reference.row(i).tail(d)).cwiseAbs().maxCoeff());
  }
  return err;
}

/// Times t0 + i (T − t0)/n, i = 0 … n.
inline std::vector<double> uniform_times(double t0, double t_end, std::size_t n) {
  std::vector<double> t(n + 1);
  for (std::size_t i = 0; i <= n; ++i) {
    t[i] = t0 + static_cast<double>(i) * ((t_end - t0) / static_cast<double>(n));
  }
  return t;
}

}  // namespace fracvi::test
