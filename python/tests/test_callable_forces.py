"""The force g(x, v, t) as a Python function (issue 16 item 2): Problem(force=g,
force_jacobian=J). Runs must equal the runs of the same force given as formulas (whose orders
tests/integrate/state_force_test.cpp measures against independent references), every way a
function can go wrong must give the field and the rule (or, during a run, a failure status with
the traceback and the rows so far), and the problem must survive overrides, pickling, write/load."""
import os
import pickle
import subprocess

import numpy as np
import pytest
import scipy.sparse

import fracvi

# A coupled nonlinear pair with full M and R and fractional damping (2α = 1.2), and a force with
# van der Pol negative damping in v2, a state coupling and a time-dependent drive.
BASE = dict(name="callable-forces", dim=2, mass=[[2.0, 0.5], [0.5, 1.0]],
            damping=[[0.2, 0.05], [0.05, 0.1]], alpha=0.6, convention="caputo",
            potential="x1^4/4 + x2^2/2 - 0.2*x1*x2", position=[1.0, 0.0], velocity=[0.0, 0.5],
            end=5.0, steps=400, mirror="off")
FORMULAS = ["-0.3*x1*v2 + 0.1*sin(t)", "0.5*(1 - x1^2)*v2 - 0.2*x2*v1"]


def g(x, v, t):
    return np.array([-0.3 * x[0] * v[1] + 0.1 * np.sin(t),
                     0.5 * (1 - x[0]**2) * v[1] - 0.2 * x[1] * v[0]])


def J(x, v, t):
    dx = np.array([[-0.3 * v[1], 0.0], [-x[0] * v[1], -0.2 * v[0]]])
    dv = np.array([[0.0, -0.3 * x[0]], [-0.2 * x[1], 0.5 * (1 - x[0]**2)]])
    return dx, dv


def J_sparse(x, v, t):
    dx, dv = J(x, v, t)
    return scipy.sparse.csr_matrix(dx), scipy.sparse.csc_matrix(dv)


def U(x, t):
    return x[0]**4 / 4 + x[1]**2 / 2 - 0.2 * x[0] * x[1]


def dU(x, t):
    return np.array([x[0]**3 - 0.2 * x[1], x[1] - 0.2 * x[0]])


