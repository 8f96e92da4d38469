#!/usr/bin/python3
"""Reference prototype of the Lobatto IIIC Runge–Kutta-CQ fractional variational integrators
fvi-lobatto2/3/4 (docs/theory/fvi_lobatto.md).  Run with Debian's /usr/bin/python3 (numpy, scipy,
mpmath).  Direct O(N²) history, dense linear algebra, Newton with exact derivatives.  Not fast,
meant to be read next to the theory note and to produce the numbers recorded there.

    M x'' + R D^β x + ∇U(x, t) = f(t),   β = 2α ∈ [0, 2),   x ∈ R^d,

discretised on t_n = t0 + n h by the Lobatto–Galerkin discrete Lagrangian on the s Lobatto nodes c
(stage values X_{n,1} = x_n, …, X_{n,s} = x_{n+1}) and the damping R D^β by the Lobatto IIIC RKCQ
acting on the stage values, G_n = h^{−β} Σ_j W_j X̃_{n−j} (+ the exact D^β of the Taylor polynomial
P(t) = x0 + (t − t0) v0, X̃ = X − P).

Usage:
    /usr/bin/python3 tools/prototypes/fvi_lobatto.py [all|weights|published|gradient|mirror|
                                                      energy|stability|orders]
"""
import math
import sys
import time

import mpmath as mp
import numpy as np

# ---------------------------------------------------------------------------------------------
# Lobatto IIIC tableaux (Hairer & Wanner II, Sect. IV.5)
# ---------------------------------------------------------------------------------------------


def lobatto_iiic(s, ctx=None):
    """(A, b, c) as numpy arrays (ctx None) or as mpmath matrices (ctx = mp)."""
    if ctx is None:
        r5 = math.sqrt(5.0)
        one = 1.0
        F = float
    else:
        r5 = ctx.sqrt(5)
        one = ctx.mpf(1)
        F = ctx.mpf
    if s == 2:
        A = [[one / 2, -one / 2], [one / 2, one / 2]]
        b = [one / 2, one / 2]
        c = [0 * one, one]
    elif s == 3:
        A = [[one / 6, -one / 3, one / 6], [one / 6, 5 * one / 12, -one / 12],
             [one / 6, 2 * one / 3, one / 6]]
        b = [one / 6, 2 * one / 3, one / 6]
        c = [0 * one, one / 2, one]
    elif s == 4:
        A = [[one / 12, -r5 / 12, r5 / 12, -one / 12],
             [one / 12, one / 4, (10 - 7 * r5) / 60, r5 / 60],
             [one / 12, (10 + 7 * r5) / 60, one / 4, -r5 / 60],
             [one / 12, 5 * one / 12, 5 * one / 12, one / 12]]
        b = [one / 12, 5 * one / 12, 5 * one / 12, one / 12]
        c = [0 * one, (5 - r5) / 10, (5 + r5) / 10, one]
    else:
        raise ValueError("s must be 2, 3 or 4")
    if ctx is None:
        return np.array(A, dtype=float), np.array(b, dtype=float), np.array(c, dtype=float)
    del F
    return ctx.matrix(A), b, c


def differentiation_matrix(c):
    """D[a, k] = ℓ_k'(c_a), ℓ_k the Lagrange basis on the nodes c (barycentric formula)."""
    s = len(c)
    w = np.array([1.0 / np.prod([c[k] - c[m] for m in range(s) if m != k]) for k in range(s)])
    D = np.zeros((s, s))
    for a in range(s):
        for k in range(s):
            if a != k:
                D[a, k] = (w[k] / w[a]) / (c[a] - c[k])
        D[a, a] = -D[a].sum()
    return D


# ---------------------------------------------------------------------------------------------
# Block weights W_j of Δ(ζ)^β, Δ(ζ) = (A + ζ/(1 − ζ) 𝟙bᵀ)^{−1} = A^{−1} − (ζ/b_1) e_1 e_sᵀ
# ---------------------------------------------------------------------------------------------

_weight_cache = {}


