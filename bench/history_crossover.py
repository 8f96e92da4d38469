"""Where the fast history starts to pay, per scheme: whole `fracvi run` costs with
`method.history = "direct"` against `"fast"` (issue 17; the crossover `history = "auto"` uses).

    /usr/bin/python3 bench/history_crossover.py [build/release/fracvi] [--quick]

Each run is a fresh process, as a user's `fracvi run` is, so the fast history pays for its fit
(or, for the Lobatto schemes, its block tail) every time. The cost compared is summary.json's
wall_seconds = set-up (weights, fit, factorisations) + stepping, mirror run and error estimate off.
Problem: the Caputo fractional oscillator x'' + 0.5 D^{3/2}x + x = 0 (d = 1) and a chain of
d = 100 masses with the same damping, on [0, 20]. Direct and fast runs alternate; the best of
three of each is kept. Prints a table of direct / fast per scheme, d and N, and what `auto`
chose. Not a test; bench/RESULTS.md records it.
"""
import json
import os
import subprocess
import sys
import tempfile

SCHEMES = ("fvi-gl", "fvi-bdf2", "fvi-midpoint", "fvi-lobatto3")

OSCILLATOR = """name = "oscillator"
[model]
dim = {d}
mass = 1.0
damping = 0.5
alpha = 0.75
convention = "caputo"
{potential}
[initial]
position = "{position}"
velocity = 0.0
[time]
start = 0.0
end = 20.0
steps = {steps}
[method]
scheme = "{scheme}"
history = "{history}"
mirror = "off"
error_estimate = "none"
threads = 1
[output]
every = {steps}
"""


def problem_text(scheme, d, steps, history):
    if d == 1:
        potential, position = 'potential = "0.5*x1^2"', "1.0"
    else:
        potential, position = "[model.chain]\nstiffness = 1.0\nboundary = \"fixed\"", "0.5*sin(pi*i/(d+1))"
    return OSCILLATOR.format(d=d, potential=potential, position=position, steps=steps,
                             scheme=scheme, history=history)


def run(cli, directory, text):
    path = os.path.join(directory, "problem.toml")
    with open(path, "w") as f:
        f.write(text)
    out = os.path.join(directory, "out")
    subprocess.run([cli, "run", path, "--out", out, "--no-plot", "--quiet"], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    return summary["wall_seconds"], summary["history"]


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    cli = args[0] if args else "build/release/fracvi"
    quick = "--quick" in sys.argv
    sizes = (512, 2048) if quick else (512, 1024, 1536, 2048, 3072, 4096, 6144)
    dims = (1,) if quick else (1, 100)
    repeats = 1 if quick else 3
    print("| scheme | d | N | direct (s) | fast (s) | direct / fast | auto chose |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as directory:
        for scheme in SCHEMES:
            for d in dims:
                for steps in sizes:
                    best = {"direct": float("inf"), "fast": float("inf")}
                    for _ in range(repeats):
                        for history in ("direct", "fast"):
                            wall, _ = run(cli, directory,
                                          problem_text(scheme, d, steps, history))
                            best[history] = min(best[history], wall)
                    _, chosen = run(cli, directory, problem_text(scheme, d, steps, "auto"))
                    print(f"| {scheme} | {d} | {steps} | {best['direct']:.4f} | "
                          f"{best['fast']:.4f} | {best['direct'] / best['fast']:.2f} | "
                          f"{chosen} |", flush=True)


if __name__ == "__main__":
    main()
