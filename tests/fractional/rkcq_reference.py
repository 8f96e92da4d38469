#!/usr/bin/python3
"""High-precision reference values of the Runge–Kutta convolution-quadrature block weights.

Writes tests/fractional/rkcq_reference_data.inc (included by runge_kutta_cq_test.cpp): the s × s
block weights W_j of K(s) = s^β for the s-stage Lobatto IIIC method, s = 2, 3, 4, several β and
lags up to 10^7, correct to 30 digits or more. Run with Debian's Python (python3-mpmath):

    /usr/bin/python3 tests/fractional/rkcq_reference.py        # about 10 minutes on one core

W_j are the Taylor coefficients of Δ(ζ)^β, Δ(ζ) = (A + ζ/(1 − ζ) 𝟙bᵀ)^{−1}. Nothing here uses the
real-axis (Stieltjes) representation that the C++ code evaluates; two other evaluations are used,
at 50 significant digits, and checked against each other where both apply:

1. Cauchy integral on the circle |ζ| = 2/5 (lags 0 … 12): W_j = (1/M) Σ_k Δ(ζ_k)^β ζ_k^{−j} with
   M = 256 equispaced points (shifted off the real axis, where Δ(ζ) can be defective), Δ(ζ) from its definition (a matrix inverse), Δ(ζ)^β through an
   eigendecomposition (mpmath.eig; the eigenvalues of Δ(ζ) lie in Re λ > 0 for |ζ| < 1 by
   A-stability). Aliasing error ~ 0.4^{256} relative; round-off amplification 0.4^{−12}.

2. Dunford–Taylor integral in the frequency plane (lags ≥ 2): with Δ(ζ) = D0 + ζ D1 (checked
   here numerically from the definition; it holds because the method is stiffly accurate) and
   R(λ) = (λ − D0)^{−1}, the Neumann series of the resolvent gives
       W_j = (1/2πi) ∮ λ^β (R(λ) D1)^j R(λ) dλ
   over a contour enclosing spec(D0) and not the branch cut of λ^β. The contour is the left-opening
   hyperbola λ(θ) = σμ(1 + sin(iθ − a)) (Weideman & Trefethen 2007), traversed downwards, closed
   at infinity on the right (the integrand decays like |λ|^{β+1−2j}), with the scale σ ≈ 1/j so
   that (R D1)^j = O(1) where the contour crosses the positive axis. The trapezoidal rule in θ
   converges geometrically; (R D1)^j by binary powering of the s × s matrix (no stability
   function, no Sherman–Morrison). Each weight is computed on two different contours with two
   different steps; the script stops if they disagree beyond 1e-35 relative (normwise).

The lags 2 … 12 are computed both ways and must agree to 1e-35 (normwise relative).
"""
import itertools
import os
import sys
import time

import mpmath as mp

mp.mp.dps = 50

STAGES = (2, 3, 4)
ORDERS = ("0.1", "0.3", "0.5", "0.9", "1.1", "1.5", "1.7", "1.95")
LAGS = (0, 1, 2, 3, 4, 5, 10, 100, 1000, 10**4, 10**5, 10**6, 10**7)
CIRCLE_LAGS = 12
CIRCLE_POINTS = 256
AGREE = mp.mpf("1e-35")


def lobatto_iiic(s):
    """A, b of the s-stage Lobatto IIIC method (Hairer & Wanner II, Sect. IV.5)."""
    f = mp.mpf
    if s == 2:
        a = [[f(1) / 2, -f(1) / 2], [f(1) / 2, f(1) / 2]]
        b = [f(1) / 2, f(1) / 2]
    elif s == 3:
        a = [[f(1) / 6, -f(1) / 3, f(1) / 6], [f(1) / 6, f(5) / 12, -f(1) / 12],
             [f(1) / 6, f(2) / 3, f(1) / 6]]
        b = [f(1) / 6, f(2) / 3, f(1) / 6]
    elif s == 4:
        r5 = mp.sqrt(5)
        a = [[f(1) / 12, -r5 / 12, r5 / 12, -f(1) / 12],
             [f(1) / 12, f(1) / 4, (10 - 7 * r5) / 60, r5 / 60],
             [f(1) / 12, (10 + 7 * r5) / 60, f(1) / 4, -r5 / 60],
             [f(1) / 12, f(5) / 12, f(5) / 12, f(1) / 12]]
        b = [f(1) / 12, f(5) / 12, f(5) / 12, f(1) / 12]
    return mp.matrix(a), mp.matrix(b)


def delta(a, b, zeta):
    s = a.rows
    ones_bt = mp.matrix(s, s)
    for i in range(s):
        for k in range(s):
            ones_bt[i, k] = b[k]
    return mp.inverse(a + (zeta / (1 - zeta)) * ones_bt)


def power(m, beta):
    """Principal m^β through an eigendecomposition (eigenvalues in the open right half plane)."""
    e, er = mp.eig(m)
    for lam in e:
        assert mp.re(lam) > 0, lam
    d = mp.diag([lam**beta for lam in e])
    return er * d * mp.inverse(er)


