#include "fracvi/integrate/solution.hpp"

namespace fracvi {

std::string_view to_string(Status status) {
  switch (status) {
    case Status::kRunning: return "running";
    case Status::kSuccess: return "success";
    case Status::kNewtonFailure: return "newton-failure";
    case Status::kNonFinite: return "non-finite";
    case Status::kCallbackError: return "callback-error";
  }
  return "unknown";
}

}  // namespace fracvi
