"""fracvi.plot draws the three figures of `fracvi run` from a Solution or a run directory."""
import os

import pytest

import fracvi
from conftest import PROBLEM

PNGS = ("trajectory.png", "phase.png", "energy.png")
MIN_BYTES = 10000  # a blank 800 × 500 PNG is ~3 kB; curves, labels and titles make more


def check_pngs(directory, paths=None):
    for name in PNGS:
        path = os.path.join(directory, name)
        assert os.path.getsize(path) > MIN_BYTES, path
        with open(path, "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    if paths is not None:
        assert paths == [os.path.join(directory, n) for n in PNGS]


def test_plot_solution_to_directory(tmp_path):
    sol = fracvi.integrate(fracvi.Problem.from_toml(PROBLEM))
    out = str(tmp_path / "plots")
    check_pngs(out, fracvi.plot(sol, out))
    check_pngs(str(tmp_path / "m"), sol.plot(str(tmp_path / "m")))


def test_plot_run_directory_and_write_with_plots(tmp_path):
    sol = fracvi.integrate(fracvi.Problem.default(overrides=["time.steps=600", "time.end=6"]))
    run = str(tmp_path / "run")
    fracvi.write(sol, sol.problem, run, plot=True)
    check_pngs(run)
    again = str(tmp_path / "again")
    check_pngs(again, fracvi.plot(run, again))


def test_plot_without_directory_returns_pyplot_figures():
    plt = pytest.importorskip("matplotlib.pyplot")
    sol = fracvi.integrate(fracvi.Problem.from_toml(PROBLEM))
    figures = fracvi.plot(sol, show=False)
    assert len(figures) == 3
    assert all(plt.fignum_exists(f.number) for f in figures)
    for f in figures:
        plt.close(f)


def test_plot_script_still_works_for_the_cli(cli, tmp_path):
    out = tmp_path / "cli"
    r = cli("run", "--set", "time.end=6", "--set", "time.steps=600", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    check_pngs(str(out))
