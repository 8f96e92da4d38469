#include "baseline_support.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <numbers>

#include "fracvi/core/error.hpp"
#include "fracvi/model/potential.hpp"

namespace fracvi::internal {

LinearTestProblem linear_test_problem(const InitialValueProblem& problem) {
  LinearTestProblem test;
  const Eigen::Index d = problem.model.dimension();
  test.mass = problem.model.mass.symmetric_part().to_dense();
  test.damping = problem.model.is_undamped() ? Eigen::MatrixXd::Zero(d, d)
                                             : problem.model.damping.symmetric_part().to_dense();
  test.stiffness = Eigen::MatrixXd::Zero(d, d);
  if (const auto& u = problem.model.potential) {
    u->hessian(problem.x0, problem.t0, test.stiffness);
    test.stiffness = 0.5 * (test.stiffness + test.stiffness.transpose()).eval();
    test.exact = u->has_constant_hessian();
    // Negative curvature at x_0 (a pendulum started above its pivot) is a physical instability,
    // not a numerical one, but the trajectory soon meets curvature of about that magnitude with
    // the other sign: K enters with the magnitudes of its modes, K = MΦ|Λ|ΦᵀM (a linear
    // problem's K is positive semidefinite and unchanged).
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> modes(test.stiffness,
                                                                          test.mass);
    if (modes.eigenvalues().minCoeff() < 0.0) {
      const Eigen::MatrixXd phi_m = test.mass * modes.eigenvectors();  // K = MΦΛΦᵀM
      test.stiffness = phi_m * modes.eigenvalues().cwiseAbs().asDiagonal() * phi_m.transpose();
    }
  }
  return test;
}

namespace {

// arg(b/a) ∈ (−π, π].
double angle_between(std::complex<double> a, std::complex<double> b) {
  return std::arg(b / a);
}

}  // namespace

int characteristic_roots_inside(const CharacteristicSymbol& symbol, Eigen::Index d) {
  // The contour |ξ| = r, r = 1 − 1e-7: a root of modulus within 1e-7 of the unit circle (a neutral
  // mode, e.g. ξ = 1 for a singular K) is not counted; it would grow by at most a factor
  // (1 + 1e-7)^N. Angles: geometric near θ = 0, where (1 − ξ)^{2α} varies on the scale 1 − r,
  // uniform elsewhere, and bisected wherever det A turns by more than 0.3 rad.
  constexpr double kRadius = 1.0 - 1e-7;
  Eigen::MatrixXcd a(d, d);
  auto det = [&](double theta) {
    symbol(std::polar(kRadius, theta), a);
    return Eigen::PartialPivLU<Eigen::MatrixXcd>(a).determinant();
  };
  std::vector<double> thetas;
  for (int i = 0; i <= 200; ++i) thetas.push_back(1e-10 * std::pow(1e8, i / 200.0));
  for (int i = 1; i <= 2048; ++i) thetas.push_back(1e-2 + (std::numbers::pi - 1e-2) * i / 2048.0);
  // The closed loop −π … π through θ = 0.
  std::vector<double> loop;
  for (auto it = thetas.rbegin(); it != thetas.rend(); ++it) loop.push_back(-*it);
  loop.push_back(0.0);
  loop.insert(loop.end(), thetas.begin(), thetas.end());
  std::function<double(double, std::complex<double>, double, std::complex<double>, int)> turn =
      [&](double ta, std::complex<double> da, double tb, std::complex<double> db, int depth) {
        const double step = angle_between(da, db);
        if (std::abs(step) < 0.3 || depth > 40) return step;
        const double tm = 0.5 * (ta + tb);
        const std::complex<double> dm = det(tm);
        return turn(ta, da, tm, dm, depth + 1) + turn(tm, dm, tb, db, depth + 1);
      };
  double total = 0.0;
  std::complex<double> previous = det(loop.front());
  for (std::size_t i = 1; i < loop.size(); ++i) {
    const std::complex<double> next = det(loop[i]);
    total += turn(loop[i - 1], previous, loop[i], next, 0);
    previous = next;
  }
  return static_cast<int>(std::lround(total / (2.0 * std::numbers::pi)));
}

double largest_stable_step(const std::function<bool(double)>& stable, double h_start) {
  double lo = 0.0, hi = 0.0;
  if (stable(h_start)) {
    lo = h_start;
    for (int i = 0; i < 60 && hi == 0.0; ++i) {
      const double h = lo * 2.0;
      if (stable(h)) {
        lo = h;
      } else {
        hi = h;
      }
    }
    if (hi == 0.0) return std::numeric_limits<double>::infinity();
  } else {
    hi = h_start;
    for (int i = 0; i < 60 && lo == 0.0; ++i) {
      const double h = hi * 0.5;
      if (stable(h)) {
        lo = h;
      } else {
        hi = h;
      }
    }
    if (lo == 0.0) return 0.0;
  }
  while (hi - lo > 1e-10 * hi) {
    const double mid = std::sqrt(lo * hi);
    if (stable(mid)) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

StabilityBound step_bound(const InitialValueProblem& problem, double largest_step, bool sharp,
                          const std::string& what) {
  StabilityBound bound;
  const double h = problem.step_size();
  bound.largest_step = largest_step;
  bound.sharp = sharp;
  bound.stable = h < largest_step;
  if (std::isinf(largest_step)) {
    bound.rule = what + " holds for every h";
  } else if (largest_step == 0.0) {
    bound.rule = what + " holds for no h > 0 (h = " + format_number(h) + ")";
  } else {
    bound.rule =
        what + " holds for h < " + format_number(largest_step) + " (h = " + format_number(h) + ")";
  }
  return bound;
}

StabilityBound unchecked_bound(const InitialValueProblem& problem) {
  return StabilityBound{
      .stable = true,
      .largest_step = std::numeric_limits<double>::infinity(),
      .sharp = false,
      .rule = "not checked for d = " + std::to_string(problem.model.dimension()) + " > " +
              std::to_string(kMaxStabilityDimension) +
              " (the linear test problem is formed densely); the run's health checks remain"};
}

ExternalWork::ExternalWork(const InitialValueProblem& problem)
    : problem_(problem),
      has_forcing_(static_cast<bool>(problem.model.forcing)),
      u_time_dependent_(problem.model.potential && problem.model.potential->is_time_dependent()) {
  const Eigen::Index d = problem.model.dimension();
  f_now_.setZero(d);
  f_next_.setZero(d);
  mid_.setZero(d);
  if (has_forcing_) problem.model.forcing(problem.t0, f_now_);
}

double ExternalWork::step(std::size_t k, const Eigen::VectorXd& x_k,
                          const Eigen::VectorXd& x_next) {
  const double t_k = problem_.time(static_cast<double>(k));
  const double t_next = problem_.time(static_cast<double>(k + 1));
  double work = 0.0;
  if (has_forcing_) {
    problem_.model.forcing(t_next, f_next_);
    mid_ = x_next - x_k;
    work += 0.5 * (f_now_.dot(mid_) + f_next_.dot(mid_));
    f_now_.swap(f_next_);
  }
  if (u_time_dependent_) {
    mid_ = 0.5 * (x_k + x_next);
    work +=
        problem_.model.potential->value(mid_, t_next) - problem_.model.potential->value(mid_, t_k);
  }
  return work;
}

}  // namespace fracvi::internal
