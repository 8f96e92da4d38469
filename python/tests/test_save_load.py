"""fracvi.load reads back what `fracvi run` and fracvi.write (CSV or npz) wrote, bit for bit;
Problem and Solution pickle (multiprocessing); scipy.sparse mass and damping go in; overrides are
strings or lists of strings, never taken apart."""
import json
import multiprocessing
import os
import pickle
import shutil

import numpy as np
import pytest

import fracvi
from conftest import BLOWUP, FRACTIONAL, PROBLEM

ARRAYS = ("t", "step", "x", "v", "energy", "dissipated", "balance")
FIELDS = ("status", "message", "steps", "newton_iterations", "max_newton_iterations_per_step",
          "jacobian_factorizations",
          "mirror_error", "max_balance_error", "error_estimate", "wall_time", "setup_time",
          "method", "linear_solver", "save_every", "declared_order")
TIMINGS = ("wall_time", "setup_time")


def assert_same_solution(a, b, *, timings=True, problem=None):
    """a equals b bit for bit; a's problem is `problem` (default b's)."""
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert np.array_equal(x, y, equal_nan=True), name  # bit for bit (NaN where both are)
    for name in FIELDS:
        if name in TIMINGS and not timings:
            continue
        x, y = getattr(a, name), getattr(b, name)
        assert x == y or (x != x and y != y), (name, x, y)
    problem = b.problem if problem is None else problem
    assert a.problem == problem
    sa, sb = a.summary(), b.summary()
    assert sa.pop("problem") == problem.to_dict()
    sb.pop("problem")
    if not timings:
        for s in (sa, sb):
            for key in ("wall_seconds", "setup_wall_seconds", "stepping_wall_seconds"):
                s.pop(key)
            s["error_estimate_details"].pop("wall_seconds")
            # How the estimate was timed: alongside the run (fracvi run) or after it (the module).
            s["error_estimate_details"].pop("concurrent")
    assert sa == sb


def solutions():
    """Runs whose files differ: full rows, every = 7 (step indices not in the CSV), a Newton
    failure, diagnostics off (NaN columns), a run stopped half-way (status "running")."""
    integ = fracvi.Integrator(FRACTIONAL, every=7, error_estimate="none")
    integ.run(steps=123)
    return {
        "nonlinear-2d": fracvi.integrate(PROBLEM),
        "every-7": fracvi.integrate(FRACTIONAL, every=7),
        "newton-failure": fracvi.integrate(BLOWUP),
        "no-diagnostics": fracvi.integrate(FRACTIONAL, diagnostics=False, error_estimate="none"),
        "stopped": integ.solution(),
    }


@pytest.fixture(scope="module")
def runs():
    return solutions()


@pytest.mark.parametrize("format", ["csv", "npz"])
@pytest.mark.parametrize("name", ["nonlinear-2d", "every-7", "newton-failure", "no-diagnostics",
                                  "stopped"])
def test_write_then_load_is_the_same_solution(runs, tmp_path, name, format):
    solution = runs[name]
    directory = solution.write(tmp_path / "run", format=format)
    files = sorted(f for f in os.listdir(directory) if not f.startswith("."))
    assert files == ["problem.toml", "summary.json", f"trajectory.{format}"]
    loaded = fracvi.load(directory)
    assert_same_solution(loaded, solution)  # the format given to write() is not the problem's
    assert loaded.status == solution.status and loaded.steps == solution.steps
    if name == "every-7":
        assert loaded.step[-1] == 400 and list(loaded.step[:3]) == [0, 7, 14]
    if name == "stopped":
        assert list(loaded.step[-2:]) == [119, 123]
    # What was loaded writes the same files again.
    again = fracvi.write(loaded, tmp_path / "again", format=format)
    for f in ("problem.toml", "summary.json"):
        with open(os.path.join(directory, f)) as a, open(os.path.join(again, f)) as b:
            assert a.read() == b.read(), f


