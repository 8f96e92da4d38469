"""Issue 17 item 2's speed targets, measured in one run on the README's build.

    /usr/bin/python3 bench/speed_targets.py [build/release] [--rounds R] [--long]

Every figure is a fresh `fracvi run` process, as a user's run is (with `--no-plot`: the plots
are drawn after the steps and no figure times them, as bench/history_crossover.py does); the
configurations compared with
each other (one thread against the thread count the program chooses, `method.threads = 0`) run
in alternating order within each round, so that a host's slow phase hits both. Per step means
summary.json's stepping_wall_seconds / N (the fit and the factorisations are set-up and left out;
mirror run and error estimate off, except where a line says "file defaults"). The hosts vary from
session to session — and a KVM guest's two vCPUs can be one core's two hardware threads for a time —
so it runs `bench/core_handover` first and prints what it says. Not a test; bench/RESULTS.md
records what it printed, with the machine.

Targets (issue 17, item 2): the d = 1000 linear chain (`fvi-gl`, β = 1.5) ≤ 5 µs a step (N = 10^6
≤ 5 s), its β-FPUT variant ≤ 10 µs, d = 1 N = 10^7 with the file's defaults ≤ 2 s, two cores
≥ 1.6× one core at d = 10^4, and never slower than one core. `--long` adds the N = 10^6 run of
the d = 1000 chain with the file's defaults (mirror "auto", the error estimate's companion
alongside; about a minute a round here).
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHAIN = os.path.join(ROOT, "examples", "fractional_chain.toml")
OSCILLATOR = os.path.join(ROOT, "examples", "viscoelastic_caputo.toml")


def run(fracvi, problem, sets):
    """One `fracvi run`; returns summary.json (raises with the output if the run failed)."""
    with tempfile.TemporaryDirectory() as out:
        args = [fracvi, "run", problem, "--out", out, "--no-plot", "--quiet"]
        for key, value in sets.items():
            args += ["--set", f"{key}={value}"]
        done = subprocess.run(args, capture_output=True, text=True, check=False)
        path = os.path.join(out, "summary.json")
        if not os.path.exists(path):
            raise RuntimeError(f"{' '.join(args)}: exit {done.returncode}, no summary.json\n"
                               f"{done.stderr}")
        with open(path, encoding="utf-8") as f:
            summary = json.load(f)
    if done.returncode != 0 or summary.get("status") != "success":
        raise RuntimeError(f"{' '.join(args)}: exit {done.returncode}, status "
                           f"{summary.get('status')}\n{done.stderr}")
    return summary


def chain_sets(dim, steps, threads, extra=None):
    """The example chain at h = 0.01 with mirror and estimate off, no trajectory rows kept."""
    sets = {"model.dim": dim, "time.steps": steps, "time.end": steps * 0.01,
            "method.mirror": "off", "method.error_estimate": "none", "output.every": steps,
            "method.threads": threads}
    sets.update(extra or {})
    return sets


def per_step(fracvi, problem, sets):
    return run(fracvi, problem, sets)["stepping_wall_seconds"] / sets["time.steps"] * 1e6


def compare_threads(fracvi, label, dim, steps, rounds, extra=None):
    """Alternating one thread / threads = 0; prints µs a step and the ratio of each round."""
    one, chosen = [], []
    for r in range(rounds):
        order = (1, 0) if r % 2 == 0 else (0, 1)
        got = {t: per_step(fracvi, CHAIN, chain_sets(dim, steps, t, extra)) for t in order}
        one.append(got[1])
        chosen.append(got[0])
        print(f"  {label} round {r + 1}: one thread {got[1]:.2f} µs, threads = 0 {got[0]:.2f} µs "
              f"({got[1] / got[0]:.2f}×)", flush=True)
    ratios = [a / b for a, b in zip(one, chosen)]
    print(f"{label}: one thread {min(one):.2f}–{max(one):.2f} µs, threads = 0 "
          f"{min(chosen):.2f}–{max(chosen):.2f} µs (median {statistics.median(chosen):.2f}), "
          f"ratio {min(ratios):.2f}–{max(ratios):.2f}", flush=True)


def main():
    args = sys.argv[1:]
    long_run = "--long" in args
    rounds = 3
    if "--rounds" in args:
        rounds = int(args[args.index("--rounds") + 1])
    positional = [a for i, a in enumerate(args)
                  if not a.startswith("--") and (i == 0 or args[i - 1] != "--rounds")]
    build = positional[0] if positional else os.path.join(ROOT, "build", "release")
    fracvi = os.path.join(build, "fracvi")
    handover = os.path.join(build, "bench", "core_handover")
    with open("/proc/cpuinfo", encoding="utf-8") as f:
        model = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")),
                     "?")
    with open("/proc/loadavg", encoding="utf-8") as f:
        load = " ".join(f.read().split()[:3])
    print(f"cpu: {model} ({os.cpu_count()} CPUs); load {load}")
    if os.path.exists(handover):
        out = subprocess.run([handover, "1000", "20000"], capture_output=True, text=True,
                             check=False).stdout
        print("core_handover: " + " | ".join(out.strip().splitlines()[-3:]), flush=True)

    compare_threads(fracvi, "d = 1000 linear (target ≤ 5 µs)", 1000, 100000, rounds)
    compare_threads(fracvi, "d = 1000 β-FPUT (target ≤ 10 µs)", 1000, 50000, rounds,
                    {"model.chain.quartic": 1})
    compare_threads(fracvi, "d = 10^4 linear (target ≥ 1.6×)", 10000, 3000, rounds)
    compare_threads(fracvi, "d = 3000 linear (never slower)", 3000, 20000, rounds)

    d1 = []
    for _ in range(rounds):
        s = run(fracvi, OSCILLATOR, {"time.steps": 10000000, "time.end": 20})
        d1.append(s["setup_wall_seconds"] + s["stepping_wall_seconds"])
    print(f"d = 1, N = 10^7, file defaults (target ≤ 2 s): set-up + stepping "
          f"{min(d1):.2f}–{max(d1):.2f} s", flush=True)

    if long_run:
        for _ in range(max(1, rounds // 2)):
            s = run(fracvi, CHAIN, {"time.steps": 1000000, "time.end": 10000,
                                    "method.mirror": "auto", "output.every": 1000000})
            print(f"d = 1000, N = 10^6, file defaults (mirror auto; target ≤ 5 s): stepping "
                  f"{s['stepping_wall_seconds']:.2f} s, set-up {s['setup_wall_seconds']:.2f} s, "
                  f"K = {s.get('history_exponentials', '?')}", flush=True)


if __name__ == "__main__":
    main()
