// The block histories of Runge–Kutta CQ (memory/block_history.hpp, docs/theory/fast_history.md,
// "Block history (Runge–Kutta CQ)"):
//  * DirectBlockHistory against a naive evaluation of the definition S_k = Σ_j (W_{j+lag} ⊗ I_d)
//    vec(Z_{k−j}) with single-lag weights, lags 0 and 1, and the exact integer-order weights;
//  * the lag: S^{lag 0}_k = Z_k W_0ᵀ + S^{lag 1}_{k−1};
//  * FastBlockHistory against DirectBlockHistory over whole sequences of N = 2·10^4 pushes
//    (s = 2, 3, 4; β = 0.5, 1.5; d = 1, 3; lags 0 and 1), and a negative control (a tail used
//    beyond its max_lag is refused; a tail fitted loosely is measurably worse);
//  * the recursions kept divided by a unit stage's coefficients and plain, each against the sum of
//    the represented weights; the x86-64-v4 variants bit for bit the AVX2 kernels;
//  * memory independent of N, no allocation in push()/sum(), clear(), the factory, and a
//    10^7-push run (d = 1, s = 3) against the continuous step response.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/memory/block_history.hpp"
#include "fracvi/memory/fast_history.hpp"

#include "../support/allocation_counter.hpp"

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// Stage blocks Z_k (d × s) of a rough sequence: a random walk plus white noise per degree of
// freedom and stage (every past block matters for the memory), plus a smooth part evaluated at the
// stage times k + c_i (what a trajectory looks like). Fixed seed.
std::vector<Eigen::MatrixXd> rough_blocks(std::size_t n, Eigen::Index d, int s, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::VectorXd c = lobatto_iiic(s).c;
  std::vector<Eigen::MatrixXd> z(n, Eigen::MatrixXd(d, s));
  Eigen::VectorXd walk = Eigen::VectorXd::Zero(d);
  const double step = 1.0 / std::sqrt(static_cast<double>(n));
  for (std::size_t k = 0; k < n; ++k) {
    for (Eigen::Index r = 0; r < d; ++r) {
      walk(r) += step * normal(gen);
      for (Eigen::Index i = 0; i < s; ++i) {
        const double t = (static_cast<double>(k) + c(i)) / static_cast<double>(n);
        z[k](r, i) = 1.0 + std::cos(7.0 * t + static_cast<double>(r)) + walk(r) + 0.3 * normal(gen);
      }
    }
  }
  return z;
}

double max_abs(const std::vector<Eigen::MatrixXd>& z) {
  double m = 0.0;
  for (const auto& b : z) m = std::max(m, b.cwiseAbs().maxCoeff());
  return m;
}

// The definition, per degree of freedom: S_k(r, :) = Σ_{j=0}^{k} W_{j+lag} z_{k−j}(r, :)ᵀ, with the
// single-lag evaluator RungeKuttaCq::weight() of the plain weights.
Eigen::MatrixXd naive_sum(const std::vector<Eigen::MatrixXd>& w_plain, std::size_t lag,
                          const std::vector<Eigen::MatrixXd>& z, std::size_t k) {
  const Eigen::Index d = z[0].rows(), s = z[0].cols();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(d, s);
  for (Eigen::Index r = 0; r < d; ++r) {
    Eigen::VectorXd acc = Eigen::VectorXd::Zero(s);
    for (std::size_t j = 0; j <= k; ++j) acc += w_plain[j + lag] * z[k - j].row(r).transpose();
    out.row(r) = acc.transpose();
  }
  return out;
}

