"""Tables and pictures of a parameter sweep (`fracvi sweep`, fracvi.sweep).

As a module: table(columns, rows) and load(path) give the results as a SweepResult, a dict of
NumPy columns; plot(result, ...) draws a quantity against one parameter (a line per value of a
second one, if any) or as a heat map over two.
As a script (Debian's /usr/bin/python3 with matplotlib):

    python3 plot_sweep.py DIR [QUANTITY] [--x PARAM] [--y PARAM] [--out FILE]

reads DIR/results.csv and writes DIR/sweep-QUANTITY.png (default quantity: energy_final).

Drawn on a matplotlib Figure with the Agg canvas, not through pyplot (no global state, works
headless); matplotlib is imported on first use.
"""
import csv
import os
import sys

import numpy as np

FIGSIZE = (8, 5.5)
DPI = 100
# Columns that hold counts: int64 arrays. Other numeric columns are float64 (an empty field, e.g.
# the final state of a case refused before any run, is NaN); text columns are str arrays.
INTEGER_COLUMNS = ("case", "steps_done", "newton_iterations", "max_newton_iterations_per_step")


class SweepResult(dict):
    """The results table of a sweep: column name -> NumPy array, one entry per case in case order.

    `parameters` names the swept columns (the fields of the problem, e.g. "model.alpha"), in the
    order of the grid. Columns: case, the parameters, status ("success", "invalid", "error" or
    the run's status), message, steps_done, final_time, x1..xd and v1..vd (save = "final" or
    "trajectory"), energy_initial, energy_final, dissipated, max_balance_error, mirror_error,
    error_estimate, error_order, newton_iterations, max_newton_iterations_per_step, wall_seconds.
    """

    def __init__(self, columns, parameters):
        super().__init__(columns)
        self.parameters = list(parameters)

    @property
    def ok(self):
        """Boolean mask of the cases that succeeded."""
        return self["status"] == "success"

    def __repr__(self):
        n = len(self["case"]) if "case" in self else 0
        return (f"SweepResult({n} cases, {int(np.sum(self.ok))} succeeded, parameters "
                f"{self.parameters})")


def _column(name, values):
    if name in INTEGER_COLUMNS:
        return np.array([int(v) for v in values], dtype=np.int64)
    try:
        return np.array([float(v) if v != "" else np.nan for v in values], dtype=np.float64)
    except ValueError:
        return np.array(values, dtype=str)


def table(columns, rows):
    """A SweepResult from results.csv's header and rows (lists of field texts)."""
    parameters = columns[1:columns.index("status")]
    data = {name: _column(name, [row[k] for row in rows]) for k, name in enumerate(columns)}
    return SweepResult(data, parameters)


