// One time-stepping scheme behind one interface (DESIGN §4.1; Boost.Odeint's steppers and
// GeometricIntegrators.jl's integrator types are the models, STYLE.md).
//
// A Stepper knows its scheme's equations and nothing else: it is constructed from a validated
// problem (reserving all its workspace), holds the state at step k (position x_k, velocity v_k,
// momentum p_k = M v_k), advances it by one step, and keeps the energy account of its own
// discretisation — the cumulative work W_k of the damping, of f and of the explicit time
// dependence of U, so that E_k + W_k − E_0 is the balance error (solution.hpp). A scheme with a
// mirror equation (the restricted variational principle's y-equation) can run it backwards over a
// finished trajectory.
//
// The Integrator (fracvi/integrate/integrator.hpp) owns everything else, for every scheme:
// storage of the rows, the observer, status and messages, stopping, energy and balance.
//
// step() is noexcept and does not allocate: a user callback that throws (potential, forcing) is
// caught here, once for all schemes, and reported as Status::kCallbackError.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <functional>
#include <limits>
#include <span>
#include <string_view>

#include "fracvi/core/matrix.hpp"
#include "fracvi/core/state_archive.hpp"
#include "fracvi/core/status.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"

namespace fracvi {

/// Room for the what() of a callback that threw (Stepper::failure_detail), e.g. a Python
/// exception with its traceback (python/src/callables.cpp): fixed, so that a failing step does
/// not allocate; longer texts are cut.
inline constexpr std::size_t kFailureDetailCapacity = 4096;

namespace internal {
struct NewtonReport;  // fracvi/solve/midpoint_newton.hpp
}  // namespace internal

/// Where a mirror run (Stepper::mirror_run) puts the mirror trajectory y: row i of the run's
/// stored rows is x at steps()[i], and y at the step mirroring it (y_{N−steps[i]} ≈ x_{steps[i]})
/// goes to put(i, y), once, rows ascending; rows the mirror run does not produce (x_0, x_1 for the
/// midpoint schemes, which start from them) are skipped. stop() is polled before each backward
/// step.
class MirrorRows {
 public:
  explicit MirrorRows(std::span<const std::size_t> steps) noexcept : steps_(steps) {}
  virtual ~MirrorRows() = default;
  MirrorRows(const MirrorRows&) = delete;
  MirrorRows& operator=(const MirrorRows&) = delete;

  [[nodiscard]] std::span<const std::size_t> steps() const noexcept { return steps_; }
  virtual void put(std::size_t row, const Eigen::VectorXd& y) = 0;
  [[nodiscard]] virtual bool stop() = 0;

 private:
  std::span<const std::size_t> steps_;
};

/// The mirror error of stored rows (Solution::mirror_error): max over the rows put of
/// ‖y − x_row‖_∞, with an interrupt hook as stop() (a hook that throws asks to stop).
class MirrorComparison final : public MirrorRows {
 public:
  /// `x` and `steps` as Stepper::mirror_error's (the rows of both, whichever are fewer).
  MirrorComparison(const RowMatrixXd& x, std::span<const std::size_t> steps,
                   std::function<bool()> interrupt) noexcept;
  void put(std::size_t row, const Eigen::VectorXd& y) override;
  [[nodiscard]] bool stop() override;
  [[nodiscard]] double error() const noexcept { return error_; }

 private:
  const RowMatrixXd& x_;
  std::function<bool()> interrupt_;
  double error_ = 0.0;
};

class Stepper {
 public:
  virtual ~Stepper() = default;
  Stepper(const Stepper&) = delete;
  Stepper& operator=(const Stepper&) = delete;

  /// Advances k → k+1. kSuccess when the step was taken, otherwise the failure status; the state
  /// then still holds step k and failure_message() says why (the Integrator adds step and time).
  Status step() noexcept;

  /// The state at the current step k (valid until the next step).
  [[nodiscard]] virtual const Eigen::VectorXd& position() const = 0;
  [[nodiscard]] virtual const Eigen::VectorXd& velocity() const = 0;
  /// p_k = M v_k as the scheme computes it (the energy is ½ v_kᵀ p_k + U(x_k, t_k)).
  [[nodiscard]] virtual const Eigen::VectorXd& momentum() const = 0;
  /// W_k, cumulative (0 at k = 0); NaN when the scheme was built without diagnostics.
  [[nodiscard]] virtual double work() const = 0;
  /// The part of −W_k put in from outside: the work of f and of the explicit time dependence of U,
  /// cumulative (0 at k = 0), so that W_k + supplied_work() is the work of the damping alone.
  /// The Integrator's health check needs it to tell energy put in by f from energy put in by an
  /// unstable damping term. NaN when not tracked (the default; the check then runs only when f = 0
  /// and U does not depend on t, where it is 0) or without diagnostics.
  [[nodiscard]] virtual double supplied_work() const {
    return std::numeric_limits<double>::quiet_NaN();
  }

