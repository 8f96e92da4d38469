// The step loop does not allocate (DESIGN §4; Drake's limit_malloc idea). This executable
// interposes malloc/calloc/realloc/aligned allocation (glibc exports the real ones as __libc_*);
// operator new and Eigen's aligned_malloc both end in malloc, so every heap allocation in the
// process is counted while counting is switched on.
//
// Covered: linear (constant Hessian, one solve per step) and nonlinear (Newton) paths, local
// (α = 1/2, 1), direct and fast (α = 0.75) histories, forcing, R = 0, a fixed-size autodiff
// potential, large FPUT chains on the banded path with OpenMP threads, a formula state force
// g(x, v, t), the Lobatto schemes with method.split = "series" and on a sparse chain, the block
// history's run-ahead thread. Control: a dynamic-size autodiff potential does allocate, so the
// counter is live.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdlib>

#include "../support/test_problems.hpp"
#include "fracvi/integrate/dense_output.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/memory/block_history.hpp"
#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "integrate_test_support.hpp"

// Interposes malloc for this executable (exactly one translation unit).
#include "../support/integrator_allocations.hpp"

namespace fracvi {
namespace {

using test::allocations_while_stepping;
using test::Duffing2;
using test::DuffingDynamic;

// The coupled pendula's M and R (test_problems.hpp) with their own forcing, 300 steps on [0, 2].
InitialValueProblem base(double alpha, std::shared_ptr<const Potential> potential) {
  InitialValueProblem p;
  p.model.mass = test::pendula_mass();
  p.model.damping = test::pendula_damping();
  p.model.alpha = alpha;
  p.model.potential = std::move(potential);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = std::sin(t);
    f(1) = 0.5;
  };
  p.x0 = Eigen::VectorXd{{1.2, -0.4}};
  p.v0 = Eigen::VectorXd{{0.5, 0.8}};
  p.t_end = 2.0;
  p.steps = 300;
  return p;
}

class NoAllocation : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!FRACVI_COUNT_MALLOC) GTEST_SKIP() << "malloc interposition unavailable (sanitizer build)";
  }
};

TEST_F(NoAllocation, LinearAlphaHalf) {
  Integrator integ(base(0.5, make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}})));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, NonlinearAlphaHalf) {
  Integrator integ(base(0.5, test::pendulum_pair()));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

// Dense output and events active: output times (one every few steps, off the grid) and formula
// events of the problem files' kind (expression tape), one of them crossing zero (root search on
// the interpolant, a recorded crossing within the reserved records).
TEST_F(NoAllocation, OutputTimesAndFormulaEvents) {
  IntegratorOptions options;
  for (int j = 0; j < 50; ++j) options.output_times.push_back(0.0389 * j + 0.0123);
  options.events = {
      formula_event("turn", "v1", 2, EventDirection::kBoth, false, "events[0].g"),
      formula_event("threshold", "x1 - 10", 2, EventDirection::kRising, false, "events[1].g")};
  Integrator integ(base(0.75, test::pendulum_pair()), fvi_gl(), options);
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
  EXPECT_GE(integ.solution().events.size(), 1u);  // the search did run
  EXPECT_EQ(integ.solution().output_t.size(), 50);
}

TEST_F(NoAllocation, NonlinearFractionalDirectHistory) {
  Integrator integ(base(0.75, test::pendulum_pair()));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, NonlinearFractionalFastHistory) {
  IntegratorOptions options;
  options.history = HistoryKind::kFast;
  Integrator integ(base(0.75, test::pendulum_pair()), fvi_gl(), options);
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, AlphaOneLocalHistory) {
  Integrator integ(base(1.0, test::pendulum_pair()));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, Conservative) {
  InitialValueProblem p = base(0.5, test::pendulum_pair());
  p.model.damping.dense().setZero();
  Integrator integ(p);
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, NoPotential) {
  Integrator integ(base(0.3, nullptr));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

TEST_F(NoAllocation, FixedSizeAutodiffPotential) {
  Integrator integ(base(0.75, make_autodiff_potential<2>(Duffing2{})));
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

// A non-conservative force g(x, v, t) from formulas (ExpressionForce): its tape evaluations, the
// Jacobians and the non-symmetric dense Newton matrix, for every scheme that takes it, with a
// fractional memory (fast history) and without damping.
TEST_F(NoAllocation, StateForceFormula) {
  for (const char* name : {"fvi-gl", "fvi-bdf2", "fvi-midpoint", "fvi-lobatto2", "fvi-lobatto3",
                           "fvi-lobatto4", "dopri5"}) {
    for (const double alpha : {0.5, 0.75}) {
      if (std::string(name) == "dopri5" && alpha != 0.5) continue;  // an ODE scheme
      InitialValueProblem p = base(alpha, test::pendulum_pair());
      p.model.state_force = std::make_shared<const ExpressionForce>(
          2, std::vector<std::string>{"0.8*(1 - x1^2)*v1 - 0.1*x2*v2", "-0.3*v1*v2 + sin(t)"});
      IntegratorOptions options;
      options.history = alpha == 0.5 ? HistoryKind::kAuto : HistoryKind::kFast;
      Integrator integ(p, *parse_method(name), options);
      EXPECT_EQ(allocations_while_stepping(integ), 0u) << name << " alpha = " << alpha;
    }
  }
}

// method.split = "series" (fvi_lobatto.md §13.3): the remainder's stepper with its power-law
// forcing by exact moments, and the state mapped back to x every step.
TEST_F(NoAllocation, LobattoSeriesSplit) {
  for (const char* name : {"fvi-lobatto2", "fvi-lobatto3", "fvi-lobatto4"}) {
    for (const double alpha : {0.3, 0.75}) {
      InitialValueProblem p =
          base(alpha, make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}}));
      p.model.forcing = nullptr;
      IntegratorOptions options;
      options.split = TaylorSplit::kSeries;
      Integrator integ(p, *parse_method(name), options);
      EXPECT_EQ(allocations_while_stepping(integ), 0u) << name << " alpha = " << alpha;
    }
  }
}

