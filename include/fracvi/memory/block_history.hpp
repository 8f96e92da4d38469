// The memory of a Runge–Kutta convolution quadrature (fractional/runge_kutta_cq.hpp): the block
// analogue of History (history.hpp), for the fvi-lobatto steppers.
//
// Per step k the stepper pushes the s stage vectors of interval k, a d × s block Z_k (column i
// holds the stage value in R^d of stage i), and needs
//
//     S_k = Σ_{j=0}^{k} (W_{j+lag} ⊗ I_d) vec(Z_{k−j}),   as a d × s block:  S_k = Σ_j Z_{k−j}
//     W_{j+lag}ᵀ,
//
// i.e. for each degree of freedom r the s-vector Σ_j W_{j+lag} z_{k−j}(r), with the s × s block
// weights W_j of s^β (RungeKuttaCq; `lag` = RungeKuttaCq::lag, 1 for the known part of a sum whose
// W_0 acts on the unknowns and sits in Newton's matrix).
//
//  * DirectBlockHistory: every block kept, exact weights, O(k·d·s²) per sum, O(N·d·s) memory.
//  * FastBlockHistory: the n0 most recent lags with exact blocks, and the tail through
//    W_j ≈ Σ_i γ_i r_i^{j−n0} u_i v_iᵀ (fit_rkcq_tail(), docs/theory/rkcq_weights.md §10): per tail
//    term i one d-vector Y_i ← r_i Y_i + Z_{k−n0} v_i, and the tail is Σ_i γ_i Y_i u_iᵀ. Work
//    O((2sK + n0 s²)·d) per step, memory O((K + n0 s)·d) independent of N
//    (docs/theory/fast_history.md, "Block history (Runge–Kutta CQ)"). Integer orders (W_j = 0
//    beyond j = β) use the same class with no tail terms: a local history.
//
// push() and sum() never allocate and never throw; all storage is reserved at construction.
// Blocks are passed as Eigen::Ref of column-major d × s matrices (a MatrixXd, or a block of one
// with contiguous columns; an expression that needs a copy would allocate).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <string_view>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/internal/run_ahead.hpp"
#include "fracvi/memory/history.hpp"

namespace fracvi {

namespace internal {
struct BlockHistoryRows;  // the rows one kernel call updates (block_history.cpp)
}  // namespace internal

class BlockHistory {
 public:
  virtual ~BlockHistory() = default;

  /// Appends Z_k (d × s), where k = size() before the call. Precondition: size() < capacity().
  virtual void push(const Eigen::Ref<const Eigen::MatrixXd>& block) = 0;
  /// out (d × s) = Σ_{j=0}^{k} Z_{k−j} W_{j+lag}ᵀ for the last pushed index k.
  /// Precondition: size() ≥ 1.
  virtual void sum(Eigen::Ref<Eigen::MatrixXd> out) const = 0;
  /// The sum of the last push where the history keeps it (what sum() copies out, d × s
  /// column-major with leading dimension d), else null: a step that only reads the sum can read
  /// it there. Valid until the next push() or clear().
  [[nodiscard]] virtual const double* kept_sum() const { return nullptr; }
  /// Forgets all pushed blocks (capacity is kept).
  virtual void clear() = 0;

