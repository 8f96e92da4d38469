// The method registry: one table of every time-stepping scheme fracvi has (DESIGN §4.1).
//
// A scheme is one stepper file (src/schemes/<name>.cpp) that defines its SchemeInfo row, plus one
// line in src/schemes/registry.cpp. Everything that integrates — the Integrator, `fracvi run`,
// `fracvi convergence`, `fracvi methods`, Python's fracvi.methods() and the docs table of schemes
// (checked against `fracvi methods --json` by scripts/check-docs.py) — reads this table.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/fractional/weights.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/stepper.hpp"

namespace fracvi {

/// The stability bound of a scheme on the linear test problem M x'' + R D^{2α} x + K x = 0 for a
/// given problem (docs/theory/stability.md).
struct StabilityBound {
  /// The problem's step h satisfies the bound.
  bool stable = true;
  /// The largest stable step (strict: h < largest_step); +∞ when every h is stable, 0 when none.
  double largest_step = 0.0;
  /// The bound is the exact threshold of the linear test problem (a root of the characteristic
  /// equation crosses the unit circle there, so a step just beyond it grows). False for a
  /// sufficient condition: a measured table with a safety margin, or a bound that strong damping
  /// may lift (the Lobatto schemes' undamped bound with R ≠ 0).
  bool sharp = true;
  /// The bound as an inequality with this problem's numbers, e.g.
  /// "lambda_max(M^-1 R) (h/2)^(2-2alpha) = 1.43 must be < 1".
  std::string rule;
};

struct SchemeInfo {
  std::string_view name;        ///< the registry key, e.g. "fvi-bdf2"
  std::string_view summary;     ///< one line
  std::string_view reference;   ///< where the scheme comes from
  std::string_view order_rule;  ///< declared order in words, e.g. "1 (2 when R = 0)"
  int stages = 1;               ///< unknown states per step
  bool variational = true;      ///< derived from a (restricted) discrete variational principle
  /// The generating function δ of the scheme's Δ^α_± when the scheme is the restricted discrete
  /// variational principle of the midpoint action sum (lagrangian/action_sum.hpp) with those
  /// Δ^α_±, i.e. when it has a boundary value form (`fracvi bvp`); nullopt otherwise.
  std::optional<CqScheme> variational_quadrature;
  bool has_mirror = false;  ///< the backward mirror run exists (Solution::mirror_error)
  /// E_k + W_k − E_0 = 0 to round-off for quadratic, time-independent U (any R, α, f).
  bool exact_balance = false;
  /// method.history = "fast" is available: a memory whose cost per step does not grow like N
  /// (a sum-of-exponentials memory, independent of N; for pi-trapezoid, whose product-integration
  /// weights have no exponential fit, the FFT-blocked sums of OnlineConvolution, O(log² N) per
  /// step). "auto" uses it where it pays. Without it the memory is summed directly (O(N) per
  /// step) and "fast" is refused before step 1.
  bool fast_history = false;
  /// The loosest per-weight accuracy ε the fast history's accuracy budget may choose
  /// (history_budget.hpp): kMeasuredHistoryCeiling for a scheme whose error constant the budget's
  /// κ was measured against, kAutoHistoryCeiling otherwise.
  double history_budget_ceiling = kAutoHistoryCeiling;
  /// The convolution quadrature (of order 2α) of the damping force in the scheme's momenta p_k.
  /// Its weights ω carry round-off in the positions into the velocities:
  /// ‖δp_k‖ ≤ (h/2) ‖R‖ h^{−2α} Σ_{m≤k} |ω_m| max_j ‖δx_j‖ (the method-parameterised tests use this
  /// bound; Σ|ω| ≤ 2^{2α} for Grünwald–Letnikov, but grows like k^{2α} for the trapezoidal rule).
  CqScheme momentum_quadrature = CqScheme::kGrunwaldLetnikov;
  /// method.load = "moments" (ForcingLoad::kMoments) is available.
  bool forcing_moments = false;
  /// method.split = "series" (TaylorSplit::kSeries) is available.
  bool series_split = false;
  /// The step is chosen by an error controller from method.abs_tolerance and
  /// method.rel_tolerance (dopri5); the grid step h only samples its dense output, so the error
  /// follows the tolerances and the declared order is the order in the tolerance, not in h.
  bool adaptive = false;
  /// Its stepper can save and restore its state (Stepper::visit_state), so that a run can write
  /// checkpoints (`[output] checkpoint_every`) and be resumed bit-for-bit; refused before step 1
  /// otherwise.
  bool checkpoints = false;
  /// options.start = StartValue::kExplicitEuler (x_1 = x_0 + h v_0, a negative control of the
  /// scheme's own start) is honoured; refused before step 1 otherwise.
  bool explicit_euler_start = false;
  /// Why the scheme refuses a non-conservative force g(x, v, t) (MechanicalModel::state_force),
  /// one clause for check_applicable's message; "" when its step takes one (docs/theory/forces.md).
  /// The default refuses, so that a new scheme states how it treats such forces.
  std::string_view no_state_force = "its discrete equations have no term for a force g(x, v, t)";
  std::string_view applies_to;      ///< where it applies, in words ("every model", "2α = 1")
  std::string_view stability_rule;  ///< the stability bound in words
  /// The order the scheme reaches on smooth solutions of this model.
  int (*declared_order)(const MechanicalModel& model) = nullptr;
  /// "" when the scheme applies to the problem, else the rule it breaks (one sentence).
  std::string (*applicability)(const InitialValueProblem& problem) = nullptr;
  StabilityBound (*stability)(const InitialValueProblem& problem) = nullptr;
  /// A stepper for a validated problem (references `problem`, which must outlive it).
  std::unique_ptr<Stepper> (*make_stepper)(const InitialValueProblem& problem,
                                           const IntegratorOptions& options) = nullptr;
};

/// Every registered scheme, in the order `fracvi methods` prints them.
std::span<const SchemeInfo* const> registered_schemes();

/// The registered scheme called `name`, or null.
const SchemeInfo* find_scheme(std::string_view name);

/// "fvi-gl, fvi-bdf2" (for messages).
std::string scheme_names();
/// The names of the schemes with a property, e.g. scheme_names_with(&SchemeInfo::checkpoints).
std::string scheme_names_with(bool SchemeInfo::*property);

/// The registry as text columns, one entry per scheme with the keys name, order, stages,
/// variational, mirror, exact_balance, applies_to, stability, summary, reference (what
/// `fracvi methods --json` prints and Python's fracvi.methods() returns, plus fast_history and
/// adaptive; values are strings, integers or booleans).
struct SchemeRow {
  std::string name, order, applies_to, stability, summary, reference;
  int stages = 1;
  bool variational = true, mirror = false, exact_balance = false, fast_history = false,
       adaptive = false;
};
std::vector<SchemeRow> scheme_table();

/// A Method names a registered scheme; the default is the paper's `fvi-gl`.
class Method {
 public:
  Method();
  explicit Method(const SchemeInfo& info) : info_(&info) {}

