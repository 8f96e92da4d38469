"""Stepping by hand, saving and loading, and parallel runs: a fractional (Bagley–Torvik) Duffing
oscillator stepped until its first return to x = 0 with an observer, continued to the end, written
as CSV and as npz and read back bit for bit, and a damping study over two processes.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/stepping_and_files.py [OUT]
"""
import multiprocessing
import os
import sys
import tempfile

import numpy as np

import fracvi

problem = fracvi.Problem(
    name="stepping", dim=1, mass=1.0, damping=0.3, alpha=0.75, convention="caputo",
    potential="x1^2/2 + x1^4/4", position=[1.0], end=20.0, steps=2000)

# [snippet: stepping]
integrator = fracvi.Integrator(problem, scheme="fvi-gl")
while integrator.state.x[0] > 0:          # step by hand: the first return to x = 0
    integrator.step()
first_return = integrator.state           # k, t, x, v, p = M v, energy, dissipated, balance

peaks = []                                # an observer: called after every step
integrator.run(until=10.0, observer=lambda s: peaks.append((s.t, abs(s.x[0]))))
integrator.run()                          # to the end
solution = integrator.solution()          # the same as fracvi.integrate(problem)
# [/snippet]

print(f"first return to x = 0 after step {first_return.k}, t = {first_return.t:.2f}, "
      f"v = {first_return.v[0]:.6f}")
print(f"observed {len(peaks)} steps up to t = {peaks[-1][0]:g}; status {solution.status}, "
      f"x(20) = {solution.x[-1, 0]:.10f}")
assert np.array_equal(solution.x, fracvi.integrate(problem, scheme="fvi-gl").x)

out = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp()
# [snippet: files]
fracvi.write(solution, os.path.join(out, "csv"))               # trajectory.csv, as `fracvi run`
fracvi.write(solution, os.path.join(out, "npz"), format="npz")  # trajectory.npz
loaded = fracvi.load(os.path.join(out, "npz"))                 # a Solution, with its problem
assert np.array_equal(loaded.x, solution.x) and loaded.problem == solution.problem
# [/snippet]
print(f"wrote and read back {out}/csv and {out}/npz: {loaded}")


if __name__ == "__main__":
    # [snippet: pool]
    problems = [problem.with_overrides(f"model.damping={r}") for r in (0.1, 0.3, 1.0)]
    with multiprocessing.Pool(2) as pool:      # Problems and Solutions pickle
        solutions = pool.map(fracvi.integrate, problems)
    # [/snippet]
    for p, s in zip(problems, solutions):
        print(f"damping {p.damping.toarray()[0, 0]:g}: E(20) = {s.energy[-1]:.6f}")
