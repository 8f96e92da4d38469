"""The comparison study of docs/comparison.md: every registered scheme on five problems, against
independent references, with work–precision, error-vs-N and energy-tracking figures.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/comparison_study.py \
        [--out DIR] [--small] [--problems name,...] [--repeat R]

For each problem it calls fracvi.compare (the library behind `fracvi compare`), writes
DIR/<problem>/compare.csv and the three figures, and prints a markdown summary: per scheme the
least-squares order of the max error, the error and wall time at the finest N, the time to reach
the problem's target error, and the energy and dissipated-energy errors. --small runs the same
study at CI sizes (ctest: python_example_comparison_study); the numbers in docs/comparison.md are
from a full run (about four minutes on 2 cores):

# [snippet: full-study]
PYTHONPATH=build/release/python /usr/bin/python3 examples/python/comparison_study.py --repeat 3
# [/snippet]

The references are independent of the compared runs: closed forms (Bagley–Torvik power law),
Boost.Odeint's dopri5 at tolerances 1e-13 (2α = 1), and for the fractional problems a fine run of
fvi-lobatto4 whose own error is checked here against the exact value at t = 20 (the Caputo
oscillator, from the Laplace transform) or against a second fine run with another scheme
(pi-trapezoid) for the chain.
"""
import argparse
import csv
import math
import os
import sys
import time

import numpy as np

import fracvi

# The Caputo fractional oscillator y'' + 0.5 D^{3/2} y + y = 0, y(0) = 1, y'(0) = 0 at t = 20
# (issue 11; Laplace-transform inversion, matches Garrappa's published value).
CAPUTO_EXACT_20 = -0.061964539893443569


def problems(small):
    """name -> (problem dict or TOML path, steps, reference keywords, target error, about)."""
    here = os.path.dirname(os.path.abspath(__file__))
    examples = os.path.dirname(here)

    def doubling(first, count, small_count=3):
        return [first * 2 ** i for i in range(small_count if small else count)]

    def fine(first, count, small_count=3, scheme=None):
        # A larger power-of-two multiple of every step count: 4x the finest one.
        n = first * 2 ** ((small_count if small else count) + 1)
        return {"reference_steps": n, **({"reference_scheme": scheme} if scheme else {})}

    chain_d = 20 if small else 100
    chain_end = 10.0 if small else 50.0
    long_end = 100.0 if small else 1000.0
    return {
        "viscous-2dof": (
            os.path.join(examples, "two_dof_coupled.toml"), doubling(150, 9), fine(150, 9),
            1e-6, "linear viscous 2-D, full M and R (2α = 1), t ∈ [0, 60]"),
        "pendulum": (
            os.path.join(examples, "damped_pendulum.toml"), doubling(200, 9), fine(200, 9),
            1e-6, "nonlinear pendulum U = 1 − cos x, viscous 2α = 1, x0 = 2.5, t ∈ [0, 40]"),
        "caputo-oscillator": (
            {"name": "caputo-oscillator",
             "model": {"dim": 1, "mass": 1.0, "damping": 0.5, "alpha": 0.75,
                       "convention": "caputo", "potential": "x1^2/2"},
             "initial": {"position": [1.0], "velocity": [0.0]},
             "time": {"end": 20.0, "steps": 100}},
            doubling(100, 9), fine(100, 9, scheme="fvi-lobatto4"),
            1e-6, "Caputo fractional oscillator y'' + 0.5 D^{3/2} y + y = 0, y(0) = 1, "
                  "t ∈ [0, 20]"),
        "bagley-torvik": (
            os.path.join(examples, "bagley_torvik_power.toml"), doubling(25, 9), {},
            1e-6, "Bagley–Torvik power law, exact x = t³ (2α = 3/2, Caputo, x0 = v0 = 0), "
                  "t ∈ [0, 1]"),
        "fput-chain": (
            {"name": "fput-chain",
             "model": {"dim": chain_d, "mass": 1.0, "damping": 0.05, "damping_order": 1.5,
                       "convention": "caputo",
                       "chain": {"stiffness": 1.0, "quartic": 1.0, "boundary": "fixed"}},
             "initial": {"position": "0.8*sin(pi*i/(d + 1))", "velocity": 0.0},
             "time": {"end": chain_end, "steps": 100}},
            doubling(100, 6), fine(100, 6, scheme="fvi-lobatto4"),
            1e-6, f"β-FPUT chain, d = {chain_d}, fractional damping 2α = 3/2 (Caputo), "
                  f"lowest mode, t ∈ [0, {chain_end:g}]"),
        "pendulum-long": (
            {"name": "pendulum-long",
             "model": {"dim": 1, "mass": 1.0, "damping": 0.0, "alpha": 0.5,
                       "potential": "1 - cos(x1)"},
             "initial": {"position": [2.5], "velocity": [0.0]},
             "time": {"end": long_end, "steps": 100}},
            doubling(int(long_end) * 10, 4, 2), fine(int(long_end) * 10, 4, 2),
            1e-3, f"undamped pendulum (R = 0), x0 = 2.5, t ∈ [0, {long_end:g}]: long-time energy"),
    }


