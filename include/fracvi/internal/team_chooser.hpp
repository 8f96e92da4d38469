// The thread count of the loops over degrees of freedom that run once per step (internal; the
// loops themselves: parallel.hpp).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstddef>

namespace fracvi::internal {

/// The thread count of a loop over degrees of freedom that runs once per step (a history's push),
/// chosen by timing. A fixed rule misjudges both ways: on an idle machine the second core pays
/// only from a few thousand degrees of freedom, and on a machine busy with other work every
/// parallel region waits for a core that is not free (fvi-lobatto3, d = 1000: 5 times slower on
/// two threads than on one at load 5; bench/RESULTS.md). So, with threads = 0 (auto) and work at
/// or above the threshold, the loop alternates trials — one thread, then the team, each at least
/// kTrialCalls calls and kTrialSeconds of timed calls, the first kWarmCalls of each not timed (the
/// data move to the other core's cache, a sleeping thread wakes) — keeps the faster for a hold of
/// at least kHoldSeconds (and 32 times the trials' time, so that trials cost at most a few per
/// cent; the first hold 8 times: kFirstHoldTrials), and measures again. The caller restarts the
/// trials when its work per call changes (a history once its window is full).
///
/// Two guards keep the team from costing more than one thread would. A machine whose second core
/// is taken away in bursts (a virtual machine with steal time) makes the team's calls 10–25 times
/// slower while it lasts, and a short trial can fall between bursts (d = 1000 on the 2-vCPU
/// machine: a team trial of 14.7 µs a step, then a hold at 31.8 µs against one thread's 18.1;
/// bench/RESULTS.md). (1) The team's trial ends as lost as soon as its timed calls have taken
/// longer than the one-thread trial's, in no more calls (a team 20 times slower costs one trial's
/// time, not twenty). (2) While the team is held, the held calls' mean is compared with the
/// one-thread trial's after every call from the kTrialCalls-th; once above, one thread takes the
/// hold, for as long again as the team had it (kRetryTrials), and then trials again. So a burst
/// costs the team its hold, the time a hold can lose is bounded by one trial's and one burst's,
/// and a spell that passes does not keep one thread for the rest of a long hold.
///
/// Each degree of freedom's arithmetic does not depend on the partition, so the choice never
/// changes a result. requested ≥ 1 is used as given (above the threshold). No allocation, no system
/// call but the clock's.
///
class TeamChooser {
 public:
  static constexpr int kTrialCalls = 16;
  static constexpr int kWarmCalls = 2;
  static constexpr double kTrialSeconds = 2e-3;
  static constexpr double kHoldSeconds = 0.5;
  /// A hold lasts at least kHoldSeconds and kHoldTrials × the trials' time — but the first after
  /// configure() only kFirstHoldTrials ×: its trials ran on cold data, with the run-ahead split
  /// not yet balanced and the second thread maybe not yet on its own core, the least reliable
  /// pair (fvi-lobatto3, d = 10^4: a first team trial lost in 1 round of 8, bench/RESULTS.md).
  static constexpr double kHoldTrials = 32.0;
  static constexpr double kFirstHoldTrials = 8.0;
  /// After guard (2) gives a hold to one thread: trials again after as long as the team was held,
  /// and at least kRetryTrials × the trials' time.
  static constexpr double kRetryTrials = 4.0;