  [[nodiscard]] std::string_view name() const { return info_->name; }
  [[nodiscard]] const SchemeInfo& info() const { return *info_; }
  /// The order the scheme is designed to reach on smooth solutions of `model`.
  [[nodiscard]] int declared_order(const MechanicalModel& model) const {
    return info_->declared_order(model);
  }
  friend bool operator==(const Method& a, const Method& b) { return a.info_ == b.info_; }

 private:
  const SchemeInfo* info_;
};

/// The paper's scheme, `DiscEqs` (Grünwald–Letnikov memory).
Method fvi_gl();
/// The BDF2 convolution-quadrature FVI (docs/theory/fvi_bdf2.md).
Method fvi_bdf2();

/// The registered scheme called `name`, or nullopt.
std::optional<Method> parse_method(std::string_view name);

/// "fvi-gl, fvi-bdf2": the registered schemes with a boundary value form (for messages).
std::string boundary_value_scheme_names();

/// The δ of Δ^α_± of `info`'s boundary value form (SchemeInfo::variational_quadrature). Throws
/// ValidationError `method.scheme = "X" has no boundary value form (schemes with one: …)` when it
/// has none.
CqScheme boundary_value_quadrature(const SchemeInfo& info);

/// Throws ValidationError when `method` does not apply to `problem`, `problem`'s step is beyond
/// the method's stability bound, or `options` ask for a fast history the method does not have.
/// The message names the field (method.scheme, time.steps or method.history), the value and the
/// rule, and for the stability bound the largest stable step and the smallest stable number of
/// steps.
void check_applicable(const InitialValueProblem& problem, const Method& method,
                      const IntegratorOptions& options = {});

/// `method.scheme = "auto"` (the problem files' default): the scheme is chosen for the problem by
/// choose_scheme(). Not a registry name.
inline constexpr std::string_view kAutoScheme = "auto";

/// The rule of "auto" in words (docs, `fracvi methods`, messages).
std::string_view auto_scheme_rule();

/// The scheme "auto" runs: the first of fvi-lobatto3, fvi-midpoint, fvi-bdf2, fvi-gl that applies
/// to `problem` with `options` (check_applicable: model, stability bound at this step, history,
/// load). Chosen from the comparison study (docs/comparison.md): fvi-lobatto3 is 10³ and more
/// times as accurate as the second-order schemes at equal N for 3–5 times the cost per step, and
/// within 1.4–4× of the quickest scheme to 1e-6 on every problem there; fvi-midpoint is stable for
/// every h where it does not apply (0 <= 2α < 2); fvi-bdf2 covers 2α = 2. `admissible`, when
/// given, excludes candidates for what the run needs beyond the problem (e.g. checkpoints); fvi-gl,
/// the last resort, is always tried. Throws the ValidationError of the last candidate when none
/// applies.
Method choose_scheme(const InitialValueProblem& problem, const IntegratorOptions& options = {},
                     const std::function<bool(const SchemeInfo&)>& admissible = {});

}  // namespace fracvi
