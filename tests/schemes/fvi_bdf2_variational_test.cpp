// fvi-bdf2 is variational: its equations are the restricted gradient of the action sum whose
// discrete fractional differences Δ^α_± are the BDF2 convolution quadrature
// (docs/theory/fvi_bdf2.md).
//
// Ground truth: the extended action sum A_d⁺ = h Σ_{k=0}^{N} L(k) (`DiscActSum` completed by L(N),
// docs/theory/discrete_euler_lagrange.md §2) of the mechanical Lagrangian (Cor. 4.4 with full M, R,
// a nonlinear time-dependent U and the forcing folded into U), with the phase points of
// `AllSequencs` built from the BDF2 weights ω^{(α)} = coefficients of δ(ζ)^α,
// δ(ζ) = 3/2 − 2ζ + ζ²/2, differentiated as a whole by Eigen's AutoDiff along the restricted
// variation δx_k = δy_k (Def. 5.1). It must equal −(E^x_k + E^y_k), where E^x, E^y are the two
// lines of `DiscEqs` with c_m replaced by ω^{(2α)}_m = cq_weights(kBdf2, 2α) — one convolution, by
// δ^α·δ^α = δ^{2α} — i.e. the equations the stepper solves.
//
//  * RandomSequences: arbitrary x, y (x_0 ≠ 0, memory on x itself), α = 0.3, 0.5, 0.75.
//    Negative control: the same comparison with the paper's GL weights in the action sum fails.
//  * RandomSequences.MemoryGradients…: the memory term alone, differentiated in y only, is the
//  x-equation's damping
//    (backward sum), and in x only the y-equation's (forward sum): the composition identity and
//    the paper's routing of D_5, D_6 (discrete_euler_lagrange.md §3).
//  * IntegratorTrajectory: x from integrate(problem, fvi_bdf2()) with x_0 = v_0 = 0 and a forcing
//    (the Taylor split is then void, x̃ = x), y_k = x_{N−k}: the BDF2 `DiscEqs` residual and the AD
//    gradient of the BDF2 action sum vanish to round-off; with the GL action sum they do not.
//  * TaylorSplitTrajectory: nonzero data. The stepper's memory acts on x̃ = x − P,
//    P(t) = x_0 + (t − t_0) v_0, plus the exact force of P as the second difference of its double
//    antiderivative. That is the restricted
//    gradient of the action sum whose memory pairs Δ^α_−(x − P) with Δ^α_+(y − P*) (P* the
//    mirrored polynomial), plus the prescribed grid forces −h Σ (R F^P_k)·x_k (and mirrored in y).
//    Negative control: the plain DiscEqs on x (no split) is not solved.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "../support/test_names.hpp"
#include "../support/variational_fixture.hpp"
#include "fracvi/fractional/weights.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/lagrangian/action_sum.hpp"
#include "fracvi/model/autodiff_potential.hpp"

namespace fracvi {
namespace {

using namespace test::variational;  // NOLINT(google-build-using-namespace): the shared fixture

// The data of one comparison. Memory shifts and prescribed grid forces are zero unless the Taylor
// split is tested: px, py (d × (N+1)) are subtracted inside the memory, fx, fy are the P forces
// (before R) at the nodes of the x- and y-equation.
struct ActionGrid {
  double a = 0.5, b = 2.5;
  Eigen::Index n = 16;
  double alpha = 0.5;
  Eigen::MatrixXd px, py, fx, fy;

