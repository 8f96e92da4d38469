"""U as Python functions: three coupled pendula with fractional damping, the potential written
with NumPy instead of as a formula, checked against the formula run, and what an exception inside
the function does to a run.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/python_functions.py
"""
import numpy as np

import fracvi

# [snippet: functions]
def U(x, t):                                   # x: NumPy array of shape (d,), t: float
    return float(np.sum(1 - np.cos(x)) + 0.25 * np.sum(np.diff(x) ** 2))

def gradient(x, t):                            # ∇U, shape (d,)
    g = np.sin(x)
    g[:-1] -= 0.5 * np.diff(x)
    g[1:] += 0.5 * np.diff(x)
    return g

def hessian(x, t):                             # ∇²U, (d, d) array or scipy.sparse (optional)
    return np.diag(np.cos(x)) + 0.5 * np.array([[1, -1, 0], [-1, 2, -1], [0, -1, 1]])

problem = fracvi.Problem(name="pendula", dim=3, mass=1.0, damping=0.2, alpha=0.6,
                         convention="caputo", position=[0.5, 0.75, 1.0], end=20.0, steps=4000,
                         potential=U, gradient=gradient, hessian=hessian)
solution = fracvi.integrate(problem)           # as with a formula, only slower per step
# [/snippet]

formula = problem.with_overrides(
    "model.potential=1 - cos(x1) + 1 - cos(x2) + 1 - cos(x3) + 0.25*((x2 - x1)^2 + (x3 - x2)^2)")
reference = fracvi.integrate(formula)
difference = np.max(np.abs(solution.x - reference.x))
print(f"functions: {solution.status}, {solution.wall_time * 1e6 / 4000:.1f} µs per step; "
      f"formula: {reference.wall_time * 1e6 / 4000:.1f} µs per step; "
      f"largest difference {difference:.1e}")
assert solution.ok and reference.ok and difference < 1e-12


# [snippet: failure]
def fragile(x, t):
    if t > 5.0:
        raise RuntimeError("the model is not valid beyond t = 5")
    return gradient(x, t)

failed = fracvi.integrate(fracvi.Problem.from_dict(problem.to_dict(), functions=dict(
    potential=U, gradient=fragile, hessian=hessian)))
print(failed.status, failed.t[-1])             # callback-error, the last step before t = 5
print(failed.message.splitlines()[0])          # which function, then the Python traceback
# [/snippet]
assert failed.status == "callback-error" and failed.t[-1] <= 5.0 + problem.step
assert "RuntimeError: the model is not valid beyond t = 5" in failed.message