def _lags01_mp(s, beta, dps=40):
    """W_0 = A^{−β} and W_1 = the Fréchet derivative of X ↦ X^β at D0 = A^{−1} in the direction
    D1 = −(1/b_1) e_1 e_sᵀ (Daleckii–Krein: divided differences of λ^β on the eigenvalues of D0),
    at `dps` digits."""
    with mp.workdps(dps):
        A, b, _ = lobatto_iiic(s, mp)
        D0 = A ** -1
        D1 = mp.zeros(s, s)
        D1[0, s - 1] = -1 / b[0]
        lam, V = mp.eig(D0)
        Vi = V ** -1
        P = Vi * D1 * V
        F = mp.zeros(s, s)
        for i in range(s):
            for j in range(s):
                if abs(lam[i] - lam[j]) < mp.mpf(10) ** (-dps // 2):
                    F[i, j] = beta * lam[i] ** (beta - 1)
                else:
                    F[i, j] = (lam[i] ** beta - lam[j] ** beta) / (lam[i] - lam[j])
        W0 = V * mp.diag([l ** beta for l in lam]) * Vi
        H = mp.zeros(s, s)
        for i in range(s):
            for j in range(s):
                H[i, j] = F[i, j] * P[i, j]
        W1 = V * H * Vi
        to = lambda X: np.array([[float(mp.re(X[i, j])) for j in range(s)] for i in range(s)])
        return to(W0), to(W1)


def _log_abs_r(s, z):
    """log|r(−z)| and sign r(−z) for the Lobatto IIIC stability function (the (s−2, s) Padé
    approximant of e^{−z}), without cancellation for small z."""
    if s == 2:
        Q = 1 + z + z * z / 2
        PmQ = -z - z * z / 2
        P = np.ones_like(z)
    elif s == 3:
        Q = 1 + 3 * z / 4 + z ** 2 / 4 + z ** 3 / 24
        PmQ = -z - z ** 2 / 4 - z ** 3 / 24
        P = 1 - z / 4
    else:
        Q = 1 + 2 * z / 3 + z ** 2 / 5 + z ** 3 / 30 + z ** 4 / 360
        PmQ = -z - z ** 2 / 6 - z ** 3 / 30 - z ** 4 / 360
        P = 1 - z / 3 + z ** 2 / 30
    sign = np.sign(P)
    with np.errstate(invalid="ignore", divide="ignore"):
        small = np.log1p(PmQ / Q)
        large = np.log(np.abs(P) / Q)
    logr = np.where(P / Q > 0.5, small, large)
    return logr, sign


def block_weights(s, beta, count):
    """W_0 … W_{count−1} (array count × s × s).  Integer β exactly; otherwise W_0, W_1 from mpmath
    (40 digits) and W_j, j ≥ 2, from the real-axis representation (rkcq_weights.md (3.2))
        W_j = −(sin πβ/π) ∫_0^∞ z^β r(−z)^{j−1} u(z) v(z)ᵀ dz,
        u = (I + zA)^{−1}𝟙,  vᵀ = bᵀ(I + zA)^{−1},
    by the trapezoidal rule in x = ln z (step 0.2: aliasing ≈ e^{−π²/0.2} ≈ 4e-22)."""
    key = (s, float(beta))
    cached = _weight_cache.get(key)
    if cached is not None and len(cached) >= count:
        return cached[:count]
    A, b, c = lobatto_iiic(s)
    Ai = np.linalg.inv(A)
    D1 = np.zeros((s, s))
    D1[0, s - 1] = -1.0 / b[0]
    n = max(count, 2)
    W = np.zeros((n, s, s))
    if beta == 0.0:
        W[0] = np.eye(s)
    elif beta == 1.0:
        W[0] = Ai
        W[1] = D1
    elif beta == 2.0:
        W[0] = Ai @ Ai
        W[1] = Ai @ D1 + D1 @ Ai
    else:
        W[0], W[1] = _lags01_mp(s, beta)
        if n > 2:
            hx = 0.2
            jmax = n - 1
            zmin = (1e-20) ** (1.0 / (1.0 + beta)) / jmax
            xs = np.arange(math.floor(math.log(zmin) / hx), math.ceil(46.0 / hx) + 1) * hx
            z = np.exp(xs)
            logr, sign = _log_abs_r(s, z)
            U = np.array([np.linalg.solve(np.eye(s) + zz * A, np.ones(s)) for zz in z])
            V = np.array([np.linalg.solve((np.eye(s) + zz * A).T, b) for zz in z])
            q = -(math.sin(math.pi * beta) / math.pi) * hx * z ** (1.0 + beta)
            UV = np.einsum("ka,kb->kab", U, V)
            js = np.arange(2, n)
            # E[j, k] = q_k r_k^{j−1}; chunks keep the memory bounded
            for lo in range(0, len(js), 2048):
                jj = js[lo:lo + 2048]
                e = (jj[:, None] - 1.0) * logr[None, :]
                E = q[None, :] * np.exp(e) * np.where((jj[:, None] - 1) % 2 == 1, sign, 1.0)
                W[jj] = np.einsum("jk,kab->jab", E, UV)
    _weight_cache[key] = W
    return W[:count]


# ---------------------------------------------------------------------------------------------
# The problem and the stepper
# ---------------------------------------------------------------------------------------------


class Problem:
    """M x'' + R D^β x + ∇U(x, t) = f(t) on [t0, T], x(t0) = x0, x'(t0) = v0.
    grad(x, t), hess(x, t): ∇U and ∇²U; pot(x, t): U (for the energy); force(t): f."""

    def __init__(self, M, R, beta, grad, hess, x0, v0, t0, T, force=None, pot=None,
                 convention="caputo"):
        self.M = np.atleast_2d(np.array(M, dtype=float))
        self.R = np.atleast_2d(np.array(R, dtype=float))
        self.beta = float(beta)
        self.grad, self.hess, self.pot = grad, hess, pot
        self.force = force if force is not None else (lambda t: np.zeros(len(self.M)))
        self.x0 = np.atleast_1d(np.array(x0, dtype=float))
        self.v0 = np.atleast_1d(np.array(v0, dtype=float))
        self.t0, self.T = float(t0), float(T)
        self.convention = convention
        b = self.beta
        if convention == "rl" and b > 0:
            if np.any(self.x0 != 0) or (b > 1 and np.any(self.v0 != 0)):
                raise ValueError("prototype: Riemann–Liouville needs x0 = 0 (and v0 = 0 for "
                                 "β > 1): D^β P is infinite at the stage c_1 = 0 of interval 0")

    def taylor(self, t):
        """P(t) = x0 + (t − t0) v0 (the part the memory does not see), t an array of times."""
        if self.beta == 0:
            return np.zeros((len(t), len(self.x0)))
        return self.x0[None, :] + (t - self.t0)[:, None] * self.v0[None, :]

    def taylor_force(self, t):
        """D^β P at the times t (closed form), shape (len(t), d)."""
        b = self.beta
        tau = np.maximum(t - self.t0, 0.0)[:, None]   # a + b − t may round below t0
        out = np.zeros((len(t), len(self.x0)))
        if b == 0:
            return out
        # D^β τ = τ^{1−β}/Γ(2−β): Caputo for β ≤ 1 (β = 1: 1), Riemann–Liouville for β < 2
        if b < 1 or (b == 1) or (self.convention == "rl" and b < 2):
            out += self.v0[None, :] * (tau ** (1 - b) / math.gamma(2 - b) if b != 1 else 1.0)
        if self.convention == "rl" and b < 1 and np.any(self.x0 != 0):
            out += self.x0[None, :] * tau ** (-b) / math.gamma(1 - b)
        return out


class LobattoFvi:
    """fvi-lobatto{s}: direct history, Newton on the s − 1 new stage values per step."""

    def __init__(self, problem, s, N, load="pointwise"):
        """load: how the prescribed forces (f and D^β P) enter row k of interval n:
        "pointwise": h b_k F(t_n + c_k h) (the Lobatto quadrature; the published code),
        "moments":   h ∫_0^1 ℓ_k(σ) F(t_n + σh) dσ (exact integration against the interpolant's
                     basis; the gradient of −∫ F·x_h dt; adaptive quadrature here)."""
        self.pb, self.s, self.N = problem, s, N
        self.load = load
        self._moments = {}
        self.h = (problem.T - problem.t0) / N
        self.A, self.b, self.c = lobatto_iiic(s)
        self.D = differentiation_matrix(self.c)
        self.W = block_weights(s, problem.beta, N + 1)
        # K[k, m] = Σ_a b_a D[a, k] D[a, m]  (the kinetic Hessian of L_d, times h)
        self.K = self.D.T @ np.diag(self.b) @ self.D
        self.newton_iters = 0

    # -- pieces -------------------------------------------------------------------------------
    def stage_times(self, n):
        return self.pb.t0 + (n + self.c) * self.h

    def dLd(self, X, n):
        """∂L_d/∂X_{n,k}, k = 1 … s (rows), with the forcing in U_f = U − f·x."""
        pb, h, b, D = self.pb, self.h, self.b, self.D
        V = D @ X / h                                    # velocities at the nodes (s × d)
        ts = self.stage_times(n)
        if self.load == "moments":
            g = np.array([pb.grad(X[a], ts[a]) for a in range(self.s)])
            return (D.T @ (b[:, None] * (V @ pb.M.T)) - h * b[:, None] * g
                    + h * self.moments(n, pb.force, "f"))
        g = np.array([pb.grad(X[a], ts[a]) - pb.force(ts[a]) for a in range(self.s)])
        return D.T @ (b[:, None] * (V @ pb.M.T)) - h * b[:, None] * g

    def moments(self, n, fun, tag):
        """∫_0^1 ℓ_k(σ) fun(t_n + σh) dσ, k = 1 … s (s × d), by adaptive quadrature."""
        key = (n, tag)
        if key not in self._moments:
            from scipy.integrate import quad
            c, s, h, t0 = self.c, self.s, self.h, self.pb.t0
            d = len(self.pb.x0)
            m = np.zeros((s, d))
            for k in range(s):
                lk = lambda x: np.prod([(x - c[j]) / (c[k] - c[j]) for j in range(s) if j != k])
                for i in range(d):
                    m[k, i] = quad(lambda x: lk(x) * fun(t0 + (n + x) * h)[i], 0.0, 1.0,
                                   epsabs=1e-15, epsrel=1e-13, limit=200)[0]
            self._moments[key] = m
        return self._moments[key]

    def damping(self, X, n, hist):
        """G_n = h^{−β}(W_0 X̃_n + H_n) + D^β P at the stages (s × d)."""
        pb = self.pb
        ts = self.stage_times(n)
        Xt = X - pb.taylor(ts)
        return self.h ** (-pb.beta) * (self.W[0] @ Xt + hist) + pb.taylor_force(ts)

    def interval_force(self, X, n, hist):
        """F_n = ∂L_d/∂X_n − h B R G_n (s × d): the interval's contribution to every equation."""
        if self.load == "moments":
            pb = self.pb
            G = self.damping(X, n, hist) - pb.taylor_force(self.stage_times(n))
            fP = self.moments(n, lambda t: pb.taylor_force(np.array([t]))[0], "P")
            return (self.dLd(X, n) - self.h * self.b[:, None] * (G @ pb.R.T)
                    - self.h * (fP @ pb.R.T))
        G = self.damping(X, n, hist)
        return self.dLd(X, n) - self.h * self.b[:, None] * (G @ self.pb.R.T)

    def history(self, Xt_list, n):
        """H_n = Σ_{j=1}^{n} W_j X̃_{n−j}  (direct sum)."""
        if n == 0:
            return 0.0
        Xs = np.array(Xt_list[n - 1::-1])                # X̃_{n−1}, …, X̃_0
        return np.einsum("jab,jbd->ad", self.W[1:n + 1], Xs)

    # -- one step -----------------------------------------------------------------------------
    def step(self, n, xn, pn, hist, guess):
        pb, s, h, b, d = self.pb, self.s, self.h, self.b, len(xn)
        Minv = np.linalg.inv(pb.M)
        X = guess.copy()
        X[0] = xn
        ts = self.stage_times(n)
        # the constant part of the Jacobian: (K ⊗ M)/h − h^{1−β}(B W_0 ⊗ R), rows 1..s−1, cols 2..s
        Jc = (np.kron(self.K, pb.M) / h
              - h ** (1 - pb.beta) * np.kron(np.diag(b) @ self.W[0], pb.R))
        rows = slice(0, (s - 1) * d)
        cols = slice(d, s * d)
        for it in range(50):
            F = self.interval_force(X, n, hist)
            F[0] += pn + self.padding_term(n)
            res = F[:s - 1].reshape(-1)
            J = Jc.copy()
            for k in range(s):
                J[k * d:(k + 1) * d, k * d:(k + 1) * d] -= h * b[k] * pb.hess(X[k], ts[k])
            dz = np.linalg.solve(J[rows, cols], -res)
            X[1:] += dz.reshape(s - 1, d)
            self.newton_iters += 1
            scale = max(1.0, np.abs(X).max())
            if np.abs(dz).max() <= 1e-15 * scale * 4 and it > 0 or np.abs(dz).max() == 0:
                break
        F = self.interval_force(X, n, hist)
        p_next = F[s - 1]
        return X, p_next

    def padding_term(self, n):
        """Emulation of the published notebooks new_g_{3,4}S_Lobbato_*.ipynb (github
        khaledharizb/RKCQ): their node equation of interval n ≥ 1 carries, besides the correct
        previous-interval memory Σ_{m<n} W_{n−1−m} X_m, the extra term W_n[s, :]·pad with a padding
        stage vector pad = (X_{0,2}, X_{0,2}, X_{0,1}) (s = 3) or (X_{0,1}, X_{0,2}, X_{0,3}, X_{0,1})
        (s = 4) (their `Y = vcat(q[2],q[2],q)` / `vcat(q[1],q[2],q[3],q)`). Zero unless
        self.emulate_padding is set; for reproducing their files only."""
        s = self.s
        if not getattr(self, "emulate_padding", False) or n == 0 or s == 2:
            return 0.0
        X0 = self.stages_so_far[0]
        pad = X0[[1, 1, 0]] if s == 3 else X0[[0, 1, 2, 0]]
        return -self.h * self.b[s - 1] * self.h ** (-self.pb.beta) * (
            (self.W[n][s - 1] @ pad) @ self.pb.R.T)

    def run(self):
        pb, s, h = self.pb, self.s, self.h
        d = len(pb.x0)
        xs = [pb.x0.copy()]
        ps = [pb.M @ pb.v0]
        stages = []
        Xt = []
        Minv = np.linalg.inv(pb.M)
        self.stages_so_far = stages
        for n in range(self.N):
            hist = self.history(Xt, n)
            v = Minv @ ps[-1]
            guess = xs[-1][None, :] + (h * self.c)[:, None] * v[None, :]
            X, p = self.step(n, xs[-1], ps[-1], hist, guess)
            stages.append(X)
            Xt.append(X - pb.taylor(self.stage_times(n)))
            xs.append(X[-1].copy())
            ps.append(p)
        self.stages = np.array(stages)
        self.xs = np.array(xs)
        self.ps = np.array(ps)
        self.ts = pb.t0 + h * np.arange(self.N + 1)
        return self

    # -- diagnostics --------------------------------------------------------------------------
    def velocities(self):
        return self.ps @ np.linalg.inv(self.pb.M).T

    def energy_account(self):
        """E_n = ½ p_nᵀM⁻¹p_n + U(x_n, t_n); W_{n+1} = W_n + h Σ_a b_a (R G_{n,a} − f_a)·V_{n,a}
        (the Lobatto quadrature of the power of damping and forcing along the interpolant).
        Returns max_n |E_n + W_n − E_0| (time-independent U)."""
        pb, h, b = self.pb, self.h, self.b
        Minv = np.linalg.inv(pb.M)
        E = np.array([0.5 * p @ Minv @ p + pb.pot(x, t)
                      for p, x, t in zip(self.ps, self.xs, self.ts)])
        Wk = np.zeros(self.N + 1)
        Xt = [X - pb.taylor(self.stage_times(n)) for n, X in enumerate(self.stages)]
        for n, X in enumerate(self.stages):
            G = self.damping(X, n, self.history(Xt, n))
            V = self.D @ X / h
            ts = self.stage_times(n)
            fa = np.array([pb.force(t) for t in ts])
            Wk[n + 1] = Wk[n] + h * np.sum(b[:, None] * ((G @ pb.R.T - fa) * V))
        return np.abs(E + Wk - E[0]).max(), E, Wk


# ---------------------------------------------------------------------------------------------
# The mirror (y-) equation and the action sum (for the variational checks)
# ---------------------------------------------------------------------------------------------


def mirror_residual(sch, Y, pb_y_taylor=True):
    """The y-equation on the whole mirrored trajectory: Y[m] = stage values of y on interval m
    (time a + b − t). Interval force F^y_m = ∂L_d^{mir}(Y_m)/∂Y_m − h B R G^y_m with the forward
    memory G^y_m = h^{−β} Σ_{l ≥ m} J W_{l−m} J Ỹ_l + D^β P at the mirrored stage times.
    Returns the residuals of the internal stages and the interior nodes (max abs) and the scale."""
    pb, s, h, b, N = sch.pb, sch.s, sch.h, sch.b, sch.N
    J = np.eye(s)[::-1]
    a_plus_b = pb.t0 + pb.T
    res = []
    F = []
    # mirrored stage times: interval m of y ↔ interval N−1−m of x, stage i ↔ stage s+1−i
    ty = [a_plus_b - (pb.t0 + (m + sch.c) * h) for m in range(N)]
    Yt = [Y[m] - pb.taylor(ty[m]) for m in range(N)]
    scale = 0.0
    for m in range(N):
        hist = sum(J @ sch.W[l - m] @ J @ Yt[l] for l in range(m, N))
        G = h ** (-pb.beta) * hist + pb.taylor_force(ty[m])
        V = sch.D @ Y[m] / h
        g = np.array([pb.grad(Y[m][a], ty[m][a]) - pb.force(ty[m][a]) for a in range(s)])
        # L_d^{mir}(Y_m) = h Σ_a b_a [½ V_aᵀ M V_a − U_f(Y_{m,a}, a+b−t)]: same form
        dL = sch.D.T @ (b[:, None] * (V @ pb.M.T)) - h * b[:, None] * g
        F.append(dL - h * b[:, None] * (G @ pb.R.T))
        scale = max(scale, np.abs(dL).max(), h * np.abs(G @ pb.R.T).max())
    for m in range(N):
        for i in range(1, s - 1):
            res.append(np.abs(F[m][i]).max())
    for m in range(1, N):
        res.append(np.abs(F[m - 1][s - 1] + F[m][0]).max())
    return max(res), scale


def action_sum_mp(sch, X, Y, Wa, dps=40):
    """A_d = Σ_n [L_d(X_n) + L_d^{mir}(Y_n) − h Σ_i b_i (D^α_− X̃)_{n,i}ᵀ R (D^α_+ Ỹ)_{n,i}]
             − h Σ_n Σ_i b_i [(R FP_{n,i})·X_{n,i} + (R FP^y_{n,i})·Y_{n,i}]
    in mpmath (X, Y: lists of s × d mp matrices), D^α_− X̃_n = h^{−α} Σ_j Wa_j X̃_{n−j},
    D^α_+ Ỹ_n = h^{−α} Σ_j J Wa_j J Ỹ_{n+j}; Wa the weights of s^α (α = β/2)."""
    pb, s, N = sch.pb, sch.s, sch.N
    with mp.workdps(dps):
        h = mp.mpf(sch.h)
        b = [mp.mpf(x) for x in sch.b]
        c = [mp.mpf(x) for x in sch.c]
        D = mp.matrix(sch.D.tolist())
        M = mp.matrix(pb.M.tolist())
        R = mp.matrix(pb.R.tolist())
        d = len(pb.x0)
        alpha = mp.mpf(pb.beta) / 2
        J = mp.matrix(np.eye(s)[::-1].tolist())
        Wm = [mp.matrix(w.tolist()) for w in Wa]
        WJ = [J * w * J for w in Wm]
        a_plus_b = mp.mpf(pb.t0) + mp.mpf(pb.T)
        total = mp.mpf(0)
        Xt, Yt = [], []
        for n in range(N):
            tx = [mp.mpf(pb.t0) + (n + c[a]) * h for a in range(s)]
            ty = [a_plus_b - t for t in tx]
            P = pb.taylor(np.array([float(t) for t in tx]))
            Py = pb.taylor(np.array([float(t) for t in ty]))
            FP = pb.taylor_force(np.array([float(t) for t in tx]))
            FPy = pb.taylor_force(np.array([float(t) for t in ty]))
            # the Taylor polynomial in mp (exact linear functions of t)
            Xt.append(mp.matrix([[X[n][a, k] - (pb.x0[k] + (tx[a] - pb.t0) * pb.v0[k]
                                                  if pb.beta != 0 else 0) for k in range(d)]
                                 for a in range(s)]))
            Yt.append(mp.matrix([[Y[n][a, k] - (pb.x0[k] + (ty[a] - pb.t0) * pb.v0[k]
                                                  if pb.beta != 0 else 0) for k in range(d)]
                                 for a in range(s)]))
            del P, Py
            for Z, ts in ((X[n], tx), (Y[n], ty)):
                V = D * Z / h
                for a in range(s):
                    va = V[a, :].T
                    za = Z[a, :].T
                    kin = (va.T * M * va)[0] / 2
                    total += h * b[a] * (kin - pb.pot_mp(za, ts[a]))
            for a in range(s):
                for k in range(d):
                    fx = sum(R[k, l] * mp.mpf(FP[a, l]) for l in range(d))
                    fy = sum(R[k, l] * mp.mpf(FPy[a, l]) for l in range(d))
                    total -= h * b[a] * (fx * X[n][a, k] + fy * Y[n][a, k])
        hal = h ** (-alpha)
        for n in range(N):
            Dm = hal * sum((Wm[j] * Xt[n - j] for j in range(n + 1)), mp.zeros(s, d))
            Dp = hal * sum((WJ[j] * Yt[n + j] for j in range(N - n)), mp.zeros(s, d))
            for i in range(s):
                total -= h * b[i] * (Dm[i, :] * R * Dp[i, :].T)[0]
        return total


# ---------------------------------------------------------------------------------------------
# Problems
# ---------------------------------------------------------------------------------------------


def quadratic(K):
    K = np.atleast_2d(np.array(K, dtype=float))
    return (lambda x, t: K @ x), (lambda x, t: K), (lambda x, t: 0.5 * x @ K @ x)


def damped_oscillator_2d(N):
    """q'' + 0.25 q' + 0.5 q = 0, q(0) = (0.8, −0.5), q'(0) = (0.4, 0), T = 30 (RKCQ paper)."""
    g, H, U = quadratic(0.5 * np.eye(2))
    return Problem(np.eye(2), 0.25 * np.eye(2), 1.0, g, H, [0.8, -0.5], [0.4, 0.0], 0.0, 30.0,
                   pot=U)


def damped_oscillator_exact(t, x0, v0, c=0.25, k=0.5):
    lam = -c / 2
    om = math.sqrt(k - c * c / 4)
    e = np.exp(lam * t)
    return (e[:, None] * (np.cos(om * t)[:, None] * x0[None, :]
                          + np.sin(om * t)[:, None] * ((v0 - lam * x0) / om)[None, :]))


def damped_oscillator_velocity(t, x0, v0, c=0.25, k=0.5):
    lam = -c / 2
    om = math.sqrt(k - c * c / 4)
    e = np.exp(lam * t)[:, None]
    A, Bc = x0[None, :], ((v0 - lam * x0) / om)[None, :]
    cs, sn = np.cos(om * t)[:, None], np.sin(om * t)[:, None]
    return e * (lam * (cs * A + sn * Bc) + om * (-sn * A + cs * Bc))


def bagley_torvik(beta, N):
    """q'' + D^β q + q = f on [0, 1], zero data; β = 1/2: exact t³, β = 3/2: exact t^{5/2}."""
    if beta == 0.5:
        f = lambda t: np.array([t ** 3 + 6 * t + 16 / (5 * math.sqrt(math.pi)) * t ** 2.5])
        exact = lambda t: t ** 3
    else:
        f = lambda t: np.array([15 / 4 * math.sqrt(t) + 15 * math.sqrt(math.pi) / 8 * t
                                + t ** 2.5])
        exact = lambda t: t ** 2.5
    g, H, U = quadratic([[1.0]])
    pb = Problem([[1.0]], [[1.0]], beta, g, H, [0.0], [0.0], 0.0, 1.0, force=f, pot=U)
    return pb, exact


# ---------------------------------------------------------------------------------------------
# Experiments
# ---------------------------------------------------------------------------------------------


def check_weights():
    """Compare block_weights with the 50-digit references of tests/fractional/rkcq_reference_data.inc
    and with the composition W^{(β/2)} * W^{(β/2)} = W^{(β)} and the mirror symmetry
    W_jᵀ B = J B W_j J."""
    import os
    import re
    path = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "fractional",
                        "rkcq_reference_data.inc")
    refs = {}
    for line in open(path):
        m = re.match(r"\{(\d+), ([\d.]+), (\d+), (\d+), (\d+), ([-\deE.+]+)\}", line)
        if m:
            s, beta, lag, r, c, v = m.groups()
            refs.setdefault((int(s), float(beta), int(lag)), {})[(int(r), int(c))] = float(v)
    print("weights vs 50-digit references (max entrywise relative error over lags ≤ 10^4):")
    worst = 0.0
    for s in (2, 3, 4):
        for beta in (0.3, 0.5, 1.1, 1.5, 1.95):
            W = block_weights(s, beta, 10001)
            errs = []
            for (ss, bb, lag), entries in refs.items():
                if ss != s or bb != beta or lag > 10000:
                    continue
                scale = max(abs(v) for v in entries.values())
                for (r, c), v in entries.items():
                    errs.append(abs(W[lag][r, c] - v) / max(abs(v), 1e-3 * scale))
            worst = max(worst, max(errs))
            print(f"  s = {s}, β = {beta}: {max(errs):.1e} ({len(errs)} entries)")
    print(f"  worst {worst:.1e}")
    print("composition W^(β/2) * W^(β/2) − W^(β), max over 200 lags / max|W|, and mirror symmetry:")
    for s in (2, 3, 4):
        A, b, c = lobatto_iiic(s)
        B = np.diag(b)
        J = np.eye(s)[::-1]
        for beta in (0.5, 1.0, 1.5):
            Wa = block_weights(s, beta / 2, 200)
            Wb = block_weights(s, beta, 200)
            comp = np.array([sum(Wa[j] @ Wa[n - j] for j in range(n + 1)) for n in range(200)])
            sym = max(np.abs(w.T @ B - J @ B @ w @ J).max() / np.abs(w).max()
                      for w in Wb if np.abs(w).max() > 0)
            print(f"  s = {s}, β = {beta}: composition {np.abs(comp - Wb).max() / np.abs(Wb).max():.1e}"
                  f", symmetry {sym:.1e}")