// Larger d: Eigen's blocked LU, matrix–vector products through GEMV kernels.
TEST_F(NoAllocation, NonlinearChainD40) {
  constexpr Eigen::Index kD = 40;
  InitialValueProblem p;
  Eigen::MatrixXd mass = Eigen::MatrixXd::Identity(kD, kD);
  mass.diagonal(1).setConstant(0.2);
  mass.diagonal(-1).setConstant(0.2);
  p.model.mass = mass;
  p.model.damping = 0.1 * mass;
  p.model.alpha = 0.75;
  p.model.potential =
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd::Constant(kD, 9.81), 3.0);
  p.x0 = Eigen::VectorXd::LinSpaced(kD, -1.0, 1.0);
  p.v0 = Eigen::VectorXd::Zero(kD);
  p.t_end = 1.0;
  p.steps = 50;
  Integrator integ(p);
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

// Large chains on the structured path: diagonal sparse M and R, the FPUT chain's tridiagonal
// Hessian, LAPACK's tridiagonal Cholesky, and OpenMP threads in the fast history ((K + n0)·d above
// kParallelWork) and in the chain's loops (d ≥ kChainParallelDofs). OpenMP starts its thread team
// during set-up (set_threads / the chain's constructor), so the steps allocate nothing.
InitialValueProblem large_chain(Eigen::Index d, std::size_t steps, int threads,
                                double quartic = 1.0) {
  InitialValueProblem p;
  p.model.mass = ModelMatrix::identity(d, 1.0);
  p.model.damping = ModelMatrix::identity(d, 0.1);
  p.model.alpha = 0.75;
  ChainOptions chain;
  chain.dimension = d;
  chain.quartic = quartic;
  chain.threads = threads;
  p.model.potential = make_chain_potential(chain);
  p.x0 = Eigen::VectorXd::LinSpaced(d, 0.0, 3.0).array().sin() * 0.3;
  p.v0 = Eigen::VectorXd::Zero(d);
  p.t_end = 0.5;
  p.steps = steps;
  return p;
}