# Errors below this are at the round-off plateau (double precision × the solution's scale and the
# number of steps): their slope is noise, so the order fit leaves them out.
ROUNDOFF = 1e-12


def least_squares_order(h, err):
    """Slope of log(error) against log(h) with the round-off plateau masked: points below
    ROUNDOFF, and every point from the first halving of h that no longer lowers the error by a
    factor 1.5 (h is ascending in N, i.e. descending here)."""
    ok = np.isfinite(err) & (err > ROUNDOFF)
    for i in range(1, len(err)):
        if ok[i] and ok[i - 1] and err[i] > err[i - 1] / 1.5:
            ok[i:] = False
            break
    if ok.sum() < 2:
        return float("nan")
    x, y = np.log(h[ok]), np.log(err[ok])
    return float(np.polyfit(x, y, 1)[0])


ADAPTIVE = {m["name"] for m in fracvi.methods() if m["adaptive"]}


def time_to(target, wall, err):
    """Wall time at which the error first reaches `target` (log-log interpolation), or None."""
    for i in range(len(err)):
        if err[i] <= target:
            if i == 0:
                return wall[0]
            a, b = math.log(err[i - 1]), math.log(err[i])
            s = (math.log(target) - a) / (b - a) if b != a else 1.0
            return math.exp(math.log(wall[i - 1]) + s * (math.log(wall[i]) - math.log(wall[i - 1])))
    return None


def summarize(name, about, result, target, out):
    t = result["table"]
    print(f"\n### {name}: {about}\n")
    print(f"reference: {result['reference']}; energy reference: {result['energy_reference']}\n")
    print(f"| scheme | order (declared) | max error at N = {int(t['steps'].max())} | wall (s) | "
          f"time to {target:.0e} | energy error | dissipated error | notes |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for scheme in dict.fromkeys(t["scheme"]):
        sel = t["scheme"] == scheme
        ok = sel & (t["status"] == "success")
        notes = sorted({f"{s} at N = {n}" for s, n in zip(t["status"][sel & ~ok], t["steps"][sel & ~ok])},
                       key=lambda s: int(s.split("= ")[1]))
        if not ok.any():
            reason = t["message"][sel][0].split(": ", 1)[-1][:90]
            print(f"| {scheme} | – | – | – | – | – | – | {t['status'][sel][0]}: {reason} |")
            continue
        order = least_squares_order(t["h"][ok], t["max_error"][ok])
        last = np.flatnonzero(ok)[-1]
        reach = time_to(target, t["wall_seconds"][ok], t["max_error"][ok])
        declared = int(t["declared_order"][last])
        if scheme in ADAPTIVE:
            order_text = "adaptive"  # its error follows the tolerances, not N
        elif math.isnan(order):
            order_text = f"round-off ({declared})"
        else:
            order_text = f"{order:.2f} ({declared})"
        note = "; ".join(notes[:2]) + (" …" if len(notes) > 2 else "")
        print(f"| {scheme} | {order_text} | {t['max_error'][last]:.2e}"
              f"{'' if t['steps'][last] == t['steps'].max() else ' (N = %d)' % t['steps'][last]} | "
              f"{t['wall_seconds'][last]:.3g} | {'%.3g s' % reach if reach else 'not reached'} | "
              f"{t['energy_error'][last]:.1e} | {t['dissipated_error'][last]:.1e} | {note} |")
        rows.append((scheme, order, reach))
    directory = os.path.join(out, name)
    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, "compare.csv"), "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        keys = list(t)
        w.writerow(keys)
        for i in range(len(t["scheme"])):
            w.writerow([t[k][i] if not isinstance(t[k][i], float) else repr(float(t[k][i]))
                        for k in keys])
    fracvi.plot_compare(result, directory)
    return rows


