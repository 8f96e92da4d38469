// The result of a run: grid, states, diagnostics, statistics and a status (DESIGN §4).
//
// States are row-major contiguous arrays, one row per stored step: with the default
// IntegratorOptions::save_every = 1 that is (N+1) × d and row k is x_k; with save_every = s the
// rows are the steps 0, s, 2s, … and always the last computed one (step[i] names them). The buffer
// can be handed to NumPy without a copy. If a run stops early, the rows are the trajectory computed
// so far, ending with the last completed step (integrate() and Integrator::take_solution() drop the
// rows that were never reached).
//
// Diagnostics (docs/theory/start_step.md §4):
//   energy[k]      E_k = ½ v_kᵀ M v_k + U(x_k, t_k)       (no −f·x term)
//   dissipated[k]  W_k = Σ_{j<k} (h/2)(F_j·v_j + F_{j+1}·v_{j+1}) + (h²/8)(F_kᵀM⁻¹F_k − F_0ᵀM⁻¹F_0)
//                        − Σ_{j<k} f(t_{j+½})·(x_{j+1} − x_j)
//                        − Σ_{j<k} [U(x̄_j, t_{j+1}) − U(x̄_j, t_j)]    (time-dependent U only)
//                  with F_k = R h^{−2α} Σ c_m x̃_{k−m} the discrete damping force and x̄_j the
//                  midpoint. W_k is the energy removed by damping, minus the energy put in by f
//                  and by the explicit time dependence of U.
//   balance[k]     E_k + W_k − E_0. It equals Σ_{j<k} δ_j with δ_j the midpoint-quadrature defect
//   of
//                  U along step j: exactly zero (to round-off and Newton tolerance) when U is
//                  quadratic and time-independent, whatever R, α, f; O(h³) per step, O(h²) on a
//                  fixed interval otherwise.
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/core/matrix.hpp"
#include "fracvi/core/status.hpp"
#include "fracvi/memory/history.hpp"

namespace fracvi {

/// An a-posteriori estimate of the global error of a run (fracvi/analysis/error_estimate.hpp).
/// Accuracy, unlike the balance and mirror errors, which are consistency checks.
struct ErrorEstimate {
  /// Estimated max over the compared grid nodes of ‖x_k − x(t_k)‖_∞; NaN when none was made
  /// (`note` says why).
  double value = std::numeric_limits<double>::quiet_NaN();
  double order = std::numeric_limits<double>::quiet_NaN();  ///< the order p used in 1/(2^p − 1)
  /// log2 of the ratio of the N/4–N/2 to the N/2–N differences (NaN without the N/4 run).
  double observed_order = std::numeric_limits<double>::quiet_NaN();
  std::size_t nodes = 0;      ///< grid nodes compared
  std::string method;         ///< e.g. "richardson (N/2, N/4)"; empty when none
  std::string note;           ///< why there is none, or what limits it
  double wall_seconds = 0.0;  ///< the companion runs
  /// The companion runs ran on a second thread alongside the run (ConcurrentErrorEstimate):
  /// wall_seconds overlapped the stepping instead of following it.
  bool concurrent = false;
};

/// One run of the doubling of integrate_to_tolerance() (fracvi/analysis/error_estimate.hpp).
struct ToleranceRun {
  std::size_t steps = 0;
  double error_estimate = std::numeric_limits<double>::quiet_NaN();  ///< NaN when none
  double wall_seconds = 0.0;  ///< the run, its mirror and its companion runs
  std::string status;
};

/// The zero crossings of IntegratorOptions::events a run found (in time order), column-wise.
struct EventLog {
  std::vector<std::string> names;  ///< the events' names, by index
  std::vector<std::size_t> event;  ///< which event (index into names), per crossing
  std::vector<double> t;           ///< the crossing time (root of g on the dense interpolant)
  std::vector<std::size_t> step;   ///< the step k + 1 whose interval (t_k, t_{k+1}] holds it
  std::vector<int> direction;      ///< +1 rising, −1 falling
  std::vector<double> x, v;        ///< the interpolated state there, row-major (crossings × d)
  [[nodiscard]] std::size_t size() const { return t.size(); }
};

struct Solution {
  Eigen::VectorXd t;              ///< t_k of the stored steps
  std::vector<std::size_t> step;  ///< the step index k of each stored row
  RowMatrixXd x;                  ///< positions, (steps_done + 1) × d
  RowMatrixXd v;  ///< velocities v_k = M⁻¹ p_k from the grid momentum (start_step.md §2)

