// Theorem 5.2 (`DiscFracEL`) against its ground truth: the gradient of the whole action sum
// (`DiscActSum`) along the restricted variation δx_k = δy_k, computed by automatic
// differentiation, for a non-mechanical Lagrangian that couples x and y in every block.
//
// * ActionSum::kPrinted (`DiscActSum` as printed, k = 0..N−1): the residual with
//   D_3L(N) = D_5L(N) = 0 equals (1/h)∂A_d/∂η_k to round-off.
// * ActionSum::kExtended (k = 0..N): the paper's printed `DiscFracEL` equals the gradient of the
//   extended sum to round-off.
// * Negative control: the printed `DiscFracEL` is NOT the gradient of the printed `DiscActSum`;
//   the difference is exactly the two terms of the missing point L(N) (located and measured).
// * For the mechanical Lagrangian, the printed equations are `DiscEqs`: the trajectory of the
//   integrator with its mirror y_k = x_{N−k} makes the kExtended residual vanish, but not the
//   kPrinted one (the DESIGN §3.3 remark that the mechanical interior equations are unaffected
//   does not hold: x at k = N−1, y at every k).
#include "fracvi/lagrangian/action_sum.hpp"

#include <gtest/gtest.h>

#include <cstdio>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;
using Dual = Eigen::AutoDiffScalar<Eigen::VectorXd>;
using DualMatrix = Eigen::Matrix<Dual, Eigen::Dynamic, Eigen::Dynamic>;

constexpr Eigen::Index kDim = 2;
constexpr Eigen::Index kSteps = 12;

DiscreteGrid grid(double alpha) {
  return DiscreteGrid{0.2, 1.4, kSteps, alpha};
}

// Smooth curves plus a little noise (fixed seed), so that no term vanishes by symmetry.
void random_curves(std::mt19937_64& rng, Sequence& x, Sequence& y) {
  x.resize(kDim, kSteps + 1);
  y.resize(kDim, kSteps + 1);
  for (Eigen::Index k = 0; k <= kSteps; ++k) {
    const double s = static_cast<double>(k) / kSteps;
    x.col(k) = Eigen::Vector2d(std::sin(2 * s), 0.5 - s * s) + test::random_vector(rng, 2, 0.1);
    y.col(k) = Eigen::Vector2d(0.3 * std::cos(3 * s), s) + test::random_vector(rng, 2, 0.1);
  }
}

// (1/h) ∂A/∂η_k, η the restricted variation of the interior points: x_k and y_k are seeded with
// the same derivative direction (Def. 5.1). Column k of the result, k = 1..N−1.
Sequence restricted_gradient(const Sequence& x, const Sequence& y, const DiscreteGrid& g,
                             ActionSum sum) {
  const Eigen::Index n = kSteps, m = (n - 1) * kDim;
  DualMatrix xd(kDim, n + 1), yd(kDim, n + 1);
  for (Eigen::Index k = 0; k <= n; ++k) {
    for (Eigen::Index i = 0; i < kDim; ++i) {
      const bool interior = k >= 1 && k <= n - 1;
      Eigen::VectorXd dir = Eigen::VectorXd::Zero(m);
      if (interior) dir((k - 1) * kDim + i) = 1.0;
      xd(i, k) = Dual(x(i, k), dir);
      yd(i, k) = Dual(y(i, k), dir);
    }
  }
  const Dual a = action_sum(test::Coupled{}, xd, yd, g, sum);
  Sequence out = Sequence::Zero(kDim, n + 1);
  for (Eigen::Index k = 1; k < n; ++k)
    out.col(k) = a.derivatives().segment((k - 1) * kDim, kDim) / g.step();
  return out;
}

struct Measured {
  double error;  // max |x_eq + y_eq − (1/h)∂A/∂η|
  double scale;  // max |(1/h)∂A/∂η| (for the rounding bound)
};

Measured compare(const DiscreteElResidual& r, const Sequence& grad) {
  const Sequence sum = r.x_equation + r.y_equation;
  return {(sum - grad).cwiseAbs().maxCoeff(), grad.cwiseAbs().maxCoeff()};
}

