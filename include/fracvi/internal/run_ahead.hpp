// The thread count of a fast history's push, and its second thread running the next push ahead
// (internal; used by FastHistory and FastBlockHistory, fast_history.hpp "Recursions one step
// ahead").
//
// Both histories have the same shape: push k runs recursions fed with the value that leaves the
// window (known n0 pushes earlier), adds the window's older values (known one push earlier), and
// makes a last addition with the new value. So a team of two runs everything but that last
// addition of push k + 1 on its second thread while the caller computes the rest of step k + 1,
// and push k + 1 only waits for it; a larger team splits the rows over OpenMP threads. RunAhead
// holds what the two histories share: the measured thread count (TeamChooser, timed push to push),
// the split of the run-ahead rows (RunAheadBalance), the second thread and the protocol between
// them. The history supplies the work (RunAheadJob) and the kernels; each row's arithmetic does
// not depend on who runs it, so nothing here changes a result.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>

#include "fracvi/internal/run_ahead_balance.hpp"
#include "fracvi/internal/team_chooser.hpp"

namespace fracvi::internal {

/// The work a history runs ahead: rows [lo, hi) of the next push's recursions (fed from ring
/// column `slot`, the value leaving the window) and of its window's terms before the last
/// addition (the window starting at ring column `first`).
class RunAheadJob {
 public:
  virtual void run_ahead(Eigen::Index lo, Eigen::Index hi, Eigen::Index slot,
                         Eigen::Index first) = 0;

 protected:
  ~RunAheadJob() = default;
};

class AheadThread;  // the second thread of a team of two (src/memory/run_ahead.cpp)

/// The thread count of a history's pushes and, for a team of two, the run-ahead protocol. A push
/// calls begin() before its work over the rows and end() after it (with the size counted up).
class RunAhead {
 public:
  /// Thresholds in multiply–adds per push (fast_history.hpp: kParallelWork, kRunAheadWork) and
  /// rows (kBalancedRunAheadFrom).
  struct Thresholds {
    Eigen::Index parallel_work, run_ahead_work, balanced_from;
  };

  RunAhead(RunAheadJob& job, Thresholds thresholds);
  ~RunAhead();
  RunAhead(const RunAhead&) = delete;
  RunAhead& operator=(const RunAhead&) = delete;

  /// `threads` as History::set_threads (0 = measured); `rows` = d; `work` = multiply–adds per push.
  /// Below parallel_work one thread does everything, but a team of two (the run-ahead thread)
  /// from run_ahead_work.
  void configure(int threads, Eigen::Index rows, Eigen::Index work);
  /// Rows [0, rows) of each next push to the run-ahead thread (0: balanced by timing from
  /// balanced_from rows, all rows below). The caller checks rows ≥ 0.
  void set_fixed_rows(Eigen::Index rows) {
    finish();
    fixed_rows_ = rows;
    configure_balance();
  }
  /// The run-ahead thread's share of the next push.
  [[nodiscard]] Eigen::Index rows() const { return balance_.rows(); }
  /// Since configure(): the thread choice (its team and decisions), the pushes, and how many of
  /// them ran on more than one thread (the run-ahead thread or a split).
  [[nodiscard]] const TeamChooser& chooser() const { return team_; }
  [[nodiscard]] std::size_t pushes() const { return pushes_; }
  [[nodiscard]] std::size_t team_pushes() const { return team_pushes_; }
  /// A push the history made on its own thread without begin() (a system too small for a team).
  void count_single_push() { ++pushes_; }

  /// One push: `size` values pushed before it, window n0, `capacity` pushes in all; `next_ran`:
  /// the next push's recursions already ran (a pass of several pushes), so none is posted.
  struct Turn {
    int split;       // threads for the push's own rows (1 with the run-ahead thread)
    bool ahead;      // the recursions and older window of this push already ran ahead
    bool post_next;  // end() posts the next push's
  };
  Turn begin(std::size_t size, std::size_t window, std::size_t capacity, bool next_ran = false);
  /// After the push's rows: with turn.post_next, rows [0, rows()) of the next push (its leaving
  /// value in ring column `next_slot`, its window from `next_first`) go to the thread, and the
  /// caller runs the rest now, while the thread runs its share, before it returns to its step.
  void end(const Turn& turn, Eigen::Index next_slot, Eigen::Index next_first);

  /// Waits for the job in flight (if any).
  void finish() const;
  /// Whether the recursions and the older window of the next push already ran (a checkpoint's
  /// record: finish() first).
  [[nodiscard]] bool ahead() const { return ahead_; }
  void set_ahead(bool ahead) {
    ahead_ = ahead;
    timed_ahead_ = false;
  }
  /// Forgets a job that ran ahead (after finish(): clear()).
  void reset() { set_ahead(false); }

 private:
  void configure_balance() {
    balance_.configure(rows_, fixed_rows_ == 0 && rows_ >= thresholds_.balanced_from,
                       fixed_rows_ == 0 ? rows_ : fixed_rows_);
    timed_ahead_ = false;  // a job in flight was timed for the former split
  }

  RunAheadJob& job_;
  Thresholds thresholds_;
  Eigen::Index rows_ = 0;
  Eigen::Index fixed_rows_ = 0;  // as set (0: balanced)
  TeamChooser team_;             // threads per push: measured (threads = 0) or as set
  RunAheadBalance balance_;      // the run-ahead thread's rows and the caller's
  bool timed_ahead_ = false;     // the job in flight records its times for balance_
  bool ahead_ = false;
  std::size_t pushes_ = 0, team_pushes_ = 0;
  std::unique_ptr<AheadThread> thread_;  // last: destroyed (joined) first
};

}  // namespace fracvi::internal
