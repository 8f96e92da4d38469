// An a-posteriori estimate of the global error of a finished run (issue 12, "An error estimate on
// every run"). The balance and mirror errors are consistency checks: a run can pass both to
// round-off and still be 10 % wrong. This estimate is of accuracy: Richardson extrapolation from
// companion runs of the same problem and scheme,
//
//     err_N ≈ max_k ‖x^N_k − x^{N/2}_k‖_∞ / (2^p − 1)   (max over the common grid nodes),
//
// with p the order observed from a third run with N/4 steps (log2 of the ratio of the N/4–N/2 to
// the N/2–N differences on the nodes all three share), limited to [0.5, declared + 2], or the
// declared order without that run; and the first 16 steps estimated towards finer grids (runs over
// them with h/2 and h/4) when that is larger — a fractional run's error can peak at step 1, which
// the N/2 run does not share. It assumes the runs are in the asymptotic range; the observed
// order is reported so that a user can see when they are not. When N is odd, or the N/2 run is
// refused (stability bound) or fails, the companion is a run with 2N steps instead:
// err_N ≈ max_k ‖x^N_k − x^{2N}_{2k}‖ · 2^p/(2^p − 1) with the declared p (twice the cost).
// An adaptive scheme (dopri5), whose error follows its tolerances and not h, is compared with a
// run on the same grid with 1000 times tighter tolerances instead.
// Measured within a factor 3 of the true error on problems with known solutions
// (tests/analysis/error_estimate_test.cpp, docs/verification.md).
#pragma once

#include <atomic>
#include <functional>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include "fracvi/integrate/solution.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {

/// Fills solution.error_estimate for the run of `problem` with `method` and `options` that
/// produced `solution` (nothing but a note when options.error_estimate is kNone or the run did not
/// succeed). The companion runs use the same options without mirror, diagnostics and stored rows.
/// Never throws for a failing companion run: the note says what happened.
void estimate_error(const InitialValueProblem& problem, const Method& method,
                    const IntegratorOptions& options, Solution& solution);

namespace internal {
struct CompanionRuns;  // error_estimate.cpp
}  // namespace internal

/// Below this many degrees of freedom ConcurrentErrorEstimate runs the companions on a second
/// thread: a step's history then stays below FastHistory's kParallelWork (2^18 multiply–adds for
/// K + window ≤ 128 terms), so the main run never splits it over a thread team that the companion
/// thread would compete with (two busy teams on two cores are slower than one after the other).
/// The run-ahead thread of a team of two (from kRunAheadWork) is kept only while TeamChooser
/// times whole steps faster with it, the companion's competition included.
inline constexpr Eigen::Index kMaxConcurrentDimension = 2048;

/// estimate_error() with its companion runs on a second thread, started before the main run:
/// they depend on it only through the steps it stores (known before it runs, io/output.hpp
/// stored_steps), so they can run alongside it and its mirror run. On two cores a run that
/// stores its estimate costs ≈ 2 N step-costs of wall time instead of 2.75 N (N, N for the mirror,
/// N/2 + N/4 + the initial layer). The same runs as estimate_error, so the same estimate, bit for
/// bit; ErrorEstimate::concurrent says that wall_seconds overlapped the stepping.
/// Construct it after the main Integrator (so that a refused run starts nothing), call finish()
/// after the main run; the destructor of an unfinished one stops the companions (through their
/// interrupt hook) and waits for them. The interrupt hook of `options` must be callable from the
/// second thread (the CLI's reads a signal flag).
class ConcurrentErrorEstimate {
 public:
  /// Whether the companions may run concurrently: an estimate is requested, method.threads ≠ 1
  /// (1 means one thread), no output times or events (the stored steps are then known and the run
  /// cannot stop early), d < kMaxConcurrentDimension, and at least two hardware threads.
  static bool applies(const InitialValueProblem& problem, const IntegratorOptions& options);

  /// `stored`: the steps the main run will store (Solution::step).
  ConcurrentErrorEstimate(const InitialValueProblem& problem, const Method& method,
                          const IntegratorOptions& options, std::vector<std::size_t> stored);
  ~ConcurrentErrorEstimate();
  ConcurrentErrorEstimate(const ConcurrentErrorEstimate&) = delete;
  ConcurrentErrorEstimate& operator=(const ConcurrentErrorEstimate&) = delete;

  /// Waits for the companions and fills solution.error_estimate as estimate_error() would (the
  /// same note when the run did not succeed or stopped at an event). Rethrows what a companion
  /// threw.
  void finish(Solution& solution);

 private:
  InitialValueProblem problem_;
  const Method& method_;
  IntegratorOptions options_;
  std::vector<std::size_t> stored_;
  std::shared_ptr<std::atomic<bool>> cancel_;
  std::future<std::shared_ptr<const internal::CompanionRuns>> runs_;
};

/// Runs `problem` with problem.steps, 2·problem.steps, 4·problem.steps, … steps, each with its
/// error estimate, until the estimate is ≤ options.tolerance (> 0 required), and returns the last
/// run. If the next doubling would pass options.max_steps, or a run fails or has no estimate, the
/// last run is returned with status kInaccurate (a run that failed keeps its own status) and a
/// message naming the tolerance, the estimate reached and the rule. Solution::tolerance_runs lists
/// the runs; `before_run(steps)` is called before each (progress display; may be empty). Throws
/// ValidationError as Integrator does (e.g. a first N beyond the stability bound).
Solution integrate_to_tolerance(const InitialValueProblem& problem, const Method& method,
                                const IntegratorOptions& options,
                                const std::function<void(std::size_t)>& before_run = {});

}  // namespace fracvi
