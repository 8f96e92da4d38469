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

#include <functional>
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
