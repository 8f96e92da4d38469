"""fracvi.solve_bvp: the variational boundary value problem of `fracvi bvp` from Python. The
numbers are the CLI's to the last bit (its trajectory.csv has 17 significant digits), the scheme of
[method] reaches it, and bad input raises ProblemError with the CLI's message."""
import csv
import json
import os

import numpy as np
import pytest

import fracvi

# A non-mechanical Lagrangian coupling x and y (tests/lagrangian/data/coupled_bvp.toml, shorter):
# only a boundary value problem can pose it.
COUPLED = """\
name = "coupled-bvp"
[model]
dim = 2
alpha = 0.6
lagrangian = \"\"\"0.5*(1 + 0.3*x1^2)*(xdot1^2 + xdot2^2) + 0.5*(ydot1^2 + ydot2^2) \\
  - (1 - cos(x1) + 0.5*x2^2 + 1 - cos(y1) + 0.5*y2^2 + 0.1*sin(t)*x2*y1) \\
  - (0.4*dx1*dy1 + 0.1*dx1*dy2 + 0.1*dx2*dy1 + 0.3*dx2*dy2) + 0.2*x1*ydot2\"\"\"
[boundary]
start = [0.3, -0.2]
end = [-0.4, 0.5]
[time]
end = 1.5
steps = 40
"""

# The mechanical model with fractional damping (Riemann–Liouville, as the Lagrangian needs).
MECHANICAL = """\
name = "mechanical-bvp"
[model]
dim = 1
mass = 1.0
damping = 0.3
alpha = 0.75
convention = "riemann-liouville"
potential = "x1^2/2 + x1^4/8"
[boundary]
start = [1.0]
end = [0.0]
[time]
end = 2.0
steps = 50
"""

BVP_PREFIX = "fracvi bvp: "


def read_csv(path):
    with open(path, encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(v) for v in row] for row in rows[1:]])


def run_cli(cli, path, out, *args, returncode=0):
    r = cli("bvp", path, "--out", out, "--quiet", *args)
    assert r.returncode == returncode, r.stderr
    header, data = read_csv(os.path.join(out, "trajectory.csv"))
    with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    return header, data, summary


def cli_error(cli, *args):
    r = cli("bvp", *args, "--quiet", "--out", "/nonexistent/never")
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(BVP_PREFIX), r.stderr
    return lines[0][len(BVP_PREFIX):]


def assert_same_as_cli(solution, header, data, summary):
    d = solution.dim
    assert header == (["t"] + [f"x{i}" for i in range(1, d + 1)] +
                      [f"y{i}" for i in range(1, d + 1)] + ["residual_x", "residual_y"])
    assert np.array_equal(solution.t, data[:, 0])
    assert np.array_equal(solution.x, data[:, 1:1 + d])
    assert np.array_equal(solution.y, data[:, 1 + d:1 + 2 * d])
    assert np.array_equal(np.max(np.abs(solution.x_residual), axis=1), data[:, 1 + 2 * d])
    assert np.array_equal(np.max(np.abs(solution.y_residual), axis=1), data[:, 2 + 2 * d])
    assert solution.status == summary["status"]
    assert solution.residual_norm == summary["residual_norm"]
    assert solution.residual_floor == summary["residual_floor"]
    assert solution.residual_tolerance == summary["residual_tolerance"]
    assert solution.residual_history == summary["residual_history"]
    assert solution.newton_iterations == summary["newton_iterations"]
    assert solution.linear_iterations == summary["linear_iterations"]
    assert solution.linear_solver == summary["linear_solver"]
    assert solution.sum == summary["action_sum"]
    assert solution.scheme == summary["scheme"]
    assert solution.mirror_error == summary["mirror_error"]
    mine = solution.summary()
    for key in summary:
        if key != "wall_time_seconds":
            assert mine[key] == summary[key], key


