// FastHistory: the memory sum of `DiscEqs` in O((n0 + K)·d) work and memory per step,
// independent of the number of steps N (DESIGN §6; docs/theory/fast_history.md).
//
// The sum Σ_{m=0}^{k} c_m x̃_{k−m} (c = the order-β CQ weights, β = 2α) is split at the window n0:
//
//     Σ_{m=0}^{n0−1} c_m x̃_{k−m}            exact weights, the last n0 values in a ring buffer;
//   + Σ_{m=n0}^{k}   c_m x̃_{k−m}            with c_m ≈ Σ_j w_j e^{−λ_j (m − n0)} (ExponentialFit)
//   ≈ Σ_j w_j Y_j,   Y_j^{(k)} = Σ_{i=0}^{k−n0} e^{−λ_j (k − n0 − i)} x̃_i,
//
// and each Y_j (a d-vector) follows the one-term recursion Y_j ← e^{−λ_j} Y_j + x̃_{k−n0} when
// x̃_k is pushed (x̃_{k−n0} is the value that leaves the window). Because every tail weight is
// reproduced to relative error ε, |S_k − S_k^direct| ≤ ε Σ_m |c_m| max|x̃| (+ round-off, which the
// recursions keep at the level of the direct sum since λ_j > 0 and the weights hardly cancel:
// ExponentialFit::cancellation, measured 1–3).
//
// push() does the recursions, the tail Σ_j w_j Y_j and the window's d × n0 matrix–vector product
// in one pass over the d × K state (one parallel region per step); sum() returns the result. The
// ring stores each value once (x̃_j in column j mod n0), and the window's kernels find its columns
// around the ring's end, oldest first (one index per group of four columns): it used to store every
// value twice so that the window was n0 contiguous columns, which cost a d × n0 copy of memory
// (1.3 MB at d = 10^4, where the history's state no longer fits a core's L2) and a column copy a
// step. Neither allocates nor throws; all storage is sized at construction.
//
// Recursions one step ahead (a team of two threads). The recursions of push k use x̃_{k−n0}, known
// since push k − n0, and the window's older values are known since push k − 1; only the window's
// last addition (its last group of four, whose fourth value is x̃_k) needs x̃_k. So with two threads
// the second one forms push k+1's recursions, tail and the window but for that last addition while
// the caller computes the rest of step k+1, and push k+1 only waits for them and makes the last
// addition: nearly the whole history leaves the caller's path instead of being split with it (the
// rest of a step is serial: at d = 10^4 a split history allowed ≤ 1.3×, bench/RESULTS.md): what
// crosses between the cores on the caller's path is only x̃_k and the tail. For a large system
// the second thread takes only the first rows of that work, and the caller runs the rest right
// after posting them, at the same time, before it returns to its step: at d = 10^4 the whole
// history on the second thread outlasted the caller's step (its 2 MB of state comes from L3), and
// the split is balanced by timing (internal/run_ahead_balance.hpp). The operations and their order
// are those of the one-thread push in every row, so the sums are bit for bit the same. The thread
// count, the second thread and their protocol are internal::RunAhead's (internal/run_ahead.hpp),
// shared with FastBlockHistory.
//
// When n0 is a multiple of 4, what the second thread runs for push k+1 is a group's pass (the
// rows by groups of set_rows_ahead): the rows fall into four groups, and at each push the thread
// runs, for the group whose turn it is, the recursions and older windows of the next four pushes
// in one pass (push k+4's older window ends with x̃_k, already in the ring). That is the
// one-thread four-push pass, a quarter of the rows at a time: one push a pass for every row moved
// the whole state through the caches each push and took about twice the thread's time (d = 1000,
// bench/RESULTS.md 2026-12-02, fifth session), so that the caller waited for it.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cstddef>
#include <memory>
#include <string_view>

#include "fracvi/fractional/exponential_fit.hpp"
#include "fracvi/internal/run_ahead.hpp"
#include "fracvi/memory/history.hpp"

namespace fracvi {

namespace internal {
struct FastHistoryBlock;  // the rows one kernel call updates (fast_history.cpp)
}  // namespace internal

class FastHistory final : public History, private internal::RunAheadJob {
 public:
  /// A history on a precomputed fit (e.g. shared_exponential_fit()). Throws std::invalid_argument
  /// if fit is null, dimension < 1, capacity < 1, or the fit does not cover lags up to
  /// capacity − 1 (fit->max_lag < capacity − 1).
  FastHistory(std::shared_ptr<const ExponentialFit> fit, Eigen::Index dimension,
              std::size_t capacity);