// Rounding bound: each residual entry is a sum of O(N) terms of size up to
// h^{−1}·max|∇L| (the Δ_± terms) and h^{−α}·max_n|ω_n|·max|∇L| (the CQ sums; max_n|ω_n| = 1 for
// the GL weights, ≤ 1.5 for BDF2 with α ≤ 1); AD of the action sum adds the same terms in another
// order. 8ε·N·(largest term) covers both.
double roundoff_bound(double h, double gradient_scale, double weight_scale = 1.0) {
  return 8 * kEps * kSteps * gradient_scale * std::max(1.0, weight_scale) / h;
}

double largest_weight(const DiscreteGrid& g) {
  double w = 0.0;
  for (double v : cq_weights(g.quadrature, g.alpha, kSteps + 1)) w = std::max(w, std::abs(v));
  return w;
}

// (α, the quadrature of Δ^α_±): the paper's Grünwald–Letnikov weights and the BDF2 ones of
// `fvi-bdf2` — the derivation of `DiscFracEL` holds for any weights.
class RestrictedGradient : public ::testing::TestWithParam<std::tuple<double, CqScheme>> {};

TEST_P(RestrictedGradient, ResidualSumIsTheGradientOfTheActionSum) {
  const auto [alpha, quadrature] = GetParam();
  const auto L = make_autodiff_lagrangian(test::Coupled{}, kDim);
  DiscreteGrid g = grid(alpha);
  g.quadrature = quadrature;
  std::mt19937_64 rng(2026);
  Sequence x, y;
  random_curves(rng, x, y);
  for (ActionSum sum : {ActionSum::kPrinted, ActionSum::kExtended}) {
    const DiscreteElResidual r = discrete_el_residual(*L, x, y, g, sum);
    const Sequence grad = restricted_gradient(x, y, g, sum);
    const Measured m = compare(r, grad);
    const double tol =
        roundoff_bound(g.step(), std::max(1.0, m.scale * g.step()), largest_weight(g));
    std::printf(
        "  alpha %.2f, %s, %s sum: max |x_eq + y_eq - grad/h| = %.2e (|grad/h| %.2e, tol "
        "%.2e)\n",
        alpha, std::string(to_string(quadrature)).c_str(), std::string(to_string(sum)).c_str(),
        m.error, m.scale, tol);
    EXPECT_LE(m.error, tol);
    // Negative control: the residual against the gradient of the action sum with the other
    // quadrature (the weights really reach both sides).
    DiscreteGrid other = g;
    other.quadrature =
        quadrature == CqScheme::kBdf2 ? CqScheme::kGrunwaldLetnikov : CqScheme::kBdf2;
    const Measured wrong = compare(r, restricted_gradient(x, y, other, sum));
    std::printf("    against the action sum with %s weights: %.2e\n",
                std::string(to_string(other.quadrature)).c_str(), wrong.error);
    EXPECT_GT(wrong.error, 1e6 * tol);
    // The action sums themselves: functor template and Lagrangian object agree.
    const double a_obj = action_sum(*L, x, y, g, sum);
    const double a_tpl =
        action_sum(test::Coupled{}, Eigen::MatrixXd(x), Eigen::MatrixXd(y), g, sum);
    EXPECT_NEAR(a_obj, a_tpl, 16 * kEps * kSteps * std::abs(a_obj));
  }
}

INSTANTIATE_TEST_SUITE_P(AlphasAndQuadratures, RestrictedGradient,
                         ::testing::Combine(::testing::Values(0.5, 0.3, 0.8),
                                            ::testing::Values(CqScheme::kGrunwaldLetnikov,
                                                              CqScheme::kBdf2)));

