// FastHistory and the exponential fit behind it (DESIGN §6, docs/theory/fast_history.md):
//  * the integral representation of the GL weights, checked through its raw trapezoidal
//    quadrature (no compression) — and a negative control (a fit used beyond its range);
//  * every tail weight to relative error ≤ ε: all lags n0 … 3000 and log-spaced lags up to 1e8,
//    six orders, GL and BDF2;
//  * K(N_max, ε) grows like log N (the numbers are printed and recorded);
//  * the history sum against DirectHistory (N = 2·10^4, d = 8) and against an exact FFT
//    convolution (N = 10^6, d = 2) on rough random-forced sequences;
//  * clear(), the fit cache, argument checks, and no allocation in push()/sum().
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unsupported/Eigen/FFT>
#include <utility>
#include <vector>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/fractional/exponential_fit.hpp"
#include "fracvi/fractional/weights.hpp"
#include "fracvi/internal/float_environment.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/memory/fast_history.hpp"
#include "fracvi/memory/history.hpp"

#include "../support/allocation_counter.hpp"

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kOrders[] = {0.3, 0.5, 0.75, 1.25, 1.5, 1.8};
constexpr std::size_t kDenseCheckEnd = 3000;  // every lag n0 … 3000 is checked
constexpr std::size_t kLargestLag = 100'000'000;

// Lags 3000 < m ≤ 1e8, 37 per decade (a grid unrelated to the fit's own 200-per-decade
// verification grid, so the test sees lags the fit never looked at), plus 1e8 itself.
std::vector<std::size_t> log_spaced_lags(std::size_t from, std::size_t to) {
  std::vector<std::size_t> lags;
  const double a = std::log10(static_cast<double>(from)), b = std::log10(static_cast<double>(to));
  const auto n = static_cast<std::size_t>(std::ceil((b - a) * 37.0));
  for (std::size_t i = 1; i <= n; ++i) {
    const auto m = static_cast<std::size_t>(std::round(
        std::pow(10.0, a + (b - a) * (static_cast<double>(i) - 0.5) / static_cast<double>(n))));
    if (m > from && (lags.empty() || m > lags.back())) lags.push_back(m);
  }
  lags.push_back(to);
  return lags;
}

struct WeightErrors {
  double dense = 0.0;   // max over n0 ≤ m ≤ 3000
  double sparse = 0.0;  // max over the log-spaced lags
  std::size_t worst_lag = 0;
};

// Relative error of every represented tail weight against the exact reference (dense_exact is
// the represented sequence: c_{m+lag} at index m).
WeightErrors weight_errors(const ExponentialFit& fit, const std::vector<double>& dense_exact) {
  WeightErrors e;
  const std::size_t last_dense = std::min(kDenseCheckEnd, fit.max_lag);
  for (std::size_t m = fit.window; m <= last_dense; ++m) {
    const double err = std::abs(fit.weight(m) / dense_exact[m] - 1.0);
    if (err > e.dense) {
      e.dense = err;
      e.worst_lag = m;
    }
  }
  if (fit.max_lag > kDenseCheckEnd) {
    for (const std::size_t m : log_spaced_lags(kDenseCheckEnd, fit.max_lag)) {
      const double err =
          std::abs(fit.weight(m) / cq_weight(fit.scheme, fit.order, m + fit.lag) - 1.0);
      if (err > e.sparse) {
        e.sparse = err;
        e.worst_lag = m;
      }
    }
  }
  return e;
}

// ---- The representation and the per-weight accuracy ------------------------------------------

// c_m = −(sin πβ/π) ∫ e^{−(m−β)s}(1 − e^{−s})^β ds discretised by the trapezoidal rule in
// u = ln s and nothing else: if the representation (or its sign, or the shift by β) were wrong,
// this sum could not match the Gamma-ratio weights. Bound: the quadrature is built for ε/10
// (discretisation) + 2·ε/100 (truncation), so ε covers it with margin.
TEST(ExponentialFit, RawQuadratureReproducesTheWeights) {
  constexpr double kTol = 1e-10;
  for (const double beta : kOrders) {
    ExponentialFitOptions o;
    o.order = beta;
    o.tolerance = kTol;
    o.max_lag = kLargestLag;
    o.compress = false;
    const ExponentialFit raw = fit_exponentials(o);
    const WeightErrors e = weight_errors(raw, gl_weights(beta, kDenseCheckEnd + 1));
    EXPECT_LE(e.dense, kTol) << "beta " << beta;
    EXPECT_LE(e.sparse, kTol) << "beta " << beta << " worst lag " << e.worst_lag;
    o.compress = true;
    EXPECT_LT(fit_exponentials(o).terms(), raw.terms()) << "compression must pay";
    std::printf("raw quadrature beta=%.2f: J=%zu h=%.3f max rel err %.2e (dense) %.2e (to 1e8)\n",
                beta, raw.terms(), raw.quadrature_step, e.dense, e.sparse);
  }
}

// The reference itself: gl_weight (Gamma ratio, a few ulps) and the recurrence gl_weights
// (≤ ~1e-12 by weights_test) agree on 0 … 3000, so the 1e-10 checks below measure the fit.
TEST(ExponentialFit, ReferenceWeightsAgree) {
  for (const double beta : kOrders) {
    const std::vector<double> seq = gl_weights(beta, kDenseCheckEnd + 1);
    for (std::size_t m = 2; m <= kDenseCheckEnd; m += 7)
      ASSERT_NEAR(gl_weight(beta, m) / seq[m], 1.0, 1e-12) << beta << " " << m;
  }
  // BDF2: the 41-term convolution of cq_weight against the exact power-series recurrence.
  for (const double beta : {0.5, 1.5}) {
    const std::vector<double> seq = cq_weights(CqScheme::kBdf2, beta, kDenseCheckEnd + 1);
    for (std::size_t m = 80; m <= kDenseCheckEnd; m += 13)
      ASSERT_NEAR(cq_weight(CqScheme::kBdf2, beta, m) / seq[m], 1.0, 1e-12) << beta << " " << m;
  }
}