  /// Grünwald–Letnikov weights of `order` (the paper's scheme) to relative tolerance
  /// `tolerance`, through the process-wide fit cache with max_lag = fast_history_fit_lag(capacity).
  /// Throws std::invalid_argument for what fit_exponentials() rejects (integer orders: use
  /// LocalHistory) and for dimension < 1 or capacity < 1.
  FastHistory(double order, Eigen::Index dimension, std::size_t capacity,
              double tolerance = kDefaultFitTolerance);
  ~FastHistory() override;
  FastHistory(const FastHistory&) = delete;
  FastHistory& operator=(const FastHistory&) = delete;

  void push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) override;
  /// From kAcrossTermsBelow degrees of freedom on one thread (set_threads(1)): push() is
  /// begin_row_push(), push_rows(0, d), end_row_push().
  [[nodiscard]] bool pushes_rows() const override;
  void begin_row_push(const double* x_tilde) override;
  void push_rows(Eigen::Index lo, Eigen::Index hi) override;
  void end_row_push() override;
  /// Pushes run ahead by row groups (History::set_rows_ahead): the rows fall into kAheadGroups
  /// groups (one when n0 is not a multiple of 4), and each push runs, for the group whose turn it
  /// is, the recursions and older windows of that push and the kAheadGroups − 1 after it in one
  /// pass (the four-push pass of one thread, a quarter of the rows at a time) — every row's tails
  /// are then ready a push or more ahead, and the push itself only adds x̃. Each row's operations
  /// are those of push(), so the numbers are the same bit for bit. Throws std::logic_error
  /// unless pushes_rows().
  static constexpr int kAheadGroups = 4;
  void set_rows_ahead(bool on) override;
  void rows_ahead(int share, int shares) override;
  void sum(Eigen::Ref<Eigen::VectorXd> out) const override;
  /// push() forms the sum here (never the second thread).
  [[nodiscard]] const double* kept_sum() const override { return sum_.data(); }
  void clear() override;
  [[nodiscard]] std::size_t size() const override { return size_; }
  [[nodiscard]] std::size_t capacity() const override { return capacity_; }
  [[nodiscard]] std::string_view kind() const override { return "fast"; }
  [[nodiscard]] std::size_t memory_bytes() const override {
    return static_cast<std::size_t>(ring_.size() + state_.size() + tails_.size() + sum_.size() +
                                    head_reversed_.size() + decay_.size() + weights_.size()) *
           sizeof(double);
  }
  [[nodiscard]] Eigen::Index dimension() const override { return ring_.rows(); }
  [[nodiscard]] ConvolutionQuadrature quadrature() const override {
    return {fit_->scheme, fit_->order, fit_->lag};
  }
  /// Threads for push() (0 = OpenMP's default, measured against one; see TeamChooser). A team of
  /// two runs the next push ahead on its second thread (above); a larger team splits the degrees
  /// of freedom over OpenMP threads. Below kParallelWork multiply–adds per step one thread does
  /// everything (a parallel region costs about a microsecond) — but a team of two, the run-ahead
  /// thread, from kRunAheadWork. A push that one thread runs alone, with no thread running the next
  /// one, runs the recursions and older windows of the next three pushes in the same pass over the
  /// state (one when n0 is not a multiple of 4; fast_history.cpp) — the same numbers, a quarter
  /// of the state's memory traffic — and those pushes then run as run ahead.
  void set_threads(int threads) override;
  /// Rows [0, rows) of each next push go to the run-ahead thread of a team of two, and the caller
  /// runs the rest right after posting them (fast_history.cpp). 0 (the default): balanced by timing
  /// (internal/run_ahead_balance.hpp) from kBalancedRunAheadFrom degrees of freedom, all rows to
  /// the thread below. The split never changes a result. Throws std::invalid_argument for rows < 0.
  void set_run_ahead_rows(Eigen::Index rows);
  /// The run-ahead thread's share of the next push (rows [0, run_ahead_rows())).
  [[nodiscard]] Eigen::Index run_ahead_rows() const { return run_ahead_.rows(); }
  /// The window (ring), the K recursions Y_j, the tail and the last sum.
  void visit_state(StateArchive& archive) override;

