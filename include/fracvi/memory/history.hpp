// The memory of the fractional damping term, behind one small interface.
//
// The damping sum of `DiscEqs` is Σ_{n=0}^{k} α_n Σ_{p=0}^{k−n} α_p x̃_{k−n−p} = Σ_{m=0}^{k} c_m
// x̃_{k−m} with c = gl_weights(2α), the coefficients of (1 − ζ)^{2α} (DESIGN §3.1): one convolution.
// Other schemes use other convolution quadratures (BDF2: the coefficients of δ_BDF2(ζ)^{2α}); a
// History is keyed by its ConvolutionQuadrature (fractional/convolution_quadrature.hpp), the
// generating function and the order, so that one interface serves every scheme.
// A History receives x̃_0, x̃_1, … one at a time and returns that convolution for the latest index.
// The mirror equation's forward-running sum Σ_{m=0}^{N−k} c_m ỹ_{k+m} is the same object fed in
// reverse order (ỹ_N first).
//
//  * DirectHistory: stores every x̃ and sums directly, O(k·d) per step, O(N·d) memory.
//  * LocalHistory: for integer damping orders 2α ∈ {0, 1, 2} the GL and BDF2 weights terminate
//    (δ(ζ)^{2α} is a polynomial), so only the last deg(δ)·2α + 1 values are kept. For GL and
//    α = 1/2 this is Lemma 5.3: Σ c_m x̃_{k−m} = x̃_k − x̃_{k−1}.
//  * FastHistory (fast_history.hpp): exact weights for a short window of recent lags and a
//    sum-of-exponentials compression of the tail (DESIGN §6, docs/theory/fast_history.md):
//    O((n0 + K)·d) per step and memory independent of N, K ~ log N · log(1/ε).
//
// push() and sum() never allocate and never throw; all storage is reserved at construction.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cstddef>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/fractional/convolution_quadrature.hpp"

namespace fracvi {

/// What a run's damping memory is (Solution, summary.json): its implementation ("direct",
/// "fast", "local", "fft" or "none": what method.history = "auto" chose), its bytes, and for a
/// fast history the number K of exponentials (recursions per degree of freedom) and the window
/// n0 of exactly weighted recent lags (0 for the others).
///
/// `threads`: how a fast history's pushes used the cores (internal::RunAhead, TeamChooser), for
/// runs whose speed on two cores needs explaining: the most threads a push could use (1: one
/// thread throughout, e.g. below kRunAheadWork), whether the count was measured (threads = 0)
/// or set, the pushes and how many ran on the team, the trial pairs decided, how many the team
/// won, and how many of those holds it lost to a slow spell (guard 2). A memory of two histories
/// (fvi-midpoint's) adds them up.
struct HistoryThreads {
  int team = 1;
  bool measured = false;
  std::size_t pushes = 0;
  std::size_t team_pushes = 0;
  std::size_t decisions = 0;
  std::size_t team_won = 0;
  std::size_t team_dropped = 0;
  /// The team split whole steps by rows (CqMidpointStepper's step by rows: the history's push
  /// and the step's passes), not only the history's push; pushes count those steps.
  bool whole_steps = false;

  /// Two histories' use as one: the larger team, the counts added.
  [[nodiscard]] HistoryThreads operator+(const HistoryThreads& o) const {
    return {std::max(team, o.team),        measured || o.measured,      pushes + o.pushes,
            team_pushes + o.team_pushes,   decisions + o.decisions,     team_won + o.team_won,
            team_dropped + o.team_dropped, whole_steps || o.whole_steps};
  }
};

namespace internal {
class RunAhead;
/// A fast history's HistoryThreads from its RunAhead (src/memory/run_ahead.cpp).
HistoryThreads thread_use(const RunAhead& run_ahead);
}  // namespace internal

struct HistoryReport {
  std::string_view kind = "none";
  std::size_t bytes = 0;
  std::size_t exponentials = 0;
  std::size_t window = 0;
  HistoryThreads threads;
};

class History {
 public:
  virtual ~History() = default;

