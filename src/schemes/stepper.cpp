#include "fracvi/schemes/stepper.hpp"

#include <cstdarg>
#include <cstdio>
#include <exception>
#include <limits>

namespace fracvi {

Status Stepper::step() noexcept {
  message_[0] = '\0';
  detail_[0] = '\0';
  const char* detail = "unknown exception";
  try {
    return advance();
  } catch (const std::exception& e) {
    std::snprintf(detail_.data(), detail_.size(), "%s", e.what());
    detail = nullptr;
  } catch (...) {
  }
  if (detail != nullptr) std::snprintf(detail_.data(), detail_.size(), "%s", detail);
  return fail(Status::kCallbackError, "the potential or the forcing threw");
}

Status Stepper::fail(Status status, const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  std::vsnprintf(message_.data(), message_.size(), format, args);
  va_end(args);
  return status;
}

double Stepper::mirror_error(const RowMatrixXd&, std::span<const std::size_t>) const {
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace fracvi