TEST(ExponentialFit, EveryTailWeightWithinToleranceGl) {
  constexpr double kTol = kDefaultFitTolerance;
  for (const double beta : kOrders) {
    ExponentialFitOptions o;
    o.order = beta;
    o.tolerance = kTol;
    o.max_lag = kLargestLag;
    const ExponentialFit fit = fit_exponentials(o);
    const std::vector<double> exact = gl_weights(beta, kDenseCheckEnd + 1);
    // The window is exact: the same numbers DirectHistory uses.
    for (std::size_t m = 0; m < fit.window; ++m) ASSERT_EQ(fit.weight(m), exact[m]);
    const WeightErrors e = weight_errors(fit, exact);
    EXPECT_LE(e.dense, kTol) << "beta " << beta << " lag " << e.worst_lag;
    EXPECT_LE(e.sparse, kTol) << "beta " << beta << " lag " << e.worst_lag;
    for (std::size_t j = 0; j < fit.terms(); ++j) ASSERT_GT(fit.lambdas[j], 0.0);
    std::printf(
        "GL beta=%.2f eps=1e-10 N=1e8: n0=%zu K=%zu J=%zu max rel err %.2e (n0..3000) %.2e "
        "(to 1e8), cancellation %.2f, fit %.1f ms\n",
        beta, fit.window, fit.terms(), fit.quadrature_nodes, e.dense, e.sparse, fit.cancellation,
        1e3 * fit.seconds);
  }
}

// Negative GL orders (−1 < β < 0: the fractional-integral weights c_m ~ m^{−β−1}/Γ(−β), positive)
// and lagged sequences c_{m+1} (fvi-midpoint's two memory sums, orders 2α and 1 − 2α, lag 1): the
// same representation, the same per-weight tolerance.
TEST(ExponentialFit, EveryTailWeightWithinToleranceNegativeOrdersAndLags) {
  constexpr double kTol = kDefaultFitTolerance;
  struct Case {
    double beta;
    std::size_t lag;
  };
  for (const Case c : {Case{-0.9, 0}, Case{-0.5, 0}, Case{-0.1, 0}, Case{-0.5, 1}, Case{0.6, 1},
                       Case{1.5, 1}, Case{-0.8, 1}}) {
    ExponentialFitOptions o;
    o.order = c.beta;
    o.lag = c.lag;
    o.tolerance = kTol;
    o.max_lag = kLargestLag;
    const ExponentialFit fit = fit_exponentials(o);
    std::vector<double> exact = gl_weights(c.beta, kDenseCheckEnd + 1 + c.lag);
    exact.erase(exact.begin(), exact.begin() + static_cast<std::ptrdiff_t>(c.lag));
    for (std::size_t m = 0; m < fit.window; ++m) ASSERT_EQ(fit.weight(m), exact[m]);
    const WeightErrors e = weight_errors(fit, exact);
    EXPECT_LE(e.dense, kTol) << "beta " << c.beta << " lag " << c.lag << " at " << e.worst_lag;
    EXPECT_LE(e.sparse, kTol) << "beta " << c.beta << " lag " << c.lag << " at " << e.worst_lag;
    std::printf(
        "GL beta=%.2f lag %zu eps=1e-10 N=1e8: K=%zu max rel err %.2e / %.2e, cancellation "
        "%.2f, fit %.1f ms\n",
        c.beta, c.lag, fit.terms(), e.dense, e.sparse, fit.cancellation, 1e3 * fit.seconds);
  }
}

TEST(ExponentialFit, EveryTailWeightWithinToleranceBdf2) {
  constexpr double kTol = kDefaultFitTolerance;
  for (const double beta : kOrders) {
    ExponentialFitOptions o;
    o.scheme = CqScheme::kBdf2;
    o.order = beta;
    o.tolerance = kTol;
    o.max_lag = kLargestLag;
    const ExponentialFit fit = fit_exponentials(o);
    const std::vector<double> exact = cq_weights(CqScheme::kBdf2, beta, kDenseCheckEnd + 1);
    for (std::size_t m = 0; m < fit.window; ++m) ASSERT_EQ(fit.weight(m), exact[m]);
    const WeightErrors e = weight_errors(fit, exact);
    EXPECT_LE(e.dense, kTol) << "beta " << beta << " lag " << e.worst_lag;
    EXPECT_LE(e.sparse, kTol) << "beta " << beta << " lag " << e.worst_lag;
    std::printf(
        "BDF2 beta=%.2f eps=1e-10 N=1e8: n0=%zu K=%zu max rel err %.2e / %.2e, fit %.1f ms\n", beta,
        fit.window, fit.terms(), e.dense, e.sparse, 1e3 * fit.seconds);
  }
}

// Negative control: exponentials cannot follow the power law m^{−1−β} beyond the range they were
// fitted on, so the checks above are sensitive to the range actually covered.
TEST(ExponentialFit, FailsBeyondItsRange) {
  ExponentialFitOptions o;
  o.order = 0.75;
  o.max_lag = 10'000;
  const ExponentialFit fit = fit_exponentials(o);
  EXPECT_LE(std::abs(fit.weight(10'000) / gl_weight(0.75, 10'000) - 1.0), o.tolerance);
  EXPECT_GT(std::abs(fit.weight(1'000'000) / gl_weight(0.75, 1'000'000) - 1.0), 1e-3);
}