// threads = 2: a fixed team; threads = 0: the history times its pushes and switches between one
// thread and the team (internal::TeamChooser) — 200 steps cover both trials and the restart when
// the window fills, so the team's first region comes inside the step loop (it found start_threads
// doing nothing: 3 allocations). threads = 0 first: the team a run starts lives on in the process.
TEST_F(NoAllocation, BandedChainWithThreadedFastHistory) {
  for (const int threads : {0, 2}) {
    IntegratorOptions options;
    options.history = HistoryKind::kFast;
    options.threads = threads;
    Integrator integ(large_chain(8000, 200, 1), fvi_gl(), options);
    ASSERT_EQ(integ.linear_solver(), LinearSolver::kBanded);
    EXPECT_EQ(allocations_while_stepping(integ), 0u) << "threads = " << threads;
  }
}

// The chain's step split by rows over the threads (CqMidpointStepper::step_by_rows): one parallel
// region a step, OpenMP's team started at set-up; threads = 0 switches between one thread and
// the team. Linear (the residual by rows) and β-FPUT (Newton on one thread, refactoring its
// banded Jacobian in the counted steps).
TEST_F(NoAllocation, ChainStepByRows) {
  for (const double quartic : {0.0, 1.0}) {
    for (const int threads : {0, 2, 1}) {
      IntegratorOptions options;
      options.history = HistoryKind::kFast;
      options.threads = threads;
      options.row_split_from = 1000;
      Integrator integ(large_chain(4000, 200, 1, quartic), fvi_gl(), options);
      EXPECT_EQ(allocations_while_stepping(integ), 0u)
          << "threads = " << threads << ", quartic = " << quartic;
      const Solution solution = integ.take_solution();
      EXPECT_TRUE(solution.history_threads.whole_steps) << "threads = " << threads;
      if (quartic != 0.0) {
        EXPECT_GE(solution.jacobian_factorizations, 1u);
      }
    }
  }
}

// The Lobatto schemes' block history on a team of two: its second thread runs the next push's
// recursions and older window (internal/run_ahead.hpp), started by set_threads; threads = 0 also
// times its pushes and switches.
TEST_F(NoAllocation, BlockHistoryRunAhead) {
  const Eigen::Index d = 700;  // d (K(2s + 1) + n0 s²) ≥ kRunAheadWork
  for (const int s : {2, 3, 4}) {
    for (const int threads : {0, 2}) {
      const auto history = make_fast_block_history(RungeKuttaCq{s, 0.75, 1}, d, 200);
      history->set_threads(threads);
      Eigen::MatrixXd block = Eigen::MatrixXd::Ones(d, s), sum(d, s);
      g_allocations = 0;
      g_counting = true;
      for (int k = 0; k < 200; ++k) {
        block *= -0.99;
        history->push(block);
        history->sum(sum);
      }
      g_counting = false;
      EXPECT_EQ(g_allocations, 0u) << "s = " << s << ", threads = " << threads;
    }
  }
}

// The Lobatto schemes on a sparse system ((s − 1)d > 96), on one thread and with the history's
// run-ahead thread. Sparse LU (forced) on the linear chain, factored once at set-up: Eigen's
// SparseLU solve allocated a work vector and a permutation mask on every call before StageMatrix
// took it step by step. Band LU (kAuto's choice for the chain) on the β-FPUT chain, whose stage
// matrix (s ≥ 3: with the internal stages' Hessians) is first factored in the first step and
// again whenever Newton's kept matrix stops contracting: LAPACK's dgbtrf works in the storage sized
// at set-up. Control: the same β-FPUT runs with sparse LU forced allocate (SparseLU's factorize
// and setFromTriplets size their storage on every call; kAuto takes it only for wide bands).
TEST_F(NoAllocation, LobattoSparseChain) {
  struct Case {
    double quartic;
    LinearSolver solver;
    bool allocates;
  };
  for (const Case c :
       {Case{0.0, LinearSolver::kSparse, false}, Case{1.0, LinearSolver::kAuto, false},
        Case{1.0, LinearSolver::kSparse, true}}) {
    for (const char* name : {"fvi-lobatto2", "fvi-lobatto3", "fvi-lobatto4"}) {
      const bool refactors = c.quartic > 0.0 && std::string(name) != "fvi-lobatto2";
      if (c.allocates && !refactors) continue;
      for (const int threads : {1, 0, 2}) {
        IntegratorOptions options;
        options.history = HistoryKind::kFast;
        options.threads = threads;
        options.linear_solver = c.solver;
        Integrator integ(large_chain(600, 60, 1, c.quartic), *parse_method(name), options);
        ASSERT_EQ(integ.linear_solver(),
                  c.solver == LinearSolver::kAuto ? LinearSolver::kBanded : c.solver)
            << name;
        const std::size_t allocations = allocations_while_stepping(integ);
        if (c.allocates) {
          EXPECT_GT(allocations, 0u) << name << ", threads = " << threads;
        } else {
          EXPECT_EQ(allocations, 0u)
              << name << ", threads = " << threads << ", quartic = " << c.quartic;
        }
        // The factorisation happened inside the counted steps (the constructor factors only a
        // linear stage system).
        if (refactors) {
          EXPECT_GE(integ.take_solution().jacobian_factorizations, 1u) << name;
        }
      }
    }
  }
}