def relative(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("scheme", ["fvi-gl", "fvi-midpoint", "fvi-bdf2", "fvi-lobatto2",
                                    "fvi-lobatto3", "fvi-lobatto4"])
def test_a_function_force_gives_the_formula_run(scheme):
    formula = fracvi.integrate(fracvi.Problem(**BASE, force=FORMULAS), scheme=scheme)
    python = fracvi.integrate(fracvi.Problem(**BASE, force=g, force_jacobian=J), scheme=scheme)
    assert formula.status == python.status == "success", (scheme, python.message)
    # Same discrete Lagrange–d'Alembert equations, same Newton iterates: only the rounding of g
    # (NumPy against the compiled formula) differs, a few ulps.
    assert relative(python.x, formula.x) <= 1e-13, scheme
    # The energy account includes g's work, the same way.
    assert np.max(np.abs(python.dissipated - formula.dissipated)) <= 1e-12, scheme
    assert python.summary()["newton_iterations"] == formula.summary()["newton_iterations"]
    assert python.summary()["problem"]["model"]["force"] == [
        "python:test_callable_forces:g, test_callable_forces:J"]


def test_dopri5_sparse_and_difference_jacobians():
    viscous = dict(BASE, alpha=0.5)  # dopri5: 2α = 1 (or R = 0)
    formula = fracvi.integrate(fracvi.Problem(**viscous, force=FORMULAS), scheme="dopri5")
    python = fracvi.integrate(fracvi.Problem(**viscous, force=g), scheme="dopri5")
    assert formula.status == python.status == "success"
    assert relative(python.x, formula.x) <= 1e-12
    reference = fracvi.integrate(fracvi.Problem(**BASE, force=FORMULAS))
    sparse = fracvi.integrate(fracvi.Problem(**BASE, force=g, force_jacobian=J_sparse))
    assert relative(sparse.x, reference.x) <= 1e-13
    # Without force_jacobian: central differences of g (4d calls) in Newton's matrix only; the
    # converged iterates solve the same equations to Newton's tolerance.
    difference = fracvi.integrate(fracvi.Problem(**BASE, force=g))
    assert difference.status == "success"
    assert relative(difference.x, reference.x) <= 1e-9
    assert difference.summary()["newton_iterations"] <= 2 * reference.summary()["newton_iterations"]
    # A wrong Jacobian only slows Newton down (or stops it): never a different answer. Leaving
    # ∂g/∂v out is the negative control that the Jacobian is used at all.
    wrong = fracvi.integrate(fracvi.Problem(
        **BASE, force=g, force_jacobian=lambda x, v, t: (J(x, v, t)[0], np.zeros((2, 2)))))
    assert wrong.summary()["newton_iterations"] > reference.summary()["newton_iterations"]
    if wrong.status == "success":
        assert relative(wrong.x, reference.x) <= 1e-9


def test_potential_and_force_functions_together():
    formula = fracvi.integrate(fracvi.Problem(**BASE, force=FORMULAS))
    both = fracvi.Problem(**dict(BASE, potential=U), gradient=dU, force=g, force_jacobian=J)
    assert both.potential is U and both.force is g and both.force_jacobian is J
    solution = fracvi.integrate(both)
    assert solution.status == "success"
    assert relative(solution.x, formula.x) <= 1e-13
    # The run keeps the GIL and calls both; an observer-free Integrator steps the same way.
    integrator = fracvi.Integrator(both)
    integrator.run()
    assert np.array_equal(integrator.solution().x, solution.x)


def test_bad_force_functions_are_refused_at_construction():
    with pytest.raises(fracvi.ProblemError, match=r"model.force_jacobian = .* goes with a Python "
                                                  r"force function"):
        fracvi.Problem(**BASE, force=FORMULAS, force_jacobian=J)
    with pytest.raises(fracvi.ProblemError, match=r"model.force_jacobian = 3 is not a function"):
        fracvi.Problem(**BASE, force=g, force_jacobian=3)
    with pytest.raises(fracvi.ProblemError,
                       match=r"t0 = 0.0\): model.force\(x, v, t\) returned shape \(3,\): it must "
                             r"return g at \(x, v, t\), an array of shape \(d,\) = \(2,\)"):
        fracvi.Problem(**BASE, force=lambda x, v, t: np.zeros(3))
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.force\(x, v, t\) returned None \(NoneType\)"):
        fracvi.Problem(**BASE, force=lambda x, v, t: None)
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.force_jacobian\(x, v, t\) returned .*ndarray.*: it must "
                             r"return the pair \(∂g/∂x, ∂g/∂v\)"):
        fracvi.Problem(**BASE, force=g, force_jacobian=lambda x, v, t: np.zeros((2, 2)))
    with pytest.raises(fracvi.ProblemError,
                       match=r"model.force_jacobian\(x, v, t\) returned shape \(2, 3\): it must "
                             r"return ∂g/∂v at \(x, v, t\), its second entry"):
        fracvi.Problem(**BASE, force=g,
                       force_jacobian=lambda x, v, t: (np.zeros((2, 2)), np.zeros((2, 3))))
    with pytest.raises(fracvi.ProblemError,  # a force of the wrong signature
                       match=r"model.force\(x, v, t\) raised an exception:\nTypeError: .*takes 2 "
                             r"positional arguments but 3 were given"):
        fracvi.Problem(**BASE, force=lambda x, t: np.zeros(2))

    def broken(x, v, t):
        return {}["missing"]

    with pytest.raises(fracvi.ProblemError) as error:
        fracvi.Problem(**BASE, force=broken)
    text = str(error.value)
    assert "model.force(x, v, t) raised an exception" in text
    assert "Traceback" in text and "in broken" in text and "KeyError: 'missing'" in text
    with pytest.raises(fracvi.ProblemError, match=r"model.force: cannot be combined with "
                                                  r"model.lagrangian"):
        fracvi.Problem(dim=1, alpha=0.5, lagrangian="xdot1*ydot1 - x1*y1", force=g,
                       boundary=dict(start=[1.0], end=[0.5]), end=1.0, steps=10)