// K(N_max, ε) for GL β = 0.5 (and 1.5): recorded, and asserted to grow like log N (the brief's
// K(1e8) ≤ 2.5 K(1e4)) and like log(1/ε) (K(·, 1e-12) ≤ 2.5 K(·, 1e-6)). Also never decreasing
// in N.
TEST(ExponentialFit, TermsGrowLogarithmically) {
  constexpr double kTols[] = {1e-6, 1e-8, 1e-10, 1e-12};
  constexpr std::size_t kLags[] = {1'000, 10'000, 100'000, 1'000'000, 10'000'000, 100'000'000};
  for (const double beta : {0.5, 1.5}) {
    std::size_t k_table[4][6];
    std::printf("K for GL beta=%.1f (n0 = 16); rows eps, columns N_max = 1e3 … 1e8; [fit ms]\n",
                beta);
    for (std::size_t i = 0; i < 4; ++i) {
      std::printf("  eps=%.0e:", kTols[i]);
      for (std::size_t j = 0; j < 6; ++j) {
        ExponentialFitOptions o;
        o.order = beta;
        o.tolerance = kTols[i];
        o.max_lag = kLags[j];
        const ExponentialFit fit = fit_exponentials(o);
        k_table[i][j] = fit.terms();
        EXPECT_LE(fit.max_relative_error, kTols[i]);
        std::printf(" %3zu [%4.1f]", fit.terms(), 1e3 * fit.seconds);
        RecordProperty(
            "K_beta" + std::to_string(beta) + "_eps" + std::to_string(i) + "_N" + std::to_string(j),
            static_cast<int>(fit.terms()));
        if (j > 0) {
          EXPECT_GE(k_table[i][j], k_table[i][j - 1]) << kTols[i] << " " << kLags[j];
        }
      }
      std::printf("\n");
      EXPECT_LE(static_cast<double>(k_table[i][5]), 2.5 * static_cast<double>(k_table[i][1]))
          << "eps " << kTols[i];
    }
    for (std::size_t j = 0; j < 6; ++j)
      EXPECT_LE(static_cast<double>(k_table[3][j]), 2.5 * static_cast<double>(k_table[0][j]));
  }
}

// ---- The history sum ---------------------------------------------------------------------------

// A rough sequence: a random walk (every past value matters for the memory) plus white noise,
// i.e. what a randomly forced trajectory looks like at the step scale. Fixed seed.
Eigen::MatrixXd rough_sequence(std::size_t n, Eigen::Index d, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd xs(d, static_cast<Eigen::Index>(n));
  Eigen::VectorXd walk = Eigen::VectorXd::Zero(d);
  const double step = 1.0 / std::sqrt(static_cast<double>(n));
  for (Eigen::Index k = 0; k < xs.cols(); ++k) {
    for (Eigen::Index i = 0; i < d; ++i) {
      walk(i) += step * normal(gen);
      xs(i, k) = 1.0 + walk(i) + 0.5 * normal(gen);
    }
  }
  return xs;
}

double abs_weight_sum(double beta, std::size_t n) {
  double s = 0.0;
  for (const double c : gl_weights(beta, n)) s += std::abs(c);
  return s;
}

// Every step is compared in optimised builds. Unoptimised builds (dev/Debug preset, where the
// O(N² d) DirectHistory reference takes minutes) compare the first 4 n0 steps and then every 7th
// step — 7 is coprime to the window, so every ring phase is still visited.
#ifdef NDEBUG
constexpr std::size_t kDirectCheckStride = 1;
#else
constexpr std::size_t kDirectCheckStride = 7;
#endif

TEST(FastHistory, MatchesDirectHistory) {
  // β = 0.3 (slowest-decaying weights) at the full size; β = 1.5 on a quarter of it to keep the
  // O(N² d) reference affordable.
  constexpr Eigen::Index kD = 8;
  for (const auto& [beta, kN] :
       {std::pair{0.3, std::size_t{20'000}}, std::pair{1.5, std::size_t{5'000}}}) {
    const Eigen::MatrixXd xs = rough_sequence(kN, kD, 20240611u);
    const double max_x = xs.cwiseAbs().maxCoeff();
    FastHistory fast(beta, kD, kN);
    DirectHistory direct(beta, kD, kN);
    Eigen::VectorXd a(kD), b(kD);
    double max_diff = 0.0, max_early = 0.0;
    for (std::size_t k = 0; k < kN; ++k) {
      fast.push(xs.col(static_cast<Eigen::Index>(k)));
      direct.push(xs.col(static_cast<Eigen::Index>(k)));
      if (k >= 4 * fast.window() && k % kDirectCheckStride != 0 && k + 1 != kN) continue;
      fast.sum(a);
      direct.sum(b);
      const double diff = (a - b).cwiseAbs().maxCoeff();
      max_diff = std::max(max_diff, diff);
      if (k < fast.window()) max_early = std::max(max_early, diff);
    }
    // |S − S_direct| ≤ Σ_m |ĉ_m − c_m| |x| ≤ ε Σ|c_m| max|x| (relative error ε per tail weight);
    // both sums' round-off is ~ (n0 + K) ε_mach Σ|c| max|x| ≪ that.
    const double weight_sum = abs_weight_sum(beta, kN);
    const double bound = 1e-10 * weight_sum * max_x;
    EXPECT_LE(max_diff, bound) << "beta " << beta;
    // Before the tail starts both are the same finite sum, up to summation order: 4 n0 ε.
    EXPECT_LE(max_early, 4.0 * static_cast<double>(fast.window()) * kEps * weight_sum * max_x);
    std::printf(
        "vs direct beta=%.2f N=%zu d=8: K=%zu max|S-S_direct| = %.2e, bound %.2e (ratio %.1e)\n",
        beta, kN, fast.terms(), max_diff, bound, max_diff / bound);
  }
}

// Exact linear convolution by FFT (Eigen's unsupported FFT, kissfft backend), length 2^21 for
// N = 10^6 lags, compared at every step with the fast history on d = 2 rough sequences.
TEST(FastHistory, MatchesFftConvolutionMillionSteps) {
  constexpr std::size_t kN = 1'000'000;
  constexpr Eigen::Index kD = 2;
  constexpr std::size_t kFftSize = std::size_t{1} << 21;  // ≥ 2N − 1: no wrap-around
  const Eigen::MatrixXd xs = rough_sequence(kN, kD, 777u);
  const double max_x = xs.cwiseAbs().maxCoeff();
  for (const double beta : {0.3, 1.8}) {
    const std::vector<double> c = gl_weights(beta, kN);
    Eigen::FFT<double> fft;
    std::vector<double> padded(kFftSize, 0.0);
    std::copy(c.begin(), c.end(), padded.begin());
    std::vector<std::complex<double>> c_hat, x_hat;
    fft.fwd(c_hat, padded);
    double c_norm2 = 0.0;
    for (const double w : c) c_norm2 += w * w;
    Eigen::MatrixXd exact(kD, static_cast<Eigen::Index>(kN));
    std::vector<double> conv;
    for (Eigen::Index i = 0; i < kD; ++i) {
      std::fill(padded.begin(), padded.end(), 0.0);
      for (std::size_t k = 0; k < kN; ++k) padded[k] = xs(i, static_cast<Eigen::Index>(k));
      fft.fwd(x_hat, padded);
      for (std::size_t f = 0; f < kFftSize; ++f) x_hat[f] *= c_hat[f];
      fft.inv(conv, x_hat);
      for (std::size_t k = 0; k < kN; ++k) exact(i, static_cast<Eigen::Index>(k)) = conv[k];
    }
    FastHistory fast(beta, kD, kN);
    Eigen::VectorXd s(kD);
    double max_diff = 0.0;
    for (std::size_t k = 0; k < kN; ++k) {
      fast.push(xs.col(static_cast<Eigen::Index>(k)));
      fast.sum(s);
      max_diff =
          std::max(max_diff, (s - exact.col(static_cast<Eigen::Index>(k))).cwiseAbs().maxCoeff());
    }
    // ε Σ|c| max|x| as above, plus the FFT's own error: per entry at most
    // ~ log2(L) ε_mach ‖c‖₂ ‖x‖₂ (normwise bound of FFT convolution); here ≈ 1e-12·max|x|,
    // a hundredth of the first term.
    const double fft_error = std::log2(static_cast<double>(kFftSize)) * kEps * std::sqrt(c_norm2) *
                             max_x * std::sqrt(static_cast<double>(kN));
    const double bound = 1e-10 * abs_weight_sum(beta, kN) * max_x + fft_error;
    EXPECT_LE(max_diff, bound) << "beta " << beta;
    std::printf(
        "vs FFT beta=%.2f N=1e6 d=2: K=%zu max|S-S_exact| = %.2e, bound %.2e (FFT part %.1e)\n",
        beta, fast.terms(), max_diff, bound, fft_error);
  }
}

TEST(FastHistory, Bdf2MatchesDirectConvolution) {
  constexpr std::size_t kN = 5'000;
  constexpr Eigen::Index kD = 3;
  const Eigen::MatrixXd xs = rough_sequence(kN, kD, 99u);
  const double max_x = xs.cwiseAbs().maxCoeff();
  for (const double beta : {0.5, 1.5}) {
    const std::vector<double> w = cq_weights(CqScheme::kBdf2, beta, kN);
    double weight_sum = 0.0;
    for (const double x : w) weight_sum += std::abs(x);
    const auto history = make_fast_history({CqScheme::kBdf2, beta}, kD, kN, 1e-10);
    Eigen::VectorXd s(kD);
    double max_diff = 0.0;
    for (std::size_t k = 0; k < kN; ++k) {
      history->push(xs.col(static_cast<Eigen::Index>(k)));
      history->sum(s);
      Eigen::VectorXd ref = Eigen::VectorXd::Zero(kD);
      for (std::size_t m = 0; m <= k; ++m) ref += w[m] * xs.col(static_cast<Eigen::Index>(k - m));
      max_diff = std::max(max_diff, (s - ref).cwiseAbs().maxCoeff());
    }
    EXPECT_LE(max_diff, 1e-10 * weight_sum * max_x) << "beta " << beta;
  }
}

TEST(FastHistory, ClearRestartsExactly) {
  const Eigen::MatrixXd xs = rough_sequence(300, 2, 5u);
  FastHistory fast(0.75, 2, 300);
  Eigen::VectorXd s(2);
  std::vector<Eigen::VectorXd> first;
  for (Eigen::Index k = 0; k < 300; ++k) {
    fast.push(xs.col(k));
    fast.sum(s);
    first.push_back(s);
  }
  fast.clear();
  EXPECT_EQ(fast.size(), 0u);
  for (Eigen::Index k = 0; k < 300; ++k) {
    fast.push(xs.col(k));
    fast.sum(s);
    ASSERT_TRUE((s.array() == first[static_cast<std::size_t>(k)].array()).all()) << k;
  }
}

TEST(FastHistory, SmallSystemsSumInTheOrderOfLargeOnes) {
  // Below 4 degrees of freedom push() runs each row along its K recursions (fast_history.cpp,
  // push_rows_across_terms) instead of along the rows; it keeps the large-system kernels' order of
  // additions, so a row's sum is bitwise that row's sum in a larger system (the order matters:
  // interleaved partial sums measured 4× the round-off). d = 1 (recursions stored interleaved in
  // blocks of 16, one_row_across_terms) and 3 (strided) against the same rows inside d = 8, through
  // the window's filling and 3000 steps of the tail, for K = 29 (a 3000-step fit at the default ε)
  // and K = 63 (10^7 steps at ε = 2.9e-12, the fit of the d = 1
  // run of bench/RESULTS.md): neither a multiple of 4, so the remainder terms are covered.
  const std::size_t n = 3000;
  const Eigen::MatrixXd xs = rough_sequence(static_cast<Eigen::Index>(n), 8, 11u);
  for (const auto& [capacity, tolerance] : {std::pair<std::size_t, double>{n, 1e-10},
                                            std::pair<std::size_t, double>{10'000'000, 2.9e-12}}) {
    FastHistory large(1.5, 8, capacity, tolerance);
    ASSERT_NE(large.terms() % 4, 0u);
    for (const Eigen::Index d : {1, 3}) {
      large.clear();
      FastHistory small(1.5, d, capacity, tolerance);
      Eigen::VectorXd s_small(d), s_large(8);
      for (std::size_t k = 0; k < n; ++k) {
        const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
        small.push(x.head(d));
        large.push(x);
        small.sum(s_small);
        large.sum(s_large);
        ASSERT_TRUE((s_small.array() == s_large.head(d).array()).all())
            << "d = " << d << ", K = " << large.terms() << ", k = " << k;
      }
    }
  }
}

TEST(FastHistory, PassOlderWindowsAreThePushByPushOnesBitForBit) {
  // With the default windows (n0 = 16 for Grünwald–Letnikov, 32 for BDF2) a four-push pass forms
  // its pushes' older windows in one loop over the rows (fast_history.cpp, older_windows_of), in
  // an x86-64-v4 variant (32 registers) where the CPU has it and the AVX2 one otherwise: both
  // give, at every push, the bits of the same rows summed push by push across the terms (d = 3:
  // push_rows_across_terms, whose older window is the single-push loop) — the first rows and the
  // last, past the row vectors. On a CPU without AVX-512 both runs take the AVX2 kernel (said
  // below).
  std::printf("x86-64-v4 variants %s\n",
              internal::wide_registers_available() ? "available" : "not available here");
  const Eigen::Index d = 37;  // row vectors and a remainder
  const std::size_t n = 300;
  const Eigen::MatrixXd xs = rough_sequence(n, d, 61u);
  for (const auto& [scheme, window] : {std::pair{CqScheme::kGrunwaldLetnikov, std::size_t{16}},
                                       std::pair{CqScheme::kBdf2, std::size_t{32}}}) {
    const ConvolutionQuadrature q{scheme, 1.5, 0};
    for (const bool wide : {false, true}) {
      internal::wide_registers_allowed = wide;
      const auto pass = make_fast_history(q, d, n);
      const auto first_rows = make_fast_history(q, 3, n), last_rows = make_fast_history(q, 3, n);
      ASSERT_EQ(pass->report().window, window);
      pass->set_threads(1);
      Eigen::VectorXd s_pass(d), s_first(3), s_last(3);
      for (std::size_t k = 0; k < n; ++k) {
        const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
        pass->push(x);
        first_rows->push(x.head(3));
        last_rows->push(x.tail(3));
        pass->sum(s_pass);
        first_rows->sum(s_first);
        last_rows->sum(s_last);
        ASSERT_TRUE((s_pass.head(3).array() == s_first.array()).all() &&
                    (s_pass.tail(3).array() == s_last.array()).all())
            << "n0 = " << window << ", " << (wide ? "x86-64-v4" : "AVX2") << " variant, push " << k;
      }
    }
  }
  internal::wide_registers_allowed = true;
}

// Keeps the values of one record of a saved state.
class RecordCapture final : public StateArchive {
 public:
  explicit RecordCapture(std::string name) : name_(std::move(name)) {}
  [[nodiscard]] bool loading() const override { return false; }
  void doubles(std::string_view name, std::span<double> values) override {
    if (name == name_) values_.assign(values.begin(), values.end());
  }
  void count(std::string_view, std::size_t&) override {}
  [[nodiscard]] const std::vector<double>& values() const { return values_; }

 private:
  std::string name_;
  std::vector<double> values_;
};

TEST(FastHistory, OneDegreeOfFreedomCheckpointsItsRecursionsInOrder) {
  // At d = 1 the recursions are stored interleaved in blocks of 16 (fast_history.cpp,
  // one_row_across_terms); the checkpoint record keeps the order Y_0 … Y_{K−1}: the same values
  // as row 0 of a d = 3 history fed the same row (stored in order; the recursions are the same
  // operations, so the same bits), and a restored history continues bit for bit. K = 63: three
  // interleaved blocks and 15 terms after them.
  const std::size_t n = 400, saved_at = 250;
  const Eigen::MatrixXd xs = rough_sequence(n, 3, 29u);
  FastHistory one(1.5, 1, 10'000'000, 2.9e-12), three(1.5, 3, 10'000'000, 2.9e-12);
  ASSERT_EQ(one.terms(), 63u);
  FastHistory resumed(1.5, 1, 10'000'000, 2.9e-12);
  Eigen::VectorXd s(1), s_resumed(1);
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
    if (k == saved_at) {
      RecordCapture one_record("fast.recursions"), three_record("fast.recursions");
      one.visit_state(one_record);
      three.visit_state(three_record);
      ASSERT_EQ(one_record.values().size(), 63u);
      for (std::size_t j = 0; j < 63; ++j) {
        ASSERT_EQ(one_record.values()[j], three_record.values()[3 * j]) << "Y_" << j;
      }
      StateWriter writer;
      one.visit_state(writer);
      StateReader reader(writer.bytes(), "test state");
      resumed.visit_state(reader);
      reader.finish();
    }
    one.push(x.head(1));
    three.push(x);
    one.sum(s);
    if (k >= saved_at) {
      resumed.push(x.head(1));
      resumed.sum(s_resumed);
      ASSERT_EQ(s(0), s_resumed(0)) << "k = " << k;
    }
  }
}

