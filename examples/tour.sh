#!/usr/bin/env bash
# The shell commands shown in docs/getting-started.md and docs/cli.md, run by ctest (examples_tour)
# so that every one of them works as printed. Usage: tour.sh DIRECTORY_OF_FRACVI_BINARY
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
export PATH="$1:$PATH"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$repo/examples" "$work/examples"
cd "$work"

# [snippet: run-example]
fracvi run examples/damped_pendulum.toml
# [/snippet]
test -f fracvi-out/damped-pendulum/summary.json

# [snippet: override]
fracvi run examples/viscoelastic_caputo.toml --set model.alpha=0.6 --set name=visco-alpha-0.6
# [/snippet]
grep -q '"alpha": 0.6' fracvi-out/visco-alpha-0.6/summary.json

# [snippet: ill-posed]
fracvi run examples/viscoelastic_caputo.toml --set model.convention=riemann-liouville || echo "exit status $?"
# [/snippet]

# [snippet: convergence]
fracvi convergence examples/bagley_torvik_power.toml --steps 100,200,400,800,1600
# [/snippet]
test -f fracvi-out/bagley-torvik-power-convergence/convergence.csv

# [snippet: second-order]
fracvi methods
fracvi convergence examples/bagley_torvik_power_bdf2.toml --steps 100,200,400,800,1600
# [/snippet]
test -f fracvi-out/bagley-torvik-power-bdf2-convergence/convergence.csv

# [snippet: higher-order]
fracvi convergence examples/bagley_torvik_root_lobatto.toml --steps 16,32,64,128
# [/snippet]
test -f fracvi-out/bagley-torvik-root-lobatto-convergence/convergence.csv

# [snippet: convergence-fine]
fracvi convergence examples/damped_pendulum.toml --steps 500,1000,2000,4000 --reference-steps 64000
# [/snippet]

# [snippet: compare]
fracvi compare examples/two_dof_coupled.toml --steps 100,200,400,800 --reference-steps 6400
# [/snippet]
test -f fracvi-out/two-dof-coupled-compare/work_precision.png

# [snippet: plot]
fracvi plot fracvi-out/damped-pendulum
# [/snippet]

# [snippet: weights]
fracvi weights --order 1.5 --scheme gl -n 5
# [/snippet]

# [snippet: derivative]
fracvi derivative --alpha 0.5 --f "t^1.5" --a 0 --b 2 --t 0.5,1,2 --exact "0.75*sqrt(pi)*t"
# [/snippet]
