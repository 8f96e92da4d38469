"""Weights, the paper's discrete operators (`AllSequencs`) and continuous Riemann–Liouville
derivatives (`RL`) from Python: NumPy in, NumPy out."""
import math

import numpy as np
import pytest

import fracvi

EPS = np.finfo(float).eps


# --- weights ---------------------------------------------------------------------------------

def test_gl_weights_known_values():
    # (1 - z)^(1/2) = 1 - z/2 - z^2/8 - z^3/16 - 5 z^4/128: dyadic, so exact.
    w = fracvi.gl_weights(0.5, 5)
    assert isinstance(w, np.ndarray) and w.dtype == np.float64 and w.shape == (5,)
    assert w.tolist() == [1.0, -0.5, -0.125, -0.0625, -0.0390625]
    assert fracvi.gl_weights(1, 4).tolist() == [1.0, -1.0, 0.0, 0.0]
    assert fracvi.gl_weights(2, 4).tolist() == [1.0, -2.0, 1.0, 0.0]
    assert fracvi.gl_weights(0.3, 0).shape == (0,)


def test_gl_weights_match_gamma_ratio():
    # α_n = Γ(n − β)/(Γ(−β) Γ(n + 1)); math.gamma is accurate to a few ulps, the ratio of three
    # gammas to ~10 ulps, the library to ≤ kGlAnchorInterval·ε but far less for n ≤ 60.
    tolerance = 64 * EPS
    for beta in (0.3, 0.75, 1.5, -0.4):
        w = fracvi.gl_weights(beta, 60)
        for n in range(60):
            exact = math.gamma(n - beta) / (math.gamma(-beta) * math.gamma(n + 1))
            assert abs(w[n] - exact) <= tolerance * abs(exact), (beta, n)


def test_cq_weights():
    assert fracvi.cq_weights(1, 4, "bdf2").tolist() == [1.5, -2.0, 0.5, 0.0]
    assert fracvi.cq_weights(1, 4, "trapezoidal").tolist() == [2.0, -4.0, 4.0, -4.0]
    assert np.array_equal(fracvi.cq_weights(0.7, 100), fracvi.gl_weights(0.7, 100))
    # Composition: δ^a δ^b = δ^(a+b), so the weight sequences convolve.
    a, b = fracvi.cq_weights(0.3, 40, "bdf2"), fracvi.cq_weights(0.45, 40, "bdf2")
    ab = fracvi.cq_weights(0.75, 40, "bdf2")
    np.testing.assert_allclose(np.convolve(a, b)[:40], ab, rtol=0, atol=1e-14)


def test_weight_errors():
    with pytest.raises(ValueError, match="scheme = 'bdf3' is not a known scheme"):
        fracvi.cq_weights(0.5, 3, "bdf3")
    with pytest.raises(ValueError, match="n = -1"):
        fracvi.gl_weights(0.5, -1)
    with pytest.raises(ValueError, match="finite"):
        fracvi.gl_weights(float("nan"), 3)
    with pytest.raises(TypeError):
        fracvi.gl_weights(0.5, 2.0)


# --- discrete operators ----------------------------------------------------------------------

def sequence(n=21, d=3, seed=7):
    return np.random.default_rng(seed).standard_normal((n, d))