TEST(DirectBlockHistory, MatchesTheDefinition) {
  constexpr std::size_t kN = 60;
  constexpr Eigen::Index kD = 3;
  for (const int s : {2, 3, 4}) {
    for (const double beta : {0.5, 1.0, 1.5}) {
      std::vector<Eigen::MatrixXd> w_plain;
      double weight_sum = 0.0;
      for (std::size_t j = 0; j <= kN; ++j) {
        w_plain.push_back(RungeKuttaCq{s, beta}.weight(j));
        weight_sum += w_plain.back().cwiseAbs().maxCoeff();
      }
      const auto z = rough_blocks(kN, kD, s, 17u + static_cast<unsigned>(s));
      for (const std::size_t lag : {std::size_t{0}, std::size_t{1}}) {
        DirectBlockHistory direct(RungeKuttaCq{s, beta, lag}, kD, kN);
        EXPECT_EQ(direct.stages(), s);
        EXPECT_EQ(direct.quadrature().lag, lag);
        Eigen::MatrixXd out(kD, s);
        double max_diff = 0.0;
        for (std::size_t k = 0; k < kN; ++k) {
          direct.push(z[k]);
          direct.sum(out);
          max_diff =
              std::max(max_diff, (out - naive_sum(w_plain, lag, z, k)).cwiseAbs().maxCoeff());
        }
        // weights(count) and weight(j) agree to 1e-14 (rkcq_weights.md §7); summation order aside
        // the two sums are the same products: a few ε of Σ_j s·max|W_j|·max|Z|.
        EXPECT_LE(max_diff, 1e-14 * s * weight_sum * max_abs(z)) << s << " " << beta << " " << lag;
      }
    }
  }
}

TEST(DirectBlockHistory, OrderOneIsTheLocalDifference) {
  // β = 1: W_0 = A^{−1}, W_1 = −A^{−1}𝟙e_sᵀ, nothing beyond (rkcq_weights.md §2).
  for (const int s : {2, 3, 4}) {
    const Eigen::MatrixXd a_inv = lobatto_iiic(s).a.inverse();
    const Eigen::MatrixXd w1 =
        -a_inv * Eigen::VectorXd::Ones(s) * Eigen::RowVectorXd::Unit(s, s - 1);
    const auto z = rough_blocks(20, 2, s, 3u);
    DirectBlockHistory direct(RungeKuttaCq{s, 1.0}, 2, 20);
    Eigen::MatrixXd out(2, s);
    for (std::size_t k = 0; k < 20; ++k) {
      direct.push(z[k]);
      direct.sum(out);
      Eigen::MatrixXd expect = z[k] * a_inv.transpose();
      if (k > 0) expect += z[k - 1] * w1.transpose();
      EXPECT_LE((out - expect).cwiseAbs().maxCoeff(), 64 * kEps * expect.cwiseAbs().maxCoeff())
          << s << " " << k;
    }
  }
}

TEST(BlockHistory, LagOneIsTheKnownPart) {
  // S^{lag 0}_k = Z_k W_0ᵀ + S^{lag 1}_{k−1}: the lag-1 sum after pushing Z_{k−1} is what the
  // stepper adds to W_0 Z_k, for the direct and the fast history.
  constexpr std::size_t kN = 3000;
  constexpr Eigen::Index kD = 2;
  for (const int s : {2, 3}) {
    const double beta = 0.7;
    const auto z = rough_blocks(kN, kD, s, 5u);
    const Eigen::MatrixXd w0 = RungeKuttaCq{s, beta}.weight(0);
    for (const HistoryKind kind : {HistoryKind::kDirect, HistoryKind::kFast}) {
      auto plain = make_block_history(kind, RungeKuttaCq{s, beta}, kD, kN);
      auto lagged = make_block_history(kind, RungeKuttaCq{s, beta, 1}, kD, kN);
      EXPECT_EQ(lagged->quadrature().lag, 1u);
      Eigen::MatrixXd a(kD, s), b(kD, s);
      double max_diff = 0.0, scale = 0.0;
      for (std::size_t k = 0; k < kN; ++k) {
        plain->push(z[k]);
        plain->sum(a);
        Eigen::MatrixXd expect = z[k] * w0.transpose();
        if (k > 0) expect += b;  // the lag-1 sum after Z_{k−1}
        max_diff = std::max(max_diff, (a - expect).cwiseAbs().maxCoeff());
        scale = std::max(scale, a.cwiseAbs().maxCoeff());
        lagged->push(z[k]);
        lagged->sum(b);
      }
      // The fast lagged history has its own window (n0 blocks from lag 1), so the two fast sums
      // differ by the tail's error: ≤ 1e-10 relative (as against the direct one, below).
      const double tol = kind == HistoryKind::kDirect ? 1e-13 : 1e-10;
      EXPECT_LE(max_diff, tol * scale) << s << " " << to_string(kind);
      std::printf("lag identity s=%d %s: max diff / max|S| = %.2e\n", s,
                  std::string(to_string(kind)).c_str(), max_diff / scale);
    }
  }
}