  /// requested: 0 = measured, n ≥ 1 = n threads; team: the threads a call may use
  /// (parallel.hpp's team_size(requested, work, threshold): 1 below the threshold, else requested
  /// or, for 0, all cores or OMP_NUM_THREADS).
  void configure(int requested, int team) {
    team_ = std::max(team, 1);
    adaptive_ = requested == 0 && team_ > 1;
    chosen_ = team_;
    period_start_ = {};
    decisions_ = team_won_ = team_dropped_ = 0;
    restart();
  }
  /// Starts a new pair of trials (the calls so far do not represent the ones to come).
  void restart() {
    phase_ = Phase::kTrialOne;
    calls_ = one_calls_ = team_calls_ = 0;
    one_ = team_time_ = 0.0;
  }
  /// The largest team a call may use (for start_threads at set-up).
  [[nodiscard]] int team() const { return team_; }
  /// Whether the calls are timed (threads = 0 above the threshold): then each next() is followed
  /// by record() with the call's wall time.
  [[nodiscard]] bool measuring() const { return adaptive_; }
  /// Whether the next call is one of a trial's (not of a hold).
  [[nodiscard]] bool in_trial() const { return adaptive_ && phase_ != Phase::kHold; }
  /// The thread count of the next call.
  [[nodiscard]] int next() const {
    if (!adaptive_) return team_;
    return phase_ == Phase::kTrialOne ? 1 : (phase_ == Phase::kTrialTeam ? team_ : chosen_);
  }
  /// For callers timed by period: records the period of the previous call (now minus its start, if
  /// there was one since configure()) and returns the thread count of the call starting `now`. The
  /// first period after restart() is one of the untimed warm-up calls, so a period that began
  /// before the restart does not reach the trial.
  int next_by_period(std::chrono::steady_clock::time_point now) {
    if (adaptive_ && period_start_ != std::chrono::steady_clock::time_point{}) {
      record(std::chrono::duration<double>(now - period_start_).count());
    }
    period_start_ = now;
    return next();
  }
  /// Since configure(): the pairs of trials decided, how many the team won, and how many of those
  /// holds the team lost to guard (2) (summary.json's history_threads).
  [[nodiscard]] std::size_t decisions() const { return decisions_; }
  [[nodiscard]] std::size_t team_won() const { return team_won_; }
  [[nodiscard]] std::size_t team_dropped() const { return team_dropped_; }
  /// The wall time of the call made with next() threads.
  void record(double seconds) {
    switch (phase_) {
      case Phase::kTrialOne:
        if (calls_ >= kWarmCalls) {
          one_ += seconds;
          ++one_calls_;
        }
        if (++calls_ >= kTrialCalls && one_ >= kTrialSeconds) {
          phase_ = Phase::kTrialTeam;
          calls_ = 0;
        }
        return;
      case Phase::kTrialTeam: {
        if (calls_ >= kWarmCalls) {
          team_time_ += seconds;
          ++team_calls_;
        }
        ++calls_;
        // Guard (1): in no more calls than one thread's trial, and already longer.
        const bool lost = team_calls_ <= one_calls_ && team_time_ > one_;
        if (!lost && (calls_ < kTrialCalls || team_time_ < kTrialSeconds)) return;
        chosen_ = !lost && team_time_ / team_calls_ < one_ / one_calls_ ? team_ : 1;
        ++decisions_;
        if (chosen_ != 1) ++team_won_;
        hold_ = std::max(kHoldSeconds,
                         (decisions_ == 1 ? kFirstHoldTrials : kHoldTrials) * (one_ + team_time_));
        phase_ = Phase::kHold;
        held_ = 0.0;
        held_calls_ = 0;
        return;
      }
      case Phase::kHold:
        held_ += seconds;
        ++held_calls_;
        // Guard (2): the held team's mean against the one-thread trial's.
        if (chosen_ != 1 && held_calls_ >= kTrialCalls && held_ * one_calls_ > one_ * held_calls_) {
          chosen_ = 1;
          ++team_dropped_;
          // One thread for as long as the team was held, at least kRetryTrials × the trials'
          // time, then trials again: a spell that passes costs the team no more than that.
          hold_ = std::min(hold_, held_ + std::max(held_, kRetryTrials * (one_ + team_time_)));
        }
        if (held_ >= hold_) restart();
        return;
    }
  }

 private:
  enum class Phase { kTrialOne, kTrialTeam, kHold };

  int team_ = 1;
  bool adaptive_ = false;
  Phase phase_ = Phase::kTrialOne;
  int calls_ = 0;  // the trial's calls so far, warm-up included
  int one_calls_ = 0, team_calls_ = 0, held_calls_ = 0;  // the timed calls of each phase
  double one_ = 0.0, team_time_ = 0.0, held_ = 0.0, hold_ = kHoldSeconds;
  int chosen_ = 1;
  std::size_t decisions_ = 0, team_won_ = 0, team_dropped_ = 0;
  std::chrono::steady_clock::time_point period_start_{};  // next_by_period(): the last call's start
};

}  // namespace fracvi::internal
