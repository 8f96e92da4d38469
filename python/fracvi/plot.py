"""Plots of a fracvi run: trajectory, phase portrait, energy balance, and for large systems a
space-time image.

Used by `fracvi run` / `fracvi plot DIR` (as a script, with Debian's /usr/bin/python3 and
matplotlib) and by the Python package (fracvi.plot, which also plots a Solution object). As a
script it reads DIR/trajectory.csv (or trajectory.npz) and DIR/summary.json and writes DIR/trajectory.png,
DIR/phase.png and DIR/energy.png (800 x 500 px), and DIR/spacetime.png when d > 8.

Large systems (d > MAX_COMPONENTS, e.g. a chain of 10^5 masses) stay readable: the trajectory
shows the first, middle and last coordinates and the one with the largest excursion, the phase
portrait that largest one, and spacetime.png shows x_i(t) as an image (site i across, time t
up), reduced to at most MAX_IMAGE × MAX_IMAGE pixels and cropped to the sites that moved.

Files are drawn on matplotlib Figure objects with the Agg canvas, not through pyplot: no global
state and no GUI backend is touched, so plotting works headless and inside applications that use
pyplot themselves. matplotlib is imported on first use, so importing fracvi stays fast.
"""
import json
import os
import sys

import numpy as np

MAX_COMPONENTS = 8  # up to this many components are all drawn; more get the large-d treatment
MAX_IMAGE = 1000  # pixels per axis of the space-time image
FIGSIZE = (8, 5)
DPI = 100
FILES = ("trajectory.png", "phase.png", "energy.png", "spacetime.png")
COLUMNS = ("t", "energy", "dissipated", "balance")  # besides x1..xd, v1..vd
MALFORMED_EXIT = 3  # the script's exit status for malformed input (apps/plot.cpp reads it)


class MalformedInput(ValueError):
    """trajectory.csv or summary.json is not what `fracvi run` writes: the message names the
    file, the line and what is wrong (not matplotlib's fault)."""


def _locate_bad_line(path, names):
    """The first line of the CSV at `path` that does not hold len(names) numbers, as a
    MalformedInput (called when np.loadtxt failed, to say where)."""
    with open(path, encoding="utf-8", errors="replace") as f:
        f.readline()
        for number, line in enumerate(f, start=2):
            fields = line.rstrip("\n").split(",")
            if len(fields) != len(names):
                return MalformedInput(f"{path}, line {number}: {len(fields)} values, the header "
                                      f"has {len(names)} columns")
            for name, field in zip(names, fields):
                try:
                    float(field)
                except ValueError:
                    return MalformedInput(f"{path}, line {number}: column {name} = {field!r} "
                                          f"is not a number")
    return MalformedInput(f"{path}: not a table of numbers")


def _title(summary, what):
    p = summary.get("problem", {})
    m = p.get("model", {})
    alpha = m.get("alpha", float("nan"))
    return (f"{p.get('name', 'fracvi')}: {what}\n"
            f"α = {alpha:g} (damping order 2α = {2 * alpha:g}, {m.get('convention', '')}), "
            f"scheme {summary.get('method', '')}, N = {summary.get('steps', '?')}")


ARRAYS = ("t", "x", "v", "energy", "dissipated", "balance")  # of a trajectory, as load() gives them


def load_summary(directory):
    """summary.json of the run in `directory` as a dict."""
    summary_path = os.path.join(directory, "summary.json")
    with open(summary_path, encoding="utf-8", errors="replace") as f:
        try:
            summary = json.load(f)
        except json.JSONDecodeError as e:
            raise MalformedInput(f"{summary_path}, line {e.lineno}: {e.msg}") from None
    if not isinstance(summary, dict):
        raise MalformedInput(f"{summary_path}, line 1: not a JSON object")
    return summary


def trajectory_file(directory):
    """The trajectory of the run in `directory`: trajectory.npz (fracvi.write(..., format="npz"))
    or trajectory.csv (writing one removes the other)."""
    npz = os.path.join(directory, "trajectory.npz")
    return npz if os.path.exists(npz) else os.path.join(directory, "trajectory.csv")


