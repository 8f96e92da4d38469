// Parameters as they may appear in a value-parameterised test's name (the name generators of
// INSTANTIATE_TEST_SUITE_P: letters, digits and '_' only).
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace fracvi::test {

/// "riemann_liouville" for "riemann-liouville", "fvi_gl" for "fvi-gl": '-' and '.' become '_'.
inline std::string name_tag(std::string_view text) {
  std::string out(text);
  for (char& ch : out) {
    if (ch == '-' || ch == '.') ch = '_';
  }
  return out;
}

/// "0_5" for 0.5 (printed with %g).
inline std::string name_tag(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", value);
  return name_tag(std::string_view(buf));
}

}  // namespace fracvi::test
