"""The figures of a `fracvi compare` directory (or of fracvi.compare's table).

Run as a script by the CLI (Debian's /usr/bin/python3 with matplotlib):
    plot_compare.py DIRECTORY
Reads compare.csv, compare.json and energy.csv (if present) and writes
  work_precision.png   max error over the grid against wall time, one line per scheme
  error_vs_steps.png   max error against N, with the declared-order slopes
  energy_tracking.png  E(t) and the dissipated work W(t) of every scheme at one N against the
                       reference, and their errors

Drawn on matplotlib Figure objects with the Agg canvas, not through pyplot (no global state, no
GUI backend touched); matplotlib is imported on first use.
"""
import csv
import json
import os
import sys

import numpy as np


def _figure(**kwargs):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(dpi=100, **kwargs)
    FigureCanvasAgg(fig)
    return fig


FIGURES = ("work_precision.png", "error_vs_steps.png", "energy_tracking.png")
_FLOAT_COLUMNS = ("h", "final_error", "max_error", "energy_error", "dissipated_error",
                  "balance_error", "wall_seconds")


def read_table(path):
    """compare.csv as a dict of NumPy columns (the same layout fracvi.compare returns)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")
    table = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        if key in _FLOAT_COLUMNS:
            table[key] = np.array([float(v) for v in values])
        elif key in ("steps", "declared_order", "newton_iterations"):
            table[key] = np.array([int(v) for v in values])
        else:
            table[key] = np.array(values, dtype=object)
    return table


def _schemes(table):
    seen = []
    for s in table["scheme"]:
        if s not in seen:
            seen.append(s)
    return seen


def _styles(names):
    import matplotlib
    cmap = matplotlib.colormaps["tab20" if len(names) > 10 else "tab10"]
    markers = "os^vD<>ph*"
    return {n: dict(color=cmap(i % cmap.N), marker=markers[i % len(markers)])
            for i, n in enumerate(names)}


def _title(meta, what):
    problem = meta.get("problem", {})
    m = problem.get("model", {})
    alpha = m.get("alpha")
    order = f", damping order 2α = {2 * alpha:g}" if alpha is not None else ""
    return f"{problem.get('name', '')}: {what}{order}\nreference: {meta.get('reference', '')}"


def plot_work_precision(table, meta, path):
    names = _schemes(table)
    style = _styles(names)
    fig = _figure(figsize=(9, 6))
    ax = fig.subplots()
    for n in names:
        sel = (table["scheme"] == n) & (table["status"] == "success") & (table["max_error"] > 0)
        if sel.any():
            ax.loglog(table["wall_seconds"][sel], table["max_error"][sel], "-", label=n,
                      **style[n])
    ax.set_xlabel("wall time of the integration [s]")
    ax.set_ylabel(r"$\max_k \|x_k - x_{\mathrm{ref}}(t_k)\|_\infty$")
    ax.set_title(_title(meta, "work–precision"), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path)


def plot_error_vs_steps(table, meta, path):
    names = _schemes(table)
    style = _styles(names)
    fig = _figure(figsize=(9, 6))
    ax = fig.subplots()
    for n in names:
        sel = (table["scheme"] == n) & (table["status"] == "success") & (table["max_error"] > 0)
        if not sel.any():
            continue
        steps, err = table["steps"][sel], table["max_error"][sel]
        ax.loglog(steps, err, "-", label=n, **style[n])
        p = int(table["declared_order"][sel][0])
        # An adaptive scheme's error follows its tolerances, not N: no slope to draw.
        if p > 0 and len(steps) > 1 and n not in meta.get("adaptive", ()):  # the declared slope through the coarsest point
            ax.loglog(steps, err[0] * (steps / steps[0]) ** (-p), ":", color=style[n]["color"],
                      lw=0.8)
    ax.set_xlabel("steps N")
    ax.set_ylabel(r"$\max_k \|x_k - x_{\mathrm{ref}}(t_k)\|_\infty$")
    ax.set_title(_title(meta, "error against N (dotted: declared order)"), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path)


def read_energy(path):
    """energy.csv as (t, reference E, reference W, {scheme: (E, W)})."""
    data = np.genfromtxt(path, delimiter=",", names=True, deletechars="", dtype=float)
    names = data.dtype.names
    curves = {}
    for key in names:
        if key.startswith("energy:"):
            s = key[len("energy:"):]
            curves[s] = (data[key], data["dissipated:" + s])
    return data["t"], data["reference_energy"], data["reference_dissipated"], curves


def plot_energy_tracking(energy, meta, path):
    t, e_ref, w_ref, curves = energy
    style = _styles(list(curves))
    fig = _figure(figsize=(12, 8))
    axes = fig.subplots(2, 2, sharex=True)
    axes[0, 0].plot(t, e_ref, "k-", lw=2.5, alpha=0.4, label="reference")
    axes[0, 1].plot(t, w_ref, "k-", lw=2.5, alpha=0.4, label="reference")
    for s, (e, w) in curves.items():
        c = style[s]["color"]
        axes[0, 0].plot(t, e, "-", color=c, lw=1, label=s)
        axes[0, 1].plot(t, w, "-", color=c, lw=1, label=s)
        de, dw = np.abs(e - e_ref), np.abs(w - w_ref)
        if np.any(de > 0):
            axes[1, 0].semilogy(t, np.where(de > 0, de, np.nan), "-", color=c, lw=1, label=s)
        if np.any(dw > 0):
            axes[1, 1].semilogy(t, np.where(dw > 0, dw, np.nan), "-", color=c, lw=1, label=s)
    axes[0, 0].set_ylabel(r"energy $E = \frac{1}{2} v^\top M v + U$")
    axes[0, 1].set_ylabel("dissipated work W")
    axes[1, 0].set_ylabel(r"$|E_k - E_{\mathrm{ref}}(t_k)|$")
    axes[1, 1].set_ylabel(r"$|W_k - W_{\mathrm{ref}}(t_k)|$")
    for ax in axes[1]:
        ax.set_xlabel("t")
    for ax in axes.flat:
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].legend(loc="best", fontsize=7, ncol=2)
    fig.suptitle(_title(meta, f"energy tracking at N = {meta.get('energy_steps', '?')}") +
                 f"; energy reference: {meta.get('energy_reference', '')}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)


def plot_compare(directory):
    with open(os.path.join(directory, "compare.json"), encoding="utf-8") as f:
        meta = json.load(f)
    table = read_table(os.path.join(directory, "compare.csv"))
    written = []
    for name, draw in (("work_precision.png", plot_work_precision),
                       ("error_vs_steps.png", plot_error_vs_steps)):
        path = os.path.join(directory, name)
        draw(table, meta, path)
        written.append(path)
    energy_path = os.path.join(directory, "energy.csv")
    if os.path.exists(energy_path):
        path = os.path.join(directory, "energy_tracking.png")
        plot_energy_tracking(read_energy(energy_path), meta, path)
        written.append(path)
    return written


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot_compare.py DIRECTORY")
    for p in plot_compare(sys.argv[1]):
        print(p)
