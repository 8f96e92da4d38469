"""fracvi.Integrator: stepping by hand gives the rows of fracvi.integrate, bit for bit; run(until=),
the observer, failures, exceptions from the observer and Ctrl-C leave the solution so far."""
import os
import signal
import threading
import time

import numpy as np
import pytest

import fracvi
from conftest import BLOWUP, FRACTIONAL, PROBLEM

ARRAYS = ("t", "step", "x", "v", "energy", "dissipated", "balance")


def assert_same_rows(a, b):
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize("text", [PROBLEM, FRACTIONAL], ids=["nonlinear-2d", "fractional"])
def test_hand_stepping_is_integrate_bit_for_bit(text):
    problem = fracvi.Problem.from_toml(text)
    one_call = fracvi.integrate(problem)
    integ = fracvi.Integrator(problem)
    assert (integ.k, integ.t, integ.status) == (0, problem.start, "running")
    np.testing.assert_array_equal(integ.state.x, problem.position)
    statuses = []
    while integ.status == "running":
        statuses.append(integ.step())
        assert integ.state.k == integ.k == len(statuses)
        np.testing.assert_array_equal(integ.state.x, one_call.x[integ.k])
        np.testing.assert_array_equal(integ.state.v, one_call.v[integ.k])
    assert statuses == ["running"] * (problem.steps - 1) + ["success"]
    assert integ.step() == "success" and integ.k == problem.steps  # ended: a no-op
    solution = integ.solution()
    assert_same_rows(solution, one_call)
    assert solution.status == one_call.status == "success"
    # The finished solution has the mirror run and the error estimate of integrate().
    assert solution.mirror_error == one_call.mirror_error and solution.mirror_error > 0
    assert solution.error_estimate == one_call.error_estimate
    assert integ.solution() is not solution and integ.solution()._run is solution._run  # made once


def test_state_has_the_momentum_of_the_mass_matrix():
    # PROBLEM has a full 2 × 2 mass matrix: p = M v, computed here independently.
    problem = fracvi.Problem.from_toml(PROBLEM)
    integ = fracvi.Integrator(problem, mirror=False, error_estimate="none")
    integ.run(steps=37)
    state = integ.state
    assert state.k == 37 and state.t == pytest.approx(0.37, abs=1e-15)
    np.testing.assert_allclose(state.p, problem.mass @ state.v, rtol=1e-15, atol=0)
    assert state.balance == pytest.approx(state.energy + state.dissipated - integ.solution()
                                          .energy[0], abs=1e-12)
    # A copy: the next step does not change it.
    x = state.x.copy()
    integ.step()
    np.testing.assert_array_equal(state.x, x)


def test_run_until_stops_on_the_grid():
    problem = fracvi.Problem.from_toml(PROBLEM)  # h = 0.01 on [0, 5]
    integ = fracvi.Integrator(problem, mirror=False, error_estimate="none")
    assert integ.run(until=1.0) == "running" and integ.k == 100
    assert integ.run(until=1.0099) == "running" and integ.k == 100  # t_101 = 1.01 > until
    assert integ.run(until=0.3 * 7) == "running" and integ.k == 210  # 2.1000000000000001
    assert integ.run(steps=5) == "running" and integ.k == 215
    part = integ.solution()
    assert part.status == "running" and part.steps == 215 and len(part.t) == 216
    assert "stopped by the caller after 215 of 500 steps" in part.message
    assert integ.run(steps=10**9) == "success" and integ.k == 500
    assert_same_rows(integ.solution(), fracvi.integrate(problem, mirror=False,
                                                        error_estimate="none"))