def reference_check(name, source, reference, small):
    """How good the fine reference run is, measured independently of the compared runs: against
    the exact value at t = 20 (Caputo oscillator), and for every fine run of a Lobatto scheme by
    self-convergence (max over the grid of |x^{N_ref} − x^{2 N_ref}|, which bounds the
    reference's error for any order ≥ 1). Returns (bound, text)."""
    scheme = reference.get("reference_scheme")
    if not scheme:
        return None, ""
    problem = (fracvi.Problem.from_toml(source) if isinstance(source, str)
               else fracvi.Problem.from_dict(source))
    n = reference["reference_steps"]

    def run(steps):
        p = problem.with_overrides(f"time.steps={steps}")
        return fracvi.integrate(p, scheme=scheme, mirror=False, error_estimate="none",
                                history_tolerance=1e-13)

    a, b = run(n), run(2 * n)
    bound = float(np.max(np.abs(a.x - b.x[::2])))
    text = f"reference check: |x^{n} − x^{2 * n}| ≤ {bound:.1e} over the grid ({scheme})"
    if name == "caputo-oscillator":
        exact = abs(a.x[-1, 0] - CAPUTO_EXACT_20)
        text += f"; |y_N − y(20)| = {exact:.1e} against the Laplace-transform value"
        bound = max(bound, exact)
    return bound, text


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=os.path.join("fracvi-out", "comparison-study"))
    parser.add_argument("--small", action="store_true", help="CI sizes")
    parser.add_argument("--problems", default="", help="comma-separated subset")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    all_problems = problems(args.small)
    chosen = [p for p in args.problems.split(",") if p] or list(all_problems)
    unknown = [p for p in chosen if p not in all_problems]
    if unknown:
        sys.exit(f"--problems: unknown {unknown} (choose from {', '.join(all_problems)})")
    print(f"fracvi comparison study ({'small' if args.small else 'full'} sizes), "
          f"{len(fracvi.methods())} schemes")
    failures = []
    for name in chosen:
        source, steps, reference, target, about = all_problems[name]
        problem = (fracvi.Problem.from_toml(source) if isinstance(source, str)
                   else fracvi.Problem.from_dict(source))
        start = time.perf_counter()
        result = fracvi.compare(problem, steps=steps, repeat=args.repeat, **reference)
        summarize(name, about, result, target, args.out)
        bound, text = reference_check(name, source, reference, args.small)
        if text:
            print(f"\n{text}: errors below about 10 × this are the reference's, not the scheme's")
            # The reference must be far below the typical second-order error at the finest N
            # for the table to mean anything.
            t = result["table"]
            finest = t["steps"] == t["steps"].max()
            second = finest & (t["declared_order"] == 2) & (t["status"] == "success")
            if second.any() and bound > 1e-2 * np.nanmedian(t["max_error"][second]):
                failures.append(f"{name}: reference error {bound:.1e} is not far below the "
                                f"compared errors")
        print(f"\n({time.perf_counter() - start:.1f} s)")
    print(f"\nfigures and tables in {args.out}")
    if failures:
        sys.exit("; ".join(failures))


if __name__ == "__main__":
    main()
