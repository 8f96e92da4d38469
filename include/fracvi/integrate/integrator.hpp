// The Integrator drives any registered scheme (DESIGN §4.1): it validates the problem, the method
// and the options, refuses a problem the method does not apply to or whose step is beyond the
// method's stability bound (before step 1), and owns what every scheme shares — the stored rows,
// the observer, status and messages, stopping, and the energy diagnostics E_k, W_k, E_k + W_k − E_0
// (the scheme keeps W_k, its own discrete energy account; solution.hpp). The scheme's equations
// live in its Stepper (fracvi/schemes/stepper.hpp), one file each, listed in the method registry
// (fracvi/schemes/registry.hpp). For the paper's scheme see src/schemes/cq_midpoint_stepper.hpp.
//
// The step loop does not allocate and does not throw: numerical failure ends the run with a
// Status and a message, and everything computed so far is kept.
//
// Usage — one call:
//   fracvi::Solution sol = fracvi::integrate(problem);                     // fvi-gl
//   fracvi::Solution sol = fracvi::integrate(problem, fracvi::fvi_bdf2());  // any scheme
// or stepped by hand (Boost.Odeint style):
//   fracvi::Integrator integ(problem);
//   while (integ.step() == fracvi::Status::kRunning) { use(integ.position()); }
//   fracvi::Solution sol = integ.take_solution();
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <utility>

#include "fracvi/core/newton_options.hpp"
#include "fracvi/integrate/solution.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {

/// The state after a step, as the observer sees it (views into the solution storage; valid until
/// the next step).
struct StepView {
  std::size_t k;
  double t;
  Eigen::Map<const Eigen::VectorXd> x;
  Eigen::Map<const Eigen::VectorXd> v;
  double energy;
  double dissipated;
  double balance;
};

class Integrator {
 public:
  /// Validates problem, method and options, checks that the method applies and that the step is
  /// within its stability bound (check_applicable; throws ValidationError), and reserves all
  /// storage: the solution's rows and the stepper's workspace. Computes the state at k = 0.
  explicit Integrator(InitialValueProblem problem, Method method = fvi_gl(),
                      IntegratorOptions options = {});
  ~Integrator();
  Integrator(Integrator&&) noexcept;
  Integrator& operator=(Integrator&&) noexcept;
  Integrator(const Integrator&) = delete;
  Integrator& operator=(const Integrator&) = delete;

  /// Advances one step (k → k+1). Returns kRunning while steps remain, kSuccess after the last
  /// one, or a failure status; once finished or failed it does nothing and returns the status.
  /// Never allocates, never throws.
  Status step() noexcept;

  /// Steps to the end. observer(const StepView&) is called for the current state if no step has
  /// been taken yet, then after every completed step.
  template <class Observer>
  Status run(Observer&& observer) {
    if (steps_done() == 0) observer(view());
    Status s = status();
    while (s == Status::kRunning) {
      s = step();
      if (s == Status::kRunning || s == Status::kSuccess) observer(view());
    }
    return s;
  }
  Status run() {
    return run([](const StepView&) {});
  }

  [[nodiscard]] Status status() const;
  [[nodiscard]] std::size_t steps_done() const;
  [[nodiscard]] std::size_t steps_total() const;
  [[nodiscard]] double time() const;                                 ///< t_k
  [[nodiscard]] Eigen::Map<const Eigen::VectorXd> position() const;  ///< x_k
  [[nodiscard]] Eigen::Map<const Eigen::VectorXd> velocity() const;  ///< v_k
  [[nodiscard]] StepView view() const;

  [[nodiscard]] const InitialValueProblem& problem() const;
  [[nodiscard]] const Method& method() const;
  [[nodiscard]] const IntegratorOptions& options() const;

  /// The storage so far: all stored rows are allocated, rows not reached yet are NaN.
  [[nodiscard]] const Solution& solution() const;
  /// The factorisation in use for the scheme's implicit step (kDense, kBanded or kSparse).
  [[nodiscard]] LinearSolver linear_solver() const;

  /// Runs the backward mirror equation on the computed trajectory (if options().mirror and the run
  /// succeeded), records the wall time, drops unreached rows and hands the solution over. The
  /// Integrator is unusable afterwards.
  Solution take_solution();

  /// The mirror run alone: max_k ‖y_k − x_{N−k}‖_∞ over the stored rows, or NaN if the run has
  /// not succeeded or the backward Newton fails.
  [[nodiscard]] double mirror_error() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One call: validate, integrate to t_end, run the mirror check (if enabled), return.
Solution integrate(const InitialValueProblem& problem, const Method& method = fvi_gl(),
                   const IntegratorOptions& options = {});

/// Same, calling observer(const StepView&) at k = 0 and after every step.
template <class Observer>
Solution integrate(const InitialValueProblem& problem, const Method& method,
                   const IntegratorOptions& options, Observer&& observer) {
  Integrator integrator(problem, method, options);
  integrator.run(std::forward<Observer>(observer));
  return integrator.take_solution();
}

}  // namespace fracvi