// A push that one thread runs alone runs the recursions and older windows of up to three later
// pushes in the same pass (fast_history.cpp, recursion_block_steps) — as many as the window n0
// allows: two for n0 not a multiple of 4, four otherwise. (1) With windows of 2 and 3 a row's sums
// are bit for bit those of the d = 3 history, which runs push by push (push_rows_across_terms);
// with windows of 4 and 8 (passes of four; the d = 3 path does not reproduce the large kernels'
// roundings at n0 = 4 even push by push), one thread's sums are bit for bit those of a team of
// two, whose second thread runs one push at a time. (2) A checkpoint taken after any push of the
// cycle — the next push's tail formed, and 2, 1 or 0 later pushes' tails ("fast.later") —
// restores to a history that continues bit for bit like the uninterrupted one. (3) A "fast.later"
// that the state cannot have is refused.
class LaterOverride final : public StateArchive {
 public:
  LaterOverride(StateArchive& inner, std::size_t later) : inner_(inner), later_(later) {}
  [[nodiscard]] bool loading() const override { return inner_.loading(); }
  void doubles(std::string_view name, std::span<double> values) override {
    inner_.doubles(name, values);
  }
  void count(std::string_view name, std::size_t& value) override {
    inner_.count(name, value);
    if (name == "fast.later") value = later_;
  }

