// The options of a time integration (any scheme). Defaults here are the defaults everywhere: the
// problem-file reader, the resolved problem.toml, Python and the C++ API all start from
// IntegratorOptions{} (tests/io/problem_file_test.cpp checks the reader against it).
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string_view>
#include <vector>

#include "fracvi/core/event.hpp"
#include "fracvi/core/newton_options.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/solve/symmetric_factor.hpp"

namespace fracvi {

/// How x_1 is obtained from (x_0, v_0).
enum class StartValue {
  /// The scheme's own start from the discrete Legendre transform (for the midpoint FVIs
  /// p⁺_0 = M v_0 − (h/2) F_0, start_step.md §2): keeps the order.
  kDiscreteLegendre,
  /// x_1 = x_0 + h v_0. First order; only for comparisons (it costs an order when R = 0).
  kExplicitEuler,
};

/// How the forcing f enters a step (IntegratorOptions::load).
enum class ForcingLoad {
  /// f at the scheme's quadrature points (the midpoint, the Lobatto stages): the published
  /// setting. A forcing that is not smooth at t_0 (e.g. √t) costs order there.
  kPointwise,
  /// The exact Galerkin moments h∫ ℓ_k(σ) f(t_n + σh) dσ against the scheme's interpolant (the
  /// variational form of −∫ f·x dt; for the midpoint schemes the cell average of f as their
  /// midpoint force), by tanh–sinh quadrature on the first interval (integrable singularities at
  /// t_0) and 20-point Gauss–Legendre beyond.
  kMoments,
};
std::optional<ForcingLoad> parse_forcing_load(std::string_view name);
std::string_view to_string(ForcingLoad load);

/// What the Lobatto schemes take out of x at t_0 (IntegratorOptions::split;
/// docs/theory/fvi_lobatto.md §2 and §13.3).
enum class TaylorSplit {
  /// The Taylor polynomial P(t) = x_0 + (t − t_0) v_0: the damping memory acts on x − P and
  /// D^{2α}P enters by its exact moments (the split of every CQ scheme).
  kTaylor,
  /// Also the solution's fractional Taylor terms S = Σ c_γ (t − t_0)^γ, 1 < γ ≤ 2s − 1, computed
  /// from the data and the equation (linear problems without forcing only): the scheme integrates
  /// x − S under the forcing −(M S'' + R D^{2α}S + K S) (exact moments), so that neither its memory
  /// nor its Galerkin part meets the non-smooth terms at t_0 (the start-up error goes).
  kSeries,
};
std::optional<TaylorSplit> parse_taylor_split(std::string_view name);
std::string_view to_string(TaylorSplit split);

/// The a-posteriori estimate of the global error of a run (IntegratorOptions::error_estimate;
/// fracvi/analysis/error_estimate.hpp).
enum class ErrorEstimateKind {
  /// None (Solution::error_estimate stays NaN).
  kNone,
  /// Richardson extrapolation from companion runs of the same problem with N/2 and N/4 steps
  /// (without mirror and diagnostics: about 0.75 of the x-run's cost more).
  kRichardson,
};
std::optional<ErrorEstimateKind> parse_error_estimate(std::string_view name);
std::string_view to_string(ErrorEstimateKind kind);

/// Bounds of IntegratorOptions::history_tolerance (the per-weight relative accuracy ε of the
/// sum-of-exponentials fit: below 1e-13 the fit is limited by round-off, above 1e-3 it is useless).
inline constexpr double kMinHistoryTolerance = 1e-13;
inline constexpr double kMaxHistoryTolerance = 1e-3;
/// IntegratorOptions::history_tolerance = kAutoHistoryTolerance (the default, "auto" in problem
/// files and Python): the run chooses ε from its step size, damping order, the scheme's order and
/// λ_max(M⁻¹R) (history_budget(), fracvi/schemes/history_budget.hpp; fast_history.md §10).
inline constexpr double kAutoHistoryTolerance = 0.0;

/// IntegratorOptions::row_split_from's default, measured on the 2-vCPU machine of bench/RESULTS.md
/// (examples/fractional_chain.toml, `fvi-gl`, two threads forced against one, µs a step,
/// 2026-12-02): 14.0 against 9.3 at d = 1000, even at 2048 (21.4 against 21.7), ahead from 3072
/// (28.7–29.6 against 32.9–33.0; 35.8 against 45.7 at 4096).
inline constexpr Eigen::Index kRowSplitFrom = 3072;

struct IntegratorOptions {
  NewtonOptions newton;
  HistoryKind history = HistoryKind::kAuto;
  /// Per-weight relative accuracy ε of the fast history (its sum-of-exponentials fit):
  /// kAutoHistoryTolerance (0) lets the run choose it (history_budget()); a number in
  /// [kMinHistoryTolerance, kMaxHistoryTolerance] is used exactly.
  double history_tolerance = kAutoHistoryTolerance;
  /// Run the mirror equation backwards and report Solution::mirror_error (about the cost of the
  /// run again: on a second core alongside the run when mirror_alongside applies, else after it).
  bool mirror = true;
  /// Run the mirror check on a second thread alongside the run, from the end of the first step on
  /// (the backward run needs only x_0 and x_1; Stepper::mirror_run), when threads ≠ 1, the
  /// machine has two hardware threads, there are no events, d < kMaxAlongsideMirrorDimension, the
  /// scheme has a mirror run and its copy of the stored positions fits kMaxAlongsideMirrorBytes
  /// (integrator.hpp); otherwise after the run. The same mirror error either way, bit for bit.
  /// Off by default: a library call starts no thread of its own unless asked (the fast history's
  /// team aside, IntegratorOptions::threads), and the model's callbacks are then called from two
  /// threads at once (allowed by the Potential contract). Problem files (`fracvi run`, the Python
  /// module) turn it on; the Python module not for models that call Python functions, whose runs
  /// hold the GIL.
  bool mirror_alongside = false;
  /// Compute energy, dissipated work and balance every step (one potential value per step, three
  /// for a time-dependent U, and a few dot products). When false those columns stay NaN and
  /// Solution::max_balance_error is NaN.
  bool diagnostics = true;
  /// Flush subnormal numbers (below DBL_MIN ≈ 2.2e-308) to zero while stepping: each step, and
  /// the library's threads working for it, compute with SSE's flush-to-zero and
  /// denormals-are-zero set, and the caller's setting is restored after the step (a potential's or
  /// force's callbacks run inside it). A localised pulse in a chain keeps positions and history
  /// states in the subnormal range, where each operation costs ≈ 100 cycles on x86-64
  /// (examples/fractional_chain.toml stepped 2.4–2.9× slower: bench/RESULTS.md); flushed, the run's
  /// absolute floor is DBL_MIN instead of 4.9e-324. False keeps gradual underflow. x86-64 only
  /// (elsewhere subnormals are kept); internal/float_environment.hpp.
  bool flush_subnormals = true;
  StartValue start = StartValue::kDiscreteLegendre;
  /// How the forcing enters (ForcingLoad); kMoments is refused for schemes without it
  /// (SchemeInfo::forcing_moments).
  ForcingLoad load = ForcingLoad::kPointwise;
  /// What the damping memory subtracts (TaylorSplit); kSeries is refused for schemes without it
  /// (SchemeInfo::series_split) and for problems outside its domain.
  TaylorSplit split = TaylorSplit::kTaylor;
  /// The error estimate the whole-run drivers (`fracvi run`, Python's fracvi.integrate) add to
  /// the solution with estimate_error() (fracvi/analysis/error_estimate.hpp); the Integrator and
  /// integrate() themselves run the one trajectory only.
  ErrorEstimateKind error_estimate = ErrorEstimateKind::kRichardson;
  /// > 0: the whole-run drivers choose N by doubling time.steps until the error estimate is
  /// ≤ tolerance (integrate_to_tolerance(), fracvi/analysis/error_estimate.hpp); 0: off.
  double tolerance = 0.0;
  /// The ceiling of that doubling: a run that would need more steps ends `inaccurate`.
  std::size_t max_steps = 10'000'000;
  /// Factorisation of the Newton matrix M + (h²/4)∇²U (and of M for v = M⁻¹p): kAuto uses a band
  /// or sparse factorisation when M is stored sparse and the potential declares a sparse Hessian
  /// (O(d) per step for chains), dense otherwise (symmetric_factor.hpp).
  LinearSolver linear_solver = LinearSolver::kAuto;
  /// Error tolerances of the adaptive schemes (SchemeInfo::adaptive, dopri5): the controller keeps
  /// each internal step's error estimate below abs_tolerance + rel_tolerance·|z| per component of
  /// z = (x, v). Ignored by the fixed-step schemes.
  double abs_tolerance = 1e-8;
  double rel_tolerance = 1e-8;
  /// Store every n-th state (and always the last one): a run of 10^6 steps of 1000 degrees of
  /// freedom would otherwise keep 16 GB of positions and velocities. Diagnostics and the mirror
  /// check still see every step (the mirror error is then the maximum over the stored rows).
  std::size_t save_every = 1;
  /// Times at which the run also outputs the state (Solution::output_t, output_x, output_v),
  /// ascending, in [t_0, t_end]: the cubic Hermite interpolant of (x_k, v_k, x_{k+1}, v_{k+1})
  /// evaluated during the run from every step's full-precision state, so save_every does not
  /// thin them (docs/theory/dense_output.md). A time on the grid gives that step's state exactly.
  std::vector<double> output_times;
  /// Zero crossings of g(t, x, v) located on the same interpolant, recorded in Solution::events,
  /// optionally terminal (core/event.hpp). Names distinct and non-empty.
  std::vector<Event> events;
  /// Threads for the work over degrees of freedom (fast-history recursions): 0 = measured, the
  /// histories time one thread against OpenMP's default (all cores, or OMP_NUM_THREADS) during
  /// the run and keep the faster (internal/team_chooser.hpp); n ≥ 1 = n threads; small systems
  /// run on one thread regardless.
  int threads = 0;
  /// The dimension from which an `fvi-gl` or `fvi-bdf2` step with diagonal M and R and the fast
  /// history runs split by rows over the threads: each thread of the team takes its share of the
  /// rows of every pass and of the history's push (kRowParts parts of the rows), and only the
  /// linear solve stays on one thread — for a linear potential with Potential::gradient_rows()
  /// (the chains) just the tridiagonal solve, otherwise Newton's whole solve
  /// (docs/large-systems.md). The trajectory is the same bit for bit with or without the split and
  /// whatever the threads; the diagnostics' sums (energy, balance, the health check's norm) are
  /// formed part by part, the same for every team, and differ from the whole steps' in their last
  /// bits. Measured default: kRowSplitFrom; tests set it to compare both paths. Must be ≥ 1.
  Eigen::Index row_split_from = kRowSplitFrom;
  /// Polled before every step (and by the companion runs of the error estimate): when it returns
  /// true the run stops there with Status::kInterrupted, the trajectory so far kept. `fracvi run`
  /// sets it to a flag raised by SIGINT, SIGTERM and SIGHUP; Python to a check of its signal
  /// handlers (Ctrl-C) about every 0.1 s. Must not throw or allocate (it runs in the step loop),
  /// and once it has returned true it must keep returning true (the drivers ask again after the
  /// run to tell an interrupted error estimate from a failed one).
  std::function<bool()> interrupt;
};

/// Throws ValidationError naming the offending field.
void validate(const IntegratorOptions& options);

}  // namespace fracvi
