"""Writing and reading a run's trajectory: trajectory.csv against trajectory.npz (issue 16 item 6).

    PYTHONPATH=build/release/python /usr/bin/python3 bench/trajectory_files_bench.py [--quick]

A chain of d = 1000 masses (the FPUT chain with fractional damping, fvi-gl), N = 2000 steps, every
step stored: 2001 rows of x and v. Times, best of three in one process: fracvi.write with
format="csv" and "npz" (both the C++ writer: 17-digit text, or libzip + .npy headers), NumPy's
own np.savez of the same arrays for comparison, and fracvi.load of each directory; file sizes.
Checks that every written file reads back bit for bit. Not a test; bench/RESULTS.md records it.
"""
import os
import shutil
import sys
import tempfile
import time

import numpy as np

import fracvi

ARRAYS = ("t", "step", "x", "v", "energy", "dissipated", "balance")


def best(f, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def main():
    quick = "--quick" in sys.argv
    d, steps, repeats = (200, 500, 1) if quick else (1000, 2000, 3)
    problem = fracvi.Problem(name="chain", dim=d, mass=1.0, damping=0.1, alpha=0.75,
                             convention="caputo", chain=dict(quartic=1.0),
                             position=f"0.5*sin(pi*i/(d+1))", end=10.0, steps=steps,
                             scheme="fvi-gl", mirror="off", error_estimate="none")
    solution = fracvi.integrate(problem)
    assert solution.ok, solution.message
    root = tempfile.mkdtemp()
    try:
        dirs = {f: os.path.join(root, f) for f in ("csv", "npz")}
        written = {f: best(lambda f=f: fracvi.write(solution, dirs[f], format=f), repeats)
                   for f in dirs}
        numpy_file = os.path.join(root, "numpy.npz")
        numpy_time = best(lambda: np.savez(numpy_file, **{a: getattr(solution, a)
                                                          for a in ARRAYS}), repeats)
        loaded = {f: best(lambda f=f: fracvi.load(dirs[f]), repeats) for f in dirs}
        for f in dirs:
            back = fracvi.load(dirs[f])
            for a in ARRAYS:
                assert np.array_equal(getattr(back, a), getattr(solution, a), equal_nan=True), a
        sizes = {f: os.path.getsize(os.path.join(dirs[f], f"trajectory.{f}")) for f in dirs}
        print(f"d = {d}, {len(solution.t)} rows; best of {repeats}")
        print(f"{'format':>8} {'size MB':>8} {'write s':>8} {'load s':>8}")
        for f in dirs:
            print(f"{f:>8} {sizes[f] / 1e6:>8.1f} {written[f]:>8.3f} {loaded[f]:>8.3f}")
        print(f"{'np.savez':>8} {os.path.getsize(numpy_file) / 1e6:>8.1f} {numpy_time:>8.3f}")
        print(f"csv/npz: size {sizes['csv'] / sizes['npz']:.1f}x, write "
              f"{written['csv'] / written['npz']:.1f}x, load {loaded['csv'] / loaded['npz']:.1f}x")
    finally:
        shutil.rmtree(root)


if __name__ == "__main__":
    main()
