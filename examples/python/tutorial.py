"""The code of docs/tutorial.md: from a damped pendulum to a fractional viscoelastic chain —
energy and dissipated energy, fractional (memory) damping, the choice of scheme and step, the run's own
error estimate against independent references, events and dense output, a chain, and where fracvi
differs from scipy.integrate.solve_ivp.

    cmake --preset release && cmake --build --preset release
    PYTHONPATH=build/release/python /usr/bin/python3 examples/python/tutorial.py [OUT_DIR]

With OUT_DIR the figures are written there; docs/figures/tutorial/ holds the output of

# [snippet: figures]
PYTHONPATH=build/release/python /usr/bin/python3 examples/python/tutorial.py docs/figures/tutorial
# [/snippet]

Every number docs/tutorial.md quotes is printed here (lines starting with "tutorial:"), and every
claim the text makes is asserted, so that ctest (python_example_tutorial) fails when the text
goes stale. Needs SciPy and mpmath (Debian's python3-scipy, python3-mpmath) for the references.
"""
import os
import sys
import tempfile

import matplotlib
import matplotlib.pyplot as plt

# [snippet: imports]
import math

import mpmath                                      # a reference: inverse Laplace transforms
import numpy as np
from scipy.integrate import solve_ivp

import fracvi
# [/snippet]

matplotlib.use("Agg")  # files, no window (ctest also sets MPLBACKEND=Agg)

out = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp()
os.makedirs(out, exist_ok=True)


def say(text):
    """A number the tutorial quotes."""
    print("tutorial:", text, flush=True)


def save(figure, name):
    figure.tight_layout()
    figure.savefig(os.path.join(out, name), dpi=90)
    plt.close(figure)


def slope(steps, errors):
    """Least-squares order p of error ~ C N^-p."""
    return -np.polyfit(np.log(steps), np.log(errors), 1)[0]


# ---------------------------------------------------------------------------------------------
# 1. A damped pendulum: x'' + 0.2 x' + sin x = 0 (viscous damping, damping order 2α = 1)
# ---------------------------------------------------------------------------------------------
# [snippet: viscous]
pendulum = fracvi.Problem(
    name="pendulum", dim=1, mass=1.0, damping=0.2, alpha=0.5,   # R x', 2α = 1
    potential="1 - cos(x1)", position=[2.5], velocity=[0.0], end=40.0, steps=4000)
solution = fracvi.integrate(pendulum)
print(solution.status, solution.method)            # success fvi-lobatto3 ("auto" chose it)
E, W = solution.energy, solution.dissipated        # E_k = v²/2 + U(x_k), W_k = work of damping
print(E[0], E[-1], W[-1], solution.max_balance_error)   # max |E_k + W_k - E_0|
# [/snippet]
assert solution.status == "success" and solution.method == "fvi-lobatto3"
assert np.all(np.diff(E) <= 1e-12)                 # viscous damping only takes energy out
say(f"viscous pendulum: {solution.method}, E_0 = {E[0]:.4f}, E(40) = {E[-1]:.2e}, "
    f"W(40) = {W[-1]:.4f}, balance {solution.max_balance_error:.1e}, "
    f"mirror {solution.mirror_error:.1e}, error estimate {solution.error_estimate:.1e}")
assert solution.max_balance_error < 1e-10 and solution.mirror_error < 1e-12
viscous = solution

figure, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2))
ax1.plot(viscous.t, viscous.x[:, 0])
ax1.set(xlabel="t", ylabel="x (rad)", title="viscous pendulum, x(0) = 2.5")
ax2.plot(viscous.t, E, label="energy $E_k$")
ax2.plot(viscous.t, W, label="dissipated $W_k$")
ax2.plot(viscous.t, E + W, "k--", label="$E_k + W_k$")
ax2.set(xlabel="t", title="energy account")
ax2.legend()
save(figure, "pendulum.png")