def test_load_reads_what_the_cli_wrote(cli, write_file, tmp_path):
    path = write_file(FRACTIONAL + "[output]\nevery = 9\n")
    r = cli("run", path, "--out", tmp_path / "cli", "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    loaded = fracvi.load(tmp_path / "cli")
    in_process = fracvi.integrate(path)
    assert loaded.problem == in_process.problem
    assert_same_solution(loaded, in_process, timings=False)
    with open(tmp_path / "cli" / "summary.json") as f:
        assert loaded.summary()["wall_seconds"] == json.load(f)["wall_seconds"]


def test_formats_replace_each_other(runs, tmp_path):
    solution = runs["every-7"]
    fracvi.write(solution, tmp_path, format="npz")
    fracvi.write(solution, tmp_path)
    assert not (tmp_path / "trajectory.npz").exists() and (tmp_path / "trajectory.csv").exists()
    fracvi.write(solution, tmp_path, format="npz")
    assert (tmp_path / "trajectory.npz").exists() and not (tmp_path / "trajectory.csv").exists()
    with np.load(tmp_path / "trajectory.npz") as f:
        assert sorted(f.files) == sorted(ARRAYS)
        np.testing.assert_array_equal(f["x"], solution.x)
    with pytest.raises(ValueError, match="write: format = 'hdf5' must be one of 'csv', 'npz'"):
        fracvi.write(solution, tmp_path, format="hdf5")
    # The plots read either format.
    pytest.importorskip("matplotlib")
    paths = fracvi.plot(str(tmp_path), tmp_path / "png")
    assert [os.path.basename(p) for p in paths] == ["trajectory.png", "phase.png", "energy.png"]


def test_the_cli_writes_npz_that_numpy_reads(cli, write_file, tmp_path):
    # output.format = "npz": the C++ writer (libzip, hand-written .npy headers) against NumPy's
    # reader, and against the CSV of the same run, bit for bit.
    for text, out in (("", "csv"), ('format = "npz"\n', "npz")):
        path = write_file(FRACTIONAL + "[output]\nevery = 9\n" + text)
        r = cli("run", path, "--out", tmp_path / out, "--no-plot", "--quiet")
        assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(tmp_path / "npz")) == ["problem.toml", "summary.json",
                                                     "trajectory.npz"]
    table = np.loadtxt(tmp_path / "csv" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    with np.load(tmp_path / "npz" / "trajectory.npz") as f:
        assert sorted(f.files) == sorted(ARRAYS)
        d = f["x"].shape[1]
        assert f["step"].dtype == np.int64 and f["t"].dtype == np.float64
        assert f["x"].flags.c_contiguous and f["x"].shape == (len(table), d)
        for name, column in (("t", table[:, 0]), ("x", table[:, 1:1 + d]),
                             ("v", table[:, 1 + d:1 + 2 * d]), ("energy", table[:, -3]),
                             ("dissipated", table[:, -2]), ("balance", table[:, -1])):
            assert np.array_equal(f[name], column, equal_nan=True), name
        assert list(f["step"][:3]) == [0, 9, 18]
    # Each member is stored uncompressed with its data 64-byte aligned, as np.savez writes.
    import zipfile
    with zipfile.ZipFile(tmp_path / "npz" / "trajectory.npz") as z:
        for info in z.infolist():
            assert info.compress_type == zipfile.ZIP_STORED
            with z.open(info) as member:
                assert np.lib.format.read_magic(member) == (1, 0)
                np.lib.format.read_array_header_1_0(member)
                assert member.tell() % 64 == 0, info.filename
    loaded = fracvi.load(tmp_path / "npz")
    assert_same_solution(loaded, fracvi.load(tmp_path / "csv"), timings=False,
                         problem=loaded.problem)
    assert loaded.problem.format == "npz"
    r = cli("plot", tmp_path / "npz")
    assert r.returncode == 0, r.stderr
    bad = write_file(FRACTIONAL + "[output]\nformat = \"hdf5\"\n")
    r = cli("run", bad, "--out", tmp_path / "bad", "--no-plot", "--quiet")
    assert r.returncode == 2
    assert 'output.format = "hdf5" is not one of' in r.stderr


def test_cli_plots_an_npz_directory(runs, cli, tmp_path):
    pytest.importorskip("matplotlib")
    fracvi.write(runs["every-7"], tmp_path, format="npz")
    r = cli("plot", tmp_path)
    assert r.returncode == 0, r.stderr
    assert all((tmp_path / f).exists() for f in ("trajectory.png", "phase.png", "energy.png"))


def test_load_without_problem_toml_takes_the_summary_problem(runs, tmp_path):
    solution = runs["nonlinear-2d"]
    fracvi.write(solution, tmp_path)
    os.remove(tmp_path / "problem.toml")
    assert_same_solution(fracvi.load(tmp_path), solution)


def test_load_a_sweep_case(tmp_path):
    problem = fracvi.Problem(dim=1, mass=1.0, damping=0.5, alpha=0.5, potential="x1^2/2",
                             position=[1.0], end=2.0, steps=50)
    fracvi.sweep(problem, {"model.damping": [0.1, 0.2]}, out=tmp_path, save="trajectory")
    case = fracvi.load(tmp_path / "cases" / "1")
    assert case.problem.damping.toarray()[0, 0] == 0.2
    assert_same_solution(case, fracvi.integrate(case.problem), timings=False)
    with pytest.raises(FileNotFoundError, match="sweep's directory; fracvi.load_sweep reads"):
        fracvi.load(tmp_path)


def test_load_names_what_is_wrong(runs, tmp_path):
    with pytest.raises(FileNotFoundError, match="is not a directory"):
        fracvi.load(tmp_path / "nothing")
    with pytest.raises(FileNotFoundError, match="summary.json does not exist: a run directory "
                                                "holds a complete run once summary.json"):
        fracvi.load(tmp_path)
    good = tmp_path / "good"
    fracvi.write(runs["every-7"], good)

    def broken(name):
        target = tmp_path / name
        shutil.copytree(good, target)
        return target

    # A trajectory with a row too few (written by something else, or cut short).
    short = broken("short")
    lines = (short / "trajectory.csv").read_text().splitlines(keepends=True)
    (short / "trajectory.csv").write_text("".join(lines[:-1]))
    with pytest.raises(ValueError, match=r"trajectory.csv: t has shape \(58,\); the summary's "
                                         r"steps = 400 with save_every = 7 make 59 stored rows"):
        fracvi.load(short)
    # A summary field of the wrong type.
    bad = broken("bad-summary")
    summary = json.loads((bad / "summary.json").read_text())
    summary["newton_iterations"] = "many"
    (bad / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ValueError, match='"newton_iterations" = "many" is not a count'):
        fracvi.load(bad)
    del summary["newton_iterations"]
    (bad / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ValueError, match='"newton_iterations" is missing'):
        fracvi.load(bad)
    summary["newton_iterations"], summary["status"] = 3, "finished"
    (bad / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ValueError, match='"status" = "finished" is not a status of a run'):
        fracvi.load(bad)
    # A problem of another dimension.
    other = broken("other-dim")
    (other / "problem.toml").write_text(fracvi.Problem.from_toml(PROBLEM).to_toml())
    with pytest.raises(ValueError, match=r"x has shape \(59, 1\); .* 59 stored rows of the "
                                         r"problem's dim = 2 values"):
        fracvi.load(other)
    # An npz without the velocities.
    npz = tmp_path / "npz"
    fracvi.write(runs["every-7"], npz, format="npz")
    with np.load(npz / "trajectory.npz") as f:
        arrays = {k: f[k] for k in f.files if k != "v"}
    np.savez(npz / "trajectory.npz", **arrays)
    with pytest.raises(ValueError, match=r"trajectory.npz: lacks the array\(s\) v"):
        fracvi.load(npz)


def test_load_refuses_a_boundary_value_solution(tmp_path):
    problem = fracvi.Problem(dim=1, mass=1.0, damping=0.2, alpha=0.5, potential="x1^2/2",
                             boundary=dict(start=[1.0], end=[0.0]), end=1.0, steps=20)
    fracvi.solve_bvp(problem).write(tmp_path)
    with pytest.raises(ValueError, match="boundary value solution .* fracvi.load reads initial "
                                         "value runs"):
        fracvi.load(tmp_path)


def test_pickled_problem_integrates_to_the_same_trajectory():
    problem = fracvi.Problem.from_toml(PROBLEM, overrides=["time.steps=200"])
    copy = pickle.loads(pickle.dumps(problem))
    assert copy == problem and copy.source == problem.source and copy is not problem
    assert_same_solution(fracvi.integrate(copy), fracvi.integrate(problem), timings=False)


def test_pickled_solution_is_the_same(runs):
    for solution in runs.values():
        copy = pickle.loads(pickle.dumps(solution))
        assert_same_solution(copy, solution)
        assert copy.x.flags.c_contiguous and not copy.x.flags.writeable  # like any Solution


@pytest.mark.parametrize("method", ["spawn", "fork"])
def test_pool_map_integrate(method):
    problems = [fracvi.Problem.from_toml(FRACTIONAL, overrides=[f"model.damping={r}"])
                for r in (0.1, 0.3, 0.5)]
    with multiprocessing.get_context(method).Pool(2) as pool:
        results = pool.map(fracvi.integrate, problems)
    for problem, result in zip(problems, results):
        assert isinstance(result, fracvi.Solution) and result.problem == problem
        assert_same_solution(result, fracvi.integrate(problem), timings=False)


def test_boundary_value_solutions_pickle():
    problems = [fracvi.Problem(dim=1, mass=1.0, damping=r, alpha=0.5, potential="x1^2/2",
                               boundary=dict(start=[1.0], end=[0.0]), end=1.0, steps=20)
                for r in (0.2, 0.4)]
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        results = pool.map(fracvi.solve_bvp, problems)
    for problem, result in zip(problems, results):
        direct = fracvi.solve_bvp(problem)
        assert result.problem == problem and result.status == direct.status == "success"
        for name in ("t", "x", "y", "x_residual", "y_residual"):
            np.testing.assert_array_equal(getattr(result, name), getattr(direct, name))
        for name in ("message", "residual_norm", "residual_floor", "residual_tolerance",
                     "residual_history", "newton_iterations", "linear_iterations",
                     "linear_solver", "sum"):
            assert getattr(result, name) == getattr(direct, name), name
        copy = pickle.loads(pickle.dumps(direct))
        assert copy.wall_time == direct.wall_time and copy.summary() == direct.summary()


def test_sparse_mass_and_damping_go_in():
    sparse = pytest.importorskip("scipy.sparse")
    base = dict(alpha=0.5, potential="x1^2/2 + x2^2/2 + x3^4/4", position=[1.0, 0.0, 0.5],
                end=2.0, steps=100)
    listed = fracvi.Problem(dim=3, mass=[1.0, 2.0, 3.0], damping=0.1, **base)
    # Problem.mass returns scipy.sparse for a diagonal: it goes back in as it came out.
    again = fracvi.Problem(dim=3, mass=listed.mass, damping=listed.damping, **base)
    assert again == listed
    assert sparse.issparse(again.mass) and again.to_dict()["model"]["mass"] == [1.0, 2.0, 3.0]
    for matrix in (sparse.diags([1.0, 2.0, 3.0]).tocsr(), sparse.coo_matrix(np.diag([1., 2, 3])),
                   sparse.csr_array(np.diag([1.0, 2.0, 3.0]))):
        assert fracvi.Problem(dim=3, mass=matrix, damping=0.1, **base) == listed
    assert_same_solution(fracvi.integrate(again), fracvi.integrate(listed), timings=False)
    # Not a diagonal: stored dense (the problem files have no other sparse form).
    full = np.array([[2.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]])
    dense = fracvi.Problem(dim=3, mass=sparse.csr_matrix(full), damping=0.1, **base)
    assert isinstance(dense.mass, np.ndarray) and np.array_equal(dense.mass, full)
    assert dense == fracvi.Problem(dim=3, mass=full.tolist(), damping=0.1, **base)
    # A large non-diagonal one is refused before it is expanded (d = 20000: 3 GiB dense).
    tridiagonal = sparse.diags([np.ones(19999), 2 * np.ones(20000), np.ones(19999)], [-1, 0, 1])
    with pytest.raises(fracvi.ProblemError, match=r"shape \(20000, 20000\) with off-diagonal "
                                                  r"entries is stored dense \(2.98 GiB\)"):
        fracvi.Problem(dim=20000, mass=tridiagonal, **base)
    # Bad matrices get the reader's messages, naming the field.
    with pytest.raises(fracvi.ProblemError, match="model.mass: has 2 entries, model.dim is 3"):
        fracvi.Problem(dim=3, mass=sparse.identity(2), **base)
    with pytest.raises(fracvi.ProblemError, match="model.mass: is not symmetric"):
        fracvi.Problem(dim=3, mass=sparse.csr_matrix(np.triu(full)), **base)


def test_overrides_are_strings_or_lists_of_strings():
    problem = fracvi.Problem.from_toml(FRACTIONAL)
    one = problem.with_overrides("model.alpha=0.6")
    assert one.alpha == 0.6
    assert problem.with_overrides(["model.alpha=0.6"]) == one
    assert problem.with_overrides(("model.alpha=0.6", "time.steps=10")).steps == 10
    assert problem.with_overrides("model.alpha=0.6", "time.steps=10").steps == 10
    assert fracvi.Problem.default(overrides="model.alpha=0.6").alpha == 0.6
    assert fracvi.Problem.default(overrides=["model.alpha=0.6"]).alpha == 0.6
    assert fracvi.Problem.from_toml(FRACTIONAL, overrides="model.alpha=0.6") == one
    assert fracvi.Problem.from_dict(problem.to_dict(), overrides="model.alpha=0.6") == one
    rule = r'each is "section.key=value", as for `fracvi run --set`'
    for call in (lambda o: problem.with_overrides(o), lambda o: fracvi.Problem.default(overrides=o)):
        with pytest.raises(TypeError, match=r"overrides = 0.6 is not a string or a list of "
                                            r"strings \(" + rule):
            call(0.6)
        with pytest.raises(TypeError, match=r"overrides\[1\] = 3 is not a string"):
            call(["model.alpha=0.6", 3])
        with pytest.raises(TypeError, match=r"overrides = \{'model.alpha': 0.6\} is not"):
            call({"model.alpha": 0.6})
    # A malformed assignment is the reader's message, for the whole string.
    with pytest.raises(fracvi.ProblemError, match="alpha"):
        problem.with_overrides("alpha")