// Fast against direct over a whole sequence of N pushes. The direct reference costs
// O(N² d s²); it is compared at every step up to 4 n0 and then at every 5th step (5 is coprime to
// the window 16, so every ring phase is visited) and at the last one.
struct FastVsDirect {
  double max_diff = 0.0;  // max over compared steps of max|S_fast − S_direct|
  double max_sum = 0.0;   // max over compared steps of max|S_direct|
  double bound = 0.0;     // ε s Σ_j max|W_j| max|Z|, the a priori bound of the tail error
  std::size_t terms = 0;
  double fast_seconds = 0.0;
};

FastVsDirect compare_fast_direct(int s, double beta, std::size_t lag, Eigen::Index d, std::size_t n,
                                 double tolerance, unsigned seed) {
  const RungeKuttaCq q{s, beta, lag};
  const auto z = rough_blocks(n, d, s, seed);
  DirectBlockHistory direct(q, d, n);
  const auto fast_ptr = make_fast_block_history(q, d, n, tolerance);
  auto& fast = dynamic_cast<FastBlockHistory&>(*fast_ptr);
  FastVsDirect r;
  r.terms = fast.terms();
  double weight_sum = 0.0;
  for (std::size_t j = 0; j < n; ++j) weight_sum += direct.weights()[j].cwiseAbs().maxCoeff();
  r.bound = tolerance * s * weight_sum * max_abs(z);
  Eigen::MatrixXd a(d, s), b(d, s);
  for (std::size_t k = 0; k < n; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    fast.push(z[k]);
    fast.sum(a);
    r.fast_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    direct.push(z[k]);
    if (k >= 4 * fast.window() && k % 5 != 0 && k + 1 != n) continue;
    direct.sum(b);
    r.max_diff = std::max(r.max_diff, (a - b).cwiseAbs().maxCoeff());
    r.max_sum = std::max(r.max_sum, b.cwiseAbs().maxCoeff());
  }
  return r;
}

TEST(FastBlockHistory, MatchesDirectOverWholeSequences) {
  constexpr std::size_t kN = 20'000;
  for (const int s : {2, 3, 4}) {
    for (const double beta : {0.5, 1.5}) {
      for (const Eigen::Index d : {Eigen::Index{1}, Eigen::Index{3}}) {
        const std::size_t lag = (s + d) % 2 == 0 ? 0 : 1;  // both lags over the table
        const FastVsDirect r = compare_fast_direct(s, beta, lag, d, kN, 1e-10, 2025u);
        const double rel = r.max_diff / r.max_sum;
        EXPECT_LE(r.max_diff, r.bound) << s << " " << beta << " " << d;
        EXPECT_LE(rel, 1e-10) << s << " " << beta << " " << d;
        std::printf(
            "s=%d beta=%.1f d=%ld lag=%zu N=%zu: K=%zu max|dS|/max|S| = %.2e, max|dS|/bound = "
            "%.2e, fast %.3f s\n",
            s, beta, static_cast<long>(d), lag, kN, r.terms, rel, r.max_diff / r.bound,
            r.fast_seconds);
      }
    }
  }
}

TEST(FastBlockHistory, LooseToleranceIsMeasurablyWorse) {
  // Negative control: the comparison sees the tail. A 1e-5 tail misses the direct sum by far more
  // than 1e-10 (and stays within its own bound).
  const FastVsDirect r = compare_fast_direct(3, 0.5, 0, 1, 5000, 1e-5, 7u);
  EXPECT_GT(r.max_diff / r.max_sum, 1e-9);
  EXPECT_LE(r.max_diff, r.bound);
  std::printf("loose tail (1e-5): max|dS|/max|S| = %.2e\n", r.max_diff / r.max_sum);
}

