"""End-to-end tests of `fracvi sweep` (issue 15): the same table whatever runs the cases (threads
or MPI ranks), nothing lost or run twice across a kill and --resume, failing cases as rows, and the
sweep file's errors.

Run by ctest as: python3 sweep_test.py /path/to/fracvi [MPIRUN]
(MPIRUN is the mpirun of an MPI build, or absent: the MPI test is then skipped and says why.)
"""
import csv
import io
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest

FRACVI = None
MPIRUN = None

EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples",
                       "sweep", "fractional_oscillator.toml")


def grid(steps):
    """The example sweep (the fractional oscillator x'' + R D^(2 alpha) x + x = 0 on [0, 20] over a
    6 x 5 grid of (2 alpha, R)) with `steps` steps."""
    with open(EXAMPLE, encoding="utf-8") as f:
        text = f.read()
    assert "steps = 400\n" in text
    return text.replace("steps = 400\n", f"steps = {steps}\n")


def write(directory, name, text):
    path = os.path.join(directory, name)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
    return path


def sweep(*args, launcher=()):
    return subprocess.run([*launcher, FRACVI, "sweep", *args], capture_output=True, text=True,
                          timeout=300)


def text_of(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def table(out):
    with open(os.path.join(out, "results.csv"), encoding="utf-8", newline="") as f:
        return list(csv.reader(f))


def start_and_wait(file, out, rows, launcher=()):
    """Starts `fracvi sweep FILE --out OUT --jobs 1 --quiet` and returns it once results.csv has
    more than `rows` rows."""
    results = os.path.join(out, "results.csv")
    p = subprocess.Popen([*launcher, FRACVI, "sweep", file, "--out", out, "--jobs", "1",
                          "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and p.poll() is None:
        if os.path.exists(results) and len(text_of(results).splitlines()) > rows + 1:
            break
        time.sleep(0.01)
    return p


def without_wall_time(rows):
    """Every column but wall_seconds, as the text the file holds (bitwise numbers)."""
    column = rows[0].index("wall_seconds")
    return [row[:column] + row[column + 1:] for row in rows]


class SameTable(unittest.TestCase):
    """The numbers of a case do not depend on what ran it: --jobs 1, --jobs 2, MPI ranks."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.file = write(cls.tmp.name, "grid.toml", grid(400))
        cls.reference = os.path.join(cls.tmp.name, "jobs1")
        r = sweep(cls.file, "--out", cls.reference, "--jobs", "1", "--quiet")
        assert r.returncode == 0, r.stderr
        cls.rows = table(cls.reference)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_grid_has_every_case_in_order(self):
        header, rows = self.rows[0], self.rows[1:]
        self.assertEqual(header[:4], ["case", "model.damping_order", "model.damping", "status"])
        self.assertEqual(len(rows), 30)
        self.assertEqual([int(r[0]) for r in rows], list(range(30)))
        # The first parameter varies slowest; the range end points are exact.
        self.assertEqual([r[1] for r in rows[:6]], ["0.2"] * 5 + ["0.52"])
        self.assertEqual([r[2] for r in rows[:5]][0::4], ["0.1", "2.0"])
        self.assertEqual({r[3] for r in rows}, {"success"})
        x1 = header.index("x1")
        self.assertEqual(len({r[x1] for r in rows}), 30)  # 30 different final states

    def test_case_equals_fracvi_run_of_the_same_problem(self):
        # Case 7 is (2 alpha, R) = (0.52, 0.44721359549995798): a plain run with --set.
        with tempfile.TemporaryDirectory() as out:
            problem = write(out, "p.toml", grid(400).split("[sweep]")[0]
                            .replace("[problem.", "[").replace("[problem]\n", ""))
            case = self.rows[8]
            r = subprocess.run([FRACVI, "run", problem, "--out", os.path.join(out, "run"),
                                "--no-plot", "--quiet", "--set", "model.damping_order=0.52",
                                "--set", "model.damping=" + case[2]],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 0, r.stderr)
            with open(os.path.join(out, "run", "trajectory.csv"), encoding="utf-8") as f:
                last = list(csv.DictReader(f))[-1]
        self.assertEqual(case[1], "0.52")
        header = self.rows[0]
        self.assertEqual(case[header.index("x1")], last["x1"])  # the same text: bitwise
        self.assertEqual(case[header.index("v1")], last["v1"])

    def test_two_jobs_give_the_same_table(self):
        out = os.path.join(self.tmp.name, "jobs2")
        r = sweep(self.file, "--out", out, "--jobs", "2", "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(without_wall_time(table(out)), without_wall_time(self.rows))

    def test_three_mpi_ranks_give_the_same_table(self):
        if not MPIRUN:
            self.skipTest("fracvi built without MPI (install libopenmpi-dev and reconfigure)")
        out = os.path.join(self.tmp.name, "mpi3")
        r = sweep(self.file, "--out", out, "--quiet",
                  launcher=(MPIRUN, "-n", "3", "--oversubscribe", "--allow-run-as-root"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertEqual(without_wall_time(table(out)), without_wall_time(self.rows))


class KillAndResume(unittest.TestCase):
    def test_resume_after_kill_runs_each_case_once(self):
        with tempfile.TemporaryDirectory() as tmp:
            # About 0.1 s a case: slow enough to be killed in the middle.
            file = write(tmp, "slow.toml", grid(4000))
            reference = os.path.join(tmp, "reference")
            r = sweep(file, "--out", reference, "--jobs", "2", "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)

            out = os.path.join(tmp, "killed")
            p = start_and_wait(file, out, 4)
            p.send_signal(signal.SIGKILL)
            p.communicate()
            before = table(out)[1:]
            self.assertGreaterEqual(len(before), 5)
            self.assertLess(len(before), 30, "the sweep finished before it was killed")

            # Without --resume the table is never overwritten.
            r = sweep(file, "--out", out, "--quiet")
            self.assertEqual(r.returncode, 2)
            self.assertIn("--resume", r.stderr)

            r = sweep(file, "--out", out, "--jobs", "2", "--resume")
            self.assertEqual(r.returncode, 0, r.stderr)
            after = table(out)
            # Same final table as the uninterrupted sweep, in case order.
            self.assertEqual(without_wall_time(after), without_wall_time(table(reference)))
            # Count: the resume ran exactly the cases without a row, ...
            self.assertIn(f"ran {30 - len(before)} here", r.stdout)
            self.assertIn(f"{len(before)} from earlier runs", r.stdout)
            # ... and the rows written before the kill are kept byte for byte, wall time
            # included: none of those cases ran again.
            kept = {row[0]: row for row in after[1:]}
            for row in before:
                self.assertEqual(kept[row[0]], row)
            self.assertEqual(len(after) - 1, 30)

    def test_ctrl_c_stops_handing_out_cases_and_keeps_the_rows(self):
        with tempfile.TemporaryDirectory() as tmp:
            file = write(tmp, "slow.toml", grid(4000))
            out = os.path.join(tmp, "out")
            p = start_and_wait(file, out, 2)
            p.send_signal(signal.SIGINT)
            _, err = p.communicate(timeout=60)
            self.assertEqual(p.returncode, 130, err)
            self.assertIn("interrupted: continue with --resume", err)
            rows = table(out)[1:]
            self.assertLess(len(rows), 30)
            # The running case finished and was written: rows are whole and in case order.
            self.assertEqual([int(r[0]) for r in rows], list(range(len(rows))))
            self.assertEqual({r[table(out)[0].index("status")] for r in rows}, {"success"})

    def test_killed_mpi_rank_then_resume(self):
        if not MPIRUN:
            self.skipTest("fracvi built without MPI (install libopenmpi-dev and reconfigure)")
        launcher = (MPIRUN, "-n", "3", "--oversubscribe", "--allow-run-as-root")
        with tempfile.TemporaryDirectory() as tmp:
            file = write(tmp, "slow.toml", grid(4000))
            reference = os.path.join(tmp, "reference")
            self.assertEqual(sweep(file, "--out", reference, "--jobs", "2", "--quiet").returncode,
                             0)
            out = os.path.join(tmp, "killed")
            p = start_and_wait(file, out, 4, launcher)
            # A worker rank: a child of mpirun running fracvi that is not rank 0, the one whose
            # environment says OMPI_COMM_WORLD_RANK=1.
            ranks = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True,
                                   text=True).stdout.split()
            worker = None
            for pid in ranks:
                try:
                    with open(f"/proc/{pid}/environ", "rb") as f:
                        if b"OMPI_COMM_WORLD_RANK=1\0" in f.read():
                            worker = int(pid)
                except OSError:
                    pass
            self.assertIsNotNone(worker, f"no rank 1 among {ranks}")
            os.kill(worker, signal.SIGKILL)
            p.communicate(timeout=60)
            self.assertNotEqual(p.returncode, 0)  # the MPI job ends with its rank
            before = table(out)[1:]
            self.assertLess(len(before), 30, "the sweep finished before the rank was killed")
            r = sweep(file, "--out", out, "--resume", launcher=launcher)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.assertIn(f"ran {30 - len(before)} on the MPI ranks", r.stdout)
            after = table(out)
            self.assertEqual(without_wall_time(after), without_wall_time(table(reference)))
            kept = {row[0]: row for row in after[1:]}
            for row in before:
                self.assertEqual(kept[row[0]], row)

    def test_resume_refuses_a_different_sweep(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "out")
            r = sweep(write(tmp, "a.toml", grid(400)), "--out", out, "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)
            r = sweep(write(tmp, "b.toml", grid(401)), "--out", out, "--resume")
            self.assertEqual(r.returncode, 2)
            self.assertIn("different sweep", r.stderr)
            r = sweep(write(tmp, "c.toml", grid(400).replace(
                'save = "final"', 'save = "summary"')), "--out", out,
                "--resume")
            self.assertEqual(r.returncode, 2)
            self.assertIn("other columns", r.stderr)

    def test_torn_last_row_is_dropped_and_rerun(self):
        with tempfile.TemporaryDirectory() as tmp:
            file = write(tmp, "grid.toml", grid(400))
            out = os.path.join(tmp, "out")
            self.assertEqual(sweep(file, "--out", out, "--quiet").returncode, 0)
            full = text_of(os.path.join(out, "results.csv"))
            lines = full.splitlines(keepends=True)
            # Ten whole rows and half of the eleventh, as a crash of the machine could leave.
            with open(os.path.join(out, "results.csv"), "w", encoding="utf-8") as f:
                f.write("".join(lines[:11]) + lines[11][: len(lines[11]) // 2])
            r = sweep(file, "--out", out, "--resume")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("ran 20 here", r.stdout)
            self.assertEqual(without_wall_time(table(out)),
                             without_wall_time(list(csv.reader(io.StringIO(full)))))


FAILURES = """
[problem]
name = "failures"
[problem.model]
dim = 1
mass = 1.0
damping = 0.5
alpha = 0.5
potential = "0.5*x1^2"
[problem.initial]
position = [1.0]
[problem.time]
end = 10.0
steps = 100
[problem.method]
scheme = "fvi-gl"  # the step numbers below are fvi-gl's (the default "auto" takes fvi-lobatto3)

[sweep]
combine = "zip"
[sweep.parameters]
"model.potential" = ["0.5*x1^2", "0.5*x1^2", "0.5*x1^2*sqrt(5 - t)", "10*x1^4"]
"model.alpha" = [0.5, 1.5, 0.5, 0.5]
"method.newton_max_iterations" = [20, 20, 20, 1]
"""


class FailingCases(unittest.TestCase):
    def test_each_failure_is_a_row_and_the_sweep_completes(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "out")
            r = sweep(write(tmp, "failures.toml", FAILURES), "--out", out, "--jobs", "2")
            self.assertEqual(r.returncode, 1, r.stderr)  # some case failed: exit 1, all rows
            rows = {row["case"]: row
                    for row in csv.DictReader(io.StringIO(text_of(os.path.join(out, "results.csv"))))}
            self.assertEqual(len(rows), 4)
            self.assertEqual(rows["0"]["status"], "success")
            # Bad parameters: refused before any run, named with its parameters, on stderr too.
            self.assertEqual(rows["1"]["status"], "invalid")
            self.assertIn("case 1: ", rows["1"]["message"])
            self.assertIn("model.alpha=1.5", rows["1"]["message"])
            self.assertIn("outside [0, 1]", rows["1"]["message"])
            self.assertEqual(rows["1"]["steps_done"], "0")
            self.assertIn("refused:", r.stderr)
            self.assertIn("model.alpha=1.5", r.stderr)
            # A potential that turns NaN at t = 5: stopped there, the trajectory's end kept.
            self.assertEqual(rows["2"]["status"], "non-finite")
            self.assertIn("step 51", rows["2"]["message"])
            self.assertEqual(rows["2"]["final_time"], "5")
            # Newton failure at the first step.
            self.assertEqual(rows["3"]["status"], "newton-failure")
            self.assertIn("did not converge within 1 iterations", rows["3"]["message"])


class SweepFileErrors(unittest.TestCase):
    def check_refused(self, text, *expected):
        with tempfile.TemporaryDirectory() as tmp:
            r = sweep(write(tmp, "bad.toml", text), "--out", os.path.join(tmp, "out"))
            self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
            self.assertEqual(r.stdout, "")
            self.assertEqual(len(r.stderr.splitlines()), 1, r.stderr)
            for e in expected:
                self.assertIn(e, r.stderr)
            self.assertFalse(os.path.exists(os.path.join(tmp, "out", "results.csv")))

    def base(self, parameters, sweep_keys=""):
        return grid(100).split("[sweep]")[0] + "[sweep]\n" + sweep_keys + \
            "[sweep.parameters]\n" + parameters

    def test_unknown_field(self):
        self.check_refused(self.base("model.alpah = [0.3]\n"), "model.alpah", "alpha")

    def test_unknown_sweep_key(self):
        self.check_refused(self.base("model.alpha = [0.3]\n", 'combien = "zip"\n'),
                           "sweep.combien", "did you mean 'combine'")

    def test_zip_lengths_differ(self):
        self.check_refused(self.base("model.alpha = [0.3, 0.4]\nmodel.damping = [1.0]\n",
                                     'combine = "zip"\n'), "one length", "model.damping")

    def test_range_without_count(self):
        self.check_refused(self.base("model.alpha = { linspace = [0.1, 0.9] }\n"),
                           "model.alpha.linspace", "[start, stop, count]")

    def test_random_without_seed(self):
        self.check_refused(
            self.base('model.alpha = { random = "uniform", low = 0.1, high = 0.9, count = 3 }\n'),
            "needs seed")

    def test_base_and_inline_problem(self):
        self.check_refused('base = "x.toml"\n' + self.base("model.alpha = [0.3]\n"),
                           "base problem once")


class RandomDraws(unittest.TestCase):
    def test_seeded_draws_repeat_and_integer_fields_round(self):
        text = grid(100).split("[sweep]")[0] + """[sweep]
combine = "zip"
save = "summary"
[sweep.parameters]
model.damping = { random = "loguniform", low = 0.1, high = 2.0, count = 8, seed = 7 }
model.alpha = { random = "uniform", low = 0.2, high = 0.6, count = 8, seed = 8 }
time.steps = { logspace = [200, 1600, 8] }
"""
        with tempfile.TemporaryDirectory() as tmp:
            file = write(tmp, "mc.toml", text)
            runs = []
            for name in ("a", "b"):
                r = sweep(file, "--out", os.path.join(tmp, name), "--quiet")
                self.assertEqual(r.returncode, 0, r.stderr)
                runs.append(without_wall_time(table(os.path.join(tmp, name))))
            self.assertEqual(runs[0], runs[1])
            header, rows = runs[0][0], runs[0][1:]
            self.assertNotIn("x1", header)  # save = "summary": no final state columns
            damping = [float(r[1]) for r in rows]
            alpha = [float(r[2]) for r in rows]
            self.assertTrue(all(0.1 <= d <= 2.0 for d in damping))
            self.assertTrue(all(0.2 <= a <= 0.6 for a in alpha))
            self.assertEqual(len(set(damping)), 8)
            # NumPy's geomspace(200, 1600, 8) rounded: an integer field takes rounded values.
            self.assertEqual([r[3] for r in rows], ["200", "269", "362", "488", "656", "883", "1189",
                                                    "1600"])
            self.assertEqual(rows[1][header.index("steps_done")], rows[1][3])


class ExampleSweep(unittest.TestCase):
    """examples/sweep/fractional_oscillator.toml as its comment runs it, with its heat map."""

    def test_example_and_its_heat_map(self):
        root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
        example = os.path.join(root, "examples", "sweep", "fractional_oscillator.toml")
        with tempfile.TemporaryDirectory() as out:
            r = sweep(example, "--out", out, "--quiet")
            self.assertEqual(r.returncode, 0, r.stderr)
            rows = list(csv.DictReader(io.StringIO(text_of(os.path.join(out, "results.csv")))))
            self.assertEqual(len(rows), 30)
            for row in rows:
                self.assertEqual(row["status"], "success")
                # Damping only removes energy: E(20) below E(0) = 1/2 in every case.
                self.assertLess(float(row["energy_final"]), float(row["energy_initial"]))
            r = subprocess.run(["/usr/bin/python3", os.path.join(root, "python", "fracvi",
                                                                 "plot_sweep.py"),
                                out, "energy_final"], capture_output=True, text=True,
                               timeout=120, env=dict(os.environ, MPLBACKEND="Agg"))
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertGreater(os.path.getsize(os.path.join(out, "sweep-energy_final.png")),
                               10000)


if __name__ == "__main__":
    FRACVI = sys.argv[1]
    MPIRUN = sys.argv[2] if len(sys.argv) > 2 and sys.argv[2] else None
    unittest.main(argv=[sys.argv[0], "-v"])
