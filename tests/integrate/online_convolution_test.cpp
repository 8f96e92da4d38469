// OnlineConvolution (the FFT-blocked memory sums of Hairer, Lubich & Schlichte) against the direct
// lower-triangular Toeplitz sums, evaluated independently in long double; pi-trapezoid's whole
// trajectories with the FFT history against its direct history; and no allocation in commit().
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <vector>

#include "../support/test_problems.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/memory/online_convolution.hpp"
#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/schemes/registry.hpp"

// Interposes malloc for this executable (exactly one translation unit; after the other headers).
#include "../support/allocation_counter.hpp"

namespace fracvi {
namespace {

RowMatrixXd random_values(Eigen::Index rows, Eigen::Index d, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  RowMatrixXd values(rows, d);
  for (Eigen::Index i = 0; i < rows; ++i)
    for (Eigen::Index c = 0; c < d; ++c) values(i, c) = normal(gen);
  return values;
}

// Product-integration-like weights m^{γ−1} (γ = 0.6: decaying; γ = 1.5: growing) and signed
// random weights, over capacities that end inside a block, with a series offset `first`.
TEST(OnlineConvolution, MatchesTheDirectSumsToRoundOff) {
  struct Case {
    const char* name;
    std::size_t capacity;
    Eigen::Index first;
    double power;  // w_m = (m + 1)^(power − 1); 0: random signed weights
  };
  for (const Case& c : {Case{"power 0.6", 3000, 1, 0.6}, Case{"power 1.5", 4096, 0, 1.5},
                        Case{"random signed", 1500, 2, 0.0}, Case{"tiny", 3, 0, 1.5}}) {
    const Eigen::Index d = 3;
    Eigen::VectorXd w(static_cast<Eigen::Index>(c.capacity));
    std::mt19937_64 gen(7);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    for (Eigen::Index m = 0; m < w.size(); ++m) {
      const double lag = static_cast<double>(m);
      w[m] = c.power == 0.0 ? uniform(gen) : std::pow(lag + 1.0, c.power - 1.0);
    }
    const RowMatrixXd values =
        random_values(c.first + static_cast<Eigen::Index>(c.capacity), d, 11);
    OnlineConvolution online(w, d, c.capacity, c.first);
    double worst = 0.0;
    for (std::size_t n = 0; n < c.capacity; ++n) {
      ASSERT_EQ(online.committed(), n);
      for (Eigen::Index col = 0; col < d; ++col) {
        long double exact = 0.0L, magnitude = 0.0L;
        for (std::size_t j = 0; j < n; ++j) {
          const long double term = static_cast<long double>(w[static_cast<Eigen::Index>(n - j)]) *
                                   values(c.first + static_cast<Eigen::Index>(j), col);
          exact += term;
          magnitude += std::fabs(term);
        }
        if (n == 0) {
          EXPECT_EQ(online.pending(0)(col), 0.0);
          continue;
        }
        const double error =
            static_cast<double>(std::fabs(online.pending(n)(col) - exact) / magnitude);
        worst = std::max(worst, error);
      }
      online.commit(n, values);
    }
    std::printf("[measured] %s, capacity %zu: max |s_n - direct| / sum |terms| = %.2e\n", c.name,
                c.capacity, worst);
    EXPECT_LE(worst, 1e-14) << c.name;
  }
}

TEST(OnlineConvolution, RefusesBadArgumentsAndOutOfOrderCommits) {
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(10);
  EXPECT_THROW(OnlineConvolution(w, 0, 10), std::invalid_argument);
  EXPECT_THROW(OnlineConvolution(w, 1, 0), std::invalid_argument);
  EXPECT_THROW(OnlineConvolution(w, 1, 11), std::invalid_argument);  // weights short
  OnlineConvolution online(w, 1, 10);
  const RowMatrixXd values = RowMatrixXd::Ones(10, 1);
  EXPECT_THROW(online.commit(1, values), std::logic_error);
}

TEST(OnlineConvolution, CommitDoesNotAllocate) {
  if (!FRACVI_COUNT_MALLOC) GTEST_SKIP() << "malloc interposition unavailable (sanitizer build)";
  constexpr std::size_t kCapacity = 5000;  // FFT levels 64 … 4096
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(kCapacity, 1.0, 2.0);
  const RowMatrixXd values = random_values(kCapacity, 4, 3);
  OnlineConvolution online(w, 4, kCapacity);
  g_allocations = 0;
  g_counting = true;
  for (std::size_t n = 0; n < kCapacity; ++n) online.commit(n, values);
  g_counting = false;
  EXPECT_EQ(g_allocations, 0u);
}

// pi-trapezoid: the FFT history ("fast") against the direct sums on whole trajectories of a
// forced nonlinear (Duffing) oscillator, 2α = 0.6 and 1.5, N = 20000, and a 2-DOF linear problem
// with full M and R; "auto" takes the FFT sums from 512 steps.
InitialValueProblem two_dof(double alpha, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{2.0, 0.3}, {0.3, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.5, -0.1}, {-0.1, 0.3}};
  p.model.alpha = alpha;
  p.model.convention = Convention::kCaputo;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}});
  p.x0 = Eigen::VectorXd{{1.0, -0.5}};
  p.v0 = Eigen::VectorXd{{0.2, 0.4}};
  p.t_end = 50.0;
  p.steps = steps;
  return p;
}