  Eigen::VectorXd energy;      ///< E_k (NaN with options.diagnostics = false)
  Eigen::VectorXd dissipated;  ///< W_k (idem)
  Eigen::VectorXd balance;     ///< E_k + W_k − E_0 (idem)

  /// The state at IntegratorOptions::output_times reached by the run (all of them unless it
  /// stopped early): the dense interpolant of every step, whatever save_every.
  Eigen::VectorXd output_t;
  RowMatrixXd output_x;
  RowMatrixXd output_v;
  /// The crossings of IntegratorOptions::events.
  EventLog events;

  Status status = Status::kRunning;
  std::string message;  ///< empty on success; otherwise names the step, the time and the cause

  std::size_t steps_done = 0;         ///< completed steps; rows 0 … steps_done are valid
  std::size_t newton_iterations = 0;  ///< total over all steps (1 per step for linear problems)
  std::size_t max_newton_iterations_per_step = 0;
  /// How many times the implicit step's Newton matrix (M + (h²/4)∇²U, or the Lobatto stage
  /// matrix) was formed and factored, the set-up's included: 1 for a linear problem, up to one
  /// per Newton iteration for a nonlinear one (Newton keeps J while it converges fast, also from
  /// step to step on the banded and sparse paths); 0 for explicit and adaptive schemes.
  std::size_t jacobian_factorizations = 0;
  std::size_t save_every = 1;  ///< IntegratorOptions::save_every of the run
  /// The grid's h (InitialValueProblem::step_size()): the dense output's interpolant uses it, so
  /// that interpolate() reproduces the run's output_x bit for bit; 0 when unknown (a solution
  /// read back from files), then t[i+1] − t[i].
  double step_size = 0.0;
  std::string linear_solver;      ///< factorisation used: "dense", "banded" or "sparse"
  std::size_t history_bytes = 0;  ///< memory of the damping history (History::memory_bytes)
  /// The damping memory used: "direct", "fast", "local" or "none" (what "auto" chose).
  std::string history = "none";
  /// A fast history's K (exponentials: recursions per degree of freedom) and n0 (the window of
  /// exactly weighted recent lags); 0 for the other memories (HistoryReport).
  std::size_t history_exponentials = 0;
  std::size_t history_window = 0;
  /// The per-weight relative accuracy ε of the fast history (NaN when the run has none: direct,
  /// local, FFT or no memory), and whether the accuracy budget chose it ("auto") or the user
  /// (history_budget.hpp). history_limited: the budget asked for less than the fit can deliver
  /// (1e-13), so the history may limit the accuracy of this run.
  double history_tolerance = std::numeric_limits<double>::quiet_NaN();
  bool history_tolerance_auto = false;
  bool history_limited = false;
  /// How the fast history's pushes used the cores (HistoryReport::threads): the team, the pushes
  /// on it, the measured choice's decisions. A team of 1 for the other memories.
  HistoryThreads history_threads;

  /// max_k ‖y_k − x_{N−k}‖_∞ from the independent backward run of the mirror equation
  /// (`DiscEqs`, second line); NaN if not computed (disabled, or the run did not succeed).
  double mirror_error = std::numeric_limits<double>::quiet_NaN();
  /// The mirror run ran on a second thread alongside the run (IntegratorOptions::mirror_alongside)
  /// rather than after it: the same mirror_error; wall_time_seconds then holds only the wait for
  /// it.
  bool mirror_alongside = false;
  double max_balance_error = 0.0;  ///< max_k |balance[k]| (NaN with options.diagnostics = false)
  /// Stepping: the x-run plus the mirror run, or plus the wait for the mirror run when it ran
  /// alongside (the integration alone, what comparisons time).
  double wall_time_seconds = 0.0;
  /// Setting up the run before step 1 (Integrator's constructor: validation, weights, the fast
  /// history's fit or FFT plans, factorisations); a run's whole cost is the sum of the two.
  double setup_seconds = 0.0;
  /// Filled by estimate_error() (fracvi/analysis/error_estimate.hpp), not by the Integrator.
  ErrorEstimate error_estimate;
  /// The runs of integrate_to_tolerance() that led to this one (this one last); empty otherwise.
  std::vector<ToleranceRun> tolerance_runs;

  std::string method;      ///< e.g. "fvi-gl"
  int declared_order = 0;  ///< Method::declared_order() for this model

  [[nodiscard]] bool ok() const { return status == Status::kSuccess; }
};

}  // namespace fracvi
