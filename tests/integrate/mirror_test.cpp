// Test 6: the mirror equation (`DiscEqs`, second line), solved backwards from y_N = x_0,
// y_{N−1} = x_1 in its own (second-difference, forward-running-sum) form, reproduces x reversed:
// y_k = x_{N−k} to round-off, for α = 1/2 (Lemma 5.3) and fractional α (0.3, 0.75; Caputo with
// x_0, v_0 ≠ 0, so the mirrored Caputo shift is exercised), on a nonlinear, forced problem.
#include <gtest/gtest.h>

#include <atomic>
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/internal/background_thread.hpp"
#include "fracvi/schemes/registry.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

using test::kEps;

constexpr std::size_t kN = 400;

InitialValueProblem problem(double alpha, Convention convention, Eigen::VectorXd x0) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
  p.model.alpha = alpha;
  p.model.convention = convention;
  p.model.potential =
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = 0.1 * t;
  };
  p.x0 = std::move(x0);
  p.v0 = Eigen::VectorXd{{0.5, 0.8}};
  p.t_end = 4.0;
  p.steps = kN;
  return p;
}

IntegratorOptions tight(HistoryKind history = HistoryKind::kAuto) {
  IntegratorOptions o;
  o.newton.relative_tolerance = 1e-14;
  o.history = history;
  return o;
}

// Round-off budget: both runs round the positions at every step (ε‖x‖ each) and their Newton
// iterations stop at round-off (quadratic convergence below the 1e-14 tolerance). These
// independent rounding errors propagate through the N steps of a damped, stable two-step
// recursion and accumulate like a random walk: bound 16ε · √N · max‖x‖ (≈ 7e-14 for N = 400,
// ‖x‖ ≈ 1.2). Measured: 0.6–0.9e-14 (printed).
double mirror_tolerance(const Solution& sol) {
  return 16.0 * kEps * std::sqrt(static_cast<double>(kN)) * sol.x.cwiseAbs().maxCoeff();
}

struct Case {
  double alpha;
  Convention convention;
  HistoryKind history;
  const char* label;
};

class Mirror : public ::testing::TestWithParam<Case> {};

TEST_P(Mirror, BackwardRunReproducesReversedTrajectory) {
  const Case c = GetParam();
  const Solution sol = integrate(problem(c.alpha, c.convention, Eigen::VectorXd{{1.2, -0.4}}),
                                 fvi_gl(), tight(c.history));
  ASSERT_TRUE(sol.ok()) << sol.message;
  const double tol = mirror_tolerance(sol);
  std::printf("  %s: mirror_error = %.3e (tolerance %.3e)\n", c.label, sol.mirror_error, tol);
  EXPECT_LE(sol.mirror_error, tol);
}

INSTANTIATE_TEST_SUITE_P(
    Alphas, Mirror,
    ::testing::Values(
        Case{0.5, Convention::kCaputo, HistoryKind::kAuto, "alpha 0.5 (Lemma 5.3)"},
        Case{0.5, Convention::kCaputo, HistoryKind::kDirect, "alpha 0.5, direct history"},
        Case{0.3, Convention::kCaputo, HistoryKind::kAuto, "alpha 0.3 Caputo"},
        Case{0.75, Convention::kCaputo, HistoryKind::kAuto, "alpha 0.75 Caputo"},
        Case{0.3, Convention::kRiemannLiouville, HistoryKind::kAuto, "alpha 0.3 Riemann-Liouville"},
        Case{1.0, Convention::kCaputo, HistoryKind::kAuto, "alpha 1 Caputo"}));

// Negative control: the mirror error is not zero by construction. With a tolerance so loose that
// Newton stops after its first correction, each run keeps its own (different) iteration error in
// the step equations (the x-run in momentum form, the y-run in second-difference form), and the
// reported error grows far above round-off (measured 3.3e-8).
TEST(MirrorControl, LooseNewtonToleranceIsVisible) {
  IntegratorOptions loose;
  loose.newton.relative_tolerance = 0.5;
  const Solution sol =
      integrate(problem(0.75, Convention::kCaputo, Eigen::VectorXd{{1.2, -0.4}}), fvi_gl(), loose);
  ASSERT_TRUE(sol.ok());
  std::printf("  loose Newton (one correction per step): mirror_error = %.3e\n", sol.mirror_error);
  EXPECT_GT(sol.mirror_error, 100.0 * mirror_tolerance(sol));
}