 private:
  StateArchive& inner_;
  std::size_t later_;
};

class CountCapture final : public StateArchive {
 public:
  explicit CountCapture(std::string name) : name_(std::move(name)) {}
  [[nodiscard]] bool loading() const override { return false; }
  void doubles(std::string_view, std::span<double>) override {}
  void count(std::string_view name, std::size_t& value) override {
    if (name == name_) value_ = value;
  }
  [[nodiscard]] std::size_t value() const { return value_; }

 private:
  std::string name_;
  std::size_t value_ = 99;
};

TEST(FastHistory, PassesOfSeveralPushesKeepEveryPushsNumbers) {
  const std::size_t n = 600;
  const Eigen::MatrixXd xs = rough_sequence(static_cast<Eigen::Index>(n), 8, 41u);
  for (const std::size_t window : {2, 3}) {
    ExponentialFitOptions o;
    o.order = 1.5;
    o.max_lag = 4096;
    o.window = window;
    const auto fit = shared_exponential_fit(o);
    FastHistory large(fit, 8, n), small(fit, 3, n);
    Eigen::VectorXd s_large(8), s_small(3);
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
      large.push(x);
      small.push(x.head(3));
      large.sum(s_large);
      small.sum(s_small);
      ASSERT_TRUE((s_large.head(3).array() == s_small.array()).all())
          << "n0 = " << window << ", k = " << k;
    }
  }

  for (const std::size_t window : {4, 8}) {
    const Eigen::Index wide = 1200;  // wide (K + n0) ≥ kRunAheadWork: two threads run ahead
    const Eigen::MatrixXd rows = rough_sequence(300, wide, 43u);
    ExponentialFitOptions o;
    o.order = 1.5;
    o.max_lag = 4096;
    o.window = window;
    const auto fit = shared_exponential_fit(o);
    FastHistory one(fit, wide, 300), two(fit, wide, 300);
    one.set_threads(1);
    two.set_threads(2);
    Eigen::VectorXd s_one(wide), s_two(wide);
    for (Eigen::Index k = 0; k < 300; ++k) {
      one.push(rows.col(k));
      two.push(rows.col(k));
      one.sum(s_one);
      two.sum(s_two);
      ASSERT_TRUE((s_one.array() == s_two.array()).all()) << "n0 = " << window << ", k = " << k;
    }
    EXPECT_GT(two.report().threads.team_pushes, 0u);
  }

  const Eigen::Index d = 8;
  const std::size_t capacity = 4096, pushes = 80;
  FastHistory reference(1.5, d, capacity);
  const std::size_t n0 = reference.window();
  std::vector<Eigen::VectorXd> sums;
  std::vector<std::string> saved;  // the state after pushes n0 + 1 … n0 + 8
  std::vector<std::size_t> later;
  Eigen::VectorXd s(d);
  for (std::size_t k = 0; k < pushes; ++k) {
    reference.push(xs.col(static_cast<Eigen::Index>(k)));
    reference.sum(s);
    sums.push_back(s);
    if (k >= n0 && k < n0 + 8) {
      StateWriter writer;
      reference.visit_state(writer);
      saved.push_back(writer.bytes());
      CountCapture capture("fast.later");
      reference.visit_state(capture);
      later.push_back(capture.value());
    }
  }
  // Push n0 (the first with recursions) runs pushes n0 … n0 + 3: 2, 1, 0 later tails after
  // pushes n0, n0 + 1, n0 + 2; push n0 + 4 starts the next pass.
  EXPECT_EQ(later, (std::vector<std::size_t>{2, 1, 0, 0, 2, 1, 0, 0}));
  for (std::size_t i = 0; i < saved.size(); ++i) {
    FastHistory restored(1.5, d, capacity);
    StateReader reader(saved[i], "test state");
    restored.visit_state(reader);
    reader.finish();
    for (std::size_t k = n0 + i + 1; k < pushes; ++k) {
      restored.push(xs.col(static_cast<Eigen::Index>(k)));
      restored.sum(s);
      ASSERT_TRUE((s.array() == sums[k].array()).all())
          << "restored after push " << n0 + i << ", push " << k;
    }
  }
  for (const std::size_t bad : {std::size_t{4}, std::size_t{1}}) {
    // 4: more than a pass of four pushes leaves (the next and three later); 1 after push n0 + 3,
    // whose next push runs its own recursions.
    FastHistory restored(1.5, d, capacity);
    StateReader reader(saved[bad == 4 ? 0 : 3], "test state");
    LaterOverride tampered(reader, bad);
    EXPECT_THROW(restored.visit_state(tampered), CheckpointError) << "fast.later = " << bad;
  }
}