  /// Number of blocks pushed since construction or clear().
  [[nodiscard]] virtual std::size_t size() const = 0;
  /// Maximum number of pushes between clears.
  [[nodiscard]] virtual std::size_t capacity() const = 0;
  /// d, the rows of a block.
  [[nodiscard]] virtual Eigen::Index dimension() const = 0;
  /// s, the columns of a block.
  [[nodiscard]] virtual int stages() const = 0;
  /// The weights: stages, order β and lag.
  [[nodiscard]] virtual RungeKuttaCq quadrature() const = 0;
  /// Bytes of state this history keeps (blocks, weights, recursions).
  [[nodiscard]] virtual std::size_t memory_bytes() const = 0;
  /// "direct", "fast" or "local": what method.history = "auto" chose (summary.json's history).
  [[nodiscard]] virtual std::string_view kind() const = 0;
  /// kind(), memory_bytes() and, for the fast history, K and n0 (history.hpp).
  [[nodiscard]] virtual HistoryReport report() const { return {kind(), memory_bytes(), 0, 0, {}}; }
  /// Threads for the work over degrees of freedom (0 = measured against one). Only the fast
  /// history uses them (a run-ahead thread from kRunAheadWork multiply–adds per step, split rows
  /// from kParallelWork); the direct one ignores it.
  virtual void set_threads(int threads) { static_cast<void>(threads); }
  /// Saves or restores the pushed blocks and every accumulator (core/state_archive.hpp), so that a
  /// restored history continues bit-for-bit; the weights (and the tail's fit) are rebuilt by the
  /// constructor, and their sizes are checked against the saved ones.
  virtual void visit_state(StateArchive& archive) = 0;
};

/// All blocks kept, exact weights W_lag … W_{lag+capacity−1}. O(k·d·s²) per sum.
class DirectBlockHistory final : public BlockHistory {
 public:
  /// Throws std::invalid_argument for an invalid quadrature, dimension < 1 or capacity < 1.
  DirectBlockHistory(const RungeKuttaCq& quadrature, Eigen::Index dimension, std::size_t capacity);

  void push(const Eigen::Ref<const Eigen::MatrixXd>& block) override;
  void sum(Eigen::Ref<Eigen::MatrixXd> out) const override;
  void clear() override { size_ = 0; }
  [[nodiscard]] std::size_t size() const override { return size_; }
  [[nodiscard]] std::size_t capacity() const override { return capacity_; }
  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }
  [[nodiscard]] int stages() const override { return quadrature_.stages; }
  [[nodiscard]] RungeKuttaCq quadrature() const override { return quadrature_; }
  [[nodiscard]] std::string_view kind() const override { return "direct"; }
  [[nodiscard]] std::size_t memory_bytes() const override {
    return (weights_.data().size() + values_.size()) * sizeof(double);
  }
  [[nodiscard]] const BlockWeights& weights() const { return weights_; }
  void visit_state(StateArchive& archive) override;

 private:
  RungeKuttaCq quadrature_;
  Eigen::Index dimension_;
  std::size_t capacity_;
  BlockWeights weights_;        // W_lag … W_{lag+capacity−1}
  std::vector<double> values_;  // capacity blocks, Z_j column-major d × s at values_[j·d·s]
  std::size_t size_ = 0;
};

/// Exact blocks for the n0 most recent lags and the rank-one sum-of-decays tail of an RkcqTail.
class FastBlockHistory final : public BlockHistory, private internal::RunAheadJob {
 public:
  /// A history of the weights W_{j+lag} on a tail representation of the plain weights W_j
  /// (e.g. shared_rkcq_tail()): the window is tail->window − lag blocks (tail->head[lag …]), the
  /// tail terms are used unchanged (the shift j − n0 does not see the lag). Throws
  /// std::invalid_argument if tail is null, lag ≥ tail->window, dimension < 1, capacity < 1, or
  /// the tail does not cover the lags up to capacity − 1 + lag (tail->max_lag).
  FastBlockHistory(std::shared_ptr<const RkcqTail> tail, std::size_t lag, Eigen::Index dimension,
                   std::size_t capacity);

