"""Scaling of `fracvi sweep` (issue 15): cases per second on 1 and 2 local threads and on 1, 2 and
3 MPI ranks (every rank runs cases; `mpirun -n 1` runs locally with --jobs 1, so it shows what
mpirun itself costs), and the overhead per case against a plain `fracvi run` of the same problem.

The study: the fractional oscillator x'' + R D^(2 alpha) x + x = 0 on [0, 20] over a grid of
(2 alpha, R), at two costs per case (time.steps = 400: about a millisecond; 4000: tens of
milliseconds). For each launcher the sweep runs --repeat times into a fresh directory and the best
wall time of the whole command counts (process start, validation of every case, the table).

Overhead per case, on a sweep of identical cases (the base problem with 2 alpha = 1.5, R = 0.5,
swept over `name` only, so that every case costs the same): (sweep wall time with --jobs 1) /
cases − mean of the rows' wall_seconds (the case's own solve, from the same run), against the wall
time of `fracvi run --no-plot --quiet` of that problem (a process, its output files). Prints markdown; bench/RESULTS.md records one run. Not a test.

Usage: /usr/bin/python3 bench/sweep_scaling.py build/release/fracvi [--repeat 3] [--mpirun mpirun]
"""
import argparse
import csv
import os
import resource
import shutil
import subprocess
import tempfile
import time

EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "sweep",
                       "fractional_oscillator.toml")


def sweep_text(steps, n_order, n_damping):
    """examples/sweep/fractional_oscillator.toml with `steps` steps and an n_order x n_damping
    grid (0 x 0: the base problem and its [sweep] header only)."""
    with open(EXAMPLE, encoding="utf-8") as f:
        text = f.read().replace("steps = 400\n", f"steps = {steps}\n")
    text = text.replace("linspace = [0.2, 1.8, 6]", f"linspace = [0.2, 1.8, {n_order}]")
    return text.replace("logspace = [0.1, 2.0, 5]", f"logspace = [0.1, 2.0, {n_damping}]")


def cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(command, out, repeat):
    """(wall, CPU) seconds of the fastest of `repeat` runs; CPU is user + system of the command
    and its children (the MPI ranks), so CPU/wall shows how many cores it kept busy — on a
    machine shared with other work a speed-up can only be as large as that."""
    best = (float("inf"), 0.0)
    for _ in range(repeat):
        shutil.rmtree(out, ignore_errors=True)
        cpu = cpu_seconds()
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        wall = time.perf_counter() - start
        if wall < best[0]:
            best = (wall, cpu_seconds() - cpu)
    return best


def best_time(command, out, repeat):
    return timed(command, out, repeat)[0]


def sweep_and_solve_time(command, out, repeat):
    """(wall time, mean wall_seconds of its rows) of the fastest of `repeat` runs."""
    best = (float("inf"), 0.0)
    for _ in range(repeat):
        shutil.rmtree(out, ignore_errors=True)
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        seconds = time.perf_counter() - start
        if seconds < best[0]:
            best = (seconds, mean_case_seconds(out)[0])
    return best


def mean_case_seconds(out):
    with open(os.path.join(out, "results.csv"), encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return sum(float(r["wall_seconds"]) for r in rows) / len(rows), len(rows)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("fracvi")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--mpirun", default=shutil.which("mpirun"))
    args = parser.parse_args()
    # --bind-to none: OpenMPI pins each rank to one core when there are no more ranks than cores,
    # which on a machine shared with other work pins a worker to a busy core.
    mpi = ([args.mpirun, "--oversubscribe", "--allow-run-as-root", "--bind-to", "none", "-n"]
           if args.mpirun else None)

    print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print()
    print("| steps | cases | launcher | wall s | cases/s | speed-up | CPU/wall |")
    print("|---|---|---|---|---|---|---|")
    overhead = []
    with tempfile.TemporaryDirectory() as tmp:
        for steps, n_order, n_damping in ((400, 20, 10), (4000, 6, 5)):
            file = os.path.join(tmp, f"sweep{steps}.toml")
            with open(file, "w", encoding="utf-8") as f:
                f.write(sweep_text(steps, n_order, n_damping))
            out = os.path.join(tmp, "out")
            launchers = [("--jobs 1", [args.fracvi, "sweep", file, "--out", out, "--quiet",
                                       "--jobs", "1"]),
                         ("--jobs 2", [args.fracvi, "sweep", file, "--out", out, "--quiet",
                                       "--jobs", "2"])]
            if mpi:
                for ranks in (1, 2, 3):
                    launchers.append((f"mpirun -n {ranks}",
                                      mpi + [str(ranks), args.fracvi, "sweep", file, "--out", out,
                                             "--quiet", "--jobs", "1"]))
            base = None
            cases = n_order * n_damping
            for name, command in launchers:
                seconds, cpu = timed(command, out, args.repeat)
                base = base or seconds
                print(f"| {steps} | {cases} | {name} | {seconds:.3f} | {cases / seconds:.1f} | "
                      f"{base / seconds:.2f} | {cpu / seconds:.2f} |")

        for steps in (400, 4000):
            # Identical cases: the base problem swept over its name only.
            file = os.path.join(tmp, f"same{steps}.toml")
            problem_text = sweep_text(steps, 1, 1).split("[sweep]")[0]
            problem_text = problem_text.replace("damping_order = 1.0", "damping_order = 1.5")
            cases = 100 if steps == 400 else 20
            with open(file, "w", encoding="utf-8") as f:
                f.write(problem_text + "[sweep.parameters]\nname = [" +
                        ", ".join(f'"c{i}"' for i in range(cases)) + "]\n")
            out = os.path.join(tmp, "same")
            total, solve = sweep_and_solve_time(
                [args.fracvi, "sweep", file, "--out", out, "--quiet", "--jobs", "1"], out,
                args.repeat)
            problem = os.path.join(tmp, f"problem{steps}.toml")
            with open(problem, "w", encoding="utf-8") as f:
                f.write(problem_text.replace("[problem.", "[").replace("[problem]\n", ""))
            run = best_time([args.fracvi, "run", problem, "--out", os.path.join(tmp, "run"),
                             "--no-plot", "--quiet"], os.path.join(tmp, "run"), args.repeat)
            overhead.append((steps, total / cases, solve, run))

    print()
    print("| steps | sweep s/case (--jobs 1) | solve s/case (wall_seconds) | sweep overhead/case | "
          "plain `fracvi run` s |")
    print("|---|---|---|---|---|")
    for steps, per_case, solve, run in overhead:
        print(f"| {steps} | {per_case * 1e3:.2f} ms | {solve * 1e3:.2f} ms | "
              f"{(per_case - solve) * 1e3:.2f} ms | {run * 1e3:.1f} ms |")


if __name__ == "__main__":
    main()