def load_trajectory(directory):
    """The trajectory of the run in `directory` as arrays t, x (rows × d), v, energy, dissipated,
    balance (and step, from trajectory.npz only). trajectory.csv is read with np.loadtxt, not
    genfromtxt: a chain of 10^5 masses has 2·10^5 + 4 columns."""
    path = trajectory_file(directory)
    if path.endswith(".npz"):
        try:
            with np.load(path, allow_pickle=False) as f:
                arrays = {name: f[name] for name in f.files}
        except (OSError, ValueError) as e:
            raise MalformedInput(f"{path}: not a NumPy .npz archive ({e})") from None
        missing = [name for name in ARRAYS if name not in arrays]
        if missing:
            raise MalformedInput(f"{path}: lacks the array(s) {', '.join(missing)} "
                                 f"({', '.join(ARRAYS)}, step)")
        return arrays
    with open(path, encoding="utf-8", errors="replace") as f:
        names = f.readline().strip().split(",")
    missing = [c for c in COLUMNS + ("x1", "v1") if c not in names]
    if missing:
        raise MalformedInput(f"{path}, line 1: the header lacks the column(s) "
                             f"{', '.join(missing)} (t,x1..xd,v1..vd,energy,dissipated,balance)")
    try:
        values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError:
        raise _locate_bad_line(path, names) from None
    if values.size and values.shape[1] != len(names):
        raise _locate_bad_line(path, names)
    if values.size == 0:
        values = np.empty((0, len(names)))
    data = {n: values[:, k] for k, n in enumerate(names)}
    xs = [n for n in names if n.startswith("x")]
    vs = [n for n in names if n.startswith("v")]
    return dict(t=data["t"], x=np.column_stack([data[n] for n in xs]),
                v=np.column_stack([data[n] for n in vs]), energy=data["energy"],
                dissipated=data["dissipated"], balance=data["balance"])


def load(directory):
    """(arrays, summary): the trajectory (load_trajectory) and summary.json (a dict)."""
    summary = load_summary(directory)
    return load_trajectory(directory), summary


def _largest_excursion(x):
    """Index of the coordinate with the largest max_t |x_i(t)| (NaN rows ignored)."""
    with np.errstate(invalid="ignore"):
        peak = np.nanmax(np.abs(x), axis=0) if len(x) else np.zeros(x.shape[1])
    peak = np.where(np.isfinite(peak), peak, -1.0)
    return int(np.argmax(peak))