// A push split by rows (History::begin_row_push, push_rows, end_row_push: the CQ midpoint step
// split by rows) gives push()'s numbers bit for bit, whatever the ranges and their order (here
// odd bounds, the second range pushed first), through the four-push passes; the sum's rows are
// final once their range is pushed. The other histories refuse it.
TEST(FastHistory, PushesByRowsArePushesBitForBit) {
  const Eigen::Index d = 301;
  const Eigen::MatrixXd xs = rough_sequence(200, d, 47u);
  FastHistory whole(1.5, d, 200), by_rows(1.5, d, 200);
  whole.set_threads(1);
  by_rows.set_threads(1);
  ASSERT_TRUE(by_rows.pushes_rows());
  Eigen::VectorXd s_whole(d), s_rows(d);
  for (Eigen::Index k = 0; k < 200; ++k) {
    whole.push(xs.col(k));
    whole.sum(s_whole);
    by_rows.begin_row_push(xs.col(k).data());
    for (const auto& [lo, hi] : {std::pair<Eigen::Index, Eigen::Index>{77, 301}, {0, 5}, {5, 77}}) {
      by_rows.push_rows(lo, hi);
      for (Eigen::Index i = lo; i < hi; ++i) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(by_rows.kept_sum()[i]),
                  std::bit_cast<std::uint64_t>(s_whole[i]))
            << "k = " << k << ", row " << i;
      }
    }
    by_rows.end_row_push();
    by_rows.sum(s_rows);
    ASSERT_TRUE((s_rows.array() == s_whole.array()).all()) << "k = " << k;
  }
  EXPECT_EQ(by_rows.size(), whole.size());
  FastHistory team(1.5, 5000, 200);
  team.set_threads(2);  // a run-ahead team pushes whole
  EXPECT_FALSE(team.pushes_rows());
  DirectHistory direct(1.5, d, 10);
  EXPECT_FALSE(direct.pushes_rows());
  EXPECT_THROW(direct.begin_row_push(xs.col(0).data()), std::logic_error);
}

// The order-1.5 Grünwald–Letnikov fit for a capacity of n pushes, with window n0 = `window` (0:
// the fit's default).
std::shared_ptr<const ExponentialFit> order_1_5_fit(std::size_t n, std::size_t window) {
  ExponentialFitOptions o;
  o.order = 1.5;
  o.max_lag = fast_history_fit_lag(n);
  o.window = window;
  return shared_exponential_fit(o);
}

