// How many rows of the next push the run-ahead thread of a fast history (FastHistory,
// FastBlockHistory) takes, the caller taking the rest (internal; internal/run_ahead.hpp and
// fast_history.hpp, "Recursions one step ahead").
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace fracvi::internal {

/// The split of the next push's recursions between the run-ahead thread (rows [0, rows())) and the
/// caller (rows [rows(), d)), which runs its share right after posting the thread's, before it
/// returns to the rest of its step. Both shares then run at the same time, and the step is bound
/// by the longer of (the caller's step + its share) and (the thread's share). With the whole
/// history on the thread, a large system waits for it: at d = 10^4 its 2 MB of state comes from
/// L3 each step while the caller's own work is shorter (bench/RESULTS.md).
///
/// Balanced by timing, one step at a time: the thread records its share's time T (per row:
/// T / rows()), the caller the slack s = (its arrival at the next push) − (the thread's finish).
/// Moving r rows to the thread delays its finish by r·T/rows() and brings the caller's arrival
/// forward by about as much, so r = s / (2T/rows()) balances them; half of that is taken (a
/// damped step: one slow step, a page fault or a preemption, moves the split only half way), at
/// most d/8 at once, rounded to kGrain rows (a whole number of cache lines of each state column,
/// so that the two threads do not write the same lines). Each row's arithmetic does not depend on
/// the split, so the split never changes a result.
class RunAheadBalance {
 public:
  /// Rows per unit of the split (eight cache lines of doubles).
  static constexpr Eigen::Index kGrain = 64;

  /// `rows` rows in all; balanced (`balanced`) or the thread's share fixed at `fixed` rows
  /// (clamped to [0, rows]; with balanced = false and fixed = rows the thread takes every row).
  void configure(Eigen::Index rows, bool balanced, Eigen::Index fixed) {
    total_ = std::max<Eigen::Index>(rows, 0);
    balanced_ = balanced && total_ >= 2 * kGrain;
    share_ = balanced_ ? total_ : std::clamp<Eigen::Index>(fixed, 0, total_);
  }
  /// Rows [0, rows()) go to the run-ahead thread.
  [[nodiscard]] Eigen::Index rows() const { return share_; }
  /// Whether the thread's share is timed (then record() follows each job).
  [[nodiscard]] bool balanced() const { return balanced_; }
  /// The last job: the thread's time for its rows() rows, and the caller's arrival at the next
  /// push minus the thread's finish (negative: the caller waited).
  void record(double job_seconds, double slack_seconds) {
    if (!balanced_ || share_ <= 0 || !(job_seconds > 0.0) || !std::isfinite(slack_seconds)) return;
    const double per_row = job_seconds / static_cast<double>(share_);
    double move = 0.5 * slack_seconds / (2.0 * per_row);
    const double limit = static_cast<double>(total_) / 8.0;
    move = std::clamp(move, -limit, limit);
    const double target = static_cast<double>(share_) + move;
    const auto grains =
        static_cast<Eigen::Index>(std::lround(target / static_cast<double>(kGrain)));
    // At least one grain on the thread (its timing is what steers the split); the last partial
    // grain goes with the thread's share when it takes all but that.
    Eigen::Index next = std::max<Eigen::Index>(grains, 1) * kGrain;
    if (next >= total_ - kGrain / 2) next = total_;
    share_ = next;
  }

 private:
  Eigen::Index total_ = 0, share_ = 0;
  bool balanced_ = false;
};

}  // namespace fracvi::internal