def published():
    rows = []
    print("Damped 2-D oscillator q'' + 0.25q' + 0.5q = 0, T = 30, max-over-nodes error "
          "(positions; velocities = node momenta):")
    pub = {(2, 32): 3.7828e-2, (2, 128): 2.2871e-3, (3, 32): 3.0588e-4, (3, 128): 1.1582e-6,
           (4, 32): 3.8855e-7, (4, 128): 9.6690e-11}
    for s in (2, 3, 4):
        prev = None
        for N in (32, 64, 128, 256):
            pb = damped_oscillator_2d(N)
            sch = LobattoFvi(pb, s, N).run()
            ex = damped_oscillator_exact(sch.ts, pb.x0, pb.v0)
            err = np.abs(sch.xs - ex).max()
            verr = np.abs(sch.velocities()
                          - damped_oscillator_velocity(sch.ts, pb.x0, pb.v0)).max()
            p = "" if prev is None else f" order {math.log2(prev / err):.2f}"
            ref = pub.get((s, N))
            refs = f"  published {ref:.4e}" if ref else ""
            print(f"  s = {s}, h = {30 / N:<9}: {err:.10e}{p}{refs}; velocity {verr:.10e}")
            rows.append(("osc", s, N, err))
            prev = err
    for beta in (0.5, 1.5):
        print(f"Bagley–Torvik β = {beta}, max-over-nodes error on [0, 1]:")
        for s in (2, 3, 4):
            prev = None
            for N in (4, 8, 16, 32, 64, 128, 256):
                pb, exact = bagley_torvik(beta, N)
                sch = LobattoFvi(pb, s, N).run()
                err = np.abs(sch.xs[:, 0] - exact(sch.ts)).max()
                p = "" if prev is None else f" order {math.log2(prev / err):.2f}"
                print(f"  s = {s}, N = {N:4d}: {err:.4e}{p}")
                rows.append((f"bt{beta}", s, N, err))
                prev = err
    return rows


