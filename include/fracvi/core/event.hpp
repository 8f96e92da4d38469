// Events: scalar functions g(t, x, v) whose zero crossings a run locates, records and may stop at
// (IntegratorOptions::events; docs/theory/dense_output.md). Bottom layer: the Integrator evaluates
// them, formulas from problem files build them (fracvi/integrate/dense_output.hpp, formula_event).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace fracvi {

/// Which sign changes of g count as a crossing.
enum class EventDirection {
  kBoth,     ///< either way
  kRising,   ///< g goes from < 0 to ≥ 0
  kFalling,  ///< g goes from > 0 to ≤ 0
};

std::optional<EventDirection> parse_event_direction(std::string_view name);
std::string_view to_string(EventDirection direction);

/// g(t, x, v). Called once per event at the end of every step and a few times more (the root
/// search on the dense interpolant) in a step where it changes sign. For the step loop to stay
/// allocation-free it must not allocate; it may throw (the run ends with Status::kCallbackError
/// and the exception's what() in the message) and must return a finite number (a NaN or an
/// infinity ends the run with Status::kNonFinite).
using EventFunction = std::function<double(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                           const Eigen::Ref<const Eigen::VectorXd>& v)>;

struct Event {
  std::string name;  ///< in records, messages and files (unique within a run)
  EventFunction function;
  EventDirection direction = EventDirection::kBoth;
  /// Stop the run at the first crossing (Status::kEvent): everything computed is kept.
  bool terminal = false;
};

}  // namespace fracvi
