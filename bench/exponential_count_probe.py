"""How few exponentials can the fast history's tail have? (issue 17 item 2: "fewer exponentials").

    /usr/bin/python3 bench/exponential_count_probe.py [beta] [eps]      (defaults 1.5 1e-6)

The example chain's run (d = 1000, h = 0.01, N = 10^6: the budget's ε = 1e-6, window n0 = 16,
largest lag 2^20) steps with K = 33 exponentials; the recursions are 2K multiply–adds per degree
of freedom a step, the largest share of its step. This re-does src/fractional/exponential_fit.cpp's
fit in NumPy (trapezoidal nodes in log s, docs/theory/fast_history.md §3; pivoted QR of the
relative-error matrix and the smallest K whose relative error is ≤ ε/2 at every lag, §4) and asks
whether another fit reaches the same accuracy with fewer terms:

1. rows weighted by (m/n0)^γ: a relative error allowed to grow with the lag, since the far lags'
   weights are small — compared at equal worst-case sum error Σ|ĉ_m − c_m| and at equal error of
   the sum over a smooth history (x̃ = cos t − 1, h = 0.01, the measure of c_H in
   history_budget.hpp);
2. a finer trapezoidal grid (more candidate nodes for the pivoting);
3. the nodes themselves refined (Levenberg–Marquardt on (ln λ_j, w_j), reweighted towards the
   minimax relative error).

Every error is measured at every lag n0 … 2^20 against the exact weights (long-double recurrence).
Not a test; bench/RESULTS.md records what it printed. About five minutes.
"""
import sys

import numpy as np
import scipy.linalg as sl
from scipy.optimize import least_squares
from scipy.special import gamma as gamma_function

BETA = float(sys.argv[1]) if len(sys.argv) > 1 else 1.5
EPS = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-6
N0 = 16
MAX_LAG = 2**20

# Exact Grünwald–Letnikov weights c_m = c_{m−1} (m − 1 − β)/m in long double.
_m = np.arange(1, MAX_LAG + 1, dtype=np.longdouble)
_c = np.concatenate([[np.longdouble(1)], np.cumprod((_m - 1 - BETA) / _m)])
C = _c.astype(np.float64)
LAGS = np.arange(N0, MAX_LAG + 1)
TAIL = C[N0:]
TAIL_SUM = np.sum(np.abs(TAIL))
X_SMOOTH = np.cos(np.arange(MAX_LAG + 1) * 0.01) - 1.0


def trapezoidal_step(share):
    """The largest h whose aliasing model (3.1) is ≤ share·ε."""
    def model(h):
        return (2 * np.sqrt(2 * np.pi) * (2 * np.pi / h) ** (BETA + 0.5) * np.exp(-np.pi**2 / h)
                / gamma_function(1 + BETA))
    h = 0.05
    while model(h + 1e-3) <= share * EPS:
        h += 1e-3
    return h


def trapezoidal_nodes(h):
    p = abs(np.sin(np.pi * BETA)) / np.pi
    target = 0.01 * EPS
    u_lo = np.log(target * abs(TAIL[-1]) * (1 + BETA) / p) / (1 + BETA)
    s_hi = max(np.log(p / (target * abs(TAIL[0]) * (N0 - BETA))) / (N0 - BETA), 1e-3)
    s = np.exp(np.arange(np.log(s_hi), u_lo, -h))
    q = h * s * (-(np.sin(np.pi * BETA) / np.pi)) * np.exp(BETA * np.log(np.expm1(s)) - N0 * s)
    return s, q


def sample_lags(dense, per_decade):
    lags = list(range(N0, N0 + dense + 1))
    x = float(lags[-1])
    while x < MAX_LAG:
        x *= 10 ** (1 / per_decade)
        lags.append(min(int(round(x)), MAX_LAG))
    return np.unique(np.array(lags))


ROWS = sample_lags(256, 60)