TEST(MirrorControl, CanBeSkipped) {
  IntegratorOptions o;
  o.mirror = false;
  const Solution sol =
      integrate(problem(0.75, Convention::kCaputo, Eigen::VectorXd{{1.2, -0.4}}), fvi_gl(), o);
  ASSERT_TRUE(sol.ok());
  EXPECT_TRUE(std::isnan(sol.mirror_error));
}

// The mirror run alongside the run (IntegratorOptions::mirror_alongside): started after the first
// step on a second thread, it keeps y at the stored steps, and take_solution() compares: the same
// mirror error bit for bit as the mirror run after the run, and the same trajectory, for every
// scheme with a mirror run (the midpoint schemes start from x_0, x_1; the Lobatto FVIs from x_0,
// v_0; the series split shifts y), with strides that divide N and that do not (the last row).
struct AlongsideCase {
  const char* scheme;
  std::size_t every;
  bool series;
};

class MirrorAlongside : public ::testing::TestWithParam<AlongsideCase> {};

TEST_P(MirrorAlongside, SameMirrorErrorAsAfterTheRun) {
  // One hardware thread: the mirror run goes after the run, and the test checks that path.
  const bool two_threads = std::thread::hardware_concurrency() >= 2;
  const AlongsideCase c = GetParam();
  InitialValueProblem p = problem(0.75, Convention::kCaputo, Eigen::VectorXd{{1.2, -0.4}});
  IntegratorOptions after = tight();
  after.save_every = c.every;
  if (c.series) {
    // The series split is for linear problems with a power-law forcing only.
    p.model.forcing = nullptr;
    p.model.potential = make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}});
    after.split = TaylorSplit::kSeries;
  }
  IntegratorOptions alongside = after;
  alongside.mirror_alongside = true;
  const Method method = *parse_method(c.scheme);
  const Solution a = integrate(p, method, after);
  const Solution b = integrate(p, method, alongside);
  ASSERT_TRUE(a.ok()) << a.message;
  ASSERT_TRUE(b.ok()) << b.message;
  EXPECT_FALSE(a.mirror_alongside);
  EXPECT_EQ(b.mirror_alongside, two_threads);
  std::printf("  %s every %zu%s: mirror_error %.3e after, %.3e alongside\n", c.scheme, c.every,
              c.series ? " series" : "", a.mirror_error, b.mirror_error);
  ASSERT_TRUE(std::isfinite(a.mirror_error));
  EXPECT_LT(a.mirror_error, 1e-10);  // round-off, not a failed check
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.mirror_error),
            std::bit_cast<std::uint64_t>(b.mirror_error));
  EXPECT_TRUE((a.x.array() == b.x.array()).all());
}

INSTANTIATE_TEST_SUITE_P(Schemes, MirrorAlongside,
                         ::testing::Values(AlongsideCase{"fvi-gl", 1, false},
                                           AlongsideCase{"fvi-gl", 7, false},
                                           AlongsideCase{"fvi-bdf2", 1, false},
                                           AlongsideCase{"fvi-midpoint", 1, false},
                                           AlongsideCase{"fvi-midpoint", 7, false},
                                           AlongsideCase{"fvi-lobatto3", 1, false},
                                           AlongsideCase{"fvi-lobatto3", 7, false},
                                           AlongsideCase{"fvi-lobatto3", 3, true}));

// A potential that forwards to `inner` and, for every gradient asked on a thread other than the
// one that built it, first calls `elsewhere` (the mirror run alongside asks on its own thread).
class OnOtherThreads final : public Potential {
 public:
  OnOtherThreads(std::shared_ptr<const Potential> inner, std::function<void()> elsewhere)
      : inner_(std::move(inner)),
        elsewhere_(std::move(elsewhere)),
        owner_(std::this_thread::get_id()) {}
  [[nodiscard]] Eigen::Index dimension() const override { return inner_->dimension(); }
  [[nodiscard]] bool has_constant_hessian() const override {
    return inner_->has_constant_hessian();
  }
  [[nodiscard]] bool is_time_dependent() const override { return inner_->is_time_dependent(); }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    return inner_->value(x, t);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    if (std::this_thread::get_id() != owner_) elsewhere_();
    inner_->gradient(x, t, g);
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> h) const override {
    inner_->hessian(x, t, h);
  }

 private:
  std::shared_ptr<const Potential> inner_;
  std::function<void()> elsewhere_;
  std::thread::id owner_;
};