  [[nodiscard]] double h() const { return (b - a) / static_cast<double>(n); }
  [[nodiscard]] double time(double k) const { return a + k * h(); }
  void zero_split() { px = py = fx = fy = Eigen::MatrixXd::Zero(kDim, n + 1); }
};

// The mechanical Lagrangian of Cor. 4.4 at one phase point z = [x; y; ẋ; ẏ; D^α_−x; D^α_+y], with
// U_f(x, t) = U(x, t) − f(t)·x evaluated at t for x and at the mirrored time a + b − t for y.
// `memory_only` keeps only −(D^α_−x)ᵀR D^α_+y.
template <class T>
T mechanical_lagrangian(const Eigen::Matrix<T, Eigen::Dynamic, 1>& z, double t, double t_mirror,
                        bool memory_only) {
  const auto x = z.segment(0, kDim), y = z.segment(kDim, kDim), xd = z.segment(2 * kDim, kDim),
             yd = z.segment(3 * kDim, kDim), dx = z.segment(4 * kDim, kDim),
             dy = z.segment(5 * kDim, kDim);
  const T memory = bilinear<T>(damping(), dx, dy);
  if (memory_only) return -memory;
  const Eigen::Matrix2d m = mass();
  const T kinetic = T(0.5) * bilinear<T>(m, xd, xd) + T(0.5) * bilinear<T>(m, yd, yd);
  const Eigen::Matrix<T, Eigen::Dynamic, 1> xv = x, yv = y;
  return kinetic - potential_f<T>(xv, t) - potential_f<T>(yv, t_mirror) - memory;
}

// A_d⁺ with the Δ^α_± of `weights` (ω^{(α)}, length ≥ N + 1), memory on (x − px, y − py), minus
// the prescribed grid forces h Σ_k (R fx_k)·x_k + (R fy_k)·y_k.
template <class T>
T action_sum(const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& x,
             const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& y, const ActionGrid& s,
             const std::vector<double>& weights, bool memory_only = false) {
  using Matrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  const double h = s.h();
  Matrix z = internal::discrete_phase_points<T>(x, y, h, s.alpha, weights);
  Matrix xs = x, ys = y;
  for (Eigen::Index k = 0; k <= s.n; ++k) {
    for (Eigen::Index i = 0; i < kDim; ++i) {
      xs(i, k) -= T(s.px(i, k)) + T(0.0) * x(i, k);
      ys(i, k) -= T(s.py(i, k)) + T(0.0) * y(i, k);
    }
  }
  const Matrix zs = internal::discrete_phase_points<T>(xs, ys, h, s.alpha, weights);
  z.middleRows(4 * kDim, 2 * kDim) = zs.middleRows(4 * kDim, 2 * kDim);
  T total = T(0.0) * x(0, 0);
  for (Eigen::Index k = 0; k <= s.n; ++k) {
    const double t = k == s.n ? s.b : s.time(static_cast<double>(k) + 0.5);
    const Eigen::Matrix<T, Eigen::Dynamic, 1> zk = z.col(k);
    total += mechanical_lagrangian<T>(zk, t, s.a + s.b - t, memory_only);
  }
  if (!memory_only) {
    const Eigen::Matrix2d r = damping();
    for (Eigen::Index k = 1; k < s.n; ++k) {
      const Eigen::Vector2d gx = r * s.fx.col(k), gy = r * s.fy.col(k);
      for (Eigen::Index i = 0; i < kDim; ++i) total -= x(i, k) * gx(i) + y(i, k) * gy(i);
    }
  }
  return T(h) * total;
}

enum class Seed { kRestricted, kXOnly, kYOnly };

// (1/h) ∂A/∂η_k, k = 1..N−1 (columns; 0 and N stay zero). kRestricted seeds x_k and y_k with the
// same direction (Def. 5.1); kXOnly / kYOnly seed one of them.
Eigen::MatrixXd gradient(const Eigen::MatrixXd& x, const Eigen::MatrixXd& y, const ActionGrid& s,
                         const std::vector<double>& weights, Seed seed, bool memory_only = false) {
  const Eigen::Index n = s.n, dirs = (n - 1) * kDim;
  DualMatrix xd(kDim, n + 1), yd(kDim, n + 1);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(dirs);
  for (Eigen::Index k = 0; k <= n; ++k) {
    for (Eigen::Index i = 0; i < kDim; ++i) {
      Eigen::VectorXd dir = Eigen::VectorXd::Zero(dirs);
      if (k >= 1 && k <= n - 1) dir((k - 1) * kDim + i) = 1.0;
      xd(i, k) = Dual(x(i, k), seed == Seed::kYOnly ? zero : dir);
      yd(i, k) = Dual(y(i, k), seed == Seed::kXOnly ? zero : dir);
    }
  }
  const Dual a = action_sum<Dual>(xd, yd, s, weights, memory_only);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(kDim, n + 1);
  for (Eigen::Index k = 1; k < n; ++k) out.col(k) = a.derivatives().segment((k - 1) * kDim, kDim);
  return out / s.h();
}

// The two lines of the BDF2 `DiscEqs` (what the stepper solves), their damping parts alone, and
// the size S_k of their terms (Σ of absolute values, for the rounding tolerance).
struct Equations {
  Eigen::MatrixXd ex, ey;          // E^x_k, E^y_k
  Eigen::MatrixXd damp_x, damp_y;  // R h^{−2α} Σ ω_m x̃_{k−m} (+ R F^P), and the mirror
  double scale = 0.0;              // max_k S_k
  double damping_scale = 0.0;      // max_k of the damping terms' absolute sums
};

Equations disc_eqs(const Eigen::MatrixXd& x, const Eigen::MatrixXd& y, const ActionGrid& s,
                   const Potential& u) {
  const Eigen::Index n = s.n;
  const double h = s.h(), beta = 2.0 * s.alpha, hb = std::pow(h, -beta);
  const std::vector<double> w = cq_weights(CqScheme::kBdf2, beta, static_cast<std::size_t>(n + 1));
  const Eigen::Matrix2d m = mass(), r = damping();
  const Eigen::Matrix2d am = m.cwiseAbs(), ar = r.cwiseAbs();
  Equations e;
  e.ex = e.ey = e.damp_x = e.damp_y = Eigen::MatrixXd::Zero(kDim, n + 1);
  Eigen::VectorXd g(kDim), f(kDim);
  // ½∇U_f(q̄, t) and its size ½(|∇U| + |f|).
  auto half_force = [&](const Eigen::VectorXd& q, double t, Eigen::VectorXd& size) {
    u.gradient(q, t, g);
    forcing(t, f);
    size += 0.5 * (g.cwiseAbs() + f.cwiseAbs());
    return Eigen::VectorXd(0.5 * (g - f));
  };
  for (Eigen::Index k = 1; k < n; ++k) {
    for (int side = 0; side < 2; ++side) {
      const Eigen::MatrixXd& q = side == 0 ? x : y;
      const Eigen::MatrixXd& p = side == 0 ? s.px : s.py;
      const Eigen::MatrixXd& fp = side == 0 ? s.fx : s.fy;
      Eigen::VectorXd sum = Eigen::VectorXd::Zero(kDim), abs_sum = Eigen::VectorXd::Zero(kDim);
      if (side == 0) {
        for (Eigen::Index j = 0; j <= k; ++j) {
          sum += w[static_cast<std::size_t>(j)] * (q.col(k - j) - p.col(k - j));
          abs_sum += std::abs(w[static_cast<std::size_t>(j)]) *
                     (q.col(k - j).cwiseAbs() + p.col(k - j).cwiseAbs());
        }
      } else {
        for (Eigen::Index j = 0; j <= n - k; ++j) {
          sum += w[static_cast<std::size_t>(j)] * (q.col(k + j) - p.col(k + j));
          abs_sum += std::abs(w[static_cast<std::size_t>(j)]) *
                     (q.col(k + j).cwiseAbs() + p.col(k + j).cwiseAbs());
        }
      }
      const Eigen::VectorXd damp = r * (hb * sum + fp.col(k));
      const Eigen::VectorXd damp_size = ar * (hb * abs_sum + fp.col(k).cwiseAbs());
      const double kd = static_cast<double>(k);
      const double t_hi = side == 0 ? s.time(kd + 0.5) : s.a + s.b - s.time(kd + 0.5);
      const double t_lo = side == 0 ? s.time(kd - 0.5) : s.a + s.b - s.time(kd - 0.5);
      Eigen::VectorXd size =
          am * (q.col(k + 1).cwiseAbs() + 2.0 * q.col(k).cwiseAbs() + q.col(k - 1).cwiseAbs()) /
          (h * h);
      size += damp_size;
      const Eigen::VectorXd res = m * (q.col(k + 1) - 2.0 * q.col(k) + q.col(k - 1)) / (h * h) +
                                  damp + half_force(0.5 * (q.col(k) + q.col(k + 1)), t_hi, size) +
                                  half_force(0.5 * (q.col(k - 1) + q.col(k)), t_lo, size);
      (side == 0 ? e.ex : e.ey).col(k) = res;
      (side == 0 ? e.damp_x : e.damp_y).col(k) = damp;
      e.scale = std::max(e.scale, size.maxCoeff());
      e.damping_scale = std::max(e.damping_scale, damp_size.maxCoeff());
    }
  }
  return e;
}

// ---------------------------------------------------------------------------------------------

// The grid (α = GetParam(), no Taylor split) and the sequences x, y of a RandomSequences test.
struct Sequences {
  ActionGrid s;
  Eigen::MatrixXd x, y;
};

class RandomSequences : public ::testing::TestWithParam<double> {
 protected:
  /// x_k = x_of(k/N), then y_k = y_of(k/N), for k = 0 … N in this order (the generators may
  /// share one random engine).
  template <class XOf, class YOf>
  [[nodiscard]] Sequences sequences(XOf x_of, YOf y_of) const {
    Sequences q;
    q.s.alpha = GetParam();
    q.s.zero_split();
    q.x.resize(kDim, q.s.n + 1);
    q.y.resize(kDim, q.s.n + 1);
    for (Eigen::Index k = 0; k <= q.s.n; ++k) {
      const double frac = static_cast<double>(k) / static_cast<double>(q.s.n);
      q.x.col(k) = x_of(frac);
      q.y.col(k) = y_of(frac);
    }
    return q;
  }
};

TEST_P(RandomSequences, Bdf2DiscEqsIsTheRestrictedGradientOfTheBdf2ActionSum) {
  std::mt19937_64 rng(2027);
  std::uniform_real_distribution<double> noise(-0.1, 0.1);
  const auto [s, x, y] = sequences(
      [&](double frac) {
        return Eigen::Vector2d(0.4 + std::sin(2 * frac) + noise(rng),
                               0.5 - frac * frac + noise(rng));
      },
      [&](double frac) {
        return Eigen::Vector2d(0.3 * std::cos(3 * frac) + noise(rng), frac + noise(rng));
      });
  const auto u = pendula();
  const Equations e = disc_eqs(x, y, s, *u);
  const Eigen::MatrixXd scheme = -(e.ex + e.ey);
  const auto n1 = static_cast<std::size_t>(s.n + 1);
  const Eigen::MatrixXd grad_bdf2 =
      gradient(x, y, s, cq_weights(CqScheme::kBdf2, s.alpha, n1), Seed::kRestricted);
  const Eigen::MatrixXd grad_gl = gradient(x, y, s, gl_weights(s.alpha, n1), Seed::kRestricted);
  const double tol = equation_tolerance(s.n, e.scale);
  const double err = max_interior(scheme - grad_bdf2, s.n);
  const double control = max_interior(scheme - grad_gl, s.n);
  std::printf(
      "  alpha %.2f: |DiscEqs_bdf2 + grad A_bdf2/h| = %.2e (tol %.2e, term size %.2e, |grad/h| "
      "%.2e); GL action sum: %.2e\n",
      s.alpha, err, tol, e.scale, max_interior(grad_bdf2, s.n), control);
  EXPECT_LE(err, tol);
  EXPECT_GT(control, kControlFactor * tol);
}

TEST_P(RandomSequences, MemoryGradientsAreTheDampingSumsOfBothEquations) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> v(-1.0, 1.0);
  const auto uniform = [&](double) { return Eigen::Vector2d(v(rng), v(rng)); };
  const auto [s, x, y] = sequences(uniform, uniform);
  const auto u = pendula();
  const Equations e = disc_eqs(x, y, s, *u);
  const auto w = cq_weights(CqScheme::kBdf2, s.alpha, static_cast<std::size_t>(s.n + 1));
  // A_mem = −h Σ_k (Δ^α_−x_k)ᵀ R Δ^α_+y_k. Varying y gives the x-equation's term
  // Δ^α_−D_6L = −R h^{−2α} Σ_m ω^{(2α)}_m x_{k−m}; varying x the y-equation's Δ^α_+D_5L.
  const Eigen::MatrixXd by_y = gradient(x, y, s, w, Seed::kYOnly, /*memory_only=*/true);
  const Eigen::MatrixXd by_x = gradient(x, y, s, w, Seed::kXOnly, /*memory_only=*/true);
  const double tol = equation_tolerance(s.n, e.damping_scale);
  const double err_x = max_interior(by_y + e.damp_x, s.n);
  const double err_y = max_interior(by_x + e.damp_y, s.n);
  // Negative control: the routing matters — the x-variation is not the backward sum.
  const double swapped = max_interior(by_x + e.damp_x, s.n);
  std::printf(
      "  alpha %.2f: x-eq damping vs d/dy A_mem: %.2e, y-eq damping vs d/dx A_mem: %.2e "
      "(tol %.2e); swapped routing: %.2e\n",
      s.alpha, err_x, err_y, tol, swapped);
  EXPECT_LE(err_x, tol);
  EXPECT_LE(err_y, tol);
  EXPECT_GT(swapped, kControlFactor * tol);
}

INSTANTIATE_TEST_SUITE_P(Alphas, RandomSequences, ::testing::Values(0.3, 0.5, 0.75), alpha_name);

// ---------------------------------------------------------------------------------------------

Eigen::MatrixXd run_bdf2(const InitialValueProblem& p) {
  IntegratorOptions o;
  // Quadratic convergence: the accepted iterate is accurate to ≈ (1e-14)², i.e. to round-off.
  o.newton.relative_tolerance = 1e-14;
  o.mirror = false;
  const Solution sol = integrate(p, fvi_bdf2(), o);
  EXPECT_TRUE(sol.ok()) << sol.message;
  return sol.x.transpose();  // d × (N+1), column k = x_k
}

class IntegratorTrajectory : public ::testing::TestWithParam<double> {};

TEST_P(IntegratorTrajectory, SolvesTheRestrictedEquationsOfTheBdf2ActionSum) {
  ActionGrid s;
  s.n = 40;
  s.alpha = GetParam();
  s.zero_split();  // x_0 = v_0 = 0: P ≡ 0, x̃ = x, no polynomial force
  const InitialValueProblem p = problem(s.alpha, Convention::kCaputo, Eigen::Vector2d::Zero(),
                                        Eigen::Vector2d::Zero(), s.a, s.b, s.n);
  const Eigen::MatrixXd x = run_bdf2(p);
  const Eigen::MatrixXd y = x.rowwise().reverse();  // y_k = x_{N−k} (Remark 4.5)
  const Equations e = disc_eqs(x, y, s, *p.model.potential);
  const auto n1 = static_cast<std::size_t>(s.n + 1);
  const Eigen::MatrixXd grad_bdf2 =
      gradient(x, y, s, cq_weights(CqScheme::kBdf2, s.alpha, n1), Seed::kRestricted);
  const Eigen::MatrixXd grad_gl = gradient(x, y, s, gl_weights(s.alpha, n1), Seed::kRestricted);
  const double tol = equation_tolerance(s.n, e.scale);
  const double res_x = max_interior(e.ex, s.n), res_y = max_interior(e.ey, s.n);
  const double res_grad = max_interior(grad_bdf2, s.n), res_gl = max_interior(grad_gl, s.n);
  std::printf(
      "  alpha %.2f, max|x| %.2e: DiscEqs_bdf2 x-eq %.2e, y-eq %.2e; grad A_bdf2/h %.2e "
      "(tol %.2e, term size %.2e); grad A_gl/h %.2e\n",
      s.alpha, x.cwiseAbs().maxCoeff(), res_x, res_y, res_grad, tol, e.scale, res_gl);
  EXPECT_LE(res_x, tol);
  EXPECT_LE(res_y, tol);
  EXPECT_LE(res_grad, tol);
  EXPECT_GT(res_gl, kControlFactor * tol);
}

INSTANTIATE_TEST_SUITE_P(Alphas, IntegratorTrajectory, ::testing::Values(0.3, 0.5, 0.75),
                         alpha_name);

// ---------------------------------------------------------------------------------------------

// The double antiderivative H(τ) = ∫_0^τ∫_0^σ D^{2α}P, P(t) = x_0 + t v_0 (τ = t − t_0), written
// out from the closed forms D^β 1 = t^{−β}/Γ(1−β) and D^β t = t^{1−β}/Γ(2−β) (Riemann–Liouville;
// Caputo kills the constant for β > 0 and the linear term for β > 1; integer orders: D^1 t = 1,
// D^2 P = 0). Integrated twice: t^{2−β}/Γ(3−β) and t^{3−β}/Γ(4−β).
Eigen::Vector2d polynomial_force_antiderivative(double tau, double beta, Convention c,
                                                const Eigen::Vector2d& x0,
                                                const Eigen::Vector2d& v0) {
  Eigen::Vector2d j = Eigen::Vector2d::Zero();
  if (tau <= 0.0 || beta <= 0.0 || beta >= 2.0) return j;
  const bool caputo = c == Convention::kCaputo;
  if (!caputo && beta < 1.0) j += std::pow(tau, 2.0 - beta) / boost::math::tgamma(3.0 - beta) * x0;
  if (!caputo || beta <= 1.0) j += std::pow(tau, 3.0 - beta) / boost::math::tgamma(4.0 - beta) * v0;
  return j;
}

class TaylorSplitTrajectory : public ::testing::TestWithParam<SplitCase> {};

TEST_P(TaylorSplitTrajectory, SolvesTheSplitEquationsOfTheBdf2ActionSum) {
  const SplitCase c = GetParam();
  ActionGrid s;
  s.n = 40;
  s.alpha = c.alpha;
  const Eigen::Vector2d x0(0.4, -0.3), v0(0.5, 0.8);
  const InitialValueProblem p = problem(s.alpha, c.convention, x0, v0, s.a, s.b, s.n);
  const Eigen::MatrixXd x = run_bdf2(p);
  const Eigen::MatrixXd y = x.rowwise().reverse();
  const double h = s.h(), beta = 2.0 * s.alpha;
  // P at the nodes (x clock) and mirrored (y clock: P*(t_k) = P(a + b − t_k)); P's force as the
  // second difference F^P_k = (H(t_{k+1}) − 2H(t_k) + H(t_{k−1}))/h² (2H(h)/h² at k = 0), computed
  // here by the direct formula (N = 40: no cancellation to speak of), and the y-node k sees the
  // force of x-node N − k.
  s.zero_split();
  auto big_h = [&](double tau) {
    return polynomial_force_antiderivative(tau, beta, c.convention, x0, v0);
  };
  for (Eigen::Index k = 0; k <= s.n; ++k) {
    const double tk = static_cast<double>(k) * h;
    s.px.col(k) = x0 + tk * v0;
    s.fx.col(k) =
        k == 0 ? Eigen::Vector2d(2.0 * big_h(h) / (h * h))
               : Eigen::Vector2d((big_h(tk + h) - 2.0 * big_h(tk) + big_h(tk - h)) / (h * h));
  }
  for (Eigen::Index k = 0; k <= s.n; ++k) {
    s.py.col(k) = s.px.col(s.n - k);
    s.fy.col(k) = s.fx.col(s.n - k);
  }
  const Equations e = disc_eqs(x, y, s, *p.model.potential);
  const Eigen::MatrixXd grad =
      gradient(x, y, s, cq_weights(CqScheme::kBdf2, s.alpha, static_cast<std::size_t>(s.n + 1)),
               Seed::kRestricted);
  const double tol = equation_tolerance(s.n, e.scale);
  const double res_x = max_interior(e.ex, s.n), res_grad = max_interior(grad, s.n);
  // Negative control: DiscEqs_bdf2 on x itself (no split, no polynomial force).
  ActionGrid plain = s;
  plain.zero_split();
  const double res_plain = max_interior(disc_eqs(x, y, plain, *p.model.potential).ex, s.n);
  std::printf(
      "  alpha %.2f %s: split DiscEqs_bdf2 x-eq %.2e, grad A/h %.2e (tol %.2e); "
      "without the split %.2e\n",
      s.alpha, std::string(to_string(c.convention)).c_str(), res_x, res_grad, tol, res_plain);
  EXPECT_LE(res_x, tol);
  EXPECT_LE(res_grad, tol);
  EXPECT_GT(res_plain, kControlFactor * tol);
}

INSTANTIATE_TEST_SUITE_P(Conventions, TaylorSplitTrajectory, kSplitCases, split_case_name);

}  // namespace
}  // namespace fracvi