// Pushes run ahead by row groups (History::set_rows_ahead: the step by rows whose Newton solve
// runs on one thread) give push()'s numbers bit for bit: with windows of 8 and the default (four
// groups, each group's pass running four pushes, the first push with recursions bringing the
// groups to their turns) and of 3 (one group, a push at a time); the work shared three ways in
// reverse order; the last pushes' passes cut at the capacity; switched off and on mid-run; a
// checkpoint taken in the middle of the groups' cycle restored to a history with groups and to one
// without, both continuing bit for bit.
TEST(FastHistory, PushesAheadByGroupsArePushesBitForBit) {
  const Eigen::Index d = 301;
  const std::size_t n = 150;
  const Eigen::MatrixXd xs = rough_sequence(static_cast<Eigen::Index>(n), d, 53u);
  for (const std::size_t window : {std::size_t{0}, std::size_t{8}, std::size_t{3}}) {
    const auto fit = order_1_5_fit(n, window);
    SCOPED_TRACE("n0 = " + std::to_string(fit->window));
    FastHistory whole(fit, d, n), ahead(fit, d, n);
    whole.set_threads(1);
    ahead.set_threads(1);
    ahead.set_rows_ahead(true);
    std::unique_ptr<FastHistory> restored[2];
    Eigen::VectorXd s_whole(d), s(d);
    auto push_ahead = [&](FastHistory& h, const Eigen::VectorXd& x) {
      h.begin_row_push(x.data());
      for (int share = 2; share >= 0; --share) h.rows_ahead(share, 3);
      h.push_rows(150, d);
      h.push_rows(0, 150);
      h.end_row_push();
    };
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
      whole.push(x);
      whole.sum(s_whole);
      if (k == 60) ahead.set_rows_ahead(false);
      if (k == 62) ahead.set_rows_ahead(true);
      if (k >= 60 && k < 62) {
        ahead.push(x);
      } else {
        push_ahead(ahead, x);
      }
      ahead.sum(s);
      ASSERT_TRUE((s.array() == s_whole.array()).all()) << "k = " << k;
      for (int r = 0; r < 2 && restored[0]; ++r) {
        if (r == 0) {
          push_ahead(*restored[r], x);
        } else {
          restored[r]->push(x);
        }
        restored[r]->sum(s);
        ASSERT_TRUE((s.array() == s_whole.array()).all()) << "restored " << r << ", k = " << k;
      }
      if (k == fit->window + 41) {  // groups ready for 0, 1, 2 and 3 more pushes
        StateWriter writer;
        ahead.visit_state(writer);
        for (int r = 0; r < 2; ++r) {
          restored[r] = std::make_unique<FastHistory>(fit, d, n);
          restored[r]->set_threads(1);
          if (r == 0) restored[r]->set_rows_ahead(true);
          StateReader reader(writer.bytes(), "test state");
          restored[r]->visit_state(reader);
          reader.finish();
        }
      }
    }
    EXPECT_EQ(ahead.size(), n);
  }
  FastHistory team(1.5, 5000, 200);
  team.set_threads(2);  // a run-ahead team pushes whole
  EXPECT_THROW(team.set_rows_ahead(true), std::logic_error);
  DirectHistory direct(1.5, d, 10);
  EXPECT_THROW(direct.set_rows_ahead(true), std::logic_error);
}

// A team of two runs the next push ahead by row groups (fast_history.hpp, configure_threads): its
// thread runs one group's recursions and older windows for four pushes a push. The sums are those
// of one thread bit for bit at every push; a checkpoint taken at each push of the groups' cycle —
// among them the state with the next push's passes planned, four pushes ready in one group
// ('fast.later' = 3) — restores on one thread and on two and continues bit for bit; the team
// switched to one thread and back mid-run changes nothing; with a window that allows no groups of
// four (n0 = 3) the team runs one push ahead, as before.
TEST(FastHistory, TeamOfTwoRunsAheadByGroupsBitForBit) {
  // d (K + n0) ≥ kRunAheadWork: a team of two when asked; d not a multiple of 8, so that the last
  // group's rows are not whole cache lines.
  const Eigen::Index d = 1203;
  const std::size_t n = 160;
  const Eigen::MatrixXd xs = rough_sequence(n, d, 59u);
  for (const std::size_t window : {std::size_t{0}, std::size_t{8}, std::size_t{3}}) {
    const auto fit = order_1_5_fit(n, window);
    const std::size_t n0 = fit->window;
    SCOPED_TRACE("n0 = " + std::to_string(n0));
    FastHistory one(fit, d, n), two(fit, d, n);
    one.set_threads(1);
    two.set_threads(2);
    std::vector<Eigen::VectorXd> sums;
    std::vector<std::string> saved;  // after pushes n0 + 40 … n0 + 43
    std::size_t most_later = 0;
    Eigen::VectorXd s_one(d), s(d);
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
      if (k == n0 + 60) two.set_threads(1);
      if (k == n0 + 63) two.set_threads(2);
      one.push(x);
      two.push(x);
      one.sum(s_one);
      two.sum(s);
      sums.push_back(s_one);
      ASSERT_TRUE((s.array() == s_one.array()).all()) << "k = " << k;
      if (k >= n0 + 40 && k < n0 + 44) {
        CountCapture capture("fast.later");
        two.visit_state(capture);
        most_later = std::max(most_later, capture.value());
        StateWriter writer;
        two.visit_state(writer);
        saved.push_back(writer.bytes());
      }
    }
    // Counted since the last set_threads: every push from there ran with the team.
    EXPECT_EQ(two.report().threads.team_pushes, n - (n0 + 63));
    // Groups of four: the planned turn's pass makes four pushes ready; one push ahead: one.
    EXPECT_EQ(most_later, n0 % 4 == 0 ? 3u : 0u);
    for (std::size_t i = 0; i < saved.size(); ++i) {
      for (const int threads : {1, 2}) {
        FastHistory restored(fit, d, n);
        restored.set_threads(threads);
        StateReader reader(saved[i], "test state");
        restored.visit_state(reader);
        reader.finish();
        for (std::size_t k = n0 + 41 + i; k < n; ++k) {
          restored.push(xs.col(static_cast<Eigen::Index>(k)));
          restored.sum(s);
          ASSERT_TRUE((s.array() == sums[k].array()).all())
              << "restored after push " << n0 + 40 + i << " on " << threads << " thread(s), push "
              << k;
        }
      }
    }
  }
}

// A checkpoint taken between steps brings the groups of a team of two even (the passes the next
// pushes would have run) outside the step, whose subnormal numbers are flushed (IntegratorOptions
// ::flush_subnormals): those passes must run with the pushes' flush bits, or values in the
// subnormal range come out differently. Here every push runs flushed, as in a step, the
// checkpoints not, on inputs of 10^-306 whose recursions and window products are subnormal: the
// sums stay those of one thread that was never checkpointed, bit for bit.
TEST(FastHistory, ATeamsCheckpointBetweenStepsKeepsThePushesFlushBits) {
  if (!internal::kCanFlushSubnormals) GTEST_SKIP() << "no flush-to-zero on this architecture";
  const Eigen::Index d = 1203;
  const std::size_t n = 120;
  const Eigen::MatrixXd xs = 1e-306 * rough_sequence(n, d, 67u);
  FastHistory one(1.5, d, n), two(1.5, d, n);
  one.set_threads(1);
  two.set_threads(2);
  const std::size_t n0 = two.window();
  ASSERT_EQ(n0 % 4, 0u);  // the team runs ahead by groups
  Eigen::VectorXd s_one(d), s_two(d);
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::VectorXd x = xs.col(static_cast<Eigen::Index>(k));
    {
      const internal::SubnormalsFlushed flushed(true);
      one.push(x);
      two.push(x);
    }
    if (k >= n0 + 20 && k < n0 + 24) {
      StateWriter writer;
      two.visit_state(writer);
    }
    one.sum(s_one);
    two.sum(s_two);
    ASSERT_TRUE((s_one.array() == s_two.array()).all()) << "push " << k;
  }
}