// The sum of the represented weights (RkcqTail::weight: the head, then the rank-one terms) over
// the blocks pushed so far, per degree of freedom: what FastBlockHistory computes but for
// round-off.
Eigen::MatrixXd represented_sum(const RkcqTail& tail, std::size_t lag,
                                const std::vector<Eigen::MatrixXd>& z, std::size_t k) {
  std::vector<Eigen::MatrixXd> w;
  for (std::size_t j = 0; j <= k + lag; ++j) w.push_back(tail.weight(j));
  return naive_sum(w, lag, z, k);
}

TEST(FastBlockHistory, UnitStageAndPlainRecursionsBothSumTheRepresentation) {
  // Each recursion is kept divided by its (v_i)_p for the unit stage p (one multiply–add fewer a
  // term); where no stage qualifies the recursions are the plain ones. Both against the
  // represented weights themselves (so the fit's 1e-10 does not hide a scaling error): the tail of
  // s = 3, β = 1.5 as fitted, and with one zero coefficient per stage (no unit stage).
  const RkcqTail fitted =
      fit_rkcq_tail({.stages = 3, .order = 1.5, .tolerance = 1e-10, .max_lag = 4096, .window = 17});
  RkcqTail plain = fitted;
  for (Eigen::Index e = 0; e < 3; ++e) plain.right[static_cast<std::size_t>(5 * e)](e) = 0.0;
  constexpr Eigen::Index kD = 9;  // two row vectors and a remainder
  constexpr std::size_t kN = 160;
  const auto z = rough_blocks(kN, kD, 3, 31u);
  for (const bool unit : {true, false}) {
    const RkcqTail& tail = unit ? fitted : plain;
    FastBlockHistory h(std::make_shared<const RkcqTail>(tail), 1, kD, kN);
    if (unit) {
      EXPECT_LT(h.unit_stage(), 3);
    } else {
      EXPECT_EQ(h.unit_stage(), 3);
    }
    Eigen::MatrixXd out(kD, 3);
    double max_rel = 0.0;
    for (std::size_t k = 0; k < kN; ++k) {
      h.push(z[k]);
      if (k % 7 != 0 && k + 1 != kN) continue;
      h.sum(out);
      const Eigen::MatrixXd expected = represented_sum(tail, 1, z, k);
      max_rel = std::max(max_rel,
                         (out - expected).cwiseAbs().maxCoeff() / expected.cwiseAbs().maxCoeff());
    }
    // K ≈ 30 terms and n0·s² window products a sum, round-off of the sizes of the terms.
    EXPECT_LE(max_rel, 1e-13) << "unit " << unit;
    std::printf("unit stage %ld, K = %zu: max relative difference from the representation %.2e\n",
                static_cast<long>(h.unit_stage()), h.terms(), max_rel);
  }
}

TEST(FastBlockHistory, WideRegisterKernelsAreTheAvx2KernelsBitForBit) {
  // The recursions' x86-64-v4 variant (32 registers; with it, two pushes a pass for every s) and
  // the AVX2 kernels (one push a pass for s = 3, 4) make the same operations in the same order:
  // the same sums bit for bit, push by push. On a CPU without AVX-512 both runs take the AVX2
  // kernels (said below).
  const bool available = internal::wide_registers_available();
  std::printf("x86-64-v4 variants %s\n", available ? "available" : "not available here");
  constexpr Eigen::Index kD = 37;  // row vectors and a remainder
  constexpr std::size_t kN = 300;
  for (const int s : {2, 3, 4}) {
    const auto z = rough_blocks(kN, kD, s, 41u);
    std::vector<Eigen::MatrixXd> sums[2];
    for (const bool wide : {false, true}) {
      internal::wide_registers_allowed = wide;
      auto h = make_fast_block_history(RungeKuttaCq{s, 1.5, 1}, kD, kN);
      h->set_threads(1);
      Eigen::MatrixXd out(kD, s);
      for (const auto& block : z) {
        h->push(block);
        h->sum(out);
        sums[wide ? 1 : 0].push_back(out);
      }
    }
    internal::wide_registers_allowed = true;
    for (std::size_t k = 0; k < kN; ++k) {
      ASSERT_TRUE((sums[0][k].array() == sums[1][k].array()).all()) << "s " << s << " push " << k;
    }
  }
}