# ---------------------------------------------------------------------------------------------
# 2. Fractional (viscoelastic) damping: R D^{2α} x with 2α = 0.5 and 1.5, Caputo
# ---------------------------------------------------------------------------------------------
# [snippet: fractional]
runs = {}
for order in (0.5, 1.0, 1.5):                      # the damping order 2α
    problem = pendulum.with_overrides([f"model.alpha={order / 2}", "model.convention=caputo"])
    runs[order] = fracvi.integrate(problem)
    E = runs[order].energy
    print(order, runs[order].status, E[-1], np.max(np.diff(E)))   # largest energy increase
# [/snippet]
for order, run in runs.items():
    assert run.status == "success", (order, run.status, run.message)
rise = {order: float(np.max(np.diff(run.energy))) for order, run in runs.items()}
say("fractional pendulum E(40): " + ", ".join(
    f"2α = {o}: {r.energy[-1]:.3g}" for o, r in runs.items()))
say("largest energy increase in one step: " + ", ".join(
    f"2α = {o}: {rise[o]:.1e}" for o in runs))
assert rise[1.0] <= 1e-12 and rise[0.5] > 1e-5 and rise[1.5] > 1e-5   # memory gives energy back
say("fractional pendulum balance error: " + ", ".join(
    f"2α = {o}: {r.max_balance_error:.0e}" for o, r in runs.items()))
for order in (0.5, 1.5):
    assert runs[order].max_balance_error < 1e-8, runs[order].max_balance_error

# [snippet: riemann-liouville]
try:
    fracvi.Problem(name="rl", dim=1, mass=1.0, damping=0.2, damping_order=1.5,
                   convention="riemann-liouville", potential="1 - cos(x1)",
                   position=[2.5], end=40.0, steps=4000)
except fracvi.ProblemError as error:
    print(error)                                   # ... is ill-posed: ... not integrable at t = 0
rl = fracvi.integrate(pendulum.with_overrides(
    ["model.alpha=0.25", "model.convention=riemann-liouville"]))
print(np.max(np.abs(rl.x - runs[0.5].x)))          # RL and Caputo differ when x(0) != 0
# [/snippet]
try:
    fracvi.Problem(name="rl", dim=1, mass=1.0, damping=0.2, damping_order=1.5,
                   convention="riemann-liouville", potential="1 - cos(x1)",
                   position=[2.5], end=40.0, steps=4000)
    raise AssertionError("the ill-posed Riemann-Liouville problem was accepted")
except fracvi.ProblemError as error:
    assert "ill-posed" in str(error) and "not integrable" in str(error)
assert rl.status == "success"
rl_difference = float(np.max(np.abs(rl.x - runs[0.5].x)))
say(f"RL - Caputo at 2α = 0.5: max |Δx| = {rl_difference:.2f}")
assert rl_difference > 0.01

figure, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2))
for order, run in runs.items():
    ax1.plot(run.t, run.x[:, 0], label=f"2α = {order} (Caputo)")
    ax2.semilogy(run.t, run.energy, label=f"2α = {order}")
ax1.plot(rl.t, rl.x[:, 0], "k:", label="2α = 0.5 (Riemann–Liouville)")
ax1.set(xlabel="t", ylabel="x (rad)", title="pendulum, R = 0.2, damping order 2α")
ax1.legend(fontsize=7)
ax2.set(xlabel="t", ylabel="energy E", title="energy (memory: not monotone for 2α ≠ 1)")
ax2.legend(fontsize=7)
save(figure, "fractional.png")

# ---------------------------------------------------------------------------------------------
# 3. Choosing the scheme and the step
# ---------------------------------------------------------------------------------------------
# [snippet: schemes]
for method in fracvi.methods():
    print(f"{method['name']:16} {method['order']:50} {method['applies_to']}")
# [/snippet]
names = [m["name"] for m in fracvi.methods()]
assert {"fvi-gl", "fvi-midpoint", "fvi-lobatto3", "dopri5"} <= set(names)

