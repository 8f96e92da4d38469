#!/usr/bin/python3
"""The start-up of fvi-lobatto3/4 at t = 0 (docs/theory/fvi_lobatto.md §13): what limits their
orders on fractional problems, and the series split.  Run with Debian's /usr/bin/python3 (numpy,
scipy, mpmath); uses the reference prototype fvi_lobatto.py next to this file.

For a linear problem  M x'' + R D^β x + K x = f,  f = Σ_φ f_φ t^φ (power laws), the solution is the
fractional power series  x = Σ_γ c_γ t^γ  over the exponents generated from 0, 1 and the φ by
adding 2 and 2 − β (fractional_series: the coefficient of t^e in the equation gives c_{e+2}).  It
serves twice:

  * as the independent reference (40 digits, summed to γ ≤ 120: the terms fall like 1/Γ(γ));
  * as the known singular part S = Σ_{1<γ≤g} c_γ t^γ of the solution near t_0, subtracted in one
    of two ways:
      "memory":  the split of the damping memory extended, X̃ = X − P − S, with D^β S entering by
                 exact moments like D^β P (the C++ method.split = "series");
      "full":    the change of variables x = w + S: the scheme integrates w with the forcing
                 f − M S'' − R D^β S − K S (power laws, exact moments), x_n = w_n + S(t_n).

Usage:
    /usr/bin/python3 tools/prototypes/lobatto_start.py cap                  # §13.1
    /usr/bin/python3 tools/prototypes/lobatto_start.py study CASE S VARIANTS STEPS
        CASE: a (Caputo d = 2, 2α = 0.6), b (the same, 2α = 1.5), ch / cr (Bagley–Torvik D^{1/2},
        q = t³ / D^{3/2}, q = t^{5/2}, zero data), chd / crd (the same with x0 = 1, v0 = ½);
        VARIANTS: comma-separated none, memory:g, full:g, nonint:g (g: the largest exponent of S);
        STEPS: comma-separated N.  Prints the max error over all nodes and at the sample times.
"""
import math
import os
import sys

import mpmath as mp
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fvi_lobatto as fl  # noqa: E402

mp.mp.dps = 40
np.seterr(all="ignore")

# The d = 2 reference system of the tests (tests/support/test_problems.hpp).
M2 = [[2.0, 0.3], [0.3, 1.0]]
R2 = [[0.4, 0.1], [0.1, 0.2]]
K2 = [[5.0, -1.0], [-1.0, 3.0]]
X0, V0 = [1.0, -0.5], [0.3, 0.8]


def dcoef(g, beta, caputo=True, lib=math):
    """g(γ) with D^β t^γ = g(γ) t^{γ−β} (Caputo: 0 for t^0, and for t^1 when β > 1)."""
    if caputo and (g == 0 or (g == 1 and beta > 1)):
        return 0.0
    if lib is mp:
        return mp.gamma(g + 1) * mp.rgamma(g + 1 - beta)
    x = g + 1 - beta
    if x <= 0 and abs(x - round(x)) < 1e-12:
        return 0.0
    return math.gamma(g + 1) / math.gamma(x)


def key(e):
    return round(e, 9)


