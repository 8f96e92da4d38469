#include "fracvi/internal/run_ahead.hpp"

#include <atomic>
#include <chrono>
#include <thread>

#include "fracvi/internal/cpu_placement.hpp"
#include "fracvi/internal/float_environment.hpp"
#include "fracvi/internal/parallel.hpp"
#include "fracvi/memory/history.hpp"

namespace fracvi::internal {

/// The second thread of a team of two: it runs the recursions of the next push while the caller
/// computes the rest of its step. One job at a time, handed over through one atomic: kIdle (no
/// job, or its results published), kWork (slot posted), kStop. Each side spins a while before it
/// sleeps on the atomic (futex): a job posted at the end of a push is usually finished before the
/// next push, and the next job comes one step later, so at the sizes where a team pays (≥
/// kRunAheadWork multiply–adds per push, microseconds) the handover stays in the spin. Neither
/// side allocates after construction.
class AheadThread {
 public:
  using Clock = std::chrono::steady_clock;

  explicit AheadThread(RunAheadJob& job) : job_(job), worker_([this] { serve(); }) {}
  ~AheadThread() {
    finish();
    state_.store(kStop, std::memory_order_release);
    state_.notify_one();
    worker_.join();
  }
  AheadThread(const AheadThread&) = delete;
  AheadThread& operator=(const AheadThread&) = delete;

  /// Starts the next push's recursions (fed from ring column `leaving_slot`) and older window
  /// (from column `first`) for rows [0, rows); `timed`: the job records its start and finish.
  void post(Eigen::Index leaving_slot, Eigen::Index first, Eigen::Index rows, bool timed) {
    slot_ = leaving_slot;
    first_ = first;
    rows_ = rows;
    timed_ = timed;
    caller_cpu_ = current_cpu();
    flush_bits_ = flush_bits();
    state_.store(kWork, std::memory_order_release);
    state_.notify_one();
  }
  /// Returns once the job posted last (if any) has finished; its writes are then visible.
  void finish() const { await_other_than(kWork); }
  /// The last timed job's start and finish (read after finish()).
  [[nodiscard]] Clock::time_point started() const { return started_; }
  [[nodiscard]] Clock::time_point finished() const { return finished_; }

 private:
  static constexpr int kIdle = 0, kWork = 1, kStop = 2;
  // ≈ 0.1–0.5 ms of spinning, longer than the gap between two pushes at the sizes where the team
  // is used. Every kYieldEvery-th turn yields the core: when the machine is busy the two threads
  // may share one core, and a spinning thread would hold it from the one it waits for (forced
  // threads = 2 beside another build: 10.0 s of stepping against 2.2 s on one thread before).
  static constexpr int kSpins = 1 << 14;
  static constexpr int kYieldEvery = 64;

  int await_other_than(int busy) const {
    for (int i = 1; i <= kSpins; ++i) {
      const int now = state_.load(std::memory_order_acquire);
      if (now != busy) return now;
      if (i % kYieldEvery == 0) {
        std::this_thread::yield();
      } else {
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#endif
      }
    }
    int now = state_.load(std::memory_order_acquire);
    while (now == busy) {
      state_.wait(busy, std::memory_order_acquire);
      now = state_.load(std::memory_order_acquire);
    }
    return now;
  }

  void serve() {
    for (;;) {
      if (await_other_than(kIdle) == kStop) return;
      const int caller_cpu = caller_cpu_;  // posted with the job (the next post may change it)
      // The caller's floating-point environment: the same numbers on one thread or two.
      adopt_flush_bits(flush_bits_);
      if (timed_) started_ = Clock::now();
      job_.run_ahead(0, rows_, slot_, first_);
      if (timed_) finished_ = Clock::now();
      const bool shared = movable_ && caller_cpu >= 0 && current_cpu() == caller_cpu;
      state_.store(kIdle, std::memory_order_release);
      state_.notify_one();
      // On the caller's CPU, the two threads take turns instead of overlapping: move to another
      // (cpu_placement.hpp). Once that is refused (one allowed CPU), never ask again.
      if (shared) movable_ = move_off_cpu(caller_cpu);
    }
  }

  RunAheadJob& job_;
  Eigen::Index slot_ = 0, first_ = 0, rows_ = 0;
  bool timed_ = false;
  Clock::time_point started_{}, finished_{};  // written by the worker, read after finish()
  int caller_cpu_ = -1;                       // where the caller posted the job from
  unsigned flush_bits_ = 0;                   // the caller's (float_environment.hpp)
  bool movable_ = true;                       // the worker's thread only
  mutable std::atomic<int> state_{kIdle};
  std::thread worker_;  // last: it starts serving once the members above exist
};

RunAhead::RunAhead(RunAheadJob& job, Thresholds thresholds) : job_(job), thresholds_(thresholds) {}

RunAhead::~RunAhead() = default;

void RunAhead::configure(int threads, Eigen::Index rows, Eigen::Index work) {
  finish();
  rows_ = rows;
  pushes_ = team_pushes_ = 0;
  int team = team_size(threads, work, thresholds_.parallel_work);
  if (team == 1 && team_size(threads, work, thresholds_.run_ahead_work) == 2) team = 2;
  team_.configure(threads, team);
  configure_balance();
  if (team_.team() == 2) {
    if (!thread_) thread_ = std::make_unique<AheadThread>(job_);
  } else {
    thread_.reset();
    start_threads(team_.team());
  }
}

RunAhead::Turn RunAhead::begin(std::size_t size, std::size_t window, std::size_t capacity,
                               bool next_ran) {
  // The pushes before the window is full skip the recursions: the thread choice measures again.
  if (size == window) team_.restart();
  // Timed from push to push (TeamChooser::next_by_period): the second thread's work overlaps
  // the caller's step, which the push alone would not show.
  using Clock = std::chrono::steady_clock;
  const bool timed_job = ahead_ && timed_ahead_;
  const Clock::time_point arrival =
      team_.measuring() || timed_job ? Clock::now() : Clock::time_point{};
  const int threads = team_.measuring() ? team_.next_by_period(arrival) : team_.next();
  finish();
  if (timed_job) {
    // The thread's share of this push against the caller's arrival (RunAheadBalance).
    const Clock::time_point finished = thread_->finished();
    balance_.record(std::chrono::duration<double>(finished - thread_->started()).count(),
                    std::chrono::duration<double>(arrival - finished).count());
  }
  timed_ahead_ = false;
  ++pushes_;
  if (threads > 1) ++team_pushes_;
  return {thread_ ? 1 : threads, ahead_,
          thread_ && threads > 1 && !next_ran && size + 1 >= window && size + 1 < capacity};
}

void RunAhead::end(const Turn& turn, Eigen::Index next_slot, Eigen::Index next_first) {
  ahead_ = false;
  if (!turn.post_next) return;
  const Eigen::Index share = balance_.rows();
  timed_ahead_ = balance_.balanced();
  thread_->post(next_slot, next_first, share, timed_ahead_);
  job_.run_ahead(share, rows_, next_slot, next_first);
  ahead_ = true;
}

HistoryThreads thread_use(const RunAhead& run_ahead) {
  const TeamChooser& chooser = run_ahead.chooser();
  return {chooser.team(),      chooser.measuring(), run_ahead.pushes(),    run_ahead.team_pushes(),
          chooser.decisions(), chooser.team_won(),  chooser.team_dropped()};
}

void RunAhead::finish() const {
  if (thread_) thread_->finish();
}

}  // namespace fracvi::internal
