"""FracEL residuals and the action along given curves from Python (issue 13): formulas and
callables, against closed forms and the Theorem ConsFraEL identity."""
import math

import numpy as np
import pytest

import fracvi

# The damped oscillator x'' + 0.25 x' + x = 0 of Corollary 4.4 (alpha = 1/2) on [0, 2].
OSCILLATOR = {
    "model": {"dim": 1, "mass": 1.0, "damping": 0.25, "alpha": 0.5, "potential": "x1^2/2"},
    "initial": {"position": [0.0], "velocity": [0.0]},  # not used by the residual
    "time": {"end": 2.0, "steps": 10},
}
G = 0.125
W = math.sqrt(1 - G * G)
C = (0.5 + G) / W  # x(0) = 1, v(0) = 0.5


def exact(s):
    return f"exp(-{G}*{s})*(cos({W!r}*{s}) + {C!r}*sin({W!r}*{s}))"


def exact_callables(mirrored):
    # x and its first two derivatives by hand (x'' = -0.25 x' - x).
    def value(t):
        s = 2.0 - t if mirrored else t
        return math.exp(-G * s) * (math.cos(W * s) + C * math.sin(W * s))

    def rate(t):
        s = 2.0 - t if mirrored else t
        d = math.exp(-G * s) * ((-G + C * W) * math.cos(W * s) + (-G * C - W) * math.sin(W * s))
        return -d if mirrored else d

    def acceleration(t):
        # x'' = -0.25 x' - x for x; the mirror y satisfies y'' = +0.25 y' - y.
        return (0.25 if mirrored else -0.25) * rate(t) - value(t)

    return (value, rate, acceleration)


def test_residual_with_nonzero_initial_data_formulas_and_callables():
    for x, y in ((exact("t"), exact("(2 - t)")),
                 (exact_callables(False), exact_callables(True))):
        ex, ey = fracvi.fracel_residual(OSCILLATOR, x, y, [0.01, 0.7, 1.99])
        assert ex.shape == (3, 1) and ey.shape == (3, 1)
        assert np.max(np.abs(ex)) <= 1e-10 and np.max(np.abs(ey)) <= 1e-10
    ex, ey = fracvi.fracel_residual(OSCILLATOR, "cos(t)", "cos(2 - t)", 1.0)
    assert ex.shape == (1,) and abs(ex[0]) > 0.05  # the undamped curve is not a solution


def test_residual_matches_closed_form_at_fractional_alpha():
    # Mechanical L (m = 1, R = 0.25, k = 1) along x = 0.8 + t^2.5, y = 0 at alpha = 0.7:
    # x-equation = -x - x'' - R D^a D^a x with D^a D^a (c + t^p) = c t^(-2a)/G(1-2a)
    #              + G(p+1)/G(p+1-2a) t^(p-2a).
    problem = {**OSCILLATOR,
               "model": {**OSCILLATOR["model"], "alpha": 0.7, "convention": "riemann-liouville"}}
    a, p, t = 0.7, 2.5, 0.9
    dd = 0.8 * t ** (-2 * a) / math.gamma(1 - 2 * a) + math.gamma(p + 1) / math.gamma(
        p + 1 - 2 * a) * t ** (p - 2 * a)
    expected = -(0.8 + t ** p) - p * (p - 1) * t ** (p - 2) - 0.25 * dd
    ex, _ = fracvi.fracel_residual(problem, "0.8 + t^2.5", "0", t)
    assert abs(ex[0] - expected) <= 1e-10 * (1 + abs(expected))


def test_action_variation_and_pairing():
    problem = {"model": {"dim": 1, "alpha": 0.5,
                         "lagrangian": "0.5*xdot1^2 + 0.5*ydot1^2 - 0.5*x1^2 - 0.5*y1^2"
                                       " - 0.25*dx1*dy1 + 0.3*xdot1*dy1"},
               "boundary": {"start": [0.0], "end": [0.0]},
               "time": {"end": 2.0, "steps": 10}}
    r = fracvi.action(problem, "1 + sin(t)", "cos(2 - t)")
    assert list(r) == ["action"]
    eta = "t^2*(2 - t)^2"
    r = fracvi.action(problem, "1 + sin(t)", "cos(2 - t)", eta, pairing=True, tolerance=1e-6)
    assert abs(r["variation"]) > 0.05
    assert abs(r["variation"] - r["pairing"]) <= 1e-8 * abs(r["variation"])
    # Unrestricted: delta y != delta x breaks the identity.
    u = fracvi.action(problem, "1 + sin(t)", "cos(2 - t)", eta, "sin(pi*t/2)^2", pairing=True,
                      tolerance=1e-6)
    assert abs(u["variation"] - u["pairing"]) > 1e-3


def test_bad_input():
    with pytest.raises(ValueError, match="2 components"):
        fracvi.fracel_residual(OSCILLATOR, ["t", "t"], "0", 1.0)
    with pytest.raises(ValueError, match="three"):
        fracvi.fracel_residual(OSCILLATOR, (math.sin, math.cos), "0", 1.0)
    with pytest.raises(ValueError, match="terminal"):
        fracvi.fracel_residual(OSCILLATOR, "1 + t", "0", 0.0)
    with pytest.raises(ValueError, match="need eta"):
        fracvi.action(OSCILLATOR, "t", "2 - t", pairing=True)
    with pytest.raises(ValueError, match="second order"):
        fracvi.action(OSCILLATOR, "t", "2 - t", "t*(2 - t)", pairing=True)
