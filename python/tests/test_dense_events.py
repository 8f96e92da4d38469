"""Dense output (t_eval, dense=True, solution(t)) and events (formulas, callables; terminal,
direction; bad callbacks) from Python (docs/python.md, docs/theory/dense_output.md). The orders
of the interpolant for every scheme are measured in C++ (tests/integrate/dense_output_test.cpp);
here the Python surface, against the closed form of a damped oscillator."""
import math

import numpy as np
import pytest

import fracvi

# x'' + 2 zeta omega x' + omega^2 x = 0, x(0) = 1, v(0) = 0 (2 alpha = 1).
OMEGA, ZETA = 2.0, 0.1
OMEGA_D = OMEGA * math.sqrt(1 - ZETA * ZETA)


def exact(t):
    t = np.asarray(t, dtype=float)
    decay = np.exp(-ZETA * OMEGA * t)
    x = decay * (np.cos(OMEGA_D * t) + ZETA * OMEGA / OMEGA_D * np.sin(OMEGA_D * t))
    v = -OMEGA * OMEGA / OMEGA_D * decay * np.sin(OMEGA_D * t)
    return x, v


def zero_time(j):
    """The j-th zero of x (falling for odd j)."""
    return (j * math.pi - math.atan(OMEGA_D / (ZETA * OMEGA))) / OMEGA_D


def oscillator(steps=200, **method):
    return fracvi.Problem(dim=1, mass=1.0, damping=2 * ZETA * OMEGA, alpha=0.5,
                          potential=f"{OMEGA * OMEGA / 2}*x1^2", position=[1.0], velocity=[0.0],
                          end=6.0, steps=steps, error_estimate="none", mirror="off", **method)


# Off the grid for every N below: irrational fractions of the interval.
T_EVAL = 6.0 * (np.arange(7) + (math.sqrt(5) - 1) / 2) / 7


def test_t_eval_keeps_the_fourth_order_of_fvi_lobatto3():
    hs, errors = [], []
    for n in (25, 50, 100, 200):
        solution = fracvi.integrate(oscillator(n, scheme="fvi-lobatto3"), t_eval=T_EVAL)
        assert solution.ok, solution.message
        np.testing.assert_array_equal(solution.t_eval, T_EVAL)
        x, _ = exact(T_EVAL)
        hs.append(6.0 / n)
        errors.append(np.abs(solution.x_eval[:, 0] - x).max())
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert slope > 3.8, (slope, errors)
    # Negative control: linear interpolation of the same stored grid states is second order.
    lin = []
    for n in (25, 50, 100, 200):
        solution = fracvi.integrate(oscillator(n, scheme="fvi-lobatto3"))
        lin.append(np.abs(np.interp(T_EVAL, solution.t, solution.x[:, 0]) - exact(T_EVAL)[0]).max())
    assert np.polyfit(np.log(hs), np.log(lin), 1)[0] < 2.3


def test_grid_times_are_the_grid_states_and_every_does_not_thin_t_eval():
    problem = oscillator(60, scheme="fvi-midpoint")
    grid = problem.start + problem.step * np.array([0, 7, 30, 60])
    times = np.sort(np.concatenate([grid, T_EVAL]))
    full = fracvi.integrate(problem, t_eval=times)
    thinned = fracvi.integrate(problem, t_eval=times, every=7)
    np.testing.assert_array_equal(full.x_eval, thinned.x_eval)
    np.testing.assert_array_equal(full.v_eval, thinned.v_eval)
    for t in grid:
        row = np.flatnonzero(full.t == t)[0]
        np.testing.assert_array_equal(full.x_eval[np.flatnonzero(times == t)[0]], full.x[row])


def test_dense_solution_is_callable_and_matches_t_eval():
    problem = oscillator(80, scheme="fvi-lobatto3")
    solution = fracvi.integrate(problem, t_eval=T_EVAL, dense=True)
    np.testing.assert_array_equal(solution(T_EVAL), solution.x_eval)
    x, v = solution.interpolate(T_EVAL[2])
    np.testing.assert_array_equal(x, solution.x_eval[2])
    np.testing.assert_array_equal(v, solution.v_eval[2])
    assert solution(T_EVAL[:3]).shape == (3, 1)
    assert abs(solution(1.0)[0] - exact(1.0)[0]) < 1e-6  # h = 0.075: measured 2.0e-7
    with pytest.raises(ValueError, match=r"sol\(t\) at t = 7: must be within the stored times"):
        solution(7.0)
    with pytest.raises(ValueError, match=r"dense=True needs every step stored \(output.every = "
                                         r"1\).*output.every = 10"):
        fracvi.integrate(problem, dense=True, every=10)
    thinned = fracvi.integrate(problem, every=10)
    with pytest.raises(ValueError, match="not consecutive: dense output needs every step stored"):
        thinned(0.55)


