"""End-to-end tests of `fracvi bvp`, `fracvi residual` and `fracvi run` with general Lagrangians.

Run by ctest as: python3 cli_lagrangian_test.py /path/to/fracvi /path/to/tests/lagrangian/data
Contracts: exit 0 success, 1 numerical failure (files still written), 2 bad input with exactly one
line on stderr naming the key or flag, and nothing on stdout.
"""
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

FRACVI = None
DATA = None


def run(*args):
    return subprocess.run([FRACVI, *args], capture_output=True, text=True, timeout=300)


def data(name):
    return os.path.join(DATA, name)


def read_csv(path):
    with open(path, encoding="utf-8") as f:
        return list(csv.DictReader(f))


def read_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


class Bvp(unittest.TestCase):
    def test_coupled_lagrangian_converges(self):
        with tempfile.TemporaryDirectory() as out:
            r = run("bvp", data("coupled_bvp.toml"), "--out", out, "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual(r.stdout, "")
            s = read_json(os.path.join(out, "summary.json"))
            self.assertEqual(s["status"], "success")
            self.assertLessEqual(s["residual_norm"], 1e-10)
            self.assertEqual(s["action_sum"], "extended")
            rows = read_csv(os.path.join(out, "trajectory.csv"))
            self.assertEqual(list(rows[0].keys()),
                             ["t", "x1", "x2", "y1", "y2", "residual_x", "residual_y"])
            self.assertEqual(len(rows), 61)
            self.assertEqual([float(rows[0]["x1"]), float(rows[0]["x2"])], [0.3, -0.2])
            self.assertEqual([float(rows[-1]["y1"]), float(rows[-1]["y2"])], [0.3, -0.2])
            self.assertLessEqual(max(float(r["residual_x"]) for r in rows), 1e-10)
            # The problem.toml written back solves to the same curves.
            r2 = run("bvp", os.path.join(out, "problem.toml"), "--out", out + "/again", "--quiet")
            self.assertEqual(r2.returncode, 0, r2.stderr)
            again = read_csv(os.path.join(out, "again", "trajectory.csv"))
            self.assertEqual([r["x1"] for r in rows], [r["x1"] for r in again])

    def test_mechanical_bvp_reproduces_run(self):
        with tempfile.TemporaryDirectory() as out:
            # The scheme the boundary value form uses under "auto" (fvi-gl).
            r = run("run", data("pendulum_mechanical.toml"), "--out", out + "/ivp", "--quiet",
                    "--no-plot", "--set", "method.scheme=fvi-gl")
            self.assertEqual(r.returncode, 0, r.stderr)
            ivp = read_csv(os.path.join(out, "ivp", "trajectory.csv"))
            end = "[%s,%s]" % (ivp[-1]["x1"], ivp[-1]["x2"])
            r = run("bvp", data("pendulum_mechanical.toml"), "--out", out + "/bvp", "--quiet",
                    "--set", "boundary.start=[0.4,-0.3]", "--set", "boundary.end=" + end)
            self.assertEqual(r.returncode, 0, r.stderr)
            bvp = read_csv(os.path.join(out, "bvp", "trajectory.csv"))
            worst = max(abs(float(a[c]) - float(b[c])) for a, b in zip(ivp, bvp)
                        for c in ("x1", "x2"))
            self.assertLessEqual(worst, 1e-12)
            mirror = max(abs(float(a["y1"]) - float(b["x1"])) for a, b in zip(bvp, reversed(bvp)))
            self.assertLessEqual(mirror, 1e-12)

    def test_bdf2_scheme_of_the_file_reaches_bvp(self):
        # [method] scheme = "fvi-bdf2" in the file: fracvi bvp solves the restricted principle with
        # the BDF2 Delta^alpha (docs/theory/fvi_bdf2.md). With zero initial data (the scheme's
        # Taylor split is void) and forcing, fracvi run with the same file steps exactly these
        # x-equations, so the BVP from the run's end points returns the run.
        with tempfile.TemporaryDirectory() as out:
            with open(data("pendulum_mechanical.toml"), encoding="utf-8") as f:
                text = f.read()
            self.assertIn("[method]\n", text)
            problem = os.path.join(out, "bdf2.toml")
            with open(problem, "w", encoding="utf-8") as f:
                f.write(text.replace("[method]\n", '[method]\nscheme = "fvi-bdf2"\n'))
            zero = ["--set", "initial.position=[0,0]", "--set", "initial.velocity=[0,0]"]
            r = run("run", problem, "--out", out + "/ivp", "--quiet", "--no-plot", *zero)
            self.assertEqual(r.returncode, 0, r.stderr)
            ivp = read_csv(os.path.join(out, "ivp", "trajectory.csv"))
            self.assertGreater(max(abs(float(row["x1"])) for row in ivp), 1e-3)  # it moved
            ends = ["--set", "boundary.start=[0,0]",
                    "--set", "boundary.end=[%s,%s]" % (ivp[-1]["x1"], ivp[-1]["x2"])]
            r = run("bvp", problem, "--out", out + "/bdf2", *ends)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("fvi-bdf2", r.stdout)
            s = read_json(os.path.join(out, "bdf2", "summary.json"))
            self.assertEqual(s["status"], "success")
            self.assertEqual(s["scheme"], "fvi-bdf2")
            bdf2 = read_csv(os.path.join(out, "bdf2", "trajectory.csv"))
            # The BVP stops at max|F| <= 1e-10; its equations are (M/h^2) times a second
            # difference plus bounded terms, so ||J^-1|| ~ ||M^-1|| (b - a)^2 / 8 ~ 0.16 and the
            # positions agree to ~2e-11 at worst (17-digit CSV: no extra loss).
            tol = 1e-10
            worst = max(abs(float(a[c]) - float(b[c])) for a, b in zip(ivp, bdf2)
                        for c in ("x1", "x2"))
            self.assertLessEqual(worst, tol)
            # The same file with the paper's scheme: the Grunwald-Letnikov Delta^alpha, a different
            # discretisation (first order in the memory), a different curve.
            r = run("bvp", problem, "--out", out + "/gl", "--quiet", *ends,
                    "--set", "method.scheme=fvi-gl")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual(read_json(os.path.join(out, "gl", "summary.json"))["scheme"], "fvi-gl")
            gl = read_csv(os.path.join(out, "gl", "trajectory.csv"))
            differ = max(abs(float(a[c]) - float(b[c])) for a, b in zip(gl, bdf2)
                         for c in ("x1", "x2"))
            self.assertGreater(differ, 1e3 * tol)
            # The resolved problem.toml keeps the scheme: solving it again gives the same curve.
            r = run("bvp", os.path.join(out, "bdf2", "problem.toml"), "--out", out + "/again",
                    "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)
            again = read_csv(os.path.join(out, "again", "trajectory.csv"))
            self.assertEqual([row["x1"] for row in bdf2], [row["x1"] for row in again])

    def test_newton_failure_writes_best_iterate(self):
        with tempfile.TemporaryDirectory() as out:
            r = run("bvp", data("coupled_bvp.toml"), "--out", out, "--quiet",
                    "--set", "method.newton_max_iterations=1")
            self.assertEqual(r.returncode, 1, r.stderr)
            s = read_json(os.path.join(out, "summary.json"))
            self.assertEqual(s["status"], "newton-failure")
            self.assertIn("no convergence", s["message"])
            self.assertTrue(os.path.exists(os.path.join(out, "trajectory.csv")))

    def test_printed_sum_is_selectable(self):
        with tempfile.TemporaryDirectory() as out:
            r = run("bvp", data("coupled_bvp.toml"), "--out", out, "--quiet", "--sum", "printed",
                    "--solver", "dense")
            self.assertEqual(r.returncode, 0, r.stderr)
            s = read_json(os.path.join(out, "summary.json"))
            self.assertEqual(s["action_sum"], "printed")
            self.assertIn("dense LU", s["linear_solver"])

    def test_default_tolerance_rises_to_the_round_off_floor(self):
        # Issue 14 item 6: a linear BVP at N = 5000. The equations scale like 1/h², so their
        # round-off floor (2 eps |J| |u|, about 1e-8 here) is far above the old fixed default
        # 1e-10, and Newton stagnated at 2.5e-9 with exit 1. The default now converges at the
        # floor; an explicit --tolerance is taken as given and still fails, saying why.
        with tempfile.TemporaryDirectory() as out:
            path = os.path.join(out, "linear.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write('name = "linear-bvp"\n[model]\ndim = 1\nmass = 1.0\ndamping = 0.3\n'
                        'alpha = 0.75\nconvention = "riemann-liouville"\n'
                        'potential = "x1^2/2"\n[boundary]\nstart = [1.0]\nend = [0.5]\n'
                        '[time]\nend = 2.0\nsteps = 5000\n')
            r = run("bvp", path, "--out", os.path.join(out, "a"), "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)
            s = read_json(os.path.join(out, "a", "summary.json"))
            self.assertEqual(s["status"], "success")
            self.assertGreater(s["residual_floor"], 1e-9)  # the old default was unreachable
            self.assertEqual(s["residual_tolerance"], max(1e-10, s["residual_floor"]))
            self.assertLessEqual(s["residual_norm"], s["residual_tolerance"])
            # The curve: y mirrors x to what the residual allows — an iterate error of at most
            # |J^-1| max|F| <= (T^2/8 for M u'' with unit mass on [0, T = 2]) x tolerance, doubled
            # — and N = 2500 agrees to the scheme's first order.
            fine = read_csv(os.path.join(out, "a", "trajectory.csv"))
            mirror_bound = 2 * (2.0 ** 2 / 8) * s["residual_tolerance"]
            self.assertLess(max(abs(float(fine[k]["y1"]) - float(fine[5000 - k]["x1"]))
                                for k in range(5001)), mirror_bound)
            r = run("bvp", path, "--out", os.path.join(out, "b"), "--quiet", "--set",
                    "time.steps=2500")
            self.assertEqual(r.returncode, 0, r.stderr)
            coarse = read_csv(os.path.join(out, "b", "trajectory.csv"))
            self.assertLess(abs(float(fine[2500]["x1"]) - float(coarse[1250]["x1"])), 1e-2)

            r = run("bvp", path, "--out", os.path.join(out, "c"), "--quiet",
                    "--tolerance", "1e-10")
            self.assertEqual(r.returncode, 1)
            # --quiet: no summary, but the failure's one line (issue 14 item 7).
            self.assertEqual(r.stdout, "")
            lines = r.stderr.strip().splitlines()
            self.assertEqual(len(lines), 1, r.stderr)
            self.assertIn("fracvi bvp: linear-bvp: newton-failure: Newton stagnated", lines[0])
            self.assertIn("the tolerance is too tight for this step size (without an explicit "
                          "tolerance the solver converges at the floor)", lines[0])
            self.assertIn("best iterate written: max |F| = ", lines[0])


class Residual(unittest.TestCase):
    EXACT_X = "exp(-0.2*t)*sin(sqrt(3.96)*t)"
    EXACT_Y = "exp(-0.2*(2-t))*sin(sqrt(3.96)*(2-t))"

    def values(self, *args):
        r = run("residual", data("oscillator.toml"), *args)
        self.assertEqual(r.returncode, 0, r.stderr)
        return [[float(v) for v in line.split()] for line in r.stdout.splitlines()]

    def test_damped_oscillator_with_mirror_solves_fracel(self):
        rows = self.values("--x", self.EXACT_X, "--y", self.EXACT_Y, "--t", "0.5,1,1.5")
        self.assertEqual([row[0] for row in rows], [0.5, 1.0, 1.5])
        for row in rows:
            self.assertLessEqual(max(abs(v) for v in row[1:]), 1e-12)

    def test_nonzero_initial_position_and_velocity(self):
        # Issue 13 item 2: x(0) = 1, v(0) = 0.5 (and y(b) = 1): the endpoint singularities
        # x(a)(t-a)^(-1/2)/Gamma(1/2) are split off in closed form; round-off, up to near the ends.
        w, c = "sqrt(3.96)", "(0.7/sqrt(3.96))"
        x = f"exp(-0.2*t)*(cos({w}*t) + {c}*sin({w}*t))"
        y = f"exp(-0.2*(2-t))*(cos({w}*(2-t)) + {c}*sin({w}*(2-t)))"
        rows = self.values("--x", x, "--y", y, "--t", "0.001,0.5,1,1.5,1.999")
        for row in rows:
            self.assertLessEqual(max(abs(v) for v in row[1:]), 1e-10)

    def test_non_solution_has_order_one_residual(self):
        rows = self.values("--x", "sin(2*t)", "--y", "sin(2*(2-t))", "--t", "1")
        self.assertGreater(abs(rows[0][1]), 0.1)
        self.assertGreater(abs(rows[0][2]), 0.1)

    def test_commas_inside_parentheses_stay_in_one_formula(self):
        r = run("residual", data("coupled_bvp.toml"), "--x", "pow(t, 2),sin(t)",
                "--y", "1.5-t,0", "--t", "0.7")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(len(r.stdout.split()), 5)


class Action(unittest.TestCase):
    # Issue 13 item 1: `fracvi action`. L = 0.5 xdot^2 - 0.7 dx dy (expression) along x = t^2.5,
    # y = (1.5 - t)^2.25 on [0, 1.5], alpha = 0.5, against the closed form (Beta integrals).
    def values(self, *args):
        r = run("action", *args)
        self.assertEqual(r.returncode, 0, r.stderr)
        return {line.split()[0]: float(line.split()[1]) for line in r.stdout.splitlines()}

    def problem(self, directory):
        path = os.path.join(directory, "action.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write('[model]\ndim = 1\nalpha = 0.5\nlagrangian = "0.5*xdot1^2 - 0.7*dx1*dy1"\n'
                    '[boundary]\nstart = [0.0]\nend = [0.0]\n[time]\nend = 1.5\nsteps = 10\n')
        return path

    def test_action_matches_closed_form(self):
        p, q, alpha, length = 2.5, 2.25, 0.5, 1.5
        c1 = math.gamma(p + 1) / math.gamma(p + 1 - alpha)
        c2 = math.gamma(q + 1) / math.gamma(q + 1 - alpha)
        mu, nu = p - alpha, q - alpha
        beta = math.gamma(mu + 1) * math.gamma(nu + 1) / math.gamma(mu + nu + 2)
        expected = (0.5 * p * p * length ** (2 * p - 1) / (2 * p - 1)
                    - 0.7 * c1 * c2 * length ** (mu + nu + 1) * beta)
        with tempfile.TemporaryDirectory() as d:
            v = self.values(self.problem(d), "--x", "t^2.5", "--y", "(1.5 - t)^2.25")
        self.assertEqual(list(v), ["action"])
        self.assertLessEqual(abs(v["action"] - expected), 1e-11 * abs(expected))

    def test_exact_solution_is_stationary_and_pairing_agrees(self):
        # The damped oscillator's exact solution with x(0) = 1 and its mirror: E = 0, so the
        # restricted first variation vanishes; for a non-solution it equals the pairing.
        w, c = "sqrt(3.96)", "(0.7/sqrt(3.96))"
        x = f"exp(-0.2*t)*(cos({w}*t) + {c}*sin({w}*t))"
        y = f"exp(-0.2*(2-t))*(cos({w}*(2-t)) + {c}*sin({w}*(2-t)))"
        eta = "t^2*(2 - t)^2"
        v = self.values(data("oscillator.toml"), "--x", x, "--y", y, "--eta", eta)
        self.assertLessEqual(abs(v["variation"]), 1e-12)
        v = self.values(data("oscillator.toml"), "--x", "sin(2*t)", "--y", "sin(2*(2-t))",
                        "--eta", eta, "--pairing", "--tolerance", "1e-6")
        self.assertGreater(abs(v["variation"]), 0.1)
        self.assertLessEqual(abs(v["variation"] - v["pairing"]), 1e-8 * abs(v["variation"]))


class BadInput(unittest.TestCase):
    def assert_bad(self, args, *needles):
        r = run(*args)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertEqual(r.stdout, "")
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        for n in needles:
            self.assertIn(n, r.stderr)

    def test_lagrangian_variable_that_does_not_exist_for_d(self):
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--set",
                         "model.lagrangian=0.5*xdot1^2 + 0.5*ydot1^2 - x3"],
                        "model.lagrangian", "x3", "column")

    def test_singular_velocity_hessian(self):
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--set",
                         "model.lagrangian=0.5*(xdot1^2 + xdot2^2) + 0.5*ydot1^2 - dx1*dy1"],
                        "singular", "ydot")
        self.assert_bad(["run", data("pendulum_lagrangian.toml"), "--set",
                         "model.lagrangian=0.5*xdot1^2 + 0.5*(ydot1^2 + ydot2^2) - x2^2"],
                        "singular", "xdot", "initial data")

    def test_run_refuses_coupled_lagrangian_and_points_to_bvp(self):
        self.assert_bad(["run", data("coupled_bvp.toml"), "--set", "initial.position=[0.1,0.2]"],
                        "fracvi bvp", "involves y")

    def test_run_refuses_boundary_only_file(self):
        self.assert_bad(["run", data("coupled_bvp.toml")], "[initial]", "fracvi bvp")

    def test_bvp_needs_boundary(self):
        self.assert_bad(["bvp", data("oscillator.toml")], "[boundary]")

    def test_lagrangian_excludes_mechanical_fields(self):
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--set", "model.mass=1.0"],
                        "model.mass", "model.lagrangian")

    def test_caputo_is_refused_for_variational_problems(self):
        self.assert_bad(["bvp", data("pendulum_mechanical.toml"), "--set", "boundary.start=[0,0]",
                         "--set", "boundary.end=[0,0]", "--set", "model.alpha=0.3",
                         "--set", "model.convention=caputo"], "caputo", "riemann-liouville")

    def test_residual_bad_curves(self):
        osc = data("oscillator.toml")
        self.assert_bad(["residual", osc, "--x", "t,t", "--y", "0", "--t", "1"], "--x", "2 components")
        self.assert_bad(["residual", osc, "--x", "s", "--y", "0", "--t", "1"], "--x", "'s'")
        self.assert_bad(["residual", osc, "--x", "t", "--y", "0", "--t", "3"], "--t", "outside")
        # At t = a the outer D^alpha_- acts at its terminal on -R D^alpha_- x ~ (t-a)^(1/2).
        self.assert_bad(["residual", osc, "--x", "1+t", "--y", "0", "--t", "0"], "terminal")
        # x(a) != 0 with a dL/dD^alpha_+y that is not affine in D^alpha_- x (the coupled L).
        self.assert_bad(["residual", data("coupled_bvp.toml"), "--x", "1+t,t", "--y", "1.5-t,0.3*(1.5-t)",
                         "--t", "1"], "x(a) = (1, 0) != 0", "x(a) = 0")

    def test_action_bad_variations(self):
        osc = data("oscillator.toml")
        self.assert_bad(["action", osc, "--x", "t", "--y", "2-t", "--eta", "t"], "--eta",
                        "t = 2", "must vanish")
        self.assert_bad(["action", osc, "--x", "t", "--y", "2-t", "--pairing"], "--pairing",
                        "--eta")
        self.assert_bad(["action", osc, "--x", "t", "--y", "2-t", "--eta", "t*(2-t)",
                         "--pairing"], "delta_x", "second order")

    def test_bad_flags(self):
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--sum", "both"], "--sum")
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--solver", "magic"], "--solver")
        self.assert_bad(["bvp", data("coupled_bvp.toml"), "--tolerance", "0"], "--tolerance")


class RunWithLagrangian(unittest.TestCase):
    def test_mechanical_lagrangian_matches_mechanical_fields(self):
        with tempfile.TemporaryDirectory() as out:
            a = run("run", data("pendulum_mechanical.toml"), "--out", out + "/a", "--quiet",
                    "--no-plot")
            b = run("run", data("pendulum_lagrangian.toml"), "--out", out + "/b", "--quiet",
                    "--no-plot")
            self.assertEqual(a.returncode, 0, a.stderr)
            self.assertEqual(b.returncode, 0, b.stderr)
            ra = read_csv(os.path.join(out, "a", "trajectory.csv"))
            rb = read_csv(os.path.join(out, "b", "trajectory.csv"))
            worst = max(abs(float(x[c]) - float(y[c])) for x, y in zip(ra, rb)
                        for c in ("x1", "x2", "v1", "v2"))
            self.assertLessEqual(worst, 1e-13)
            s = read_json(os.path.join(out, "b", "summary.json"))
            self.assertIn("lagrangian", s["problem"]["model"])


if __name__ == "__main__":
    FRACVI, DATA = sys.argv[1], sys.argv[2]
    unittest.main(argv=sys.argv[:1], verbosity=1)