  [[nodiscard]] const ExponentialFit& fit() const { return *fit_; }
  /// n0, the number of exactly weighted recent lags.
  [[nodiscard]] std::size_t window() const { return fit_->window; }
  /// K, the number of exponentials (recursions per degree of freedom).
  [[nodiscard]] std::size_t terms() const { return fit_->terms(); }
  [[nodiscard]] HistoryReport report() const override {
    return {kind(), memory_bytes(), terms(), window(), internal::thread_use(run_ahead_)};
  }

 private:
  std::shared_ptr<const ExponentialFit> fit_;
  std::size_t capacity_;
  Eigen::Index window_;            // n0
  Eigen::VectorXd head_reversed_;  // c_{n0−1}, …, c_0 (matches the ring's chronological order)
  Eigen::MatrixXd ring_;           // d × n0; x̃_j in column j mod n0
  Eigen::ArrayXd decay_;           // e^{−λ_j}
  Eigen::VectorXd weights_;        // w_j
  Eigen::ArrayXXd state_;          // d × K; column j holds Y_j (all degrees of freedom)
  // Tails Σ_j w_j Y_j, plus the window's terms before its last addition once they are added: the
  // sum but for the terms with x̃_k (fast_history.cpp, newest_start). d × 4 (kPassSteps): column
  // tail_column_ is the next push's (where the run-ahead thread forms it), and when one pass ran
  // several pushes' recursions and older windows (fast_history.cpp, recursion_block_steps) the
  // following columns, cyclically, hold the complete tails of the later_ pushes after it.
  Eigen::MatrixXd tails_;
  Eigen::Index tail_column_ = 0;
  std::size_t later_ = 0;
  Eigen::VectorXd sum_;  // the whole sum after the last push (d)
  std::size_t size_ = 0;
  // The push begun by begin_row_push(): x̃_k, x̃_{k−n0}'s ring column, the window's first column,
  // this push's tails_ column, whether it runs the recursions and how many pushes' (a pass).
  struct RowPush {
    const double* entering = nullptr;
    Eigen::Index slot = 0, first = 0, own = 0;
    bool run_recursions = false;
    bool by_groups = false;  // run ahead by row groups: push_rows() only adds x̃
    int steps = 1;
    internal::RunAhead::Turn turn{};
  } pending_;
  // Pushes run ahead by row groups (set_rows_ahead): the groups' rows, and for each group the
  // pushes from size_ on whose tails are complete ("ready"); the passes that begin_row_push()
  // chose for rows_ahead() (a group's rows, its first push after size_, the pushes).
  bool by_groups_ = false;
  bool groups_by_team_ = false;  // the groups are the team of two's (configure_threads)
  int groups_ = 1;
  std::array<Eigen::Index, kAheadGroups + 1> group_bounds_{};
  std::array<int, kAheadGroups> group_ready_{};
  struct GroupPass {
    Eigen::Index lo = 0, hi = 0;
    int from = 0, steps = 0;
  };
  std::array<GroupPass, kAheadGroups> group_passes_{};
  int group_pass_count_ = 0;
  // The flush bits (internal/float_environment.hpp) of the last push: even_groups() runs its
  // passes with them.
  unsigned push_flush_bits_ = 0;
  // The thread count and the run-ahead thread (last: its thread is joined before the arrays it
  // writes are destroyed).
  internal::RunAhead run_ahead_;

  void configure_threads(int threads);
  // Pushes by row groups on or off (the groups brought even first).
  void switch_groups(bool on);
  // The passes of the push size_ (group_passes_): the group whose turn it is, and any group whose
  // ready pushes ran out.
  void plan_group_passes();
  // Rows [lo, hi) of a group's pass: the recursions and older windows of pushes size_ + from …
  // size_ + from + steps − 1.
  void group_pass(const GroupPass& pass, Eigen::Index lo, Eigen::Index hi);
  // Every group brought to the most ready pushes of any (running the others' passes), stated as
  // the pushes without groups keep it (later_ and the ahead flag): a checkpoint's form.
  void even_groups();
  // Rows [b, b + n) of a push: `terms` recursions (0: none) with x̃ from ring column `slot`, the
  // window from column `first` (wrapping at n0), the new value `entering` (null: the recursions
  // alone), written into ring column `slot`.
  internal::FastHistoryBlock block(Eigen::Index b, Eigen::Index n, Eigen::Index terms,
                                   Eigen::Index slot, Eigen::Index first, const double* entering,
                                   Eigen::Index tail);
  // Rows [lo, hi) of the next push's recursions with x̃ from ring column `leaving_slot`, and its
  // tail plus the window's terms before the last addition, from column `first` on, into the next
  // push's tails_ column.
  void run_ahead(Eigen::Index lo, Eigen::Index hi, Eigen::Index leaving_slot,
                 Eigen::Index first) override;
};