def gradient_check():
    """(1/h)-free check: ∂A_d/∂η (central differences of the mpmath action sum, 40 digits) against
    E^x + E^y, the x- and y-equations assembled from the interval forces, for arbitrary sequences
    X, Y (x0, v0 ≠ 0, Caputo, forcing, nonlinear U, full M and R)."""
    rng = np.random.default_rng(7)
    d = 2
    M = np.array([[2.0, 0.3], [0.3, 1.0]])
    R = np.array([[0.7, 0.2], [0.2, 0.4]])
    K = np.array([[1.0, -0.3], [-0.3, 0.8]])
    kap = 0.6

    def grad(x, t):
        return K @ x + kap * np.sin(x) * (1 + 0.1 * t)

    def hess(x, t):
        return K + np.diag(kap * np.cos(x) * (1 + 0.1 * t))

    def pot(x, t):
        return 0.5 * x @ K @ x + kap * np.sum(1 - np.cos(x)) * (1 + 0.1 * t)

    def pot_mp(z, t):
        zz = [z[i] for i in range(d)]
        quad = sum(zz[i] * K[i, j] * zz[j] for i in range(d) for j in range(d)) / 2
        return quad + kap * sum(1 - mp.cos(v) for v in zz) * (1 + mp.mpf(0.1) * t)

    force = lambda t: np.array([0.3 * math.cos(t), -0.2 * t])
    print("restricted gradient of the action sum vs E^x + E^y (arbitrary X, Y, N = 5, d = 2):")
    for s in (2, 3, 4):
        for beta in (0.6, 1.0, 1.5):
            N = 5
            pb = Problem(M, R, beta, grad, hess, [0.3, -0.2], [0.5, 0.25], 0.0, 2.0,
                         force=force, pot=pot)
            pb.pot_mp = lambda z, t: pot_mp(z, t) - sum(
                mp.mpf(fv) * z[i] for i, fv in enumerate(force(float(t)))) if False else None
            # U_f = U − f·x in mp (f evaluated in mp for exactness of the difference)
            def potf_mp(z, t):
                f0 = mp.mpf(3) / 10 * mp.cos(t)
                f1 = -mp.mpf(2) / 10 * t
                return pot_mp(z, t) - f0 * z[0] - f1 * z[1]
            pb.pot_mp = potf_mp
            pb.force = lambda t: np.array([0.3 * math.cos(t), -0.2 * t])
            sch = LobattoFvi(pb, s, N)
            X = [rng.normal(size=(s, d)) for _ in range(N)]
            Y = [rng.normal(size=(s, d)) for _ in range(N)]
            for n in range(1, N):          # shared nodes
                X[n][0] = X[n - 1][-1]
                Y[n][0] = Y[n - 1][-1]
            Wa = block_weights(s, beta / 2, N + 1)
            # equations: interval forces with the memory of β = 2α
            Xt = [X[n] - pb.taylor(sch.stage_times(n)) for n in range(N)]
            Fx = [sch.interval_force(X[n], n, sch.history(Xt, n)) for n in range(N)]
            J = np.eye(s)[::-1]
            ty = [pb.t0 + pb.T - sch.stage_times(m) for m in range(N)]
            Yt = [Y[m] - pb.taylor(ty[m]) for m in range(N)]
            Fy = []
            for m in range(N):
                G = sch.h ** (-beta) * sum(J @ sch.W[l - m] @ J @ Yt[l] for l in range(m, N)) \
                    + pb.taylor_force(ty[m])
                V = sch.D @ Y[m] / sch.h
                g = np.array([pb.grad(Y[m][a], ty[m][a]) - pb.force(ty[m][a]) for a in range(s)])
                Fy.append(sch.D.T @ (sch.b[:, None] * (V @ M.T)) - sch.h * sch.b[:, None] * g
                          - sch.h * sch.b[:, None] * (G @ R.T))
            # variables: (interval, stage) for internal stages, (node) for nodes 1..N−1
            variables = [("stage", n, i) for n in range(N) for i in range(1, s - 1)] + \
                        [("node", k, None) for k in range(1, N)]
            # negative control: the y-memory with W_j in place of J W_j J (the mirror symmetry
            # W_jᵀB = J B W_j J is what makes the y-variation collapse onto W^{(β)})
            Fy_bad = []
            for m in range(N):
                G = sch.h ** (-beta) * sum(sch.W[l - m] @ Yt[l] for l in range(m, N))
                Gg = sch.h ** (-beta) * sum(J @ sch.W[l - m] @ J @ Yt[l] for l in range(m, N))
                Fy_bad.append(-sch.h * sch.b[:, None] * ((G - Gg) @ R.T))

            def Fy_ctl_delta(var, comp):
                kind, n, i = var
                if kind == "stage":
                    return -Fy_bad[n][i, comp]
                return -(Fy_bad[n - 1][s - 1, comp] + Fy_bad[n][0, comp])

            worst, scale, control = 0.0, 0.0, 0.0
            with mp.workdps(40):
                Xm = [mp.matrix(x.tolist()) for x in X]
                Ym = [mp.matrix(y.tolist()) for y in Y]
                eps = mp.mpf(10) ** -12
                for var in variables:
                    for comp in range(d):
                        def shifted(delta):
                            Xs = [x.copy() for x in Xm]
                            Ys = [y.copy() for y in Ym]
                            kind, n, i = var
                            if kind == "stage":
                                Xs[n][i, comp] += delta
                                Ys[n][i, comp] += delta
                            else:
                                Xs[n - 1][s - 1, comp] += delta
                                Xs[n][0, comp] += delta
                                Ys[n - 1][s - 1, comp] += delta
                                Ys[n][0, comp] += delta
                            return action_sum_mp(sch, Xs, Ys, Wa)
                        fd = (shifted(eps) - shifted(-eps)) / (2 * eps)
                        kind, n, i = var
                        if kind == "stage":
                            e = Fx[n][i, comp] + Fy[n][i, comp]
                        else:
                            e = Fx[n - 1][s - 1, comp] + Fx[n][0, comp] + \
                                Fy[n - 1][s - 1, comp] + Fy[n][0, comp]
                        ctl = e - Fy_ctl_delta(var, comp)
                        if not (math.isfinite(e) and math.isfinite(float(fd))):
                            raise RuntimeError("non-finite equation or gradient")
                        worst = max(worst, abs(float(fd) - e))
                        control = max(control, abs(float(fd) - ctl))
                        scale = max(scale, abs(e))
            # negative control: the y-memory with W_j instead of J W_j J
            print(f"  s = {s}, β = {beta}: max |∂A/∂η − (E^x + E^y)| = {worst:.1e} "
                  f"(largest term {scale:.1e}; control W_j for J W_j J in the y-memory: "
                  f"{control:.1e})")


