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


# A force g(x, v, t) as a Python function: feedback that pumps energy into pendulum 1 when it is
# slow (van der Pol negative damping) while the fractional damping takes it out, with its
# Jacobians (optional: central differences of g without them).
# [snippet: force]
def feedback(x, v, t):                         # g(x, v, t), shape (d,)
    g = np.zeros_like(x)
    g[0] = 0.5 * (1 - x[0] ** 2) * v[0]
    return g

def feedback_jacobian(x, v, t):                # (∂g/∂x, ∂g/∂v), each (d, d)
    dx, dv = np.zeros((3, 3)), np.zeros((3, 3))
    dx[0, 0] = -x[0] * v[0]
    dv[0, 0] = 0.5 * (1 - x[0] ** 2)
    return dx, dv

driven = fracvi.Problem.from_dict(problem.to_dict(), functions=dict(
    potential=U, gradient=gradient, hessian=hessian, force=feedback,
    force_jacobian=feedback_jacobian))
pumped = fracvi.integrate(driven)              # discrete Lagrange–d'Alembert, as a formula force
# [/snippet]
as_formula = fracvi.integrate(formula.with_overrides(
    'model.force=["0.5*(1 - x1^2)*v1", "0", "0"]'))
difference = np.max(np.abs(pumped.x - as_formula.x))
print(f"force function: {pumped.status}, balance error {pumped.max_balance_error:.1e} "
      f"(the account includes g's work), largest difference from the formula force "
      f"{difference:.1e}")
assert pumped.ok and as_formula.ok and difference < 1e-12