def fractional_series(M, R, K, beta, x0, v0, forcing, largest, lib=np):
    """{γ: c_γ} for γ ≤ largest (c_0 = x0, c_1 = v0); forcing {φ: f_φ}."""
    mpm = lib is mp
    conv = (lambda v: mp.matrix(list(v))) if mpm else (lambda v: np.array(v, dtype=float))
    Mi = mp.inverse(mp.matrix(M)) if mpm else np.linalg.inv(M)
    Mm, Rm, Km = ((mp.matrix(M), mp.matrix(R), mp.matrix(K)) if mpm
                  else (np.array(M), np.array(R), np.array(K)))
    mul = (lambda A, v: A * v) if mpm else (lambda A, v: A @ v)
    zero = conv([0] * len(x0))
    c = {0.0: conv(x0), 1.0: conv(v0)}
    eqs = set()

    def add_solution(g):
        eqs.add(key(g))
        if dcoef(g, beta) != 0.0:
            eqs.add(key(g - beta))

    add_solution(0.0)
    add_solution(1.0)
    eqs.update(key(e) for e in forcing)
    done = set()
    while True:
        rest = sorted(e for e in eqs if e not in done)
        if not rest:
            return c
        e = rest[0]
        done.add(e)
        if e + 2 > largest + 1e-9:
            continue
        rhs = (conv(forcing[e]) if e in forcing else zero) - mul(Km, c.get(key(e), zero))
        gb = key(e + beta)
        if gb in c:
            rhs = rhs - mul(Rm, c[gb]) * dcoef(gb, beta, lib=mp if mpm else math)
        ee = mp.mpf(e) if mpm else e
        c[key(e + 2)] = mul(Mi, rhs) / ((ee + 2) * (ee + 1))
        add_solution(key(e + 2))


def series(c, t):
    return sum((v * (t ** g if g != 0 else 1) for g, v in c.items()), 0)


class SeriesSplit(fl.Problem):
    """The memory's split P + S (the C++ method.split = "series")."""

    def taylor(self, t):
        tau = np.maximum(t - self.t0, 0.0)[:, None]
        return super().taylor(t) + sum((tau ** g * v[None, :] for g, v in self.S.items()), 0)

    def taylor_force(self, t):
        tau = np.maximum(t - self.t0, 0.0)[:, None]
        return super().taylor_force(t) + sum(
            (dcoef(g, self.beta) * tau ** (g - self.beta) * v[None, :] for g, v in self.S.items()),
            0)


def run(variant, M, R, K, beta, x0, v0, forcing, T, s, N, largest):
    """Positions at the nodes (times, x) of fvi-lobatto{s} with the forcing's exact moments."""
    M, R, K = (np.array(a, float) for a in (M, R, K))
    x0, v0 = np.array(x0, float), np.array(v0, float)
    grad, hess, pot = fl.quadratic(K)

    def force_of(terms):
        if not terms:
            return None
        return lambda t: sum(np.array(v, float) * t ** e for e, v in terms.items()) + 0 * x0

    if variant != "none":
        c = fractional_series(M, R, K, beta, x0, v0,
                              {e: np.array(v, float) for e, v in forcing.items()}, largest)
        S = {g: v for g, v in c.items() if g not in (0.0, 1.0)}
        if variant == "nonint":
            S = {g: v for g, v in S.items() if abs(g - round(g)) > 1e-9}
    if variant == "none":
        pb = fl.Problem(M, R, beta, grad, hess, x0, v0, 0.0, T, force=force_of(forcing), pot=pot)
    elif variant == "memory":
        pb = SeriesSplit(M, R, beta, grad, hess, x0, v0, 0.0, T, force=force_of(forcing),
                         pot=pot)
        pb.S = S
    else:  # full (or nonint): x = w + S, the forcing of w in closed form
        fw = {key(e): np.array(v, float) for e, v in forcing.items()}
        for g, v in S.items():
            for e, term in ((g - 2, -g * (g - 1) * (M @ v)), (g - beta, -dcoef(g, beta) * (R @ v)),
                            (g, -(K @ v))):
                if np.any(term != 0):
                    fw[key(e)] = fw.get(key(e), 0) + term
        pb = fl.Problem(M, R, beta, grad, hess, x0, v0, 0.0, T, force=force_of(fw), pot=pot)
    sch = fl.LobattoFvi(pb, s, N, load="moments").run()
    xs = sch.xs
    if variant in ("full", "nonint"):
        xs = xs + np.array([series(S, t) + 0 * x0 for t in sch.ts])
    return sch.ts, xs


def fit(hs, es, floor=1e-13):
    hs, es = np.array(hs), np.array(es)
    m = es > floor
    return np.polyfit(np.log(hs[m]), np.log(es[m]), 1)[0] if m.sum() >= 2 else float("nan")


