"""Shared fixtures of the Python tests (run by ctest: python3 -m pytest, PYTHONPATH = the build's
python/ directory, FRACVI_CLI = the built command line)."""
import json
import os
import subprocess

import pytest

# The problem of tests/cli/cli_test.py: two coupled nonlinear oscillators, viscous damping with a
# full R, a forcing term. Nonlinear, so Newton takes several iterations per step.
PROBLEM = """\
name = "cli-test"
[model]
dim = 2
mass = [[2.0, 0.5], [0.5, 1.0]]
damping = [[0.2, 0.05], [0.05, 0.1]]
alpha = 0.5
potential = "x1^4/4 + x2^2/2 - 0.2*x1*x2"
force = ["0.1*sin(t)", "0"]
[initial]
position = [1.0, 0.0]
velocity = [0.0, 0.5]
[time]
end = 5.0
steps = 500
"""

# Fractional (Bagley–Torvik) damping, Caputo: exercises the full memory sum.
FRACTIONAL = """\
name = "fractional"
[model]
dim = 1
mass = 1.0
damping = 0.3
alpha = 0.75
convention = "caputo"
potential = "x1^2/2 + x1^4/8"
[initial]
position = [1.0]
velocity = [0.2]
[time]
end = 4.0
steps = 400
"""


@pytest.fixture
def cli():
    """Runs the built `fracvi` binary; returns the CompletedProcess."""
    path = os.environ.get("FRACVI_CLI")
    if not path:
        pytest.skip("FRACVI_CLI is not set (ctest sets it to the built fracvi binary)")

    def run(*args, cwd=None):
        return subprocess.run([path, *map(str, args)], capture_output=True, text=True,
                              timeout=120, cwd=cwd)
    return run


@pytest.fixture
def write_file(tmp_path):
    def write(text, name="p.toml"):
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return str(path)
    return write


def read_summary(directory):
    with open(os.path.join(directory, "summary.json"), encoding="utf-8") as f:
        return json.load(f)

# U = −x⁴ sends the particle to infinity in finite time (x' = √(2x⁴ + c)); Newton fails on the
# way, at step 297 of 500 (with fvi-gl; the default fvi-lobatto3's Newton fails earlier).
BLOWUP = """\
name = "blow-up"
[model]
dim = 1
mass = 1.0
alpha = 0.5
potential = "-x1^4"
[initial]
position = [1.0]
velocity = [1.0]
[time]
end = 5.0
steps = 500
[method]
scheme = "fvi-gl"
"""

# A general Lagrangian of mechanical form, L = ½ẋ² − ½x² − 0.3 D^α_−x D^α_+y (viscous damping
# 0.3 for α = 1/2), integrated by `fracvi run` like the mechanical model.
LAGRANGIAN = """\
name = "lagrangian"
[model]
dim = 1
lagrangian = "xdot1^2/2 - x1^2/2 - 0.3*dx1*dy1"
alpha = 0.5
[initial]
position = [1.0]
[time]
end = 3.0
steps = 300
"""
