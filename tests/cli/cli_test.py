"""End-to-end tests of the fracvi command line: outputs, exit statuses and error contracts.

Run by ctest as: python3 cli_test.py /path/to/fracvi
Bad input must give exit status 2, exactly one line on stderr naming the argument, and nothing on
stdout.
"""
import csv
import json
import math
import os
import signal
import time
import subprocess
import sys
import tempfile
import unittest

FRACVI = None
# examples/ of the source tree (a problem file for the commands that need one).
FRACVI_EXAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples")


def run(*args):
    return subprocess.run([FRACVI, *args], capture_output=True, text=True, timeout=120)


class Weights(unittest.TestCase):
    def test_gl_half(self):
        r = run("weights", "--order", "0.5", "--scheme", "gl", "-n", "5")
        self.assertEqual(r.returncode, 0, r.stderr)
        values = [float(v) for v in r.stdout.split()]
        self.assertEqual(values, [1.0, -0.5, -0.125, -0.0625, -0.0390625])

    def test_seventeen_digits_round_trip(self):
        r = run("weights", "--order", "0.3", "-n", "3")
        lines = r.stdout.splitlines()
        self.assertEqual(lines[1], "-0.29999999999999999")  # repr of -0.3 at 17 digits
        self.assertEqual(float(lines[2]), -0.3 * (1 - 0.3) / 2)

    def test_bdf2_and_trapezoidal_order_one(self):
        r = run("weights", "--order", "1", "--scheme", "bdf2", "-n", "4")
        self.assertEqual([float(v) for v in r.stdout.split()], [1.5, -2.0, 0.5, 0.0])
        r = run("weights", "--order", "1", "--scheme", "trapezoidal", "-n", "4")
        self.assertEqual([float(v) for v in r.stdout.split()], [2.0, -4.0, 4.0, -4.0])


class Derivative(unittest.TestCase):
    def values(self, *args):
        r = run("derivative", *args)
        self.assertEqual(r.returncode, 0, r.stderr)
        return [[float(v) for v in line.split()] for line in r.stdout.splitlines()]

    def test_left_power_closed_form(self):
        # D^{1/2}_- (t-a)^2 = Gamma(3)/Gamma(2.5) (t-a)^{1.5}
        rows = self.values("--alpha", "0.5", "--side", "left", "--f", "(t-0.5)^2",
                           "--a", "0.5", "--b", "2", "--t", "1,1.5,2")
        for t, v in rows:
            exact = math.gamma(3) / math.gamma(2.5) * (t - 0.5) ** 1.5
            self.assertAlmostEqual(v, exact, delta=1e-11 * abs(exact))

    def test_right_power_closed_form(self):
        rows = self.values("--alpha", "0.3", "--side", "right", "--f", "(2-t)^3",
                           "--a", "0", "--b", "2", "--t", "0,0.7,1.9")
        for t, v in rows:
            exact = math.gamma(4) / math.gamma(4 - 0.3) * (2 - t) ** (3 - 0.3)
            self.assertAlmostEqual(v, exact, delta=1e-11 * abs(exact))

    def test_order_one_is_the_derivative(self):
        rows = self.values("--alpha", "1", "--f", "sin(t)", "--a", "0", "--b", "3", "--t", "0.5,2")
        for t, v in rows:
            self.assertAlmostEqual(v, math.cos(t), delta=1e-14)
        rows = self.values("--alpha", "1", "--side", "right", "--f", "sin(t)", "--a", "0",
                           "--b", "3", "--t", "0.5")
        self.assertAlmostEqual(rows[0][1], -math.cos(0.5), delta=1e-14)

    def test_exact_column(self):
        rows = self.values("--alpha", "0.5", "--f", "t^1.5", "--a", "0", "--b", "2",
                           "--t", "1", "--exact", "0.75*sqrt(pi)*t")
        t, v, e, diff = rows[0]
        self.assertAlmostEqual(e, 0.75 * math.sqrt(math.pi), delta=1e-15)
        self.assertLess(abs(diff), 1e-11)


class BadInput(unittest.TestCase):
    def assert_bad(self, args, *needles):
        r = run(*args)
        self.assertEqual(r.returncode, 2, f"{args}: {r.stdout} {r.stderr}")
        self.assertEqual(r.stdout, "", args)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        for needle in needles:
            self.assertIn(needle, lines[0], args)

    D = ["derivative", "--f", "sin(t)", "--a", "0", "--b", "1", "--t", "0.5"]

    def test_alpha_outside_unit_interval(self):
        self.assert_bad(self.D + ["--alpha", "1.5"], "--alpha", "1.5", "[0, 1]")
        self.assert_bad(self.D + ["--alpha", "-0.1"], "--alpha", "-0.1")

    def test_a_not_below_b(self):
        self.assert_bad(["derivative", "--alpha", "0.5", "--f", "t", "--a", "1", "--b", "1",
                         "--t", "1"], "--a", "--b", "A < B")

    def test_t_outside_interval(self):
        self.assert_bad(["derivative", "--alpha", "0.5", "--f", "t", "--a", "0", "--b", "1",
                         "--t", "0.5,1.5"], "--t", "1.5", "outside")

    def test_unknown_side(self):
        self.assert_bad(self.D + ["--alpha", "0.5", "--side", "middle"], "--side", "middle")

    def test_malformed_expression(self):
        self.assert_bad(["derivative", "--alpha", "0.5", "--f", "sin(t", "--a", "0", "--b", "1",
                         "--t", "0.5"], "--f", "sin(t", "column")
        self.assert_bad(["derivative", "--alpha", "0.5", "--f", "cos(x1)", "--a", "0", "--b", "1",
                         "--t", "0.5"], "--f", "x1", "column")
        self.assert_bad(["derivative", "--alpha", "0.5", "--f", "t/0", "--a", "0", "--b", "1",
                         "--t", "0.5"], "--f", "column")

    def test_nonpositive_count(self):
        self.assert_bad(["weights", "--order", "0.5", "-n", "0"], "-n", "0", "positive")
        self.assert_bad(["weights", "--order", "0.5", "-n", "-3"], "-n", "-3")

    def test_no_plot_removes_stale_plots(self):
        # An earlier run's pictures must not stay beside new data (issue 14 item 8).
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "stale")
            os.makedirs(out)
            for name in ("trajectory.png", "phase.png", "energy.png", "spacetime.png"):
                with open(os.path.join(out, name), "wb") as f:
                    f.write(b"old")
            r = run("run", "--out", out, "--no-plot", "--set", "time.steps=100")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual([n for n in os.listdir(out) if n.endswith(".png")], [])
            self.assertIn("{trajectory.csv,summary.json,problem.toml}", r.stdout)

    def test_version(self):
        r = run("--version")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stdout.strip(), r"^fracvi \d+\.\d+\.\d+ \(commit ([0-9a-f]+|unknown)\)$")
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "v")
            r2 = run("run", "--out", out, "--no-plot", "--quiet", "--set", "time.steps=100")
            self.assertEqual(r2.returncode, 0, r2.stderr)
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                self.assertEqual(json.load(f)["fracvi_version"], r.stdout.strip())
            with open(os.path.join(out, "problem.toml"), encoding="utf-8") as f:
                self.assertEqual(f.readline().strip(), "# written by " + r.stdout.strip())

    def test_unknown_scheme(self):
        self.assert_bad(["weights", "--order", "0.5", "--scheme", "bdf3", "-n", "3"],
                        "--scheme", "bdf3", "gl, bdf2 or trapezoidal")

    def test_not_a_number_and_missing_option(self):
        self.assert_bad(["weights", "--order", "half", "-n", "3"], "--order")
        self.assert_bad(["weights", "-n", "3"], "--order")
        self.assert_bad(["frobnicate"], "frobnicate")


