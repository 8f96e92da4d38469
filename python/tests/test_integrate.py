"""fracvi.integrate against `fracvi run`: the same problem gives the same numbers, bit for bit
(both call the same C++ integrate() on the same validated spec); arrays are zero-copy views;
numerical failure is a status."""
import csv
import gc
import json
import math
import os
import tomllib

import numpy as np
import pytest

import fracvi
from conftest import BLOWUP, FRACTIONAL, LAGRANGIAN, PROBLEM, read_summary

# Not reproducible between runs, and not a result ("concurrent": whether the estimate's companion
# runs overlapped the run — the CLI's do, the module's do not; the estimate is the same).
VOLATILE = {"wall_seconds", "setup_wall_seconds", "stepping_wall_seconds", "concurrent"}


def cli_run(cli, path, out, *args):
    r = cli("run", path, "--out", out, "--no-plot", "--quiet", *args)
    assert r.returncode in (0, 1), r.stderr
    return read_summary(out)


def read_csv(directory):
    with open(os.path.join(directory, "trajectory.csv"), encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(v) for v in row] for row in rows[1:]])


def strip(summary):
    """summary without its timings (also those of the error estimate and the tolerance runs)."""
    if isinstance(summary, dict):
        return {k: strip(v) for k, v in summary.items() if k not in VOLATILE}
    if isinstance(summary, list):
        return [strip(v) for v in summary]
    return summary


@pytest.mark.parametrize("text", [PROBLEM, FRACTIONAL, LAGRANGIAN],
                         ids=["nonlinear-2d", "fractional", "lagrangian"])
def test_bit_for_bit_with_the_cli(cli, write_file, tmp_path, text):
    path = write_file(text)
    cli_summary = cli_run(cli, path, tmp_path / "cli")
    header, table = read_csv(tmp_path / "cli")

    sol = fracvi.integrate(fracvi.Problem.from_toml(path))
    assert sol.status == "success" and sol.ok and sol.message == ""
    # summary.json has the final state and diagnostics: exactly equal (JSON numbers are written
    # with enough digits to round-trip a double).
    assert strip(sol.summary()) == strip(cli_summary)
    assert sol.x[-1].tolist() == cli_summary["final_position"]
    assert sol.v[-1].tolist() == cli_summary["final_velocity"]
    assert sol.mirror_error == cli_summary["mirror_error"]
    assert sol.max_balance_error == cli_summary["max_balance_error"]
    assert sol.newton_iterations == cli_summary["newton_iterations"]
    # Every row of trajectory.csv (17 significant digits also round-trip).
    d = sol.dim
    assert header == ["t"] + [f"x{i}" for i in range(1, d + 1)] + \
        [f"v{i}" for i in range(1, d + 1)] + ["energy", "dissipated", "balance"]
    ours = np.column_stack([sol.t, sol.x, sol.v, sol.energy, sol.dissipated, sol.balance])
    assert np.array_equal(ours, table)

    # Negative control: one ulp in x(0) changes the trajectory, so equality above is not vacuous.
    d = tomllib.loads(text)
    d["initial"]["position"][0] = float(np.nextafter(d["initial"]["position"][0], 2.0))
    assert not np.array_equal(fracvi.integrate(d).x, sol.x)

    # The dict (JSON) and keyword paths give the same problem, hence the same numbers.
    d = tomllib.loads(text)
    for problem in (fracvi.Problem.from_dict(d), fracvi.Problem(**d), d):
        again = fracvi.integrate(problem)
        assert np.array_equal(again.x, sol.x) and np.array_equal(again.v, sol.v)
        assert np.array_equal(again.balance, sol.balance)