def _shown_components(x):
    """The coordinates the trajectory plot draws: all for d <= MAX_COMPONENTS, else the first,
    middle and last and the one with the largest excursion."""
    d = x.shape[1]
    if d <= MAX_COMPONENTS:
        return list(range(d))
    return sorted({0, (d - 1) // 2, d - 1, _largest_excursion(x)})


def _block_extreme(a, size):
    """Columns of a reduced in blocks of `size`: each block keeps its entry of largest |value|
    (a narrow pulse stays visible, which taking every size-th column would miss)."""
    rows, n = a.shape
    if size <= 1:
        return a
    pad = (-n) % size
    if pad:
        a = np.concatenate([a, np.full((rows, pad), np.nan)], axis=1)
    blocks = a.reshape(rows, -1, size)
    magnitude = np.where(np.isfinite(blocks), np.abs(blocks), -1.0)
    pick = np.argmax(magnitude, axis=2)
    return np.take_along_axis(blocks, pick[..., None], axis=2)[..., 0]


def spacetime_image(t, x):
    """(image, sites, times): x_i(t) reduced to at most MAX_IMAGE × MAX_IMAGE for display, rows
    = times, columns = sites. Sites are cropped to where the chain moved (max_t |x_i| above 10^-3
    of the maximum, with a margin) when that is less than half of them; `sites` = (first, last,
    block) in 1-based site numbers, `times` the row times."""
    rows, d = x.shape
    lo, hi = 0, d - 1
    with np.errstate(invalid="ignore"):
        peak = np.nanmax(np.abs(x), axis=0) if rows else np.zeros(d)
    top = np.nanmax(peak) if np.isfinite(peak).any() else 0.0
    if top > 0:
        active = np.flatnonzero(peak > 1e-3 * top)
        if active.size and active[-1] - active[0] + 1 < d // 2:
            margin = max(2, (active[-1] - active[0] + 1) // 10)
            lo, hi = max(0, active[0] - margin), min(d - 1, active[-1] + margin)
    step_t = max(1, -(-rows // MAX_IMAGE))
    block = max(1, -(-(hi - lo + 1) // MAX_IMAGE))
    image = _block_extreme(x[::step_t, lo:hi + 1], block)
    return image, (lo + 1, hi + 1, block), np.asarray(t)[::step_t]


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
    marker = "." if len(t) <= 60 and d > MAX_COMPONENTS else None  # thinned output: show samples

    fig1 = _new_figure(pyplot)
    ax = fig1.subplots()
    for i in _shown_components(x):
        ax.plot(t, x[:, i], lw=1.2, marker=marker, ms=4, label=f"$x_{{{i + 1}}}(t)$")
    if d > MAX_COMPONENTS:
        ax.plot([], [], " ", label=f"(first, middle, last, largest of {d}; see spacetime.png)")
    ax.set_xlabel("time $t$")
    ax.set_ylabel("position $x_i$")
    ax.set_title(_title(summary, "trajectory"), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig1.tight_layout()

    fig2 = _new_figure(pyplot)
    ax = fig2.subplots()
    c = 0 if d <= MAX_COMPONENTS else _largest_excursion(x)
    which = "first component" if c == 0 else f"component {c + 1}, the largest excursion"
    ax.plot(x[:, c], v[:, c], lw=0.9, marker=marker, ms=4, label="trajectory")
    ax.plot(x[0, c], v[0, c], "o", color="tab:green", label="start")
    ax.plot(x[-1, c], v[-1, c], "s", color="tab:red", label="end")
    ax.set_xlabel(f"position $x_{{{c + 1}}}$")
    ax.set_ylabel(f"velocity $v_{{{c + 1}}}$")
    ax.set_title(_title(summary, f"phase portrait ({which})"), fontsize=10)
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
    if d <= MAX_COMPONENTS:
        return [fig1, fig2, fig3]

    fig4 = _new_figure(pyplot)
    ax = fig4.subplots()
    image, (first, last, block), times = spacetime_image(t, x)
    finite = np.abs(image[np.isfinite(image)])
    scale = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    dt = float(np.mean(np.diff(times))) if len(times) > 1 else 1.0
    mesh = ax.imshow(image, origin="lower", aspect="auto", interpolation="nearest",
                     cmap="RdBu_r", vmin=-scale, vmax=scale,
                     extent=(first - 0.5, last + 0.5, times[0] - dt / 2, times[-1] + dt / 2))
    fig4.colorbar(mesh, ax=ax, label="position $x_i(t)$")
    ax.set_xlabel(f"site $i$ (of {d}; sites {first}–{last} shown"
                  + (f", blocks of {block}: largest |x_i|)" if block > 1 else ")"))
    ax.set_ylabel(f"time $t$ ({len(times)} stored rows)")
    ax.set_title(_title(summary, "space-time image of $x_i(t)$"), fontsize=10)
    fig4.tight_layout()
    return [fig1, fig2, fig3, fig4]


def save(figs, directory):
    """Writes the figures of figures() as trajectory.png, phase.png, energy.png (and
    spacetime.png for d > MAX_COMPONENTS); returns the paths."""
    os.makedirs(directory, exist_ok=True)
    paths = []
    for fig, name in zip(figs, FILES):
        path = os.path.join(directory, name)
        fig.savefig(path)
        paths.append(path)
    return paths


def plot_run(directory):
    """Draws the plots of the run in `directory` (trajectory.csv, summary.json) into it. A
    spacetime.png left there by an earlier run with d > 8 is removed when this one has none."""
    arrays, summary = load(directory)
    arrays = {name: arrays[name] for name in ARRAYS}
    paths = save(figures(summary=summary, **arrays), directory)
    stale = os.path.join(directory, FILES[-1])
    if stale not in paths and os.path.exists(stale):
        os.remove(stale)
    return paths


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot.py RUN_DIRECTORY")
    try:
        for p in plot_run(sys.argv[1]):
            print(p)
    except MalformedInput as e:
        print(e, file=sys.stderr)
        sys.exit(MALFORMED_EXIT)
