// The memory sum behind the History interface (DESIGN §3.1): the single convolution with
// c = gl_weights(2α) equals the paper's double sum of `DiscEqs`; Lemma 5.3; the local window
// matches the direct sum bit for bit; pushing in reverse gives the mirror's forward sum.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "fracvi/fractional/weights.hpp"
#include "fracvi/memory/history.hpp"

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

std::vector<Eigen::VectorXd> random_sequence(std::size_t n, Eigen::Index d, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> dist(-1.0, 1.0);
  std::vector<Eigen::VectorXd> xs(n, Eigen::VectorXd::Zero(d));
  for (auto& x : xs)
    for (Eigen::Index i = 0; i < d; ++i) x(i) = dist(gen);
  return xs;
}

// `DiscEqs`: Σ_{n=0}^{k} α_n Σ_{p=0}^{k−n} α_p x_{k−n−p}, α_n = gl_weights(α).
TEST(DirectHistory, EqualsPaperDoubleSum) {
  constexpr std::size_t kN = 80;
  constexpr Eigen::Index kD = 3;
  const auto xs = random_sequence(kN, kD, 12345u);
  for (const double alpha : {0.3, 0.5, 0.75, 0.9}) {
    const std::vector<double> a = gl_weights(alpha, kN);
    double abs_sum = 0.0;
    for (const double w : a) abs_sum += std::abs(w);
    DirectHistory hist(2.0 * alpha, kD, kN);
    Eigen::VectorXd s(kD);
    for (std::size_t k = 0; k < kN; ++k) {
      hist.push(xs[k]);
      hist.sum(s);
      Eigen::VectorXd ref = Eigen::VectorXd::Zero(kD);
      for (std::size_t n = 0; n <= k; ++n)
        for (std::size_t p = 0; p + n <= k; ++p) ref += a[n] * a[p] * xs[k - n - p];
      // Both are sums of ≤ (k+1)² products bounded by (Σ|α_n|)² max|x| = (Σ|α|)²; the weights
      // c_m themselves carry ≤ a few ulps (weights_test). Bound: 4 (k+1) ε (Σ|α|)².
      const double tol = 4.0 * static_cast<double>(k + 1) * kEps * abs_sum * abs_sum;
      ASSERT_LE((s - ref).cwiseAbs().maxCoeff(), tol) << "alpha " << alpha << " k " << k;
    }
  }
}

TEST(LocalHistory, LemmaFiveThreeExactly) {
  const auto xs = random_sequence(20, 2, 7u);
  LocalHistory hist(1.0, 2);
  Eigen::VectorXd s(2);
  hist.push(xs[0]);
  hist.sum(s);
  EXPECT_TRUE((s.array() == xs[0].array()).all());  // k = 0: c_0 x_0
  for (std::size_t k = 1; k < xs.size(); ++k) {
    hist.push(xs[k]);
    hist.sum(s);
    const Eigen::VectorXd diff = xs[k] - xs[k - 1];
    EXPECT_TRUE((s.array() == diff.array()).all()) << "k " << k;
  }
}

TEST(LocalHistory, BitwiseEqualToDirectForIntegerOrders) {
  const auto xs = random_sequence(50, 3, 99u);
  for (const double order : {0.0, 1.0, 2.0}) {
    LocalHistory local(order, 3);
    DirectHistory direct(order, 3, xs.size());
    Eigen::VectorXd a(3), b(3);
    for (const auto& x : xs) {
      local.push(x);
      direct.push(x);
      local.sum(a);
      direct.sum(b);
      ASSERT_TRUE((a.array() == b.array()).all()) << "order " << order;
    }
    EXPECT_EQ(local.order(), order);
  }
}

// The mirror's forward sum Σ_{m=0}^{N−k} c_m y_{k+m} is the same History fed with y_N, y_{N−1}, …;
// for α = 1/2 it is −(y_{k+1} − y_k) (the paper's identity after Lemma 5.3).
TEST(History, ReversePushGivesForwardSum) {
  constexpr std::size_t kN = 30;
  const auto ys = random_sequence(kN + 1, 2, 4242u);
  const std::vector<double> c = gl_weights(1.5, kN + 1);
  DirectHistory hist(1.5, 2, kN + 1);
  LocalHistory half(1.0, 2);
  Eigen::VectorXd s(2), h(2);
  for (std::size_t j = 0; j <= kN; ++j) {
    const std::size_t k = kN - j;
    hist.push(ys[k]);
    half.push(ys[k]);
    hist.sum(s);
    Eigen::VectorXd ref = Eigen::VectorXd::Zero(2);
    for (std::size_t m = 0; m + k <= kN; ++m) ref += c[m] * ys[k + m];
    EXPECT_LE((s - ref).cwiseAbs().maxCoeff(), 4.0 * static_cast<double>(kN) * kEps);
    half.sum(h);
    if (k < kN) {
      const Eigen::VectorXd expect = -(ys[k + 1] - ys[k]);
      EXPECT_TRUE((h.array() == expect.array()).all());
    }
  }
}

TEST(History, ClearAndFactory) {
  auto local = make_history(HistoryKind::kAuto, 1.0, 2, 10);
  EXPECT_NE(dynamic_cast<LocalHistory*>(local.get()), nullptr);
  auto direct = make_history(HistoryKind::kDirect, 1.0, 2, 10);
  EXPECT_NE(dynamic_cast<DirectHistory*>(direct.get()), nullptr);
  auto frac = make_history(HistoryKind::kAuto, 1.5, 2, 10);
  EXPECT_NE(dynamic_cast<DirectHistory*>(frac.get()), nullptr);
  EXPECT_EQ(frac->capacity(), 10u);
  frac->push(Eigen::VectorXd::Ones(2));
  EXPECT_EQ(frac->size(), 1u);
  frac->clear();
  EXPECT_EQ(frac->size(), 0u);
  EXPECT_TRUE(grunwald_letnikov(0.0).is_local() && grunwald_letnikov(1.0).is_local() &&
              grunwald_letnikov(2.0).is_local());
  EXPECT_FALSE(grunwald_letnikov(0.5).is_local());
  EXPECT_TRUE((ConvolutionQuadrature{CqScheme::kBdf2, 2.0}.is_local()));
  EXPECT_FALSE((ConvolutionQuadrature{CqScheme::kTrapezoidal, 1.0}.is_local()));
  EXPECT_THROW(LocalHistory(0.5, 2), std::invalid_argument);
  EXPECT_THROW(DirectHistory(0.5, 0, 10), std::invalid_argument);
  EXPECT_THROW(DirectHistory(std::nan(""), 2, 10), std::invalid_argument);
}

}  // namespace
}  // namespace fracvi