# [snippet: estimate]
fractional = runs[1.5]
print(fractional.method, fractional.error_estimate)     # fvi-lobatto3, ~6e-10 (max |x_k - x(t_k)|)
print(fractional.summary()["error_estimate_details"])   # Richardson from N/2 and N/4, order seen
gl = fracvi.integrate(fractional.problem, scheme="fvi-gl")
print(gl.error_estimate)                               # the paper's scheme, first order: ~1e-2
fine = fracvi.integrate(fractional.problem, scheme="fvi-midpoint", tolerance=1e-5)
print(fine.steps, fine.error_estimate)                 # N doubled until the estimate is <= 1e-5
# [/snippet]
details = fractional.summary()["error_estimate_details"]
say(f"fractional pendulum 2α = 1.5, N = 4000: {fractional.method} estimate "
    f"{fractional.error_estimate:.1e} (observed order {details['observed_order']:.1f}); "
    f"fvi-gl estimate {gl.error_estimate:.1e} (observed order "
    f"{gl.summary()['error_estimate_details']['observed_order']:.2f}); "
    f"fvi-midpoint to 1e-5: N = {fine.steps}, estimate {fine.error_estimate:.1e}")
assert fine.status == "success" and fine.error_estimate <= 1e-5
tried = [r["steps"] for r in fine.summary()["tolerance_runs"]]
say(f"tolerance=1e-5 tried N = {tried}")
assert tried[0] == 4000 and tried[-1] == fine.steps
# The estimates against an independent check: a far finer run of another scheme, fvi-lobatto4.
check = fracvi.integrate(fractional.problem.with_overrides("time.steps=32000"), every=8,
                         scheme="fvi-lobatto4")
for run, name in ((fractional, "fvi-lobatto3"), (gl, "fvi-gl")):
    error = np.abs(run.x[:, 0] - check.x[:, 0])
    worst = int(np.argmax(error))
    # Richardson compares the run with its N/2 companion at their common nodes, the even steps;
    # the first 16 steps are checked with h/2 and h/4 too (where fvi-lobatto3's error peaks).
    say(f"{name} on the fractional pendulum: true max error {error.max():.1e} at t = "
        f"{run.t[worst]:g} (step {worst}), over the even steps {error[::2].max():.1e}; "
        f"estimate / true = {run.error_estimate / error.max():.2f}, over the even steps "
        f"{run.error_estimate / error[::2].max():.2f}")
    assert 0.5 < run.error_estimate / error.max() < 2.0, (name, run.error_estimate, error.max())

# A convergence study against independent references: the viscous pendulum against SciPy's
# DOP853 at tolerance 1e-13, the linear fractional oscillator against the inverse Laplace
# transform of its exact solution.
# [snippet: references]
def rhs(t, y):                                     # the viscous pendulum as a first-order ODE
    return [y[1], -0.2 * y[1] - math.sin(y[0])]

def pendulum_reference(t):
    return solve_ivp(rhs, (0.0, 40.0), [2.5, 0.0], method="DOP853", t_eval=t,
                     rtol=1e-13, atol=1e-13).y[0]

R, order = 0.2, 1.5                                # x'' + 0.2 D^1.5 x + x = 0, x(0) = 1 (Caputo)
def laplace_x(s):                                  # its Laplace transform, exact
    return (s + R * s**(order - 1)) / (s**2 + R * s**order + 1)

def oscillator_reference(t):
    mpmath.mp.dps = 30
    return np.array([float(mpmath.invertlaplace(laplace_x, ti, method="talbot")) for ti in t])
# [/snippet]

# The references checked: DOP853 at 1e-13 against Radau (a different method) at 1e-12; Talbot's
# inversion against de Hoog's and against the published y(20) of the comparison study (R = 0.5).
t_check = np.linspace(0.0, 40.0, 81)
radau = solve_ivp(rhs, (0.0, 40.0), [2.5, 0.0], method="Radau", t_eval=t_check,
                  rtol=1e-12, atol=1e-12).y[0]