Solution run_pi(const InitialValueProblem& p, HistoryKind kind) {
  IntegratorOptions o;
  o.history = kind;
  o.mirror = false;
  o.newton.relative_tolerance = 1e-14;
  return integrate(p, *parse_method("pi-trapezoid"), o);
}

// The criterion of the issue for a fast history (1e-10 relative on N = 2·10^4), and a sharper one:
// no more than three times what changing x0 by one ulp does to the direct run (the forced Duffing
// oscillator amplifies round-off: 1.7e-11 at 2α = 0.6; the linear 2-DOF problem 1.9e-13).
TEST(PiTrapezoidFftHistory, WholeTrajectoriesAgreeWithTheDirectSums) {
  for (double alpha : {0.3, 0.75}) {
    for (const InitialValueProblem& p :
         {test::forced_duffing(alpha, 20000), two_dof(alpha, 5000)}) {
      const Solution direct = run_pi(p, HistoryKind::kDirect);
      const Solution fft = run_pi(p, HistoryKind::kFast);
      ASSERT_TRUE(direct.ok() && fft.ok()) << direct.message << fft.message;
      EXPECT_EQ(direct.history, "direct");
      EXPECT_EQ(fft.history, "fft");
      InitialValueProblem nudged = p;
      nudged.x0(0) = std::nextafter(p.x0(0), 2.0 * p.x0(0));
      const Solution ulp = run_pi(nudged, HistoryKind::kDirect);
      const double scale = direct.x.cwiseAbs().maxCoeff();
      const double dx = (fft.x - direct.x).cwiseAbs().maxCoeff() / scale;
      const double dulp = (ulp.x - direct.x).cwiseAbs().maxCoeff() / scale;
      const double dv = (fft.v - direct.v).cwiseAbs().maxCoeff() / direct.v.cwiseAbs().maxCoeff();
      const double dw = std::abs(fft.dissipated.tail(1)(0) - direct.dissipated.tail(1)(0)) /
                        std::max(1.0, std::abs(direct.dissipated.tail(1)(0)));
      std::printf(
          "[measured] pi-trapezoid, d = %td, alpha = %.2f, N = %zu: fft vs direct x %.2e (x0 + 1 "
          "ulp: %.2e), v %.2e, W %.2e; wall %.3f s (fft) vs %.3f s (direct)\n",
          p.model.dimension(), alpha, p.steps, dx, dulp, dv, dw, fft.wall_time_seconds,
          direct.wall_time_seconds);
      EXPECT_LE(std::max({dx, dv, dw}), 1e-10);
      EXPECT_LE(dx, 3.0 * dulp);
    }
  }
}

TEST(PiTrapezoidFftHistory, AutoTakesTheFftSumsFrom512Steps) {
  EXPECT_EQ(run_pi(test::forced_duffing(0.75, 511), HistoryKind::kAuto).history, "direct");
  const Solution automatic = run_pi(test::forced_duffing(0.75, 512), HistoryKind::kAuto);
  EXPECT_EQ(automatic.history, "fft");
  EXPECT_EQ((automatic.x - run_pi(test::forced_duffing(0.75, 512), HistoryKind::kFast).x)
                .cwiseAbs()
                .maxCoeff(),
            0.0);
}

}  // namespace
}  // namespace fracvi
