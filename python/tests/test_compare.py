"""fracvi.compare: the table as NumPy columns, measured against an independent closed form, and
fracvi.plot_compare."""
import math
import os

import numpy as np
import pytest

import fracvi

W = math.sqrt(1 - 1 / 64)
C = 0.625 / W
OSCILLATOR = {
    "name": "osc",
    "model": {"dim": 1, "mass": 1.0, "damping": 0.25, "alpha": 0.5, "potential": "x1^2/2"},
    "initial": {"position": [1.0], "velocity": [0.5]},
    "time": {"end": 16.0, "steps": 100},
}
EXACT = f"exp(-t/8)*(cos({W!r}*t) + {C!r}*sin({W!r}*t))"


def exact_x(t):
    return np.exp(-t / 8) * (np.cos(W * t) + C * np.sin(W * t))


def test_table_columns_and_values():
    r = fracvi.compare(OSCILLATOR, steps=[50, 100, 200],
                       schemes=["fvi-bdf2", "euler-explicit", "dopri5"], reference=EXACT)
    t = r["table"]
    assert r["reference"] == "exact solution"
    assert list(t["scheme"]) == ["fvi-bdf2"] * 3 + ["euler-explicit"] * 3 + ["dopri5"] * 3
    assert list(t["steps"]) == [50, 100, 200] * 3
    assert t["max_error"].dtype == np.float64 and t["steps"].dtype == np.int64
    assert t["status"][3] == "not applicable" and "stability bound" in t["message"][3]
    assert np.isnan(t["max_error"][3])
    # The fvi-bdf2 rows against the closed form, measured here with fracvi.integrate.
    for i, n in enumerate((50, 100, 200)):
        problem = dict(OSCILLATOR, time={"end": 16.0, "steps": n})
        sol = fracvi.integrate(problem, scheme="fvi-bdf2", mirror=False, error_estimate="none")
        err = np.max(np.abs(sol.x[:, 0] - exact_x(sol.t)))
        assert t["max_error"][i] == pytest.approx(err, rel=1e-10)
        assert t["final_error"][i] == pytest.approx(abs(sol.x[-1, 0] - exact_x(16.0)), rel=1e-9)
    # dopri5's error follows its tolerances (1e-8), not N.
    assert np.all(t["max_error"][6:] < 1e-6)
    e = r["energy"]
    assert e["steps"] == 100 and e["t"].shape == (101,)
    assert set(e["energy"]) == {"fvi-bdf2", "euler-explicit", "dopri5"}
    assert e["reference_energy"][0] == pytest.approx(0.625, abs=1e-15)


def test_fine_run_reference_and_plots(tmp_path):
    r = fracvi.compare(OSCILLATOR, steps=[100, 200], schemes="fvi-midpoint",
                       reference_steps=3200, reference_scheme="fvi-lobatto4")
    assert r["reference"] == "fvi-lobatto4 with 3200 steps"
    ratio = r["table"]["max_error"][0] / r["table"]["max_error"][1]
    assert ratio == pytest.approx(4.0, abs=0.3)  # second order
    paths = fracvi.plot_compare(r, str(tmp_path / "figs"))
    assert [os.path.basename(p) for p in paths] == ["work_precision.png", "error_vs_steps.png",
                                                     "energy_tracking.png"]
    for p in paths:
        assert os.path.getsize(p) > 10000, p


def test_bad_arguments():
    with pytest.raises(ValueError, match="step counts must increase"):
        fracvi.compare(OSCILLATOR, steps=[100, 50], reference=EXACT)
    with pytest.raises(ValueError, match="no reference"):
        fracvi.compare(OSCILLATOR, steps=[100])
    with pytest.raises(ValueError, match="is not a known scheme"):
        fracvi.compare(OSCILLATOR, steps=[100], schemes=["nope"], reference=EXACT)
    with pytest.raises(ValueError, match="repeat"):
        fracvi.compare(OSCILLATOR, steps=[100], reference=EXACT, repeat=0)
