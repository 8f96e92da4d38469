"""convergence.png of a `fracvi convergence` directory: log-log max error against h.

Run as a script by the CLI (Debian's /usr/bin/python3 with matplotlib):
    plot_convergence.py DIRECTORY
Reads DIRECTORY/convergence.csv and DIRECTORY/convergence.json.
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_convergence(directory):
    with open(os.path.join(directory, "convergence.json"), encoding="utf-8") as f:
        meta = json.load(f)
    data = np.atleast_1d(np.genfromtxt(os.path.join(directory, "convergence.csv"), delimiter=",",
                                       names=True, dtype=None, encoding="utf-8"))
    h, err = data["h"], data["error"]
    ok = np.isfinite(err) & (err > 0)
    fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
    ax.loglog(h[ok], err[ok], "o-", label="max error over the grid")
    p = meta.get("declared_order", 0)
    if p and ok.any():
        i = np.flatnonzero(ok)[-1]
        ax.loglog(h[ok], err[i] * (h[ok] / h[i]) ** p, "k--", lw=0.8,
                  label=f"slope {p} (declared order)")
    m = meta["problem"]["model"]
    ax.set_xlabel("step $h$")
    ax.set_ylabel(r"$\max_k \|x_k - x_{\mathrm{ref}}(t_k)\|_\infty$")
    ax.set_title(f"{meta['problem']['name']}: convergence, α = {m['alpha']:g} "
                 f"(damping order {2 * m['alpha']:g}), scheme {meta.get('method', '')}\n"
                 f"least-squares order {meta['fitted_order']:.3f}; reference: {meta['reference']}",
                 fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    path = os.path.join(directory, "convergence.png")
    fig.savefig(path)
    plt.close(fig)
    return path


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot_convergence.py DIRECTORY")
    print(plot_convergence(sys.argv[1]))
