#!/usr/bin/env bash
# Fuzzes the problem-file reader (with the checks before step 1) and the expression parser with
# libFuzzer under AddressSanitizer, UBSan (incl. float-cast-overflow) and _GLIBCXX_ASSERTIONS
# (issue 14 item 7). Not part of ctest: a bounded run a developer starts.
#
#   scripts/fuzz.sh [RUNS] [SECONDS]     (default 1000000 executions per target, at most 1200 s)
#
# Builds the `fuzz` preset (clang; the library only, about 5 minutes on 2 cores the first time),
# seeds the problem-file corpus with examples/*.toml and fuzz/seeds/problem_file/, the expression
# corpus with the formulas of those files and fuzz/seeds/expression/ (the formula functions no
# example uses), gives the expression target the grammar's words (fuzz/expression.dict), and runs
# each target. An input counts as a hang after 30 s: a large `dim` legitimately costs O(d) before
# step 1 (a 615 589-DOF chain takes 2.7 s in this instrumented build, 0.14 s in release), and a
# loaded machine triples that; the first run's 10 s limit reported it as a false hang. Prints each target's executions and time; exit status 1
# and the crashing input in build/fuzz/findings/ on a finding.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-1000000}
seconds=${2:-1200}
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz --target problem_file_fuzzer expression_fuzzer
work=build/fuzz/corpus
findings=build/fuzz/findings
mkdir -p "$work/problem_file" "$work/expression" "$findings"
cp examples/*.toml fuzz/seeds/problem_file/*.toml "$work/problem_file/"
cp fuzz/seeds/expression/* "$work/expression/"
# One seed per formula of the examples: the quoted strings of potential/force/position lines.
n=0
grep -hoE '(potential|force|position|velocity|lagrangian) *= *\[?"[^"]+"' examples/*.toml |
  sed -E 's/^[^"]*"//; s/"$//' | while IFS= read -r formula; do
    n=$((n + 1))
    printf '%s' "$formula" >"$work/expression/seed$n"
  done
status=0
for target in problem_file expression; do
  log=build/fuzz/${target}.log
  echo "== ${target}_fuzzer: up to $runs executions or $seconds s"
  dict=()
  if [[ -f fuzz/${target}.dict ]]; then dict=(-dict="fuzz/${target}.dict"); fi
  if ! build/fuzz/fuzz/${target}_fuzzer -runs="$runs" -max_total_time="$seconds" -timeout=30 \
      "${dict[@]}" \
      -rss_limit_mb=2048 -max_len=8192 -print_final_stats=1 \
      -artifact_prefix="$findings/${target}-" "$work/$target" >"$log" 2>&1; then
    echo "   FINDING: see $log and $findings/"
    status=1
  fi
  grep -E "^Done [0-9]+ runs|stat::number_of_executed_units|stat::peak_rss_mb" "$log" | sed 's/^/   /'
done
exit $status
