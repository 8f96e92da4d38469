"""fracvi.Problem: every way of stating a problem gives the same validated problem, and every bad
input raises ValueError with exactly the message of `fracvi run`."""
import tomllib

import numpy as np
import pytest

import fracvi
from conftest import FRACTIONAL, PROBLEM

CLI_PREFIX = "fracvi run: "

# The bad inputs of tests/cli/cli_test.py plus a few more: (what, (old, new)) edits of PROBLEM.
BAD = [
    ("unknown key", ("damping =", "dampng =")),
    ("unknown section", ("[time]", "[timing]")),
    ("unknown top-level key", ('name = "cli-test"', 'nmae = "cli-test"')),
    ("wrong type", ("alpha = 0.5", 'alpha = "half"')),
    ("float steps", ("steps = 500", "steps = 500.0")),
    ("missing field", ("end = 5.0", "")),
    ("both steps", ("steps = 500", "steps = 500\nstep = 0.01")),
    ("neither", ("steps = 500", "")),
    ("dim mismatch", ("position = [1.0, 0.0]", "position = [1.0]")),
    ("M not SPD", ("mass = [[2.0, 0.5], [0.5, 1.0]]", "mass = [[1.0, 2.0], [2.0, 1.0]]")),
    ("M not symmetric", ("mass = [[2.0, 0.5], [0.5, 1.0]]", "mass = [[2.0, 0.5], [0.4, 1.0]]")),
    ("R not PSD", ("damping = [[0.2, 0.05], [0.05, 0.1]]", "damping = [[0.2, 0.5], [0.5, 0.1]]")),
    ("alpha", ("alpha = 0.5", "alpha = 1.2")),
    ("steps", ("steps = 500", "steps = -4")),
    ("end before start", ("end = 5.0", "end = -1.0")),
    ("expression", ("- 0.2*x1*x2", "- 0.2*x1*x3")),
    ("malformed expression", ("- 0.2*x1*x2", "- 0.2*x1*")),
    ("force expression", ('"0.1*sin(t)"', '"0.1*sin(x3)"')),
    ("force name", ('"0.1*sin(t)"', '"0.1*sin(w1)"')),
    ("force components", ('force = ["0.1*sin(t)", "0"]', 'force = ["0.1*sin(t)"]')),
    ("convention missing", ("alpha = 0.5", "alpha = 0.6")),
    ("convention unknown", ("alpha = 0.5", 'alpha = 0.6\nconvention = "caputto"')),
    ("ill-posed", ("alpha = 0.5", 'alpha = 0.8\nconvention = "riemann-liouville"')),
    ("scheme", ("[time]", '[method]\nscheme = "fvi-bdf9"\n[time]')),
    ("newton tolerance", ("[time]", "[method]\nnewton_tolerance = 0.0\n[time]")),
    ("newton iterations", ("[time]", "[method]\nnewton_max_iterations = 0\n[time]")),
    ("every", ("[time]", "[output]\nevery = 0\n[time]")),
]


# Files `fracvi run` rejects as a whole (not edits of PROBLEM). A boundary value problem without
# [initial] is a valid Problem (for solve_bvp); integrate() refuses it (test_bvp.py).
BAD_FILES = [
    ("Lagrangian not of mechanical form", """\
name = "coupled"
[model]
dim = 1
lagrangian = "xdot1*ydot1/2 - x1*y1/2"
alpha = 0.5
[initial]
position = [1.0]
[time]
end = 1.0
steps = 10
"""),
]


def cli_message(cli, *args):
    r = cli("run", *args, "--no-plot", "--quiet", "--out", "/nonexistent/never")
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(CLI_PREFIX), r.stderr
    return lines[0][len(CLI_PREFIX):]


def expected_dict():
    return tomllib.loads(PROBLEM)


# --- ways of stating the same problem --------------------------------------------------------

