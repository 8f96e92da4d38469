// Grünwald–Letnikov and convolution-quadrature weights (`AlphaDef`, DESIGN §3.1).
#include "fracvi/fractional/weights.hpp"

#include <gtest/gtest.h>

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// The definition as printed: α_n = −α(1−α)(2−α)···(n−1−α)/n!.
double alpha_def(double alpha, int n) {
  if (n == 0) return 1.0;
  double num = -alpha, fact = 1.0;
  for (int j = 1; j < n; ++j) num *= (j - alpha);
  for (int j = 2; j <= n; ++j) fact *= j;
  return num / fact;
}

std::vector<double> convolve(const std::vector<double>& a, const std::vector<double>& b,
                             std::size_t count) {
  std::vector<double> c(count, 0.0);
  for (std::size_t n = 0; n < count; ++n)
    for (std::size_t m = 0; m <= n; ++m) c[n] += a[m] * b[n - m];
  return c;
}

TEST(GlWeights, MatchThePrintedDefinition) {
  for (double alpha : {0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 1.9}) {
    const auto w = gl_weights(alpha, 25);
    for (int n = 0; n < 25; ++n) {
      const double ref = alpha_def(alpha, n);
      // Both are products of n factors: a few ulps per factor.
      EXPECT_NEAR(w[n], ref, 4.0 * (n + 1) * kEps * std::abs(ref))
          << "alpha=" << alpha << " n=" << n;
    }
  }
  const auto half = gl_weights(0.5, 4);  // 1, −1/2, −1/8, −1/16
  EXPECT_EQ(half[0], 1.0);
  EXPECT_EQ(half[1], -0.5);
  EXPECT_EQ(half[2], -0.125);
  EXPECT_EQ(half[3], -0.0625);
}

TEST(GlWeights, IntegerOrdersAreBinomialsAndExactlyZeroBeyondTheDegree) {
  EXPECT_EQ(gl_weights(0.0, 5), (std::vector<double>{1, 0, 0, 0, 0}));
  EXPECT_EQ(gl_weights(1.0, 5), (std::vector<double>{1, -1, 0, 0, 0}));
  EXPECT_EQ(gl_weights(2.0, 5), (std::vector<double>{1, -2, 1, 0, 0}));
  EXPECT_EQ(gl_weight(2.0, 1), -2.0);
  EXPECT_EQ(gl_weight(2.0, 1000000), 0.0);
}

TEST(GlWeights, SelfConvolutionOfOrderAlphaIsOrderTwoAlpha) {
  // (1−ζ)^α (1−ζ)^α = (1−ζ)^{2α}: the double sum of `DiscEqs` is one convolution.
  for (double alpha : {0.2, 0.5, 0.75, 0.9}) {
    const std::size_t n = 400;
    const auto a = gl_weights(alpha, n);
    const auto c = gl_weights(2 * alpha, n);
    const auto aa = convolve(a, a, n);
    for (std::size_t k = 0; k < n; ++k) {
      double scale = 0.0;  // Σ |a_m a_{k−m}| bounds the rounding of the convolution
      for (std::size_t m = 0; m <= k; ++m) scale += std::abs(a[m] * a[k - m]);
      EXPECT_NEAR(aa[k], c[k], 8.0 * static_cast<double>(k + 1) * kEps * scale)
          << "alpha=" << alpha << " k=" << k;
    }
  }
}

TEST(GlWeights, PartialSumsAreTheWeightsOfOrderMinusOne) {
  // Σ_{n≤N} coeff of (1−ζ)^β = coeff_N of (1−ζ)^β/(1−ζ) = (1−ζ)^{β−1}.
  for (double beta : {0.5, 1.5}) {
    const auto w = gl_weights(beta, 3000);
    const auto w1 = gl_weights(beta - 1.0, 3000);
    double sum = 0.0;
    for (std::size_t n = 0; n < w.size(); ++n) {
      sum += w[n];
      EXPECT_NEAR(sum, w1[n], 64 * kEps) << "beta=" << beta << " n=" << n;
    }
  }
}

TEST(GlWeights, AnchoredRecurrenceStaysAccurateOverMillionsOfWeights) {
  // Reference: the Gamma-ratio value at every 997th lag (not aligned with the anchors).
  for (double beta : {0.3, 1.5}) {
    const std::size_t n = std::size_t{1} << 21;
    const auto w = gl_weights(beta, n);
    double worst = 0.0;
    for (std::size_t k = 1; k < n; k += 997)
      worst = std::max(worst, std::abs(w[k] / gl_weight(beta, k) - 1.0));
    // Within one anchor interval the recurrence accumulates at most ~kGlAnchorInterval·ε.
    EXPECT_LT(worst, static_cast<double>(kGlAnchorInterval) * kEps) << "beta=" << beta;
    RecordProperty("worst_relative_error_beta_" + std::to_string(beta), std::to_string(worst));
  }
}

TEST(GlWeights, SingleWeightAtHundredMillionMatchesItsAsymptoticExpansion) {
  // α_n = n^{−β−1}/Γ(−β) · [1 + β(β+1)/(2n) + O(n^{−2})]: an independent check at n = 1e8,
  // where the neglected term is ~1e-16 relative.
  for (double beta : {0.25, 0.5, 1.5, 1.9}) {
    for (std::size_t n : {std::size_t{10'000'000}, std::size_t{100'000'000}}) {
      const double nd = static_cast<double>(n);
      const double asym = std::pow(nd, -beta - 1.0) / boost::math::tgamma(-beta) *
                          (1.0 + beta * (beta + 1.0) / (2.0 * nd));
      EXPECT_NEAR(gl_weight(beta, n) / asym, 1.0, 1e-13) << "beta=" << beta << " n=" << n;
    }
  }
}

