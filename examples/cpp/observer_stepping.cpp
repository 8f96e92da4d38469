// Stepping an integrator by hand, with an observer (the Boost.Odeint style of driving a stepper).
//
// A damped pendulum (α = 1/2) is advanced one step at a time; the loop watches the angle and
// stops at the first time the pendulum has settled below 0.05 rad for good, which a fixed-length
// integrate() could not do. A second run uses run(observer) to record the turning points.
//
// Exits non-zero if the invariants do not hold (CI runs it).
#include <cmath>
#include <cstdio>
#include <fracvi/integrate/integrator.hpp>
#include <fracvi/model/autodiff_potential.hpp>
#include <vector>

struct Pendulum {
  template <class T>
  T operator()(const Eigen::Matrix<T, 1, 1>& x, T /*t*/) const {
    using std::cos;
    return T(1.0) - cos(x(0));
  }
};

fracvi::InitialValueProblem pendulum() {
  fracvi::InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Constant(1, 1, 1.0);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.3);
  p.model.alpha = 0.5;
  p.model.potential = fracvi::make_autodiff_potential<1>(Pendulum{}, 1, {.time_dependent = false});
  p.x0 = Eigen::VectorXd::Constant(1, 2.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 100.0;
  p.steps = 10000;
  return p;
}

int main() {
  // [snippet: stepping]
  fracvi::IntegratorOptions options;
  options.mirror = false;  // stepping by hand: no backward mirror run at the end
  fracvi::Integrator integrator(pendulum(), fracvi::fvi_gl(), options);
  double settled_at = -1.0;
  while (integrator.step() == fracvi::Status::kRunning) {
    const fracvi::StepView s = integrator.view();
    // Settled: small angle and too little energy to leave the 0.05 rad band again.
    if (std::abs(s.x(0)) < 0.05 && s.energy < 1.0 - std::cos(0.05)) {
      settled_at = s.t;
      break;
    }
  }
  // [/snippet]
  std::printf("pendulum settled below 0.05 rad at t = %.2f after %zu steps\n", settled_at,
              integrator.steps_done());

  // [snippet: observer]
  std::vector<double> turning_times;
  double previous_v = 0.0;
  fracvi::Integrator recorder(pendulum(), fracvi::fvi_gl(), options);
  recorder.run([&](const fracvi::StepView& s) {
    if (s.k > 0 && previous_v > 0.0 && s.v(0) <= 0.0) turning_times.push_back(s.t);
    previous_v = s.v(0);
  });
  // [/snippet]
  std::printf("%zu right turning points; first at t = %.3f\n", turning_times.size(),
              turning_times.empty() ? -1.0 : turning_times.front());

  const bool ok = settled_at > 0.0 && settled_at < 100.0 && !turning_times.empty() &&
                  recorder.status() == fracvi::Status::kSuccess;
  return ok ? 0 : 1;
}
