#!/usr/bin/env bash
# The sanitizer run (issue 14 item 7): the whole test suite under AddressSanitizer + UBSan
# (with float-cast-overflow) and libstdc++'s _GLIBCXX_ASSERTIONS — the `asan` preset.
#
#   scripts/sanitize.sh [CTEST ARGS...]      e.g. scripts/sanitize.sh -R checkpoint
#
# Builds build/asan (the library, the CLI, the tests, the C++ examples and the Python module; no
# benchmarks; -O1 -g1 instead of -O2 -g: about half the compile time, line numbers kept for the
# reports), then runs `ctest --preset asan` with the given arguments (all tests by default; the
# allocation-counting tests skip themselves under ASan, which allocates on its own). ccache is used
# when installed, so a rebuild after a small change takes minutes. The build runs under
# `nice -n ${NICE:-10}` with ${JOBS:-all cores} jobs (a shared machine: NICE=19 JOBS=2).
# Prints the build and test times; exit status that of ctest (1 on any failure or sanitizer
# report: ASan/UBSan abort the test with the report on its output).
# Measured (docs/verification.md#sanitizers): see there for the times on the 2-core VM.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=${JOBS:-$(nproc)}
niceness=${NICE:-10}
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
start=$(date +%s)
nice -n "$niceness" cmake --preset asan "${launcher[@]}" >/dev/null
nice -n "$niceness" cmake --build --preset asan -j "$jobs"
built=$(date +%s)
echo "sanitize: build $(((built - start) / 60)) min $(((built - start) % 60)) s"
status=0
# UBSan: stop at the first report (it only prints by default) and show where.
UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1} \
  nice -n "$niceness" ctest --preset asan -j "$jobs" "$@" || status=$?
done=$(date +%s)
echo "sanitize: tests $(((done - built) / 60)) min $(((done - built) % 60)) s (exit status $status)"
exit "$status"
