// The paper's discrete operators (`AllSequencs`), their integration-by-parts identities,
// composition, Lemma 5.3 and its mirror, and the convergence of Δ^α_− to the RL derivative.
#include "fracvi/discrete/operators.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr int kDim = 3;
constexpr int kN = 40;       // N: sequences z_0..z_N
constexpr double kH = 0.05;  // step

Sequence random_sequence(std::mt19937_64& rng, int d = kDim, int n = kN) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Sequence z(d, n + 1);
  for (Eigen::Index k = 0; k < z.cols(); ++k)
    for (Eigen::Index i = 0; i < d; ++i) z(i, k) = u(rng);
  return z;
}

// Σ_{k=lo}^{hi} F_k·G_k, with Σ|F_k·G_k| returned for the rounding bound.
double dot_range(const Sequence& f, const Sequence& g, int lo, int hi, double* abs_sum) {
  double s = 0.0;
  for (int k = lo; k <= hi; ++k) {
    const double t = f.col(k).dot(g.col(k));
    s += t;
    *abs_sum += std::abs(t);
  }
  return s;
}

TEST(DiscreteOperators, DefinitionsAndIndexRanges) {
  Sequence z(1, 4);
  z << 1.0, 3.0, 7.0, 15.0;
  const double h = 0.5;
  EXPECT_EQ(midpoint(z), (Eigen::RowVector4d(2.0, 5.0, 11.0, 0.0)));
  EXPECT_EQ(delta_minus(z, h), (Eigen::RowVector4d(0.0, 4.0, 8.0, 16.0)));  // Δ_− z_0 := 0
  EXPECT_EQ(delta_plus(z, h), (Eigen::RowVector4d(-4.0, -8.0, -16.0, 0.0)));
  // Remark after `AlphaDef`: Δ^α_− x_0 = α_0 x_0/h^α and Δ^α_+ y_N = α_0 y_N/h^α.
  const double alpha = 0.4;
  EXPECT_DOUBLE_EQ(frac_delta_minus(z, h, alpha)(0, 0), z(0, 0) / std::pow(h, alpha));
  EXPECT_DOUBLE_EQ(frac_delta_plus(z, h, alpha)(0, 3), z(0, 3) / std::pow(h, alpha));
  EXPECT_THROW(delta_minus(z, 0.0), std::invalid_argument);
}

TEST(DiscreteOperators, IntegrationByPartsForDifferences) {
  // Σ_{k=0}^{N−1} F_k Δ_+G_k = Σ_{k=1}^{N} (Δ_−F_k) G_k + F_0G_0/h − F_NG_N/h.
  std::mt19937_64 rng(20260121);
  for (int trial = 0; trial < 5; ++trial) {
    const Sequence f = random_sequence(rng), g = random_sequence(rng);
    double scale = 0.0;
    const double lhs = dot_range(f, delta_plus(g, kH), 0, kN - 1, &scale);
    const double rhs = dot_range(delta_minus(f, kH), g, 1, kN, &scale) +
                       f.col(0).dot(g.col(0)) / kH - f.col(kN).dot(g.col(kN)) / kH;
    EXPECT_NEAR(lhs, rhs, 8 * kEps * (scale + 2.0 * kDim / kH)) << "trial " << trial;
  }
}

TEST(DiscreteOperators, IntegrationByPartsForFractionalDifferences) {
  // Σ_{k=0}^{N−1} F_k Δ^α_+G_k = Σ_{k=1}^{N} (Δ^α_−F_k) G_k + F_0G_0/h^α − F_NG_N/h^α.
  std::mt19937_64 rng(7);
  for (double alpha : {0.1, 0.3, 0.5, 0.77, 1.0}) {
    const Sequence f = random_sequence(rng), g = random_sequence(rng);
    const double ha = std::pow(kH, alpha);
    double scale = 0.0;
    const double lhs = dot_range(f, frac_delta_plus(g, kH, alpha), 0, kN - 1, &scale);
    const double rhs = dot_range(frac_delta_minus(f, kH, alpha), g, 1, kN, &scale) +
                       f.col(0).dot(g.col(0)) / ha - f.col(kN).dot(g.col(kN)) / ha;
    // Each Δ^α value is a sum of up to N+1 terms: rounding ~ (N+1)·ε relative to |terms|.
    EXPECT_NEAR(lhs, rhs, 4 * (kN + 1) * kEps * (scale + 2.0 * kDim / ha)) << "alpha=" << alpha;
  }
}