/// Multiply–adds per step ((K + n0)·d: the recursions and the window) from which FastHistory
/// splits the degrees of freedom over threads. Measured on the 2-core machine of bench/RESULTS.md
/// (bench/fractional_chain, -march=native, K + n0 ≈ 80): two threads were slower than one at
/// d = 1000 (0.80×), about even at d = 2000 (1.07×), ahead from d = 4000 (1.21×; 1.30× at 10^4).
inline constexpr Eigen::Index kParallelWork = Eigen::Index{1} << 18;
/// The same for a team of exactly two, whose second thread runs the next push's recursions
/// while the caller computes the rest of its step (no split, no parallel region): it pays from
/// smaller systems. Linear chain, one thread against forced two, three rounds each
/// (bench/RESULTS.md): d = 150 2.8–3.0 → 2.1–2.7 µs per step, d = 600 9.0–10.0 → 6.3–6.6 (one
/// run 12.4), d = 1000 15.4–16.4 → 10.2–14.9; whether it does on a given machine and load,
/// TeamChooser measures (threads = 0).
inline constexpr Eigen::Index kRunAheadWork = Eigen::Index{1} << 15;
/// Degrees of freedom from which a team of two balances the next push's rows between its threads
/// by timing (set_run_ahead_rows(0)); below, the run-ahead thread takes them all.
inline constexpr Eigen::Index kBalancedRunAheadFrom = 2048;

/// The max_lag used by FastHistory(order, …) for a capacity: the next power of two ≥
/// capacity − 1 (at least 1), so that runs of similar length share one cached fit. A fit for a
/// larger max_lag is valid for every smaller lag, and K grows by about 2 terms per doubling of
/// max_lag at ε = 1e-10, so the rounding costs at most about 2 terms.
std::size_t fast_history_fit_lag(std::size_t capacity);

/// FastHistory for the Grünwald–Letnikov or BDF2 weights of `quadrature` (lag included; what
/// HistoryKind::kFast constructs). Throws like the constructors and fit_exponentials().
std::unique_ptr<History> make_fast_history(const ConvolutionQuadrature& quadrature,
                                           Eigen::Index dimension, std::size_t capacity,
                                           double tolerance = kDefaultFitTolerance);

/// Capacity from which HistoryKind::kAuto should pick FastHistory for non-integer orders. Measured
/// by bench/history_bench.cpp (docs/theory/fast_history.md §8): above it FastHistory wins a whole
/// run of `capacity` push+sum steps for d = 1 and d = 100 even when the run pays for its fit and
/// against a direct sum written as one gemv; below it a direct run takes ≲ 30 ms and is exact to
/// round-off. (With the fit cached the crossover is 20–200 steps.) Re-measured for whole
/// `fracvi run`s (bench/history_crossover.py, bench/RESULTS.md, 2026-11-26, idle machine, after
/// the faster push kernel): at d = 1 direct / fast = 0.61–0.80 at N = 1024–1536, 1.05–1.37 at
/// 2048, 1.31–1.67 at 3072 for fvi-gl, fvi-bdf2 and fvi-midpoint; hence 2048 (was 4096).
inline constexpr std::size_t kFastHistoryCrossover = 2048;

/// HistoryKind::kAuto's choice for a non-integer order: FastHistory from kFastHistoryCrossover
/// steps whatever d, and earlier for large d, when the estimated direct run (N²·d/2 multiply–adds)
/// costs more than the fast one (≈ 100·N·d multiply–adds for K ≈ 45 recursions plus the window,
/// plus ≈ 2·10^7 for one fit of ≈ 10 ms). That model reproduces the measured crossover at d = 100
/// (N ≈ 400–800, fit included) and sends a 20 000-degree-of-freedom run of 1000 steps (160 MB and
/// 50 s with the direct sum) to the fast history.
bool fast_history_pays(std::size_t capacity, Eigen::Index dimension);

}  // namespace fracvi
