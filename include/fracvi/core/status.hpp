// How a run ended (DESIGN §4, "numerical failure is data"). Bottom layer: every layer may use it.
#pragma once

#include <optional>
#include <string_view>

namespace fracvi {

enum class Status {
  kRunning,        ///< steps remain (hand-stepped Integrator only)
  kSuccess,        ///< all N steps done and the run's own checks found nothing wrong
  kNewtonFailure,  ///< Newton did not reach the tolerance within max_iterations
  kNonFinite,      ///< a NaN or infinity appeared (residual, iterate, state or diagnostics)
  kCallbackError,  ///< the potential or the forcing threw an exception (its what() is in message)
  /// The run's own diagnostics found it blowing up: the damping put energy in, or the state grew
  /// by orders of magnitude beyond its scale (integrator.hpp, "Health checks"). The run stops at
  /// the first detection; the trajectory up to that step is kept.
  kUnstable,
  /// All steps done, but the energy balance error exceeded the documented fraction of the energy
  /// scale at some step (integrator.hpp, "Health checks"): the numbers are not to be trusted.
  kInaccurate,
  /// Stopped on request before the last step (IntegratorOptions::interrupt: SIGINT, SIGTERM or
  /// SIGHUP in `fracvi run`, Ctrl-C in Python); the trajectory up to the last completed step is
  /// kept, as for a failure.
  kInterrupted,
  /// Stopped by a terminal event (IntegratorOptions::events, core/event.hpp) before the last
  /// step: not a failure. The rows end with the step in which the event was found; the crossing
  /// itself (time and interpolated state) is in Solution::events.
  kEvent,
};

std::string_view to_string(Status status);
/// The inverse of to_string (summary.json's "status"); nullopt for any other name.
std::optional<Status> parse_status(std::string_view name);

}  // namespace fracvi