@pytest.mark.parametrize("text", [COUPLED, MECHANICAL], ids=["coupled", "mechanical"])
def test_same_numbers_as_the_cli(cli, write_file, tmp_path, text):
    path = write_file(text)
    header, data, summary = run_cli(cli, path, str(tmp_path / "cli"))
    solution = fracvi.solve_bvp(path)
    assert solution.ok and solution.residual_norm <= solution.residual_tolerance
    assert_same_as_cli(solution, header, data, summary)
    # The boundary data, and y runs between the same points in reverse.
    problem = solution.problem
    assert np.array_equal(solution.x[0], problem.boundary["start"])
    assert np.array_equal(solution.x[-1], problem.boundary["end"])
    assert np.array_equal(solution.y[0], problem.boundary["end"])
    assert np.array_equal(solution.y[-1], problem.boundary["start"])
    # write() writes the CLI's files.
    out = solution.write(tmp_path / "python")
    with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as mine, \
            open(tmp_path / "cli" / "trajectory.csv", encoding="utf-8") as theirs:
        assert mine.read() == theirs.read()
    with open(os.path.join(out, "problem.toml"), encoding="utf-8") as mine, \
            open(tmp_path / "cli" / "problem.toml", encoding="utf-8") as theirs:
        assert mine.read() == theirs.read()


def test_the_scheme_reaches_the_boundary_value_problem(cli, write_file, tmp_path):
    # scheme="fvi-bdf2": Δ^α_± of BDF2 convolution quadrature, as `--set method.scheme=fvi-bdf2`;
    # different numbers from fvi-gl's.
    path = write_file(MECHANICAL)
    header, data, summary = run_cli(cli, path, str(tmp_path / "bdf2"), "--set",
                                    "method.scheme=fvi-bdf2")
    bdf2 = fracvi.solve_bvp(path, scheme="fvi-bdf2")
    assert bdf2.scheme == "fvi-bdf2" and bdf2.ok
    assert_same_as_cli(bdf2, header, data, summary)
    gl = fracvi.solve_bvp(path)
    assert gl.scheme == "fvi-gl"
    assert np.max(np.abs(gl.x - bdf2.x)) > 1e-4
    # The same through the problem's [method] section.
    in_file = fracvi.solve_bvp(fracvi.Problem.from_toml(path, overrides=["method.scheme=fvi-bdf2"]))
    assert np.array_equal(in_file.x, bdf2.x)


def test_options_of_the_cli(cli, write_file, tmp_path):
    path = write_file(COUPLED)
    header, data, summary = run_cli(cli, path, str(tmp_path / "cli"), "--solver", "krylov",
                                    "--tolerance", "1e-9", "--set", "output.every=4")
    solution = fracvi.solve_bvp(path, solver="krylov", tolerance=1e-9, every=4)
    assert solution.ok and solution.linear_iterations > 0
    assert solution.residual_tolerance == 1e-9 and solution.linear_solver.startswith("GMRES")
    # every= thins the written file only; the solution keeps every row.
    assert len(solution.t) == 41 and len(data) == 11
    rows = list(range(0, 41, 4)) + ([40] if 40 % 4 else [])
    assert np.array_equal(solution.x[rows], data[:, 1:3])
    assert solution.newton_iterations == summary["newton_iterations"]
    assert solution.residual_norm == summary["residual_norm"]


def test_printed_action_sum_same_as_cli_also_when_newton_fails(cli, write_file, tmp_path):
    # The equations of the printed action sum (to N−1) have no solution for this problem: Newton
    # stagnates, the CLI exits 1 and writes the best iterate, and so does solve_bvp (a status).
    path = write_file(COUPLED)
    header, data, summary = run_cli(cli, path, str(tmp_path / "cli"), "--sum", "printed",
                                    returncode=1)
    solution = fracvi.solve_bvp(path, sum="printed")
    assert solution.sum == "printed" and not solution.ok
    assert solution.status == "newton-failure" and "stagnated" in solution.message
    assert_same_as_cli(solution, header, data, summary)


