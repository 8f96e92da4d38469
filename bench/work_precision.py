"""Work-precision of the registered schemes on the Caputo fractional oscillator of issue 11.

    y'' + 0.5 D^{3/2} y + y = 0,  y(0) = 1, y'(0) = 0  on [0, 20],  exact y(20) = -0.061964539893443569

For each scheme and step count: |y_N - y(20)| and the wall time of fracvi.integrate (history
"auto": the fast history from N = 4096 where the scheme has one; no mirror run). Prints a
markdown table; bench/RESULTS.md records one run. Not part of the tests (timings vary).

Usage: PYTHONPATH=build/release/python /usr/bin/python3 bench/work_precision.py [--repeat 3]
"""
import argparse
import time

import fracvi

EXACT = -0.061964539893443569
PROBLEM = """\
name = "caputo-oscillator"
[model]
dim = 1
mass = 1.0
damping = 0.5
alpha = 0.75
convention = "caputo"
potential = "0.5*x1^2"
[initial]
position = [1.0]
velocity = [0.0]
[time]
end = 20.0
steps = 1000
"""
TARGETS = (1e-4, 1e-6, 1e-8, 1e-10)


def run(scheme, steps, repeat):
    problem = fracvi.Problem.from_toml(PROBLEM, overrides=[f"time.steps={steps}"])
    best = float("inf")
    error = None
    for _ in range(repeat):
        start = time.perf_counter()
        sol = fracvi.integrate(problem, scheme=scheme, mirror=False, every=steps)
        best = min(best, time.perf_counter() - start)
        error = abs(sol.x[-1, 0] - EXACT)
    return error, best


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--max-steps", type=int, default=2 ** 21)
    args = parser.parse_args()
    schemes = [m["name"] for m in fracvi.methods()]
    print("| scheme | N | error at t = 20 | wall (s) |")
    print("|---|---|---|---|")
    reached = {}
    for scheme in schemes:
        steps = 25
        while steps <= args.max_steps:
            error, wall = run(scheme, steps, args.repeat)
            print(f"| {scheme} | {steps} | {error:.3e} | {wall:.4f} |", flush=True)
            for target in TARGETS:
                if error <= target and (scheme, target) not in reached:
                    reached[(scheme, target)] = (steps, wall)
            if error <= TARGETS[-1] or (scheme == "fvi-gl" and steps >= 2 ** 18):
                break
            steps *= 2
    print()
    print("| scheme | " + " | ".join(f"time to {t:.0e}" for t in TARGETS) + " |")
    print("|---|" + "---|" * len(TARGETS))
    for scheme in schemes:
        cells = []
        for target in TARGETS:
            if (scheme, target) in reached:
                n, wall = reached[(scheme, target)]
                cells.append(f"{wall:.4f} s (N = {n})")
            else:
                cells.append("not reached")
        print(f"| {scheme} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