assert np.max(np.abs(radau - pendulum_reference(t_check))) < 1e-9
mpmath.mp.dps = 30
assert abs(float(mpmath.invertlaplace(laplace_x, 7.3, method="dehoog"))
           - oscillator_reference([7.3])[0]) < 1e-14
published = float(mpmath.invertlaplace(
    lambda s: (s + 0.5 * s**0.5) / (s**2 + 0.5 * s**1.5 + 1), 20.0, method="talbot"))
assert abs(published - (-0.061964539893443569)) < 1e-15

# Reference times: every node of the coarsest grid (h = 0.2 for the pendulum, 0.1 for the
# oscillator) and the first 16 steps of the finest: the largest errors of a fractional run sit
# in its first steps (see the text).
steps = [200, 400, 800, 1600, 3200]
oscillator = fracvi.Problem(name="oscillator", dim=1, mass=1.0, damping=R, damping_order=order,
                            convention="caputo", potential="x1^2/2", position=[1.0], end=20.0,
                            steps=200)
studies = {
    "viscous pendulum vs DOP853": (pendulum, 40.0, pendulum_reference,
                                   ["fvi-gl", "fvi-midpoint", "fvi-lobatto3"]),
    "fractional oscillator (2α = 1.5) vs Laplace": (
        oscillator, 20.0, oscillator_reference,
        ["fvi-gl", "fvi-bdf2", "fvi-midpoint", "fvi-lobatto3"]),
}
measured = {}
figure, axes = plt.subplots(1, 2, figsize=(9, 3.6))
for ax, (title, (problem, end, reference, schemes)) in zip(axes, studies.items()):
    h_min = end / steps[-1]
    t_ref = np.unique(np.round(np.concatenate(
        [np.linspace(0.0, end, steps[0] + 1), h_min * np.arange(17)]), 12))[1:]   # t > 0
    x_ref = reference(t_ref)
    for scheme in schemes:
        errors, estimates = [], []
        for n in steps:
            run = fracvi.integrate(problem.with_overrides(f"time.steps={n}"), scheme=scheme)
            assert run.status == "success", (scheme, n, run.message)
            k = np.round(t_ref / (end / n))
            on_grid = np.abs(k * (end / n) - t_ref) < 1e-9
            errors.append(np.max(np.abs(run.x[k[on_grid].astype(int), 0] - x_ref[on_grid])))
            estimates.append(run.error_estimate)
        errors, estimates = np.array(errors), np.array(estimates)
        measured[title, scheme] = (slope(steps, errors), errors, estimates)
        color = {"fvi-gl": "C0", "fvi-bdf2": "C1", "fvi-midpoint": "C2"}.get(scheme, "C3")
        ax.loglog(steps, errors, "o-", color=color,
                  label=f"{scheme}: slope {slope(steps, errors):.2f}")
        ax.loglog(steps, estimates, "x:", color=color)
    ax.set(xlabel="steps N", ylabel="max error of x", title=title)
    ax.legend(fontsize=7, title="o true error, x estimate", title_fontsize=7)
save(figure, "convergence.png")
for (title, scheme), (p, errors, estimates) in measured.items():
    ratio = estimates / errors
    say(f"{title}, {scheme}: slope {p:.2f}, error at N = {steps[-1]} {errors[-1]:.1e}, "
        f"estimate/error {ratio.min():.2f} .. {ratio.max():.2f}")
    # The estimate is within a factor 3 of the true error either way (low only where the first
    # steps of a fractional run hold the largest error: fvi-lobatto3, see the text).
    assert 1 / 3 < ratio.min() and ratio.max() < 3.0, (title, scheme, ratio)
lobatto3_errors = measured["viscous pendulum vs DOP853", "fvi-lobatto3"][1]
say("viscous pendulum, fvi-lobatto3 error by N: " + ", ".join(
    f"{n}: {e:.1e}" for n, e in zip(steps, lobatto3_errors)))
