#include "fracvi/memory/block_history.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "fracvi/fractional/convolution.hpp"
#include "fracvi/internal/parallel.hpp"
#include "fracvi/internal/ring_window.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/memory/fast_history.hpp"

namespace fracvi {

namespace {

void check_sizes(const char* who, Eigen::Index dimension, std::size_t capacity) {
  if (dimension < 1 || capacity < 1) {
    throw std::invalid_argument(std::string(who) + ": dimension = " + std::to_string(dimension) +
                                " and capacity = " + std::to_string(capacity) + " must be >= 1");
  }
}

// The terms of accumulate_causal() for blocks: w[m] * z(j) is the pair (W_m, Z_j), and the
// accumulator adds Z_j W_mᵀ to the d × s output (out(r, c) += Σ_e W_m(c, e) Z_j(r, e)) in plain
// loops: an Eigen product here would evaluate into a heap temporary (or need noalias(), which the
// shared loop cannot say), and per-block product calls cost more than the s² axpys themselves.
struct BlockTerm {
  const double* w;  // W_m, s × s column-major
  const double* z;  // Z_j, d × s column-major
};
struct BlockWeightRef {
  const double* w;
};
struct BlockValueRef {
  const double* z;
};
inline BlockTerm operator*(BlockWeightRef w, BlockValueRef z) {
  return {w.w, z.z};
}

struct BlockWeightSequence {
  const double* data;
  std::size_t block;  // s²
  BlockWeightRef operator[](std::size_t m) const { return {data + m * block}; }
};

struct BlockAccumulator {
  double* out;
  Eigen::Index out_stride;
  Eigen::Index d;
  Eigen::Index s;
  void operator+=(const BlockTerm& t) const {
    for (Eigen::Index c = 0; c < s; ++c) {
      double* __restrict o = out + c * out_stride;
      for (Eigen::Index e = 0; e < s; ++e) {
        const double w = t.w[c + e * s];
        const double* __restrict z = t.z + e * d;
        for (Eigen::Index r = 0; r < d; ++r) o[r] += w * z[r];
      }
    }
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// DirectBlockHistory

DirectBlockHistory::DirectBlockHistory(const RungeKuttaCq& quadrature, Eigen::Index dimension,
                                       std::size_t capacity)
    : quadrature_(quadrature), dimension_(dimension), capacity_(capacity) {
  quadrature.validate();
  check_sizes("DirectBlockHistory", dimension, capacity);
  weights_ = quadrature.weights(capacity);
  values_.assign(
      capacity * static_cast<std::size_t>(dimension) * static_cast<std::size_t>(quadrature.stages),
      0.0);
}

void DirectBlockHistory::push(const Eigen::Ref<const Eigen::MatrixXd>& block) {
  assert(size_ < capacity_ && block.rows() == dimension_ && block.cols() == quadrature_.stages);
  const Eigen::Index s = quadrature_.stages;
  Eigen::Map<Eigen::MatrixXd>(values_.data() + size_ * static_cast<std::size_t>(dimension_ * s),
                              dimension_, s) = block;
  ++size_;
}

void DirectBlockHistory::sum(Eigen::Ref<Eigen::MatrixXd> out) const {
  assert(size_ >= 1 && out.rows() == dimension_ && out.cols() == quadrature_.stages);
  // Σ_{j=0}^{k} Z_j W_{k−j}ᵀ through the one direct-sum loop of the library (oldest block first).
  const std::size_t k = size_ - 1;
  const Eigen::Index s = quadrature_.stages;
  const auto block = static_cast<std::size_t>(dimension_ * s);
  out.setZero();
  accumulate_causal(
      BlockWeightSequence{weights_.data().data(), static_cast<std::size_t>(s * s)}, k,
      [&](std::size_t j) { return BlockValueRef{values_.data() + j * block}; },
      BlockAccumulator{out.data(), out.outerStride(), dimension_, s});
}

void DirectBlockHistory::visit_state(StateArchive& archive) {
  archive.expect("block_direct.dimension", static_cast<std::size_t>(dimension_));
  archive.expect("block_direct.stages", static_cast<std::size_t>(quadrature_.stages));
  archive.expect("block_direct.capacity", capacity_);
  archive.count("block_direct.size", size_);
  if (size_ > capacity_) {
    throw CheckpointError("checkpoint record 'block_direct.size' exceeds capacity");
  }
  // Only the pushed blocks: the rest of the buffer is never read before it is pushed again.
  const auto block = static_cast<std::size_t>(dimension_ * quadrature_.stages);
  archive.doubles("block_direct.values", std::span<double>(values_.data(), size_ * block));
}

// ---------------------------------------------------------------------------------------------
// FastBlockHistory

namespace {

std::shared_ptr<const RkcqTail> checked_tail(std::shared_ptr<const RkcqTail> tail, std::size_t lag,
                                             Eigen::Index dimension, std::size_t capacity) {
  if (!tail) throw std::invalid_argument("FastBlockHistory: tail is null");
  check_sizes("FastBlockHistory", dimension, capacity);
  if (tail->stages < 1 || tail->stages > 4) {
    throw std::invalid_argument("FastBlockHistory: the tail has " + std::to_string(tail->stages) +
                                " stages (1 … 4 supported)");
  }
  if (lag >= tail->window || tail->head.size() != tail->window) {
    throw std::invalid_argument("FastBlockHistory: lag = " + std::to_string(lag) +
                                " must be below the tail's window " + std::to_string(tail->window));
  }
  if (tail->max_lag < lag || tail->max_lag - lag < capacity - 1) {
    throw std::invalid_argument(
        "FastBlockHistory: the tail covers lags up to max_lag = " + std::to_string(tail->max_lag) +
        " but capacity = " + std::to_string(capacity) + " and lag = " + std::to_string(lag) +
        " need lags up to capacity - 1 + lag");
  }
  return tail;
}

}  // namespace

namespace internal {

// The stage at position e of the kernels' order: the unit stage p first, then the others in
// ascending order (the identity without a unit stage, p = s).
constexpr Eigen::Index stage_in_kernel_order(Eigen::Index e, Eigen::Index p, Eigen::Index s) {
  if (p >= s) return e;
  return e == 0 ? p : (e <= p ? e - 1 : e);
}

}  // namespace internal

Eigen::Index FastBlockHistory::choose_unit_stage(const RkcqTail& tail) {
  // The stage whose coefficient is smallest against its term's largest, at its worst over the
  // terms, is the largest; it is scaled to 1 when that ratio is above 1e-8 (so the scaled
  // states stay within 10^8 of the plain ones; any ratio would keep the relative rounding, only
  // overflow is avoided). Otherwise none: s. Ties go to the first stage.
  const auto s = static_cast<Eigen::Index>(tail.stages);
  Eigen::Index best = s;
  double best_ratio = 1e-8;
  for (Eigen::Index p = 0; p < s; ++p) {
    double worst = std::numeric_limits<double>::infinity();
    for (const Eigen::VectorXd& v : tail.right) {
      const double largest = v.cwiseAbs().maxCoeff();
      worst = std::min(worst, largest > 0.0 ? std::abs(v(p)) / largest : 0.0);
    }
    if (worst > best_ratio) {
      best = p;
      best_ratio = worst;
    }
  }
  return best;
}

FastBlockHistory::FastBlockHistory(std::shared_ptr<const RkcqTail> tail, std::size_t lag,
                                   Eigen::Index dimension, std::size_t capacity)
    : tail_(checked_tail(std::move(tail), lag, dimension, capacity)),
      lag_(lag),
      capacity_(capacity),
      run_ahead_(*this, {kParallelWork, kRunAheadWork, kBalancedRunAheadFrom}) {
  const Eigen::Index s = tail_->stages;
  stages_ = s;
  window_ = static_cast<Eigen::Index>(tail_->window - lag);
  head_.resize(window_ * s, s);
  for (Eigen::Index t = 0; t < window_; ++t) {
    // Ring position t (oldest first) holds Z_{k−(n0−1−t)}: weight W_{lag+n0−1−t}.
    head_.middleRows(t * s, s) =
        tail_->head[static_cast<std::size_t>(static_cast<Eigen::Index>(tail_->window) - 1 - t)]
            .transpose();
  }
  ring_.setZero(dimension, window_ * s);
  const auto k = static_cast<Eigen::Index>(tail_->terms());
  decay_.resize(k);
  right_.resize(k, s);
  left_.resize(k, s);
  unit_stage_ = choose_unit_stage(*tail_);
  for (Eigen::Index i = 0; i < k; ++i) {
    const auto u = static_cast<std::size_t>(i);
    decay_(i) = tail_->decays[u];
    const Eigen::VectorXd& v = tail_->right[u];
    // Y_i kept as Y_i / (v_i)_p: the unit stage enters every recursion with the coefficient 1 (one
    // multiply–add fewer per term), γ_i (u_i)_c (v_i)_p weighs it into the outputs.
    const double scale = unit_stage_ < s ? v(unit_stage_) : 1.0;
    for (Eigen::Index e = 0; e < s; ++e)
      right_(i, e) = v(internal::stage_in_kernel_order(e, unit_stage_, s)) / scale;
    left_.row(i) = (tail_->gammas[u] * scale) * tail_->left[u].transpose();
  }
  state_.setZero(dimension, k);
  partial_.setZero(dimension, s);
  step_partial_.setZero(dimension, s);
  sum_.setZero(dimension, s);
  run_ahead_.configure(0, dimension, push_work());
}

namespace internal {

// One block of rows of FastBlockHistory::push() (the columns of every array are d long; the
// pointers are offset to the block's first row).
struct BlockHistoryRows {
  Eigen::Index rows, terms, window, ld, block_ld;
  Eigen::Index slot, first;  // ring positions of Z_{k−n0} (taken by Z_k) and of the window's start
  double* state;             // d × K: column i is Y_i
  double* ring;              // d × (n0·s): column t·s + e is stage e at ring position t
  double* partial;           // d × s: the sum but for the terms with Z_k (newest_start())
  double* sum;               // d × s
  const double* block;       // Z_k, d × s with column stride block_ld (null: run ahead)
  const double* decay;       // r_i
  const double* right;  // K × s: (v_i)_e at e·K + i, the stages in kernel order (step_columns)
  const double* left;   // K × s: γ_i (u_i)_c at c·K + i
  Eigen::Index unit_stage;  // the stage first in kernel order (FastBlockHistory::unit_stage_)
  const double* head;       // (n0·s) × s: column c holds the window's weights of output c
};

}  // namespace internal

using internal::BlockHistoryRows;

namespace {

// The window's n0·s columns (oldest first) are added in groups of four, then the remainder one by
// one. Only the last s columns hold Z_k, so the additions are split before the first that
// involves one of them — the last group of four (s ≤ 4 columns fit in it) or, past the groups,
// the first of the last s — and push k + 1's recursions and older window can run on the second
// thread while the caller computes step k + 1 (internal/run_ahead.hpp). One thread makes both
// parts in a row: the same additions in the same order.
Eigen::Index newest_start(Eigen::Index width, Eigen::Index s) {
  const Eigen::Index grouped = width / 4 * 4, first_new = width - s;
  return first_new < grouped ? first_new / 4 * 4 : first_new;
}

// The window's column q (oldest first) is ring column first·s + q, wrapped at n0·s (the ring
// holds each block once, as FastHistory's: fast_history.hpp).
inline const double* window_column(const BlockHistoryRows& blk, Eigen::Index s, Eigen::Index q) {
  return internal::ring_window_column(blk.ring, blk.ld, blk.window * s, blk.first * s, q);
}

// One group of four window columns q … q + 3 (oldest first) into the s outputs: out[c] = in[c] +
// their terms (in = out: in place).
template <int S>
[[gnu::always_inline]] inline void window_group(const BlockHistoryRows& blk,
                                                const double* const* in, double* const* out,
                                                Eigen::Index q) {
  const Eigen::Index n = blk.rows, width = blk.window * S;
  const double* c0 = window_column(blk, S, q);
  const double* c1 = window_column(blk, S, q + 1);
  const double* c2 = window_column(blk, S, q + 2);
  const double* c3 = window_column(blk, S, q + 3);
  double h[S][4];
  for (int c = 0; c < S; ++c)
    for (int j = 0; j < 4; ++j) h[c][j] = blk.head[c * width + q + j];
  FRACVI_INDEPENDENT_ITERATIONS
  for (Eigen::Index r = 0; r < n; ++r) {
    const double z0 = c0[r], z1 = c1[r], z2 = c2[r], z3 = c3[r];
    // One multiply–add a term, oldest first (the pairwise form took six operations for four).
    for (int c = 0; c < S; ++c) {
      double o = in[c][r] + h[c][0] * z0;
      o += h[c][1] * z1;
      o += h[c][2] * z2;
      out[c][r] = o + h[c][3] * z3;
    }
  }
}

// One window column q into the s outputs: out[c] = in[c] + its term.
template <int S>
[[gnu::always_inline]] inline void window_single(const BlockHistoryRows& blk,
                                                 const double* const* in, double* const* out,
                                                 Eigen::Index q) {
  const Eigen::Index n = blk.rows, width = blk.window * S;
  const double* col = window_column(blk, S, q);
  for (int c = 0; c < S; ++c) {
    const double weight = blk.head[c * width + q];
    const double* src = in[c];
    double* dst = out[c];
    FRACVI_INDEPENDENT_ITERATIONS
    for (Eigen::Index r = 0; r < n; ++r) dst[r] = src[r] + weight * col[r];
  }
}

// Window columns [begin, end) in place onto `out`, in the order of the whole window's loop (groups
// of four from a multiple of four, then one by one).
template <int S>
[[gnu::always_inline]] inline void add_window(const BlockHistoryRows& blk, double* const* out,
                                              Eigen::Index begin, Eigen::Index end) {
  const Eigen::Index grouped_end = std::min(end, blk.window * S / 4 * 4);
  Eigen::Index q = begin;
  for (; q + 4 <= grouped_end; q += 4) window_group<S>(blk, out, out, q);
  for (; q < end; ++q) window_single<S>(blk, out, out, q);
}

// Four recursions i … i + 3 over the rows, their terms added to the outputs; the first group
// (kFirst) adds them to 0 instead of reading the outputs: 0 + t is the same number as a zeroed
// output plus t, −0 included, without a pass that zeroes them. kSteps pushes in one pass
// (older_rows_two_steps): push k + t's leaving block x[t] enters after push k + t − 1's, its
// terms going to out[t]; each element sees the one-step operations of push k, then of push
// k + 1, in that order, so the numbers are those of one-step passes bit for bit. kUnit: the
// first stage in kernel order enters with the coefficient 1 (FastBlockHistory::unit_stage_), so
// a term costs 2s multiply–adds instead of 2s + 1.
template <int S, int kSteps>
struct StepColumns {
  const double* x[kSteps][S];  // the stage vectors of Z_{k+t−n0}, leaving the window at push k + t
  double* out[kSteps][S];      // push k + t's outputs
};

// A recursion's new value: r Y + Σ_e v_e z_e, the stages in kernel order.
template <int S, bool kUnit>
[[gnu::always_inline]] inline double recurse(double a, const double* v, double y,
                                             const double* const* x, Eigen::Index r) {
  double w = kUnit ? a * y + x[0][r] : a * y + v[0] * x[0][r];
  for (int e = 1; e < S; ++e) w += v[e] * x[e][r];
  return w;
}

template <int S, bool kUnit, bool kFirst, int kSteps>
[[gnu::always_inline]] inline void recursion_group(const BlockHistoryRows& blk,
                                                   const StepColumns<S, kSteps>& in,
                                                   Eigen::Index i) {
  const Eigen::Index n = blk.rows, ld = blk.ld, terms = blk.terms;
  // Local copies: a store through an output could otherwise alias the pointers themselves.
  const double* x[kSteps][S];
  double* out[kSteps][S];
  for (int t = 0; t < kSteps; ++t) {
    for (int c = 0; c < S; ++c) {
      x[t][c] = in.x[t][c];
      out[t][c] = in.out[t][c];
    }
  }
  double* y0 = blk.state + i * ld;
  double* y1 = y0 + ld;
  double* y2 = y1 + ld;
  double* y3 = y2 + ld;
  double a[4], v[4][S], u[4][S];
  for (int j = 0; j < 4; ++j) {
    a[j] = blk.decay[i + j];
    for (int e = 0; e < S; ++e) v[j][e] = blk.right[e * terms + i + j];
    for (int c = 0; c < S; ++c) u[j][c] = blk.left[c * terms + i + j];
  }
  FRACVI_INDEPENDENT_ITERATIONS
  for (Eigen::Index r = 0; r < n; ++r) {
    double w0 = y0[r], w1 = y1[r], w2 = y2[r], w3 = y3[r];
    for (int t = 0; t < kSteps; ++t) {
      w0 = recurse<S, kUnit>(a[0], v[0], w0, x[t], r);
      w1 = recurse<S, kUnit>(a[1], v[1], w1, x[t], r);
      w2 = recurse<S, kUnit>(a[2], v[2], w2, x[t], r);
      w3 = recurse<S, kUnit>(a[3], v[3], w3, x[t], r);
      // One multiply–add a term, in ascending i (the pairwise form took six operations for four).
      for (int c = 0; c < S; ++c) {
        double o = (kFirst ? 0.0 : out[t][c][r]) + u[0][c] * w0;
        o += u[1][c] * w1;
        o += u[2][c] * w2;
        out[t][c][r] = o + u[3][c] * w3;
      }
    }
    y0[r] = w0;
    y1[r] = w1;
    y2[r] = w2;
    y3[r] = w3;
  }
}

// The kernels for s stages. As FastHistory's kernels (fast_history.cpp), the loops run along the
// degrees of freedom (contiguous columns, no horizontal sums), and four recursions share one load
// and store of the s output columns: per term Y_i ← r_i Y_i + Σ_e (v_i)_e Z_{k−n0}(:, e) and
// out(:, c) += γ_i (u_i)_c Y_i, i.e. 2sK multiply–adds per degree of freedom (kUnit; one more a
// term without); then the window, n0·s columns against s outputs. (The layout of one degree of
// freedom per pass, with the loops over the K terms, ran at 4–7 times s scalar histories per step
// at d = 100 … 1000: bench/block_history_bench.cpp.)
// recursions: the recursions of kSteps pushes (push k + t fed with Z_{k+t−n0}), into their
// outputs.
template <int S, bool kUnit, int kSteps>
[[gnu::always_inline]] inline void recursions(const BlockHistoryRows& blk,
                                              const StepColumns<S, kSteps>& in) {
  const Eigen::Index n = blk.rows, ld = blk.ld, terms = blk.terms;
  Eigen::Index i = 0;
  if (terms >= 4) {
    recursion_group<S, kUnit, true, kSteps>(blk, in, 0);
    i = 4;
  } else {
    for (int t = 0; t < kSteps; ++t)
      for (int c = 0; c < S; ++c)
        for (Eigen::Index r = 0; r < n; ++r) in.out[t][c][r] = 0.0;
  }
  for (; i + 4 <= terms; i += 4) recursion_group<S, kUnit, false, kSteps>(blk, in, i);
  for (; i < terms; ++i) {
    double* y = blk.state + i * ld;
    const double a = blk.decay[i];
    double v[S], u[S];
    for (int e = 0; e < S; ++e) v[e] = blk.right[e * terms + i];
    for (int c = 0; c < S; ++c) u[c] = blk.left[c * terms + i];
    FRACVI_INDEPENDENT_ITERATIONS
    for (Eigen::Index r = 0; r < n; ++r) {
      double w = y[r];
      for (int t = 0; t < kSteps; ++t) {
        w = recurse<S, kUnit>(a, v, w, in.x[t], r);
        for (int c = 0; c < S; ++c) in.out[t][c][r] += u[c] * w;
      }
      y[r] = w;
    }
  }
}

// The stage vectors of ring position `position`, in kernel order (the unit stage first, then the
// others in ascending order), and the s output columns at `outputs`.
template <int S>
[[gnu::always_inline]] inline void step_columns(const BlockHistoryRows& blk, Eigen::Index position,
                                                double* outputs, const double** x, double** out) {
  for (int e = 0; e < S; ++e) {
    const Eigen::Index stage = internal::stage_in_kernel_order(e, blk.unit_stage, S);
    x[e] = blk.ring + (position * S + stage) * blk.ld;
  }
  for (int c = 0; c < S; ++c) out[c] = outputs + c * blk.ld;
}

// older_rows: the recursions (fed with Z_{k−n0}, which sits in the slot Z_k will take) and the
// window's columns before newest_start(), into `partial`.
template <int S, bool kUnit>
[[gnu::always_inline]] inline void older_rows(const BlockHistoryRows& blk) {
  StepColumns<S, 1> in;
  step_columns<S>(blk, blk.slot, blk.partial, in.x[0], in.out[0]);
  recursions<S, kUnit, 1>(blk, in);
  add_window<S>(blk, in.out[0], 0, newest_start(blk.window * S, S));
}

// Two pushes' recursions in one pass over the state (FastBlockHistory::push, when one thread
// runs them and no push is run ahead): Z_{k−n0} (ring position blk.slot) and Z_{k+1−n0}
// (`next_slot`) enter every Y_i, which is loaded and stored once; push k's terms go to
// blk.partial, push k + 1's to `next_partial`; then push k's older window.
template <int S, bool kUnit>
[[gnu::always_inline]] inline void older_rows_two_steps(const BlockHistoryRows& blk,
                                                        Eigen::Index next_slot,
                                                        double* next_partial) {
  StepColumns<S, 2> in;
  step_columns<S>(blk, blk.slot, blk.partial, in.x[0], in.out[0]);
  step_columns<S>(blk, next_slot, next_partial, in.x[1], in.out[1]);
  recursions<S, kUnit, 2>(blk, in);
  add_window<S>(blk, in.out[0], 0, newest_start(blk.window * S, S));
}

// The window's columns before newest_start() onto `partial` (push k + 1's, once Z_k is in the
// ring: blk.first its window's start).
template <int S>
[[gnu::always_inline]] inline void older_window(const BlockHistoryRows& blk) {
  double* out[S];
  for (int c = 0; c < S; ++c) out[c] = blk.partial + c * blk.ld;
  add_window<S>(blk, out, 0, newest_start(blk.window * S, S));
}

// newest_rows: Z_k enters the ring (once; Z_{k−n0}, read by older_rows, sat in the same slot), and
// the sum = partial + the window's columns from newest_start() on.
template <int S>
[[gnu::always_inline]] inline void newest_rows(const BlockHistoryRows& blk) {
  const Eigen::Index n = blk.rows, ld = blk.ld;
  for (int e = 0; e < S; ++e) {
    const double* z = blk.block + e * blk.block_ld;
    double* a = blk.ring + (blk.slot * S + e) * ld;
    for (Eigen::Index r = 0; r < n; ++r) a[r] = z[r];
  }
  const double* partial[S];
  double* out[S];
  for (int c = 0; c < S; ++c) {
    partial[c] = blk.partial + c * ld;
    out[c] = blk.sum + c * ld;
  }
  // The first addition from partial into the sum, the others in place.
  const Eigen::Index width = blk.window * S, q = newest_start(width, S);
  if (q + 4 <= width / 4 * 4) {
    window_group<S>(blk, partial, out, q);
    add_window<S>(blk, out, q + 4, width);
  } else {
    window_single<S>(blk, partial, out, q);
    add_window<S>(blk, out, q + 1, width);
  }
}

// The kernels of a push for S stages (s = 2, 3, 4: checked_tail() and RungeKuttaCq) with or
// without a unit stage, each with the x86-64-v3 clone; the recursions also as x86-64-v4 variants
// (kWide): a group of four holds 4(2s + 1) coefficients, which AVX2's 16 registers cannot keep
// (GCC reloads them from the stack each row: the loop was bound by loads), AVX-512's 32 can
// (bench/block_history_bench at d = 100 and 1000: s = 4 1.19–1.31× faster, s = 3 0.89–1.21×;
// bench/RESULTS.md 2026-12-02).
template <int S, bool kUnit, bool kWide>
struct Kernels;
template <int S, bool kUnit>
struct Kernels<S, kUnit, false> {
  FRACVI_HOT_KERNEL static void older(const BlockHistoryRows& blk) { older_rows<S, kUnit>(blk); }
  FRACVI_HOT_KERNEL static void older_two_steps(const BlockHistoryRows& blk, Eigen::Index next_slot,
                                                double* next_partial) {
    older_rows_two_steps<S, kUnit>(blk, next_slot, next_partial);
  }
};
template <int S, bool kUnit>
struct Kernels<S, kUnit, true> {
  FRACVI_WIDE_REGISTERS_KERNEL static void older(const BlockHistoryRows& blk) {
    older_rows<S, kUnit>(blk);
  }
  FRACVI_WIDE_REGISTERS_KERNEL static void older_two_steps(const BlockHistoryRows& blk,
                                                           Eigen::Index next_slot,
                                                           double* next_partial) {
    older_rows_two_steps<S, kUnit>(blk, next_slot, next_partial);
  }
};
// The window's passes (four columns a group: 4s weights) fit AVX2's registers.
template <int S>
struct WindowKernels {
  FRACVI_HOT_KERNEL static void window(const BlockHistoryRows& blk) { older_window<S>(blk); }
  FRACVI_HOT_KERNEL static void newest(const BlockHistoryRows& blk) { newest_rows<S>(blk); }
};

struct StageKernels {
  void (*older)(const BlockHistoryRows&);
  void (*older_two_steps)(const BlockHistoryRows&, Eigen::Index, double*);
  void (*window)(const BlockHistoryRows&);
  void (*newest)(const BlockHistoryRows&);
};
template <int S, bool kUnit, bool kWide>
constexpr StageKernels kStageKernels{Kernels<S, kUnit, kWide>::older,
                                     Kernels<S, kUnit, kWide>::older_two_steps,
                                     WindowKernels<S>::window, WindowKernels<S>::newest};
template <int S, bool kUnit>
StageKernels kernels_of(bool wide) {
  return wide ? kStageKernels<S, kUnit, true> : kStageKernels<S, kUnit, false>;
}
template <int S>
StageKernels kernels_of(bool unit, bool wide) {
  return unit ? kernels_of<S, true>(wide) : kernels_of<S, false>(wide);
}
StageKernels stage_kernels(Eigen::Index s, bool unit) {
  const bool wide = internal::wide_registers();
  if (s == 2) return kernels_of<2>(unit, wide);
  if (s == 3) return kernels_of<3>(unit, wide);
  return kernels_of<4>(unit, wide);
}

// Blocks of kBlock rows keep the s output columns in L1 while the K recursions pass over them.
constexpr Eigen::Index kBlock = 256;

}  // namespace

internal::BlockHistoryRows FastBlockHistory::rows(Eigen::Index b, Eigen::Index n,
                                                  Eigen::Index terms, Eigen::Index slot,
                                                  Eigen::Index first,
                                                  const Eigen::Ref<const Eigen::MatrixXd>* block) {
  return {n,
          terms,
          window_,
          sum_.rows(),
          block != nullptr ? block->outerStride() : 0,
          slot,
          first,
          state_.data() + b,
          ring_.data() + b,
          partial_.data() + b,
          sum_.data() + b,
          block != nullptr ? block->data() + b : nullptr,
          decay_.data(),
          right_.data(),
          left_.data(),
          unit_stage_,
          head_.data()};
}

void FastBlockHistory::run_ahead(Eigen::Index lo, Eigen::Index hi, Eigen::Index leaving_slot,
                                 Eigen::Index first) {
  const Eigen::Index terms = decay_.size();
  const auto older = stage_kernels(stages_, unit_stage_ < stages_).older;
  for (Eigen::Index b = lo; b < hi; b += kBlock)
    older(rows(b, std::min(kBlock, hi - b), terms, leaving_slot, first, nullptr));
}

void FastBlockHistory::push(const Eigen::Ref<const Eigen::MatrixXd>& block) {
  assert(size_ < capacity_ && block.rows() == sum_.rows() && block.cols() == stages_);
  const Eigen::Index n0 = window_, terms = decay_.size(), d = sum_.rows();
  const auto window = static_cast<std::size_t>(n0);
  const auto slot = static_cast<Eigen::Index>(size_ % window);
  const bool recurse = size_ >= window;
  // After the push the last n0 blocks Z_{k−n0+1} … Z_k sit at ring positions first … first + n0 − 1
  // (each position s columns); before k = n0 − 1 the missing ones are the zeros the ring was
  // cleared to.
  const auto first = static_cast<Eigen::Index>((size_ + 1) % window);
  const StageKernels kernels = stage_kernels(stages_, unit_stage_ < stages_);
  const internal::RunAhead::Turn turn = run_ahead_.begin(size_, window, capacity_);
  // One thread runs this push's recursions and no thread runs the next push's: run both in one
  // pass over the state (older_rows_two_steps), Z_{k+1−n0} being at ring position `first`, and the
  // next push's older window once Z_k is in the ring (it ends before Z_{k+1}: newest_start()) —
  // what the run-ahead thread would have done, into partial_; the next push then runs as one run
  // ahead (the same numbers). This push's own partial sum goes to step_partial_. Two stages, and
  // three and four with the wide-register kernels: at s = 2 the pass is bound by moving the state,
  // and two steps ran 1.08–1.21× faster (bench/block_history_bench, d = 100 and 1000); with three
  // and four stages the AVX2 kernels are bound by reloading their coefficients (3 % slower to 2 %
  // faster, and 5 % slower at s = 4, d = 1000), the x86-64-v4 ones 0.96–1.19× (s = 4, faster in
  // five rounds of six; s = 3 even; bench/RESULTS.md 2026-12-02).
  const bool two_steps = (stages_ == 2 || internal::wide_registers()) && recurse && !turn.ahead &&
                         turn.split == 1 && !turn.post_next && size_ + 1 < capacity_ && n0 >= 2;
  const auto next_first = static_cast<Eigen::Index>((size_ + 2) % window);
  auto update = [&](Eigen::Index lo, Eigen::Index hi) {
    for (Eigen::Index b = lo; b < hi; b += kBlock) {
      const Eigen::Index n = std::min(kBlock, hi - b);
      BlockHistoryRows blk = rows(b, n, recurse ? terms : 0, slot, first, &block);
      if (two_steps) {
        blk.partial = step_partial_.data() + b;
        kernels.older_two_steps(blk, first, partial_.data() + b);
      } else if (!turn.ahead) {
        kernels.older(blk);
      }
      kernels.newest(blk);
      if (two_steps) kernels.window(rows(b, n, terms, first, next_first, nullptr));
    }
  };
  // A team of two runs the next push ahead (the caller only makes the window's last additions);
  // a larger team splits the rows.
  internal::for_blocks(d, turn.split, update);
  ++size_;
  run_ahead_.end(turn, static_cast<Eigen::Index>(size_ % window), next_first);
  if (two_steps) run_ahead_.set_ahead(true);
}

void FastBlockHistory::sum(Eigen::Ref<Eigen::MatrixXd> out) const {
  assert(size_ >= 1 && out.rows() == sum_.rows() && out.cols() == sum_.cols());
  out = sum_;  // formed by push()
}

void FastBlockHistory::set_threads(int threads) {
  run_ahead_.configure(threads, sum_.rows(), push_work());
}

void FastBlockHistory::set_run_ahead_rows(Eigen::Index rows) {
  if (rows < 0) {
    throw std::invalid_argument("FastBlockHistory: run-ahead rows = " + std::to_string(rows) +
                                " must be >= 0 (0: balanced by timing)");
  }
  run_ahead_.set_fixed_rows(rows);
}

void FastBlockHistory::visit_state(StateArchive& archive) {
  // The tail's fit is rebuilt by the constructor from the same options (the shared cache); its
  // sizes are checked so that a checkpoint of another fit is refused.
  archive.expect("block_fast.dimension", static_cast<std::size_t>(sum_.rows()));
  archive.expect("block_fast.stages", static_cast<std::size_t>(stages_));
  archive.expect("block_fast.capacity", capacity_);
  archive.expect("block_fast.window", static_cast<std::size_t>(window_));
  archive.expect("block_fast.terms", static_cast<std::size_t>(decay_.size()));
  // The recursions are kept as Y_i / (v_i)_p for the unit stage p (s: none).
  archive.expect("block_fast.unit_stage", static_cast<std::size_t>(unit_stage_));
  archive.count("block_fast.size", size_);
  if (size_ > capacity_) {
    throw CheckpointError("checkpoint record 'block_fast.size' exceeds capacity");
  }
  run_ahead_.finish();
  // Records of the degree-of-freedom-major layout (ring and recursions as d × … columns): the
  // names differ from those of the earlier transposed layout and of the unscaled recursions, so
  // that their checkpoints are refused by name rather than restored transposed or unscaled.
  archive.dense("block_fast.ring_by_stage", ring_);
  archive.dense("block_fast.scaled_recursions_by_term", state_);
  archive.dense("block_fast.partial", partial_);
  archive.dense("block_fast.sum", sum_);
  // Whether the recursions and `partial` already include the next push's (run ahead).
  bool ahead = run_ahead_.ahead();
  archive.flag("block_fast.ahead", ahead);
  if (ahead != run_ahead_.ahead()) run_ahead_.set_ahead(ahead);  // restored
  if (ahead && (size_ < static_cast<std::size_t>(window_) || size_ >= capacity_)) {
    throw CheckpointError("checkpoint record 'block_fast.ahead' is set where no push runs ahead");
  }
}

void FastBlockHistory::clear() {
  run_ahead_.finish();
  ring_.setZero();
  state_.setZero();
  partial_.setZero();
  step_partial_.setZero();
  sum_.setZero();
  size_ = 0;
  run_ahead_.reset();
}

// ---------------------------------------------------------------------------------------------
// Tail cache and factories

namespace {

using TailKey = std::tuple<int, double, double, std::size_t, std::size_t, bool>;

struct TailCache {
  std::mutex mutex;
  std::map<TailKey, std::shared_ptr<const RkcqTail>> tails;
};

TailCache& tail_cache() {
  static TailCache cache;
  return cache;
}

}  // namespace

std::shared_ptr<const RkcqTail> shared_rkcq_tail(const RkcqTailOptions& options) {
  // A NaN would compare equivalent to every key of the map: reject before the lookup.
  if (!std::isfinite(options.order) || !std::isfinite(options.tolerance)) {
    throw std::invalid_argument("shared_rkcq_tail: order and tolerance must be finite");
  }
  const TailKey key{options.stages,  options.order,  options.tolerance,
                    options.max_lag, options.window, options.compress};
  TailCache& cache = tail_cache();
  {
    const std::lock_guard<std::mutex> lock(cache.mutex);
    const auto it = cache.tails.find(key);
    if (it != cache.tails.end()) return it->second;
  }
  // Fit outside the lock; if another thread got there first, keep its tail.
  auto tail = std::make_shared<const RkcqTail>(fit_rkcq_tail(options));
  const std::lock_guard<std::mutex> lock(cache.mutex);
  return cache.tails.emplace(key, std::move(tail)).first->second;
}

void clear_rkcq_tail_cache() {
  TailCache& cache = tail_cache();
  const std::lock_guard<std::mutex> lock(cache.mutex);
  cache.tails.clear();
}

std::size_t rkcq_tail_cache_size() {
  TailCache& cache = tail_cache();
  const std::lock_guard<std::mutex> lock(cache.mutex);
  return cache.tails.size();
}

std::unique_ptr<BlockHistory> make_fast_block_history(const RungeKuttaCq& quadrature,
                                                      Eigen::Index dimension, std::size_t capacity,
                                                      double tolerance) {
  quadrature.validate();
  check_sizes("make_fast_block_history", dimension, capacity);
  const std::size_t lag = quadrature.lag;
  if (quadrature.is_local()) {
    // W_j = 0 for j > β: the exact blocks W_0 … W_{window−1} with window ≥ 3 cover every nonzero
    // one, and no tail term is needed for any lag.
    auto tail = std::make_shared<RkcqTail>();
    tail->stages = quadrature.stages;
    tail->order = quadrature.order;
    tail->window = std::max<std::size_t>(3, lag + 1);
    tail->max_lag = std::numeric_limits<std::size_t>::max();
    tail->head = RungeKuttaCq{quadrature.stages, quadrature.order}.weights(tail->window);
    return std::make_unique<FastBlockHistory>(std::move(tail), lag, dimension, capacity);
  }
  if (lag > (std::size_t{1} << 40)) {
    throw std::invalid_argument("make_fast_block_history: lag = " + std::to_string(lag) +
                                " is too large");
  }
  RkcqTailOptions options;
  options.stages = quadrature.stages;
  options.order = quadrature.order;
  options.tolerance = tolerance;
  options.window = kBlockHistoryWindow + lag;
  options.max_lag = fast_history_fit_lag(capacity) + lag;
  return std::make_unique<FastBlockHistory>(shared_rkcq_tail(options), lag, dimension, capacity);
}

bool fast_block_history_pays(std::size_t capacity, Eigen::Index dimension, int stages) {
  // Measured (docs/theory/fast_history.md, "Block history"; whole runs of push + sum, the fit
  // included, s = 2 … 4, β = 0.5): at d = 1 the two are even near N = 4096 (direct 0.06–0.15 s,
  // fast 0.06–0.17 s); at d = 100 the fast one wins from N = 1024 (0.02–0.03 s against
  // 0.04–0.16 s). Model in multiply–adds: direct run N²·d·s²/2 against the fast run
  // N·d·(K(2s + 1) + n0·s²), K ≈ 50, plus the fit counted as 10^8.
  if (capacity >= kBlockFastHistoryCrossover) return true;
  const auto n = static_cast<double>(capacity), d = static_cast<double>(dimension);
  const auto s = static_cast<double>(stages);
  const double direct = 0.5 * n * n * d * s * s;
  const double fast = n * d * (50.0 * (2.0 * s + 1.0) + 16.0 * s * s) + 1e8;
  return direct > fast;
}

std::unique_ptr<BlockHistory> make_block_history(HistoryKind kind, const RungeKuttaCq& quadrature,
                                                 Eigen::Index dimension, std::size_t capacity,
                                                 double tolerance) {
  quadrature.validate();
  check_sizes("make_block_history", dimension, capacity);
  if (kind == HistoryKind::kDirect) {
    return std::make_unique<DirectBlockHistory>(quadrature, dimension, capacity);
  }
  if (kind == HistoryKind::kFast || quadrature.is_local() ||
      fast_block_history_pays(capacity, dimension, quadrature.stages)) {
    return make_fast_block_history(quadrature, dimension, capacity, tolerance);
  }
  return std::make_unique<DirectBlockHistory>(quadrature, dimension, capacity);
}

}  // namespace fracvi