  /// Appends x̃_k, where k = size() before the call. Precondition: size() < capacity().
  virtual void push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) = 0;
  /// out = Σ_{m=0}^{k} c_m x̃_{k−m} for the last pushed index k (out has size d).
  /// Precondition: size() ≥ 1.
  virtual void sum(Eigen::Ref<Eigen::VectorXd> out) const = 0;
  /// The sum of the last push where the history keeps it (what sum() copies out), else null: a
  /// step that only reads the sum can read it there. Valid until the next push() or clear().
  [[nodiscard]] virtual const double* kept_sum() const { return nullptr; }
  /// Forgets all pushed values (capacity is kept).
  virtual void clear() = 0;

  /// A push split by rows over the caller's own threads (the CQ midpoint step split by rows,
  /// cq_midpoint_stepper.hpp): begin_row_push(x̃) on one thread, then push_rows(lo, hi) for
  /// disjoint ranges covering [0, d) — from several threads at once, each after x̃'s rows
  /// [lo, hi) are written, and reading only those rows of x̃ — then end_row_push() on one thread,
  /// after every range: the same numbers as push(x̃), and kept_sum()'s rows [lo, hi) are the
  /// sum's once push_rows(lo, hi) returns. A push begun but never ended (its step failed) leaves
  /// the pushed values and the sum as they were only if no push_rows ran. Only where
  /// pushes_rows(); the defaults throw std::logic_error.
  [[nodiscard]] virtual bool pushes_rows() const { return false; }
  virtual void begin_row_push(const double* x_tilde);
  virtual void push_rows(Eigen::Index lo, Eigen::Index hi);
  virtual void end_row_push();
  /// With set_rows_ahead(true) (the step by rows whose solve runs on one thread: the others wait
  /// for it): between begin_row_push() and the push_rows() calls, rows_ahead(share, shares) for
  /// share = 0 … shares − 1 — from as many threads at once, while x̃ is still being computed —
  /// runs the push's work that does not need x̃ (FastHistory: its recursions and older window,
  /// and those of the next pushes on a group of the rows), and push_rows() then only adds x̃.
  /// The same numbers as push(x̃). Only where pushes_rows(); the defaults throw
  /// std::logic_error.
  virtual void set_rows_ahead(bool on);
  virtual void rows_ahead(int share, int shares);

  /// Number of values pushed since construction or clear().
  [[nodiscard]] virtual std::size_t size() const = 0;
  /// Maximum number of pushes between clears.
  [[nodiscard]] virtual std::size_t capacity() const = 0;
  [[nodiscard]] virtual Eigen::Index dimension() const = 0;
  /// The weights: generating function and order (2α for the damping sums).
  [[nodiscard]] virtual ConvolutionQuadrature quadrature() const = 0;
  /// The order of the weights (quadrature().order).
  [[nodiscard]] double order() const { return quadrature().order; }
  /// Bytes of state this history keeps (values, weights, recursions): N·d·8 for the direct sum,
  /// (K + n0 + 2)·d·8 plus the weights for the fast one.
  [[nodiscard]] virtual std::size_t memory_bytes() const = 0;
  /// "direct", "fast" or "local": what method.history = "auto" chose (summary.json's history).
  [[nodiscard]] virtual std::string_view kind() const = 0;
  /// kind(), memory_bytes() and, for the fast history, K and n0.
  [[nodiscard]] virtual HistoryReport report() const { return {kind(), memory_bytes(), 0, 0, {}}; }
  /// Threads for the work over degrees of freedom (0 = OpenMP's default). Only the fast history
  /// has enough work per step to use them; the others ignore it.
  virtual void set_threads(int threads) { static_cast<void>(threads); }
  /// Saves or restores the pushed values and every accumulator (core/state_archive.hpp), so that
  /// a restored history continues bit-for-bit; the weights are rebuilt by the constructor.
  virtual void visit_state(StateArchive& archive) = 0;
};

/// All x̃ kept, exact convolution with the quadrature's weights. O(k·d) per sum.
class DirectHistory final : public History {
 public:
  /// Throws std::invalid_argument if the order is not finite, dimension < 1 or capacity < 1.
  DirectHistory(ConvolutionQuadrature quadrature, Eigen::Index dimension, std::size_t capacity);
  /// Grünwald–Letnikov weights of `order`.
  DirectHistory(double order, Eigen::Index dimension, std::size_t capacity)
      : DirectHistory(grunwald_letnikov(order), dimension, capacity) {}

