"""Output where you want it, and events: a fractional (Bagley–Torvik, 2α = 1.5) Duffing
oscillator sampled at chosen times by the dense output of every step, its zero crossings located
between grid points (a formula and a Python callable), and a terminal event that stops the run
when the amplitude has decayed; then a viscous oscillator whose first zero is known in closed
form, to show how close the located crossing is.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/dense_and_events.py
"""
import math

import numpy as np

import fracvi

problem = fracvi.Problem(
    name="dense-events", dim=1, mass=1.0, damping=0.3, alpha=0.75, convention="caputo",
    potential="x1^2/2 + x1^4/4", position=[1.0], end=20.0, steps=2000, scheme="fvi-lobatto3")

# [snippet: t-eval]
t_eval = np.linspace(0.0, 20.0, 41)[1:-1] + 0.0123   # not grid times
solution = fracvi.integrate(problem, t_eval=t_eval, every=100)
solution.t_eval, solution.x_eval, solution.v_eval    # the state there: order kept (min(p, 4))
# [/snippet]
assert np.array_equal(solution.t_eval, t_eval) and len(solution.t) == 21

# [snippet: dense]
dense = fracvi.integrate(problem, dense=True)          # every step kept (every = 1)
x = dense(12.345)                                      # x(t) anywhere in [start, end]
x, v = dense.interpolate([1.5, 2.5])                   # x and v, one row per time
# [/snippet]
assert np.array_equal(dense(t_eval), solution.x_eval)  # the same interpolant, bit for bit


# [snippet: events]
def amplitude_low(t, x, v):                # a Python callable g(t, x, v) -> float
    return x[0] ** 2 + v[0] ** 2 - 0.04
amplitude_low.terminal = True              # SciPy's attributes: stop at the first crossing
amplitude_low.direction = -1               # falling only

solution = fracvi.integrate(problem, events=[
    {"name": "down", "g": "x1", "direction": "falling"},   # a formula: fast, no Python per step
    amplitude_low])
solution.status                            # "event": stopped by amplitude_low, not a failure
solution.t_events["down"]                  # the downward zero crossings
solution.events[-1]                        # EventRecord(name, t, direction, step, x, v)
# [/snippet]
stop = solution.events[-1]
print(f"{len(solution.t_events['down'])} downward crossings, stopped at t = {stop.t:.6f} "
      f"(status {solution.status}): x = {stop.x[0]:.6f}, v = {stop.v[0]:.6f}")
assert solution.status == "event" and stop.name == "amplitude_low"
assert abs(stop.x[0] ** 2 + stop.v[0] ** 2 - 0.04) < 1e-12

# A viscous oscillator x'' + 0.4 x' + 4 x = 0, x(0) = 1: its first zero in closed form.
omega_d = 2.0 * math.sqrt(0.99)
first_zero = (math.pi - math.atan(omega_d / 0.2)) / omega_d
for steps in (100, 200, 400):
    oscillator = fracvi.Problem(dim=1, mass=1.0, damping=0.4, alpha=0.5, potential="2*x1^2",
                                position=[1.0], end=2.0, steps=steps, scheme="fvi-lobatto3")
    located = fracvi.integrate(oscillator, events={"name": "zero", "g": "x1",
                                                   "terminal": True}).events[0].t
    print(f"N = {steps:4d}: first zero at {located:.15f}, error {abs(located - first_zero):.2e}")
    assert abs(located - first_zero) < 1e-6
