// libFuzzer target: the problem-file reader and the checks before step 1 (issue 14 item 7).
//
// Any input must end in a parsed problem or a ProblemFileError (one line, the README's exit 2);
// every other exception, a crash, a sanitizer report or a hang is a finding. prepare_run is
// included because it builds the model (expressions, matrices, the scheme's applicability and
// stability bound) from what the reader accepted. Run by scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    fracvi::ProblemSpec spec = fracvi::parse_problem(text, "<fuzz>");
    // Keep the memory of one input bounded (a real run would refuse what does not fit, which
    // check_storage tests; the fuzzer's own limit is 2 GB).
    if (spec.dim > 10000 || spec.steps > 10'000'000) return 0;
    (void)fracvi::prepare_run(std::move(spec));
  } catch (const fracvi::ProblemFileError&) {
    // bad input, reported as such: fine
  }
  return 0;
}