def test_run_refuses_bad_targets():
    integ = fracvi.Integrator(PROBLEM, mirror=False, error_estimate="none")
    integ.run(until=2.0)
    with pytest.raises(ValueError, match=r"until = 1.5 is before the current time t = 2.0 "
                                         r"\(step 200\): an Integrator only goes forward"):
        integ.run(until=1.5)
    with pytest.raises(ValueError, match=r"until = 5.5 is after the problem's end time "
                                         r"time.end = 5.0"):
        integ.run(until=5.5)
    with pytest.raises(ValueError, match="until = nan must be a finite time"):
        integ.run(until=float("nan"))
    with pytest.raises(TypeError, match="until = '3' must be a number"):
        integ.run(until="3")
    with pytest.raises(ValueError, match="steps = -1 must not be negative"):
        integ.run(steps=-1)
    with pytest.raises(TypeError, match=r"steps = 2.0 must be an integer"):
        integ.run(steps=2.0)
    with pytest.raises(TypeError, match="until= or steps=, not both"):
        integ.run(until=3.0, steps=2)
    with pytest.raises(TypeError, match="observer = 3 is not callable"):
        integ.run(observer=3)
    assert integ.k == 200  # nothing was stepped


def test_options_are_those_of_integrate():
    problem = fracvi.Problem.from_toml(FRACTIONAL)
    integ = fracvi.Integrator(problem, scheme="fvi-bdf2", every=7, diagnostics=False,
                              mirror=False, error_estimate="none")
    assert integ.problem.scheme == "fvi-bdf2" and integ.problem.every == 7
    integ.run()
    solution = integ.solution()
    one_call = fracvi.integrate(problem, scheme="fvi-bdf2", every=7, diagnostics=False,
                                mirror=False, error_estimate="none")
    assert solution.method == "fvi-bdf2" and np.all(np.isnan(solution.energy))
    assert_same_rows(solution, one_call)
    with pytest.raises(TypeError, match="Integrator\\(\\) got an unexpected keyword argument "
                                        "'steps_per_unit'"):
        fracvi.Integrator(problem, steps_per_unit=3)
    with pytest.raises(fracvi.ProblemError, match="method.tolerance = 0.001: .* an Integrator "
                                                  "steps one grid"):
        fracvi.Integrator(problem, tolerance=1e-3)
    with pytest.raises(fracvi.ProblemError, match="fracvi.Integrator writes none"):
        fracvi.Integrator(FRACTIONAL + "[output]\ncheckpoint_every = 100\n")
    with pytest.raises(fracvi.ProblemError, match="method.scheme"):
        fracvi.Integrator(problem, scheme="rk4")


def test_observer_sees_every_step():
    problem = fracvi.Problem.from_toml(FRACTIONAL)
    one_call = fracvi.integrate(problem, mirror=False, error_estimate="none")
    integ = fracvi.Integrator(problem, every=50, mirror=False, error_estimate="none")
    seen = []
    assert integ.run(until=1.0, observer=seen.append) == "running"
    assert [s.k for s in seen] == list(range(0, 101))  # k = 0 first, no step taken yet
    assert all(isinstance(s, fracvi.State) for s in seen)
    for s in seen:
        np.testing.assert_array_equal(s.x, one_call.x[s.k])
        assert s.t == one_call.t[s.k] and s.energy == one_call.energy[s.k]
    more = []
    integ.run(observer=more.append)
    assert [s.k for s in more] == list(range(101, problem.steps + 1))  # no k = 100 again


def test_exception_in_the_observer_ends_run_with_the_solution_so_far():
    problem = fracvi.Problem.from_toml(PROBLEM)
    integ = fracvi.Integrator(problem, every=3, mirror=False, error_estimate="none")

    def observer(state):
        if state.k == 7:
            raise RuntimeError("enough at 7")

    with pytest.raises(RuntimeError, match="enough at 7") as raised:
        integ.run(observer=observer)
    partial = raised.value.solution
    assert partial.status == "running" and partial.steps == 7 == integ.k
    np.testing.assert_array_equal(partial.step, [0, 3, 6, 7])  # the current state last
    # The Integrator goes on where it was: the same rows as one call.
    assert integ.run() == "success"
    assert_same_rows(integ.solution(), fracvi.integrate(problem, every=3, mirror=False,
                                                        error_estimate="none"))