TEST(GlWeights, SingleWeightAgreesWithTheSequence) {
  const auto w = gl_weights(0.7, 100);
  for (std::size_t n = 0; n < w.size(); ++n)
    EXPECT_NEAR(gl_weight(0.7, n), w[n], 16 * kEps * std::abs(w[n])) << n;
}

TEST(CqWeights, BackwardEulerIsGrunwaldLetnikov) {
  EXPECT_EQ(cq_weights(CqScheme::kGrunwaldLetnikov, 0.6, 500), gl_weights(0.6, 500));
}

TEST(CqWeights, IntegerOrderOneGivesTheGeneratingPolynomials) {
  const auto bdf2 = cq_weights(CqScheme::kBdf2, 1.0, 6);
  EXPECT_EQ(bdf2, (std::vector<double>{1.5, -2.0, 0.5, 0.0, 0.0, 0.0}));
  const auto trap = cq_weights(CqScheme::kTrapezoidal, 1.0, 6);  // 2(1−ζ)/(1+ζ)
  EXPECT_EQ(trap, (std::vector<double>{2.0, -4.0, 4.0, -4.0, 4.0, -4.0}));
}

// Independent route: factor δ(ζ) and convolve power series of the factors.
TEST(CqWeights, Bdf2MatchesTheProductOfItsFactors) {
  // (1−ζ) + (1−ζ)²/2 = (3/2)(1−ζ)(1−ζ/3).
  for (double beta : {0.5, 1.5}) {
    const std::size_t n = 1500;
    const auto a = gl_weights(beta, n);
    auto b = gl_weights(beta, n);
    for (std::size_t k = 0; k < n; ++k) b[k] *= std::pow(3.0, -static_cast<double>(k));
    auto ref = convolve(a, b, n);
    for (double& r : ref) r *= std::pow(1.5, beta);
    const auto w = cq_weights(CqScheme::kBdf2, beta, n);
    for (std::size_t k = 0; k < n; ++k) {
      double scale = 0.0;
      for (std::size_t m = 0; m <= k; ++m) scale += std::abs(a[m] * b[k - m]);
      EXPECT_NEAR(w[k], ref[k], 64 * kEps * static_cast<double>(k + 1) * scale)
          << "beta=" << beta << " k=" << k;
    }
  }
}

TEST(CqWeights, TrapezoidalMatchesTheProductOfItsFactors) {
  // 2(1−ζ)/(1+ζ) → 2^β (1−ζ)^β (1+ζ)^{−β}; (1+ζ)^{−β} has coefficients (−1)^n α_n(−β).
  for (double beta : {0.5, 1.5}) {
    const std::size_t n = 1500;
    const auto a = gl_weights(beta, n);
    auto b = gl_weights(-beta, n);
    for (std::size_t k = 1; k < n; k += 2) b[k] = -b[k];
    auto ref = convolve(a, b, n);
    for (double& r : ref) r *= std::pow(2.0, beta);
    const auto w = cq_weights(CqScheme::kTrapezoidal, beta, n);
    for (std::size_t k = 0; k < n; ++k) {
      double scale = 0.0;
      for (std::size_t m = 0; m <= k; ++m) scale += std::abs(a[m] * b[k - m]);
      EXPECT_NEAR(w[k], ref[k], 64 * kEps * static_cast<double>(k + 1) * scale)
          << "beta=" << beta << " k=" << k;
    }
  }
}

TEST(CqWeights, SeriesSumsToTheGeneratingFunctionInsideTheDisc) {
  const double z = 0.5;
  for (double beta : {0.3, 1.2}) {
    const auto sum_at = [&](CqScheme s) {
      const auto w = cq_weights(s, beta, 200);  // |z|^200 ≈ 6e-61: the tail is negligible
      double acc = 0.0, zn = 1.0;
      for (double wk : w) acc += wk * zn, zn *= z;
      return acc;
    };
    EXPECT_NEAR(sum_at(CqScheme::kBdf2), std::pow((1 - z) + 0.5 * (1 - z) * (1 - z), beta), 1e-14);
    EXPECT_NEAR(sum_at(CqScheme::kTrapezoidal), std::pow(2 * (1 - z) / (1 + z), beta), 1e-14);
  }
}

TEST(CqWeights, NamesRoundTripAndBadInputIsRejected) {
  for (auto s : {CqScheme::kGrunwaldLetnikov, CqScheme::kBdf2, CqScheme::kTrapezoidal})
    EXPECT_EQ(parse_cq_scheme(to_string(s)), s);
  EXPECT_FALSE(parse_cq_scheme("bdf3").has_value());
  EXPECT_THROW(gl_weights(std::nan(""), 3), std::invalid_argument);
  const double p[] = {-1.0, 1.0}, q[] = {1.0};
  EXPECT_THROW(rational_power_series(p, q, 0.5, 3), std::invalid_argument);
}

}  // namespace
}  // namespace fracvi
