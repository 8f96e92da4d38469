// The measured thread count of the fast histories' push (internal/team_chooser.hpp):
//  * the trial / hold cycle of TeamChooser on synthetic call times and periods (which count it
//    picks, when it measures again, the untimed warm-up calls, the trials' minimum time, the two
//    guards against a team slower than one thread, that a requested count is used as given);
//  * the choice never changes a result: FastHistory and FastBlockHistory sums with threads = 0
//    (measured: one thread for the first trial's calls, the team for the second's, then the
//    faster) are bitwise those of threads = 1 and of a fixed team of 2, over pushes that cover
//    both trials; and both histories' run-ahead thread (internal/run_ahead.hpp) gives the
//    one-thread sums for any split of the rows, through checkpoints and clear().
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/internal/cpu_placement.hpp"
#include "fracvi/internal/run_ahead_balance.hpp"
#include "fracvi/internal/team_chooser.hpp"
#include "fracvi/memory/block_history.hpp"
#include "fracvi/memory/fast_history.hpp"

namespace fracvi {
namespace {

using internal::TeamChooser;
constexpr int kTrial = TeamChooser::kTrialCalls;
constexpr int kTimed = TeamChooser::kTrialCalls - TeamChooser::kWarmCalls;

// Runs one trial cycle with the given per-call times (each trial until its end, at most 10^6
// calls); returns the count chosen for the hold. `team_calls`, if given: the team trial's calls.
int trial(TeamChooser& team, double one_thread_seconds, double team_seconds,
          int* team_calls = nullptr) {
  EXPECT_TRUE(team.in_trial());
  int calls = 0;
  for (; team.next() == 1 && calls < 1'000'000; ++calls) team.record(one_thread_seconds);
  EXPECT_GE(calls, kTrial) << "the one-thread trial";
  int on_team = 0;
  for (; team.in_trial() && on_team < 1'000'000; ++on_team) {
    EXPECT_EQ(team.next(), team.team()) << "call " << on_team << " of the team trial";
    team.record(team_seconds);
  }
  if (team_calls != nullptr) *team_calls = on_team;
  return team.next();
}

TEST(TeamChooser, PicksTheFasterCountAndMeasuresAgainAfterTheHold) {
  TeamChooser team;
  team.configure(0, 2);
  ASSERT_TRUE(team.measuring());
  int team_calls = 0;
  EXPECT_EQ(trial(team, 1e-3, 0.6e-3, &team_calls), 2);  // the team is faster: held on 2 threads
  EXPECT_EQ(team_calls, kTrial);
  // The first hold lasts max(0.5 s, 8 × the trials' timed 2 × 14 calls, 22.4 ms) = 0.5 s.
  EXPECT_GT(TeamChooser::kHoldSeconds, TeamChooser::kFirstHoldTrials * kTimed * 1.6e-3);
  const auto hold_calls = [&](double hold, double seconds, int count) {
    const int calls = static_cast<int>(hold / seconds);
    for (int i = 0; i < calls - 1; ++i) {
      ASSERT_EQ(team.next(), count) << "hold call " << i;
      ASSERT_FALSE(team.in_trial()) << "hold call " << i;
      team.record(seconds);
    }
    team.record(2 * seconds);  // the hold is over
    EXPECT_TRUE(team.in_trial());
  };
  hold_calls(TeamChooser::kHoldSeconds, 0.6e-3, 2);
  // Trials again: the team is still faster, and the second hold lasts max(0.5 s, 32 × 22.4 ms)
  // = 0.72 s.
  EXPECT_EQ(trial(team, 1e-3, 0.6e-3), 2);
  hold_calls(TeamChooser::kHoldTrials * kTimed * 1.6e-3, 0.6e-3, 2);
  // Trials again, and now the machine is busy.
  EXPECT_EQ(trial(team, 1e-3, 5e-3), 1);
  EXPECT_EQ(team.decisions(), 3u);
  EXPECT_EQ(team.team_won(), 2u);
  EXPECT_EQ(team.team_dropped(), 0u);
}

TEST(TeamChooser, WarmUpCallsAreNotTimedAndRestartMeasuresAgain) {
  TeamChooser team;
  team.configure(0, 2);
  // The team's first calls are slow (a thread wakes, data move between caches), the rest fast.
  for (int i = 0; i < kTrial; ++i) team.record(1e-3);
  for (int i = 0; i < kTrial; ++i) team.record(i < TeamChooser::kWarmCalls ? 50e-3 : 0.5e-3);
  EXPECT_EQ(team.next(), 2);
  EXPECT_FALSE(team.in_trial());
  // Negative control: the same slow call after the warm-up counts.
  team.restart();
  EXPECT_EQ(team.next(), 1);
  for (int i = 0; i < kTrial; ++i) team.record(1e-3);
  for (int i = 0; i < kTrial; ++i) team.record(i == TeamChooser::kWarmCalls ? 50e-3 : 0.5e-3);
  EXPECT_EQ(team.next(), 1);
}

TEST(TeamChooser, ShortCallsAreTriedForTwoMillisecondsAndHeldForHalfASecond) {
  TeamChooser team;
  team.configure(0, 4);
  // 20 µs calls: the one-thread trial needs 100 timed calls (2 ms) besides its 2 warm-up calls.
  int team_calls = 0;
  EXPECT_EQ(trial(team, 20e-6, 19e-6, &team_calls), 4);
  EXPECT_EQ(team_calls, TeamChooser::kWarmCalls + 106) << "2 ms of 19 µs calls (the sum rounds)";
  team.restart();
  EXPECT_EQ(trial(team, 20e-6, 30e-6, &team_calls), 1);
  // Guard (1): the team's calls took longer than one thread's 100 after 67 of its own.
  EXPECT_EQ(team_calls, TeamChooser::kWarmCalls + 67);
  // One thread for the hold and then for the next one-thread trial, until the team's trial.
  int calls = 0;
  while (team.next() == 1 && calls < 1'000'000) {
    team.record(20e-6);
    ++calls;
  }
  // The hold ends once 0.5 s (not 32 × 3.3 ms) has been held: 25 000 calls of 20 µs (to one call:
  // the sum of the times rounds), then the 102 calls of the next one-thread trial.
  EXPECT_NEAR(calls - (TeamChooser::kWarmCalls + 100), TeamChooser::kHoldSeconds / 20e-6, 1.0);
  EXPECT_EQ(team.next(), 4);
}

// A virtual machine whose second core is taken away in bursts (steal time): the team's trial can
// fall between bursts and its hold then run far slower than one thread. Guard (1) ends a losing
// team trial early; guard (2) gives the rest of a hold to one thread once the held team's mean is
// above the one-thread trial's.
TEST(TeamChooser, ATeamSlowerThanOneThreadLosesItsTrialAndItsHold) {
  {
    TeamChooser team;
    team.configure(0, 2);
    int team_calls = 0;
    // 20 times slower: lost at the first timed call (20 ms > the 14 ms of one thread's trial).
    EXPECT_EQ(trial(team, 1e-3, 20e-3, &team_calls), 1);
    EXPECT_EQ(team_calls, TeamChooser::kWarmCalls + 1);
  }
  // A team of two that won its trial (0.6 ms against 1 ms a call) and then held `calls` calls of
  // `seconds` each, every one of them on the team.
  const auto held_team = [](int calls, double seconds) {
    TeamChooser team;
    team.configure(0, 2);
    EXPECT_EQ(trial(team, 1e-3, 0.6e-3), 2);
    for (int i = 0; i < calls; ++i) {
      EXPECT_EQ(team.next(), 2) << "hold call " << i;
      team.record(seconds);
    }
    return team;
  };
  const auto hold_after_burst = [&](double burst_seconds) {
    TeamChooser team = held_team(200, 0.6e-3);
    team.record(burst_seconds);  // the other core was taken away for this call
    return team.next();
  };
  // 200 calls of 0.6 ms and one of 100 ms: a mean of 1.09 ms against one thread's 1 ms.
  EXPECT_EQ(hold_after_burst(100e-3), 1);
  // Negative control: a burst of 70 ms leaves the mean at 0.945 ms, and the team keeps the hold.
  EXPECT_EQ(hold_after_burst(70e-3), 2);
  {
    // Held calls steadily slower than the team's trial but faster than one thread: kept for the
    // whole (first) hold (0.5 s: 526 calls of 0.95 ms).
    TeamChooser kept = held_team(520, 0.95e-3);
    EXPECT_EQ(kept.next(), 2);
    EXPECT_EQ(kept.team_dropped(), 0u);
    // Held calls slower than one thread: one thread from the kTrial-th on, for as long again as
    // the team was held but at least 4 × the trials' 22.4 ms, and then trials again (not for the
    // rest of the 0.5 s hold).
    TeamChooser slow = held_team(kTrial, 1.2e-3);
    EXPECT_EQ(slow.next(), 1);
    EXPECT_FALSE(slow.in_trial());
    EXPECT_EQ(slow.team_dropped(), 1u);
    int calls = 0;
    for (; !slow.in_trial() && calls < 1'000'000; ++calls) slow.record(1e-3);
    EXPECT_NEAR(calls, TeamChooser::kRetryTrials * kTimed * 1.6e-3 / 1e-3, 1.0);
    // A team held longer before a slow spell: 200 calls of 0.6 ms (120 ms), then calls of 4 ms
    // until the mean passes one thread's 1 ms (27 of them): one thread for as long again
    // (228 ms), more than 4 × 22.4 ms and less than the 0.5 s hold's remaining 272 ms.
    TeamChooser spell = held_team(200, 0.6e-3);
    double held = 200 * 0.6e-3;
    int slow_calls = 0;
    for (; spell.next() == 2 && slow_calls < 1000; ++slow_calls) {
      spell.record(4e-3);
      held += 4e-3;
    }
    EXPECT_EQ(slow_calls, 27) << "the mean passes 1 ms at the 27th call of 4 ms";
    calls = 0;
    for (; !spell.in_trial() && calls < 1'000'000; ++calls) spell.record(1e-3);
    EXPECT_NEAR(calls, held / 1e-3, 1.0);
    // Then the team is tried again, and wins again once the spell has passed.
    EXPECT_EQ(trial(spell, 1e-3, 0.6e-3), 2);
    EXPECT_EQ(spell.decisions(), 2u);
    EXPECT_EQ(spell.team_won(), 2u);
    EXPECT_EQ(spell.team_dropped(), 1u);
  }
}

TEST(TeamChooser, RequestedCountsAndSmallWorkAreNotMeasured) {
  TeamChooser team;
  team.configure(3, 3);
  EXPECT_FALSE(team.measuring());
  EXPECT_FALSE(team.in_trial());
  EXPECT_EQ(team.next(), 3);
  team.configure(0, 1);  // below the work threshold
  EXPECT_FALSE(team.measuring());
  EXPECT_EQ(team.next(), 1);
  team.configure(1, 1);
  EXPECT_FALSE(team.measuring());
  EXPECT_EQ(team.next(), 1);
}

// A caller timed by period (FastHistory with its run-ahead thread): each period is attributed to
// the count of the call that started it. Synthetic clock: a call on the team returns sooner (its
// own time would favour the team), but the period until the next call is longer (the overlap slows
// the caller's step) — the period decides.
TEST(TeamChooser, PeriodsDecideForCallersTimedByPeriod) {
  using Clock = std::chrono::steady_clock;
  // The counts of the first `calls` calls, and the count after them.
  const auto choose = [](double one_period, double team_period, int calls) {
    TeamChooser team;
    team.configure(0, 2);
    Clock::time_point now = Clock::now();
    std::vector<int> counts;
    for (int i = 0; i < calls + 1; ++i) {
      const int threads = team.next_by_period(now);
      counts.push_back(threads);
      now += std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(threads == 1 ? one_period : team_period));
    }
    return counts;
  };
  // The trials run one thread, then the team, each for kTrial calls; the team's steps are faster.
  std::vector<int> counts = choose(1e-3, 0.6e-3, 2 * kTrial);
  for (int i = 0; i < 2 * kTrial; ++i) EXPECT_EQ(counts[i], i < kTrial ? 1 : 2) << "call " << i;
  EXPECT_EQ(counts.back(), 2);
  // The team's steps are slower: its trial is lost after 12 timed periods (14.4 ms > 14 ms).
  counts = choose(1e-3, 1.2e-3, 2 * kTrial);
  const int lost_after = kTrial + TeamChooser::kWarmCalls + 12;
  for (int i = 0; i < 2 * kTrial; ++i) {
    EXPECT_EQ(counts[i], i < kTrial || i >= lost_after ? 1 : 2) << "call " << i;
  }
  EXPECT_EQ(counts.back(), 1);
  // Negative control: only the first period of each trial differs (a warm-up call), not counted.
  TeamChooser team;
  team.configure(0, 2);
  Clock::time_point now = Clock::now();
  for (int i = 0; i < 2 * kTrial; ++i) {
    const int threads = team.next_by_period(now);
    const bool first_of_trial = i == 0 || i == kTrial;
    now += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
        first_of_trial ? (threads == 1 ? 1e-3 : 50e-3) : (threads == 1 ? 1e-3 : 0.5e-3)));
  }
  EXPECT_EQ(team.next_by_period(now), 2);
}

