"""Cost of U as Python functions against the same U as a formula (issue 16 item 2).

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python_functions_bench.py [--quick]

A chain of d coupled pendula, U = sum(1 - cos x_i) + k/2 sum (x_{i+1} - x_i)^2, with fractional
damping (2α = 1.2, fast history), fvi-gl, mirror run and error estimate off. Three runs per d in
one process, interleaved: the formula; Python functions U, gradient and Hessian (NumPy,
vectorised); the same without the Hessian (central differences of the gradient). Prints the time
per step, the ratios to the formula run, Newton iterations, and the largest difference between the
trajectories (it must be round-off: the same equations). A second table does the same for the
force g(x, v, t) = -C x_i^2 v_i (nonlinear friction) with the formula potential: formula force,
Python g with its Jacobians, Python g without them (central differences).
Not a test; bench/RESULTS.md records it.
"""
import sys
import time

import numpy as np

import fracvi

K = 0.5


def U(x, t):
    return float(np.sum(1.0 - np.cos(x)) + 0.5 * K * np.sum(np.diff(x) ** 2))


def dU(x, t):
    g = np.sin(x)
    dx = np.diff(x)
    g[:-1] -= K * dx
    g[1:] += K * dx
    return g


def H(x, t):
    d = len(x)
    h = np.diag(np.cos(x))
    i = np.arange(d - 1)
    h[i, i] += K
    h[i + 1, i + 1] += K
    h[i, i + 1] -= K
    h[i + 1, i] -= K
    return h


C = 0.3


def g(x, v, t):
    return -C * x * x * v


def g_jacobian(x, v, t):
    return np.diag(-2.0 * C * x * v), np.diag(-C * x * x)


def force_formulas(d):
    return [f"-{C}*x{i}^2*v{i}" for i in range(1, d + 1)]


def formula(d):
    terms = [f"(1 - cos(x{i}))" for i in range(1, d + 1)]
    terms += [f"{K / 2}*(x{i + 1} - x{i})^2" for i in range(1, d)]
    return " + ".join(terms)


def problem(d, steps, **potential):
    return fracvi.Problem(name=f"pendula-{d}", dim=d, mass=1.0, damping=0.2, alpha=0.6,
                          convention="caputo", position=list(np.linspace(0.5, 1.0, d)),
                          end=10.0, steps=steps, mirror="off", error_estimate="none",
                          scheme="fvi-gl", **potential)


def timed(p, repeats):
    best, solution = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        solution = fracvi.integrate(p)
        best = min(best, time.perf_counter() - start)
    return best, solution


def table(title, columns, make_runs, steps, repeats):
    """One table: per d, the runs make_runs(d) = {formula, functions, difference} timed."""
    print(title)
    print(f"{'d':>4} {'formula':>9} {columns[0]:>10} {'ratio':>6} {columns[1]:>11} "
          f"{'ratio':>6} {'newton':>17} {'max |Δx|':>9}")
    for d in (1, 2, 10, 50):
        results = {name: timed(p, repeats) for name, p in make_runs(d).items()}
        per_step = {name: 1e6 * t / steps for name, (t, _) in results.items()}
        sols = {name: s for name, (_, s) in results.items()}
        for name, s in sols.items():
            assert s.status == "success", (name, s.message)
        newton = "/".join(str(sols[n].summary()["newton_iterations"])
                          for n in ("formula", "functions", "difference"))
        dx = max(np.max(np.abs(sols[n].x - sols["formula"].x)) for n in ("functions",
                                                                         "difference"))
        print(f"{d:>4} {per_step['formula']:>9.2f} {per_step['functions']:>10.2f} "
              f"{per_step['functions'] / per_step['formula']:>6.1f} "
              f"{per_step['difference']:>11.2f} "
              f"{per_step['difference'] / per_step['formula']:>6.1f} {newton:>17} {dx:>9.1e}")


def main():
    quick = "--quick" in sys.argv
    steps = 2000 if quick else 10000
    repeats = 1 if quick else 3
    print(f"steps = {steps}, best of {repeats}; time per step in µs; Newton iterations of the "
          f"formula/functions/difference runs")
    table("U as functions", ("functions", "no hessian"), lambda d: {
        "formula": problem(d, steps, potential=formula(d)),
        "functions": problem(d, steps, potential=U, gradient=dU, hessian=H),
        "difference": problem(d, steps, potential=U, gradient=dU),
    }, steps, repeats)
    table("\nthe force g(x, v, t) = -C x^2 v as a function", ("function", "no jacobian"),
          lambda d: {
              "formula": problem(d, steps, potential=formula(d), force=force_formulas(d)),
              "functions": problem(d, steps, potential=formula(d), force=g,
                                   force_jacobian=g_jacobian),
              "difference": problem(d, steps, potential=formula(d), force=g),
          }, steps, repeats)


if __name__ == "__main__":
    main()
