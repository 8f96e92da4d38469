#include "fracvi/analysis/error_estimate.hpp"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "fracvi/core/error.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/internal/background_thread.hpp"

namespace fracvi {
namespace internal {

// What the companion runs of one estimate produced: they depend on the main run only through the
// steps it stores, so they can run before it ends (ConcurrentErrorEstimate). Which runs exist
// follows estimate_error's rules; combine() turns them into the estimate.
struct CompanionRuns {
  std::optional<RowMatrixXd> tight;     // adaptive scheme: tolerances / 1000
  std::optional<RowMatrixXd> half;      // N/2
  std::optional<RowMatrixXd> quarter;   // N/4 (only after N/2)
  std::optional<RowMatrixXd> twice;     // 2N (only without N/2)
  std::optional<RowMatrixXd> layer[3];  // the initial layer with h, h/2, h/4 (only after N/2)
  std::string why, why_quarter, why_layer;
  bool layer_checked = false;  // the three layer runs succeeded
  double wall_seconds = 0.0;
};

}  // namespace internal

namespace {

using internal::CompanionRuns;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The options of a companion run with `steps` steps: no mirror run, no diagnostics, no stored rows
// (the observer takes them), no output times or events (the grid rows are compared; no stop at a
// terminal event). `cancel` (concurrent companions only): the main run failed or threw, stop.
IntegratorOptions companion_options(const IntegratorOptions& options, std::size_t steps,
                                    const std::shared_ptr<std::atomic<bool>>& cancel) {
  IntegratorOptions o = options;
  o.mirror = false;
  o.diagnostics = false;
  o.save_every = steps;
  o.output_times.clear();
  o.events.clear();
  if (cancel) {
    o.interrupt = [cancel, hook = options.interrupt] {
      return cancel->load(std::memory_order_relaxed) || (hook && hook());
    };
  }
  return o;
}

// x of a companion run with `steps` steps at the main run's stored nodes that it shares: row i of
// the result is x^{steps} at the main run's step solution.step[i] when that node is on the
// companion's grid (k · steps / N whole), NaN otherwise. nullopt when the run is refused or fails
// (`why` says which).
std::optional<RowMatrixXd> companion(const InitialValueProblem& problem, const Method& method,
                                     const IntegratorOptions& options,
                                     std::span<const std::size_t> stored, std::size_t steps,
                                     const std::shared_ptr<std::atomic<bool>>& cancel,
                                     std::string& why) {
  InitialValueProblem p = problem;
  p.steps = steps;
  const IntegratorOptions o = companion_options(options, steps, cancel);
  const std::size_t n = problem.steps;
  // Companion step j ↔ main step j · n / steps: the (j, stored row) pairs of the stored nodes on
  // the companion's grid. `stored` holds a run's rows, so its steps ascend without repeats, and
  // so do the pairs' j. One pair per stored row, not a table over all `steps` (that was 8 bytes
  // per companion step: 40 MB for the N/2 run at N = 10^7, most of a d = 1 run's peak memory).
  assert(std::is_sorted(stored.begin(), stored.end()));
  std::vector<std::pair<std::size_t, Eigen::Index>> rows;
  rows.reserve(stored.size());
  for (std::size_t i = 0; i < stored.size(); ++i) {
    const std::size_t k = stored[i];
    if ((k * steps) % n == 0) rows.emplace_back(k * steps / n, static_cast<Eigen::Index>(i));
  }
  RowMatrixXd x = RowMatrixXd::Constant(static_cast<Eigen::Index>(stored.size()),
                                        problem.model.dimension(), kNaN);
  try {
    Integrator integrator(std::move(p), method, o);
    std::size_t next = 0;  // the first pair not yet reached (the steps come in order)
    const Status status = integrator.run([&](const StepView& view) {
      while (next < rows.size() && rows[next].first < view.k) ++next;
      if (next < rows.size() && rows[next].first == view.k) {
        x.row(rows[next].second) = view.x.transpose();
      }
    });
    if (status != Status::kSuccess) {
      why = "the companion run with " + std::to_string(steps) + " steps ended " +
            std::string(to_string(status)) + ": " + integrator.take_solution().message;
      return std::nullopt;
    }
  } catch (const ValidationError& e) {
    why = "the companion run with " + std::to_string(steps) + " steps is refused: " + e.what();
    return std::nullopt;
  }
  return x;
}

// x at the steps 0 … m of a run over the first m·refine steps of `problem` with the step h/refine
// (h the main run's): row j is the state at t0 + j·h. A run's first steps do not depend on the
// end of its interval (every scheme steps forward from t0 with the past only), so these are the
// first steps of the main run's grid refined `refine` times, at the cost of m·refine steps.
std::optional<RowMatrixXd> first_steps(const InitialValueProblem& problem, const Method& method,
                                       const IntegratorOptions& options, std::size_t m,
                                       std::size_t refine,
                                       const std::shared_ptr<std::atomic<bool>>& cancel,
                                       std::string& why) {
  InitialValueProblem p = problem;
  p.steps = m * refine;
  p.t_end = problem.time(static_cast<double>(m));
  const IntegratorOptions o = companion_options(options, p.steps, cancel);
  RowMatrixXd x(static_cast<Eigen::Index>(m + 1), problem.model.dimension());
  try {
    Integrator integrator(std::move(p), method, o);
    const Status status = integrator.run([&](const StepView& view) {
      if (view.k % refine == 0) x.row(static_cast<Eigen::Index>(view.k / refine)) = view.x;
    });
    if (status != Status::kSuccess) {
      why = "the run over the first " + std::to_string(m) + " steps with h/" +
            std::to_string(refine) + " ended " + std::string(to_string(status)) + ": " +
            integrator.take_solution().message;
      return std::nullopt;
    }
  } catch (const ValidationError& e) {
    why = "the run over the first " + std::to_string(m) + " steps with h/" +
          std::to_string(refine) + " is refused: " + e.what();
    return std::nullopt;
  }
  return x;
}

// max over the rows where both are defined of ‖a_i − b_i‖_∞, restricted to rows where `only` is
// defined too (when given); and the number of rows compared.
double max_difference(const RowMatrixXd& a, const RowMatrixXd& b, const RowMatrixXd* only,
                      std::size_t& rows) {
  double m = 0.0;
  rows = 0;
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    if (std::isnan(b(i, 0)) || std::isnan(a(i, 0))) continue;
    if (only != nullptr && std::isnan((*only)(i, 0))) continue;
    m = std::max(m, (a.row(i) - b.row(i)).cwiseAbs().maxCoeff());
    ++rows;
  }
  return m;
}

// The initial layer. A fractional problem's solution has non-smooth terms at t0 (powers of
// t − t0 with non-integer exponents), so a high-order scheme's largest error can sit at its first
// steps, between the nodes the N/2 run shares: at step 1, 2.6× the estimate over the shared nodes
// for fvi-lobatto3 at 2α = 1.5 (tests/integrate/error_estimate_test.cpp). The first kLayer steps
// are therefore also estimated by Richardson towards finer grids, runs over [t0, t0 + kLayer·h]
// with h/2 and h/4 (7·kLayer steps in all, next to N/2 + N/4 for the shared nodes):
//     e_h ≈ D1 · 2^q/(2^q − 1),   D1 = max_{k ≤ kLayer} ‖x^h_k − x^{h/2}_{2k}‖,
// q = log2(D1/D2) the order observed there (D2 the same between h/2 and h/4), limited to
// [0.5, declared + 2]. The estimate is the larger of the two; the note says when the layer's is.
constexpr std::size_t kLayer = 16;

// The companion runs of an estimate of a run of `problem` that stores the steps `stored`, in the
// order estimate_error has always made them (each run only where the one before allows it).
CompanionRuns run_companions(const InitialValueProblem& problem, const Method& method,
                             const IntegratorOptions& options, std::span<const std::size_t> stored,
                             const std::shared_ptr<std::atomic<bool>>& cancel) {
  const auto start = std::chrono::steady_clock::now();
  CompanionRuns r;
  const std::size_t n = problem.steps;
  if (method.info().adaptive) {
    // An adaptive scheme's error follows its tolerances, not h: the companion is the same grid
    // with tolerances 1000 times tighter (its error is then far below the run's; measured slope
    // of error against tolerance ≈ 1, docs/verification.md).
    constexpr double kTighter = 1e-3;
    IntegratorOptions tight = options;
    tight.abs_tolerance *= kTighter;
    tight.rel_tolerance *= kTighter;
    r.tight = companion(problem, method, tight, stored, n, cancel, r.why);
  } else {
    if (n % 2 == 0 && n >= 4)
      r.half = companion(problem, method, options, stored, n / 2, cancel, r.why);
    if (r.half) {
      if (n % 4 == 0 && n >= 8) {
        r.quarter = companion(problem, method, options, stored, n / 4, cancel, r.why_quarter);
      }
      const std::size_t m = std::min(kLayer, n);
      r.layer_checked = true;
      for (std::size_t i = 0; i < 3 && r.layer_checked; ++i) {
        r.layer[i] =
            first_steps(problem, method, options, m, std::size_t{1} << i, cancel, r.why_layer);
        r.layer_checked = r.layer[i].has_value();
      }
    } else {
      // N odd or too small, or the N/2 run refused or failed: a finer companion with 2N steps.
      std::string why_twice;
      r.twice = companion(problem, method, options, stored, 2 * n, cancel, why_twice);
      if (!r.twice) r.why = (r.why.empty() ? "" : r.why + "; ") + why_twice;
    }
  }
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

// The initial layer from its three runs (see kLayer).
void estimate_initial_layer(const CompanionRuns& r, std::size_t m, int declared, ErrorEstimate& e) {
  if (!r.layer_checked) {
    e.note += (e.note.empty() ? "" : "; ") + r.why_layer + ": the initial layer is not checked";
    return;
  }
  std::size_t rows = 0;
  const double d1 = max_difference(*r.layer[0], *r.layer[1], nullptr, rows);
  const double d2 = max_difference(*r.layer[1], *r.layer[2], nullptr, rows);
  if (!(d1 > 0.0)) return;
  const double q = d2 > 0.0 ? std::clamp(std::log2(d1 / d2), 0.5, declared + 2.0) : declared + 2.0;
  const double layer = d1 * std::pow(2.0, q) / (std::pow(2.0, q) - 1.0);
  if (!(layer > e.value)) return;
  char text[160];
  std::snprintf(text, sizeof text,
                "the first %zu steps, checked with h/2 and h/4, have the larger error %.3g (order "
                "%.2f there; %.3g at the nodes the N/2 run shares)",
                m, layer, q, e.value);
  e.note += (e.note.empty() ? "" : "; ") + std::string(text);
  e.value = layer;
}

// The estimate of `solution` from its companion runs.
void combine(const InitialValueProblem& problem, const Method& method, const CompanionRuns& r,
             const Solution& solution, ErrorEstimate& e) {
  const std::size_t n = problem.steps;
  const RowMatrixXd& x = solution.x;
  e.wall_seconds = r.wall_seconds;
  if (method.info().adaptive) {
    if (!r.tight) {
      e.note = r.why;
    } else {
      std::size_t rows = 0;
      e.value = max_difference(x, *r.tight, nullptr, rows);
      e.nodes = rows;
      e.method = "tolerances / 1000 (adaptive scheme)";
    }
    return;
  }
  const int declared = method.declared_order(problem.model);
  if (r.half) {
    std::size_t rows = 0;
    const double d1 = max_difference(x, *r.half, nullptr, rows);
    e.nodes = rows;
    e.order = declared;
    e.method = "richardson (N/2)";
    if (r.quarter) {
      std::size_t shared = 0;
      const double d1_shared = max_difference(x, *r.half, &*r.quarter, shared);
      const double d2 = max_difference(*r.half, *r.quarter, nullptr, shared);
      e.method = "richardson (N/2, N/4)";
      if (d1_shared > 0.0 && d2 > 0.0) {
        e.observed_order = std::log2(d2 / d1_shared);
        e.order = std::clamp(e.observed_order, 0.5, declared + 2.0);
        if (e.observed_order < declared - 0.5) {
          e.note = "observed order below the declared " + std::to_string(declared) +
                   ": the steps are not in the asymptotic range, or the solution's regularity "
                   "caps the order; the estimate uses the observed order";
        }
      }
    } else if (!r.why_quarter.empty()) {
      e.note = r.why_quarter + "; the declared order is used";
    } else {
      e.note = "N is not a multiple of 4: the declared order is used";
    }
    e.value = d1 / (std::pow(2.0, e.order) - 1.0);
    estimate_initial_layer(r, std::min(kLayer, n), declared, e);
  } else if (!r.twice) {
    e.note = r.why;
  } else {
    std::size_t rows = 0;
    const double d = max_difference(x, *r.twice, nullptr, rows);
    e.nodes = rows;
    e.order = declared;
    const double q = std::pow(2.0, e.order);
    e.value = d * q / (q - 1.0);
    e.method = "richardson (2N)";
    e.note = r.why.empty() ? "N is odd: a companion run with 2N steps, the declared order"
                           : r.why + "; a companion run with 2N steps instead";
  }
}

// The note when the estimate is not made at all; empty when it is.
std::string no_estimate(const IntegratorOptions& options, const Solution& solution) {
  if (options.error_estimate == ErrorEstimateKind::kNone) {
    return "not requested (method.error_estimate = \"none\")";
  }
  if (solution.status == Status::kEvent) {
    return "the run stopped at a terminal event (the companion runs compare whole runs)";
  }
  if (!solution.ok()) return "the run did not succeed";
  return {};
}

}  // namespace

void estimate_error(const InitialValueProblem& problem, const Method& method,
                    const IntegratorOptions& options, Solution& solution) {
  ErrorEstimate& e = solution.error_estimate;
  e = ErrorEstimate{};
  e.note = no_estimate(options, solution);
  if (!e.note.empty()) return;
  combine(problem, method, run_companions(problem, method, options, solution.step, nullptr),
          solution, e);
}

bool ConcurrentErrorEstimate::applies(const InitialValueProblem& problem,
                                      const IntegratorOptions& options) {
  return options.error_estimate != ErrorEstimateKind::kNone && options.threads != 1 &&
         options.output_times.empty() && options.events.empty() &&
         problem.model.dimension() < kMaxConcurrentDimension &&
         std::thread::hardware_concurrency() >= 2;
}

ConcurrentErrorEstimate::ConcurrentErrorEstimate(const InitialValueProblem& problem,
                                                 const Method& method,
                                                 const IntegratorOptions& options,
                                                 std::vector<std::size_t> stored)
    : problem_(problem),
      method_(method),
      options_(options),
      stored_(std::move(stored)),
      cancel_(std::make_shared<std::atomic<bool>>(false)) {
  // std::async(launch::async) runs on its own thread at once; the future's exception (a
  // companion that throws, as estimate_error would have thrown) is rethrown by finish().
  runs_ = std::async(std::launch::async, [this] {
    internal::lower_this_thread_priority();  // the main run keeps its core (background_thread.hpp)
    return std::make_shared<const CompanionRuns>(
        run_companions(problem_, method_, options_, stored_, cancel_));
  });
}

ConcurrentErrorEstimate::~ConcurrentErrorEstimate() {
  // Not finished (the main run threw): stop the companions at their next step and wait for them.
  if (runs_.valid()) {
    cancel_->store(true, std::memory_order_relaxed);
    runs_.wait();
  }
}

void ConcurrentErrorEstimate::finish(Solution& solution) {
  ErrorEstimate& e = solution.error_estimate;
  e = ErrorEstimate{};
  e.note = no_estimate(options_, solution);
  if (!e.note.empty() || solution.step != stored_) {
    // No estimate for this run (the companions' results are dropped, as estimate_error would not
    // have made them), or — never expected — other stored steps than predicted: the sequential
    // estimate then runs.
    cancel_->store(true, std::memory_order_relaxed);
    runs_.wait();
    runs_ = {};
    if (e.note.empty()) estimate_error(problem_, method_, options_, solution);
    return;
  }
  const std::shared_ptr<const CompanionRuns> runs = runs_.get();
  combine(problem_, method_, *runs, solution, e);
  e.concurrent = true;
}

Solution integrate_to_tolerance(const InitialValueProblem& problem, const Method& method,
                                const IntegratorOptions& options,
                                const std::function<void(std::size_t)>& before_run) {
  if (!(options.tolerance > 0.0) || !std::isfinite(options.tolerance)) {
    throw ValidationError("method.tolerance = " + format_number(options.tolerance) +
                          " must be a positive number");
  }
  IntegratorOptions o = options;
  if (method.info().adaptive) {
    throw ValidationError(
        "method.tolerance doubles time.steps, which does not set the error of "
        "the adaptive method.scheme = \"" +
        std::string(method.name()) +
        "\": give it method.abs_tolerance and method.rel_tolerance instead");
  }
  if (o.error_estimate == ErrorEstimateKind::kNone) {
    throw ValidationError(
        "method.tolerance needs an error estimate: method.error_estimate = \"none\" is set");
  }
  InitialValueProblem p = problem;
  std::vector<ToleranceRun> history;
  for (;;) {
    if (before_run) before_run(p.steps);
    const auto start = std::chrono::steady_clock::now();
    Solution solution = integrate(p, method, o);
    estimate_error(p, method, o, solution);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double estimate = solution.error_estimate.value;
    // Interrupted during the companion runs: the trajectory is complete but the tolerance was
    // not verified (the interrupt hook keeps answering true once it has, options.hpp).
    if (solution.ok() && !std::isfinite(estimate) && o.interrupt && o.interrupt()) {
      solution.status = Status::kInterrupted;
      solution.message = "interrupted during the error estimate of the run with " +
                         std::to_string(p.steps) + " steps (method.tolerance not verified)";
    }
    history.push_back({p.steps, estimate, seconds, std::string(to_string(solution.status))});
    solution.tolerance_runs = history;
    if (!solution.ok() || estimate <= options.tolerance) return solution;
    std::string reason;
    if (!std::isfinite(estimate)) {
      reason = "the run has no error estimate (" + solution.error_estimate.note + ")";
    } else if (2 * p.steps > options.max_steps) {
      reason = "doubling to " + std::to_string(2 * p.steps) +
               " steps would pass method.max_steps = " + std::to_string(options.max_steps);
    }
    if (!reason.empty()) {
      solution.status = Status::kInaccurate;
      char reached[32];
      std::snprintf(reached, sizeof reached, "%.3e", estimate);
      solution.message = "method.tolerance = " + format_number(options.tolerance) +
                         " not reached: error estimate " + reached +
                         " at N = " + std::to_string(p.steps) + "; " + reason;
      return solution;
    }
    p.steps *= 2;
  }
}

}  // namespace fracvi