TEST(FastHistory, ShortCapacityIsExact) {
  // max_lag < n0: no tail at all (K = 0); the sum is the direct one up to summation order.
  const Eigen::MatrixXd xs = rough_sequence(10, 3, 6u);
  ExponentialFitOptions o;
  o.order = 1.25;
  o.max_lag = 9;
  FastHistory fast(shared_exponential_fit(o), 3, 10);
  DirectHistory direct(1.25, 3, 10);
  EXPECT_EQ(fast.terms(), 0u);
  Eigen::VectorXd a(3), b(3);
  for (Eigen::Index k = 0; k < 10; ++k) {
    fast.push(xs.col(k));
    direct.push(xs.col(k));
    fast.sum(a);
    direct.sum(b);
    // Same ≤ 10 products, summed in another order: 4·10 ε Σ|c| max|x|, Σ|c| ≤ 2^{1.25} < 3.
    EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 4 * 10 * kEps * 3.0 * xs.cwiseAbs().maxCoeff());
  }
}

TEST(FastHistory, SharesCachedFits) {
  clear_exponential_fit_cache();
  EXPECT_EQ(exponential_fit_cache_size(), 0u);
  // Capacities 1000 and 1020 both round to max_lag 1024: one fit.
  FastHistory a(0.6, 1, 1000), b(0.6, 4, 1020);
  EXPECT_EQ(&a.fit(), &b.fit());
  EXPECT_EQ(a.fit().max_lag, 1024u);
  EXPECT_EQ(fast_history_fit_lag(1025), 1024u);
  EXPECT_EQ(fast_history_fit_lag(1026), 2048u);
  EXPECT_EQ(fast_history_fit_lag(1), 1u);
  FastHistory c(0.6, 1, 5000);
  EXPECT_NE(&a.fit(), &c.fit());
  EXPECT_EQ(exponential_fit_cache_size(), 2u);
  // A fit for more lags serves a shorter history: c's capacity 5000 rounds to max_lag 8192.
  ExponentialFitOptions o;
  o.order = 0.6;
  o.max_lag = 8192;
  FastHistory d(shared_exponential_fit(o), 2, 100);
  EXPECT_EQ(&d.fit(), &c.fit());
  clear_exponential_fit_cache();
}

TEST(FastHistory, RejectsBadArguments) {
  // Populate the cache first: invalid options must not be answered from it (a NaN order once
  // compared equivalent to every cached key).
  EXPECT_NO_THROW(FastHistory(0.3, 1, 100));
  EXPECT_THROW(FastHistory(1.0, 1, 100), std::invalid_argument);  // integer: LocalHistory
  EXPECT_THROW(FastHistory(0.0, 1, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(2.0, 1, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(2.5, 1, 100), std::invalid_argument);
  EXPECT_NO_THROW(FastHistory(-0.5, 1, 100));  // GL of negative order: a fractional integral
  EXPECT_THROW(FastHistory(-1.0, 1, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(-1.5, 1, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(std::nan(""), 1, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(0.5, 0, 100), std::invalid_argument);
  EXPECT_THROW(FastHistory(0.5, 1, 0), std::invalid_argument);
  EXPECT_THROW(FastHistory(0.5, 1, 100, 1e-15), std::invalid_argument);
  EXPECT_THROW(FastHistory(0.5, 1, 100, 0.1), std::invalid_argument);
  EXPECT_THROW(FastHistory(nullptr, 1, 100), std::invalid_argument);
  // LocalHistory reports capacity SIZE_MAX; a fast history cannot promise that many lags.
  EXPECT_THROW(FastHistory(0.5, 1, static_cast<std::size_t>(-1)), std::invalid_argument);
  ExponentialFitOptions o;
  o.max_lag = 100;
  EXPECT_THROW(FastHistory(shared_exponential_fit(o), 1, 102), std::invalid_argument);
  EXPECT_NO_THROW(FastHistory(shared_exponential_fit(o), 1, 101));
  o.scheme = CqScheme::kTrapezoidal;
  EXPECT_THROW(fit_exponentials(o), std::invalid_argument);
  o.scheme = CqScheme::kGrunwaldLetnikov;
  o.window = 1;
  EXPECT_THROW(fit_exponentials(o), std::invalid_argument);
  o.max_lag = 0;
  o.window = 0;
  EXPECT_THROW(fit_exponentials(o), std::invalid_argument);
}

// push() and sum() do not allocate (DESIGN §4), for d = 1 and d = 50, across the switch-on of
// the tail at k = n0; the control shows the counter is live.
TEST(FastHistory, NoAllocationInPushAndSum) {
  if (!FRACVI_COUNT_MALLOC) GTEST_SKIP() << "malloc interposition unavailable (sanitizer build)";
  for (const Eigen::Index d : {Eigen::Index{1}, Eigen::Index{50}}) {
    const Eigen::MatrixXd xs = rough_sequence(2000, d, 11u);
    FastHistory fast(0.75, d, 2000);
    Eigen::VectorXd s(d);
    g_allocations = 0;
    g_counting = true;
    for (Eigen::Index k = 0; k < xs.cols(); ++k) {
      fast.push(xs.col(k));
      fast.sum(s);
    }
    g_counting = false;
    EXPECT_EQ(g_allocations, 0u) << "d " << d;
  }
  g_allocations = 0;
  g_counting = true;
  const Eigen::VectorXd control = Eigen::VectorXd::Ones(100);
  g_counting = false;
  EXPECT_GT(g_allocations, 0u) << "the counter must see an Eigen allocation";
  EXPECT_EQ(control.size(), 100);
}

}  // namespace
}  // namespace fracvi