TEST(FastBlockHistory, IntegerOrdersAreLocalAndExact) {
  for (const double beta : {0.0, 1.0, 2.0}) {
    for (const std::size_t lag : {std::size_t{0}, std::size_t{1}, std::size_t{2}}) {
      const RungeKuttaCq q{3, beta, lag};
      const auto fast_ptr = make_block_history(HistoryKind::kAuto, q, 2, 500);
      const auto* fast = dynamic_cast<const FastBlockHistory*>(fast_ptr.get());
      ASSERT_NE(fast, nullptr);
      EXPECT_EQ(fast->terms(), 0u);
      DirectBlockHistory direct(q, 2, 500);
      const auto z = rough_blocks(500, 2, 3, 9u);
      Eigen::MatrixXd a(2, 3), b(2, 3);
      double max_diff = 0.0;
      for (std::size_t k = 0; k < 500; ++k) {
        fast_ptr->push(z[k]);
        direct.push(z[k]);
        fast_ptr->sum(a);
        direct.sum(b);
        max_diff = std::max(max_diff, (a - b).cwiseAbs().maxCoeff());
      }
      // The same ≤ 3 nonzero blocks, summed in another order (and exact zeros elsewhere).
      EXPECT_LE(max_diff, 64 * kEps * max_abs(z) * 100.0) << beta << " " << lag;
    }
  }
}

TEST(FastBlockHistory, ClearRestartsExactly) {
  const auto z = rough_blocks(400, 2, 4, 5u);
  auto h = make_fast_block_history(RungeKuttaCq{4, 1.3, 1}, 2, 400);
  Eigen::MatrixXd out(2, 4);
  std::vector<Eigen::MatrixXd> first;
  for (const auto& b : z) {
    h->push(b);
    h->sum(out);
    first.push_back(out);
  }
  h->clear();
  EXPECT_EQ(h->size(), 0u);
  for (std::size_t k = 0; k < z.size(); ++k) {
    h->push(z[k]);
    h->sum(out);
    ASSERT_TRUE((out.array() == first[k].array()).all()) << k;
  }
}

