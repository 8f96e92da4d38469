#!/usr/bin/env bash
# Installs a built tree into a temporary prefix, builds tests/consumer against it with
# find_package(fracvi), runs it, and runs the installed CLI (which must find its plotting scripts).
# Usage: test-install.sh BUILD_DIR
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >/dev/null
test -f "$work/prefix/include/fracvi/integrate/integrator.hpp"
test -x "$work/prefix/bin/fracvi"
cmake -S "$repo/tests/consumer" -B "$work/build" -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/build" >/dev/null
"$work/build/consumer"
"$work/prefix/bin/fracvi" run --set time.steps=300 --set time.end=3 --out "$work/out" --quiet
test -f "$work/out/summary.json"
if [ -x /usr/bin/python3 ] && /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  test -f "$work/out/trajectory.png"  # plot.py found under prefix/share/fracvi
fi
echo "test-install: installed tree, find_package consumer and installed CLI work"
