"""Plots of a fracvi run: trajectory, phase portrait, energy balance.

Used by `fracvi run` / `fracvi plot DIR` (as a script, with Debian's /usr/bin/python3 and
matplotlib) and by the Python package (fracvi.plot, which also plots a Solution object). As a
script it reads DIR/trajectory.csv and DIR/summary.json and writes DIR/trajectory.png,
DIR/phase.png and DIR/energy.png (800 x 500 px).

Files are drawn on matplotlib Figure objects with the Agg canvas, not through pyplot: no global
state and no GUI backend is touched, so plotting works headless and inside applications that use
pyplot themselves. matplotlib is imported on first use, so importing fracvi stays fast.
"""
import json
import os
import sys

import numpy as np

MAX_COMPONENTS = 6  # more components than this make an unreadable trajectory plot
FIGSIZE = (8, 5)
DPI = 100
FILES = ("trajectory.png", "phase.png", "energy.png")


def _title(summary, what):
    p = summary.get("problem", {})
    m = p.get("model", {})
    alpha = m.get("alpha", float("nan"))
    return (f"{p.get('name', 'fracvi')}: {what}\n"
            f"α = {alpha:g} (damping order 2α = {2 * alpha:g}, {m.get('convention', '')}), "
            f"scheme {summary.get('method', '')}, N = {summary.get('steps', '?')}")


def load(directory):
    """(data, summary): trajectory.csv as a structured array and summary.json as a dict."""
    with open(os.path.join(directory, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    data = np.genfromtxt(os.path.join(directory, "trajectory.csv"), delimiter=",", names=True)
    return np.atleast_1d(data), summary


def columns(data):
    """The columns of trajectory.csv as arrays t, x (rows × d), v, energy, dissipated, balance."""
    names = data.dtype.names
    xs = [n for n in names if n.startswith("x")]
    vs = [n for n in names if n.startswith("v")]
    return dict(t=data["t"], x=np.column_stack([data[n] for n in xs]),
                v=np.column_stack([data[n] for n in vs]), energy=data["energy"],
                dissipated=data["dissipated"], balance=data["balance"])


def _new_figure(pyplot, **kwargs):
    if pyplot:
        import matplotlib.pyplot as plt
        return plt.figure(figsize=FIGSIZE, dpi=DPI, **kwargs)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=FIGSIZE, dpi=DPI, **kwargs)
    FigureCanvasAgg(fig)
    return fig


def figures(t, x, v, energy, dissipated, balance, summary, pyplot=False):
    """The three figures [trajectory, phase, energy] of a run: x and v have shape (rows, d).
    pyplot=True creates them through pyplot (so that plt.show() shows them)."""
    x = np.asarray(x).reshape(len(t), -1)
    v = np.asarray(v).reshape(len(t), -1)
    energy = np.asarray(energy)
    dissipated = np.asarray(dissipated)
    d = x.shape[1]

    fig1 = _new_figure(pyplot)
    ax = fig1.subplots()
    for i in range(min(d, MAX_COMPONENTS)):
        ax.plot(t, x[:, i], lw=1.2, label=f"$x_{{{i + 1}}}(t)$")
    if d > MAX_COMPONENTS:
        ax.plot([], [], " ", label=f"(first {MAX_COMPONENTS} of {d} shown)")
    ax.set_xlabel("time $t$")
    ax.set_ylabel("position $x_i$")
    ax.set_title(_title(summary, "trajectory"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig1.tight_layout()

    fig2 = _new_figure(pyplot)
    ax = fig2.subplots()
    ax.plot(x[:, 0], v[:, 0], lw=0.9, label="trajectory")
    ax.plot(x[0, 0], v[0, 0], "o", color="tab:green", label="start")
    ax.plot(x[-1, 0], v[-1, 0], "s", color="tab:red", label="end")
    ax.set_xlabel("position $x_1$")
    ax.set_ylabel("velocity $v_1$")
    ax.set_title(_title(summary, "phase portrait (first component)"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig2.tight_layout()

    fig3 = _new_figure(pyplot)
    ax, ax2 = fig3.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(t, energy, lw=1.2, label="energy $E_k$")
    ax.plot(t, dissipated, lw=1.2, label="dissipated work $W_k$ (damping loss − work of $f$)")
    ax.plot(t, energy + dissipated, lw=1.0, ls="--", label="$E_k + W_k$")
    ax.set_ylabel("energy")
    ax.set_title(_title(summary, "energy balance"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    ax2.plot(t, balance, lw=1.0, color="tab:red", label="$E_k + W_k - E_0$")
    ax2.set_xlabel("time $t$")
    ax2.set_ylabel("balance error")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="best", fontsize=9)
    ax2.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    fig3.tight_layout()
    return [fig1, fig2, fig3]


def save(figs, directory):
    """Writes the figures of figures() as trajectory.png, phase.png, energy.png; returns the
    paths."""
    os.makedirs(directory, exist_ok=True)
    paths = []
    for fig, name in zip(figs, FILES):
        path = os.path.join(directory, name)
        fig.savefig(path)
        paths.append(path)
    return paths


def plot_run(directory):
    """Draws the plots of the run in `directory` (trajectory.csv, summary.json) into it."""
    data, summary = load(directory)
    return save(figures(summary=summary, **columns(data)), directory)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot.py RUN_DIRECTORY")
    for p in plot_run(sys.argv[1]):
        print(p)