def errors(lam, w):
    """(max relative error, Σ|ĉ − c| / Σ|c|, max over n of |Σ_m (ĉ_m − c_m) x̃_{n−m}|)."""
    approx = np.zeros(len(LAGS))
    for lj, wj in zip(lam, w):
        approx += wj * np.exp(-lj * (LAGS - N0))
    e = approx - TAIL
    padded = np.zeros(MAX_LAG + 1)
    padded[N0:] = e
    size = 1 << 22
    smooth = np.fft.irfft(np.fft.rfft(padded, size) * np.fft.rfft(X_SMOOTH, size), size)
    return (np.max(np.abs(e / TAIL)), np.sum(np.abs(e)) / TAIL_SUM,
            np.max(np.abs(smooth[:MAX_LAG + 1])))


class PivotedFit:
    """The production fit's pivoting and least squares, rows weighted by (m/n0)^γ."""

    def __init__(self, h, gamma=0.0):
        self.s, self.q = trapezoidal_nodes(h)
        scale = 1.0 / (np.abs(C[ROWS]) * (ROWS / N0) ** gamma)
        self.a = self.q[None, :] * np.exp(-np.outer(ROWS - N0, self.s)) * scale[:, None]
        self.b = C[ROWS] * scale
        self.pivots = sl.qr(self.a, pivoting=True, mode="economic")[2]

    def terms(self, k):
        cols = self.pivots[:k]
        v = np.linalg.lstsq(self.a[:, cols], self.b, rcond=None)[0]
        return self.s[cols], self.q[cols] * v

    def first(self, accept, start=16):
        """The smallest K ≥ start whose errors pass `accept`."""
        for k in range(start, len(self.s) + 1):
            err = errors(*self.terms(k))
            if accept(err):
                return k, err
        return None, None


def refined(lam0, w0, sweeps=12):
    """Levenberg–Marquardt on (ln λ, w), rows reweighted towards the minimax relative error."""
    k, rows = len(lam0), sample_lags(256, 120)
    wscale = np.abs(w0).max()

    def residual(x):
        return (np.exp(-np.outer(rows - N0, np.exp(x[:k]))) @ (x[k:] * wscale)) / C[rows] - 1

    x, weight = np.concatenate([np.log(lam0), w0 / wscale]), np.ones(len(rows))
    for _ in range(sweeps):
        x = least_squares(lambda y: residual(y) * weight, x, method="lm", max_nfev=2000,
                          xtol=1e-15, ftol=1e-15).x
        r = np.abs(residual(x))
        weight = np.sqrt(weight**2 * (r / r.max() + 1e-3))
        weight /= weight.max()
    return np.exp(x[:k]), x[k:] * wscale


def main():
    h = trapezoidal_step(0.1)
    base = PivotedFit(h)
    k0, (rel0, l1_0, smooth0) = base.first(lambda e: e[0] <= EPS / 2)
    print(f"beta = {BETA}, eps = {EPS}, n0 = {N0}, max lag 2^20, h = {h:.3f} "
          f"({len(base.s)} quadrature nodes)")
    print(f"production rule: K = {k0}, max relative {rel0:.2e}, sum|err|/sum|c| {l1_0:.2e}, "
          f"smooth-history sum error {smooth0:.2e}", flush=True)
    for gamma in (0.5, 1.0, 1.25):
        fit = PivotedFit(h, gamma)
        k_l1, e_l1 = fit.first(lambda e: e[1] <= l1_0)
        k_sm, e_sm = fit.first(lambda e: e[2] <= smooth0)
        print(f"rows weighted (m/n0)^{gamma}: K = {k_l1} at equal sum|err| "
              f"({e_l1[1] if e_l1 else float('nan'):.2e}), K = {k_sm} at equal smooth-history "
              f"error ({e_sm[2] if e_sm else float('nan'):.2e})", flush=True)
    for finer in (0.3, 0.2):
        k, e = PivotedFit(finer).first(lambda e: e[0] <= EPS / 2)
        print(f"trapezoidal step {finer}: K = {k} by the production rule", flush=True)
    for k in (k0 - 7, k0 - 5, k0 - 3):
        lam, w = refined(*base.terms(k))
        rel = errors(lam, w)[0]
        print(f"K = {k}, nodes refined: max relative {rel:.2e} "
              f"({'meets' if rel <= EPS / 2 else 'misses'} eps/2 = {EPS / 2:.1e})", flush=True)


if __name__ == "__main__":
    main()
