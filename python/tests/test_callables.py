"""U, ∇U and ∇²U as Python functions (issue 16 item 2): Problem(potential=U, gradient=dU,
hessian=H). The runs must equal the formula runs of the same potential, every way a function can
go wrong must give the field and the rule (or, during a run, status "callback-error" with the
traceback and the rows so far), and the problem must survive to_dict, pickling, write/load."""
import os
import pickle
import subprocess

import numpy as np
import pytest
import scipy.sparse

import fracvi

# The coupled nonlinear pair of the CLI tests: U = x1^4/4 + x2^2/2 - 0.2 x1 x2, full M and R,
# fractional damping (2α = 1.2), so Newton and the memory both work.
BASE = dict(name="callables", dim=2, mass=[[2.0, 0.5], [0.5, 1.0]],
            damping=[[0.2, 0.05], [0.05, 0.1]], alpha=0.6, convention="caputo", position=[1.0, 0.0],
            velocity=[0.0, 0.5], end=5.0, steps=400, mirror="off")
FORMULA = "x1^4/4 + x2^2/2 - 0.2*x1*x2"


def U(x, t):
    return x[0]**4 / 4 + x[1]**2 / 2 - 0.2 * x[0] * x[1]


def dU(x, t):
    return np.array([x[0]**3 - 0.2 * x[1], x[1] - 0.2 * x[0]])


def H(x, t):
    return np.array([[3 * x[0]**2, -0.2], [-0.2, 1.0]])


def H_sparse(x, t):
    return scipy.sparse.csr_matrix(H(x, t))


def functions_problem(**extra):
    return fracvi.Problem(**dict(BASE, potential=U, gradient=dU, hessian=H), **extra)


def test_functions_give_the_formula_run():
    formula = fracvi.integrate(fracvi.Problem(**BASE, potential=FORMULA))
    python = fracvi.integrate(functions_problem())
    assert formula.status == python.status == "success"
    # Same equations, same Newton iterates; only the rounding of U's derivatives differs
    # (NumPy against the compiled formula): a few ulps, amplified by at most the run's condition.
    scale = np.max(np.abs(formula.x))
    assert np.max(np.abs(python.x - formula.x)) <= 1e-13 * scale
    assert np.max(np.abs(python.energy - formula.energy)) <= 1e-13 * np.max(np.abs(formula.energy))
    assert python.summary()["problem"]["model"]["potential"] == (
        "python:test_callables:U, test_callables:dU, test_callables:H")


def test_sparse_hessian_and_difference_hessian():
    formula = fracvi.integrate(fracvi.Problem(**BASE, potential=FORMULA))
    sparse = fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=dU, hessian=H_sparse))
    assert np.max(np.abs(sparse.x - formula.x)) <= 1e-13 * np.max(np.abs(formula.x))
    # Without a Hessian: central differences of dU in Newton's Jacobian only. The converged
    # iterates solve the same equations to Newton's tolerance (1e-12 relative by default).
    difference = fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=dU))
    assert difference.status == "success"
    assert np.max(np.abs(difference.x - formula.x)) <= 1e-9 * np.max(np.abs(formula.x))
    assert difference.summary()["newton_iterations"] <= 2 * formula.summary()["newton_iterations"]


