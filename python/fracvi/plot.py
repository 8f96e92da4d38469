"""Plots of a fracvi run: trajectory, phase portrait, energy balance.

Used by `fracvi run` / `fracvi plot DIR` (as a script, with Debian's /usr/bin/python3 and
matplotlib) and importable from Python. Reads DIR/trajectory.csv and DIR/summary.json and writes
DIR/trajectory.png, DIR/phase.png and DIR/energy.png (800 x 500 px).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MAX_COMPONENTS = 6  # more components than this make an unreadable trajectory plot


def _title(summary, what):
    p = summary.get("problem", {})
    m = p.get("model", {})
    alpha = m.get("alpha", float("nan"))
    return (f"{p.get('name', 'fracvi')}: {what}\n"
            f"α = {alpha:g} (damping order 2α = {2 * alpha:g}, {m.get('convention', '')}), "
            f"scheme {summary.get('method', '')}, N = {summary.get('steps', '?')}")


def load(directory):
    with open(os.path.join(directory, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    data = np.genfromtxt(os.path.join(directory, "trajectory.csv"), delimiter=",", names=True)
    return data, summary


def plot_run(directory):
    data, summary = load(directory)
    data = np.atleast_1d(data)
    names = data.dtype.names
    xs = [n for n in names if n.startswith("x")]
    vs = [n for n in names if n.startswith("v")]
    t = data["t"]
    written = []

    fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
    for n in xs[:MAX_COMPONENTS]:
        ax.plot(t, data[n], lw=1.2, label=f"${n[0]}_{{{n[1:]}}}(t)$")
    if len(xs) > MAX_COMPONENTS:
        ax.plot([], [], " ", label=f"(first {MAX_COMPONENTS} of {len(xs)} shown)")
    ax.set_xlabel("time $t$")
    ax.set_ylabel("position $x_i$")
    ax.set_title(_title(summary, "trajectory"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    written.append(_save(fig, directory, "trajectory.png"))

    fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
    ax.plot(data[xs[0]], data[vs[0]], lw=0.9, label="trajectory")
    ax.plot(data[xs[0]][0], data[vs[0]][0], "o", color="tab:green", label="start")
    ax.plot(data[xs[0]][-1], data[vs[0]][-1], "s", color="tab:red", label="end")
    ax.set_xlabel("position $x_1$")
    ax.set_ylabel("velocity $v_1$")
    ax.set_title(_title(summary, "phase portrait (first component)"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    written.append(_save(fig, directory, "phase.png"))

    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 5), dpi=100, sharex=True,
                                  gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(t, data["energy"], lw=1.2, label="energy $E_k$")
    ax.plot(t, data["dissipated"], lw=1.2, label="dissipated work $W_k$ (damping loss − work of $f$)")
    ax.plot(t, data["energy"] + data["dissipated"], lw=1.0, ls="--", label="$E_k + W_k$")
    ax.set_ylabel("energy")
    ax.set_title(_title(summary, "energy balance"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    ax2.plot(t, data["balance"], lw=1.0, color="tab:red", label="$E_k + W_k - E_0$")
    ax2.set_xlabel("time $t$")
    ax2.set_ylabel("balance error")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="best", fontsize=9)
    ax2.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    fig.tight_layout()
    written.append(_save(fig, directory, "energy.png"))
    return written


def _save(fig, directory, name):
    path = os.path.join(directory, name)
    fig.savefig(path)
    plt.close(fig)
    return path


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot.py RUN_DIRECTORY")
    for p in plot_run(sys.argv[1]):
        print(p)