def test_newton_iteration_limit_is_a_status(write_file):
    solution = fracvi.solve_bvp(write_file(COUPLED), newton_max_iterations=1)
    assert not solution.ok and solution.status != "success" and solution.message
    assert solution.newton_iterations == 1
    assert solution.x.shape == (41, 2)  # the best iterate
    with pytest.raises(fracvi.IntegrationError) as e:
        fracvi.solve_bvp(write_file(COUPLED), newton_max_iterations=1, raise_on_failure=True)
    assert e.value.solution.message == solution.message


def test_every_registered_scheme_solves_or_says_it_has_no_boundary_value_form(write_file):
    path = write_file(MECHANICAL)
    for method in fracvi.methods():
        try:
            solution = fracvi.solve_bvp(path, scheme=method["name"])
        except fracvi.ProblemError as e:
            assert (f'method.scheme = "{method["name"]}" has no boundary value form'
                    in str(e)), str(e)
            assert str(e).startswith(path + ": ")
        else:
            assert solution.ok and solution.scheme == method["name"]


# --- bad input -------------------------------------------------------------------------------

def test_unknown_scheme_same_message_as_cli(cli, write_file):
    path = write_file(MECHANICAL)
    message = cli_error(cli, path, "--set", "method.scheme=fvi-bdf9")
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.solve_bvp(path, scheme="fvi-bdf9")
    assert 'method.scheme = "fvi-bdf9" is not a known scheme (available: ' in str(e.value)
    # The keyword goes through the dict of the problem, so the source differs from the file's.
    assert str(e.value).split(": ", 1)[1] == message.split(": ", 1)[1]
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.solve_bvp(fracvi.Problem.from_toml(path, overrides=["method.scheme=fvi-bdf9"]))
    assert str(e.value) == message


@pytest.mark.parametrize("what,edit", [
    ("no boundary", ("[boundary]\nstart = [1.0]\nend = [0.0]\n",
                     "[initial]\nposition = [1.0]\n")),
    ("caputo", ('convention = "riemann-liouville"', 'convention = "caputo"')),
    ("boundary size", ("start = [1.0]", "start = [1.0, 2.0]")),
])
def test_bad_problems_same_message_as_cli(cli, write_file, what, edit):
    path = write_file(MECHANICAL.replace(*edit))
    message = cli_error(cli, path)
    with pytest.raises(fracvi.ProblemError) as e:
        problem = fracvi.Problem.from_toml(path)
        fracvi.solve_bvp(problem)
    assert str(e.value) == message
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.solve_bvp(path)
    assert str(e.value) == message


def test_integrate_refuses_a_boundary_value_problem_with_the_cli_message(cli, write_file):
    path = write_file(COUPLED)
    problem = fracvi.Problem.from_toml(path)  # a valid boundary value problem
    assert problem.boundary is not None and len(problem.position) == 0
    r = cli("run", path, "--quiet", "--no-plot", "--out", "/nonexistent/never")
    assert r.returncode == 2
    with pytest.raises(fracvi.ProblemError) as e:
        fracvi.integrate(problem)
    assert "fracvi run: " + str(e.value) == r.stderr.strip()
    assert "[initial] position missing" in str(e.value)


def test_option_errors():
    problem = fracvi.Problem.from_toml(MECHANICAL)
    with pytest.raises(TypeError, match="solve_bvp\\(\\) got an unexpected keyword argument "
                                        "'mirror' \\(valid: abs_tolerance, every, history, "):
        fracvi.solve_bvp(problem, mirror=True)
    with pytest.raises(ValueError, match="sum = 'both' must be 'extended' or 'printed'"):
        fracvi.solve_bvp(problem, sum="both")
    with pytest.raises(ValueError, match="solver = 'magic' must be 'auto', 'dense' or 'krylov'"):
        fracvi.solve_bvp(problem, solver="magic")
    with pytest.raises(ValueError, match="tolerance = 0.0 must be a positive number"):
        fracvi.solve_bvp(problem, tolerance=0.0)
    with pytest.raises(fracvi.ProblemError, match="method.newton_max_iterations = 0 must be in"):
        fracvi.solve_bvp(problem, newton_max_iterations=0)