def circle_weights(a, b, betas, count):
    """W_0 … W_{count−1} for every β by the Cauchy integral on |ζ| = 1/2."""
    s = a.rows
    rho = mp.mpf(2) / 5
    m = CIRCLE_POINTS
    sums = {beta: [mp.matrix(s, s) for _ in range(count)] for beta in betas}
    # Points off the real axis (Δ(ζ) can be defective at real ζ, e.g. s = 2, ζ = 1/2), in
    # conjugate pairs: Δ(conj ζ) = conj Δ(ζ).
    for k in range(m // 2):
        zeta = rho * mp.expjpi(mp.mpf(2 * k + 1) / m)
        e, er = mp.eig(delta(a, b, zeta))
        er_inv = mp.inverse(er)
        assert mp.mnorm(er * mp.diag(e) * er_inv - delta(a, b, zeta), 1) < AGREE
        for lam in e:
            assert mp.re(lam) > 0, lam
        weight = 2
        for beta in betas:
            f = er * mp.diag([lam**beta for lam in e]) * er_inv
            zpow = mp.mpc(1)
            for j in range(count):
                term = f * zpow
                for i, l in itertools.product(range(s), range(s)):
                    sums[beta][j][i, l] += weight * mp.re(term[i, l])
                zpow /= zeta
    return {beta: [w / m for w in sums[beta]] for beta in betas}


def hyperbola_weight(d0, d1, betas, j, a_angle, crossing, h):
    """W_j for every β by the trapezoidal rule on the hyperbola (see the module docstring)."""
    s = d0.rows
    min_re = min(mp.re(lam) for lam in mp.eig(d0)[0])
    mu = crossing / (1 - mp.sin(a_angle))
    # Scale: e^{jλ} = O(1) at the crossing, and the vertical line Re λ = σμ (the contour deformed
    # by the strip half-width a towards a = 0) stays left of spec(D0).
    sigma = min(mp.mpf(1) / j, mp.mpf("0.45") * min_re / mu)
    eye = mp.eye(s)
    total = {beta: mp.matrix(s, s) for beta in betas}
    tiny = mp.mpf(10) ** (-(mp.mp.dps + 5))

    def term(theta):
        lam = sigma * mu * (1 + mp.sin(1j * theta - a_angle))
        dlam = sigma * mu * 1j * mp.cos(1j * theta - a_angle)
        r = mp.inverse(lam * eye - d0)
        core = ((r * d1) ** j) * r * dlam
        return {beta: core * lam**beta for beta in betas}

    def add(t, wt):
        for beta in betas:
            total[beta] += t[beta] * wt

    def norm(t):
        return max(mp.mnorm(t[beta], 1) for beta in betas)

    t0 = term(mp.mpf(0))
    add(t0, 1)
    scale = norm(t0)
    for sign in (1, -1):
        small = 0
        k = 1
        while small < 3:
            t = term(sign * k * h)
            add(t, 1)
            n = norm(t)
            scale = max(scale, n)
            small = small + 1 if n < tiny * scale else 0
            k += 1
    out = {}
    for beta in betas:
        w = total[beta] * (-h / (2j * mp.pi))
        out[beta] = mp.matrix([[mp.re(w[i, l]) for l in range(s)] for i in range(s)])
        imag = max(abs(mp.im(w[i, l])) for i in range(s) for l in range(s))
        assert imag < AGREE * mp.mnorm(out[beta], 1), (j, beta, imag)
    return out


def rel_diff(x, y):
    return mp.mnorm(x - y, 1) / mp.mnorm(y, 1)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    betas = [mp.mpf(b) for b in ORDERS]
    lines = []
    start = time.time()
    for s in STAGES:
        a, b = lobatto_iiic(s)
        d0 = mp.inverse(a)
        third = mp.mpf(1) / 3
        d1 = (delta(a, b, third) - d0) / third
        # Stiffly accurate: Δ(ζ) is affine in ζ (checked, not assumed).
        assert rel_diff(delta(a, b, mp.mpf("-0.7")), d0 + mp.mpf("-0.7") * d1) < AGREE
        circle = circle_weights(a, b, betas, CIRCLE_LAGS + 1)
        for j in LAGS:
            if j >= 2:
                w1 = hyperbola_weight(d0, d1, betas, j, mp.pi / 4, mp.mpf(1), mp.mpf("0.04"))
                w2 = hyperbola_weight(d0, d1, betas, j, mp.mpf("0.6"), mp.mpf("0.7"),
                                      mp.mpf("0.035"))
                for beta in betas:
                    diff = rel_diff(w1[beta], w2[beta])
                    assert diff < AGREE, (s, j, beta, diff)
                    if j <= CIRCLE_LAGS:
                        diff = rel_diff(w1[beta], circle[beta][j])
                        assert diff < AGREE, (s, j, beta, "circle", diff)
                weights = w1
            else:
                weights = {beta: circle[beta][j] for beta in betas}
            for beta, text in zip(betas, ORDERS):
                w = weights[beta]
                for i, l in itertools.product(range(s), range(s)):
                    lines.append("{%d, %s, %d, %d, %d, %s}," %
                                 (s, text, j, i, l, mp.nstr(w[i, l], 36, min_fixed=1,
                                                            max_fixed=0)))
            print("s=%d lag=%d done (%.0f s)" % (s, j, time.time() - start), flush=True)
    out = os.path.join(here, "rkcq_reference_data.inc")
    with open(out, "w") as fh:
        fh.write("// Generated by tests/fractional/rkcq_reference.py (mpmath, 50 digits): do not "
                 "edit.\n// {stages, beta, lag, row, col, W_lag(row, col)} of the Lobatto IIIC "
                 "RKCQ weights of s^beta.\n")
        fh.write("\n".join(lines) + "\n")
    print("wrote %d entries to %s" % (len(lines), out))


if __name__ == "__main__":
    sys.exit(main())
