#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>

#include <unistd.h>

#include "fracvi/core/error.hpp"
#include "fracvi/core/event.hpp"
#include "fracvi/core/memory.hpp"
#include "fracvi/core/newton_options.hpp"
#include "fracvi/core/status.hpp"
#include "fracvi/core/version.hpp"

namespace fracvi {

std::string_view version() {
  return FRACVI_VERSION;
}

std::string_view git_commit() {
  return FRACVI_GIT_COMMIT;
}

std::string version_string() {
  return "fracvi " + std::string(version()) + " (commit " + std::string(git_commit()) + ")";
}

std::string_view to_string(Status status) {
  switch (status) {
    case Status::kRunning: return "running";
    case Status::kSuccess: return "success";
    case Status::kNewtonFailure: return "newton-failure";
    case Status::kNonFinite: return "non-finite";
    case Status::kCallbackError: return "callback-error";
    case Status::kUnstable: return "unstable";
    case Status::kInaccurate: return "inaccurate";
    case Status::kInterrupted: return "interrupted";
    case Status::kEvent: return "event";
  }
  return "unknown";
}

std::optional<Status> parse_status(std::string_view name) {
  for (const Status s : {Status::kRunning, Status::kSuccess, Status::kNewtonFailure,
                         Status::kNonFinite, Status::kCallbackError, Status::kUnstable,
                         Status::kInaccurate, Status::kInterrupted, Status::kEvent}) {
    if (to_string(s) == name) return s;
  }
  return std::nullopt;
}

std::optional<EventDirection> parse_event_direction(std::string_view name) {
  for (const EventDirection d :
       {EventDirection::kBoth, EventDirection::kRising, EventDirection::kFalling}) {
    if (to_string(d) == name) return d;
  }
  return std::nullopt;
}

std::string_view to_string(EventDirection direction) {
  switch (direction) {
    case EventDirection::kBoth: return "both";
    case EventDirection::kRising: return "rising";
    case EventDirection::kFalling: return "falling";
  }
  return "unknown";
}

std::size_t physical_memory_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page_size <= 0) return 0;
  return static_cast<std::size_t>(pages) * static_cast<std::size_t>(page_size);
}

std::string format_bytes(double bytes) {
  static constexpr const char* kUnits[] = {"bytes", "kB", "MB", "GB", "TB", "PB", "EB"};
  std::size_t unit = 0;
  while (bytes >= 1000.0 && unit + 1 < std::size(kUnits)) {
    bytes /= 1000.0;
    ++unit;
  }
  std::array<char, 64> buf{};
  std::snprintf(buf.data(), buf.size(), unit == 0 ? "%.0f %s" : "%.3g %s", bytes, kUnits[unit]);
  return buf.data();
}

void check_fits_in_memory(double bytes, const std::string& what, const std::string& advice) {
  const std::size_t total = physical_memory_bytes();
  if (total == 0 || !(bytes > static_cast<double>(total))) return;
  throw ValidationError(what + " needs " + format_bytes(bytes) +
                        ", more than this machine's memory (" +
                        format_bytes(static_cast<double>(total)) + ")" + advice);
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