TEST(DiscreteGridQuadrature, PhasePointsUseTheOperatorsWeights) {
  // The phase points of the action sum use the same Δ^α_± as frac_delta_minus/plus with the same
  // quadrature (one set of weights, cq_weights), and the default is the paper's GL exactly.
  std::mt19937_64 rng(7);
  Sequence x, y;
  random_curves(rng, x, y);
  for (CqScheme q : {CqScheme::kGrunwaldLetnikov, CqScheme::kBdf2}) {
    DiscreteGrid g = grid(0.4);
    g.quadrature = q;
    const Eigen::MatrixXd z = discrete_phase_points(x, y, g);
    const double h = g.step();
    const Sequence dx = frac_delta_minus(x, h, g.alpha, q);
    const Sequence dy = frac_delta_plus(y, h, g.alpha, q);
    // Same weights, same terms; the two implementations sum in different orders: N + 1 terms,
    // each at most h^{−α}·max|ω|·max|x|.
    const double tol = 4 * kEps * (kSteps + 1) * std::pow(h, -g.alpha) * largest_weight(g) *
                       std::max(x.cwiseAbs().maxCoeff(), y.cwiseAbs().maxCoeff());
    EXPECT_LE((z.middleRows(4 * kDim, kDim) - dx).cwiseAbs().maxCoeff(), tol);
    EXPECT_LE((z.middleRows(5 * kDim, kDim) - dy).cwiseAbs().maxCoeff(), tol);
  }
  // Default argument and default grid: bit for bit the Grünwald–Letnikov sums.
  const double h = 0.1, alpha = 0.4;
  const auto w = gl_weights(alpha, kSteps + 1);
  EXPECT_EQ(frac_delta_minus(x, h, alpha), Sequence(convolve_past(w, x) * std::pow(h, -alpha)));
  EXPECT_EQ(frac_delta_plus(y, h, alpha), Sequence(convolve_future(w, y) * std::pow(h, -alpha)));
  EXPECT_EQ(DiscreteGrid{}.quadrature, CqScheme::kGrunwaldLetnikov);
  // BDF2 is a different operator (ω_0 = (3/2)^α, not 1).
  EXPECT_GT((frac_delta_minus(x, h, alpha, CqScheme::kBdf2) - frac_delta_minus(x, h, alpha))
                .cwiseAbs()
                .maxCoeff(),
            1e-2);
}

TEST(RestrictedGradient, PrintedEquationsAreNotTheGradientOfThePrintedSum) {
  // The paper's DiscFracEL (= the kExtended residual) against the gradient of DiscActSum as
  // printed: they differ exactly by the terms of L(N), −D_3L(N)/h in the x-equation at k = N−1 and
  // h^{−α}α_{N−k}D_5L(N) in the y-equation at every k.
  const double alpha = 0.6;
  const auto L = make_autodiff_lagrangian(test::Coupled{}, kDim);
  const DiscreteGrid g = grid(alpha);
  std::mt19937_64 rng(99);
  Sequence x, y;
  random_curves(rng, x, y);
  const DiscreteElResidual printed_eqs = discrete_el_residual(*L, x, y, g, ActionSum::kExtended);
  const DiscreteElResidual exact_eqs = discrete_el_residual(*L, x, y, g, ActionSum::kPrinted);
  const Sequence grad = restricted_gradient(x, y, g, ActionSum::kPrinted);
  const Measured wrong = compare(printed_eqs, grad);
  const Measured right = compare(exact_eqs, grad);
  std::printf("  gradient of DiscActSum vs printed DiscFracEL: %.3e; vs exact: %.3e\n", wrong.error,
              right.error);
  EXPECT_GT(wrong.error, 1e6 * right.error);

  // The difference, term by term.
  const Eigen::MatrixXd z = discrete_phase_points(x, y, g);
  Eigen::VectorXd gn(6 * kDim);
  L->gradient(g.b, z.col(kSteps), gn);
  const double h = g.step();
  const auto w = gl_weights(alpha, kSteps + 1);
  Sequence dx = printed_eqs.x_equation - exact_eqs.x_equation;
  Sequence dy = printed_eqs.y_equation - exact_eqs.y_equation;
  const double tol = roundoff_bound(h, gn.cwiseAbs().maxCoeff() + 1.0);
  for (Eigen::Index k = 1; k < kSteps; ++k) {
    const Eigen::VectorXd ex = k == kSteps - 1 ? Eigen::VectorXd(-gn.segment(2 * kDim, kDim) / h)
                                               : Eigen::VectorXd::Zero(kDim);
    const Eigen::VectorXd ey =
        std::pow(h, -alpha) * w[static_cast<std::size_t>(kSteps - k)] * gn.segment(4 * kDim, kDim);
    EXPECT_LE((dx.col(k) - ex).cwiseAbs().maxCoeff(), tol) << "x-equation, k = " << k;
    EXPECT_LE((dy.col(k) - ey).cwiseAbs().maxCoeff(), tol) << "y-equation, k = " << k;
  }
  std::printf("  missing-L(N) terms: x-eq at k = N-1 %.3e, y-eq at k = 1 %.3e, at k = N-1 %.3e\n",
              dx.col(kSteps - 1).cwiseAbs().maxCoeff(), dy.col(1).cwiseAbs().maxCoeff(),
              dy.col(kSteps - 1).cwiseAbs().maxCoeff());
}