def test_all_forms_agree(write_file):
    path = write_file(PROBLEM)
    from_file = fracvi.Problem.from_toml(path)
    from_text = fracvi.Problem.from_toml(PROBLEM)
    from_dict = fracvi.Problem.from_dict(expected_dict())
    d = expected_dict()
    from_keywords = fracvi.Problem(name=d["name"], model=d["model"], initial=d["initial"],
                                   time=d["time"])
    flat = fracvi.Problem(name="cli-test", dim=2, mass=[[2.0, 0.5], [0.5, 1.0]],
                          damping=np.array([[0.2, 0.05], [0.05, 0.1]]), alpha=0.5,
                          potential="x1^4/4 + x2^2/2 - 0.2*x1*x2", force=("0.1*sin(t)", "0"),
                          position=np.array([1.0, 0.0]), velocity=[0.0, 0.5], end=5.0,
                          steps=np.int64(500))
    mixed = fracvi.Problem(name="cli-test", model=d["model"], position=[1.0, 0.0],
                           velocity=[0.0, 0.5], time=dict(end=5.0), steps=500)
    for p in (from_text, from_dict, from_keywords, flat, mixed):
        assert p == from_file
    assert from_file.source == path
    assert from_text.source == "<string>"
    assert from_dict.source == "<dict>"
    assert from_keywords.source == "<keywords>"