  void push(const Eigen::Ref<const Eigen::MatrixXd>& block) override;
  void sum(Eigen::Ref<Eigen::MatrixXd> out) const override;
  /// push() forms the sum here (its own threads, before it returns; never the run-ahead thread).
  [[nodiscard]] const double* kept_sum() const override { return sum_.data(); }
  void clear() override;
  [[nodiscard]] std::size_t size() const override { return size_; }
  [[nodiscard]] std::size_t capacity() const override { return capacity_; }
  [[nodiscard]] Eigen::Index dimension() const override { return sum_.rows(); }
  [[nodiscard]] int stages() const override { return tail_->stages; }
  [[nodiscard]] RungeKuttaCq quadrature() const override {
    return {tail_->stages, tail_->order, lag_};
  }
  [[nodiscard]] std::string_view kind() const override { return "fast"; }
  [[nodiscard]] std::size_t memory_bytes() const override {
    return static_cast<std::size_t>(ring_.size() + state_.size() + partial_.size() +
                                    step_partial_.size() + sum_.size() + head_.size() +
                                    right_.size() + left_.size() + decay_.size()) *
           sizeof(double);
  }
  /// Threads for push() (0 = measured against one; internal/run_ahead.hpp), as FastHistory's: a
  /// team of two runs the next push's recursions and older window on its second thread while the
  /// caller computes the rest of its step (from kRunAheadWork multiply–adds per push); a larger
  /// team splits the degrees of freedom (from kParallelWork).
  void set_threads(int threads) override;
  /// Rows [0, rows) of each next push go to the run-ahead thread of a team of two (0, the
  /// default: balanced by timing from kBalancedRunAheadFrom degrees of freedom). The split never
  /// changes a result. Throws std::invalid_argument for rows < 0.
  void set_run_ahead_rows(Eigen::Index rows);
  /// The run-ahead thread's share of the next push.
  [[nodiscard]] Eigen::Index run_ahead_rows() const { return run_ahead_.rows(); }
  void visit_state(StateArchive& archive) override;

  [[nodiscard]] const RkcqTail& tail() const { return *tail_; }
  /// n0, the number of exactly weighted recent lags (tail().window − lag).
  [[nodiscard]] std::size_t window() const { return static_cast<std::size_t>(window_); }
  /// K, the number of tail terms (recursions per degree of freedom).
  [[nodiscard]] std::size_t terms() const { return static_cast<std::size_t>(decay_.size()); }
  /// The stage p whose values enter every recursion with the coefficient 1 (each recursion kept
  /// divided by its (v_i)_p: 2s multiply–adds a term instead of 2s + 1), or stages() when no
  /// stage's coefficient is above 1e-8 of its term's largest in every term.
  [[nodiscard]] Eigen::Index unit_stage() const { return unit_stage_; }
  [[nodiscard]] HistoryReport report() const override {
    return {kind(), memory_bytes(), terms(), window(), internal::thread_use(run_ahead_)};
  }

 private:
  std::shared_ptr<const RkcqTail> tail_;
  std::size_t lag_;
  std::size_t capacity_;
  Eigen::Index window_;  // n0
  Eigen::Index stages_;  // s
  Eigen::MatrixXd head_;  // (n0·s) × s; rows t·s … t·s + s − 1 hold W_{lag+n0−1−t}ᵀ (oldest first)
  Eigen::MatrixXd ring_;   // d × (n0·s); column t·s + e: stage e of ring position t
  Eigen::VectorXd decay_;  // r_i (K)
  // p, the unit stage (unit_stage(); s: none): each recursion is kept divided by its (v_i)_p, so
  // that Z(:, p) enters it with the coefficient 1.
  Eigen::Index unit_stage_;
  // K × s, column e: (v_i)_q / (v_i)_p, q the stage at position e of the kernels' order
  // (block_history.cpp, stage_in_kernel_order)
  Eigen::MatrixXd right_;
  Eigen::MatrixXd left_;   // K × s, column c: γ_i (u_i)_c (v_i)_p
  Eigen::MatrixXd state_;  // d × K, column i: Y_i / (v_i)_p
  // d × s: the recursions' terms and the window's before its first addition with Z_k (the sum
  // but for those; block_history.cpp, newest_start).
  Eigen::MatrixXd partial_;
  // A push's partial sum when its recursions run two pushes in one pass: the next push's goes to
  // partial_ (block_history.cpp, older_rows_two_steps).
  Eigen::MatrixXd step_partial_;
  Eigen::MatrixXd sum_;  // d × s, the sum after the last push
  std::size_t size_ = 0;
  // The thread count and the run-ahead thread (last: its thread is joined before the arrays it
  // writes are destroyed).
  internal::RunAhead run_ahead_;