def test_bad_t_eval_names_the_field_the_value_and_the_rule():
    with pytest.raises(fracvi.ProblemError, match=r"output.times\[3\] = 7 must be within "
                                                  r"\[time.start, time.end\] = \[0, 6\]"):
        fracvi.integrate(oscillator(), t_eval=[0.5, 1.0, 7.0])
    with pytest.raises(fracvi.ProblemError, match=r"output.times\[2\] = 0.5 is smaller than the "
                                                  r"time before it \(1\): the times must be "
                                                  r"ascending"):
        fracvi.integrate(oscillator(), t_eval=[1.0, 0.5])
    with pytest.raises(ValueError, match=r"t_eval must be a 1-D sequence of times"):
        fracvi.integrate(oscillator(), t_eval=[[1.0, 2.0]])
    with pytest.raises(TypeError, match="t_eval and times"):
        fracvi.integrate(oscillator(), t_eval=[1.0], times=[1.0])


def test_formula_callable_and_dict_events_agree_with_the_closed_form():
    def down(t, x, v):
        return x[0]
    down.direction = -1  # SciPy's attribute

    solution = fracvi.integrate(
        oscillator(400, scheme="fvi-lobatto3"),
        events=["x1", down, {"name": "turn", "g": "v1", "direction": "rising"}])
    assert solution.ok, solution.message
    zeros = [zero_time(j) for j in range(1, 10) if zero_time(j) <= 6.0]
    np.testing.assert_allclose(solution.t_events["x1"], zeros, atol=1e-8)
    np.testing.assert_allclose(solution.t_events["down"], zeros[0::2], atol=1e-8)
    # v rises through 0 at its minima of x: t = j pi / omega_d, j odd.
    turns = [j * math.pi / OMEGA_D for j in (1, 3) if j * math.pi / OMEGA_D <= 6.0]
    np.testing.assert_allclose(solution.t_events["turn"], turns, atol=1e-8)
    record = solution.events[0]
    assert record.name == "x1" and record.direction == -1
    assert abs(record.x[0]) < 1e-14
    np.testing.assert_allclose(record.v, exact(record.t)[1], atol=1e-7)
    assert [e["name"] for e in solution.summary()["events"]] == [e.name for e in solution.events]


def test_terminal_event_stops_the_run_without_failing():
    def impact(t, x, v):
        return x[0]
    impact.terminal = True
    solution = fracvi.integrate(oscillator(400), events=impact, t_eval=[0.5, 5.0],
                                raise_on_failure=True)
    assert solution.status == "event"
    assert not solution.ok
    assert 'terminal event "impact"' in solution.message
    assert len(solution.events) == 1
    assert solution.t[-1] >= solution.events[0].t > solution.t[-1] - 6.0 / 400
    assert list(solution.t_eval) == [0.5]  # 5.0 is after the stop
    assert solution.summary()["status"] == "event"


def test_a_callback_that_raises_ends_the_run_with_its_traceback():
    def sensor(t, x, v):
        if t > 1.0:
            return 1.0 / 0.0
        return x[0] + 2.0
    solution = fracvi.integrate(oscillator(100), events=sensor)
    assert solution.status == "callback-error"
    assert 'events[0] ("sensor") threw in step 17' in solution.message
    assert "ZeroDivisionError: float division by zero" in solution.message
    assert "test_dense_events.py" in solution.message and "in sensor" in solution.message
    assert solution.steps == 17 and len(solution.x) > 1  # the steps so far are kept


def test_a_callback_returning_nan_or_the_wrong_shape_is_reported():
    nan = fracvi.integrate(oscillator(100),
                           events=lambda t, x, v: math.nan if t > 2.0 else 1.0)
    assert nan.status == "non-finite"
    assert 'events[0] ("<lambda>"): g = nan' in nan.message
    assert "must return a finite number" in nan.message
    # One number in an array of one element is one number (x has d = 1).
    assert fracvi.integrate(oscillator(100), events={"name": "x", "g": lambda t, x, v: x}).ok
    # Wrong from the first call (at t_0): refused before step 1.
    with pytest.raises(ValueError, match=r'events\[0\] \("pair"\): g\(t_0, x_0, v_0\) threw: g '
                                         r'returned array\(\[1., 1.\]\) \(type ndarray, shape '
                                         r'\(2,\)\): it must return one real number'):
        fracvi.integrate(oscillator(100), events={"name": "pair",
                                                  "g": lambda t, x, v: np.array([x[0], 1])})
    # Wrong later: the run ends there.
    pair = fracvi.integrate(oscillator(100), events={
        "name": "pair", "g": lambda t, x, v: np.array([x[0], 1]) if t > 1.0 else 1.0})
    assert pair.status == "callback-error" and pair.steps == 17
    assert "shape (2,)): it must return one real number" in pair.message
    text = fracvi.integrate(oscillator(100), events={
        "name": "word", "g": lambda t, x, v: "up" if t > 1.0 else 1.0})
    assert text.status == "callback-error"
    assert "g returned 'up' (type str" in text.message