def mirror_run(sch):
    """Independent backward run of the y-equation (§5): intervals m = N−1 … 0, unknowns
    Y_{m,1..s−1} (Y_{m,s} = y_{m+1} known), equations F^y_{m,s} = q_{m+1} (the node equation with
    q_{m+1} := −F^y_{m+1,1}) and F^y_{m,i} = 0 (internal stages), start y_N = x_0, q_N = −M v_0
    (the mirrored momentum); the forward memory Σ_{j≥0} J W_j J Ỹ_{m+j} runs over the later
    intervals. Returns the y-stage sequence (list over m)."""
    pb, s, h, b, N = sch.pb, sch.s, sch.h, sch.b, sch.N
    d = len(pb.x0)
    J = np.eye(s)[::-1]
    WJ = [J @ w @ J for w in sch.W]
    a_plus_b = pb.t0 + pb.T
    Y = [None] * N
    Yt = [None] * N
    q = -(pb.M @ pb.v0)
    y_next = pb.x0.copy()
    Jc = (np.kron(sch.K, pb.M) / h - h ** (1 - pb.beta) * np.kron(np.diag(b) @ WJ[0], pb.R))
    rows = list(range(d, s * d))                  # rows 2 … s (0-based blocks 1 … s−1)
    cols = list(range(0, (s - 1) * d))            # unknown stages 1 … s−1
    for m in range(N - 1, -1, -1):
        ty = a_plus_b - (pb.t0 + (m + sch.c) * h)
        hist = sum((WJ[j] @ Yt[m + j] for j in range(1, N - m)), np.zeros((s, d)))
        X = np.tile(y_next, (s, 1))
        X[-1] = y_next
        for it in range(50):
            Xt = X - pb.taylor(ty)
            G = h ** (-pb.beta) * (WJ[0] @ Xt + hist) + pb.taylor_force(ty)
            V = sch.D @ X / h
            g = np.array([pb.grad(X[a], ty[a]) - pb.force(ty[a]) for a in range(s)])
            F = sch.D.T @ (b[:, None] * (V @ pb.M.T)) - h * b[:, None] * g \
                - h * b[:, None] * (G @ pb.R.T)
            F[-1] -= q
            res = F[1:].reshape(-1)
            Jm = Jc.copy()
            for k in range(s):
                Jm[k * d:(k + 1) * d, k * d:(k + 1) * d] -= h * b[k] * pb.hess(X[k], ty[k])
            dz = np.linalg.solve(Jm[np.ix_(rows, cols)], -res)
            X[:-1] += dz.reshape(s - 1, d)
            if np.abs(dz).max() <= 4e-15 * max(1.0, np.abs(X).max()) and it > 0:
                break
        Xt = X - pb.taylor(ty)
        G = h ** (-pb.beta) * (WJ[0] @ Xt + hist) + pb.taylor_force(ty)
        V = sch.D @ X / h
        g = np.array([pb.grad(X[a], ty[a]) - pb.force(ty[a]) for a in range(s)])
        F = sch.D.T @ (b[:, None] * (V @ pb.M.T)) - h * b[:, None] * g \
            - h * b[:, None] * (G @ pb.R.T)
        q = -F[0]
        Y[m], Yt[m] = X, Xt
        y_next = X[0].copy()
    return Y


