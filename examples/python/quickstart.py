"""fracvi from Python in a dozen lines: a Duffing oscillator with Bagley–Torvik damping
(damping order 2α = 3/2), its energy balance, the files and plots of `fracvi run`, and a
Riemann–Liouville derivative.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/quickstart.py [OUT_DIR]
"""
import sys

import fracvi

# [snippet: quickstart]
problem = fracvi.Problem(
    name="quickstart", dim=1, mass=1.0, damping=0.3, alpha=0.75, convention="caputo",
    potential="x1^2/2 + x1^4/4", position=[1.0], velocity=[0.0], end=20.0, steps=2000)
solution = fracvi.integrate(problem)
# [/snippet]

print(f"status {solution.status}, x(20) = {solution.x[-1, 0]:.10f}")
print(f"energy {solution.energy[0]:.6f} -> {solution.energy[-1]:.6f}, "
      f"dissipated {solution.dissipated[-1]:.6f}, balance error {solution.max_balance_error:.1e}")
print(f"mirror error {solution.mirror_error:.1e}, Newton iterations {solution.newton_iterations}")

if len(sys.argv) > 1:  # trajectory.csv, summary.json, problem.toml and three PNGs
    fracvi.write(solution, problem, sys.argv[1], plot=True)
    print(f"wrote {sys.argv[1]}")

# D^{1/2} t^{3/2} = Γ(5/2)/Γ(2) t = (3√π/4) t, with the exact derivative of the formula.
print("D^0.5 t^1.5 at t = 1:", fracvi.rl_derivative(0.5, "t^1.5", 1.0, a=0.0, b=2.0))
