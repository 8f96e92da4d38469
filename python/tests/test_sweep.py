"""fracvi.sweep, fracvi.load_sweep and fracvi.plot_sweep (issue 15): the table of `fracvi sweep`
as NumPy columns, from the same C++ code."""
import os

import numpy as np
import pytest

import fracvi

# The base problem of examples/sweep/fractional_oscillator.toml and its grid.
OSCILLATOR = dict(name="fractional-oscillator", dim=1, mass=1.0, damping=0.5, alpha=0.5,
                  convention="caputo", potential="x1^2/2", position=[1.0], end=20.0, steps=400)
GRID = {"model.damping_order": {"linspace": [0.2, 1.8, 6]},
        "model.damping": {"logspace": [0.1, 2.0, 5]}}
EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples",
                       "sweep", "fractional_oscillator.toml")


def same_table(a, b):
    assert list(a) == list(b)
    for name in a:
        if name == "wall_seconds":
            continue
        if a[name].dtype.kind == "f":
            # Bitwise: the same doubles (NaN where both are empty).
            assert np.array_equal(a[name], b[name], equal_nan=True), name
        else:
            assert np.array_equal(a[name], b[name]), name


@pytest.fixture(scope="module")
def grid():
    return fracvi.sweep(fracvi.Problem(**OSCILLATOR), GRID, jobs=1)


def test_grid_columns(grid):
    assert grid.parameters == ["model.damping_order", "model.damping"]
    assert len(grid["case"]) == 30 and grid["case"].dtype == np.int64
    assert np.all(grid.ok)
    assert grid["model.damping_order"][0] == 0.2 and grid["model.damping_order"][-1] == 1.8
    assert grid["model.damping"][4] == 2.0
    assert grid["x1"].dtype == np.float64 and len(set(grid["x1"])) == 30
    # The damping removes energy: never more at the end than at the start.
    assert np.all(grid["energy_final"] < grid["energy_initial"])


def test_jobs_do_not_change_the_numbers(grid):
    same_table(fracvi.sweep(fracvi.Problem(**OSCILLATOR), GRID, jobs=2), grid)


def test_same_table_as_the_command_line(grid, cli, tmp_path):
    out = tmp_path / "cli"
    r = cli("sweep", EXAMPLE, "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    same_table(fracvi.load_sweep(out), grid)


def test_failures_are_rows():
    base = {"model": {"dim": 1, "mass": 1.0, "alpha": 0.5, "potential": "0.5*x1^2"},
            "initial": {"position": [1.0]}, "time": {"end": 10.0, "steps": 100}}
    r = fracvi.sweep(base,
                     {"model.potential": ["0.5*x1^2", "0.5*x1^2*sqrt(5 - t)", "10*x1^4"],
                      "model.alpha": [1.5, 0.5, 0.5],
                      "method.newton_max_iterations": [20, 20, 1]},
                     combine="zip", jobs=2)
    assert list(r["status"]) == ["invalid", "non-finite", "newton-failure"]
    assert "model.alpha=1.5" in r["message"][0]
    assert np.isnan(r["x1"][0])  # refused before any run: no final state
    assert r["final_time"][1] == 5.0


def test_bad_sweep_raises_problem_error():
    with pytest.raises(fracvi.ProblemError, match="model.alpah"):
        fracvi.sweep(fracvi.Problem(**OSCILLATOR), {"model.alpah": [0.3]})
    with pytest.raises(fracvi.ProblemError, match="needs one of values, linspace"):
        fracvi.sweep(fracvi.Problem(**OSCILLATOR), {"model.alpha": {"linspase": [0.1, 0.9, 3]}})
    with pytest.raises(fracvi.ProblemError, match="one length"):
        fracvi.sweep(fracvi.Problem(**OSCILLATOR),
                     {"model.alpha": [0.3, 0.4], "model.damping": [1.0]}, combine="zip")


def test_out_and_resume(grid, tmp_path):
    out = tmp_path / "out"
    first = fracvi.sweep(fracvi.Problem(**OSCILLATOR), GRID, out=out, save="trajectory")
    assert os.path.exists(out / "results.csv")
    assert os.path.exists(out / "cases" / "29" / "trajectory.csv")
    with pytest.raises(fracvi.ProblemError, match="--resume"):
        fracvi.sweep(fracvi.Problem(**OSCILLATOR), GRID, out=out, save="trajectory")
    again = fracvi.sweep(fracvi.Problem(**OSCILLATOR), GRID, out=out, save="trajectory",
                         resume=True)
    np.testing.assert_array_equal(again["wall_seconds"], first["wall_seconds"])  # none rerun
    same_table(first, grid)


def test_plot_sweep(grid, tmp_path):
    heat = tmp_path / "heat.png"
    fig = fracvi.plot_sweep(grid, "energy_final", file=heat)
    assert heat.stat().st_size > 10000
    assert fig.axes[0].get_xlabel() == "model.damping_order"
    line = tmp_path / "line.png"
    fig = fracvi.plot_sweep(grid, "x1", x="model.damping", y=False, file=line)
    assert line.stat().st_size > 10000
    assert len(fig.axes[0].get_lines()) == 6  # one per damping order
    with pytest.raises(KeyError, match="no column"):
        fracvi.plot_sweep(grid, "energy")