def mirror_check():
    print("mirror: y-equation residual at Y_m = J X_{N−1−m} (integrator trajectories):")
    for s in (2, 3, 4):
        for beta in (0.5, 1.0, 1.5):
            g, H, U = quadratic([[1.0, 0.2], [0.2, 0.7]])
            pb = Problem(np.array([[1.0, 0.1], [0.1, 2.0]]), np.array([[0.8, 0.1], [0.1, 0.3]]),
                         beta, lambda x, t: g(x, t) + 0.3 * np.sin(x),
                         lambda x, t: H(x, t) + np.diag(0.3 * np.cos(x)),
                         [1.0, -0.5], [0.2, 0.4], 0.0, 5.0,
                         force=lambda t: np.array([math.sin(t), 0.0]), pot=U)
            N = 40
            sch = LobattoFvi(pb, s, N).run()
            J = np.eye(s)[::-1]
            Y = [J @ sch.stages[N - 1 - m] for m in range(N)]
            r, scale = mirror_residual(sch, Y)
            Yrun = mirror_run(sch)
            err = max(np.abs(Yrun[m] - Y[m]).max() for m in range(N))
            print(f"  s = {s}, β = {beta}: residual {r:.1e} (scale {scale:.1e}); backward run "
                  f"max|y − J x_reversed| = {err:.1e} (max|x| {np.abs(sch.xs).max():.2f})")


def energy_check():
    print("energy account max_n |E_n + W_n − E_0| (damped 2-D oscillator, T = 30):")
    for s in (2, 3, 4):
        prev = None
        for N in (32, 64, 128, 256):
            sch = LobattoFvi(damped_oscillator_2d(N), s, N).run()
            e, E, Wk = sch.energy_account()
            p = "" if prev is None else f" order {math.log2(prev / e):.2f}"
            print(f"  s = {s}, N = {N}: {e:.3e}{p}")
            prev = e
    print("energy account, undamped (R = 0) and fractional (β = 0.5, 1.5), x'' + r D^β x + x = 0,"
          " x0 = 1, v0 = 0, T = 20:")
    for beta, r in ((1.0, 0.0), (0.5, 0.5), (1.5, 0.5)):
        for s in (2, 3, 4):
            prev = None
            out = []
            for N in (40, 80, 160, 320):
                g, H, U = quadratic([[1.0]])
                pb = Problem([[1.0]], [[r]], beta, g, H, [1.0], [0.0], 0.0, 20.0, pot=U)
                sch = LobattoFvi(pb, s, N).run()
                e, E, Wk = sch.energy_account()
                out.append(f"{e:.2e}" + ("" if prev is None else f" ({math.log2(prev / e):.2f})"))
                prev = e
            print(f"  β = {beta}, r = {r}, s = {s}: N = 40…320: " + ", ".join(out))


def stability_grid(steps=2000):
    print(f"stability: M = K = 1, x0 = 1, v0 = 0, Caputo, {steps} steps, max_k |x_k|/|x_0|:")
    out = {}
    for s in (2, 3, 4):
        worst = 0.0
        blown = []
        for beta in (0.5, 1.0, 1.5):
            for r in (1.0, 1e2, 1e4):
                for h in (1e-2, 1e-1, 1.0):
                    g, H, U = quadratic([[1.0]])
                    pb = Problem([[1.0]], [[r]], beta, g, H, [1.0], [0.0], 0.0, h * steps, pot=U)
                    with np.errstate(all="ignore"):
                        sch = LobattoFvi(pb, s, steps).run()
                    m = np.abs(sch.xs).max()
                    mv = np.abs(sch.ps).max()
                    out[(s, beta, r, h)] = (m, mv, abs(sch.xs[-1, 0]))
                    if not np.isfinite(m) or m > 10:
                        blown.append((beta, r, h))
                    else:
                        worst = max(worst, m)
                    print(f"  s = {s}, β = {beta}, R/M = {r:g}, h = {h:g}: max|x| = {m:.4f}, "
                          f"max|p| = {mv:.3e}, |x_N| = {abs(sch.xs[-1, 0]):.2e}", flush=True)
        print(f"  s = {s}: blown up (β, R/M, h): {blown}; largest max|x_k|/|x_0| of the others "
              f"= {worst:.4f}")
    return out