Eigen::MatrixXd rough_input(Eigen::Index rows, Eigen::Index columns) {
  std::mt19937_64 gen(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd xs(rows, columns);
  for (Eigen::Index k = 0; k < columns; ++k)
    for (Eigen::Index i = 0; i < rows; ++i) xs(i, k) = normal(gen) + 0.01 * static_cast<double>(k);
  return xs;
}

bool bitwise_equal(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::equal(a.data(), a.data() + a.size(), b.data());
}

// 3 trials' worth of pushes: the measured history runs some on one thread and some on the team.
constexpr int kPushes = 3 * kTrial;

TEST(TeamChooser, FastHistorySumsDoNotDependOnTheChoice) {
  // d (K + n0) ≥ kParallelWork, so that threads = 0 measures.
  const Eigen::Index d = 6000;
  const Eigen::MatrixXd xs = rough_input(d, kPushes);
  std::vector<Eigen::MatrixXd> sums;
  for (const int threads : {1, 2, 0}) {
    FastHistory history(1.5, d, 1 << 12);
    history.set_threads(threads);
    Eigen::MatrixXd out(d, kPushes);
    Eigen::VectorXd s(d);
    for (int k = 0; k < kPushes; ++k) {
      history.push(xs.col(k));
      history.sum(s);
      out.col(k) = s;
    }
    sums.push_back(out);
    // What the history reports of its thread use (summary.json's history_threads).
    const HistoryThreads use = history.report().threads;
    EXPECT_EQ(use.pushes, static_cast<std::size_t>(kPushes)) << threads;
    EXPECT_EQ(use.measured, threads == 0) << threads;
    if (threads == 1) {
      EXPECT_EQ(use.team, 1);
      EXPECT_EQ(use.team_pushes, 0u);
    } else if (threads == 2) {
      EXPECT_EQ(use.team, 2);
      EXPECT_EQ(use.team_pushes, static_cast<std::size_t>(kPushes));
    } else if (use.team > 1) {
      // One thread until the window is full (16 pushes) and for the first trial's calls after
      // it (the trial restarts at the 17th push, whose period counts as its first call; the
      // kTrial-th call's push already goes to the team): at least 16 + kTrial − 1 pushes.
      EXPECT_LE(use.team_pushes, static_cast<std::size_t>(kPushes - (16 + kTrial - 1)));
      EXPECT_LE(use.team_won, use.decisions);
      EXPECT_LE(use.decisions, 1u);
    }
  }
  EXPECT_TRUE(bitwise_equal(sums[0], sums[1])) << "1 thread against a team of 2";
  EXPECT_TRUE(bitwise_equal(sums[0], sums[2])) << "1 thread against the measured choice";
  // A system too small for a team (d < 4 pushes without the choice) counts its pushes too.
  FastHistory small(1.5, 1, 1 << 12);
  small.set_threads(0);
  for (int k = 0; k < kPushes; ++k) small.push(xs.col(k).head(1));
  const HistoryThreads use = small.report().threads;
  EXPECT_EQ(use.pushes, static_cast<std::size_t>(kPushes));
  EXPECT_EQ(use.team, 1);
  EXPECT_EQ(use.team_pushes, 0u);
}

// A team of two runs the recursions of the next push ahead on its second thread
// (fast_history.hpp): a checkpoint taken then records them as done ("fast.ahead"), and a history
// restored from it — on one thread or two — continues bit for bit like the uninterrupted run;
// clear() waits for them and starts afresh.
TEST(TeamChooser, FastHistoryRunAheadSurvivesCheckpointsAndClear) {
  const Eigen::Index d = 6000;
  const int pushes = 80, saved_after = 40;
  const Eigen::MatrixXd xs = rough_input(d, pushes);
  auto run = [&](FastHistory& history, int from, int to, Eigen::MatrixXd& out) {
    Eigen::VectorXd s(d);
    for (int k = from; k < to; ++k) {
      history.push(xs.col(k));
      history.sum(s);
      out.col(k) = s;
    }
  };
  Eigen::MatrixXd reference(d, pushes);
  {
    FastHistory one(1.5, d, 1 << 12);
    one.set_threads(1);
    run(one, 0, pushes, reference);
  }
  FastHistory two(1.5, d, 1 << 12);
  two.set_threads(2);
  Eigen::MatrixXd first_part(d, pushes);
  run(two, 0, saved_after, first_part);
  EXPECT_TRUE(bitwise_equal(first_part.leftCols(saved_after), reference.leftCols(saved_after)));
  StateWriter writer;
  two.visit_state(writer);
  for (const int threads : {1, 2}) {
    FastHistory restored(1.5, d, 1 << 12);
    restored.set_threads(threads);
    StateReader reader(writer.bytes(), "test state");
    restored.visit_state(reader);
    reader.finish();
    Eigen::MatrixXd rest(d, pushes);
    run(restored, saved_after, pushes, rest);
    EXPECT_TRUE(bitwise_equal(rest.rightCols(pushes - saved_after),
                              reference.rightCols(pushes - saved_after)))
        << "restored on " << threads << " thread(s)";
  }
  two.clear();
  Eigen::MatrixXd again(d, pushes);
  run(two, 0, pushes, again);
  EXPECT_TRUE(bitwise_equal(again, reference)) << "after clear()";
}

// The split of the next push between the run-ahead thread and the caller
// (internal/run_ahead_balance.hpp), steered by synthetic times: a caller whose step takes C and
// whose share of r rows (of d) costs c per row arrives after C + (d − r)c, the thread finishes
// after r·c. Balance: r = (C/c + d)/2.
struct SimulatedStep {
  double caller_seconds, per_row;
  Eigen::Index rows;
  // (the thread's job time, the caller's arrival minus the thread's finish) for a share.
  [[nodiscard]] std::pair<double, double> times(Eigen::Index share) const {
    const double job = per_row * static_cast<double>(share);
    const double arrival = caller_seconds + per_row * static_cast<double>(rows - share);
    return {job, arrival - job};
  }
};

TEST(RunAheadBalance, ConvergesToTheBalancedSplitAndStaysThere) {
  constexpr Eigen::Index kGrain = internal::RunAheadBalance::kGrain;
  const SimulatedStep step{50e-6, 20e-9, 10000};  // balance at (2500 + 10000)/2 = 6250 rows
  internal::RunAheadBalance balance;
  balance.configure(step.rows, true, 0);
  ASSERT_TRUE(balance.balanced());
  EXPECT_EQ(balance.rows(), step.rows) << "starts with every row on the thread";
  int steps = 0;
  for (; steps < 100 && std::abs(balance.rows() - 6250) > kGrain; ++steps) {
    const auto [job, slack] = step.times(balance.rows());
    balance.record(job, slack);
    EXPECT_EQ(balance.rows() % kGrain, 0);
  }
  EXPECT_LE(steps, 12) << "half-way steps, at most d/8 each";
  for (int i = 0; i < 50; ++i) {
    const auto [job, slack] = step.times(balance.rows());
    balance.record(job, slack);
    ASSERT_LE(std::abs(balance.rows() - 6250), kGrain) << "step " << i << " after convergence";
  }
  // One disturbed step (the caller preempted for a second) moves the split by at most d/8.
  const Eigen::Index before = balance.rows();
  balance.record(step.times(before).first, 1.0);
  EXPECT_LE(balance.rows() - before, step.rows / 8 + kGrain);
  EXPECT_LT(balance.rows(), step.rows) << "not every row on the thread after one step";
}

TEST(RunAheadBalance, ALongCallerStepLeavesEveryRowToTheThread) {
  // C/c = 30 000 > d: the thread's whole share ends before the caller arrives.
  const SimulatedStep step{600e-6, 20e-9, 10000};
  internal::RunAheadBalance balance;
  balance.configure(step.rows, true, 0);
  for (int i = 0; i < 30; ++i) {
    const auto [job, slack] = step.times(balance.rows());
    balance.record(job, slack);
    ASSERT_EQ(balance.rows(), step.rows);
  }
  // A thread 1000 times slower (a shared core): balance at (C/c + d)/1001 ≈ 10 rows, so the caller
  // takes nearly every row (the rule's half steps assume equal speeds and stop within a step of
  // two grains here).
  const SimulatedStep slow{10e-6, 20e-9, 10000};
  for (int i = 0; i < 60; ++i) {
    const auto [job, slack] = slow.times(balance.rows());
    balance.record(1000.0 * job, slack - 999.0 * job);
  }
  EXPECT_LE(balance.rows(), 2 * internal::RunAheadBalance::kGrain);
}

TEST(RunAheadBalance, FixedSharesAndSmallSystemsAreNotBalanced) {
  internal::RunAheadBalance balance;
  balance.configure(10000, false, 3000);
  EXPECT_FALSE(balance.balanced());
  balance.record(1e-3, 1.0);
  EXPECT_EQ(balance.rows(), 3000);
  balance.configure(10000, false, 20000);
  EXPECT_EQ(balance.rows(), 10000) << "clamped to the rows there are";
  balance.configure(100, true, 0);  // fewer than two grains: nothing to balance
  EXPECT_FALSE(balance.balanced());
  EXPECT_EQ(balance.rows(), 0) << "unbalanced with share 0 as given";
  balance.configure(100, true, 100);
  EXPECT_EQ(balance.rows(), 100);
  // Times that say nothing leave the split alone.
  balance.configure(10000, true, 0);
  balance.record(0.0, -1.0);
  balance.record(std::nan(""), -1.0);
  balance.record(1e-4, std::nan(""));
  EXPECT_EQ(balance.rows(), 10000);
}

// Any split of a push between the run-ahead thread and the caller gives the one-thread sums bit
// for bit — shares that are not whole grains, that change from push to push, none for the caller,
// and the balanced default (back-to-back pushes: the caller arrives early and takes rows) — and a
// checkpoint taken with a split share restores to the same continuation.
TEST(TeamChooser, FastHistoryRunAheadSplitsDoNotChangeTheSums) {
  const Eigen::Index d = 3000;
  const int pushes = 60, saved_after = 37;
  const Eigen::MatrixXd xs = rough_input(d, pushes);
  Eigen::MatrixXd reference(d, pushes);
  Eigen::VectorXd s(d);
  {
    FastHistory one(1.5, d, 1 << 12);
    one.set_threads(1);
    for (int k = 0; k < pushes; ++k) {
      one.push(xs.col(k));
      one.sum(s);
      reference.col(k) = s;
    }
  }
  const std::vector<Eigen::Index> fixed = {1, 64, 1000, 2999, 3000, 5000};
  for (const Eigen::Index rows : {Eigen::Index{-1}, Eigen::Index{0}, Eigen::Index{1},
                                  Eigen::Index{777}, Eigen::Index{2999}}) {
    FastHistory two(1.5, d, 1 << 12);
    two.set_threads(2);
    two.set_run_ahead_rows(std::max<Eigen::Index>(rows, 0));
    Eigen::MatrixXd out(d, pushes);
    StateWriter writer;
    for (int k = 0; k < pushes; ++k) {
      if (rows < 0) two.set_run_ahead_rows(fixed[static_cast<std::size_t>(k) % fixed.size()]);
      two.push(xs.col(k));
      two.sum(s);
      out.col(k) = s;
      if (k + 1 == saved_after) two.visit_state(writer);
    }
    EXPECT_TRUE(bitwise_equal(out, reference)) << "run-ahead rows " << rows;
    EXPECT_GE(two.run_ahead_rows(), 1);
    EXPECT_LE(two.run_ahead_rows(), d);
    FastHistory restored(1.5, d, 1 << 12);
    restored.set_threads(2);
    StateReader reader(writer.bytes(), "test state");
    restored.visit_state(reader);
    reader.finish();
    for (int k = saved_after; k < pushes; ++k) {
      restored.push(xs.col(k));
      restored.sum(s);
      out.col(k) = s;
    }
    EXPECT_TRUE(bitwise_equal(out, reference)) << "restored, run-ahead rows " << rows;
  }
  FastHistory history(1.5, d, 1 << 12);
  EXPECT_THROW(history.set_run_ahead_rows(-1), std::invalid_argument);
}

TEST(TeamChooser, FastBlockHistorySumsDoNotDependOnTheChoice) {
  const Eigen::Index d = 1500;  // d (K(2s + 1) + n0 s²) ≥ kParallelWork for s = 3
  const int s = 3;
  const Eigen::MatrixXd xs = rough_input(d, kPushes * s);
  std::vector<Eigen::MatrixXd> sums;
  for (const int threads : {1, 2, 0}) {
    const auto history = make_fast_block_history(RungeKuttaCq{s, 0.5, 1}, d, 1 << 12);
    history->set_threads(threads);
    Eigen::MatrixXd out(d, kPushes * s);
    Eigen::MatrixXd block(d, s);
    for (int k = 0; k < kPushes; ++k) {
      history->push(xs.middleCols(k * s, s));
      history->sum(block);
      out.middleCols(k * s, s) = block;
    }
    sums.push_back(out);
  }
  EXPECT_TRUE(bitwise_equal(sums[0], sums[1])) << "1 thread against a team of 2";
  EXPECT_TRUE(bitwise_equal(sums[0], sums[2])) << "1 thread against the measured choice";
}

// FastBlockHistory runs ahead like FastHistory (internal/run_ahead.hpp): for s = 2, 3, 4 stages,
// any split of the next push between the run-ahead thread and the caller — fixed shares, shares
// changing from push to push, the balanced default — gives the one-thread sums bit for bit; a
// checkpoint taken while a push ran ahead ("block_fast.ahead") — by the run-ahead thread, or by one
// thread's pass of two pushes (s = 2) — restores, on one thread or two, to the same continuation;
// clear() waits for the job in flight and starts afresh.
TEST(TeamChooser, FastBlockHistoryRunAheadSplitsAndCheckpointsDoNotChangeTheSums) {
  const Eigen::Index d = 700;  // d (K(2s + 1) + n0 s²) ≥ kRunAheadWork: a team of two runs ahead
  const int pushes = 60, saved_after = 37;
  for (const int s : {2, 3, 4}) {
    const RungeKuttaCq quadrature{s, 0.75, 1};
    const Eigen::MatrixXd xs = rough_input(d, pushes * s);
    Eigen::MatrixXd block(d, s);
    auto run = [&](BlockHistory& history, int from, int to, Eigen::MatrixXd& out,
                   StateWriter* writer) {
      for (int k = from; k < to; ++k) {
        history.push(xs.middleCols(k * s, s));
        history.sum(block);
        out.middleCols(k * s, s) = block;
        if (writer != nullptr && k + 1 == saved_after) history.visit_state(*writer);
      }
    };
    Eigen::MatrixXd reference(d, pushes * s);
    StateWriter one_writer;  // after push 37 of one thread (s = 2: two pushes a pass, run ahead)
    {
      const auto one = make_fast_block_history(quadrature, d, 1 << 12);
      one->set_threads(1);
      run(*one, 0, pushes, reference, &one_writer);
    }
    // A saved state restored on one thread and on two continues with the reference's sums.
    auto continues_like_the_reference = [&](const StateWriter& saved, const Eigen::MatrixXd& before,
                                            const std::string& what) {
      for (const int threads : {1, 2}) {
        const auto restored = make_fast_block_history(quadrature, d, 1 << 12);
        restored->set_threads(threads);
        StateReader reader(saved.bytes(), "test state");
        restored->visit_state(reader);
        reader.finish();
        Eigen::MatrixXd rest = before;
        run(*restored, saved_after, pushes, rest, nullptr);
        EXPECT_TRUE(bitwise_equal(rest, reference))
            << "s = " << s << ", " << what << ", restored on " << threads << " thread(s)";
      }
    };
    continues_like_the_reference(one_writer, reference, "one thread's state");
    const std::vector<Eigen::Index> fixed = {1, 64, 333, 699, 700, 5000};
    for (const Eigen::Index rows :
         {Eigen::Index{-1}, Eigen::Index{0}, Eigen::Index{1}, Eigen::Index{333}}) {
      const auto made = make_fast_block_history(quadrature, d, 1 << 12);
      auto& two = dynamic_cast<FastBlockHistory&>(*made);
      two.set_threads(2);
      two.set_run_ahead_rows(std::max<Eigen::Index>(rows, 0));
      Eigen::MatrixXd out(d, pushes * s);
      StateWriter writer;
      for (int k = 0; k < pushes; ++k) {
        if (rows < 0) two.set_run_ahead_rows(fixed[static_cast<std::size_t>(k) % fixed.size()]);
        run(two, k, k + 1, out, &writer);
      }
      EXPECT_TRUE(bitwise_equal(out, reference)) << "s = " << s << ", run-ahead rows " << rows;
      EXPECT_GE(two.run_ahead_rows(), 1);
      EXPECT_LE(two.run_ahead_rows(), d);
      continues_like_the_reference(writer, out, "rows " + std::to_string(rows));
      two.clear();
      Eigen::MatrixXd again(d, pushes * s);
      run(two, 0, pushes, again, nullptr);
      EXPECT_TRUE(bitwise_equal(again, reference)) << "s = " << s << ", after clear()";
    }
  }
  const auto history = make_fast_block_history(RungeKuttaCq{2, 0.75, 1}, d, 1 << 12);
  EXPECT_THROW(dynamic_cast<FastBlockHistory&>(*history).set_run_ahead_rows(-1),
               std::invalid_argument);
}

#if defined(__linux__)
// The run-ahead thread's way off the caller's CPU (internal/cpu_placement.hpp): a thread moved off
// the CPU it runs on is on another one when the call returns, and its allowed set is the one it
// had (nothing pinned). With one allowed CPU (or one hardware thread) the call refuses.
TEST(CpuPlacement, MovesTheThreadOffItsCpuAndKeepsItsAffinity) {
  std::thread probe([] {
    cpu_set_t before;
    CPU_ZERO(&before);
    ASSERT_EQ(pthread_getaffinity_np(pthread_self(), sizeof before, &before), 0);
    const int cpu = internal::current_cpu();
    ASSERT_GE(cpu, 0);
    const bool moved = internal::move_off_cpu(cpu);
    EXPECT_EQ(moved, CPU_COUNT(&before) >= 2);
    if (moved) {
      EXPECT_NE(internal::current_cpu(), cpu);
    }
    cpu_set_t after;
    CPU_ZERO(&after);
    ASSERT_EQ(pthread_getaffinity_np(pthread_self(), sizeof after, &after), 0);
    EXPECT_TRUE(CPU_EQUAL(&before, &after));
    // Pinned to one CPU: nowhere to go, and the pin stays.
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof one, &one), 0);
    EXPECT_FALSE(internal::move_off_cpu(cpu));
    EXPECT_EQ(internal::current_cpu(), cpu);
    cpu_set_t pinned;
    CPU_ZERO(&pinned);
    ASSERT_EQ(pthread_getaffinity_np(pthread_self(), sizeof pinned, &pinned), 0);
    EXPECT_TRUE(CPU_EQUAL(&one, &pinned));
  });
  probe.join();
}
#endif

}  // namespace
}  // namespace fracvi