def test_time_dependent_function_and_other_schemes():
    # U(x, t) with t: a spring stiffening in time, against the same formula, on every scheme that
    # applies to the problem (they all call U through the one Potential interface).
    def Ut(x, t):
        return (1 + 0.1 * t) * x[0]**2 / 2 + x[1]**2 / 2 + x[0]**4 / 4

    def dUt(x, t):
        return np.array([(1 + 0.1 * t) * x[0] + x[0]**3, x[1]])

    def Ht(x, t):
        return np.diag([1 + 0.1 * t + 3 * x[0]**2, 1.0])

    for scheme in ("fvi-gl", "fvi-midpoint", "fvi-bdf2", "fvi-lobatto3"):
        f = fracvi.integrate(fracvi.Problem(**BASE, potential="(1 + 0.1*t)*x1^2/2 + x2^2/2 + "
                                                              "x1^4/4"), scheme=scheme)
        p = fracvi.integrate(fracvi.Problem(**BASE, potential=Ut, gradient=dUt, hessian=Ht),
                             scheme=scheme)
        assert f.status == p.status == "success", scheme
        assert np.max(np.abs(p.x - f.x)) <= 1e-13 * np.max(np.abs(f.x)), scheme
        assert np.max(np.abs(p.dissipated - f.dissipated)) <= 1e-12, scheme


def test_bad_functions_are_refused_at_construction():
    with pytest.raises(fracvi.ProblemError, match=r"model.gradient = None .*required"):
        fracvi.Problem(**BASE, potential=U)
    with pytest.raises(fracvi.ProblemError, match=r"model.gradient = .* goes with a Python "
                                                  r"potential function"):
        fracvi.Problem(**BASE, potential=FORMULA, gradient=dU)
    with pytest.raises(fracvi.ProblemError, match=r"model.hessian = 3 is not a function"):
        fracvi.Problem(**BASE, potential=U, gradient=dU, hessian=3)
    with pytest.raises(fracvi.ProblemError,
                       match=r"t0 = 0.0\): model.gradient\(x, t\) returned shape \(3,\): it must "
                             r"return ∇U at \(x, t\), an array of shape \(d,\) = \(2,\)"):
        fracvi.Problem(**BASE, potential=U, gradient=lambda x, t: np.zeros(3))
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.hessian\(x, t\) returned shape \(2, 3\)"):
        fracvi.Problem(**BASE, potential=U, gradient=dU, hessian=lambda x, t: np.zeros((2, 3)))
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.potential\(x, t\) returned 'abc' \(str\): it must return a "
                             r"number"):
        fracvi.Problem(**BASE, potential=lambda x, t: "abc", gradient=dU)
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.gradient\(x, t\) returned None \(NoneType\)"):
        fracvi.Problem(**BASE, potential=U, gradient=lambda x, t: None)

    def broken(x, t):
        return {}["missing"]

    with pytest.raises(fracvi.ProblemError) as error:
        fracvi.Problem(**BASE, potential=broken, gradient=dU)
    text = str(error.value)
    assert "model.potential(x, t) raised an exception" in text
    assert "Traceback" in text and "in broken" in text and "KeyError: 'missing'" in text
    with pytest.raises(fracvi.ProblemError, match=r"model.chain are both given"):
        fracvi.Problem(dim=3, mass=1.0, alpha=0.5, chain=dict(quartic=1.0), potential=U,
                       gradient=dU,
                       position=[0.1, 0, 0], end=1.0, steps=10)


def test_an_exception_during_the_run_keeps_the_rows_and_the_traceback():
    def late(x, t):
        if t > 2.0:
            raise ValueError(f"no gradient beyond t = 2 (asked at t = {t:.3f})")
        return dU(x, t)

    solution = fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=late, hessian=H))
    assert solution.status == "callback-error"
    assert "model.gradient(x, t) raised an exception" in solution.message
    assert "in late" in solution.message and "ValueError: no gradient beyond t = 2" in \
        solution.message
    assert 1.9 < solution.t[-1] <= 2.0 + BASE["end"] / BASE["steps"]
    reference = fracvi.integrate(fracvi.Problem(**BASE, potential=FORMULA))
    kept = len(solution.t)
    assert np.max(np.abs(solution.x - reference.x[:kept])) <= 1e-13
    with pytest.raises(fracvi.IntegrationError) as error:
        fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=late),
                         raise_on_failure=True)
    assert error.value.solution.status == "callback-error"