  // The stage whose coefficient each recursion's input is scaled to 1: the one whose smallest
  // |(v_i)_p| / max_e |(v_i)_e| over the terms is the largest, if that is above 1e-8; else s
  // (none).
  static Eigen::Index choose_unit_stage(const RkcqTail& tail);
  // Multiply–adds per push: 2sK (K more without a unit stage) + n0·s² per degree of freedom.
  [[nodiscard]] Eigen::Index push_work() const {
    const Eigen::Index per_term = 2 * stages_ + (unit_stage_ == stages_ ? 1 : 0);
    return sum_.rows() * (decay_.size() * per_term + window_ * stages_ * stages_);
  }
  // Rows [b, b + n) of a push: `terms` recursions (0: none) fed from ring position `slot`, the
  // window from position `first`, the new block (null: the recursions and older window alone).
  internal::BlockHistoryRows rows(Eigen::Index b, Eigen::Index n, Eigen::Index terms,
                                  Eigen::Index slot, Eigen::Index first,
                                  const Eigen::Ref<const Eigen::MatrixXd>* block);
  // Rows [lo, hi) of the next push's recursions and older window, into partial_.
  void run_ahead(Eigen::Index lo, Eigen::Index hi, Eigen::Index leaving_slot,
                 Eigen::Index first) override;
};

/// Options of the process-wide cache of tail representations (the fit takes 0.05–0.5 s).
/// Returns the cached fit_rkcq_tail(options) (computed on the first request); thread-safe.
std::shared_ptr<const RkcqTail> shared_rkcq_tail(const RkcqTailOptions& options);
void clear_rkcq_tail_cache();
std::size_t rkcq_tail_cache_size();

/// The exactly weighted window of FastBlockHistory (lags n0 … max_lag are the tail's).
inline constexpr std::size_t kBlockHistoryWindow = 16;

/// FastBlockHistory for `quadrature` (lag included), able to take `capacity` pushes, tail terms
/// to relative tolerance `tolerance` per block (max-norm, fit_rkcq_tail()). Non-integer orders:
/// the cached tail with window kBlockHistoryWindow + lag and max_lag
/// fast_history_fit_lag(capacity) + lag. Integer orders (the weights end at lag β): the exact
/// nonzero blocks only, no tail terms. Throws std::invalid_argument for invalid arguments.
std::unique_ptr<BlockHistory> make_fast_block_history(const RungeKuttaCq& quadrature,
                                                      Eigen::Index dimension, std::size_t capacity,
                                                      double tolerance = 1e-10);

/// Capacity from which HistoryKind::kAuto picks FastBlockHistory for non-integer orders whatever
/// d. Measured for whole `fracvi run`s of fvi-lobatto3 (bench/history_crossover.py, 2026-11-26,
/// idle machine): at d = 1 direct / fast = 0.61 at N = 1536, 1.00 at 2048, 1.24 at 3072, 2.11 at
/// 4096; hence 2048 (was 4096, from an earlier measurement that found them even near 4096).
inline constexpr std::size_t kBlockFastHistoryCrossover = 2048;

/// HistoryKind::kAuto's choice for a non-integer order: the fast block history from
/// kBlockFastHistoryCrossover pushes, and earlier when the estimated direct run (N²·d·s²/2
/// multiply–adds) costs more than the fast one plus its fit (large d; see
/// docs/theory/fast_history.md, "Block history").
bool fast_block_history_pays(std::size_t capacity, Eigen::Index dimension, int stages);

/// kDirect: DirectBlockHistory. kFast: FastBlockHistory (local for integer orders). kAuto: the
/// local FastBlockHistory for integer orders, otherwise FastBlockHistory when
/// fast_block_history_pays(), else DirectBlockHistory. Throws std::invalid_argument for invalid
/// arguments (before any step).
std::unique_ptr<BlockHistory> make_block_history(HistoryKind kind, const RungeKuttaCq& quadrature,
                                                 Eigen::Index dimension, std::size_t capacity,
                                                 double tolerance = 1e-10);

}  // namespace fracvi