def test_write_gives_the_cli_files(cli, write_file, tmp_path):
    path = write_file(PROBLEM + "[output]\nevery = 7\n")
    cli_run(cli, path, tmp_path / "cli")
    problem = fracvi.Problem.from_toml(path)
    sol = fracvi.integrate(problem)
    assert fracvi.write(sol, problem, tmp_path / "py") == str(tmp_path / "py")
    for name in ("trajectory.csv", "problem.toml"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    assert strip(read_summary(tmp_path / "py")) == strip(read_summary(tmp_path / "cli"))
    # The two-argument form and the method write the same.
    fracvi.write(sol, tmp_path / "py2")
    sol.write(str(tmp_path / "py3"))
    for other in ("py2", "py3"):
        assert (tmp_path / other / "trajectory.csv").read_bytes() == \
            (tmp_path / "py" / "trajectory.csv").read_bytes()
    # A problem of another dimension cannot describe this solution.
    with pytest.raises(ValueError, match="dimension"):
        fracvi.write(sol, fracvi.Problem.from_toml(FRACTIONAL), tmp_path / "bad")


def test_arrays_are_zero_copy_views():
    sol = fracvi.integrate(fracvi.Problem.from_toml(PROBLEM))
    n, d = sol.steps + 1, 2
    for name in ("x", "v"):
        a, b = getattr(sol, name), getattr(sol, name)
        assert a.shape == (n, d) and a.dtype == np.float64
        assert a.flags["C_CONTIGUOUS"]
        assert a.base is not None and not a.flags["OWNDATA"]
        assert np.shares_memory(a, b)
        assert a.__array_interface__["data"][0] == b.__array_interface__["data"][0]
        assert not a.flags["WRITEABLE"]  # the solution's storage is not the user's scratch space
        with pytest.raises(ValueError):
            a[0, 0] = 1.0
    for name in ("t", "energy", "dissipated", "balance"):
        a, b = getattr(sol, name), getattr(sol, name)
        assert a.shape == (n,) and a.base is not None and np.shares_memory(a, b)
    assert not np.shares_memory(sol.x, sol.v)

    # The arrays keep the C++ storage alive after the Solution is gone.
    x, t = sol.x, sol.t
    expected = x.copy()
    del sol
    gc.collect()
    _ = [np.ones(1000) for _ in range(100)]  # reuse freed memory, if any was freed
    assert np.array_equal(x, expected)
    assert t[-1] == 5.0


@pytest.mark.parametrize("text", [PROBLEM + "[method]\nnewton_max_iterations = 1\n", BLOWUP],
                         ids=["first-step", "blow-up"])
def test_numerical_failure_is_a_status(cli, write_file, tmp_path, text):
    path = write_file(text)
    cli_summary = cli_run(cli, path, tmp_path / "cli")
    assert cli_summary["status"] == "newton-failure"
    sol = fracvi.integrate(path)
    assert sol.status == "newton-failure" and not sol.ok
    assert f"at step {sol.steps + 1} " in sol.message
    assert sol.steps < 500
    assert sol.x.shape == (sol.steps + 1, sol.dim) and len(sol.t) == sol.steps + 1
    assert np.all(np.isfinite(sol.x)) and np.all(np.isfinite(sol.balance))
    assert math.isnan(sol.mirror_error)
    assert strip(sol.summary()) == strip(cli_summary)
    assert sol.summary()["mirror_error"] is None  # null in summary.json

    with pytest.raises(fracvi.IntegrationError) as e:
        fracvi.integrate(path, raise_on_failure=True)
    assert str(e.value) == f"newton-failure: {sol.message}"
    assert e.value.status == "newton-failure"
    assert np.array_equal(e.value.solution.x, sol.x)


def test_health_checks_are_a_status(cli, write_file, tmp_path):
    # U = -1/x1 from rest jumps across its singularity (docs/conventions.md, "When a run is not a
    # success"): "inaccurate", the same in Python and on the command line, every row kept.
    path = write_file(BLOWUP.replace('"-x1^4"', '"-1/x1"').replace("[1.0]\n[time]",
                                                                  "[0.0]\n[time]")
                      .replace("steps = 500", "steps = 1000"))
    cli_summary = cli_run(cli, path, tmp_path / "cli")
    sol = fracvi.integrate(path)
    assert sol.status == "inaccurate" and not sol.ok
    assert cli_summary["status"] == "inaccurate"
    assert "energy balance error" in sol.message and "0.5 x the energy scale" in sol.message
    assert sol.steps == 1000 and sol.x.shape == (1001, 1)
    assert strip(sol.summary()) == strip(cli_summary)
    with pytest.raises(fracvi.IntegrationError) as e:
        fracvi.integrate(path, raise_on_failure=True)
    assert e.value.status == "inaccurate"


def test_partial_trajectory_is_the_start_of_the_full_one():
    # The failed run's rows are exactly the rows a run that does not fail computes.
    sol = fracvi.integrate(BLOWUP)
    assert sol.steps == 296
    shorter = fracvi.integrate(fracvi.Problem.from_toml(BLOWUP).with_overrides(
        "time.end=2.96", "time.steps=296"))
    # Run right up to the blow-up, the shorter run completes but is garbage by its own energy
    # balance (docs/conventions.md, "When a run is not a success"); its rows are the same.
    assert shorter.steps == 296 and shorter.status == "inaccurate"
    np.testing.assert_array_equal(shorter.x[:, 0], sol.x[:, 0])
    # raise_on_failure does not raise on success
    assert fracvi.integrate(PROBLEM, raise_on_failure=True).ok


def test_method_overrides_are_validated_like_the_file(cli, write_file, tmp_path):
    path = write_file(PROBLEM)
    problem = fracvi.Problem.from_toml(path)
    sol = fracvi.integrate(problem, newton_max_iterations=1)
    assert sol.status == "newton-failure"
    assert sol.summary()["problem"]["method"]["newton_max_iterations"] == 1
    assert fracvi.integrate(problem, newton_tolerance=1e-10,
                            scheme="fvi-gl").problem.newton_tolerance == 1e-10
    for key, value, cli_value in (("newton_tolerance", -1.0, "-1.0"),
                                  ("newton_max_iterations", 0, "0"),
                                  ("scheme", "rk4", "rk4")):
        r = cli("run", path, "--set", f"method.{key}={cli_value}", "--no-plot", "--quiet")
        assert r.returncode == 2
        with pytest.raises(fracvi.ProblemError) as e:
            fracvi.integrate(problem, **{key: value})
        assert "fracvi run: " + str(e.value) == r.stderr.strip()


def test_run_options():
    problem = fracvi.Problem.from_toml(FRACTIONAL)
    base = fracvi.integrate(problem)
    no_mirror = fracvi.integrate(problem, mirror=False)
    assert math.isnan(no_mirror.mirror_error) and not math.isnan(base.mirror_error)
    assert np.array_equal(no_mirror.x, base.x)
    assert no_mirror.summary()["problem"]["method"]["mirror"] == "off"
    # method.mirror = "auto" (the default): on up to steps × dim = 10^6, off above.
    assert base.summary()["problem"]["method"]["mirror"] == "auto"
    cheap = dict(scheme="fvi-gl", error_estimate="none", every=100_000, diagnostics=False)
    longer = problem.with_overrides("time.steps=1000001")
    assert math.isnan(fracvi.integrate(longer, **cheap).mirror_error)
    at_limit = problem.with_overrides("time.steps=1000000")
    assert not math.isnan(fracvi.integrate(at_limit, **cheap).mirror_error)
    with pytest.raises(fracvi.ProblemError, match='method.mirror = "sometimes" is not one of'):
        fracvi.integrate(problem, mirror="sometimes")
    quiet = fracvi.integrate(problem, diagnostics=False)
    assert np.all(np.isnan(quiet.energy)) and math.isnan(quiet.max_balance_error)
    assert np.array_equal(quiet.x, base.x)
    direct = fracvi.integrate(problem, history="direct")
    assert np.array_equal(direct.x, base.x)  # 2α = 3/2, N < 4096: "auto" is the direct sum
    fast = fracvi.integrate(problem, history="fast")  # sum-of-exponentials tail, ε = 1e-10
    assert np.max(np.abs(fast.x - base.x)) <= 1e-10 * np.max(np.abs(base.x))
    assert not np.array_equal(fast.x, base.x)
    # start applies to the midpoint-type schemes (fvi-gl here; the default is fvi-lobatto3).
    euler = fracvi.integrate(problem, start="euler", scheme="fvi-gl")
    assert not np.array_equal(euler.x, fracvi.integrate(problem, scheme="fvi-gl").x)
    for bad, needle in ((dict(history="fastest"), "history"), (dict(start="rk"), "start"),
                        (dict(newton_absolute_tolerance=-1.0), "absolute")):
        with pytest.raises(ValueError, match=needle):
            fracvi.integrate(problem, **bad)
    with pytest.raises(TypeError):
        fracvi.integrate(42)


def test_solution_fields():
    sol = fracvi.integrate(fracvi.Problem.from_toml(PROBLEM))
    assert sol.method == "fvi-lobatto3" and sol.declared_order == 4  # scheme "auto"
    assert sol.newton_iterations >= sol.steps and sol.max_newton_iterations_per_step >= 2
    assert sol.wall_time > 0 and sol.problem.name == "cli-test"
    assert sol.max_balance_error == np.max(np.abs(sol.balance))
    s = sol.summary()
    assert s["status"] == "success" and s["steps"] == 500 and s["steps_requested"] == 500
    assert json.loads(json.dumps(s)) == s
    assert "success" in repr(sol)


def test_schemes_and_schema_keywords(cli, write_file, tmp_path):
    """The registry and the problem schema reach Python: fracvi.methods() is `fracvi methods
    --json`; every [method]/[output] key is a keyword of integrate(), validated like the file."""
    names = [m["name"] for m in fracvi.methods()]
    r = cli("methods", "--json")
    assert names == [m["name"] for m in json.loads(r.stdout)]
    assert {"fvi-gl", "fvi-bdf2"} <= set(names)
    keys = {(f["section"], f["key"]) for f in fracvi.problem_schema()}
    assert {("method", "scheme"), ("method", "history_tolerance"), ("output", "every")} <= keys

    path = write_file(PROBLEM)
    sol = fracvi.integrate(path, scheme="fvi-bdf2", every=50, history_tolerance=1e-12)
    assert sol.ok and sol.method == "fvi-bdf2" and sol.declared_order == 2
    summary = sol.summary()
    assert summary["problem"]["method"]["scheme"] == "fvi-bdf2"
    assert summary["problem"]["output"]["every"] == 50
    # the same run from the CLI, bit for bit
    out = str(tmp_path / "bdf2")
    r = cli("run", path, "--set", "method.scheme=fvi-bdf2", "--set", "output.every=50",
            "--set", "method.history_tolerance=1e-12", "--out", out, "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    assert read_summary(out)["final_position"] == summary["final_position"]

    with pytest.raises(TypeError, match="unexpected keyword argument 'schem'.*scheme"):
        fracvi.integrate(path, schem="fvi-bdf2")
    with pytest.raises(fracvi.ProblemError, match="fvi-gl, fvi-bdf2"):
        fracvi.integrate(path, scheme="fvi-bdf3")


def test_history_tolerance_auto_is_recorded(cli, write_file, tmp_path):
    """method.history_tolerance: "auto" (the default) lets the accuracy budget choose the fast
    history's ε; a number is used exactly. Both are recorded in the Solution and summary.json."""
    path = write_file(FRACTIONAL.replace("steps = 400", "steps = 8192"))
    problem = fracvi.Problem.from_toml(open(path).read())
    assert problem.history_tolerance == "auto"
    sol = fracvi.integrate(path, scheme="fvi-gl", history="fast", mirror=False)
    assert sol.ok and sol.history_tolerance_auto and not sol.history_limited
    # fvi-gl's ceiling is 1e-6 (its error constant was measured); the default fvi-lobatto3 keeps 1e-10
    assert 1e-13 <= sol.history_tolerance <= 1e-6
    lobatto = fracvi.integrate(path, history="fast", mirror=False, error_estimate="none")
    assert lobatto.method == "fvi-lobatto3" and 1e-13 <= lobatto.history_tolerance <= 1e-10
    summary = sol.summary()
    assert summary["history_tolerance"] == sol.history_tolerance
    assert summary["history_tolerance_mode"] == "auto"
    assert summary["problem"]["method"]["history_tolerance"] == "auto"
    user = fracvi.integrate(path, scheme="fvi-gl", history="fast", mirror=False,
                            history_tolerance=3e-9)
    assert user.history_tolerance == 3e-9 and not user.history_tolerance_auto
    assert user.summary()["history_tolerance_mode"] == "user"
    direct = fracvi.integrate(path, scheme="fvi-gl", history="direct", mirror=False)
    assert math.isnan(direct.history_tolerance)
    # K and n0 of the fast history: a looser ε (here the budget's, 1e-6, against the user's 3e-9)
    # needs no more exponentials; its state is the window's 2·n0 columns, the K recursions and the
    # sum per degree of freedom at least.
    assert sol.history == "fast" and user.history == "fast" and direct.history == "direct"
    assert sol.history_exponentials > 0 and sol.history_window > 0
    assert sol.history_tolerance > user.history_tolerance
    assert sol.history_exponentials <= user.history_exponentials
    assert sol.history_bytes >= 8 * (sol.history_exponentials + 2 * sol.history_window + 1)
    assert direct.history_exponentials == 0 and direct.history_window == 0
    assert direct.history_bytes >= 8 * 8193
    assert summary["history_exponentials"] == sol.history_exponentials
    assert summary["history_window"] == sol.history_window
    # The CLI records the same, and fracvi.load reads it back.
    out = str(tmp_path / "auto")
    r = cli("run", path, "--set", "method.scheme=fvi-gl", "--set", "method.history=fast",
            "--set", "method.history_tolerance=auto", "--out", out, "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    written = read_summary(out)
    assert written["history_tolerance"] == sol.history_tolerance
    assert written["history_tolerance_mode"] == "auto" and written["history_limited"] is False
    loaded = fracvi.load(out)
    assert loaded.history_tolerance == sol.history_tolerance and loaded.history_tolerance_auto
    assert (loaded.history_exponentials, loaded.history_window, loaded.history_bytes) == (
        sol.history_exponentials, sol.history_window, sol.history_bytes)
    assert "damping memory    fast: %d exponentials + window of %d lags" % (
        sol.history_exponentials, sol.history_window) in cli(
            "run", path, "--set", "method.scheme=fvi-gl", "--set", "method.history=fast",
            "--out", str(tmp_path / "text"), "--no-plot").stdout


def test_memory_is_estimated_before_allocating():
    # The stored trajectory ((N + 1) rows of 16 d + 40 bytes) is refused with the number, as on
    # the command line, instead of a MemoryError (or the OOM killer) after the set-up.
    memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    if (2_000_000_000 + 1) * (16 * 2 + 40) <= memory:
        pytest.skip("this machine could hold 2e9 stored states of d = 2")
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.integrate(fracvi.Problem.from_toml(PROBLEM).with_overrides("time.steps=2000000000",
                                                                          "output.every=1"))
    message = str(e.value)
    assert "time.steps = 2000000000 with output.every = 1: the stored trajectory" in message
    assert "more than this machine's memory" in message and "[output] every = n" in message
    with pytest.raises(fracvi.ProblemError, match="model.dim = 1000000000000: the first and last"):
        fracvi.Problem.from_toml(PROBLEM).with_overrides("model.dim=1000000000000")


def test_every_auto_thins_long_runs_only():
    # output.every = "auto" (the default): every state up to 10^5 steps, beyond the smallest power
    # of two keeping 10^5 + 1 rows; dense=True (interpolation between consecutive steps) takes 1.
    problem = fracvi.Problem.from_toml(PROBLEM)
    assert problem.every == "auto"
    long_run = problem.with_overrides("time.steps=200001", "time.end=20")
    sol = fracvi.integrate(long_run, mirror=False, error_estimate="none")
    assert sol.save_every == 4 and len(sol.t) == 50001 + 1  # 0, 4, ..., 200000, and 200001
    assert sol.step[-1] == 200001
    dense = fracvi.integrate(long_run, mirror=False, error_estimate="none", dense=True)
    assert dense.save_every == 1 and len(dense.t) == 200002
    assert fracvi.integrate(problem, mirror=False, error_estimate="none").save_every == 1


def test_ctrl_c_raises_keyboard_interrupt_with_the_partial_solution():
    # Issue 14: Ctrl-C used to have no effect until the C++ loop ended (53 s), and the result was
    # then discarded. 2·10^7 steps would take about a minute; SIGINT arrives after 0.5 s (from a
    # timer thread, as a terminal's Ctrl-C would), the run stops within about 0.1 s of it.
    import signal
    import threading
    import time
    long_run = FRACTIONAL.replace("end = 4.0\nsteps = 400", "end = 2000.0\nsteps = 20000000")
    assert long_run != FRACTIONAL
    problem = fracvi.Problem.from_toml(long_run)
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as raised:
            fracvi.integrate(problem, every=1000, history="fast", error_estimate="none",
                             mirror=False)
    finally:
        timer.cancel()
    elapsed = time.monotonic() - start
    assert elapsed < 20.0, elapsed
    solution = raised.value.solution
    assert solution.status == "interrupted"
    assert "interrupted after step" in solution.message
    assert 0 < solution.steps < 20_000_000
    # Rows 0, 1000, … and the last completed step, all computed.
    assert solution.step[-1] == solution.steps
    assert len(solution.t) == solution.steps // 1000 + 1 + (1 if solution.steps % 1000 else 0)
    assert np.all(np.isfinite(solution.x))
    # The partial solution is a Solution like any other (summary, write).
    assert solution.summary()["status"] == "interrupted"


def test_checkpoint_every_is_fracvi_runs():
    problem = fracvi.Problem.from_toml(FRACTIONAL + "[output]\ncheckpoint_every = 100\n")
    with pytest.raises(fracvi.ProblemError,
                       match=r"output.checkpoint_every = 100: checkpoints are written by "
                             r"`fracvi run` into its output directory; fracvi.integrate writes "
                             r"none \(set it to 0\)"):
        fracvi.integrate(problem)
    with pytest.raises(TypeError, match="unexpected keyword argument 'checkpoint_every'"):
        fracvi.integrate(fracvi.Problem.from_toml(FRACTIONAL), checkpoint_every=100)


# --- non-conservative forces g(x, v, t) (docs/theory/forces.md) ---------------------------------

def van_der_pol(**fields):
    return fracvi.Problem(name="vdp", dim=1, mass=1.0, alpha=0.5, potential="x1^2/2",
                          force=["1.0*(1 - x1^2)*v1"], position=[2.0], velocity=[0.0], end=4.0,
                          steps=400, **fields)


def test_velocity_dependent_force_passes_through():
    p = van_der_pol()
    assert p.force == ["1.0*(1 - x1^2)*v1"]
    sol = fracvi.integrate(p, scheme="fvi-midpoint", error_estimate="none")
    assert sol.ok, sol.message
    # The force pumps energy in and takes it out (|W| of order one) and the balance, with g's
    # work booked, is exact to round-off for the quadratic U (N eps (max|E| + max|W|)).
    scale = np.abs(sol.energy).max() + np.abs(sol.dissipated).max()
    assert np.abs(sol.dissipated).max() > 0.1
    assert sol.max_balance_error <= len(sol.t) * np.finfo(float).eps * scale
    # Against the same oscillator without the force: a different trajectory.
    free = fracvi.integrate(fracvi.Problem(name="free", dim=1, mass=1.0, alpha=0.5,
                                           potential="x1^2/2",
                                           position=[2.0], velocity=[0.0], end=4.0, steps=400),
                            scheme="fvi-midpoint", error_estimate="none")
    assert abs(sol.x[-1, 0] - free.x[-1, 0]) > 0.1


def test_state_force_refused_by_schemes_without_it():
    with pytest.raises(ValueError, match=r'conformal-strang.*g\(x, v, t\)'):
        fracvi.integrate(van_der_pol(), scheme="conformal-strang")


def test_nan_force_is_a_status_with_the_trajectory():
    p = fracvi.Problem(name="nan", dim=1, mass=1.0, alpha=0.5, potential="x1^2/2",
                       force=["sqrt(x1 - 1)*v1"], position=[2.0], velocity=[0.0], end=4.0,
                       steps=400)
    sol = fracvi.integrate(p, error_estimate="none")
    assert sol.status == "non-finite" and not sol.ok
    assert 0 < len(sol.t) - 1 < 400 and np.isfinite(sol.x).all()
    assert "non-finite" in sol.message