TEST(FastBlockHistory, MemoryIndependentOfN) {
  // The state is (2 n0 s + K) per degree of freedom plus the weights: no term grows with the
  // capacity except K, which grows like log N_max (the tail fit's K(N_max), rkcq_weights.md §10).
  for (const Eigen::Index d : {Eigen::Index{1}, Eigen::Index{3}}) {
    const RungeKuttaCq q{3, 0.5, 1};
    const auto small_ptr = make_fast_block_history(q, d, 1000);
    const auto large_ptr = make_fast_block_history(q, d, 10'000'000);
    const auto& small = dynamic_cast<const FastBlockHistory&>(*small_ptr);
    const auto& large = dynamic_cast<const FastBlockHistory&>(*large_ptr);
    const auto per_term = static_cast<std::size_t>(d + 2 * 3 + 1) * sizeof(double);
    EXPECT_EQ(large.memory_bytes() - small.memory_bytes(),
              (large.terms() - small.terms()) * per_term);
    EXPECT_LT(large.memory_bytes(), std::size_t{12'000} * static_cast<std::size_t>(d));
    std::printf(
        "d=%ld: memory_bytes %zu (N=1e3, K=%zu) vs %zu (N=1e7, K=%zu); direct at 1e7: %.2e\n",
        static_cast<long>(d), small.memory_bytes(), small.terms(), large.memory_bytes(),
        large.terms(), 8.0 * 1e7 * static_cast<double>(3 * d + 9));
  }
  // The direct history keeps every block and weight.
  DirectBlockHistory direct(RungeKuttaCq{3, 0.5}, 2, 1000);
  EXPECT_EQ(direct.memory_bytes(), 1000u * (2 * 3 + 9) * sizeof(double));
}

TEST(BlockHistory, NoAllocationInPushAndSum) {
  if (!FRACVI_COUNT_MALLOC) GTEST_SKIP() << "malloc interposition unavailable (sanitizer build)";
  for (const Eigen::Index d : {Eigen::Index{1}, Eigen::Index{40}}) {
    const auto z = rough_blocks(1000, d, 3, 11u);
    for (const HistoryKind kind : {HistoryKind::kDirect, HistoryKind::kFast}) {
      auto h = make_block_history(kind, RungeKuttaCq{3, 1.5, 1}, d, 1000);
      Eigen::MatrixXd out(d, 3);
      g_allocations = 0;
      g_counting = true;
      for (const auto& b : z) {  // across the switch-on of the tail at k = n0
        h->push(b);
        h->sum(out);
      }
      g_counting = false;
      EXPECT_EQ(g_allocations, 0u) << "d " << d << " " << to_string(kind);
    }
  }
  g_allocations = 0;
  g_counting = true;
  const Eigen::MatrixXd control = Eigen::MatrixXd::Ones(10, 10);
  g_counting = false;
  EXPECT_GT(g_allocations, 0u) << "the counter must see an Eigen allocation";
  EXPECT_EQ(control.size(), 100);
}

TEST(BlockHistory, FactoryAndArguments) {
  const RungeKuttaCq q{2, 0.5};
  EXPECT_NE(
      dynamic_cast<DirectBlockHistory*>(make_block_history(HistoryKind::kAuto, q, 1, 100).get()),
      nullptr);
  EXPECT_NE(
      dynamic_cast<FastBlockHistory*>(make_block_history(HistoryKind::kAuto, q, 1, 100'000).get()),
      nullptr);
  EXPECT_NE(
      dynamic_cast<FastBlockHistory*>(make_block_history(HistoryKind::kFast, q, 1, 100).get()),
      nullptr);
  EXPECT_FALSE(fast_block_history_pays(1000, 1, 3));
  EXPECT_TRUE(fast_block_history_pays(100'000, 1, 2));
  EXPECT_TRUE(fast_block_history_pays(kBlockFastHistoryCrossover, 1, 2));
  EXPECT_TRUE(fast_block_history_pays(1024, 100, 2));  // measured 0.016 s fast vs 0.038 s direct
  EXPECT_THROW(make_block_history(HistoryKind::kAuto, RungeKuttaCq{5, 0.5}, 1, 10),
               std::invalid_argument);
  EXPECT_THROW(make_block_history(HistoryKind::kAuto, q, 0, 10), std::invalid_argument);
  EXPECT_THROW(make_block_history(HistoryKind::kFast, q, 1, 0), std::invalid_argument);
  EXPECT_THROW(make_fast_block_history(RungeKuttaCq{2, std::nan("")}, 1, 10),
               std::invalid_argument);
  // A tail used beyond its range, or a lag outside its window, is refused.
  RkcqTailOptions o;
  o.stages = 3;
  o.order = 0.5;
  o.max_lag = 1000;
  const auto tail = shared_rkcq_tail(o);
  EXPECT_THROW(FastBlockHistory(tail, 0, 1, 1002), std::invalid_argument);
  EXPECT_THROW(FastBlockHistory(tail, 1, 1, 1001), std::invalid_argument);
  EXPECT_NO_THROW(FastBlockHistory(tail, 1, 1, 1000));
  EXPECT_THROW(FastBlockHistory(tail, o.window, 1, 10), std::invalid_argument);
  EXPECT_THROW(FastBlockHistory(nullptr, 0, 1, 10), std::invalid_argument);
  // RungeKuttaCq::lag shifts the weights.
  const RungeKuttaCq lagged{3, 0.5, 1};
  EXPECT_TRUE((lagged.weight(3).array() == RungeKuttaCq{3, 0.5}.weight(4).array()).all());
  EXPECT_NE(lagged.describe().find("from lag 1"), std::string::npos);
  // The cache: one tail for equal options.
  EXPECT_EQ(shared_rkcq_tail(o).get(), tail.get());
}

TEST(FastBlockHistory, TenMillionPushes) {
  // d = 1, s = 3, β = 0.5: the constant stage data 1 (the Heaviside function). The RKCQ step
  // response Σ_{j≤k} W_j 𝟙 approximates h^β D^β 1 = (t/h)^{−β}/Γ(1 − β) at the stage times
  // t/h = k + c_i (the discretisation gap decays with k). The fast sum adds at most the tail's
  // error ε s Σ_j max|W_j| max|Z| (absolute; the step response itself decays like k^{−β}, so
  // relative to it this bound grows like k^β). The run's time is measured.
  constexpr std::size_t kN = 10'000'000;
  constexpr double kTolerance = 1e-10;
  const int s = 3;
  const double beta = 0.5;
  const auto t0 = std::chrono::steady_clock::now();
  const auto h = make_fast_block_history(RungeKuttaCq{s, beta}, 1, kN, kTolerance);
  const double setup = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Σ_j max|W_j|: exactly up to J, beyond by the asymptotics max|W_j| ≈ j^{−1−β} max b/|Γ(−β)|
  // (rkcq_weights.md §3), doubled: Σ_{j≥J} ≤ 2 · (J − 1)^{−β}/β · max b/|Γ(−β)|.
  constexpr std::size_t kJ = 20'000;
  const BlockWeights w = RungeKuttaCq{s, beta}.weights(kJ);
  double weight_sum = 0.0;
  for (std::size_t j = 0; j < kJ; ++j) weight_sum += w[j].cwiseAbs().maxCoeff();
  weight_sum += 2.0 * std::pow(static_cast<double>(kJ - 1), -beta) / beta *
                lobatto_iiic(s).b.maxCoeff() / std::abs(std::tgamma(-beta));
  const double bound = kTolerance * s * weight_sum;
  const Eigen::MatrixXd ones = Eigen::MatrixXd::Ones(1, s);
  const Eigen::VectorXd c = lobatto_iiic(s).c;
  Eigen::MatrixXd out(1, s);
  struct Gap {
    std::size_t k;
    double relative, absolute;
  };
  std::vector<Gap> gaps;
  const auto t1 = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < kN; ++k) {
    h->push(ones);
    if (k + 1 == 10 || k + 1 == 1000 || k + 1 == 100'000 || k + 1 == kN) {
      h->sum(out);
      Gap g{k + 1, 0.0, 0.0};
      for (int i = 0; i < s; ++i) {
        const double exact =
            std::pow(static_cast<double>(k) + c(i), -beta) / std::tgamma(1.0 - beta);
        g.relative = std::max(g.relative, std::abs(out(0, i) / exact - 1.0));
        g.absolute = std::max(g.absolute, std::abs(out(0, i) - exact));
      }
      gaps.push_back(g);
    }
  }
  const double run = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  std::printf(
      "1e7 pushes d=1 s=3: setup (fit) %.2f s, run %.2f s (%.0f ns/push), memory %zu B, "
      "K = %zu\n",
      setup, run, 1e9 * run / static_cast<double>(kN), h->memory_bytes(),
      dynamic_cast<const FastBlockHistory&>(*h).terms());
  for (const auto& g : gaps) {
    std::printf("  k = %zu: gap to the continuous step response %.2e relative, %.2e absolute\n",
                g.k, g.relative, g.absolute);
  }
  std::printf("  a priori bound of the tail error (absolute): %.2e\n", bound);
  EXPECT_EQ(h->size(), kN);
  EXPECT_LT(h->memory_bytes(), std::size_t{12'000});
  EXPECT_LT(gaps[1].relative, gaps[0].relative);  // the discretisation gap decays
  // From k = 1000 on the discretisation gap is below 1e-10 relative (measured 8e-11 at 10^3,
  // 1e-11 at 10^5), ≪ the bound: what is left is the fast sum's error.
  for (std::size_t g = 1; g < gaps.size(); ++g) EXPECT_LE(gaps[g].absolute, bound) << gaps[g].k;
}

}  // namespace
}  // namespace fracvi