declared = {"fvi-gl": 1.0, "fvi-bdf2": 2.0, "fvi-midpoint": 2.0}
for (title, scheme), (p, errors, estimates) in measured.items():
    if scheme in declared:
        assert abs(p - declared[scheme]) < 0.1, (title, scheme, p)
assert abs(measured["viscous pendulum vs DOP853", "fvi-lobatto3"][0] - 4.0) < 0.2
assert measured["fractional oscillator (2α = 1.5) vs Laplace", "fvi-lobatto3"][0] > 2.0

# Stability: fvi-gl's explicit memory has a step-size bound; a run past it is refused.
# [snippet: stability]
stiff = pendulum.with_overrides(["model.damping=5", "model.alpha=0.75", "model.convention=caputo",
                                 "time.steps=400"])                 # 2α = 1.5, h = 0.1
try:
    fracvi.integrate(stiff, scheme="fvi-gl")
except fracvi.ProblemError as error:
    print(error)          # ... beyond the stability bound of fvi-gl ... time.steps >= 501
print(fracvi.integrate(stiff, scheme="fvi-midpoint").status)   # implicit memory: success
# [/snippet]
try:
    fracvi.integrate(stiff, scheme="fvi-gl")
    raise AssertionError("a step beyond fvi-gl's stability bound was accepted")
except fracvi.ProblemError as error:
    message = str(error)
# λ_max(M⁻¹R) (h/2)^(2-2α) < 1 with λ = 5, 2α = 1.5: h < 2/25 = 0.08, N > 40/0.08 = 500.
assert "stability bound of fvi-gl" in message and "time.steps >= 501" in message, message
say("stability: " + message.split(": ", 1)[1])
assert fracvi.integrate(stiff, scheme="fvi-midpoint").status == "success"
at_bound = fracvi.integrate(stiff.with_overrides("time.steps=501"), scheme="fvi-gl")
assert at_bound.status == "success", at_bound.message

# ---------------------------------------------------------------------------------------------
# 4. Events and dense output: when does the pendulum first pass through the bottom?
# ---------------------------------------------------------------------------------------------
# [snippet: events]
def bottom(t, x, v):                               # g(t, x, v); SciPy's attributes
    return x[0]
bottom.terminal = True
bottom.direction = -1

first = fracvi.integrate(pendulum, events=[bottom])
print(first.status, first.t_events["bottom"])      # "event", [t*]: stopped at x(t*) = 0
dense = fracvi.integrate(pendulum, dense=True)     # every step kept: sol(t) anywhere
print(dense(first.t_events["bottom"][0]))          # x(t*) on the same interpolant: ~0
swings = fracvi.integrate(pendulum, events={"name": "zero", "g": "x1"})   # a formula: fast
print(np.diff(swings.t_events["zero"]))            # half periods, shrinking as E → 0
# [/snippet]
t_star = float(first.t_events["bottom"][0])
assert first.status == "event" and first.events[-1].name == "bottom"
def bottom_scipy(t, y):                            # SciPy's events take (t, y), y = (x, v)
    return y[0]
bottom_scipy.terminal, bottom_scipy.direction = True, -1
sp = solve_ivp(rhs, (0.0, 40.0), [2.5, 0.0], method="DOP853", rtol=1e-13, atol=1e-13,
               events=bottom_scipy)
t_scipy = float(sp.t_events[0][0])
half_periods = np.diff(swings.t_events["zero"])
say(f"first pass through the bottom: t* = {t_star:.10f}, DOP853 {t_scipy:.10f}, "
    f"difference {abs(t_star - t_scipy):.1e}; dense x(t*) = {dense(t_star)[0]:.1e}; "
    f"{len(swings.t_events['zero'])} zero crossings, half periods {half_periods[0]:.3f} .. "
    f"{half_periods[-1]:.3f}")
