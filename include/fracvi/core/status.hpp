// How a run ended (DESIGN §4, "numerical failure is data"). Bottom layer: every layer may use it.
#pragma once

#include <string_view>

namespace fracvi {

enum class Status {
  kRunning,        ///< steps remain (hand-stepped Integrator only)
  kSuccess,        ///< all N steps done and the run's own checks found nothing wrong
  kNewtonFailure,  ///< Newton did not reach the tolerance within max_iterations
  kNonFinite,      ///< a NaN or infinity appeared (residual, iterate, state or diagnostics)
  kCallbackError,  ///< the potential or the forcing threw an exception (its what() is in message)
};

std::string_view to_string(Status status);

}  // namespace fracvi
