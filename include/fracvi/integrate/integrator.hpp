// The time stepper of `DiscEqs` (DESIGN §3.2, §4).
//
// For k = 0 … N−1 it solves for x_{k+1}
//
//   M (x_{k+1} − 2x_k + x_{k−1})/h² + F_k + ½∇U_f(x̄_k, t_{k+½}) + ½∇U_f(x̄_{k−1}, t_{k−½}) = 0,
//   F_k = R h^{−2α} Σ_{m=0}^{k} c_m x̃_{k−m},   x̄_k = (x_k + x_{k+1})/2,   U_f = U − f(t)·x,
//
// in the equivalent momentum form p⁺_k = p⁻_k − h F_k (docs/theory/start_step.md §1):
//
//   M (x_{k+1} − x_k)/h + (h/2) ∇U_f(x̄_k, t_{k+½}) = p⁺_k,
//
// by Newton's method with Jacobian M + (h²/4) ∇²U(x̄_k) (x_{k+1} enters only through the kinetic
// term and the midpoint gradient; the damping sum involves known x's only). For a constant
// Hessian the matrix is factored once and each step is exactly one linear solve. The start x_1
// comes from the discrete Legendre transform (start_step.md §2); velocities are v_k = M⁻¹p_k with
// the grid momentum p_k = p⁻_k − (h/2)F_k.
//
// The step loop does not allocate and does not throw: numerical failure ends the run with a
// Status and a message, and everything computed so far is kept.
//
// Usage — one call:
//   fracvi::Solution sol = fracvi::integrate(problem);            // fvi-gl, default options
// or stepped by hand (Boost.Odeint style):
//   fracvi::Integrator integ(problem);
//   while (integ.step() == fracvi::Status::kRunning) { use(integ.position()); }
//   fracvi::Solution sol = integ.take_solution();
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <utility>

#include "fracvi/integrate/history.hpp"
#include "fracvi/integrate/method.hpp"
#include "fracvi/integrate/solution.hpp"
#include "fracvi/integrate/symmetric_factor.hpp"
#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {

struct NewtonOptions {
  /// Converged when ‖δ‖_∞ ≤ absolute_tolerance + relative_tolerance · max(‖x_{k+1}‖_∞, ‖x_k‖_∞),
  /// δ the last Newton correction (already applied). Quadratic convergence makes the accepted
  /// iterate far more accurate than the tolerance; tolerances near machine epsilon may fail to be
  /// reached because of round-off in the residual.
  double relative_tolerance = 1e-12;
  double absolute_tolerance = 0.0;
  int max_iterations = 25;  ///< per step; ≥ 1
};

/// How x_1 is obtained from (x_0, v_0).
enum class StartValue {
  /// p⁺_0 = M v_0 − (h/2) F_0 (discrete Legendre transform, start_step.md §2): keeps the order.
  kDiscreteLegendre,
  /// x_1 = x_0 + h v_0. First order; only for comparisons (it costs an order when R = 0).
  kExplicitEuler,
};

struct IntegratorOptions {
  NewtonOptions newton;
  HistoryKind history = HistoryKind::kAuto;
  /// Per-weight relative accuracy ε of the fast history (its sum-of-exponentials fit).
  double history_tolerance = 1e-10;
  /// Run the mirror equation backwards and report Solution::mirror_error (doubles the cost).
  bool mirror = true;
  /// Compute energy, dissipated work and balance every step (one potential value per step, three
  /// for a time-dependent U, and a few dot products). When false those columns stay NaN and
  /// Solution::max_balance_error is NaN.
  bool diagnostics = true;
  StartValue start = StartValue::kDiscreteLegendre;
  /// Factorisation of the Newton matrix M + (h²/4)∇²U (and of M for v = M⁻¹p): kAuto uses a band
  /// or sparse factorisation when M is stored sparse and the potential declares a sparse Hessian
  /// (O(d) per step for chains), dense otherwise (symmetric_factor.hpp).
  LinearSolver linear_solver = LinearSolver::kAuto;
  /// Store every n-th state (and always the last one): a run of 10^6 steps of 1000 degrees of
  /// freedom would otherwise keep 16 GB of positions and velocities. Diagnostics and the mirror
  /// check still see every step (the mirror error is then the maximum over the stored rows).
  std::size_t save_every = 1;
  /// Threads for the work over degrees of freedom (fast-history recursions): 0 = OpenMP's default
  /// (all cores, or OMP_NUM_THREADS); small systems run on one thread regardless.
  int threads = 0;
};

/// Throws ValidationError naming the offending field.
void validate(const IntegratorOptions& options);

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
  /// Validates problem, method and options (throws ValidationError) and reserves all storage:
  /// the solution's N+1 rows, the history, the Newton workspace and factorizations. Computes the
  /// state at k = 0 (E_0, F_0, p_0 = M v_0).
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
  /// The factorisation in use for the Newton matrix (kDense, kBanded or kSparse).
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