def test_bad_event_definitions_are_refused_before_step_1():
    with pytest.raises(fracvi.ProblemError, match=r"events\[1\].g: \"x1 \+ y\": unknown variable "
                                                  r"'y'"):
        fracvi.integrate(oscillator(), events="x1 + y")
    with pytest.raises(fracvi.ProblemError, match=r"events\[2\].direction = \"up\" is not one of "
                                                  r"both, rising, falling"):
        fracvi.integrate(oscillator(), events=["x1", {"g": "v1", "direction": "up"}])
    with pytest.raises(TypeError, match=r"events\[0\]: unknown key 'when'"):
        fracvi.integrate(oscillator(), events={"g": "x1", "when": 1})
    with pytest.raises(ValueError, match=r"names must be distinct"):
        fracvi.integrate(oscillator(), events=["x1", {"name": "x1", "g": lambda t, x, v: 1.0}])
    with pytest.raises(ValueError, match=r"g\(t_0, x_0, v_0\) = nan"):
        fracvi.integrate(oscillator(), events=lambda t, x, v: math.nan)


def test_problem_file_events_and_times(tmp_path, cli):
    text = oscillator().to_toml() + """
[[events]]
name = "zero"
g = "x1"
direction = "falling"
terminal = true
"""
    text = text.replace("[output]", "[output]\ntimes = [0.25, 0.5]")
    path = tmp_path / "p.toml"
    path.write_text(text)
    r = cli("run", path, "--out", tmp_path / "out", "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    rows = (tmp_path / "out" / "events.csv").read_text().splitlines()
    assert rows[0] == "event,direction,step,t,x1,v1"
    name, direction, step, t, x, v = rows[1].split(",")
    assert (name, direction) == ("zero", "falling") and abs(float(t) - zero_time(1)) < 1e-4
    times = (tmp_path / "out" / "times.csv").read_text().splitlines()
    assert times[0] == "t,x1,v1" and len(times) == 3
    # The same run from Python gives the same numbers.
    solution = fracvi.integrate(fracvi.Problem.from_toml(str(path)))
    assert float(t) == solution.events[0].t
    assert [float(c) for c in times[1].split(",")] == [0.25, *solution.x_eval[0],
                                                      *solution.v_eval[0]]


def test_pickle_and_load_keep_t_eval_and_the_events(tmp_path, cli):
    import pickle

    def down(t, x, v):
        return x[0]
    down.direction = -1
    solution = fracvi.integrate(oscillator(400), t_eval=T_EVAL,
                                events=["v1", down, {"name": "turn", "g": "v1"}])
    assert len(solution.events) >= 5 and len(solution.t_eval) == len(T_EVAL)

    def same(a, b):
        assert np.array_equal(a.t_eval, b.t_eval) and np.array_equal(a.x_eval, b.x_eval)
        assert np.array_equal(a.v_eval, b.v_eval)
        assert [(e.name, e.t, e.direction, e.step) for e in a.events] == \
            [(e.name, e.t, e.direction, e.step) for e in b.events]
        for e, f in zip(a.events, b.events):
            assert np.array_equal(e.x, f.x) and np.array_equal(e.v, f.v)
        assert a.t_events.keys() == b.t_events.keys()

    same(pickle.loads(pickle.dumps(solution)), solution)
    fracvi.write(solution, solution.problem, tmp_path / "py")
    same(fracvi.load(tmp_path / "py"), solution)
    # A problem file's run, read back: times.csv and summary.json's crossings, bit for bit.
    problem = oscillator(400).to_toml().replace("[output]", "[output]\ntimes = [0.25, 0.5]")
    problem += '\n[[events]]\nname = "zero"\ng = "x1"\n'
    (tmp_path / "p.toml").write_text(problem)
    r = cli("run", tmp_path / "p.toml", "--out", tmp_path / "cli", "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    loaded = fracvi.load(tmp_path / "cli")
    same(loaded, fracvi.integrate(fracvi.Problem.from_toml(str(tmp_path / "p.toml"))))
    assert list(loaded.t_eval) == [0.25, 0.5] and len(loaded.events) >= 3
    # A run directory missing its times.csv is an error that says so.
    (tmp_path / "cli" / "times.csv").unlink()
    with pytest.raises(FileNotFoundError, match=r"times.csv does not exist.*output_times = 2"):
        fracvi.load(tmp_path / "cli")


def test_the_integrator_takes_the_same_keywords():
    def impact(t, x, v):
        return x[0]
    impact.terminal = True
    integrator = fracvi.Integrator(oscillator(400, scheme="fvi-lobatto3"), events=impact,
                                   t_eval=[0.3, 0.6, 1.5])
    assert integrator.run(until=0.5) == "running"
    assert integrator.run() == "event"
    solution = integrator.solution()
    assert solution.status == "event" and len(solution.events) == 1
    assert abs(solution.events[0].t - zero_time(1)) < 1e-9
    np.testing.assert_array_equal(solution.t_eval, [0.3, 0.6])
    again = fracvi.integrate(oscillator(400, scheme="fvi-lobatto3"), events=impact,
                             t_eval=[0.3, 0.6, 1.5])
    np.testing.assert_array_equal(again.x_eval, solution.x_eval)
    assert again.events[0].t == solution.events[0].t
