#include <array>
#include <charconv>
#include <cmath>
#include <string>

#include "fracvi/core/error.hpp"
#include "fracvi/core/newton_options.hpp"
#include "fracvi/core/status.hpp"

namespace fracvi {

std::string_view to_string(Status status) {
  switch (status) {
    case Status::kRunning: return "running";
    case Status::kSuccess: return "success";
    case Status::kNewtonFailure: return "newton-failure";
    case Status::kNonFinite: return "non-finite";
    case Status::kCallbackError: return "callback-error";
    case Status::kUnstable: return "unstable";
    case Status::kInaccurate: return "inaccurate";
  }
  return "unknown";
}

std::string format_number(double value) {
  std::array<char, 64> buf{};
  const auto result = std::to_chars(buf.data(), buf.data() + buf.size(), value);
  return {buf.data(), result.ptr};
}

void validate(const NewtonOptions& n, const char* prefix) {
  const std::string p(prefix);
  if (!std::isfinite(n.relative_tolerance) || n.relative_tolerance < 0.0) {
    throw ValidationError(p + ".relative_tolerance = " + format_number(n.relative_tolerance) +
                          " must be finite and >= 0");
  }
  if (!std::isfinite(n.absolute_tolerance) || n.absolute_tolerance < 0.0) {
    throw ValidationError(p + ".absolute_tolerance = " + format_number(n.absolute_tolerance) +
                          " must be finite and >= 0");
  }
  if (n.relative_tolerance == 0.0 && n.absolute_tolerance == 0.0) {
    throw ValidationError(p +
                          ".relative_tolerance and absolute_tolerance are both 0: at least "
                          "one must be positive");
  }
  if (n.max_iterations < 1) {
    throw ValidationError(p + ".max_iterations = " + std::to_string(n.max_iterations) +
                          " must be >= 1");
  }
}

}  // namespace fracvi
