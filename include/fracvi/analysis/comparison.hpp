// The comparison of schemes on one problem (issue 12, `fracvi compare`, Python fracvi.compare):
// every scheme at every step count, measured against one independent reference.
//
// For a run with N steps on [t0, t0 + T] (h = T/N, every step stored, no mirror run, no error
// estimate, so the wall time is that of the integration alone) a row records
//   final_error       ‖x_N − x_ref(t_N)‖_∞
//   max_error         max_k ‖x_k − x_ref(t_k)‖_∞
//   energy_error      max_k |E_k − E_ref(t_k)|            E = ½ vᵀMv + U(x, t)
//   dissipated_error  max_k |W_k − W_ref(t_k)|            W_ref(t) = E_ref(t0) − E_ref(t)
//   balance_error     max_k |E_k + W_k − E_0|             (the run's own consistency check)
// with W the scheme's dissipated work (fracvi/integrate/solution.hpp). In the continuum the energy
// balance E(t) + W(t) = E(t0) is exact, which defines the reference dissipated work without a
// second quadrature of the damping; the energy and dissipated-energy errors therefore measure how
// well a scheme tracks the true energy decay, not only its own bookkeeping.
//
// A scheme that does not apply to the problem, or a step count beyond its stability bound, is a
// row with status "not applicable" and the reason; a run that fails is a row with its status and
// message (errors NaN).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "fracvi/integrate/solution.hpp"

namespace fracvi {

struct ComparisonRow {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::string scheme;
  std::size_t steps = 0;
  double h = 0.0;
  int declared_order = 0;  ///< 0 when the scheme did not run
  std::string status;      ///< "success", the run's failure status, or "not applicable"
  std::string message;     ///< empty on success; otherwise why
  double final_error = kNaN;
  double max_error = kNaN;
  double energy_error = kNaN;
  double dissipated_error = kNaN;
  double balance_error = kNaN;
  double wall_seconds = kNaN;  ///< the best of the repeats
  std::size_t newton_iterations = 0;
};

/// The energy E_k and dissipated work W_k over time of every scheme that ran with `steps` steps,
/// with the reference's (the energy-tracking figure).
struct EnergyTrack {
  std::size_t steps = 0;  ///< 0: no track (no energy reference)
  Eigen::VectorXd t, reference_energy, reference_dissipated;
  std::vector<std::string> schemes;
  /// One column per scheme; NaN past the last step a failed run completed.
  std::vector<Eigen::VectorXd> energy, dissipated;
};

struct Comparison {
  std::string problem;
  std::string reference;            ///< e.g. "exact solution" or "fvi-lobatto4 with 40960 steps"
  std::string energy_reference;     ///< how E_ref was obtained; empty if there is none
  std::vector<ComparisonRow> rows;  ///< scheme-major, step counts ascending
  EnergyTrack energy;
};

/// Thrown by a RunScheme when the scheme does not apply (or the step is beyond its bound).
class NotApplicable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One run of the compared problem with `scheme` and `steps` steps, every step stored, without
/// mirror run or error estimate. Throws NotApplicable with the reason when it cannot run.
using RunScheme = std::function<Solution(const std::string& scheme, std::size_t steps)>;

/// The reference at grid node k of the grid with n steps (t the node's time).
struct ComparisonReference {
  std::string description;
  std::function<void(std::size_t n, std::size_t k, double t, Eigen::Ref<Eigen::VectorXd> x)>
      position;
  /// E_ref at the node; empty when there is no energy reference (energy columns NaN).
  std::function<double(std::size_t n, std::size_t k, double t)> energy;
  std::string energy_description;
};

/// The reference given by a finer run whose step count is a multiple of every compared one.
/// Its energy is the run's E_k.
ComparisonReference fine_run_reference(Solution fine, const std::string& description);

struct ComparisonOptions {
  std::size_t energy_steps = 0;  ///< the N of the energy track (one of `steps`); 0: none
  int repeat = 1;                ///< runs per (scheme, N); the wall time is the best
  /// Called after each row (progress display); may be empty.
  std::function<void(const ComparisonRow&, std::size_t done, std::size_t total)> on_row;
};

/// Runs every scheme at every step count (ascending, ≥ 1) and measures each run against
/// `reference`. Throws std::invalid_argument for bad arguments (no schemes, steps not increasing,
/// energy_steps not among them, repeat < 1).
Comparison compare_schemes(const std::string& problem, double t0, double interval,
                           std::span<const std::string> schemes, std::span<const std::size_t> steps,
                           const RunScheme& run, const ComparisonReference& reference,
                           const ComparisonOptions& options = {});

}  // namespace fracvi