def test_nan_from_a_function_is_a_non_finite_run():
    def nan_later(x, t):
        return dU(x, t) * (np.nan if t > 1.0 else 1.0)

    solution = fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=nan_later,
                                               hessian=H))
    assert solution.status == "non-finite"
    assert solution.t[-1] <= 1.0 + BASE["end"] / BASE["steps"]


def test_keyboard_interrupt_inside_a_function_is_an_interrupt():
    calls = {"n": 0}

    def interrupted(x, t):
        calls["n"] += 1
        if t > 1.0:
            raise KeyboardInterrupt
        return dU(x, t)

    with pytest.raises(KeyboardInterrupt) as error:
        fracvi.integrate(fracvi.Problem(**BASE, potential=U, gradient=interrupted, hessian=H))
    partial = error.value.solution
    assert partial.status == "interrupted"
    assert 0.9 < partial.t[-1] <= 1.0 + BASE["end"] / BASE["steps"]
    integrator = fracvi.Integrator(fracvi.Problem(**BASE, potential=U, gradient=interrupted,
                                                  hessian=H))
    with pytest.raises(KeyboardInterrupt) as error:
        integrator.run()
    assert error.value.solution.t[-1] <= 1.0 + BASE["end"] / BASE["steps"]
    stepper = fracvi.Integrator(fracvi.Problem(**BASE, potential=U, gradient=interrupted,
                                               hessian=H))
    with pytest.raises(KeyboardInterrupt):
        while stepper.step() == "running":
            pass


def test_overrides_keywords_and_pickle_keep_the_functions():
    p = functions_problem()
    assert p.potential is U and p.gradient is dU and p.hessian is H
    q = p.with_overrides("time.steps=200")
    assert q.potential is U and q.steps == 200
    assert fracvi.integrate(p, scheme="fvi-bdf2").status == "success"
    r = pickle.loads(pickle.dumps(p))
    assert r == p and r.potential is U
    s = fracvi.integrate(p)
    t = pickle.loads(pickle.dumps(s))
    assert np.array_equal(t.x, s.x)
    # A formula override replaces the functions.
    f = p.with_overrides(f"model.potential={FORMULA}")
    assert f.potential == FORMULA and f.gradient is None
    with pytest.raises((pickle.PicklingError, AttributeError)):
        pickle.dumps(fracvi.Problem(**BASE, potential=lambda x, t: U(x, t), gradient=dU))
    with pytest.raises(fracvi.ProblemError, match="sweep: .*Python functions"):
        fracvi.sweep(p, {"model.alpha": [0.5, 0.6]})


def test_write_and_load_import_the_functions_again(tmp_path):
    p = functions_problem()
    s = fracvi.integrate(p)
    out = tmp_path / "run"
    fracvi.write(s, p, out)
    text = (out / "problem.toml").read_text()
    assert "potential = 'python:test_callables:U, test_callables:dU, test_callables:H'" in text
    loaded = fracvi.load(out)
    assert loaded.problem.potential is U and np.array_equal(loaded.x, s.x)
    # What cannot be imported again must be given: the error says how.
    local = fracvi.Problem(**BASE, potential=lambda x, t: U(x, t), gradient=dU)
    fracvi.write(fracvi.integrate(local), local, tmp_path / "local")
    with pytest.raises(fracvi.ProblemError, match=r"cannot be imported here .*functions=dict"):
        fracvi.load(tmp_path / "local")
    again = fracvi.load(tmp_path / "local", functions=dict(potential=U, gradient=dU))
    assert again.problem.potential is U
    # The command line cannot call Python: it says so.
    cli = os.environ.get("FRACVI_CLI")
    if cli:
        r = subprocess.run([cli, "run", str(out / "problem.toml"), "--out",
                            str(tmp_path / "cli")], capture_output=True, text=True)
        assert r.returncode == 2
        assert 'model.potential = "python:test_callables:U' in r.stderr
        assert "names Python functions, which a problem file cannot call" in r.stderr