// The mechanical Lagrangian: `DiscEqs` is the printed DiscFracEL (kExtended), so the integrator's
// trajectory with y_k = x_{N−k} solves it; the gradient of the printed DiscActSum (kPrinted) is a
// different, inconsistent set of equations (O(1/h) residual at the IVP solution).
class Mechanical : public ::testing::TestWithParam<double> {};

TEST_P(Mechanical, IntegratorTrajectorySolvesTheExtendedEquations) {
  const double alpha = GetParam();
  const InitialValueProblem p = test::mechanical_ivp(alpha, 2.5, 200);
  IntegratorOptions o;
  o.newton.relative_tolerance = 1e-15;
  o.mirror = false;
  const Solution sol = integrate(p, fvi_gl(), o);
  ASSERT_TRUE(sol.ok()) << sol.message;
  const auto n = static_cast<Eigen::Index>(p.steps);
  const Sequence x = sol.x.transpose();
  const Sequence y = x.rowwise().reverse();  // y_k = x_{N−k}
  const MechanicalLagrangian L(p.model, p.t0, p.t_end);
  const DiscreteGrid g{p.t0, p.t_end, n, alpha};
  const DiscreteElResidual ext = discrete_el_residual(L, x, y, g, ActionSum::kExtended);
  const DiscreteElResidual prt = discrete_el_residual(L, x, y, g, ActionSum::kPrinted);
  // Each equation is a sum of terms up to ‖M‖‖x‖/h² ≈ 2e4 evaluated at positions accurate to the
  // Newton tolerance (1e-15 relative, i.e. round-off): rounding ≈ 32ε·2e4 ≈ 1.4e-10.
  const double h = g.step();
  const double tol = 32 * kEps * 1.8 * sol.x.cwiseAbs().maxCoeff() / (h * h);
  std::printf(
      "  alpha %.2f: extended residual %.2e (tol %.2e); printed-sum residual %.3e "
      "(x-eq at N-1 %.3e, y-eq at 1 %.3e)\n",
      alpha, ext.max_norm(), tol, prt.max_norm(), prt.x_equation.col(n - 1).cwiseAbs().maxCoeff(),
      prt.y_equation.col(1).cwiseAbs().maxCoeff());
  EXPECT_LE(ext.max_norm(), tol);
  // The x-equation of the printed sum at k = N−1 misses M Δ_−x_N/h: O(1/h).
  const Eigen::VectorXd missing = p.model.mass.to_dense() * (x.col(n) - x.col(n - 1)) / (h * h);
  EXPECT_LE((prt.x_equation.col(n - 1) - ext.x_equation.col(n - 1) - missing).cwiseAbs().maxCoeff(),
            tol);
  EXPECT_GT(prt.max_norm(), 1e6 * tol);
}

INSTANTIATE_TEST_SUITE_P(Alphas, Mechanical, ::testing::Values(0.5, 0.3));

TEST(DiscreteElResidual, RejectsWrongSizes) {
  const auto L = make_autodiff_lagrangian(test::Coupled{}, kDim);
  const DiscreteGrid g = grid(0.5);
  EXPECT_THROW(
      discrete_el_residual(*L, Sequence::Zero(3, kSteps + 1), Sequence::Zero(3, kSteps + 1), g),
      std::invalid_argument);
  EXPECT_THROW(discrete_el_residual(*L, Sequence::Zero(2, kSteps), Sequence::Zero(2, kSteps), g),
               std::invalid_argument);
  EXPECT_THROW(discrete_el_residual(*L, Sequence::Zero(2, kSteps + 1),
                                    Sequence::Zero(2, kSteps + 1), DiscreteGrid{0, 1, kSteps, 1.5}),
               std::invalid_argument);
}

}  // namespace
}  // namespace fracvi
