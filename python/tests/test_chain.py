"""Large systems from Python: sparse mass and damping (scipy.sparse), the built-in FPUT chain,
initial data as formulas, [method] linear_solver and threads, and the storage stride
output.every (Solution.step, save_every, linear_solver)."""
import importlib
import os
import tomllib

import numpy as np
import pytest

import fracvi
from conftest import PROBLEM, read_summary

sparse = pytest.importorskip("scipy.sparse")

CHAIN = """\
name = "chain"
[model]
dim = 12
mass = 1.0
damping = 0.1
alpha = 0.5
[model.chain]
quartic = 1.0
[initial]
position = "0.5*sin(pi*i/(d+1))"
[time]
end = 2.0
steps = 20
[output]
every = 3
"""


def test_matrices_keep_their_storage():
    p = fracvi.Problem.from_toml(PROBLEM)  # d rows: dense
    assert isinstance(p.mass, np.ndarray) and isinstance(p.damping, np.ndarray)
    np.testing.assert_array_equal(p.mass, [[2.0, 0.5], [0.5, 1.0]])

    q = fracvi.Problem.from_toml(CHAIN, overrides=["model.damping=[0.1, 0.2, 0.3, 0.4, 0.5, "
                                                   "0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2]"])
    assert sparse.issparse(q.mass) and q.mass.format == "csc"
    assert q.mass.shape == (12, 12) and q.mass.nnz == 12
    np.testing.assert_array_equal(q.mass.toarray(), np.eye(12))
    np.testing.assert_allclose(q.damping.diagonal(), 0.1 * np.arange(1, 13))
    # Written back compactly.
    d = q.to_dict()
    assert d["model"]["mass"] == 1.0
    assert len(d["model"]["damping"]) == 12


def test_a_chain_of_100000_masses_is_never_dense():
    p = fracvi.Problem(name="long", dim=100000, mass=1.0, damping=0.05, alpha=0.5,
                       chain=dict(quartic=1.0), position="exp(-((i - d/2)/10)^2)", end=0.5,
                       steps=4, every=2, threads=1, scheme="fvi-gl")
    assert p.mass.nnz == 100000 and p.damping.nnz == 100000
    assert len(p.to_toml()) < 2000
    sol = fracvi.integrate(p)
    assert sol.ok, sol.message
    assert sol.linear_solver == "banded"
    assert sol.save_every == 2
    assert sol.step.tolist() == [0, 2, 4]
    assert sol.x.shape == (3, 100000)
    np.testing.assert_array_equal(sol.t, [0.0, 0.25, 0.5])


def test_chain_fields_and_defaults():
    p = fracvi.Problem.from_toml(CHAIN)
    assert p.chain == dict(stiffness=1.0, cubic=0.0, quartic=1.0, onsite=0.0, boundary="fixed")
    assert fracvi.Problem.from_toml(PROBLEM).chain is None
    # The same problem from keywords: flat chain=..., or nested in model=...
    d = tomllib.loads(CHAIN)
    assert fracvi.Problem.from_dict(d) == p
    flat = fracvi.Problem(name="chain", dim=12, mass=1.0, damping=0.1, alpha=0.5,
                          chain=dict(quartic=1.0), position="0.5*sin(pi*i/(d+1))", end=2.0,
                          steps=20, every=3)
    assert flat == p
    nested = fracvi.Problem(name="chain", model=d["model"], initial=d["initial"], time=d["time"],
                            output=d["output"])
    assert nested == p
    assert fracvi.Problem.from_dict(p.to_dict()) == p
    assert fracvi.Problem.from_toml(p.to_toml()) == p
    q = p.with_overrides("model.chain.boundary=periodic", "model.chain.cubic=0.5")
    assert q.chain["boundary"] == "periodic" and q.chain["cubic"] == 0.5