TEST(DiscreteOperators, FractionalDifferenceComposesToOrderTwoAlpha) {
  // h^{2α} Δ^α_−Δ^α_− z = Σ_m c_m z_{k−m} with c the order-2α weights; same for Δ^α_+.
  std::mt19937_64 rng(11);
  for (double alpha : {0.25, 0.5, 0.75}) {
    const Sequence z = random_sequence(rng);
    const auto c = gl_weights(2 * alpha, kN + 1);
    const double h2a = std::pow(kH, 2 * alpha);
    const Sequence left = h2a * frac_delta_minus(frac_delta_minus(z, kH, alpha), kH, alpha);
    const Sequence right = h2a * frac_delta_plus(frac_delta_plus(z, kH, alpha), kH, alpha);
    const double tol = 16 * (kN + 1) * kEps * z.cwiseAbs().maxCoeff() * (kN + 1);
    EXPECT_LT((left - convolve_past(c, z)).cwiseAbs().maxCoeff(), tol) << alpha;
    EXPECT_LT((right - convolve_future(c, z)).cwiseAbs().maxCoeff(), tol) << alpha;
  }
}

// The double sums of `DiscEqs`, exactly as printed (nested, not composed).
Eigen::VectorXd double_sum_past(const std::vector<double>& a, const Sequence& x, int k) {
  Eigen::VectorXd s = Eigen::VectorXd::Zero(x.rows());
  for (int n = 0; n <= k; ++n)
    for (int p = 0; p <= k - n; ++p) s += a[n] * a[p] * x.col(k - n - p);
  return s;
}
Eigen::VectorXd double_sum_future(const std::vector<double>& a, const Sequence& y, int k) {
  const int big_n = static_cast<int>(y.cols()) - 1;
  Eigen::VectorXd s = Eigen::VectorXd::Zero(y.rows());
  for (int n = 0; n <= big_n - k; ++n)
    for (int p = 0; p <= big_n - k - n; ++p) s += a[n] * a[p] * y.col(k + n + p);
  return s;
}

TEST(DiscreteOperators, Lemma53AndItsMirrorForAlphaOneHalf) {
  std::mt19937_64 rng(53);
  const Sequence x = random_sequence(rng), y = random_sequence(rng);
  const auto a = gl_weights(0.5, kN + 1);
  for (int k = 1; k <= kN - 1; ++k) {
    // Each entry sums ~k²/2 products bounded by |a_n a_p|·max|x|; Σ|a_n| < 2.
    const double tol = 64 * kEps * (k + 1);
    EXPECT_LT((double_sum_past(a, x, k) - (x.col(k) - x.col(k - 1))).cwiseAbs().maxCoeff(), tol)
        << "k=" << k;
    EXPECT_LT((double_sum_future(a, y, k) + (y.col(k + 1) - y.col(k))).cwiseAbs().maxCoeff(), tol)
        << "k=" << k;
  }
}

TEST(DiscreteOperators, Lemma53CollapseFailsForOtherOrders) {
  // Negative control: for α ≠ 1/2 the memory does not collapse to a two-point difference.
  std::mt19937_64 rng(54);
  const Sequence x = random_sequence(rng);
  for (double alpha : {0.3, 0.45, 0.55, 0.7}) {
    const auto a = gl_weights(alpha, kN + 1);
    double worst = 0.0;
    for (int k = 2; k <= kN - 1; ++k)
      worst = std::max(
          worst, (double_sum_past(a, x, k) - (x.col(k) - x.col(k - 1))).cwiseAbs().maxCoeff());
    EXPECT_GT(worst, 1e-2) << "alpha=" << alpha;
  }
}

// Least-squares slope of log(err) against log(h).
double fitted_order(const std::vector<double>& h, const std::vector<double>& err) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(h.size());
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double lx = std::log(h[i]), ly = std::log(err[i]);
    sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

TEST(DiscreteOperators, GrunwaldLetnikovConvergesToRiemannLiouvilleWithOrderOne) {
  // Δ^α_− of samples of (t − a)^p at t = b against Γ(p+1)/Γ(p+1−α)(b − a)^{p−α}.
  const double a = 0.5, b = 1.5;
  for (double alpha : {0.3, 0.5, 0.8}) {
    for (double p : {1.5, 2.0, 3.0}) {
      std::vector<double> hs, errs;
      const double exact = boost::math::tgamma(p + 1) / boost::math::tgamma(p + 1 - alpha) *
                           std::pow(b - a, p - alpha);
      for (int n = 64; n <= 4096; n *= 2) {
        const double h = (b - a) / n;
        Sequence z(1, n + 1);
        for (int k = 0; k <= n; ++k) z(0, k) = std::pow(k * h, p);
        hs.push_back(h);
        errs.push_back(std::abs(frac_delta_minus(z, h, alpha)(0, n) - exact));
      }
      const double order = fitted_order(hs, errs);
      std::printf("[measured] GL vs RL: alpha=%.2f p=%.1f order=%.4f error(h=%.2e)=%.3e\n", alpha,
                  p, order, hs.back(), errs.back());
      EXPECT_NEAR(order, 1.0, 0.05) << "alpha=" << alpha << " p=" << p;
      EXPECT_LT(errs.back(), 2e-3) << "alpha=" << alpha << " p=" << p;
    }
  }
}

}  // namespace
}  // namespace fracvi
