"""Inputs whose conversion to an integer or a double would overflow (issue 14, item 7): Python ints
beyond 2^53 and 2^63, tiny or subnormal steps, spans that overflow, dimensions whose storage alone
exceeds any memory, and strides near 2^63. Each is refused with the reader's rule (the same message
as `fracvi run`) or, where valid, runs; none reaches a conversion that is undefined behaviour,
which the asan preset (-fsanitize=float-cast-overflow, scripts/sanitize.sh) would report."""
import math

import pytest

import fracvi

GOOD = dict(name="k", dim=1, mass=1.0, potential="x1^2/2", position=[1.0], end=1.0, steps=10,
            alpha=0.5, damping=0.2)


def refused(match, **changes):
    with pytest.raises(fracvi.ProblemError, match=match):
        fracvi.Problem(**dict(GOOD, **changes))


def test_step_counts_that_would_overflow_are_refused():
    no_steps = {k: v for k, v in GOOD.items() if k != "steps"}
    for step, count in ((1e-300, "1e\\+300"), (5e-324, "inf")):
        with pytest.raises(fracvi.ProblemError,
                           match=f"time.step = .* divides \\[0, 1\\] into {count} steps, more "
                                 "than the limit of 2000000000"):
            fracvi.Problem(**no_steps, step=step)
    with pytest.raises(fracvi.ProblemError, match="into inf steps"):
        fracvi.Problem(**dict(no_steps, start=-1e308, end=1e308), step=1.0)
    refused("time.steps = 9223372036854775807 is more than the limit of 2000000000",
            steps=2**63 - 1)
    refused("time.steps = -9223372036854775808 must be positive", steps=-2**63)
    refused("does not fit 64 bits", steps=2**64)
    refused("time.steps = 1e\\+19 must be an integer|time.steps .*must be an integer",
            steps=1e19)


def test_integers_beyond_two_to_the_53_in_numbers():
    # 2^60 is a double; 2^53 + 1 is not (refused with the rule); 2^64 fits no 64-bit integer.
    assert fracvi.Problem(**dict(GOOD, damping=2**60)).damping == 2.0**60
    refused("integers beyond 2\\^53 are not exactly representable", damping=2**53 + 1)
    refused("does not fit 64 bits", mass=2**64)
    refused("does not fit 64 bits", mass=-2**70)


def test_storage_beyond_any_memory_is_refused_before_allocating():
    for dim in (10**12, 2**62):
        with pytest.raises(fracvi.ProblemError,
                           match=f"model.dim = {dim}: the first and last state alone"):
            fracvi.integrate(fracvi.Problem(**dict(GOOD, dim=dim, position="1")))


def test_a_span_that_overflows_is_refused():
    with pytest.raises(fracvi.ProblemError, match="time.end - time.start = inf"):
        fracvi.integrate(fracvi.Problem(**dict(GOOD, start=-1e308, end=1e308)))


def test_strides_near_two_to_the_63_run():
    # output.every = 2^63 - 1 stores the first and the last state only.
    s = fracvi.integrate(fracvi.Problem(**GOOD), every=2**63 - 1, error_estimate="none")
    assert s.status == "success", s.message
    assert list(s.step) == [0, 10]
    assert math.isfinite(s.x[-1, 0])
