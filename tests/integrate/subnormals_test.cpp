// Subnormal numbers flushed to zero while stepping (IntegratorOptions::flush_subnormals,
// internal/float_environment.hpp): the guard sets and restores only FTZ and DAZ; on a chain whose
// localised pulse keeps positions and history states below DBL_MIN, flushing changes the
// trajectory only far below DBL_MIN's neighbourhood of the solution, the library's threads (the
// history's run-ahead thread, the mirror run alongside) compute with the caller's setting, and
// the caller's setting is the same after the run as before it.
#include <gtest/gtest.h>

#include <bit>
#include <cfenv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <thread>
#include <utility>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/internal/float_environment.hpp"
#include "fracvi/model/chain_potential.hpp"

namespace fracvi {
namespace {

using internal::flush_bits;
using internal::kCanFlushSubnormals;
using internal::kFlushSubnormalBits;
using internal::SubnormalsFlushed;

constexpr double kMinNormal = std::numeric_limits<double>::min();  // DBL_MIN

// Half of DBL_MIN computed at run time (volatile: not folded by the compiler, which rounds in
// gradual underflow whatever the thread's MXCSR).
double half_of_min_normal() {
  volatile double m = kMinNormal;
  volatile double half = m * 0.5;
  return half;
}

TEST(SubnormalsFlushed, SetsAndRestoresOnlyTheTwoBits) {
  if (!kCanFlushSubnormals) GTEST_SKIP() << "no flush-to-zero control on this architecture";
  ASSERT_EQ(flush_bits(), 0U) << "the test process starts with gradual underflow";
  EXPECT_GT(half_of_min_normal(), 0.0);
  std::feclearexcept(FE_ALL_EXCEPT);
  {
    const SubnormalsFlushed flushed(true);
    EXPECT_EQ(flush_bits(), kFlushSubnormalBits);
    EXPECT_EQ(half_of_min_normal(), 0.0);  // FTZ: the subnormal result is 0
    {
      const SubnormalsFlushed nested(true);  // already flushing: left as it is
      EXPECT_EQ(flush_bits(), kFlushSubnormalBits);
    }
    EXPECT_EQ(flush_bits(), kFlushSubnormalBits);
    volatile double zero = 0.0;
    volatile double infinite = 1.0 / zero;  // raises the sticky divide-by-zero flag
    EXPECT_TRUE(std::isinf(infinite));
  }
  EXPECT_EQ(flush_bits(), 0U);
  EXPECT_GT(half_of_min_normal(), 0.0);
  EXPECT_TRUE(std::fetestexcept(FE_DIVBYZERO)) << "the flags raised inside are the caller's";
  {
    const SubnormalsFlushed kept(false);
    EXPECT_EQ(flush_bits(), 0U);
  }
  std::feclearexcept(FE_ALL_EXCEPT);
}

// A chain at rest with a narrow pulse in the middle (examples/fractional_chain.toml's initial
// position): its flanks exp(−((i − d/2)/15)²) pass through the subnormal range near |i − d/2| ≈
// 400, and the implicit step spreads tiny values into the rest. d = 1000 with the fast history's
// recursions on two threads when asked (above kRunAheadWork). The chain is linear: `height`
// scales the whole solution.
InitialValueProblem pulse_chain(double height = 1.0, Eigen::Index d = 1000) {
  InitialValueProblem p;
  p.model.mass = ModelMatrix::identity(d, 1.0);
  p.model.damping = ModelMatrix::identity(d, 0.05);
  p.model.alpha = 0.75;  // damping order 1.5
  p.model.convention = Convention::kCaputo;
  ChainOptions chain;
  chain.dimension = d;
  chain.stiffness = 1.0;
  chain.onsite = 0.1;
  p.model.potential = make_chain_potential(chain);
  p.x0.resize(d);
  for (Eigen::Index i = 0; i < d; ++i) {
    const double r = (static_cast<double>(i) - static_cast<double>(d) / 2.0) / 15.0;
    p.x0[i] = height * std::exp(-r * r);
  }
  p.v0 = Eigen::VectorXd::Zero(d);
  p.t_end = 0.3;
  p.steps = 300;
  return p;
}

IntegratorOptions pulse_options(bool flush, int threads) {
  IntegratorOptions o;
  o.history = HistoryKind::kFast;
  o.history_tolerance = 1e-10;
  o.mirror = false;
  o.flush_subnormals = flush;
  o.threads = threads;
  return o;
}

int subnormal_count(const Eigen::Ref<const Eigen::MatrixXd>& values) {
  return static_cast<int>((values.array() != 0.0 && values.array().abs() < kMinNormal).count());
}

TEST(FlushSubnormals, ChangesThePulseChainOnlyBelowTheSubnormalScale) {
  if (!kCanFlushSubnormals) GTEST_SKIP() << "no flush-to-zero control on this architecture";
  const InitialValueProblem p = pulse_chain();
  ASSERT_EQ(flush_bits(), 0U);
  const Solution kept = integrate(p, fvi_gl(), pulse_options(false, 1));
  EXPECT_EQ(flush_bits(), 0U);
  const Solution flushed = integrate(p, fvi_gl(), pulse_options(true, 1));
  EXPECT_EQ(flush_bits(), 0U) << "the caller's setting after the run";
  ASSERT_TRUE(kept.ok()) << kept.message;
  ASSERT_TRUE(flushed.ok()) << flushed.message;
  // The run met subnormals (kept: stored positions below DBL_MIN; flushed: none computed) and the
  // two settings differ, so the comparison below is not of identical runs.
  const int kept_subnormals = subnormal_count(kept.x.bottomRows(kept.x.rows() - 1));
  const int flushed_subnormals = subnormal_count(flushed.x.bottomRows(flushed.x.rows() - 1));
  std::printf("  subnormal positions after step 0: %d kept, %d flushed\n", kept_subnormals,
              flushed_subnormals);
  EXPECT_GT(kept_subnormals, 0);
  EXPECT_EQ(flushed_subnormals, 0);
  EXPECT_FALSE((kept.x.array() == flushed.x.array()).all());
  // Each flush changes a number by less than DBL_MIN; the differences it leaves in the O(1)
  // solution stay within 10^6 DBL_MIN (measured 1.0e-303 and 4.4e-303: ≈ 2·10^4 DBL_MIN, about the
  // memory weights' scale h^−1.5 ≈ 3·10^4), 290 orders of magnitude below its round-off.
  const double dx = (kept.x - flushed.x).cwiseAbs().maxCoeff();
  const double dv = (kept.v - flushed.v).cwiseAbs().maxCoeff();
  std::printf("  max |x_kept - x_flushed| = %.3e, max |v_kept - v_flushed| = %.3e (DBL_MIN %.3e)\n",
              dx, dv, kMinNormal);
  EXPECT_LT(dx, 1e6 * kMinNormal);
  EXPECT_LT(dv, 1e6 * kMinNormal);
  EXPECT_EQ(std::bit_cast<std::uint64_t>(kept.max_balance_error),
            std::bit_cast<std::uint64_t>(flushed.max_balance_error));
}

// The library's threads compute with the caller's setting: a team gives one thread's numbers bit
// for bit, flushed or not — two threads at d = 1000 (the history's run-ahead thread), three at
// d = 12000 (OpenMP's team for the history and the chain's force, above kParallelWork; the pulse
// is in the middle third, a worker's rows). Without the hand-over of the bits a team's rows kept
// their subnormals while the caller's were flushed, and the runs differed (checked for both).
TEST(FlushSubnormals, ATeamComputesOneThreadsNumbers) {
  for (const auto& [d, threads] : {std::pair<Eigen::Index, int>{1000, 2}, {12000, 3}}) {
    const InitialValueProblem p = pulse_chain(1.0, d);
    for (const bool flush : {true, false}) {
      const Solution one = integrate(p, fvi_gl(), pulse_options(flush, 1));
      const Solution team = integrate(p, fvi_gl(), pulse_options(flush, threads));
      ASSERT_TRUE(one.ok()) << one.message;
      ASSERT_TRUE(team.ok()) << team.message;
      ASSERT_EQ(team.history_threads.team, threads) << "the team took part";
      EXPECT_GT(team.history_threads.team_pushes, 0U);
      EXPECT_TRUE((one.x.array() == team.x.array()).all()) << "flush " << flush << ", d " << d;
      EXPECT_TRUE((one.v.array() == team.v.array()).all()) << "flush " << flush << ", d " << d;
    }
  }
}

// The mirror run alongside the run (its own thread) and after it (the caller's) compute with the
// run's setting: the same mirror error bit for bit. The pulse is 1e-296 high, so that the mirror
// error (≈ 1e-13 of the solution's size) is itself below DBL_MIN and shows the setting that
// computed it (at height 1 a mirror run that kept subnormals gave the flushed error bit for bit).
TEST(FlushSubnormals, MirrorAlongsideAndAfterAgree) {
  const InitialValueProblem p = pulse_chain(1e-296);
  for (const bool flush : {true, false}) {
    IntegratorOptions after = pulse_options(flush, 0);
    after.mirror = true;
    IntegratorOptions alongside = after;
    alongside.mirror_alongside = true;
    const Solution a = integrate(p, fvi_gl(), after);
    const Solution b = integrate(p, fvi_gl(), alongside);
    ASSERT_TRUE(a.ok()) << a.message;
    ASSERT_TRUE(b.ok()) << b.message;
    EXPECT_EQ(b.mirror_alongside, std::thread::hardware_concurrency() >= 2);
    ASSERT_TRUE(std::isfinite(a.mirror_error));
    std::printf("  flush %d: mirror_error %.6e after, %.6e alongside\n", flush ? 1 : 0,
                a.mirror_error, b.mirror_error);
    EXPECT_EQ(std::bit_cast<std::uint64_t>(a.mirror_error),
              std::bit_cast<std::uint64_t>(b.mirror_error))
        << "flush " << flush << ": " << a.mirror_error << " after, " << b.mirror_error
        << " alongside";
  }
  EXPECT_EQ(flush_bits(), 0U);
}

}  // namespace
}  // namespace fracvi