def test_schemes_without_forces_refuse_a_function_force():
    # Refused before step 1, with the message of a formula force in x or v.
    messages = []
    for force in (g, FORMULAS):
        with pytest.raises(fracvi.ProblemError) as error:
            fracvi.integrate(fracvi.Problem(**BASE, force=force), scheme="euler-explicit")
        messages.append(str(error.value))
    assert messages[0] == messages[1]
    assert 'method.scheme = "euler-explicit" does not take a force g(x, v, t)' in messages[0]


def test_failures_during_the_run_keep_the_rows():
    def late(x, v, t):
        if t > 2.0:
            raise ValueError(f"no force beyond t = 2 (asked at t = {t:.3f})")
        return g(x, v, t)

    solution = fracvi.integrate(fracvi.Problem(**BASE, force=late, force_jacobian=J))
    assert solution.status == "callback-error"
    assert "model.force(x, v, t) raised an exception" in solution.message
    assert "in late" in solution.message and "ValueError: no force beyond t = 2" in \
        solution.message
    assert 1.9 < solution.t[-1] <= 2.0 + BASE["end"] / BASE["steps"]
    reference = fracvi.integrate(fracvi.Problem(**BASE, force=FORMULAS))
    kept = len(solution.t)
    assert relative(solution.x, reference.x[:kept]) <= 1e-13

    def nan_later(x, v, t):
        return g(x, v, t) * (np.nan if t > 1.0 else 1.0)

    nan = fracvi.integrate(fracvi.Problem(**BASE, force=nan_later, force_jacobian=J))
    assert nan.status == "non-finite"
    assert nan.t[-1] <= 1.0 + BASE["end"] / BASE["steps"]

    def interrupted(x, v, t):
        if t > 1.0:
            raise KeyboardInterrupt
        return g(x, v, t)

    with pytest.raises(KeyboardInterrupt) as error:
        fracvi.integrate(fracvi.Problem(**BASE, force=interrupted, force_jacobian=J))
    partial = error.value.solution
    assert partial.status == "interrupted"
    assert 0.9 < partial.t[-1] <= 1.0 + BASE["end"] / BASE["steps"]


def test_overrides_pickle_write_and_load_keep_the_force(tmp_path):
    p = fracvi.Problem(**BASE, force=g, force_jacobian=J)
    q = p.with_overrides("time.steps=200")
    assert q.force is g and q.force_jacobian is J and q.steps == 200
    r = pickle.loads(pickle.dumps(p))
    assert r == p and r.force is g
    # A formula override replaces the functions.
    f = p.with_overrides(f'model.force=["{FORMULAS[0]}", "{FORMULAS[1]}"]')
    assert f.force == FORMULAS and f.force_jacobian is None
    s = fracvi.integrate(p)
    out = tmp_path / "run"
    fracvi.write(s, p, out)
    text = (out / "problem.toml").read_text()
    assert "force = [ 'python:test_callable_forces:g, test_callable_forces:J' ]" in text
    loaded = fracvi.load(out)
    assert loaded.problem.force is g and np.array_equal(loaded.x, s.x)
    local = fracvi.Problem(**BASE, force=lambda x, v, t: g(x, v, t))
    fracvi.write(fracvi.integrate(local), local, tmp_path / "local")
    with pytest.raises(fracvi.ProblemError, match=r"model.force = .*cannot be imported here "
                                                  r".*functions=dict\(force=F"):
        fracvi.load(tmp_path / "local")
    again = fracvi.load(tmp_path / "local", functions=dict(force=g))
    assert again.problem.force is g
    with pytest.raises(fracvi.ProblemError, match="sweep: .*the force is given as Python"):
        fracvi.sweep(p, {"model.alpha": [0.5, 0.6]})
    cli = os.environ.get("FRACVI_CLI")
    if cli:
        r = subprocess.run([cli, "run", str(out / "problem.toml"), "--out",
                            str(tmp_path / "cli")], capture_output=True, text=True)
        assert r.returncode == 2
        assert 'model.force = ["python:test_callable_forces:g' in r.stderr
        assert "names Python functions, which a problem file cannot call" in r.stderr
