"""The variational boundary value problem (`fracvi bvp`) and the discrete fractional differences
from Python: a damped oscillator with Bagley–Torvik damping posed between two end points, solved
with the Δ^α_± of two schemes, and the orders of the fractional differences themselves.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/boundary_value.py [OUT_DIR]
"""
import sys

import numpy as np

import fracvi

# [snippet: bvp]
problem = fracvi.Problem(
    name="bvp", dim=1, mass=1.0, damping=0.3, alpha=0.75, convention="riemann-liouville",
    potential="x1^2/2", boundary=dict(start=[1.0], end=[0.0]), end=2.0, steps=100)
gl = fracvi.solve_bvp(problem)                      # Δ^α_± of fvi-gl: Grünwald–Letnikov
bdf2 = fracvi.solve_bvp(problem, scheme="fvi-bdf2")  # of fvi-bdf2: BDF2 convolution quadrature
print(gl.status, gl.residual_norm, gl.newton_iterations, gl.mirror_error)
# [/snippet]

assert gl.ok and bdf2.ok, (gl.message, bdf2.message)
print(f"x(1) = {gl.x[50, 0]:.8f} (fvi-gl), {bdf2.x[50, 0]:.8f} (fvi-bdf2)")
if len(sys.argv) > 1:  # trajectory.csv (t, x, y, residuals), summary.json, problem.toml
    print("wrote", gl.write(sys.argv[1]))

# [snippet: differences]
alpha, exact = 0.6, fracvi.rl_derivative_power(0.6, 3.0, 1.0, 0.0, 1.0)  # D^α t³ at t = 1
for quadrature in ("gl", "bdf2", "trapezoidal"):
    errors = []
    for n in (100, 200):
        t = np.linspace(0.0, 1.0, n + 1)
        d = fracvi.frac_delta_minus(t**3, 1.0 / n, alpha, quadrature=quadrature)
        errors.append(abs(d[-1] - exact))
    print(quadrature, "order", np.log2(errors[0] / errors[1]))  # 1, 2, 2
# [/snippet]
