// The `fvi-gl` and `fvi-bdf2` step split by rows over a team (CqMidpointStepper::step_by_rows,
// from IntegratorOptions::row_split_from degrees of freedom), on linear and β-FPUT chains:
//
//  * positions and velocities are the whole steps' bit for bit, on one thread, a team of two and
//    the timed choice; the diagnostics (energy, dissipated work, balance), formed part by part,
//    are the same bit for bit whatever the team and within round-off of the whole steps';
//  * a run that fails (the health check, a non-finite residual, a potential that throws) ends as
//    the whole steps' run does (status, message, step, stored rows);
//  * a checkpoint taken on a team of two resumes bit for bit on one thread or two, after each
//    push of the fast history's four-push cycle (and with Newton's kept Jacobian);
//  * the split is reported (summary's history_threads.whole_steps) and taken only where it
//    applies (fvi-gl or fvi-bdf2, diagonal M and R, the fast history; a linear chain's residual by
//    rows too, a nonlinear one's Newton solve on one thread).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "../support/test_potentials.hpp"
#include "../support/test_problems.hpp"
#include "fracvi/core/state_archive.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {
namespace {

using test::forced_chain;

IntegratorOptions options_for(int threads, Eigen::Index row_split_from) {
  IntegratorOptions o;
  o.history = HistoryKind::kFast;
  o.threads = threads;
  o.row_split_from = row_split_from;
  o.mirror = false;
  o.error_estimate = ErrorEstimateKind::kNone;
  return o;
}

constexpr Eigen::Index kNever = std::numeric_limits<Eigen::Index>::max();

template <class A>
bool same_bits(const A& a, const A& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), static_cast<std::size_t>(a.size()) * sizeof(double)) == 0;
}

Solution run(const InitialValueProblem& p, int threads, Eigen::Index row_split_from,
             const char* scheme = "fvi-gl") {
  return integrate(p, *parse_method(scheme), options_for(threads, row_split_from));
}

// d = 501: eight parts of whole vector groups (56 to 63 rows; the last has a remainder), two
// threads take four each, three take 2, 3 and 3; 300 steps fill the window (n0 = 16) and run
// many four-push passes.
// fvi-bdf2's memory sum has P's force added, on each part's rows: with Riemann–Liouville damping
// of order 0.6 both of its terms (x_0's and v_0's) are there. The β-FPUT chain's Newton solve
// (1–3 iterations a step, its Jacobian kept from step to step) runs on one thread.
TEST(StepByRows, PositionsAreTheWholeStepsBitForBitWhateverTheTeam) {
  struct Case {
    const char* scheme;
    bool unit_mass;
    double quartic;
  };
  for (const Case c : {Case{"fvi-gl", true, 0.0}, Case{"fvi-gl", false, 0.0},
                       Case{"fvi-bdf2", false, 0.0}, Case{"fvi-gl", false, 3.0}}) {
    const char* scheme = c.scheme;
    SCOPED_TRACE(std::string(scheme) + (c.unit_mass ? ", M = I" : ", diagonal M") +
                 (c.quartic != 0.0 ? ", β-FPUT" : ""));
    const bool bdf2 = std::string(scheme) == "fvi-bdf2";
    const InitialValueProblem p = forced_chain(
        501, c.unit_mass, 300, 0.5, 3.0, bdf2 ? Convention::kRiemannLiouville : Convention::kCaputo,
        bdf2 ? 0.3 : 0.75, c.quartic);
    const Solution whole = run(p, 1, kNever, scheme);
    ASSERT_EQ(whole.status, Status::kSuccess) << whole.message;
    EXPECT_FALSE(whole.history_threads.whole_steps);
    EXPECT_EQ(whole.history, "fast");
    const Solution one = run(p, 1, 64, scheme);
    for (const int threads : {1, 2, 3, 0}) {
      SCOPED_TRACE("threads = " + std::to_string(threads));
      const Solution split = threads == 1 ? one : run(p, threads, 64, scheme);
      ASSERT_EQ(split.status, Status::kSuccess) << split.message;
      EXPECT_TRUE(split.history_threads.whole_steps);
      EXPECT_EQ(split.history_threads.pushes, p.steps);
      if (threads == 2 || threads == 3) {
        EXPECT_EQ(split.history_threads.team, threads);
        EXPECT_EQ(split.history_threads.team_pushes, p.steps);
      } else if (threads == 1) {
        EXPECT_EQ(split.history_threads.team_pushes, 0u);
      }
      EXPECT_TRUE(same_bits(split.x, whole.x));
      EXPECT_TRUE(same_bits(split.v, whole.v));
      // The part-by-part sums: the same for every team.
      EXPECT_TRUE(same_bits(split.energy, one.energy));
      EXPECT_TRUE(same_bits(split.dissipated, one.dissipated));
      EXPECT_TRUE(same_bits(split.balance, one.balance));
      EXPECT_EQ(std::memcmp(&split.max_balance_error, &one.max_balance_error, sizeof(double)), 0);
    }
    // Against the whole passes' sums: round-off (|E| ≈ 30 here).
    double energy_difference = 0.0;
    for (Eigen::Index k = 0; k < whole.energy.size(); ++k) {
      energy_difference = std::max(energy_difference, std::abs(one.energy[k] - whole.energy[k]) /
                                                          std::max(1.0, std::abs(whole.energy[k])));
    }
    EXPECT_LE(energy_difference, 1e-14);
    EXPECT_NEAR(one.max_balance_error, whole.max_balance_error,
                1e-12 * std::max(1.0, whole.max_balance_error));
  }
}