def case_data(case):
    sq = math.sqrt(math.pi)
    if case in ("a", "b"):
        return dict(beta=0.6 if case == "a" else 1.5, T=2.0, M=M2, R=R2, K=K2, x0=X0, v0=V0,
                    F={}, samples=8)
    if case == "v":  # x'' + 0.5 D^0.6 x + x = 0, x0 = 0, v0 = ½ (Caputo = Riemann–Liouville)
        return dict(beta=0.6, T=2.0, M=[[1.0]], R=[[0.5]], K=[[1.0]], x0=[0.0], v0=[0.5], F={},
                    samples=8)
    half = case[1] == "h"
    F = ({3.0: [1.0], 1.0: [6.0], 2.5: [16 / (5 * sq)]} if half
         else {0.5: [15 / 4], 1.0: [15 * sq / 8], 2.5: [1.0]})
    data = ([0.0], [0.0]) if len(case) == 2 else ([1.0], [0.5])
    return dict(beta=0.5 if half else 1.5, T=1.0, M=[[1.0]], R=[[1.0]], K=[[1.0]], x0=data[0],
                v0=data[1], F=F, samples=4)


def study(case, s, variants, steps):
    p = case_data(case)
    ref = fractional_series(p["M"], p["R"], p["K"], p["beta"], p["x0"], p["v0"],
                            {e: [mp.mpf(a) for a in v] for e, v in p["F"].items()}, 120, lib=mp)
    for variant in variants:
        name, largest = (variant.split(":") + ["0"])[:2]
        nodes, samples = [], []
        for N in steps:
            ts, xs = run(name, p["M"], p["R"], p["K"], p["beta"], p["x0"], p["v0"], p["F"],
                         p["T"], s, N, float(largest))
            exact = np.array([[float(v) for v in series(ref, mp.mpf(t))] for t in ts])
            e = np.abs(xs - exact).max(axis=1)
            nodes.append(e.max())
            samples.append(e[::max(1, N // p["samples"])].max())
        hs = [p["T"] / N for N in steps]
        for label, errs in (("nodes", nodes), ("samples", samples)):
            local = " ".join(f"{math.log2(errs[i] / errs[i + 1]):.2f}"
                             for i in range(len(errs) - 1))
            print(f"({case}) s = {s} {variant:9s} {label:7s}: "
                  + " ".join(f"{x:.2e}" for x in errs) + f" | local {local} | fit "
                  f"{fit(hs, errs):.2f}", flush=True)


def cap():
    """§13.1: zero data, f = (1, ½) t⁶ on the d = 2 system (x = O(t⁸)), T = 1, max over nodes."""
    for beta, s, steps in ((1.5, 3, (8, 16, 32, 64, 128, 256)), (1.5, 4, (8, 16, 32, 64, 128, 256)),
                           (1.2, 4, (8, 16, 32, 64, 128)), (0.6, 3, (8, 16, 32, 64, 128)),
                           (0.6, 4, (8, 16, 32, 64, 128))):
        ref = fractional_series(M2, R2, K2, beta, [0, 0], [0, 0],
                                {6.0: [mp.mpf(1), mp.mpf(0.5)]}, 140, lib=mp)
        errs = []
        for N in steps:
            ts, xs = run("none", M2, R2, K2, beta, [0, 0], [0, 0], {6.0: [1.0, 0.5]}, 1.0, s, N, 0)
            exact = np.array([[float(v) for v in series(ref, mp.mpf(t))] for t in ts])
            errs.append(np.abs(xs - exact).max())
        local = " ".join(f"{math.log2(errs[i] / errs[i + 1]):.2f}" for i in range(len(errs) - 1))
        print(f"2α = {beta}, s = {s}: " + " ".join(f"{e:.3e}" for e in errs)
              + f" | local {local} | s + 2 − 2α = {s + 2 - beta:.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "cap":
        cap()
    elif len(sys.argv) == 6 and sys.argv[1] == "study":
        study(sys.argv[2], int(sys.argv[3]), sys.argv[4].split(","),
              [int(a) for a in sys.argv[5].split(",")])
    else:
        print(__doc__)