assert abs(t_star - t_scipy) < 1e-9 and abs(dense(t_star)[0]) < 1e-9
linear_half_period = math.pi / math.sqrt(1 - 0.1**2)   # small swings: x'' + 0.2 x' + x = 0
say(f"linear damped half period {linear_half_period:.4f}")
assert np.all(np.diff(half_periods) < 0) and abs(half_periods[-1] - linear_half_period) < 0.002

# ---------------------------------------------------------------------------------------------
# 5. A fractional viscoelastic chain
# ---------------------------------------------------------------------------------------------
# [snippet: chain]
chain = fracvi.Problem(
    name="viscoelastic-chain", dim=200, mass=1.0, damping=0.05, damping_order=1.5,
    convention="caputo", chain=dict(stiffness=1.0, onsite=0.1, boundary="fixed"),
    position="exp(-((i - d/2)/8)^2)", end=100.0, steps=2000, every=10, threads=1)
paper = fracvi.integrate(chain, scheme="fvi-gl")       # the paper's scheme, first order
accurate = fracvi.integrate(chain)                     # "auto": fvi-lobatto3
for run in (paper, accurate):
    print(run.method, run.linear_solver, run.error_estimate, run.max_balance_error, run.wall_time)
# [/snippet]
for run in (paper, accurate):
    assert run.status == "success", run.message
difference = float(np.max(np.abs(paper.x - accurate.x)))
say(f"chain d = 200, N = 2000: fvi-gl estimate {paper.error_estimate:.1e}, balance "
    f"{paper.max_balance_error:.0e}, {paper.linear_solver}; {accurate.method} estimate "
    f"{accurate.error_estimate:.1e}, balance {accurate.max_balance_error:.0e}, "
    f"{accurate.linear_solver}; max |x_gl - x_lobatto3| = {difference:.1e}; "
    f"E: {accurate.energy[0]:.3f} -> {accurate.energy[-1]:.3f}; wall time ratio "
    f"{accurate.wall_time / paper.wall_time:.0f} (one run, shared machine)")
assert accurate.method == "fvi-lobatto3" and paper.linear_solver == "banded"
assert 0.5 < paper.error_estimate / difference < 2.0       # the estimate of fvi-gl, checked
assert accurate.error_estimate < 1e-3 * paper.error_estimate
assert paper.max_balance_error < 1e-11                     # exact for a quadratic U

figure, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.4))
image = ax1.imshow(accurate.x.T, aspect="auto", origin="lower", cmap="RdBu_r", vmin=-0.6,
                   vmax=0.6, extent=[0.0, 100.0, 1, chain.dim])
figure.colorbar(image, ax=ax1, label="$x_i$")
ax1.set(xlabel="t", ylabel="mass i", title="viscoelastic chain, 2α = 1.5")
ax2.plot(accurate.t, accurate.energy, label="energy $E_k$")
ax2.plot(accurate.t, accurate.dissipated, label="dissipated $W_k$")
ax2.set(xlabel="t", title="energy account of the chain")
ax2.legend()
save(figure, "chain.png")

# ---------------------------------------------------------------------------------------------
# 6. Where fracvi differs from solve_ivp
# ---------------------------------------------------------------------------------------------
# [snippet: solve-ivp]
t_eval = np.linspace(0.0, 40.0, 401)
scipy_run = solve_ivp(rhs, (0.0, 40.0), [2.5, 0.0], method="DOP853", t_eval=t_eval,
                      rtol=1e-10, atol=1e-10, dense_output=True)
fracvi_run = fracvi.integrate(pendulum, t_eval=t_eval)
reference = pendulum_reference(t_eval)
print(np.max(np.abs(scipy_run.y[0] - reference)), scipy_run.nfev)      # y is (2, n): rows
print(np.max(np.abs(fracvi_run.x_eval[:, 0] - reference)), fracvi_run.steps)   # x is (n, d)
print(fracvi_run.error_estimate)                   # fracvi's own estimate; SciPy has none
# [/snippet]
scipy_error = float(np.max(np.abs(scipy_run.y[0] - reference)))
fracvi_error = float(np.max(np.abs(fracvi_run.x_eval[:, 0] - reference)))
say(f"solve_ivp DOP853 rtol 1e-10: error {scipy_error:.1e}, {scipy_run.nfev} evaluations, "
    f"{scipy_run.sol.n_segments} steps; fracvi "
    f"{fracvi_run.method} N = {fracvi_run.steps}: error {fracvi_error:.1e}, "
    f"estimate {fracvi_run.error_estimate:.1e}")