def test_initial_formulas():
    p = fracvi.Problem.from_toml(CHAIN, overrides=["initial.velocity=-0.25"])
    i = np.arange(1, 13)
    np.testing.assert_allclose(p.position, 0.5 * np.sin(np.pi * i / 13), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(p.velocity, np.full(12, -0.25))
    assert p.to_dict()["initial"] == {"position": "0.5*sin(pi*i/(d+1))", "velocity": -0.25}


def test_method_keys():
    p = fracvi.Problem.from_toml(CHAIN)
    assert (p.linear_solver, p.threads, p.history) == ("auto", 0, "auto")
    q = fracvi.Problem.from_toml(CHAIN, overrides=["method.linear_solver=sparse",
                                                   "method.threads=1"])
    assert (q.linear_solver, q.threads) == ("sparse", 1)
    assert fracvi.integrate(q).linear_solver == "sparse"
    sol = fracvi.integrate(p, linear_solver="dense", threads=1)
    assert sol.linear_solver == "dense"
    assert sol.summary()["problem"]["method"]["linear_solver"] == "dense"
    assert sol.summary()["problem"]["method"]["threads"] == 1
    with pytest.raises(fracvi.ProblemError, match="did you mean 'banded'"):
        fracvi.integrate(p, linear_solver="bandd")
    with pytest.raises(fracvi.ProblemError, match=r"method.threads = -1 must be in \[0, 4096\]"):
        fracvi.Problem.from_toml(CHAIN, overrides=["method.threads=-1"])


BAD = [
    ("unknown chain key", ("quartic = 1.0", "quartc = 1.0"), "model.chain.quartc"),
    ("boundary", ("quartic = 1.0", 'boundary = "circular"'),
     'model.chain.boundary = "circular" is not one of fixed, free, periodic'),
    ("both", ("alpha = 0.5", 'alpha = 0.5\npotential = "x1^2"'), "model.potential and model.chain"),
    ("too short", ("dim = 12", "dim = 2"), "model.dim = 2 is too small"),
    ("formula", ('"0.5*sin(pi*i/(d+1))"', '"0.5*sin(pi*k)"'),
     "unknown variable 'k' (known: i, d) at column 12"),
    ("linear solver", ("[output]", '[method]\nlinear_solver = "lu"\n[output]'),
     "method.linear_solver"),
    ("threads", ("[output]", "[method]\nthreads = 2.5\n[output]"), "method.threads"),
]


@pytest.mark.parametrize("what,edit,needle", BAD, ids=[b[0] for b in BAD])
def test_bad_chain_input_same_message_as_cli(cli, write_file, what, edit, needle):
    old, new = edit
    text = (CHAIN if what != "too short" else CHAIN.replace("quartic = 1.0",
                                                            'boundary = "periodic"')).replace(
        old, new, 1)
    path = write_file(text)
    r = cli("run", path, "--no-plot", "--quiet", "--out", "/nonexistent/never")
    assert r.returncode == 2, r.stdout + r.stderr
    message = r.stderr.strip()[len("fracvi run: "):]
    assert needle in message
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.Problem.from_toml(path)
    assert str(e.value) == message
    with pytest.raises(ValueError) as e:
        fracvi.Problem.from_dict(tomllib.loads(text), source=path)
    assert str(e.value) == message


def test_stored_rows_are_what_the_cli_writes(cli, write_file, tmp_path):
    path = write_file(CHAIN)
    r = cli("run", path, "--out", tmp_path / "cli", "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    sol = fracvi.integrate(fracvi.Problem.from_toml(path))
    assert sol.step.tolist() == [0, 3, 6, 9, 12, 15, 18, 20]
    assert sol.step.dtype == np.int64
    table = np.loadtxt(tmp_path / "cli" / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[:, 0], sol.t)  # every stored row, nothing thinned twice
    np.testing.assert_array_equal(table[:, 1:13], sol.x)
    summary = read_summary(tmp_path / "cli")
    assert summary["save_every"] == 3 == sol.save_every
    assert summary["linear_solver"] == sol.linear_solver
    assert summary["final_position"] == sol.x[-1].tolist()
    fracvi.write(sol, tmp_path / "py")
    with open(tmp_path / "py" / "trajectory.csv", encoding="utf-8") as f:
        assert len(f.readlines()) == 1 + 8


def test_plots_of_a_long_chain(tmp_path):
    p = fracvi.Problem.from_toml(CHAIN, overrides=["model.dim=3000", "time.steps=40",
                                                   "output.every=4", "method.threads=1",
                                                   'initial.position="exp(-((i-d/2)/8)^2)"'])
    sol = fracvi.integrate(p)
    paths = fracvi.plot(sol, tmp_path)
    assert [os.path.basename(q) for q in paths] == ["trajectory.png", "phase.png", "energy.png",
                                                     "spacetime.png"]
    for q in paths:
        assert os.path.getsize(q) > 10000
    # The module (the attribute fracvi.plot is the function).
    plotting = importlib.import_module("fracvi.plot")
    image, (first, last, block), times = plotting.spacetime_image(sol.t, sol.x)
    assert image.shape[0] == len(times) == 11
    assert 1 < first < 1500 < last < 3000  # cropped to the sites that moved
    assert block == 1
