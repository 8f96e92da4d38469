"""A parameter sweep from Python: the fractional oscillator x'' + R D^(2α) x + x = 0 over a grid
of damping orders 2α and dampings R, run on two threads, and the heat map of the energy left at
t = 20 (the same study as examples/sweep/fractional_oscillator.toml with `fracvi sweep`).

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/sweep_heatmap.py [OUT_DIR]
"""
import os
import sys

import numpy as np

import fracvi

# [snippet: sweep]
problem = fracvi.Problem(
    name="fractional-oscillator", dim=1, mass=1.0, damping=0.5, alpha=0.5,
    convention="caputo", potential="x1^2/2", position=[1.0], end=20.0, steps=400)
result = fracvi.sweep(problem, {
    "model.damping_order": {"linspace": [0.2, 1.8, 6]},
    "model.damping": {"logspace": [0.1, 2.0, 5]},
}, jobs=2)
# [/snippet]

print(result)
best = np.nanargmin(np.where(result.ok, result["energy_final"], np.nan))
print(f"least energy left: {result['energy_final'][best]:.3e} at 2α = "
      f"{result['model.damping_order'][best]:g}, R = {result['model.damping'][best]:g}")

if len(sys.argv) > 1:
    os.makedirs(sys.argv[1], exist_ok=True)
    file = os.path.join(sys.argv[1], "energy_final.png")
    fracvi.plot_sweep(result, "energy_final", file=file)
    print(f"wrote {file}")