@pytest.mark.parametrize("raise_on_failure", [False, True])
def test_failing_step_is_a_status(raise_on_failure):
    one_call = fracvi.integrate(BLOWUP)
    assert one_call.status == "newton-failure"
    integ = fracvi.Integrator(BLOWUP, raise_on_failure=raise_on_failure)
    if raise_on_failure:
        with pytest.raises(fracvi.IntegrationError) as raised:
            integ.run()
        solution = raised.value.solution
        assert raised.value.status == "newton-failure"
    else:
        assert integ.run() == "newton-failure"
        solution = integ.solution()
    assert integ.status == "newton-failure" and integ.k == one_call.steps
    assert solution.message == one_call.message and "at step 297" in solution.message
    assert_same_rows(solution, one_call)
    if raise_on_failure:  # a step of an ended run takes none and says so again
        with pytest.raises(fracvi.IntegrationError):
            integ.step()
    else:
        assert integ.step() == "newton-failure"
    assert integ.k == one_call.steps


def test_health_check_status_from_step():
    # U = -1/x1 from rest crosses its singularity: "inaccurate" (test_integrate.py), here from the
    # last step().
    text = (BLOWUP.replace('"-x1^4"', '"-1/x1"').replace("[1.0]\n[time]", "[0.0]\n[time]")
            .replace("steps = 500", "steps = 1000"))
    one_call = fracvi.integrate(text, mirror=False, error_estimate="none")
    assert one_call.status == "inaccurate"
    integ = fracvi.Integrator(text, mirror=False, error_estimate="none")
    statuses = [integ.step() for _ in range(1000)]
    assert statuses[-1] == "inaccurate" and set(statuses[:-1]) == {"running"}
    assert integ.solution().message == one_call.message
    assert_same_rows(integ.solution(), one_call)


def test_ctrl_c_during_run_raises_with_the_solution_so_far_and_the_run_goes_on():
    long_run = FRACTIONAL.replace("end = 4.0\nsteps = 400", "end = 2000.0\nsteps = 20000000")
    integ = fracvi.Integrator(long_run, every=1000, history="fast", error_estimate="none",
                              mirror=False)
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as raised:
            integ.run()
    finally:
        timer.cancel()
    assert time.monotonic() - start < 20.0
    partial = raised.value.solution
    assert partial.status == "interrupted"
    assert partial.message.startswith(f"interrupted after step {integ.k} of 20000000")
    assert "the Integrator can go on" in partial.message
    assert 0 < partial.steps == integ.k < 20_000_000 and partial.step[-1] == integ.k
    assert np.all(np.isfinite(partial.x))
    # Not the end of the integration: it goes on, to the rows of an uninterrupted run.
    k = integ.k
    assert integ.status == "running"
    integ.run(steps=2500)
    assert integ.k == k + 2500
    reference = fracvi.Integrator(long_run, every=1000, history="fast", error_estimate="none",
                                  mirror=False)
    reference.run(steps=k + 2500)
    np.testing.assert_array_equal(integ.state.x, reference.state.x)
    assert_same_rows(integ.solution(), reference.solution())


def test_observer_interrupted_by_ctrl_c():
    # Ctrl-C while the observer runs (Python code) raises inside it: the same status.
    integ = fracvi.Integrator(FRACTIONAL, mirror=False, error_estimate="none")

    def observer(state):
        if state.k == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as raised:
        integ.run(observer=observer)
    assert raised.value.solution.status == "interrupted" and raised.value.solution.steps == 5


def test_one_thread_at_a_time_and_no_pickling():
    import pickle
    long_run = FRACTIONAL.replace("end = 4.0\nsteps = 400", "end = 2000.0\nsteps = 20000000")
    integ = fracvi.Integrator(long_run, history="fast", every=1000, error_estimate="none",
                              mirror=False)
    errors = []

    def other_thread():
        time.sleep(0.2)
        for call in (integ.step, lambda: integ.state, integ.run):
            try:
                call()
            except RuntimeError as e:
                errors.append(str(e))
        os.kill(os.getpid(), signal.SIGINT)  # ends the long run

    thread = threading.Thread(target=other_thread)
    thread.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            integ.run()
    finally:
        thread.join()
    assert errors == ["this fracvi.Integrator is stepping in another thread; use one "
                      "Integrator per thread"] * 3
    assert integ.status == "running" and integ.k > 0
    integ.step()  # the run goes on in this thread
    with pytest.raises(TypeError, match="a fracvi.Integrator does not pickle"):
        pickle.dumps(integ)
