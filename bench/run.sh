#!/usr/bin/env bash
# Runs every benchmark of bench/ once and writes what they print to bench-results/ (one file per
# program) — the numbers bench/RESULTS.md records. Usage (from the repository root):
#
#   cmake --preset bench && cmake --build --preset bench && bench/run.sh [build/bench] [--quick]
#
# --quick runs each Google Benchmark for a short time and the long fractional-chain run with
# N = 10^5 instead of 10^6 (about a minute instead of about fifteen). Benchmarks want an idle
# machine: OpenMP threads on busy cores make the multi-core numbers meaningless.
set -euo pipefail
build=${1:-build/bench}
quick=${2:-}
out=bench-results
mkdir -p "$out"
min_time=0.5
steps=1000000
if [ "$quick" = "--quick" ]; then
  min_time=0.05
  steps=100000
fi
{
  echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2) ($(nproc) cores)"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
  grep -E '^(CMAKE_BUILD_TYPE|FRACVI_NATIVE):' "$build/CMakeCache.txt" || true
} | tee "$out/machine.txt"
gbench=(--benchmark_min_time="$min_time" --benchmark_repetitions=3
        --benchmark_report_aggregates_only=true)
"$build/bench/history_bench" --benchmark_min_time="$min_time" | tee "$out/history_bench.txt"
"$build/bench/step_bench" "${gbench[@]}" | tee "$out/step_bench.txt"
"$build/bench/chain_bench" "${gbench[@]}" | tee "$out/chain_bench.txt"
"$build/bench/expression_bench" "${gbench[@]}" | tee "$out/expression_bench.txt"
"$build/bench/pi_trapezoid_bench" --benchmark_min_time="$min_time" | tee "$out/pi_trapezoid_bench.txt"
# Benchmark 2 of issue 6: d = 1000, N = 10^6, β = 1.5 — linear and FPUT chain, all cores and one.
"$build/bench/fractional_chain" 1000 "$steps" 0 1 0 | tee "$out/fractional_chain_linear.txt"
"$build/bench/fractional_chain" 1000 "$steps" 0 1 1 | tee "$out/fractional_chain_fput.txt"
echo "results in $out/"