def test_shapes_and_layout():
    z = sequence()
    for op, args in ((fracvi.midpoint, ()), (fracvi.delta_minus, (0.1,)),
                     (fracvi.delta_plus, (0.1,)), (fracvi.frac_delta_minus, (0.1, 0.4)),
                     (fracvi.frac_delta_plus, (0.1, 0.4))):
        out = op(z, *args)
        assert out.shape == z.shape and out.flags["C_CONTIGUOUS"], op
        # Components are independent: the 2-D result is the 1-D one per column, exactly.
        for i in range(z.shape[1]):
            col = op(z[:, i], *args)
            assert col.shape == (z.shape[0],)
            assert np.array_equal(out[:, i], col), op
        # Non-contiguous and integer input is accepted.
        assert np.array_equal(op(np.asfortranarray(z), *args), out)
    assert np.array_equal(fracvi.midpoint([0, 2, 4]), [1.0, 3.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        fracvi.midpoint(np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="h = "):
        fracvi.delta_minus(z, 0.0)


def test_differences_of_a_linear_sequence():
    h, n = 0.25, 12
    k = np.arange(n + 1)
    z = np.column_stack([2.0 + 3.0 * k * h, -1.0 * k * h])  # slopes 3 and −1
    dm = fracvi.delta_minus(z, h)
    dp = fracvi.delta_plus(z, h)
    # Each z_k carries a rounding error ≤ ε|z_k| ≤ 11ε; a difference over h = 1/4 turns two of
    # them into ≤ 88ε absolute, ≤ 30ε relative to the slopes — 8εN = 96ε covers it.
    assert np.array_equal(dm[0], [0.0, 0.0])  # Δ_− z_0 := 0
    np.testing.assert_allclose(dm[1:], np.tile([3.0, -1.0], (n, 1)), rtol=8 * EPS * n)
    np.testing.assert_allclose(dp[:-1], np.tile([-3.0, 1.0], (n, 1)), rtol=8 * EPS * n)
    assert np.array_equal(dp[-1], [0.0, 0.0])
    np.testing.assert_array_equal(fracvi.midpoint(z)[:-1], (z[:-1] + z[1:]) / 2)


def test_fractional_differences_of_integer_order():
    z, h = sequence(), 0.1
    assert np.array_equal(fracvi.frac_delta_minus(z, h, 0.0), z)
    assert np.array_equal(fracvi.frac_delta_plus(z, h, 0.0), z)
    # Order 1: weights (1, −1, 0, ...), i.e. the backward difference, with z_0/h at k = 0. The two
    # computations differ only in rounding: ≤ 4ε|z|/h with |z| ≲ 4 (standard normal, fixed seed).
    d1 = fracvi.frac_delta_minus(z, h, 1.0)
    np.testing.assert_allclose(d1[1:], fracvi.delta_minus(z, h)[1:], rtol=0, atol=4 * EPS / h)
    np.testing.assert_allclose(d1[0], z[0] / h, rtol=2 * EPS)
    d1p = fracvi.frac_delta_plus(z, h, 1.0)
    np.testing.assert_allclose(d1p[:-1], fracvi.delta_plus(z, h)[:-1], rtol=0, atol=4 * EPS / h)


def test_semigroup_and_summation_by_parts():
    z, y, h = sequence(seed=1), sequence(seed=2), 0.05
    n = z.shape[0]
    # Sums of n terms bounded by |w_m|·|z|·h^(−order) with Σ|w_m| ≤ 2^order ≤ 2: rounding error
    # ≲ n ε max|z| h^(−order) per entry; 64 × that leaves room without hiding an index error
    # (which would be O(max|z| h^(−order))).
    scale = np.abs(z).max() * h ** -1.0 * n
    # Δ^a_− Δ^b_− = Δ^(a+b)_− (the weights of (1−ζ)^a (1−ζ)^b = (1−ζ)^(a+b)).
    lhs = fracvi.frac_delta_minus(fracvi.frac_delta_minus(z, h, 0.3), h, 0.45)
    np.testing.assert_allclose(lhs, fracvi.frac_delta_minus(z, h, 0.75), rtol=0,
                               atol=64 * EPS * scale)
    # Σ_k y_k·Δ^α_− z_k = Σ_k z_k·Δ^α_+ y_k (discrete fractional integration by parts).
    alpha = 0.6
    left = np.sum(y * fracvi.frac_delta_minus(z, h, alpha))
    right = np.sum(z * fracvi.frac_delta_plus(y, h, alpha))
    assert abs(left - right) <= 64 * EPS * n * n * h ** -alpha * np.abs(y).max() * \
        np.abs(z).max()
    # convolve_past with GL weights is h^α Δ^α_−.
    w = fracvi.gl_weights(alpha, n)
    np.testing.assert_allclose(fracvi.convolve_past(w, z) * h ** -alpha,
                               fracvi.frac_delta_minus(z, h, alpha), rtol=4 * EPS, atol=0)
    np.testing.assert_allclose(fracvi.convolve_future(w, z) * h ** -alpha,
                               fracvi.frac_delta_plus(z, h, alpha), rtol=4 * EPS, atol=0)
    with pytest.raises(ValueError, match="weights"):
        fracvi.convolve_past(w[:3], z)


def test_operator_results_own_their_memory():
    z = sequence()
    out = fracvi.frac_delta_minus(z, 0.1, 0.5)
    assert out.base is not None and not np.shares_memory(out, z)
    assert out.flags["WRITEABLE"]
    out[0, 0] = 42.0  # a fresh result belongs to the caller
    del z
    assert out[0, 0] == 42.0


# --- Riemann–Liouville derivatives -----------------------------------------------------------

# rl_derivative is accurate to ≤ 3e-15 relative (tests/fractional/riemann_liouville_test.cpp);
# the C++ tests hold it to 1e-12, and so does this.
RL_TOLERANCE = 1e-12


def test_rl_derivative_formula_against_closed_form():
    t = np.array([0.25, 0.5, 1.0, 2.0])
    got = fracvi.rl_derivative(0.5, "t^1.5", t, 0.0, 2.0)
    exact = 0.75 * math.sqrt(math.pi) * t  # Γ(5/2)/Γ(2) t
    np.testing.assert_allclose(got, exact, rtol=RL_TOLERANCE)
    # shape is preserved, a scalar gives a float
    grid = fracvi.rl_derivative(0.5, "t^1.5", t.reshape(2, 2), 0.0, 2.0)
    assert grid.shape == (2, 2) and np.array_equal(grid.ravel(), got)
    one = fracvi.rl_derivative(0.5, "t^1.5", 1.0, 0.0, 2.0)
    assert isinstance(one, float) and one == got[2]


def test_rl_derivative_callables_and_right_side():
    a, b, alpha = 0.5, 2.0, 0.3
    t = np.linspace(0.6, 1.9, 5)
    got = fracvi.rl_derivative(alpha, lambda s: (s - a) ** 2, t, a, b,
                               df=lambda s: 2 * (s - a))
    exact = math.gamma(3) / math.gamma(3 - alpha) * (t - a) ** (2 - alpha)
    np.testing.assert_allclose(got, exact, rtol=RL_TOLERANCE)
    np.testing.assert_allclose(fracvi.rl_derivative_power(alpha, 2, t, a, b), exact,
                               rtol=4 * EPS)
    right = fracvi.rl_derivative(alpha, "(2-t)^3", t, a, b, side="right")
    np.testing.assert_allclose(
        right, fracvi.rl_derivative_power(alpha, 3, t, a, b, side="right"), rtol=RL_TOLERANCE)
    # α = 1: ±f' exactly (the paper's sign for D_+); a formula for f, a callable for df
    assert fracvi.rl_derivative(1.0, "sin(t)", 0.5, 0, 3) == pytest.approx(math.cos(0.5),
                                                                           abs=1e-14)
    assert fracvi.rl_derivative(1.0, "sin(t)", 0.5, 0, 3, side="right",
                                df=math.cos) == pytest.approx(-math.cos(0.5), abs=1e-14)


def test_rl_derivative_errors():
    with pytest.raises(ValueError, match="df"):
        fracvi.rl_derivative(0.5, math.sin, 1.0, 0, 2)
    with pytest.raises(ValueError, match="side = 'up'"):
        fracvi.rl_derivative(0.5, "t", 1.0, 0, 2, side="up")
    with pytest.raises(ValueError, match=r'f = "sin\(": .* at column \d+ \(a formula in t\)'):
        fracvi.rl_derivative(0.5, "sin(", 1.0, 0, 2)
    with pytest.raises(ValueError, match="alpha"):
        fracvi.rl_derivative(1.5, "t", 1.0, 0, 2)
    with pytest.raises(ValueError):
        fracvi.rl_derivative(0.5, "t", 3.0, 0, 2)  # outside [a, b]
    with pytest.raises(TypeError):
        fracvi.rl_derivative(0.5, 42, 1.0, 0, 2, df=math.cos)

    def broken(s):
        raise ZeroDivisionError("boom")
    with pytest.raises(ZeroDivisionError, match="boom"):
        fracvi.rl_derivative(0.5, math.sin, 1.0, 0, 2, df=broken)


# --- fractional differences of other convolution quadratures (quadrature=) -------------------

def test_fractional_differences_with_a_quadrature_are_its_weights():
    # Δ^α_± with quadrature=q is h^(−α) times the convolution with cq_weights(α, N+1, q): the
    # same products and sums in the same order, so equal to the last bit.
    rng = np.random.default_rng(7)
    z = rng.standard_normal((41, 2))
    h, alpha = 0.05, 0.35
    for q in ("gl", "bdf2", "trapezoidal"):
        w = fracvi.cq_weights(alpha, 41, q)
        assert np.array_equal(fracvi.frac_delta_minus(z, h, alpha, quadrature=q),
                              fracvi.convolve_past(w, z) * h ** -alpha), q
        assert np.array_equal(fracvi.frac_delta_plus(z, h, alpha, quadrature=q),
                              fracvi.convolve_future(w, z) * h ** -alpha), q
    # The default is the paper's Grünwald–Letnikov operator.
    assert np.array_equal(fracvi.frac_delta_minus(z, h, alpha),
                          fracvi.frac_delta_minus(z, h, alpha, quadrature="gl"))
    assert not np.array_equal(fracvi.frac_delta_minus(z, h, alpha),
                              fracvi.frac_delta_minus(z, h, alpha, quadrature="bdf2"))


@pytest.mark.parametrize("quadrature,order", [("gl", 1), ("bdf2", 2), ("trapezoidal", 2)])
def test_fractional_differences_converge_with_the_order_of_their_quadrature(quadrature, order):
    # z = t³ on [0, 1] (zero initial data up to z'', so no start-up correction is needed): the
    # error of Δ^α_− z at t = 1 against D^α_− t³ = Γ(4)/Γ(4 − α) t^(3−α), and of Δ^α_+ for
    # (1 − t)³ at t = 0, falls by 2^order when h halves (measured ratios within 10 %).
    alpha = 0.6
    exact = fracvi.rl_derivative_power(alpha, 3.0, 1.0, 0.0, 1.0)
    errors_minus, errors_plus = [], []
    for n in (64, 128, 256):
        t = np.linspace(0.0, 1.0, n + 1)
        h = 1.0 / n
        minus = fracvi.frac_delta_minus(t ** 3, h, alpha, quadrature=quadrature)
        plus = fracvi.frac_delta_plus((1.0 - t) ** 3, h, alpha, quadrature=quadrature)
        errors_minus.append(abs(minus[-1] - exact))
        errors_plus.append(abs(plus[0] - exact))
    for errors in (errors_minus, errors_plus):
        for coarse, fine in zip(errors, errors[1:]):
            assert coarse / fine == pytest.approx(2.0 ** order, rel=0.1), (quadrature, errors)


def test_fractional_difference_quadrature_errors():
    z = np.zeros(5)
    with pytest.raises(ValueError, match="quadrature = 'bdf3' is not a known convolution "
                                         "quadrature \\(choose gl, bdf2 or trapezoidal\\)"):
        fracvi.frac_delta_minus(z, 0.1, 0.5, quadrature="bdf3")
    with pytest.raises(ValueError, match="frac_delta_plus: quadrature = 'GL'"):
        fracvi.frac_delta_plus(z, 0.1, 0.5, quadrature="GL")
