// The one error type for bad input (STYLE.md, "Errors"): thrown before step 1, its message names
// the field, its value and the rule, e.g. "model.mass is not symmetric positive definite
// (smallest eigenvalue -0.3)". format_number() writes values the way every message does.
#pragma once

#include <stdexcept>
#include <string>

namespace fracvi {

/// Thrown for invalid input, before any step is taken.
class ValidationError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Shortest round-trip representation of a double ("1e-20", not std::to_string's "0.000000"):
/// the value in a message is the value the user wrote.
std::string format_number(double value);

}  // namespace fracvi