def load(path):
    """The SweepResult of a results.csv (or of the sweep output directory holding it)."""
    if os.path.isdir(path):
        path = os.path.join(path, "results.csv")
    with open(path, encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    return table(rows[0], rows[1:])


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=FIGSIZE, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _log_scale(values):
    """Log axis for positive values spread over more than a decade (logspace, loguniform)."""
    v = values[np.isfinite(values)]
    return v.size > 1 and np.all(v > 0) and v.max() / v.min() >= 10


def _edges(centres, log):
    """Cell edges around sorted cell centres: midway between neighbours (in log on a log axis)."""
    c = np.log(centres) if log else centres.astype(float)
    if c.size == 1:
        half = np.log(2.0) if log else 0.5
        e = np.array([c[0] - half, c[0] + half])
    else:
        inner = (c[1:] + c[:-1]) / 2
        e = np.concatenate([[2 * c[0] - inner[0]], inner, [2 * c[-1] - inner[-1]]])
    return np.exp(e) if log else e


def plot(result, quantity="energy_final", x=None, y=None, file=None):
    """A Figure of `quantity` over the sweep: a heat map over (x, y) when y is given or (y=None)
    the sweep has two parameters; otherwise (y=False, or one parameter) quantity against x, one
    line per value of the other parameter of a two-parameter sweep.
    Cases that did not succeed are left blank (heat map) or marked with a cross (lines).
    Written to `file` if given. Returns the matplotlib Figure."""
    if quantity not in result:
        raise KeyError(f"no column {quantity!r}; columns: {', '.join(result)}")
    parameters = result.parameters
    x = x or parameters[0]
    others = [p for p in parameters if p != x]
    if y is None and len(parameters) == 2:
        y = others[0]
    y = y or None  # False: lines
    for p in (x, y):
        if p is not None and p not in result:
            raise KeyError(f"no parameter column {p!r}; parameters: {', '.join(parameters)}")
    values = np.where(result.ok, result[quantity].astype(float), np.nan)
    fig = _figure()
    ax = fig.add_subplot()
    xs = result[x]
    if y is not None:
        ys = result[y]
        ux, uy = np.unique(xs), np.unique(ys)
        grid = np.full((uy.size, ux.size), np.nan)
        grid[np.searchsorted(uy, ys), np.searchsorted(ux, xs)] = values
        finite = grid[np.isfinite(grid)]
        norm = None
        if finite.size and np.all(finite > 0) and finite.max() / finite.min() > 100:
            from matplotlib.colors import LogNorm  # energies decaying over decades
            norm = LogNorm(finite.min(), finite.max())
        log_x = ux.dtype.kind == "f" and _log_scale(ux)
        log_y = uy.dtype.kind == "f" and _log_scale(uy)
        # Text values (method.scheme) get one cell each, labelled.
        ex = _edges(ux, log_x) if ux.dtype.kind == "f" else np.arange(ux.size + 1) - 0.5
        ey = _edges(uy, log_y) if uy.dtype.kind == "f" else np.arange(uy.size + 1) - 0.5
        mesh = ax.pcolormesh(ex, ey, grid, shading="flat", cmap="viridis", norm=norm)
        if ux.dtype.kind != "f":
            ax.set_xticks(np.arange(ux.size), ux)
        if uy.dtype.kind != "f":
            ax.set_yticks(np.arange(uy.size), uy)
        fig.colorbar(mesh, ax=ax, label=quantity)
        ax.set_ylabel(y)
        if log_y:
            ax.set_yscale("log")
    else:
        groups = result[others[0]] if len(others) == 1 else np.zeros(len(xs))
        for g in np.unique(groups):
            member = groups == g
            order = np.argsort(xs[member], kind="stable")
            label = f"{others[0]} = {g:g}" if len(others) == 1 and groups.dtype.kind == "f" \
                else (f"{others[0]} = {g}" if len(others) == 1 else None)
            ax.plot(xs[member][order], values[member][order], "o-", ms=3, label=label)
        failed = ~result.ok
        if np.any(failed):
            ax.plot(xs[failed], np.zeros(np.sum(failed)), "rx", label="failed")
        if len(others) == 1 or np.any(failed):
            ax.legend(fontsize="small")
        ax.set_ylabel(quantity)
    ax.set_xlabel(x)
    if xs.dtype.kind == "f" and _log_scale(xs):
        ax.set_xscale("log")
    n_ok = int(np.sum(result.ok))
    ax.set_title(f"{quantity} over the sweep ({n_ok} of {len(values)} cases succeeded)")
    fig.tight_layout()
    if file is not None:
        fig.savefig(file)
    return fig


def main(argv):
    import argparse
    parser = argparse.ArgumentParser(description="Plot a fracvi sweep's results.csv")
    parser.add_argument("directory")
    parser.add_argument("quantity", nargs="?", default="energy_final")
    parser.add_argument("--x")
    parser.add_argument("--y")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    result = load(args.directory)
    out = args.out or os.path.join(args.directory, f"sweep-{args.quantity}.png")
    plot(result, args.quantity, x=args.x, y=args.y, file=out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