// A periodic chain (bandwidth d − 1): the midpoint schemes' Newton matrix takes the sparse LDLᵀ,
// refactored in the counted steps (nonlinear U). Its permuted matrix is built once and Eigen's
// numeric factorisation runs on it directly (symmetric_factor.cpp): Eigen's own factorize
// allocated a permuted copy on every call, and its solve allocated too (113 allocations in these
// 30 steps at d = 600, 126 at d = 20000, with Eigen's factorize and solve). Beyond d = 16384 the
// factorisation's work vector of d doubles passes the 128 KB Eigen takes from the stack and comes
// from the heap: one allocation per factorisation up to d = 32768 (its two vectors of d ints
// beyond), counted exactly — which is also the control that the counter sees this path.
TEST_F(NoAllocation, PeriodicChainSparseLdlt) {
  auto periodic = [](Eigen::Index d) {
    InitialValueProblem p = large_chain(d, 30, 1);
    p.model.potential = test::periodic_fput_chain(d);
    return p;
  };
  for (const char* name : {"fvi-gl", "fvi-bdf2", "fvi-midpoint"}) {
    for (const Eigen::Index d : {600, 20000}) {
      IntegratorOptions options;
      options.history = HistoryKind::kFast;
      options.threads = 1;
      Integrator integ(periodic(d), *parse_method(name), options);
      ASSERT_EQ(integ.linear_solver(), LinearSolver::kSparse) << name;
      const std::size_t allocations = allocations_while_stepping(integ);
      const std::size_t factorizations = integ.take_solution().jacobian_factorizations;
      std::printf("  %s, d = %ld: %zu allocations, %zu factorisations\n", name,
                  static_cast<long>(d), allocations, factorizations);
      EXPECT_GE(factorizations, 1u) << name;
      EXPECT_EQ(allocations, d <= 16384 ? 0u : factorizations) << name << ", d = " << d;
    }
  }
}

// The fused element passes of the CQ midpoint schemes and of fvi-midpoint (diagonal M and R',
// d ≥ kVectorPassesFrom; solve/vector_passes.hpp), with diagnostics and the step sums.
TEST_F(NoAllocation, FusedChainPassesPerScheme) {
  for (const char* name : {"fvi-gl", "fvi-bdf2", "fvi-midpoint"}) {
    IntegratorOptions options;
    options.history = HistoryKind::kFast;
    options.threads = 1;
    Integrator integ(large_chain(200, 60, 1), *parse_method(name), options);
    EXPECT_EQ(allocations_while_stepping(integ), 0u) << name;
  }
}

TEST_F(NoAllocation, ThreadedChainPotential) {
  IntegratorOptions options;
  options.history = HistoryKind::kFast;
  options.threads = 2;
  options.save_every = 10;
  Integrator integ(large_chain(kChainParallelDofs + 100, 30, 2), fvi_gl(), options);
  ASSERT_EQ(integ.linear_solver(), LinearSolver::kBanded);
  EXPECT_EQ(allocations_while_stepping(integ), 0u);
}

// Control: the counter sees allocations — a dynamic-size autodiff potential allocates in every
// evaluation (documented in autodiff_potential.hpp).
TEST_F(NoAllocation, ControlDynamicAutodiffAllocates) {
  Integrator integ(base(0.5, make_autodiff_potential(DuffingDynamic{}, 2)));
  EXPECT_GT(allocations_while_stepping(integ), 300u);
}

}  // namespace
}  // namespace fracvi