assert scipy_run.success and fracvi_run.status == "success"
assert scipy_error < 1e-8 and fracvi_error < 1e-10
assert 0.3 < fracvi_run.error_estimate / fracvi_error < 3.0
assert scipy_run.sol.n_segments < fracvi_run.steps           # adaptive: fewer, larger steps

# The energy account: solve_ivp has none; integrate the dissipated work W' = R v² alongside.
# [snippet: solve-ivp-energy]
def rhs_with_work(t, y):                           # (x, v, W): W' = R v², the damping's work
    return [y[1], -0.2 * y[1] - math.sin(y[0]), 0.2 * y[1] ** 2]

account = solve_ivp(rhs_with_work, (0.0, 40.0), [2.5, 0.0, 0.0], method="DOP853",
                    t_eval=t_eval, rtol=1e-10, atol=1e-10)
x, v, W = account.y
balance = 0.5 * v**2 + 1 - np.cos(x) + W - (1 - math.cos(2.5))
print(np.max(np.abs(balance)))                     # the ODE solver's tolerance, not round-off
# [/snippet]
scipy_balance = float(np.max(np.abs(balance)))
gl_pendulum = fracvi.integrate(pendulum, scheme="fvi-gl")
quadratic = fracvi.integrate(pendulum.with_overrides("model.potential=x1^2/2"), scheme="fvi-gl")
say(f"balance: solve_ivp + W' = R v² {scipy_balance:.1e}; fracvi {fracvi_run.method} "
    f"{fracvi_run.max_balance_error:.1e}, fvi-gl {gl_pendulum.max_balance_error:.1e} "
    f"(pendulum), {quadratic.max_balance_error:.1e} (quadratic U)")
assert scipy_balance < 1e-8 and quadratic.max_balance_error < 1e-13

# Files: a Problem and its Solution go to disk and back.
# [snippet: files]
directory = os.path.join(tempfile.mkdtemp(), "pendulum")
fracvi.write(solution, directory, format="npz")    # §1's pendulum: trajectory.npz, problem.toml,
                                                   # summary.json
loaded = fracvi.load(directory)                    # a Solution with its Problem
assert np.array_equal(loaded.x, solution.x) and loaded.problem == solution.problem
# [/snippet]

figure, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2))
ax1.semilogy(t_eval, np.abs(scipy_run.y[0] - reference) + 1e-17,
             label="solve_ivp DOP853, tol 1e-10")
ax1.semilogy(t_eval, np.abs(fracvi_run.x_eval[:, 0] - reference) + 1e-17,
             label=f"fracvi {fracvi_run.method}, N = {fracvi_run.steps}")
ax1.set(xlabel="t", ylabel="|x - x_ref|", title="error against DOP853 at 1e-13",
        ylim=(1e-16, 1e-6))
ax1.legend(fontsize=7)
ax2.semilogy(t_eval, np.abs(balance) + 1e-17, label="solve_ivp with W' = R v²")
ax2.semilogy(viscous.t, np.abs(viscous.balance) + 1e-17, label=f"fracvi {viscous.method}")
ax2.semilogy(gl_pendulum.t, np.abs(gl_pendulum.balance) + 1e-17, label="fracvi fvi-gl")
ax2.set(xlabel="t", ylabel="|E + W - E_0|", title="energy balance error", ylim=(1e-16, 1e-4))
ax2.legend(fontsize=7)
save(figure, "solve_ivp.png")
print("tutorial: figures in", out)