PROBLEM = """
name = "cli-test"
[model]
dim = 2
mass = [[2.0, 0.5], [0.5, 1.0]]
damping = [[0.2, 0.05], [0.05, 0.1]]
alpha = 0.5
potential = "x1^4/4 + x2^2/2 - 0.2*x1*x2"
force = ["0.1*sin(t)", "0"]
[initial]
position = [1.0, 0.0]
velocity = [0.0, 0.5]
[time]
end = 5.0
steps = 500
"""


class Run(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, text, name="p.toml"):
        path = os.path.join(self.dir, name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        return path

    def test_mirror_check_off(self):
        out = os.path.join(self.dir, "out")
        r = run("run", "--out", out, "--no-plot", "--set", "time.steps=600",
                "--set", "method.mirror=off")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn('mirror error      not run (method.mirror = "off")', r.stdout)
        self.assertIn("stepping", r.stdout)
        self.assertNotIn("with the mirror run", r.stdout)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        self.assertIsNone(summary["mirror_error"])
        self.assertEqual(summary["problem"]["method"]["mirror"], "off")

    def test_built_in_problem_writes_everything(self):
        out = os.path.join(self.dir, "out")
        r = run("run", "--out", out, "--set", "time.end=6", "--set", "time.steps=600")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("status            success", r.stdout)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        self.assertEqual(summary["status"], "success")
        self.assertEqual(summary["steps"], 600)
        self.assertAlmostEqual(summary["final_time"], 6.0, delta=1e-12)
        self.assertEqual(summary["problem"]["model"]["alpha"], 0.75)
        self.assertLess(summary["mirror_error"], 1e-8)
        for key in ("message", "final_position", "final_velocity", "max_balance_error",
                    "newton_iterations", "wall_seconds"):
            self.assertIn(key, summary)
        # The whole cost is set-up plus stepping, each reported.
        self.assertGreater(summary["setup_wall_seconds"], 0.0)
        self.assertGreater(summary["stepping_wall_seconds"], 0.0)
        self.assertAlmostEqual(
            summary["wall_seconds"],
            summary["setup_wall_seconds"] + summary["stepping_wall_seconds"], delta=1e-12)
        self.assertRegex(r.stdout, r"wall time +[0-9.]+ s  \(set-up [0-9.]+ s, stepping [0-9.]+ s "
                                   r"with the mirror run\)")
        with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
            rows = list(csv.reader(f))
        self.assertEqual(rows[0], ["t", "x1", "v1", "energy", "dissipated", "balance"])
        self.assertEqual(len(rows), 602)
        self.assertEqual(float(rows[-1][1]), summary["final_position"][0])
        for png in ("trajectory.png", "phase.png", "energy.png"):
            self.assertTrue(os.path.getsize(os.path.join(out, png)) > 10000, png)
        # problem.toml reproduces the run
        out2 = os.path.join(self.dir, "again")
        r = run("run", os.path.join(out, "problem.toml"), "--out", out2, "--no-plot", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout, "")
        with open(os.path.join(out2, "summary.json"), encoding="utf-8") as f:
            self.assertEqual(json.load(f)["final_position"], summary["final_position"])

    def test_error_estimate_and_tolerance(self):
        # Every run reports an error estimate (Richardson from runs with N/2, N/4 steps); the
        # balance and mirror lines say they are consistency checks. The damped oscillator
        # x'' + 0.25 x' + x = 0 with fvi-bdf2 has a closed form: the estimate is within a factor 3.
        path = self.write('name = "osc"\n[model]\ndim = 1\nmass = 1.0\ndamping = 0.25\n'
                          'alpha = 0.5\npotential = "x1^2/2"\n[initial]\nposition = [1.0]\n'
                          'velocity = [0.5]\n[time]\nend = 16.0\nsteps = 400\n[method]\n'
                          'scheme = "fvi-bdf2"\n[reference]\nposition = '
                          '["exp(-t/8)*(cos(w*t) + 0.625/w*sin(w*t))"]\n'.replace(
                              "w", "sqrt(1 - 1/64)"))
        out = os.path.join(self.dir, "est")
        r = run("run", path, "--out", out, "--no-plot")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("error estimate    max |x_k - x(t_k)| ~", r.stdout)
        self.assertIn("(consistency check)", r.stdout)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        ratio = summary["error_estimate"] / summary["reference_error"]
        self.assertTrue(1 / 3 <= ratio <= 3, ratio)
        self.assertEqual(summary["error_estimate_details"]["method"], "richardson (N/2, N/4)")
        self.assertEqual(summary["tolerance_runs"], [])
        # method.tolerance doubles N until the estimate meets it, and says how it got there.
        out = os.path.join(self.dir, "tol")
        r = run("run", path, "--out", out, "--no-plot", "--set", "method.tolerance=1e-6")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        runs = summary["tolerance_runs"]
        self.assertEqual([x["steps"] for x in runs], [400 * 2**i for i in range(len(runs))])
        self.assertGreater(runs[-2]["error_estimate"], 1e-6)
        self.assertLessEqual(runs[-1]["error_estimate"], 1e-6)
        self.assertEqual(summary["steps"], runs[-1]["steps"])
        self.assertLess(summary["reference_error"], 3e-6)
        # A ceiling that stops the doubling: `inaccurate`, exit 1, the last run kept.
        out = os.path.join(self.dir, "ceiling")
        r = run("run", path, "--out", out, "--no-plot", "--set", "method.tolerance=1e-9",
                "--set", "method.max_steps=2000")
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("inaccurate: method.tolerance = 1e-09 not reached: error estimate", r.stdout)
        self.assertIn("would pass method.max_steps = 2000", r.stdout)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            self.assertEqual(json.load(f)["steps"], 1600)
        # Bad values name the field and the rule.
        for setting, message in (("method.tolerance=-1", "method.tolerance = -1 must be a positive"),
                                 ("method.max_steps=0", "method.max_steps = 0 must be in [1, "),
                                 ("method.error_estimate=richardsen", "did you mean 'richardson'")):
            r = run("run", path, "--out", out, "--no-plot", "--set", setting)
            self.assertEqual(r.returncode, 2, setting)
            self.assertIn(message, r.stderr)

    def test_no_hangs_on_degenerate_input(self):
        # Issue 14 item 6: each of these used to hang or take minutes before its error.
        out = os.path.join(self.dir, "h")
        r = run("run", "--no-plot", "--out", out, "--set", "model.alpha=1e-308",
                "--set", 'method.history="fast"')
        self.assertEqual(r.returncode, 2, r.stdout)
        self.assertIn("model.alpha = 1e-308 is positive but below 1e-12", r.stderr)
        r = run("run", "--no-plot", "--out", out, "--set", "model.alpha=1e-12",
                "--set", 'method.history="fast"', "--set", "time.end=1", "--set", "time.steps=100")
        self.assertEqual(r.returncode, 0, r.stderr)
        r = run("run", "/dev/zero", "--no-plot", "--out", out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("/dev/zero: is larger than 64 MiB, the limit for a problem file", r.stderr)
        path = self.write('name = "big"\n[model]\ndim = 10000000\nmass = 1.0\nalpha = 0.5\n'
                          'potential = "x1^2/2"\nforce = ["sin(t)"]\n[initial]\nposition = 0.0\n'
                          '[time]\nend = 1.0\nsteps = 10\n')
        start = time.monotonic()
        r = run("run", path, "--no-plot", "--out", out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("model.force: has 1 components, model.dim is 10000000", r.stderr)
        self.assertLess(time.monotonic() - start, 5.0)

    def test_concurrent_runs_never_share_a_directory(self):
        # Issue 14 item 4: a second run into a directory in use is refused at once (exit 2, the
        # first run's pid), and the first one finishes with its own files only.
        out = os.path.join(self.dir, "shared")
        first = subprocess.Popen([FRACVI, "run", "--out", out, "--no-plot", "--quiet", "--set",
                                  "time.steps=1000000", "--set", 'method.error_estimate="none"'],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 10
        while not os.path.exists(os.path.join(out, ".fracvi.lock")):
            self.assertLess(time.monotonic(), deadline, "the first run never claimed " + out)
            time.sleep(0.01)
        second = run("run", "--out", out, "--no-plot")
        self.assertEqual(second.returncode, 2, second.stdout)
        self.assertIn(out + ": in use by another fracvi run (pid " + str(first.pid) + ")",
                      second.stderr)
        _, err = first.communicate(timeout=120)
        self.assertEqual(first.returncode, 0, err)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            self.assertEqual(json.load(f)["steps"], 1000000)
        self.assertEqual(sorted(os.listdir(out)), ["problem.toml", "summary.json",
                                                   "trajectory.csv"])  # no lock, no temporary
        # Default directories carry the overrides (a shell sweep does not collide), unless the
        # overrides name the run.
        for alpha in ("0.6", "0.7"):
            r = subprocess.run([FRACVI, "run", "--no-plot", "--quiet", "--set",
                                "model.alpha=" + alpha, "--set", "time.end=1", "--set",
                                "time.steps=100"], cwd=self.dir, capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(os.path.join(self.dir, "fracvi-out"))),
                         ["fractional-duffing-model.alpha=0.6-time.end=1-time.steps=100",
                          "fractional-duffing-model.alpha=0.7-time.end=1-time.steps=100"])

    def test_summary_says_which_history_ran(self):
        # Issue 14 item 8: summary.json names the damping memory "auto" chose.
        for setting, expected, *extra in (('method.history="direct"', "direct"),
                                  ('method.history="fast"', "fast"),
                                  ("model.damping=0", "none"),
                                  ("model.alpha=0.5", "none", 'method.scheme="fvi-gl"'),
                                  ('method.scheme="fvi-bdf2"', "direct"),  # auto: short run
                                  ("model.alpha=0.5", "local", 'method.scheme="fvi-bdf2"')):
            out = os.path.join(self.dir, "hist")
            r = run("run", "--out", out, "--no-plot", "--quiet", "--set", setting, "--set",
                    "time.end=1", "--set", "time.steps=100",
                    *(["--set", extra[0]] if extra else []))
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                self.assertEqual(json.load(f)["history"], expected, setting)

    def test_summary_says_how_the_history_used_the_cores(self):
        # Issue 17: summary.json's history_threads, and the terminal's line for it. A chain of
        # 2000 masses has enough history work per step for the run-ahead thread (a team of 2).
        chain = os.path.join(FRACVI_EXAMPLES, "fractional_chain.toml")
        for threads, team in ((2, 2), (1, 1)):
            out = os.path.join(self.dir, "threads%d" % threads)
            r = run("run", chain, "--out", out, "--no-plot", "--set", "time.steps=200", "--set",
                    "time.end=2", "--set", "model.dim=2000", "--set", 'method.history="fast"',
                    "--set", "method.threads=%d" % threads, "--set",
                    'method.error_estimate="none"', "--set", 'method.mirror="off"')
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                use = json.load(f)["history_threads"]
            self.assertEqual(use["team"], team)
            self.assertEqual(use["pushes"], 201)  # x̃_0 at the set-up, then one a step
            self.assertEqual(use["team_pushes"], 201 if team == 2 else 0)
            self.assertFalse(use["measured"])
            self.assertEqual(("history threads   2 as set (100 % of the pushes)" in r.stdout),
                             team == 2, r.stdout)
            self.assertFalse(use["whole_steps"])
        # From 3072 masses the whole step is split by rows (IntegratorOptions::row_split_from):
        # the team counts steps, and the terminal says so.
        out = os.path.join(self.dir, "rows")
        r = run("run", chain, "--out", out, "--no-plot", "--set", "time.steps=200", "--set",
                "time.end=2", "--set", "model.dim=4000", "--set", 'method.history="fast"', "--set",
                "method.threads=2", "--set", 'method.error_estimate="none"', "--set",
                'method.mirror="off"')
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            use = json.load(f)["history_threads"]
        self.assertTrue(use["whole_steps"])
        self.assertEqual((use["team"], use["pushes"], use["team_pushes"]), (2, 200, 200))
        self.assertIn("step threads      2 as set (100 % of the steps, split by rows)", r.stdout)

    def test_problem_file_every_and_default_directory(self):
        path = self.write(PROBLEM + "[output]\nevery = 100\n")
        r = subprocess.run([FRACVI, "run", path, "--no-plot"], capture_output=True, text=True,
                           cwd=self.dir, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        out = os.path.join(self.dir, "fracvi-out", "cli-test")
        with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
            rows = list(csv.reader(f))
        self.assertEqual(rows[0], ["t", "x1", "x2", "v1", "v2", "energy", "dissipated", "balance"])
        self.assertEqual([float(r[0]) for r in rows[1:]], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])

    def test_numerical_failure_keeps_what_was_computed(self):
        path = self.write(PROBLEM + "[method]\nnewton_max_iterations = 1\n")
        out = os.path.join(self.dir, "fail")
        r = run("run", path, "--out", out, "--no-plot")
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        self.assertNotEqual(summary["status"], "success")
        self.assertIn("step", summary["message"])
        self.assertLess(summary["steps"], 500)
        with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
            self.assertEqual(len(f.readlines()), summary["steps"] + 2)

    # The run's health checks (docs/conventions.md, "When a run is not a success"): U = -1/x1
    # falls from rest at x = 1 into its singularity at t = 1.11 and the step jumps across it
    # (balance error 170 against E_0 = -1); U = -x1^4 from x = 1, v = 1 blows up in finite time
    # (t = 0.9) and 50 steps run through it (balance error 2e17). Both used to end "success".
    # With fvi-gl each ends "inaccurate" with exit 1, the message naming the quantity, its value and the rule,
    # and every row written; the same problems before the singularity are a success.
    SINGULAR = [
        ("coulomb", "-1/x1", "0.0", "5.0", 1000, "1.0"),
        ("quartic", "-x1^4", "1.0", "3.0", 50, "0.3"),
    ]

    def test_blow_up_and_singularity_are_not_success(self):
        for name, potential, velocity, end, steps, safe_end in self.SINGULAR:
            with self.subTest(name):
                path = self.write(f'name = "{name}"\n[model]\ndim = 1\nmass = 1.0\nalpha = 0.5\n'
                                  f'potential = "{potential}"\n[initial]\nposition = [1.0]\n'
                                  f'velocity = [{velocity}]\n[time]\nend = {end}\n'
                                  f'steps = {steps}\n[method]\nscheme = "fvi-gl"\n')
                out = os.path.join(self.dir, name)
                # (fvi-gl: the explicit-memory scheme steps through the singularity; the default
                # fvi-lobatto3's Newton fails there instead, also exit 1.)
                # --quiet: no summary, but the failure is one line on stderr.
                r = run("run", path, "--out", out + "-quiet", "--no-plot", "--quiet")
                self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
                self.assertEqual(r.stdout, "")
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
                self.assertIn(f"fracvi run: {name}: inaccurate: ", r.stderr)
                r = run("run", path, "--out", out, "--no-plot")
                self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
                self.assertIn("status            inaccurate: ", r.stdout)
                with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                    summary = json.load(f)
                self.assertEqual(summary["status"], "inaccurate")
                for needle in ("energy balance error |E_k + W_k - E_0| reached ",
                               "more than 0.5 x the energy scale", " at step "):
                    self.assertIn(needle, summary["message"])
                self.assertEqual(summary["steps"], steps)
                self.assertGreater(summary["max_balance_error"], 1.0)
                with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
                    self.assertEqual(len(f.readlines()), steps + 2)
                # Negative control: the same problem stopped before the singularity.
                r = run("run", path, "--out", out + "-safe", "--no-plot", "--quiet",
                        "--set", f"time.end={safe_end}", "--set", "time.steps=3000")
                self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_integers_are_read_exactly_or_refused(self):
        # 10^17 and 2^60 are doubles: read exactly (10^17 used to run as R = 6.95e-310); 2^53 + 1
        # is not: refused naming the key, the value and the rule (it used to pass the sign check).
        out = os.path.join(self.dir, "exact")
        r = run("run", "--out", out, "--no-plot", "--quiet", "--set", "time.steps=100",
                "--set", "time.end=1", "--set", "model.damping=100000000000000000",
                "--set", "model.mass=1152921504606846976")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            model = json.load(f)["problem"]["model"]
        self.assertEqual(model["damping"], 1e17)
        self.assertEqual(model["mass"], 2.0**60)
        for key, value in (("damping", "-9007199254740993"), ("mass", "9007199254740993")):
            with self.subTest(key):
                line = {"damping": "damping = [[0.2, 0.05], [0.05, 0.1]]",
                        "mass": "mass = [[2.0, 0.5], [0.5, 1.0]]"}[key]
                self.assertIn(line, PROBLEM)
                path = self.write(PROBLEM.replace(line, f"{key} = {value}"))
                never = os.path.join(self.dir, "never")
                r = run("run", path, "--out", never)
                self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
                self.assertEqual(r.stdout, "")
                lines = r.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, r.stderr)
                self.assertIn(f"p.toml: model.{key} = {value}: integers beyond 2^53 are not "
                              "exactly representable as a double; write it as a float, e.g. "
                              f"{value[:-15]}.{value[-15:]}e15", lines[0])
                self.assertFalse(os.path.exists(never))

    BAD = [
        ("unknown key", ("damping =", "dampng ="), ["model.dampng", "did you mean 'damping'"]),
        ("unknown section", ("[time]", "[timing]"), ["timing", "unknown"]),
        ("wrong type", ("alpha = 0.5", "alpha = \"half\""), ["model.alpha", "number"]),
        ("missing field", ("end = 5.0", ""), ["time.end", "missing"]),
        ("both steps", ("steps = 500", "steps = 500\nstep = 0.01"), ["time.steps", "both"]),
        ("neither", ("steps = 500", ""), ["time.steps", "missing"]),
        ("dim mismatch", ("position = [1.0, 0.0]", "position = [1.0]"), ["initial.position"]),
        ("M not SPD", ("mass = [[2.0, 0.5], [0.5, 1.0]]", "mass = [[1.0, 2.0], [2.0, 1.0]]"),
         ["model.mass", "positive definite"]),
        ("R not PSD", ("damping = [[0.2, 0.05], [0.05, 0.1]]", "damping = [[0.2, 0.5], [0.5, 0.1]]"),
         ["model.damping", "semidefinite"]),
        ("alpha", ("alpha = 0.5", "alpha = 1.2"), ["model.alpha = 1.2", "[0, 1]"]),
        ("steps", ("steps = 500", "steps = -4"), ["time.steps = -4", "positive"]),
        ("expression", ("- 0.2*x1*x2", "- 0.2*x1*x3"), ["model.potential", "x3", "column"]),
        ("ill-posed", ("alpha = 0.5", "alpha = 0.8\nconvention = \"riemann-liouville\""),
         ["ill-posed", "caputo"]),
    ]

    def test_bad_problem_files(self):
        for what, (old, new), needles in self.BAD:
            with self.subTest(what):
                self.assertIn(old, PROBLEM)
                path = self.write(PROBLEM.replace(old, new, 1))
                out = os.path.join(self.dir, "never")
                r = run("run", path, "--out", out)
                self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
                self.assertEqual(r.stdout, "")
                lines = r.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, r.stderr)
                self.assertIn("p.toml", lines[0])
                for needle in needles:
                    self.assertIn(needle, lines[0])
                self.assertFalse(os.path.exists(out), "output directory created on bad input")

    def test_missing_file_and_bad_override(self):
        r = run("run", os.path.join(self.dir, "nope.toml"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("cannot open", r.stderr)
        r = run("run", "--set", "model.alpha=2")
        self.assertEqual(r.returncode, 2)
        self.assertIn("model.alpha = 2", r.stderr)

    def test_set_goes_through_the_schema(self):
        # An unknown key: one line naming --set, the key, the nearest valid key and the valid keys;
        # a value of the wrong type: the field, the value and the rule. Exit 2, no output.
        out = os.path.join(self.dir, "set-out")
        cases = [
            (["method.newton_tolerence=1e-9"],
             "fracvi run: <built-in problem>: --set method.newton_tolerence: unknown key (did you "
             "mean 'newton_tolerance'?); valid in [method]: scheme, newton_tolerance, "
             "newton_max_iterations, history, history_tolerance, abs_tolerance, rel_tolerance, "
             "linear_solver, load, split, error_estimate, mirror, tolerance, max_steps, threads, "
             "flush_subnormals"),
            (["output.stride=2"],
             "fracvi run: <built-in problem>: --set output.stride: unknown key; valid in [output]: "
             "every, checkpoint_every, format, times"),
            (["solver.kind=lu"],
             "fracvi run: <built-in problem>: --set solver.kind: unknown section [solver]; valid "
             "sections: [model], [model.chain], [initial], [boundary], [time], [method], "
             "[output], [reference], [events]"),
            (["time.steps=many"],
             "fracvi run: <built-in problem>: time.steps = 'many' must be an integer, got a "
             "string"),
            (["output.every=2.5"],
             "fracvi run: <built-in problem>: output.every = 2.5 must be an integer, got a number"),
        ]
        for assignments, expected in cases:
            args = [a for assignment in assignments for a in ("--set", assignment)]
            r = run("run", *args, "--out", out, "--no-plot")
            self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
            self.assertEqual(r.stdout, "")
            self.assertEqual(r.stderr, expected + "\n")
            self.assertFalse(os.path.exists(out), "output directory created on bad input")


class Compare(unittest.TestCase):
    """fracvi compare: the table, the energy track and the plots; bad input exit 2."""
    OSCILLATOR = ('name = "osc"\n[model]\ndim = 1\nmass = 1.0\ndamping = 0.25\nalpha = 0.5\n'
                  'potential = "x1^2/2"\n[initial]\nposition = [1.0]\nvelocity = [0.5]\n'
                  '[time]\nend = 16.0\nsteps = 100\n[reference]\nposition = '
                  '["exp(-t/8)*(cos(w*t) + 0.625/w*sin(w*t))"]\n').replace("w", "sqrt(1 - 1/64)")

    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.dir = self._tmp.name
        self.addCleanup(self._tmp.cleanup)
        self.path = os.path.join(self.dir, "osc.toml")
        with open(self.path, "w", encoding="utf-8") as f:
            f.write(self.OSCILLATOR)

    def test_table_energy_track_and_plots(self):
        out = os.path.join(self.dir, "cmp")
        r = run("compare", self.path, "--schemes", "fvi-midpoint,euler-explicit,fvi-lobatto3",
                "--steps", "50,100,200", "--out", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("reference: exact solution", r.stdout)
        self.assertIn("9 runs: 7 succeeded, 1 failed, 1 not applicable", r.stdout)
        with open(os.path.join(out, "compare.csv"), newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([(x["scheme"], int(x["steps"])) for x in rows],
                         [(s, n) for s in ("fvi-midpoint", "euler-explicit", "fvi-lobatto3")
                          for n in (50, 100, 200)])
        refused = rows[3]
        self.assertEqual(refused["status"], "not applicable")
        self.assertIn("stability bound of euler-explicit", refused["message"])
        self.assertTrue(math.isnan(float(refused["max_error"])))
        self.assertEqual(rows[4]["status"], "inaccurate")  # h = 0.16: forward Euler's balance
        midpoint = [float(x["max_error"]) for x in rows[:3]]
        for coarse, fine in zip(midpoint, midpoint[1:]):  # second order: 4x per halving
            self.assertAlmostEqual(coarse / fine, 4.0, delta=0.3)
        self.assertEqual(rows[0]["declared_order"], "2")
        with open(os.path.join(out, "energy.csv"), newline="", encoding="utf-8") as f:
            energy = list(csv.DictReader(f))
        self.assertEqual(len(energy), 101)  # the middle N, 100 steps
        self.assertIn("energy:fvi-midpoint", energy[0])
        self.assertAlmostEqual(float(energy[0]["reference_energy"]), 0.5 + 0.125, delta=1e-15)
        with open(os.path.join(out, "compare.json"), encoding="utf-8") as f:
            meta = json.load(f)
        self.assertEqual(meta["energy_steps"], 100)
        self.assertEqual(meta["schemes"], ["fvi-midpoint", "euler-explicit", "fvi-lobatto3"])
        for png in ("work_precision.png", "error_vs_steps.png", "energy_tracking.png"):
            self.assertGreater(os.path.getsize(os.path.join(out, png)), 10000, png)

    def test_bad_input(self):
        cases = [
            (("--steps", "100,50"), "step counts must increase"),
            (("--steps", "100", "--schemes", "fvi-gll"), '"fvi-gll" is not a known scheme'),
            (("--steps", "100,300", "--reference-steps", "1000"), "(300 is not a divisor)"),
            (("--steps", "100,200", "--energy-steps", "150"), "must be one of the --steps"),
        ]
        for args, says in cases:
            out = os.path.join(self.dir, "bad")
            r = run("compare", self.path, "--out", out, "--no-plot", *args)
            self.assertEqual(r.returncode, 2, (args, r.stdout, r.stderr))
            self.assertIn(says, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertFalse(os.path.exists(out), "the refused comparison left a directory")


class Methods(unittest.TestCase):
    """The method registry reaches the CLI, and docs/schemes.md is its table."""

    def registry(self):
        r = run("methods", "--json")
        self.assertEqual(r.returncode, 0, r.stderr)
        return json.loads(r.stdout)

    def test_registry_json(self):
        rows = self.registry()
        names = [row["name"] for row in rows]
        self.assertEqual(names[:2], ["fvi-gl", "fvi-bdf2"])
        for row in rows:
            for key in ("order", "stages", "variational", "mirror", "exact_balance", "fast_history",
                        "adaptive", "applies_to", "stability", "summary", "reference"):
                self.assertIn(key, row)
        r = run("methods")
        self.assertEqual(r.returncode, 0, r.stderr)
        for name in names:
            self.assertIn(name, r.stdout)

    def test_docs_table_matches_the_registry(self):
        docs = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "schemes.md")
        with open(docs, encoding="utf-8") as f:
            lines = [l for l in f.read().split("<!-- registry -->")[1].splitlines()
                     if l.startswith("| `")]
        table = []
        for line in lines:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            table.append(cells)
        expected = [[f"`{row['name']}`", row["order"], str(row["stages"]),
                     "yes" if row["variational"] else "no", "yes" if row["mirror"] else "no",
                     "yes" if row["exact_balance"] else "no",
                     "yes" if row["fast_history"] else "no", row["applies_to"],
                     f"`{row['stability']}`"] for row in self.registry()]
        self.assertEqual(table, expected, "docs/schemes.md is out of date: regenerate its table "
                                          "from `fracvi methods --json`")

    def test_scheme_reaches_run_and_convergence(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "bdf2")
            r = run("run", "--out", out, "--no-plot", "--quiet", "--set", "method.scheme=fvi-bdf2",
                    "--set", "time.steps=600", "--set", "time.end=6")
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                summary = json.load(f)
            self.assertEqual(summary["method"], "fvi-bdf2")
            self.assertEqual(summary["declared_order"], 2)
            self.assertEqual(summary["problem"]["method"]["scheme"], "fvi-bdf2")
            out_gl = os.path.join(tmp, "gl")
            r = run("run", "--out", out_gl, "--no-plot", "--quiet", "--set", "time.steps=600",
                    "--set", "time.end=6")
            with open(os.path.join(out_gl, "summary.json"), encoding="utf-8") as f:
                self.assertNotEqual(json.load(f)["final_position"], summary["final_position"])

    def test_convergence_uses_the_scheme(self):
        # Damped oscillator x'' + 0.5 x' + x = 0, x(0) = 1, x'(0) = 0 (alpha = 1/2), closed form.
        w = "sqrt(15/16)"
        exact = f"exp(-t/4)*(cos({w}*t) + sin({w}*t)/(4*{w}))"
        text = ('name = "osc"\n[model]\ndim = 1\nmass = 1.0\ndamping = 0.5\nalpha = 0.5\n'
                'potential = "x1^2/2"\n[initial]\nposition = [1.0]\nvelocity = [0.0]\n'
                '[time]\nend = 10.0\nsteps = 100\n[method]\nscheme = "fvi-bdf2"\n')
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "osc.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            out = os.path.join(tmp, "conv")
            r = run("convergence", path, "--steps", "200,400,800,1600", "--reference", exact,
                    "--out", out, "--no-plot")
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.assertIn("scheme fvi-bdf2, declared order 2", r.stdout)
            with open(os.path.join(out, "convergence.json"), encoding="utf-8") as f:
                self.assertEqual(json.load(f)["method"], "fvi-bdf2")  # was always "fvi-gl"
            fitted = float(r.stdout.split("least-squares order:")[1].split()[0])
            self.assertGreater(fitted, 1.9, r.stdout)

    def test_unknown_scheme(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "never")
            r = run("run", "--out", out, "--set", "method.scheme=fvi-bdf3")
            self.assertEqual(r.returncode, 2)
            self.assertEqual(r.stdout, "")
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            for needle in ("method.scheme", "fvi-bdf3", "fvi-gl", "fvi-bdf2"):
                self.assertIn(needle, r.stderr)
            self.assertFalse(os.path.exists(out))

    def test_beyond_the_stability_bound_is_refused(self):
        # Overdamped oscillator, alpha = 1/2: fvi-gl needs R h < 2 (here R h = 20 * 0.2 = 4).
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "never")
            r = run("run", "--out", out, "--set", "model.alpha=0.5", "--set", "model.damping=20",
                    "--set", "time.end=6", "--set", "time.steps=30", "--set",
                    "method.scheme=fvi-gl")
            self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
            self.assertEqual(r.stdout, "")
            for needle in ("time.steps = 30", "stability bound of fvi-gl", "h < 0.1",
                           "time.steps >= 61"):
                self.assertIn(needle, r.stderr)
            self.assertFalse(os.path.exists(out))


    def test_auto_takes_the_first_scheme_that_applies_and_is_stable(self):
        # "auto" (the default): fvi-lobatto3, else fvi-midpoint, else fvi-bdf2, else fvi-gl
        # (docs/comparison.md). Stiff U = 50 x^2 at h = 0.6: h^2 lambda = 36 is beyond
        # fvi-lobatto3's 8, so fvi-midpoint (stable for every h); 2alpha = 2: neither applies,
        # fvi-bdf2 needs lambda(R) 4 h^0 < 1 (R = 0.2 yes, R = 0.25 no: then fvi-gl, R < M).
        # With [output] checkpoint_every only schemes that can write checkpoints are candidates.
        cases = ((("model.damping=0.3",), "fvi-lobatto3"),
                 (("model.potential=50*x1^2", "time.end=6", "time.steps=10"), "fvi-midpoint"),
                 (("model.alpha=1", "model.damping=0.2"), "fvi-bdf2"),
                 (("model.alpha=1", "model.damping=0.25"), "fvi-gl"),
                 # checkpoints: every candidate can write them, so the choice is the same
                 (("output.checkpoint_every=100",), "fvi-lobatto3"),
                 (("output.checkpoint_every=100", "model.potential=50*x1^2", "time.end=6",
                   "time.steps=10"), "fvi-midpoint"))
        with tempfile.TemporaryDirectory() as tmp:
            for settings, expected in cases:
                out = os.path.join(tmp, expected)
                args = [a for s in settings + ("time.end=6",) for a in ("--set", s)]
                r = run("run", "--out", out, "--no-plot", "--quiet", *args)
                self.assertEqual(r.returncode, 0, (settings, r.stderr))
                with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                    summary = json.load(f)
                self.assertEqual(summary["method"], expected, settings)
                self.assertEqual(summary["problem"]["method"]["scheme"], "auto")


class Robustness(unittest.TestCase):
    """Inputs that used to abort (exit 134) or lose a finished run: each is now one line on stderr
    with the README's exit status (2: the input, found before step 1, no output directory; 1: the
    results could not be written), and no temporary file is left behind."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        for root, dirs, _ in os.walk(self.dir):
            for d in dirs:
                os.chmod(os.path.join(root, d), 0o755)
        self.tmp.cleanup()

    def refused(self, needles, *args, status=2):
        r = run(*args)
        self.assertEqual(r.returncode, status, r.stdout + r.stderr)
        self.assertEqual(r.stdout, "")
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        for needle in needles:
            self.assertIn(needle, lines[0])
        return lines[0]

    def test_output_directory_is_checked_before_step_one(self):
        a_file = os.path.join(self.dir, "a-file")
        with open(a_file, "w", encoding="utf-8") as f:
            f.write("not a directory\n")
        cases = [
            ("a file", a_file, ["--out " + a_file, "exists and is not a directory"]),
            ("under a file", os.path.join(a_file, "out"), ["cannot create", "Not a directory"]),
            ("name too long", os.path.join(self.dir, "n" * 300), ["File name too long"]),
            ("not creatable", "/proc/fracvi-cli-test/out", ["cannot create the directory"]),
        ]
        if os.geteuid() != 0:  # root writes into a read-only directory anyway
            read_only = os.path.join(self.dir, "read-only")
            os.mkdir(read_only, 0o555)
            cases.append(("read-only", os.path.join(read_only, "out"), ["Permission denied"]))
        for what, out, needles in cases:
            with self.subTest(what):
                # 10^6 steps would take seconds: the refusal comes before the integration.
                self.refused(["fracvi run: "] + needles, "run", "--out", out, "--no-plot",
                             "--set", "time.steps=1000000")
                self.refused(["fracvi convergence: "] + needles, "convergence",
                             os.path.join(FRACVI_EXAMPLES, "damped_pendulum.toml"), "--steps",
                             "100,200", "--out", out, "--no-plot")

    def test_too_small_a_step_and_too_many_steps(self):
        path = os.path.join(self.dir, "p.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(PROBLEM.replace("steps = 500", "step = 1e-300"))
        out = os.path.join(self.dir, "never")
        # (end - start)/step = 5e300 used to overflow the conversion to an integer step count.
        self.refused(["p.toml: time.step = 1e-300 divides [0, 5] into 5e+300 steps",
                      "more than the limit of 2000000000"], "run", path, "--out", out)
        self.refused(["time.steps = 2000000001 is more than the limit of 2000000000"],
                     "run", "--out", out, "--set", "time.steps=2000000001")
        self.assertFalse(os.path.exists(out))

    def test_memory_is_estimated_before_allocating(self):
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        out = os.path.join(self.dir, "never")
        # The stored trajectory: (N + 1) rows of 16 d + 40 bytes. steps = 2e9 (d = 1) is 112 GB;
        # it used to be accepted and then die in std::bad_alloc.
        needed = (2_000_000_000 + 1) * (16 + 40)
        if needed > memory:
            self.refused(["time.steps = 2000000000 with output.every = 1: the stored "
                          "trajectory", "needs 112 GB, more than this machine's memory",
                          "store fewer states with [output] every = n (n >= "],
                         "run", "--out", out, "--set", "time.steps=2000000000")
        # model.dim = 10^12: 32 TB for two states, refused before any vector is allocated.
        self.refused(["model.dim = 1000000000000: the first and last state alone (x and v) "
                      "need 32 TB, more than this machine's memory"],
                     "run", "--out", out, "--set", "model.dim=1000000000000")

    def test_integrable_endpoint_singularity_in_derivative(self):
        # Issue 14 item 6: D^(1/2) log t was -inf with exit 0. Closed form (left, from 0):
        # t^(-a)/Gamma(1-a) (log t + psi(1) - psi(1-a)); the right side mirrored.
        exact = "t^(-0.5)/sqrt(pi)*(log(t) - 0.5772156649015329 + 1.9635100260214235)"
        r = run("derivative", "--alpha", "0.5", "--f", "log(t)", "--a", "0", "--b", "1",
                "--t", "0.1,0.5,1", "--exact", exact)
        self.assertEqual(r.returncode, 0, r.stderr)
        for line in r.stdout.strip().splitlines():
            t, value, reference, difference = map(float, line.split())
            self.assertLess(abs(difference), 1e-13 * abs(reference), line)
        r = run("derivative", "--alpha", "0.5", "--side", "right", "--f", "log(1-t)", "--a", "0",
                "--b", "1", "--t", "0.5", "--exact",
                "(1-t)^(-0.5)/sqrt(pi)*(log(1-t) - 0.5772156649015329 + 1.9635100260214235)")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertLess(abs(float(r.stdout.split()[3])), 1e-13)

    def test_singular_function_in_derivative(self):
        # Not integrable at the terminal: refused, not the number the quadrature stopped at.
        self.refused(["fracvi derivative: --f = \"1/t\": the quadrature of D^alpha f(0.5) failed",
                      "f is not integrable at the terminal 0"],
                     "derivative", "--alpha", "0.5", "--f", "1/t", "--a", "0", "--b", "1",
                     "--t", "0.5")

    def test_write_failure_after_the_run_leaves_no_temporary(self):
        import resource
        import signal

        def small_files():  # files beyond 4 kB cannot be written (EFBIG instead of SIGXFSZ)
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

        out = os.path.join(self.dir, "full")
        r = subprocess.run([FRACVI, "run", "--out", out, "--no-plot", "--quiet"],
                           capture_output=True, text=True, timeout=120, preexec_fn=small_files)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertIn("fracvi run: the results could not be written to " + out, lines[0])
        self.assertRegex(lines[0], r"trajectory.csv.tmp.[0-9]+.[0-9]+: File too large")
        self.assertEqual(os.listdir(out), [])  # no .tmp, no probe file
        # Negative control: the same run without the limit writes everything.
        r = run("run", "--out", out, "--no-plot", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(out)), ["problem.toml", "summary.json",
                                                   "trajectory.csv"])


def without_wall_times(value):
    """summary.json without the wall-clock fields and the history's thread use (the only ones a
    resumed run may change: its pushes are counted from the resume)."""
    if isinstance(value, dict):
        return {k: without_wall_times(v) for k, v in value.items()
                if "wall" not in k and k != "history_threads"}
    if isinstance(value, list):
        return [without_wall_times(v) for v in value]
    return value


class Interrupts(unittest.TestCase):
    """SIGINT, SIGTERM and SIGHUP stop `fracvi run` at the next step with everything written
    (status interrupted, exit 130); [output] checkpoint_every and --resume continue a run
    bit-for-bit (issue 14, item 5)."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    @staticmethod
    def problem(steps, end, scheme="fvi-gl", history="fast", estimate="none", every=1,
                checkpoint=0):
        """The built-in problem (the forced fractional Duffing oscillator) with these values."""
        values = {"time.steps": steps, "time.end": end, "method.scheme": scheme,
                  "method.history": history, "method.error_estimate": estimate,
                  "output.every": every, "output.checkpoint_every": checkpoint}
        return [arg for key, value in values.items() for arg in ("--set", f"{key}={value}")]

    @staticmethod
    def wait_for(path, process, timeout=60.0):
        """Waits until `path` exists (while the process runs)."""
        deadline = time.monotonic() + timeout
        while not os.path.exists(path):
            if process.poll() is not None:
                raise AssertionError(f"the run ended ({process.returncode}) before {path} "
                                     f"appeared: {process.stderr.read()}")
            if time.monotonic() > deadline:
                process.kill()
                raise AssertionError(f"{path} did not appear within {timeout} s")
            time.sleep(0.002)

    def interrupted(self, problem, out, sig, wait_file, *extra):
        """Starts `fracvi run`, sends `sig` once `wait_file` (in `out`) exists; returns
        (returncode, stdout, stderr)."""
        process = subprocess.Popen([FRACVI, "run", *problem, "--out", out, "--no-plot", *extra],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.wait_for(os.path.join(out, wait_file), process)
        process.send_signal(sig)
        try:
            stdout, stderr = process.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            process.kill()
            raise
        return process.returncode, stdout, stderr

    def load(self, out, name):
        with open(os.path.join(out, name), encoding="utf-8") as f:
            return json.load(f) if name.endswith(".json") else f.read()

    def test_signals_stop_the_run_and_write_everything_so_far(self):
        # 2·10^7 steps would take about a minute: the signal comes once the run holds its output
        # directory (.fracvi.lock: the integrator is set up, step 1 is next) and ends it at once.
        steps, every = 20_000_000, 1000
        problem = self.problem(steps, 2000.0, every=every)
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            with self.subTest(signal=sig.name):
                out = os.path.join(self.dir, "out-" + sig.name)
                start = time.monotonic()
                code, stdout, stderr = self.interrupted(problem, out, sig, ".fracvi.lock")
                self.assertLess(time.monotonic() - start, 30.0)
                self.assertEqual(code, 130, stdout + stderr)
                self.assertIn("status            interrupted: interrupted after step", stdout)
                summary = self.load(out, "summary.json")
                self.assertEqual(summary["status"], "interrupted")
                self.assertIn("interrupted after step", summary["message"])
                done = summary["steps"]
                self.assertLess(done, steps)
                with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
                    rows = list(csv.reader(f))[1:]
                # Rows 0, every, 2·every, … and the last completed step.
                self.assertEqual(len(rows), done // every + 1 + (1 if done % every else 0))
                self.assertEqual(float(rows[-1][0]), summary["final_time"])
                self.assertTrue(all(math.isfinite(float(v)) for v in rows[-1]))
                self.assertTrue(os.path.exists(os.path.join(out, "problem.toml")))
                self.assertEqual([f for f in os.listdir(out) if ".tmp" in f], [])

    def test_quiet_interrupted_run_prints_its_one_line(self):
        problem = self.problem(20_000_000, 2000.0, every=1000)
        out = os.path.join(self.dir, "quiet")
        code, stdout, stderr = self.interrupted(problem, out, signal.SIGTERM, ".fracvi.lock",
                                                "--quiet")
        self.assertEqual(code, 130)
        self.assertEqual(stdout, "")
        lines = stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, stderr)
        self.assertIn("fracvi run: fractional-duffing: interrupted: interrupted after step",
                      lines[0])

    def test_resume_continues_bit_for_bit(self):
        # Each case: an uninterrupted run, and one stopped after its first checkpoint — by SIGINT
        # (its own checkpoint at the step the signal arrived) or by SIGKILL (nothing but the
        # periodic checkpoint survives) — then resumed. trajectory.csv and summary.json (but its
        # wall times) must be identical, byte for byte.
        cases = [
            ("fvi-gl", "fast", 1_000_000, 100.0, 100_000, 7, "none", signal.SIGINT),
            ("fvi-gl", "direct", 40_000, 40.0, 2_000, 1, "richardson", signal.SIGKILL),
            ("fvi-bdf2", "fast", 1_000_000, 100.0, 100_000, 1, "none", signal.SIGINT),
            # A block history and simplified Newton's kept stage matrix; two baselines.
            ("fvi-lobatto3", "fast", 400_000, 100.0, 40_000, 3, "none", signal.SIGINT),
            ("lda-midpoint", "direct", 40_000, 40.0, 2_000, 1, "none", signal.SIGKILL),
            ("euler-implicit", "fast", 400_000, 100.0, 40_000, 1, "none", signal.SIGINT),
        ]
        for scheme, history, steps, end, checkpoint, every, estimate, sig in cases:
            with self.subTest(scheme=scheme, history=history, signal=sig.name):
                name = f"{scheme}-{history}"
                problem = self.problem(steps, end, scheme=scheme, history=history,
                                       estimate=estimate, every=every, checkpoint=checkpoint)
                reference = os.path.join(self.dir, name + "-whole")
                r = run("run", *problem, "--out", reference, "--no-plot", "--quiet")
                self.assertEqual(r.returncode, 0, r.stderr)
                # A finished run removes its checkpoint (nothing to resume).
                self.assertFalse(os.path.exists(os.path.join(reference, "checkpoint.fracvi")))

                stopped = os.path.join(self.dir, name + "-stopped")
                code, stdout, stderr = self.interrupted(problem, stopped, sig,
                                                        "checkpoint.fracvi")
                self.assertEqual(code, 130 if sig == signal.SIGINT else -signal.SIGKILL,
                                 stdout + stderr)
                if sig == signal.SIGINT:
                    self.assertIn("resume            fracvi run --resume " + stopped, stdout)
                    self.assertEqual(self.load(stopped, "summary.json")["status"],
                                     "interrupted")
                r = run("run", "--resume", stopped, "--no-plot")
                self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
                self.assertIn("status            success", r.stdout)
                self.assertEqual(self.load(stopped, "trajectory.csv"),
                                 self.load(reference, "trajectory.csv"))
                self.assertEqual(without_wall_times(self.load(stopped, "summary.json")),
                                 without_wall_times(self.load(reference, "summary.json")))
                self.assertFalse(os.path.exists(os.path.join(stopped, "checkpoint.fracvi")))

    def test_a_signal_during_the_mirror_check_stops_it(self):
        # The mirror check (the backward run after the last step, as long as the forward run)
        # polls the signal flag too. The checkpoint after step N - 1 says the forward run is one
        # step from its end: a signal sent then arrives during the mirror check (or, on a loaded
        # machine, just before step N: then the run stops there, and the test tries again).
        # method.threads = 1 keeps the mirror run after the run: on two cores it runs alongside
        # and ends with it (the interrupted wait for it: tests/integrate/mirror_test.cpp).
        steps = 20_000
        problem = self.problem(steps, 20.0, history="direct", checkpoint=steps - 1)
        problem += ["--set", "method.threads=1"]
        for attempt in range(5):
            out = os.path.join(self.dir, f"mirror-{attempt}")
            code, stdout, stderr = self.interrupted(problem, out, signal.SIGINT,
                                                    "checkpoint.fracvi")
            self.assertEqual(code, 130, stdout + stderr)
            summary = self.load(out, "summary.json")
            self.assertEqual(summary["status"], "interrupted")
            if "mirror check" in summary["message"]:
                break
            self.assertIn(f"interrupted after step {steps - 1} of {steps}", summary["message"])
        else:
            self.fail("no signal arrived during the mirror check in 5 attempts")
        self.assertIn("status            interrupted: interrupted during the mirror check, after "
                      f"all {steps} steps", stdout)
        self.assertEqual(summary["steps"], steps)
        self.assertIsNone(summary["mirror_error"])
        trajectory = self.load(out, "trajectory.csv")
        self.assertEqual(len(trajectory.splitlines()), steps + 2)  # header, steps 0 … N
        # The checkpoint is kept, and --resume finishes the run (the mirror check included) with
        # the same trajectory.
        self.assertIn("resume            fracvi run --resume " + out, stdout)
        r = run("run", "--resume", out, "--no-plot", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(self.load(out, "trajectory.csv"), trajectory)
        summary = self.load(out, "summary.json")
        self.assertEqual(summary["status"], "success")
        self.assertLess(summary["mirror_error"], 1e-9)

    def test_stale_temporaries_of_dead_runs_are_removed(self):
        # A run killed while writing a file (SIGKILL in write_file_atomically) leaves
        # <file>.tmp.<pid>.<n>, or its write probe: the next run that claims the directory — a
        # --resume or a new run — removes those of processes that are gone, and keeps those of
        # live ones.
        dead = subprocess.Popen(["true"])
        dead.wait()  # its pid names no process now
        alive = os.getpid()
        problem = self.problem(20_000, 20.0, history="direct", checkpoint=1_000)
        stopped = os.path.join(self.dir, "killed")
        code, stdout, stderr = self.interrupted(problem, stopped, signal.SIGKILL,
                                                "checkpoint.fracvi")
        self.assertEqual(code, -signal.SIGKILL, stdout + stderr)
        stale = [f"checkpoint.fracvi.tmp.{dead.pid}.7", f"problem.toml.tmp.{dead.pid}.0",
                 f".fracvi-write-test-{dead.pid}"]
        kept = [f"checkpoint.fracvi.tmp.{alive}.3", f"notes.tmp.{dead.pid}",  # not ours
                f"notes.tmp.{dead.pid}.x", f"notes.tmp.-{dead.pid}.1"]
        for name in stale + kept:
            with open(os.path.join(stopped, name), "wb") as f:
                f.write(b"half a checkpoint")
        r = run("run", "--resume", stopped, "--no-plot", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(f for f in os.listdir(stopped) if ".tmp" in f or "test" in f),
                         sorted(kept))
        # A new run into a directory with a dead run's temporaries.
        fresh = os.path.join(self.dir, "fresh")
        os.makedirs(fresh)
        for name in stale:
            with open(os.path.join(fresh, name), "wb") as f:
                f.write(b"half a trajectory")
        r = run("run", *self.problem(100, 1.0), "--out", fresh, "--no-plot", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(fresh)),
                         ["problem.toml", "summary.json", "trajectory.csv"])

    def refused(self, needles, *args):
        r = run(*args)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertEqual(r.stdout, "")
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        for needle in needles:
            self.assertIn(needle, lines[0])

    def test_resume_refuses_a_changed_missing_or_corrupt_checkpoint(self):
        problem = self.problem(1_000_000, 100.0, checkpoint=100_000)
        stopped = os.path.join(self.dir, "refuse")
        code, _, stderr = self.interrupted(problem, stopped, signal.SIGINT, "checkpoint.fracvi")
        self.assertEqual(code, 130, stderr)
        checkpoint = os.path.join(stopped, "checkpoint.fracvi")
        with open(checkpoint, "rb") as f:
            saved = f.read()
        toml = self.load(stopped, "problem.toml")

        # The problem in the directory changed: refused, naming the line.
        with open(os.path.join(stopped, "problem.toml"), "w", encoding="utf-8") as f:
            f.write(toml.replace("damping = 0.25", "damping = 0.5"))
        self.refused(["fracvi run: --resume ", "problem.toml: the problem changed since the "
                      "checkpoint was taken", "`damping = 0.25` when the checkpoint was taken, "
                      "`damping = 0.5` now", "resume refused"], "run", "--resume", stopped)
        with open(os.path.join(stopped, "problem.toml"), "w", encoding="utf-8") as f:
            f.write(toml)

        # Altered, truncated, missing.
        altered = bytearray(saved)
        altered[-5] ^= 0x40
        with open(checkpoint, "wb") as f:
            f.write(bytes(altered))
        self.refused(["checkpoint.fracvi: corrupt checkpoint: the state's checksum does not "
                      "match"], "run", "--resume", stopped)
        with open(checkpoint, "wb") as f:
            f.write(saved[:len(saved) // 2])
        self.refused(["checkpoint.fracvi: corrupt checkpoint: the state has"],
                     "run", "--resume", stopped)
        os.remove(checkpoint)
        self.refused(["checkpoint.fracvi: no checkpoint"], "run", "--resume", stopped)
        self.refused(["--resume", "not a directory"], "run", "--resume",
                     os.path.join(self.dir, "nowhere"))
        # A resumed run continues its own directory's problem.
        self.refused(["give no problem file, --set or --out with --resume"],
                     "run", *problem, "--resume", stopped)

    def test_checkpoint_every_is_validated_before_step_one(self):
        self.refused(["output.checkpoint_every = -5 must be >= 0"], "run",
                     *self.problem(1000, 1.0, checkpoint=-5), "--out",
                     os.path.join(self.dir, "neg"))
        self.refused(["output.checkpoint_every = 10 is not available for method.scheme = "
                      "\"dopri5\"", "its stepper cannot save its state yet (schemes with "
                      "checkpoints: fvi-gl, fvi-bdf2, fvi-midpoint, fvi-lobatto2, fvi-lobatto3, "
                      "fvi-lobatto4, euler-explicit, euler-implicit, lda-midpoint, "
                      "conformal-strang); set it to 0"],
                     "run", *self.problem(1000, 1.0, scheme="dopri5", history="auto",
                                          checkpoint=10),
                     "--out", os.path.join(self.dir, "mid"))
        self.refused(["output.checkpoint_every", "cannot be combined with method.tolerance"],
                     "run", *self.problem(1000, 1.0, estimate="richardson", checkpoint=10),
                     "--set", "method.tolerance=1e-3", "--out", os.path.join(self.dir, "tol"))
        self.assertFalse(os.path.exists(os.path.join(self.dir, "neg")))


class Help(unittest.TestCase):
    def test_help(self):
        for args in (["--help"], ["run", "--help"], ["weights", "--help"],
                     ["derivative", "--help"]):
            r = run(*args)
            self.assertEqual(r.returncode, 0, args)
            self.assertIn("Usage", r.stdout)


if __name__ == "__main__":
    FRACVI = sys.argv.pop(1)
    unittest.main(verbosity=2)