  /// The backward run of the scheme's mirror equation on a finished run: max_k ‖y_k − x_{N−k}‖_∞
  /// over the stored rows: row i of `x` is x at step `steps[i]` (steps ascending; rows past
  /// steps.size() or x.rows() are ignored); `interrupt` (IntegratorOptions::interrupt) is polled
  /// before each backward step and ends the run. NaN when the scheme has none, the backward run
  /// fails or is interrupted. mirror_run() compared with the rows as they come.
  [[nodiscard]] double mirror_error(const RowMatrixXd& x, std::span<const std::size_t> steps,
                                    const std::function<bool()>& interrupt = {}) const;
  /// The backward run of the mirror equation (the schemes with SchemeInfo::has_mirror): y at the
  /// step mirroring each of rows.steps() handed to rows.put(), rows ascending; false when the
  /// scheme has none, a backward step fails, a callback throws or rows.stop() asks to stop. It
  /// needs only the problem, the options and x_1: it may run on another thread while step() goes
  /// on, from the end of the first step on (the Integrator's mirror alongside the run), so it
  /// reads nothing step() writes after step 1 and shares no workspace with it.
  [[nodiscard]] virtual bool mirror_run(MirrorRows& rows) const;

  /// The stage values of the last step's interval, a d × s block (column a: the state at
  /// t_{k−1} + c_a h), for schemes whose step has internal stages (the Lobatto FVIs); null for
  /// the one-stage schemes and before the first step.
  [[nodiscard]] virtual const Eigen::MatrixXd* stage_values() const { return nullptr; }

  /// The factorisation of the implicit step: kDense, kBanded or kSparse.
  [[nodiscard]] virtual LinearSolver linear_solver() const = 0;
  /// The damping memory: implementation, bytes, and K and n0 of a fast history (memory/history.hpp;
  /// Solution::history, history_bytes, history_exponentials, history_window). Kind "none" and 0
  /// bytes without one.
  [[nodiscard]] virtual HistoryReport history() const { return {}; }
  /// Saves or restores everything the next steps depend on (core/state_archive.hpp): the state at
  /// step k, the step index, the damping memory, the energy account and any predictor carried
  /// from step to step, so that a restored stepper continues bit-for-bit. A scheme that supports
  /// it says so in its registry row (SchemeInfo::checkpoints); the default refuses with
  /// CheckpointError.
  virtual void visit_state(StateArchive& archive);
  /// How many times the step's Newton matrix was formed and factored so far, the set-up's
  /// included (a linear problem: once, in the constructor; 0 for an explicit step).
  /// Solution::jacobian_factorizations; a checkpoint keeps it.
  [[nodiscard]] virtual std::size_t jacobian_factorizations() const { return 0; }
  /// Newton iterations of the last step (1 for a linear problem; 0 for an explicit step).
  [[nodiscard]] int last_iterations() const { return last_iterations_; }

  /// Sums over the state that the last step's own element passes formed as they wrote it (a
  /// large system's fused passes), so that the Integrator's diagnostics and health check need no
  /// pass of their own: the same numbers bit for bit as those passes (dot_pass, and
  /// weighted_squares_pass with √M_ii). For step `step` only; none formed by default.
  struct StepSums {
    std::size_t step = std::numeric_limits<std::size_t>::max();
    bool has_velocity_momentum = false;
    double velocity_momentum = 0.0;  // v_k·p_k (twice the kinetic energy)
    bool has_mass_squares = false;
    double mass_squares = 0.0;  // Σ (√M_ii x_k,i)², the health check's ‖x_k‖²_M (diagonal M)
  };
  [[nodiscard]] const StepSums& step_sums() const { return step_sums_; }
  /// The health check's weights √M_ii (0 where M_ii ≤ 0), as the Integrator and a step that
  /// forms StepSums::mass_squares both take them. Set-up only (allocates).
  [[nodiscard]] static Eigen::VectorXd health_weights(const ModelMatrix& mass);

  /// Why the last step failed (empty after a successful step), and the exception text of a
  /// throwing callback (else empty).
  [[nodiscard]] const char* failure_message() const { return message_.data(); }
  [[nodiscard]] const char* failure_detail() const { return detail_.data(); }

 protected:
  Stepper() = default;
  /// The scheme's step. May throw what a user callback throws; must not allocate.
  virtual Status advance() = 0;
  /// The records every visit_state starts with: the dimension and the step count (checked against
  /// this run) and the step index k (restored; at most `steps`).
  static void visit_step_index(StateArchive& archive, Eigen::Index dimension, std::size_t steps,
                               std::size_t& k);
  /// Records a failure (printf-style cause) and returns its status.
  Status fail(Status status, const char* format, ...) noexcept;
  void set_iterations(int iterations) noexcept { last_iterations_ = iterations; }
  /// What advance() formed of step_sums() (cleared before each step, so that a failed step
  /// leaves none).
  StepSums step_sums_;
  /// One MidpointNewton solve as the step's outcome: records its iterations and returns kSuccess,
  /// or the failure with its message — non-finite values, "the Newton matrix <matrix> could not
  /// be factored (singular)", or the iteration limit with the last correction and tolerance.
  Status newton_outcome(const internal::NewtonReport& report, const char* matrix) noexcept;

 private:
  std::array<char, 200> message_{};
  std::array<char, kFailureDetailCapacity> detail_{};
  int last_iterations_ = 0;
};

}  // namespace fracvi