// Runs that fail: an unstable potential (on-site stiffness −40, every mode grows like e^{6t};
// the health check stops it at step 62), a load that turns NaN at t = 1 (the Newton residual is
// not finite at step 10), and a nonlinear potential that throws at t = 1 (a callback error). Each
// ends as the whole steps' run does, on one thread and on two.
TEST(StepByRows, FailuresEndAsTheWholeStepsRunsDo) {
  InitialValueProblem nan_load = forced_chain(300, false, 30);
  nan_load.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f.setConstant(t > 1.0 ? std::numeric_limits<double>::quiet_NaN() : 0.1);
  };
  InitialValueProblem throwing =
      forced_chain(300, false, 30, 0.5, 3.0, Convention::kCaputo, 0.75, 1.0);
  throwing.model.potential =
      std::make_shared<const test::ThrowingAfter>(throwing.model.potential, 1.0);
  for (const InitialValueProblem& p :
       {forced_chain(300, false, 4000, -40.0, 400.0), nan_load, throwing}) {
    const Solution whole = run(p, 1, kNever);
    ASSERT_NE(whole.status, Status::kSuccess);
    for (const int threads : {1, 2}) {
      SCOPED_TRACE(whole.message + ", threads = " + std::to_string(threads));
      const Solution split = run(p, threads, 64);
      EXPECT_TRUE(split.history_threads.whole_steps);
      EXPECT_EQ(split.status, whole.status);
      EXPECT_EQ(split.message, whole.message);
      EXPECT_EQ(split.steps_done, whole.steps_done);
      EXPECT_TRUE(same_bits(split.x, whole.x));
      EXPECT_TRUE(same_bits(split.t, whole.t));
    }
  }
  EXPECT_EQ(run(throwing, 2, 64).status, Status::kCallbackError);
}

// Checkpoints after each push of the four-push cycle (and at the first step), written on a team
// of two, resumed on one thread and on two and as whole steps: the rest of the run bit for bit,
// linear and β-FPUT (whose Newton keeps its Jacobian from step to step: the checkpoint carries it;
// its team runs the history ahead by row groups, brought even for the checkpoint).
TEST(StepByRows, CheckpointsResumeBitForBitOnOneThreadOrTwo) {
  for (const double quartic : {0.0, 3.0}) {
    const InitialValueProblem p =
        forced_chain(300, false, 120, 0.5, 3.0, Convention::kCaputo, 0.75, quartic);
    const Method method = *parse_method("fvi-gl");
    const Solution reference = integrate(p, method, options_for(2, 64));
    ASSERT_EQ(reference.status, Status::kSuccess) << reference.message;
    for (const std::size_t k :
         {std::size_t{1}, std::size_t{40}, std::size_t{41}, std::size_t{42}, std::size_t{43}}) {
      Integrator writer_run(p, method, options_for(2, 64));
      for (std::size_t i = 0; i < k; ++i) ASSERT_EQ(writer_run.step(), Status::kRunning);
      StateWriter writer;
      writer_run.visit_state(writer);
      for (const int threads : {1, 2, -1}) {  // -1: whole steps on one thread
        SCOPED_TRACE("checkpoint after step " + std::to_string(k) + ", resumed on " +
                     std::to_string(threads));
        Integrator resumed(p, method,
                           threads < 0 ? options_for(1, kNever) : options_for(threads, 64));
        StateReader reader(writer.bytes(), "test state");
        resumed.visit_state(reader);
        reader.finish();
        resumed.run();
        const Solution s = resumed.take_solution();
        EXPECT_EQ(s.status, Status::kSuccess) << s.message;
        EXPECT_TRUE(same_bits(s.x, reference.x));
        EXPECT_TRUE(same_bits(s.v, reference.v));
        // (The whole steps' sums differ in their last bits.)
        if (threads > 0) {
          EXPECT_TRUE(same_bits(s.balance, reference.balance));
        }
        EXPECT_EQ(s.jacobian_factorizations, reference.jacobian_factorizations);
      }
    }
  }
}

// Where the split does not apply, the whole steps run (and say so): fvi-midpoint (implicit
// damping), the direct history, d below row_split_from; a nonlinear chain splits (Newton on one
// thread).
TEST(StepByRows, OnlyCqMidpointStepsWithTheFastHistorySplit) {
  const InitialValueProblem p = forced_chain(200, false, 40);
  EXPECT_TRUE(run(forced_chain(200, false, 40, 0.5, 3.0, Convention::kCaputo, 0.75, 1.0), 2, 64)
                  .history_threads.whole_steps);
  EXPECT_TRUE(run(p, 2, 64).history_threads.whole_steps);
  EXPECT_TRUE(run(p, 2, 64, "fvi-bdf2").history_threads.whole_steps);
  EXPECT_FALSE(run(p, 2, 64, "fvi-midpoint").history_threads.whole_steps);
  IntegratorOptions direct = options_for(2, 64);
  direct.history = HistoryKind::kDirect;
  EXPECT_FALSE(integrate(p, *parse_method("fvi-gl"), direct).history_threads.whole_steps);
  EXPECT_FALSE(run(p, 2, 201).history_threads.whole_steps);  // below row_split_from
  EXPECT_THROW(run(p, 2, 0), ValidationError);
}

}  // namespace
}  // namespace fracvi
