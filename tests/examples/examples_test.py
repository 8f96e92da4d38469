"""Runs every problem file in examples/ and checks the invariants its comment block documents.

Each example states its checks in lines of the form
    # check: summary KEY OP VALUE        (OP is ==, <, <=, >, >=; the value of summary.json)
    # check: nonincreasing COLUMN TOL    (trajectory.csv column never rises by more than TOL)
    # check: order STEPS EXPECTED TOL    (fracvi convergence --steps STEPS: fitted order)
    # check: event NAME EXPECTED TOL     (the first crossing of [[events]] NAME: |t - EXPECTED|)
Usage (ctest): python3 examples_test.py FRACVI_BINARY EXAMPLES_DIR
"""
import csv
import glob
import json
import operator
import os
import re
import subprocess
import sys
import tempfile
import unittest

FRACVI = None
EXAMPLES = None
OPS = {"==": operator.eq, "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}


def checks_of(path):
    with open(path, encoding="utf-8") as f:
        return [line.split(":", 1)[1].split() for line in f if line.startswith("# check:")]


def value(text):
    try:
        return float(text)
    except ValueError:
        return text


class Examples(unittest.TestCase):
    def test_every_example_meets_its_documented_invariants(self):
        files = sorted(glob.glob(os.path.join(EXAMPLES, "*.toml")))
        self.assertGreaterEqual(len(files), 6)
        for path in files:
            with self.subTest(os.path.basename(path)):
                checks = checks_of(path)
                self.assertTrue(checks, "no '# check:' lines")
                with tempfile.TemporaryDirectory() as out:
                    r = subprocess.run([FRACVI, "run", path, "--out", out, "--no-plot", "--quiet"],
                                       capture_output=True, text=True, timeout=600)
                    self.assertEqual(r.returncode, 0, r.stderr)
                    with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
                        summary = json.load(f)
                    with open(os.path.join(out, "trajectory.csv"), encoding="utf-8") as f:
                        rows = list(csv.DictReader(f))
                    for check in checks:
                        self.run_check(path, check, summary, rows, out)

    def run_check(self, path, check, summary, rows, out):
        kind = check[0]
        if kind == "summary":
            key, op, expected = check[1], check[2], value(check[3])
            actual = summary[key]
            self.assertTrue(OPS[op](actual, expected), f"{key} = {actual}, want {op} {expected}")
        elif kind == "nonincreasing":
            column, tol = check[1], float(check[2])
            series = [float(r[column]) for r in rows]
            rise = max(b - a for a, b in zip(series, series[1:]))
            self.assertLessEqual(rise, tol, f"{column} rises by {rise}")
        elif kind == "order":
            steps, expected, tol = check[1], float(check[2]), float(check[3])
            r = subprocess.run([FRACVI, "convergence", path, "--steps", steps, "--no-plot",
                                "--out", os.path.join(out, "convergence")],
                               capture_output=True, text=True, timeout=600)
            self.assertEqual(r.returncode, 0, r.stderr)
            fitted = float(re.search(r"least-squares order: (\S+)", r.stdout).group(1))
            self.assertAlmostEqual(fitted, expected, delta=tol, msg=r.stdout)
        elif kind == "event":
            name, expected, tol = check[1], float(check[2]), float(check[3])
            times = [e["t"] for e in summary["events"] if e["name"] == name]
            self.assertTrue(times, f"event {name!r} did not occur: {summary['events']}")
            self.assertLessEqual(abs(times[0] - expected), tol, f"event {name!r} at {times[0]}")
        else:
            self.fail(f"unknown check kind {kind!r}")


if __name__ == "__main__":
    FRACVI, EXAMPLES = sys.argv[1], sys.argv[2]
    del sys.argv[1:3]
    unittest.main(verbosity=2)
