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
// Health checks (DESIGN §4.2: `success` means the run's own diagnostics found nothing wrong).
// After every step k the Integrator applies three rules (docs/conventions.md, "When a run is not a
// success"). With T = t_end − t_0, K_j = ½v_jᵀMv_j, U_j = U(x_j, t_j), ‖x‖_M = √(Σ M_ii x_i²):
//   energy scale  S_k = max(|E_0|, K_0 + |U_0|, S_R, max_{j≤k} |P_j|), where P_j is
//                 the work put in by f and by the explicit time dependence of U
//                 (Stepper::supplied_work), D_j = W_j + P_j the work of the damping alone, and
//                 S_R = (x_0ᵀRx_0 + T² v_0ᵀRv_0)·T^{−2α} the energy the damping memory of the
//                 initial state can hand back (Riemann–Liouville's x(0), Caputo's v(0));
//   tolerance     S̃_k = max(S_k, kActivityFraction · max_{j≤k}(K_j + |U_j|)), a floor for a
//                 potential whose offset makes E_0 = K_0 = U_0 = 0.
//   1. unstable (stop): D_k < −kUnstableDampingFactor · S̃_k — the damping, which can only remove
//      energy, has put in ten times the energy scale (an explicit damping memory past its
//      stability bound). Needs the diagnostics and P_k (known when the scheme tracks it, or 0
//      when f = 0 and U does not depend on t); off for Riemann–Liouville with x(0) ≠ 0 and
//      0 < 2α < 1, whose memory of x(0) is a force that legitimately puts energy in.
//   2. unstable (stop): ‖x_k‖_M > kUnstableGrowthFactor · B_k with
//      B_k = max(‖x_0‖_M + T‖v_0‖_M, T√(2 S_k), max_{j≤J} ‖x_j‖_M), J the largest power of two
//      ≤ k/2 (the state earlier in the run, so that growth polynomial in t never trips it):
//      eight orders of magnitude beyond what the initial state, the energy budget and the run so
//      far explain. The only rule without diagnostics (then without the T√(2S_k) term).
//   3. inaccurate (marked at the end, the run goes on): max_k |E_k + W_k − E_0| >
//      kInaccurateBalanceFraction · S̃_N with the scale of the whole run (a run from rest has tiny
//      energies in its first steps, where an O(h^p) balance error is relatively large but
//      absolutely negligible); the message names the step of the largest error. Without P_k the
//      largest |W_j| (which contains it) enters S_k.
// Healthy runs stay far from every bound (margins measured on examples/, docs/conventions.md).
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
#include "fracvi/core/state_archive.hpp"
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

/// IntegratorOptions::mirror_alongside applies below this dimension (above it the fast history's
/// threads use the second core; the concurrent error estimate has the same bound) …
inline constexpr Eigen::Index kMaxAlongsideMirrorDimension = 2048;
/// … and when the mirror run's copy of the stored positions (rows × d doubles) takes at most this.
inline constexpr double kMaxAlongsideMirrorBytes = 256.0 * 1024.0 * 1024.0;

/// The rules of the health checks above.
inline constexpr double kUnstableDampingFactor = 10.0;
inline constexpr double kUnstableGrowthFactor = 1e8;
inline constexpr double kInaccurateBalanceFraction = 0.5;
inline constexpr double kActivityFraction = 1e-3;

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

  /// Advances one step (k → k+1). Returns kRunning while steps remain, kSuccess (or kInaccurate,
  /// when the balance rule tripped on the way) after the last one, or a failure status (kUnstable
  /// included); kInterrupted, without a step, when options().interrupt asks to stop. Once
  /// finished or failed it does nothing and returns the status. Never allocates, never throws.
  Status step() noexcept;

  /// Steps to the end. observer(const StepView&) is called for the current state if no step has
  /// been taken yet, then after every completed step.
  template <class Observer>
  Status run(Observer&& observer) {
    if (steps_done() == 0) observer(view());
    Status s = status();
    while (s == Status::kRunning) {
      const std::size_t before = steps_done();
      s = step();
      const bool stepped = steps_done() != before;  // not when interrupted before the step
      if (stepped && (s == Status::kRunning || s == Status::kSuccess || s == Status::kInaccurate)) {
        observer(view());
      }
    }
    return s;
  }
  /// Steps to the end without an observer: the same steps, without building a StepView after
  /// each (an out-of-line call, ≈ 2 % of a d = 1 step).
  Status run() {
    Status s = status();
    while (s == Status::kRunning) s = step();
    return s;
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

  /// The solution so far without ending the run: what take_solution() would return now (the
  /// stored rows, the state at the current step as the last row, status and message), as a copy
  /// and without the mirror run; the Integrator goes on. Allocates (not for the step loop).
  [[nodiscard]] Solution snapshot() const;

  /// Runs the backward mirror equation on the computed trajectory (if options().mirror and the run
  /// succeeded), records the wall time, drops unreached rows and hands the solution over. The
  /// Integrator is unusable afterwards.
  Solution take_solution();

  /// Saves or restores the whole state of a running integration (core/state_archive.hpp): the
  /// step index, the stored rows so far, the statistics, the health checks' running quantities
  /// and the stepper's state (the damping memory included). An Integrator constructed with the
  /// same problem, method and options and restored from a checkpoint taken after step k
  /// continues exactly like the original after step k: the same rows, bit for bit. Throws
  /// CheckpointError when the scheme cannot (SchemeInfo::checkpoints), when the run is not
  /// running, or when the archive does not match this run.
  void visit_state(StateArchive& archive);

  /// The mirror run alone: max_k ‖y_k − x_{N−k}‖_∞ over the stored rows, or NaN if the run has
  /// not succeeded or the backward Newton fails.
  [[nodiscard]] double mirror_error() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The step index of each row the Integrator stores for a run that completed `steps_done` steps
/// with save_every = s: 0, s, 2s, … below steps_done, and steps_done (trajectory.csv has no
/// step column; these are its rows).
std::vector<std::size_t> stored_steps(std::size_t steps_done, std::size_t save_every);

/// Throws ValidationError when the stored trajectory of `problem` with `options` (rows × (16 d +
/// 40) bytes, allocated up front by the Integrator) would not fit in the machine's physical
/// memory, with the number and the smallest [output] every that fits in half of it. The
/// Integrator's constructor calls it; fracvi::prepare_run too.
void check_storage(const InitialValueProblem& problem, const IntegratorOptions& options);

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