def published_moments():
    """The Bagley–Torvik problems with the forcing integrated exactly against the Lagrange basis
    (load = "moments") instead of the Lobatto quadrature: what caps the published orders."""
    for beta in (0.5, 1.5):
        print(f"Bagley–Torvik β = {beta}, load = moments, max-over-nodes error on [0, 1]:")
        for s in (2, 3, 4):
            prev, line = None, []
            for N in (4, 8, 16, 32, 64, 128):
                pb, exact = bagley_torvik(beta, N)
                with np.errstate(all="ignore"):
                    sch = LobattoFvi(pb, s, N, load="moments").run()
                err = np.abs(sch.xs[:, 0] - exact(sch.ts)).max()
                line.append(f"{err:.3e}" + ("" if prev is None else
                                            f" ({math.log2(prev / err):.2f})"))
                prev = err
            print(f"  s = {s}: " + ", ".join(line), flush=True)


def orders_nonlinear():
    """Self-convergence on a damped pendulum (Newton path): x'' + 0.3 x' + sin x = 0 and the
    2-D coupled pendula with d = 2, full M, R (β = 1), x0 = 1, v0 = 0, [0, 10]."""
    print("nonlinear, β = 1: max_k |x_k − x^{2N}_{2k}| (positions) and velocities:")
    M2 = np.array([[2.0, 0.3], [0.3, 1.0]])
    R2 = np.array([[0.4, 0.1], [0.1, 0.2]])
    Kc = np.array([[0.5, -0.2], [-0.2, 0.5]])
    cases = {
        "pendulum d=1": (np.eye(1), 0.3 * np.eye(1), lambda x, t: np.sin(x),
                         lambda x, t: np.diag(np.cos(x)), [1.0], [0.0]),
        "pendula d=2": (M2, R2, lambda x, t: np.sin(x) + Kc @ x,
                        lambda x, t: np.diag(np.cos(x)) + Kc, [1.0, -0.5], [0.0, 0.3]),
    }
    for name, (M, R, g, H, x0, v0) in cases.items():
        for s in (2, 3, 4):
            res = {}
            for N in (20, 40, 80, 160, 320):
                pb = Problem(M, R, 1.0, g, H, x0, v0, 0.0, 10.0)
                sch = LobattoFvi(pb, s, N).run()
                res[N] = (sch.xs, sch.velocities())
            ex = [np.abs(res[N][0] - res[2 * N][0][::2]).max() for N in (20, 40, 80, 160)]
            ev = [np.abs(res[N][1] - res[2 * N][1][::2]).max() for N in (20, 40, 80, 160)]
            ox = [math.log2(ex[i] / ex[i + 1]) for i in range(3)]
            ov = [math.log2(ev[i] / ev[i + 1]) for i in range(3)]
            print(f"  {name}, s = {s}: x " + ", ".join(f"{e:.2e}" for e in ex) + " orders "
                  + ", ".join(f"{o:.2f}" for o in ox) + "; v orders "
                  + ", ".join(f"{o:.2f}" for o in ov), flush=True)


def orders_caputo():
    """Self-convergence on a Caputo fractional oscillator with nonzero data (no correction
    weights): x'' + D^β x + x = 0, x0 = 1, v0 = 0.5 on [0, 2]."""
    print("Caputo data, x'' + D^β x + x = 0, x0 = 1, v0 = 0.5, [0, 2]: max_k |x_k − x^{2N}_{2k}|")
    for beta in (0.6, 1.5):
        for s in (2, 3, 4):
            g, H, U = quadratic([[1.0]])
            for load in ("pointwise", "moments"):
                res = {}
                for N in (16, 32, 64, 128, 256, 512):
                    pb = Problem([[1.0]], [[1.0]], beta, g, H, [1.0], [0.5], 0.0, 2.0, pot=U)
                    with np.errstate(all="ignore"):
                        res[N] = LobattoFvi(pb, s, N, load=load).run().xs[:, 0]
                errs = []
                for N in (16, 32, 64, 128, 256):
                    errs.append(np.abs(res[N] - res[2 * N][::2]).max())
                ords = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
                print(f"  β = {beta}, s = {s}, {load:9s}: " + ", ".join(f"{e:.2e}" for e in errs)
                      + "  orders " + ", ".join(f"{o:.2f}" for o in ords), flush=True)



# ---------------------------------------------------------------------------------------------
# Stability on the scalar test problem m x'' + r D^β x + k x = 0 through the characteristic
# function (docs/theory/fvi_lobatto.md §8): scaled parameters ρ = (r/m) h^{2−β}, κ = (k/m) h².
# ---------------------------------------------------------------------------------------------


def delta_power(s, beta, zeta):
    """Δ(ζ)^β (principal power through an eigendecomposition; complex ζ, |ζ| < 1)."""
    A, b, _ = lobatto_iiic(s)
    D1 = np.zeros((s, s))
    D1[0, s - 1] = -1.0 / b[0]
    Dz = np.linalg.inv(A) + zeta * D1
    lam, V = np.linalg.eig(Dz)
    return V @ np.diag(lam.astype(complex) ** beta) @ np.linalg.inv(V)


def characteristic(s, beta, rho, kappa, zeta, limit=False):
    """det 𝒜(ζ): rows (e_1 + ζe_s)ᵀT(ζ) (node), e_kᵀT(ζ) (internal stages), (e_1 − ζe_s)ᵀ (the
    shared node), T(ζ) = DᵀBD − κB − ρBΔ(ζ)^β (limit: T = BΔ(ζ)^β, the ρ → ∞ limit)."""
    A, b, c = lobatto_iiic(s)
    D = differentiation_matrix(c)
    B = np.diag(b)
    if limit:
        T = B @ delta_power(s, beta, zeta)
    else:
        T = D.T @ B @ D - kappa * B - rho * B @ (delta_power(s, beta, zeta) if beta != 0
                                                 else np.eye(s))
    e1, es = np.eye(s)[0], np.eye(s)[s - 1]
    rows = [(e1 + zeta * es) @ T] + [T[k] for k in range(1, s - 1)] + [e1 - zeta * es]
    return np.linalg.det(np.array(rows))


def unstable_roots(s, beta, rho, kappa, limit=False, r0=0.995, n=3000):
    """Number of zeros of det 𝒜 in |ζ| < r0 (argument principle): the growing modes."""
    th = 2 * np.pi * (np.arange(n) + 0.5) / n
    v = np.array([characteristic(s, beta, rho, kappa, r0 * np.exp(1j * x), limit) for x in th])
    ph = np.unwrap(np.angle(v))
    w = (ph[-1] - ph[0] + np.angle(v[0] / v[-1])) / (2 * np.pi)
    return int(round(w))


def first_instability(count, lo, hi, points=48, bisections=14):
    """The first parameter value in [lo, hi] at which count(·) > 0 (growing modes): a geometric
    scan (points values) followed by bisection of the first stable → unstable transition. The
    stable sets are not intervals (Lobatto IIIA–IIIB has instability windows, e.g. s = 4 is
    unstable for 26 ≲ ρ ≲ 45 at β = 0.1 and stable again up to 65), so a plain bisection over
    [lo, hi] can return a later edge. Returns None if no growing mode was found on the scan,
    0.0 if unstable at lo."""
    grid = np.geomspace(lo, hi, points)
    prev = None
    for x in grid:
        if count(x) > 0:
            if prev is None:
                return 0.0
            a, b = prev, x
            for _ in range(bisections):
                m = math.sqrt(a * b)
                if count(m) > 0:
                    b = m
                else:
                    a = m
            return a
        prev = x
    return None