def test_fields_are_resolved():
    p = fracvi.Problem.from_toml(PROBLEM)
    assert (p.name, p.dim, p.alpha, p.damping_order, p.convention) == ("cli-test", 2, 0.5, 1.0,
                                                                       "caputo")
    np.testing.assert_array_equal(p.mass, [[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_array_equal(p.position, [1.0, 0.0])
    assert (p.start, p.end, p.steps, p.step) == (0.0, 5.0, 500, 0.01)
    assert (p.scheme, p.newton_tolerance, p.newton_max_iterations, p.every) == (
        "auto", 1e-12, 50, "auto")
    assert p.force == ["0.1*sin(t)", "0"]
    assert "cli-test" in repr(p)


def test_scalar_matrices_and_alternative_keys():
    d = expected_dict()
    d["model"].update(mass=2.0, damping=[0.2, 0.1], alpha=None)
    del d["model"]["alpha"]
    d["model"]["damping_order"] = 1.0
    del d["time"]["steps"]
    d["time"]["step"] = 0.01
    p = fracvi.Problem.from_dict(d)
    # A number or d numbers are stored sparse (a diagonal): scipy.sparse matrices.
    np.testing.assert_array_equal(p.mass.toarray(), 2.0 * np.eye(2))
    np.testing.assert_array_equal(p.damping.toarray(), np.diag([0.2, 0.1]))
    assert (p.alpha, p.steps) == (0.5, 500)


def test_round_trips():
    p = fracvi.Problem.from_toml(PROBLEM)
    assert fracvi.Problem.from_dict(p.to_dict()) == p
    assert fracvi.Problem.from_toml(p.to_toml()) == p
    q = fracvi.Problem.default()
    assert q.name == "fractional-duffing"
    assert fracvi.Problem.from_dict(q.to_dict()) == q


def test_overrides_like_the_cli_set_option(cli, tmp_path):
    p = fracvi.Problem.default(overrides=["time.end=6", "time.steps=600", "model.alpha=0.6"])
    assert (p.end, p.steps, p.alpha) == (6.0, 600, 0.6)
    assert p.with_overrides("model.potential=x1^2/2").potential == "x1^2/2"
    r = cli("run", "--set", "time.end=6", "--set", "time.steps=600", "--set", "model.alpha=0.6",
            "--out", tmp_path / "o", "--no-plot", "--quiet")
    assert r.returncode == 0, r.stderr
    assert fracvi.Problem.from_toml(tmp_path / "o" / "problem.toml") == p


# --- bad input: ValueError with the CLI's message --------------------------------------------

@pytest.mark.parametrize("what,edit", BAD, ids=[b[0] for b in BAD])
def test_bad_file_same_message_as_cli(cli, write_file, what, edit):
    old, new = edit
    assert old in PROBLEM
    text = PROBLEM.replace(old, new, 1)
    path = write_file(text)
    message = cli_message(cli, path)
    assert message.startswith(path + ": ")

    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.Problem.from_toml(path)
    assert str(e.value) == message
    assert isinstance(e.value, ValueError)

    # The same document as TOML text and as a dict (JSON path of the reader): same words.
    with pytest.raises(ValueError) as e:
        fracvi.Problem.from_toml(text, source=path)
    assert str(e.value) == message
    with pytest.raises(ValueError) as e:
        fracvi.Problem.from_dict(tomllib.loads(text), source=path)
    assert str(e.value) == message


@pytest.mark.parametrize("what,text", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_rejected_files_same_message_as_cli(cli, write_file, what, text):
    path = write_file(text)
    message = cli_message(cli, path)
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.Problem.from_toml(path)
    assert str(e.value) == message
    with pytest.raises(ValueError) as e:
        fracvi.Problem.from_dict(tomllib.loads(text), source=path)
    assert str(e.value) == message


def test_missing_file_and_bad_override(cli, tmp_path):
    missing = str(tmp_path / "nope.toml")
    with pytest.raises(ValueError) as e:
        fracvi.Problem.from_toml(missing)
    assert str(e.value) == cli_message(cli, missing)
    with pytest.raises(ValueError) as e:
        fracvi.Problem.default(overrides=["model.alpha=2"])
    assert str(e.value) == cli_message(cli, "--set", "model.alpha=2")
    assert "model.alpha = 2" in str(e.value)


def test_keyword_errors_name_the_key():
    good = dict(name="k", dim=1, mass=1.0, potential="x1^2/2", position=[1.0], end=1.0,
                steps=10, alpha=0.5)
    assert fracvi.Problem(**good).dim == 1
    cases = [
        (dict(alpah=0.5), ["alpah", "unknown"]),
        (dict(steps=10.0), ["time.steps", "integer"]),
        (dict(steps=True), ["time.steps"]),
        (dict(position=[float("nan")]), ["initial.position"]),
        (dict(position=[None]), ["initial.position"]),
        (dict(potential=None), ["model.potential", "null"]),
        (dict(potential=object()), ["model.potential", "object", "cannot be used"]),
        (dict(steps=2**70), ["time.steps", "64 bits"]),
        (dict(model=dict(alpha=0.5)), ["model.alpha", "twice"]),
        (dict(model=5), ["model"]),
    ]
    for change, needles in cases:
        kwargs = dict(good)
        if "alpah" in change:
            del kwargs["alpha"]
        kwargs.update(change)
        with pytest.raises(ValueError) as e:
            fracvi.Problem(**kwargs)
        message = str(e.value)
        assert message.startswith("<keywords>: "), message
        for needle in needles:
            assert needle in message, (change, message)
    with pytest.raises(ValueError, match="not a string"):
        fracvi.Problem.from_dict({"model": {1: 2}})
    with pytest.raises(ValueError, match="must be an object"):
        fracvi.Problem.from_dict([1, 2])


def test_integers_are_read_exactly_or_refused(cli, write_file):
    # Python ints become 64-bit integers of the problem (not floats): those a double holds exactly
    # are converted exactly (mass=2**60 used to be read as garbage), the others are refused with
    # the rule, exactly as the command line refuses them in a file.
    good = dict(name="k", dim=1, potential="x1^2/2", position=[1.0], end=1.0, steps=10, alpha=0.5)
    assert fracvi.Problem(mass=2**60, **good).mass == 2.0**60
    assert fracvi.Problem(mass=2**60, damping=10**17, **good).damping == 1e17
    for key, value in (("mass", 2**53 + 1), ("damping", -(2**53 + 1))):
        kwargs = dict(good, mass=1.0)
        kwargs[key] = value
        with pytest.raises(ValueError) as e:
            fracvi.Problem(**kwargs)
        message = str(e.value)
        assert message.startswith(f"<keywords>: model.{key} = {value}: integers beyond 2^53 are "
                                  "not exactly representable as a double; write it as a float"), \
            message
        path = write_file(FRACTIONAL.replace("mass = 1.0", f"mass = {value}") if key == "mass"
                          else FRACTIONAL.replace("damping = 0.3", f"damping = {value}"))
        from_file = cli_message(cli, path)
        assert from_file.split(": ", 1)[1] == message.split(": ", 1)[1], from_file


def test_unknown_keyword_same_message_as_cli(cli, write_file):
    text = PROBLEM.replace("alpha = 0.5", "alpah = 0.5")
    path = write_file(text)
    message = cli_message(cli, path)
    d = tomllib.loads(text)
    with pytest.raises(ValueError) as e:
        fracvi.Problem(source=path, **d)
    assert str(e.value) == message


# --- the one schema ----------------------------------------------------------------------------

def test_schema_rows_name_their_cpp_member():
    rows = fracvi.problem_schema()
    fields = [r for r in rows if r["type"] != "table"]
    assert {tuple(sorted(r)) for r in rows} == {
        ("binding", "default", "key", "section", "summary", "type")}
    by_key = {(r["section"], r["key"]): r["binding"] for r in fields}
    # The drift between file keys and C++ names, written down (docs/problem-file.md).
    assert by_key[("initial", "position")] == "InitialValueProblem::x0"
    assert by_key[("initial", "velocity")] == "InitialValueProblem::v0"
    assert by_key[("output", "every")] == "IntegratorOptions::save_every"
    assert by_key[("method", "newton_tolerance")] == "NewtonOptions::relative_tolerance"
    for r in fields:
        assert "::" in r["binding"], r


def test_keywords_are_the_file_keys(tmp_path):
    # Every [method]/[output] key is a keyword of integrate() (and but for the error estimate's of
    # solve_bvp()) under its file name (not its C++ name), and lands in that field of the problem.
    # checkpoint_every is `fracvi run`'s (test_integrate.py: integrate() refuses it).
    rows = [r for r in fracvi.problem_schema()
            if r["section"] in ("method", "output") and r["key"] != "checkpoint_every"]
    values = dict(scheme="fvi-bdf2", newton_tolerance=1e-11, newton_max_iterations=40,
                  history="direct", history_tolerance=1e-9, abs_tolerance=1e-7,
                  rel_tolerance=1e-6, linear_solver="dense", load="pointwise",
                  split="taylor", error_estimate="richardson", tolerance=10.0, max_steps=123456, threads=1,
                  flush_subnormals=False, every=2, mirror="off", times=[0.5, 1.5], format="npz")
    assert {r["key"] for r in rows} == set(values)
    problem = fracvi.Problem.from_toml(PROBLEM)
    fields = {k: v for k, v in values.items() if k != "history"}  # a run option of integrate()
    solution = fracvi.integrate(problem, **fields)
    resolved = solution.summary()["problem"]
    for r in rows:
        if r["key"] in fields:
            assert resolved[r["section"]][r["key"]] == values[r["key"]], r["key"]
    for cpp_name in ("save_every", "relative_tolerance", "max_iterations", "x0"):
        with pytest.raises(TypeError, match=f"unexpected keyword argument '{cpp_name}'"):
            fracvi.integrate(problem, **{cpp_name: 1})
    # Flat keys of Problem() are file keys too: position/velocity, not x0/v0.
    with pytest.raises(fracvi.ProblemError, match="x0: unknown key"):
        fracvi.Problem(dim=1, mass=1.0, alpha=0.5, potential="x1^2/2", x0=[1.0], end=1.0,
                       steps=10)
