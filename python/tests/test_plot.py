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


def test_plot_names_a_malformed_csv_not_matplotlib(cli, tmp_path):
    # Issue 14 item 8: `fracvi plot` blamed matplotlib for a corrupt trajectory.csv.
    out = tmp_path / "run"
    r = cli("run", "--set", "time.end=6", "--set", "time.steps=60", "--out", out, "--quiet",
            "--no-plot")
    assert r.returncode == 0, r.stderr
    csv_path = out / "trajectory.csv"
    good = csv_path.read_text(encoding="utf-8")
    lines = good.splitlines(keepends=True)
    cases = [
        (lines[:5] + ["0.1,0.2\n"] + lines[6:], "line 6: 2 values, the header has 6 columns"),
        (lines[:3] + [",".join(["0.2", "abc"] + lines[3].split(",")[2:])] + lines[4:],
         "line 4: column x1 = 'abc' is not a number"),
        (["t,x1\n"] + lines[1:], "line 1: the header lacks the column(s) energy, dissipated, "
                                 "balance, v1"),
    ]
    for text, needle in cases:
        csv_path.write_text("".join(text), encoding="utf-8")
        r = cli("plot", out)
        assert r.returncode == 1
        assert r.stdout == ""
        assert r.stderr.count("\n") == 1, r.stderr
        assert f"fracvi plot: not drawn: malformed input: {csv_path}, " in r.stderr, r.stderr
        assert needle in r.stderr, r.stderr
        assert "matplotlib" not in r.stderr
        assert not (out / "plot.log").exists()
    csv_path.write_text(good, encoding="utf-8")
    (out / "summary.json").write_text('{"status": "success",\n  oops}\n', encoding="utf-8")
    r = cli("plot", out)
    assert r.returncode == 1
    assert f"malformed input: {out / 'summary.json'}, line 2: " in r.stderr, r.stderr