// An interrupt while take_solution() waits for the mirror run alongside: the wait asks the hook
// (on the calling thread), the mirror run stops at its next step, and the run is reported
// interrupted with its whole trajectory, as for a signal during the mirror run after the run.
TEST(MirrorAlongsideControl, InterruptDuringTheWaitKeepsTheTrajectory) {
  // One hardware thread: the mirror run goes after the run, and the test checks that path.
  const bool two_threads = std::thread::hardware_concurrency() >= 2;
  InitialValueProblem p = problem(0.75, Convention::kCaputo, Eigen::VectorXd{{1.2, -0.4}});
  // Slow on the mirror thread: the mirror run alongside ends long after the run.
  p.model.potential = std::make_shared<const OnOtherThreads>(
      p.model.potential, [] { std::this_thread::sleep_for(std::chrono::microseconds(500)); });
  IntegratorOptions o = tight();
  o.mirror_alongside = true;
  // The run asks before each of its kN steps; from then on (the wait) the answer is yes.
  auto calls = std::make_shared<std::atomic<std::size_t>>(0);
  o.interrupt = [calls] { return calls->fetch_add(1) >= kN; };
  const auto start = std::chrono::steady_clock::now();
  const Solution sol = integrate(p, fvi_gl(), o);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(sol.status, Status::kInterrupted) << sol.message;
  EXPECT_EQ(sol.mirror_alongside, two_threads);
  EXPECT_EQ(sol.steps_done, kN);
  EXPECT_TRUE(std::isnan(sol.mirror_error));
  EXPECT_TRUE(sol.x.allFinite());
  EXPECT_NE(sol.message.find("interrupted during the mirror check"), std::string::npos)
      << sol.message;
  // ≥ 2 kN gradients at 0.5 ms each on the mirror thread: ≥ 0.4 s uninterrupted.
  std::printf("  interrupted after %.3f s\n", seconds);
  EXPECT_LT(seconds, 0.3);
}

// The mirror run alongside runs kBackgroundNice below the run's priority (background_thread.hpp),
// so that the run keeps its core; the run's own thread keeps its priority.
TEST(MirrorAlongsideControl, RunsBelowTheRunsPriority) {
  if (std::thread::hardware_concurrency() < 2)
    GTEST_SKIP() << "one hardware thread: no mirror thread";
  const std::optional<int> before = internal::this_thread_nice();
  ASSERT_TRUE(before.has_value());
  InitialValueProblem p = problem(0.75, Convention::kCaputo, Eigen::VectorXd{{1.2, -0.4}});
  // The largest nice value of the threads other than this one that ask for a gradient.
  std::mutex mutex;
  std::optional<int> elsewhere;
  p.model.potential = std::make_shared<const OnOtherThreads>(p.model.potential, [&] {
    const std::optional<int> nice = internal::this_thread_nice();
    const std::lock_guard<std::mutex> lock(mutex);
    if (nice && (!elsewhere || *nice > *elsewhere)) elsewhere = nice;
  });
  IntegratorOptions o = tight();
  o.mirror_alongside = true;
  const Solution sol = integrate(p, fvi_gl(), o);
  ASSERT_TRUE(sol.ok()) << sol.message;
  ASSERT_TRUE(sol.mirror_alongside);
  ASSERT_TRUE(elsewhere.has_value()) << "no gradient on the mirror thread";
  EXPECT_EQ(*elsewhere, std::min(*before + internal::kBackgroundNice, 19));
  if (*before < 19) {
    EXPECT_GT(*elsewhere, *before);
  }
  EXPECT_EQ(internal::this_thread_nice(), before);
}

}  // namespace
}  // namespace fracvi