  void push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) override;
  void sum(Eigen::Ref<Eigen::VectorXd> out) const override;
  void clear() override { size_ = 0; }
  [[nodiscard]] std::size_t size() const override { return size_; }
  [[nodiscard]] std::size_t capacity() const override { return weights_.size(); }
  [[nodiscard]] std::string_view kind() const override { return "direct"; }
  [[nodiscard]] std::size_t memory_bytes() const override {
    return (weights_.size() + values_.size()) * sizeof(double);
  }
  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }
  [[nodiscard]] ConvolutionQuadrature quadrature() const override { return quadrature_; }
  [[nodiscard]] const std::vector<double>& weights() const { return weights_; }
  void visit_state(StateArchive& archive) override;

 private:
  ConvolutionQuadrature quadrature_;
  Eigen::Index dimension_;
  std::vector<double> weights_;  // c_0 … c_{capacity−1}
  std::vector<double> values_;   // row-major capacity × d: x̃_j at values_[j·d]
  std::size_t size_ = 0;
};

/// Integer orders 2α ∈ {0, 1, 2} of GL or BDF2: the weights are the coefficients of the
/// polynomial δ(ζ)^{2α} (ConvolutionQuadrature::local_weights()), so only a window of as many
/// values is kept (unbounded capacity).
class LocalHistory final : public History {
 public:
  /// Throws std::invalid_argument unless quadrature.is_local() and dimension ≥ 1.
  LocalHistory(ConvolutionQuadrature quadrature, Eigen::Index dimension);
  /// Grünwald–Letnikov weights of `order` ∈ {0, 1, 2}.
  LocalHistory(double order, Eigen::Index dimension)
      : LocalHistory(grunwald_letnikov(order), dimension) {}

  void push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) override;
  void sum(Eigen::Ref<Eigen::VectorXd> out) const override;
  void clear() override { size_ = 0; }
  [[nodiscard]] std::size_t size() const override { return size_; }
  [[nodiscard]] std::size_t capacity() const override;
  [[nodiscard]] std::string_view kind() const override { return "local"; }
  [[nodiscard]] std::size_t memory_bytes() const override {
    return static_cast<std::size_t>(window_.size()) * sizeof(double);
  }
  [[nodiscard]] Eigen::Index dimension() const override { return window_.rows(); }
  [[nodiscard]] ConvolutionQuadrature quadrature() const override { return quadrature_; }
  void visit_state(StateArchive& archive) override;

 private:
  ConvolutionQuadrature quadrature_;
  int width_;               // number of nonzero weights (≤ 5)
  double weights_[5];       // ω_0 … ω_{width−1}
  Eigen::MatrixXd window_;  // d × width, column (j mod width) holds x̃_j
  std::size_t size_ = 0;
};

enum class HistoryKind {
  /// LocalHistory for integer 2α; otherwise FastHistory when fast_history_pays(capacity, d)
  /// (from capacity ≥ kFastHistoryCrossover = 2048, measured for whole runs in
  /// bench/history_crossover.py, fit included; earlier for large d; see bench/RESULTS.md), else
  /// DirectHistory.
  kAuto,
  kDirect,  ///< DirectHistory always (e.g. to check Lemma 5.3 against the full sum)
  kFast,    ///< LocalHistory for integer 2α, FastHistory otherwise
};

/// "auto", "direct", "fast" (the names of problem files and the Python module).
std::optional<HistoryKind> parse_history_kind(std::string_view name);
std::string_view to_string(HistoryKind kind);

/// The history for the weights of `quadrature`, able to take `capacity` pushes. `tolerance` is
/// the per-weight relative accuracy ε of a FastHistory. Throws std::invalid_argument for invalid
/// arguments (before any step), e.g. a fast trapezoidal history (no fit for its oscillating tail).
std::unique_ptr<History> make_history(HistoryKind kind, const ConvolutionQuadrature& quadrature,
                                      Eigen::Index dimension, std::size_t capacity,
                                      double tolerance = 1e-10);
/// The same for the Grünwald–Letnikov weights of `order` (the paper's scheme).
inline std::unique_ptr<History> make_history(HistoryKind kind, double order, Eigen::Index dimension,
                                             std::size_t capacity, double tolerance = 1e-10) {
  return make_history(kind, grunwald_letnikov(order), dimension, capacity, tolerance);
}

}  // namespace fracvi