def rho_threshold(s, beta, kappa, lo=0.5, hi=3000.0):
    """The first ρ = (r/m) h^{2−β} with a growing mode (None if stable up to hi). Scan ratio
    ≈ 1.09: an instability window narrower than that can be missed (the s = 3, β = 0.1 window
    ρ ≈ 7.8 … 9.8 at κ = 1e-4 is ≈ 25 % wide)."""
    return first_instability(lambda r: unstable_roots(s, beta, r, kappa, n=1500), lo, hi,
                             points=100)


def stability_theory():
    print("undamped (ρ = 0): first κ = (ωh)² with a growing mode, and the stable κ on a scan:")
    for s in (2, 3, 4):
        ks = first_instability(lambda k: unstable_roots(s, 1.0, 0.0, k, n=1500), 0.5, 2000.0)
        grid = np.geomspace(0.5, 2000.0, 40)
        stable = [k for k in grid if unstable_roots(s, 1.0, 0.0, k, n=1000) == 0]
        print(f"  s = {s}: κ* = {ks:.4f} (ωh < {math.sqrt(ks):.4f}); stable scan points beyond κ*: "
              + ", ".join(f"{k:.3g}" for k in stable if k > ks))
    print("ρ → ∞ limit: growing modes of det[(e_1+ζe_s)ᵀBΔ^β; e_kᵀBΔ^β; (e_1−ζe_s)ᵀ] in |ζ| < 1:")
    for s in (2, 3, 4):
        print(f"  s = {s}: " + ", ".join(f"β={b}: {unstable_roots(s, b, 0, 0, limit=True)}"
                                        for b in (0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0, 1.01, 1.3,
                                                  1.5, 1.7, 1.9)))
    print("largest stable ρ = (r/m) h^{2−β} for κ = (k/m) h² = 1e-4, 0.1, 1:")
    for s in (2, 3, 4):
        for beta in (0.1, 0.25, 0.5, 0.75, 0.9):
            th = [rho_threshold(s, beta, k) for k in (1e-4, 0.1, 1.0)]
            print(f"  s = {s}, β = {beta}: " + ", ".join("none" if x is None else f"{x:.4g}"
                                                      for x in th), flush=True)
    kst = {2: 4.0, 3: 8.0, 4: 30.0}
    print("β ≥ 1: growing modes over ρ ∈ {1e-3 … 1e8} × κ ∈ {1e-4, 0.1, 1, 0.5κ*, 0.9κ*, 0.99κ*}:")
    for s in (2, 3, 4):
        for beta in (1.0, 1.25, 1.5, 1.75, 1.95):
            bad = [(r, k) for r in (1e-3, 1e-1, 1, 10, 1e2, 1e4, 1e6, 1e8)
                   for k in (1e-4, 0.1, 1.0, 0.5 * kst[s], 0.9 * kst[s], 0.99 * kst[s])
                   if unstable_roots(s, beta, r, k, n=1500) != 0]
            print(f"  s = {s}, β = {beta}: unstable points {bad}", flush=True)
    print("beyond κ*: growing modes at κ = 1.2κ*, 10κ* and ρ = 0.01, 1, 100, 1e4 (1 = unstable):")
    for s in (2, 3, 4):
        for beta in (1.0, 1.5):
            row = [(k, r, unstable_roots(s, beta, r, k * kst[s], n=1500))
                   for k in (1.2, 10) for r in (0.01, 1, 100, 1e4)]
            print(f"  s = {s}, β = {beta}: " + ", ".join(f"({k}κ*, ρ={r:g}): {u}"
                                                      for k, r, u in row), flush=True)
    print("the root inside the disc in the ρ → ∞ limit (growth factor 1/|ζ*| per step):")
    for s in (2, 3, 4):
        out = []
        for beta in (0.1, 0.5, 0.9):
            f = lambda z: characteristic(s, beta, 0, 0, z, limit=True)
            grid = [(abs(f(r * np.exp(1j * th))), r * np.exp(1j * th))
                    for r in np.linspace(0.01, 0.99, 50) for th in np.linspace(0, 2 * np.pi, 181)]
            z0 = min(grid, key=lambda v: v[0])[1]
            z1 = z0 * 1.001 + 1e-4
            for _ in range(60):
                f0, f1 = f(z0), f(z1)
                if f1 == f0 or abs(z1 - z0) < 1e-14:
                    break
                z0, z1 = z1, z1 - f1 * (z1 - z0) / (f1 - f0)
            out.append(f"β={beta}: ζ* = {z1.real:+.4f}{z1.imag:+.1e}i")
        print(f"  s = {s}: " + ", ".join(out))


def stability_threshold_runs(steps=3000):
    """Time-stepping check of the thresholds of stability_theory(): ρ = 0.9ρ* and 1.1ρ*."""
    print(f"threshold check by time stepping (m = k = 1, x0 = 1, v0 = 0, {steps} steps):")
    # ρ* at κ = 1e-4 from stability_theory(); s = 3 and 4 at β = 0.1 are the lower edges of
    # instability windows (stable again above them: 9.8 … and 45 … 65)
    cases = [(2, 0.5, 0.01, 4.915), (3, 0.5, 0.01, 19.52), (4, 0.5, 0.01, 46.49),
             (2, 0.9, 0.01, 18.14), (4, 0.25, 0.01, 55.01), (3, 0.1, 0.01, 7.9),
             (4, 0.1, 0.01, 26.91)]
    for s, beta, h, rs in cases:
        for f in (0.9, 1.1):
            r = f * rs / h ** (2 - beta)
            g, H, U = quadratic([[1.0]])
            pb = Problem([[1.0]], [[r]], beta, g, H, [1.0], [0.0], 0.0, h * steps, pot=U)
            with np.errstate(all="ignore"):
                sch = LobattoFvi(pb, s, steps).run()
            print(f"  s = {s}, β = {beta}, h = {h}, ρ = {f}ρ* (r = {r:.4g}): "
                  f"max|x_k| = {np.abs(sch.xs).max():.3e}", flush=True)
    print("windows: s = 3, β = 0.1, ρ = 12 and s = 4, β = 0.1, ρ = 55 (stable by the count):")
    for s, beta, rho in ((3, 0.1, 12.0), (4, 0.1, 55.0)):
        h = 0.01
        r = rho / h ** (2 - beta)
        g, H, U = quadratic([[1.0]])
        pb = Problem([[1.0]], [[r]], beta, g, H, [1.0], [0.0], 0.0, h * steps, pot=U)
        with np.errstate(all="ignore"):
            sch = LobattoFvi(pb, s, steps).run()
        print(f"  s = {s}, β = {beta}, ρ = {rho}: max|x_k| = {np.abs(sch.xs).max():.3e}",
              flush=True)
    print("undamped (r = 0), h = 1, k = 0.98κ* and 1.02κ*:")
    for s, ks in ((2, 4.0), (3, 8.0), (4, 30.0)):
        for f in (0.98, 1.02):
            g, H, U = quadratic([[f * ks]])
            pb = Problem([[1.0]], [[0.0]], 1.0, g, H, [1.0], [0.0], 0.0, float(steps), pot=U)
            with np.errstate(all="ignore"):
                sch = LobattoFvi(pb, s, steps).run()
            print(f"  s = {s}, κ = {f}κ*: max|x_k| = {np.abs(sch.xs).max():.3e}", flush=True)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "all"
    t = time.time()
    if what in ("weights", "all"):
        check_weights()
    if what in ("published", "all"):
        published()
    if what in ("moments", "all"):
        published_moments()
    if what in ("gradient", "all"):
        gradient_check()
    if what in ("mirror", "all"):
        mirror_check()
    if what in ("energy", "all"):
        energy_check()
    if what in ("orders", "all"):
        orders_nonlinear()
        orders_caputo()
    if what in ("stability", "all"):
        stability_grid()
    if what in ("thresholds", "all"):
        stability_threshold_runs()
    if what == "stability-theory":   # ≈ 7 min, not part of "all"
        stability_theory()
    print(f"({time.time() - t:.0f} s)")
