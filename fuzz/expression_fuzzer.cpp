// libFuzzer target: the expression parser, evaluation and exact derivatives (issue 14 item 7).
//
// Any text must parse or throw ExpressionError; a parsed expression is evaluated and
// differentiated (twice) at a few points, which must not crash (non-finite values are allowed:
// the callers check them). Everything else is a finding. Run by scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/expression/expression.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;  // formulas are short; long inputs only slow the search
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const fracvi::Expression e = fracvi::Expression::parse(text, {"x1", "x2", "t"});
    for (const double p : {0.0, 0.5, -1.25, 3.0}) {
      (void)e({p, 1.0 - p, p * p});
      const fracvi::Expression d = e.derivative(0);
      (void)d({p, 1.0 - p, p * p});
      (void)d.derivative(2)({p, 0.5, 1.0});
    }
    (void)e.polynomial_degree();
    // The printed form parses back (Expression::to_string's contract).
    (void)fracvi::Expression::parse(e.to_string(), {"x1", "x2", "t"});
  } catch (const fracvi::ExpressionError&) {
    // malformed formula, reported with its column: fine
  }
  return 0;
}
