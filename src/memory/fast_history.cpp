#include "fracvi/memory/fast_history.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "fracvi/internal/float_environment.hpp"
#include "fracvi/internal/parallel.hpp"
#include "fracvi/internal/ring_window.hpp"
#include "fracvi/internal/vectorize.hpp"

namespace fracvi {

// One block of rows of FastHistory::push(): the K recursions Y_j ← e^{−λ_j} Y_j + x̃_{k−n0} with
// the tail Σ_j w_j Y_j, then the sum = tail + the window's exact weights against the last n0
// values. Plain loops over restrict pointers (the Eigen block expressions of the same loop ran at
// half the speed; Eigen's gemv for the window is a separate pass over the block).
namespace internal {

struct FastHistoryBlock {
  Eigen::Index rows, terms, state_stride, window, ring_stride;
  // The ring column of x̃_{k−n0+1}, the window's oldest value; the window's value c (oldest first)
  // is in column (first + c) mod n0 (window_column()).
  Eigen::Index first;
  double* state;
  double* tail;
  double* sum;
  const double* leaving;   // x̃_{k−n0}: ring column `slot`, overwritten by x̃_k below
  const double* entering;  // x̃_k
  double* slot;            // its ring column
  const double* ring;      // the ring's first column (at this block's first row)
  const double* decay;
  const double* weights;
  const double* head_reversed;
};

// The ring column of the window's value c (0 = the oldest): the ring holds each value once, in
// column j mod n0 for x̃_j, so the window wraps around its end.
inline const double* window_column(const FastHistoryBlock& blk, Eigen::Index c) {
  return ring_window_column(blk.ring, blk.ring_stride, blk.window, blk.first, c);
}

}  // namespace internal

namespace {

std::shared_ptr<const ExponentialFit> checked_fit(std::shared_ptr<const ExponentialFit> fit,
                                                  Eigen::Index dimension, std::size_t capacity) {
  if (!fit) throw std::invalid_argument("FastHistory: fit is null");
  if (dimension < 1 || capacity < 1) {
    throw std::invalid_argument("FastHistory: dimension = " + std::to_string(dimension) +
                                " and capacity = " + std::to_string(capacity) + " must be >= 1");
  }
  if (fit->max_lag < capacity - 1) {
    throw std::invalid_argument(
        "FastHistory: the fit covers lags up to max_lag = " + std::to_string(fit->max_lag) +
        " but capacity = " + std::to_string(capacity) + " needs lags up to capacity - 1");
  }
  return fit;
}

// These kernels are most of a step of a large system (bench/RESULTS.md): they carry an x86-64-v3
// clone (internal/vectorize.hpp). The restrict pointers live in the scope of one loop each:
// x̃_{k−n0} and the slot x̃_k takes are the same memory, read by the recursions and written by the
// window's pass. Four recursions (and four window columns) share one load and store of the tail
// (the sum): the loop is bound by loads and stores, not by multiply–adds (perf: one recursion per
// pass ran at ≈ 2 stores per multiply–add pair). The two passes are separate kernels because the
// second thread of a team of two runs the first one step ahead (fast_history.hpp); one thread runs
// them block by block, so that the tail's block is still in L1 for the window.
// Four recursions j … j + 3 over the block's rows, their terms added to the tail; the first
// group (kFirst) adds them to 0 instead of reading the tail: 0 + s is the same number as a zeroed
// tail plus s, −0 included (an assignment of s would keep −0), without a pass that zeroes it.
// kSteps pushes in one pass (recursion_block_steps): push k + s's leaving value x̃_{k+s−n0}
// (`in.leaving[s]`, s = 0 being blk.leaving) enters after push k + s − 1's, its terms going to
// `in.tail[s]`; each element sees the one-step operations of push k, then of push k + 1, …, in
// that order, so the numbers are those of kSteps one-step passes bit for bit.
template <int kSteps>
struct StepInputs {
  const double* leaving[kSteps];
  double* tail[kSteps];
};

template <bool kFirst, int kSteps>
[[gnu::always_inline]] inline void recursion_group(const internal::FastHistoryBlock& blk,
                                                   Eigen::Index j, const StepInputs<kSteps>& in) {
  const Eigen::Index n = blk.rows, stride = blk.state_stride;
  // Local copies: a store through a tail could otherwise alias the pointers themselves.
  const double* x[kSteps];
  double* tail[kSteps];
  for (int s = 0; s < kSteps; ++s) {
    x[s] = in.leaving[s];
    tail[s] = in.tail[s];
  }
  // Four columns of one array: restrict pointers would not vectorise (vectorize.hpp).
  double* y0 = blk.state + j * stride;
  double* y1 = blk.state + (j + 1) * stride;
  double* y2 = blk.state + (j + 2) * stride;
  double* y3 = blk.state + (j + 3) * stride;
  const double a0 = blk.decay[j], a1 = blk.decay[j + 1], a2 = blk.decay[j + 2],
               a3 = blk.decay[j + 3];
  const double w0 = blk.weights[j], w1 = blk.weights[j + 1], w2 = blk.weights[j + 2],
               w3 = blk.weights[j + 3];
  FRACVI_INDEPENDENT_ITERATIONS
  for (Eigen::Index i = 0; i < n; ++i) {
    double v0 = y0[i], v1 = y1[i], v2 = y2[i], v3 = y3[i];
#pragma GCC unroll 4
    for (int s = 0; s < kSteps; ++s) {
      const double xs = x[s][i];
      v0 = a0 * v0 + xs;
      v1 = a1 * v1 + xs;
      v2 = a2 * v2 + xs;
      v3 = a3 * v3 + xs;
      tail[s][i] = (kFirst ? 0.0 : tail[s][i]) + ((w0 * v0 + w1 * v1) + (w2 * v2 + w3 * v3));
    }
    y0[i] = v0;
    y1[i] = v1;
    y2[i] = v2;
    y3[i] = v3;
  }
}

// All recursions of the block's rows: the groups of four, then the remaining terms one by one.
template <int kSteps>
[[gnu::always_inline]] inline void recursion_pass(const internal::FastHistoryBlock& blk,
                                                  const StepInputs<kSteps>& in) {
  const Eigen::Index n = blk.rows, terms = blk.terms, stride = blk.state_stride;
  double* const state = blk.state;
  Eigen::Index j = 0;
  if (terms >= 4) {
    recursion_group<true, kSteps>(blk, 0, in);
    j = 4;
  } else {
    for (int s = 0; s < kSteps; ++s) {  // no recursions yet: the tails are 0
      for (Eigen::Index i = 0; i < n; ++i) in.tail[s][i] = 0.0;
    }
  }
  for (; j + 4 <= terms; j += 4) recursion_group<false, kSteps>(blk, j, in);
  // The remaining terms one by one, each loaded and stored once for the kSteps pushes (a loop per
  // push took a quarter of the pass's time at K = 25 with one remainder term).
  const double* x[kSteps];
  double* tail[kSteps];
  for (int s = 0; s < kSteps; ++s) {
    x[s] = in.leaving[s];
    tail[s] = in.tail[s];
  }
  for (; j < terms; ++j) {
    double* y = state + j * stride;
    const double a = blk.decay[j], w = blk.weights[j];
    FRACVI_INDEPENDENT_ITERATIONS
    for (Eigen::Index i = 0; i < n; ++i) {
      double v = y[i];
#pragma GCC unroll 4
      for (int s = 0; s < kSteps; ++s) {
        v = a * v + x[s][i];
        tail[s][i] += w * v;
      }
      y[i] = v;
    }
  }
}

FRACVI_HOT_KERNEL
void recursion_block(const internal::FastHistoryBlock& blk) {
  recursion_pass<1>(blk, {{blk.leaving}, {blk.tail}});
}

// The most pushes whose recursions one pass runs. Measured on the recursions alone (stand-alone,
// v3, d = 1000, K = 24, µs a push; bench/RESULTS.md): 1 step a pass 4.6, 2 steps 3.5, 4 steps 2.2,
// 8 steps 2.1 — from 4 on the pass is bound by its multiply–adds, no longer by moving the state.
constexpr int kPassSteps = 4;
static_assert(FastHistory::kAheadGroups <= kPassSteps);  // a group's pass: a tails_ column a push

// Up to kPassSteps pushes' recursions in one pass over the state (FastHistory::push, when one
// thread runs them and no push is run ahead): the leaving values of pushes k, k + 1, … enter every
// Y_j, which is loaded and stored once; push k + s's tail goes to tails[s]. Each element sees the
// operations of recursion_block for push k, then for push k + 1, … in the same order (the groups
// of four, the remainder), so the numbers are the same bit for bit; the state moves through the
// caches once instead of `steps` times (bench/recursion_blocking, bench/RESULTS.md).
template <int kSteps>
[[gnu::always_inline]] inline void recursion_steps(const internal::FastHistoryBlock& blk,
                                                   const double* const* leaving,
                                                   double* const* tails) {
  StepInputs<kSteps> in;
  for (int s = 0; s < kSteps; ++s) {
    in.leaving[s] = leaving[s];
    in.tail[s] = tails[s];
  }
  recursion_pass<kSteps>(blk, in);
}

FRACVI_HOT_KERNEL
void recursion_block_steps(const internal::FastHistoryBlock& blk, int steps,
                           const double* const* leaving, double* const* tails) {
  switch (steps) {
    case 2: recursion_steps<2>(blk, leaving, tails); return;
    case 3: recursion_steps<3>(blk, leaving, tails); return;
    default: recursion_steps<4>(blk, leaving, tails); return;
  }
}

// The window's terms are added to the tail oldest first, in groups of four summed pairwise and
// the remainder one by one (that order keeps the round-off of their cancellation, from O(|x̃|) to
// O(h^β |x̃|), at that of the sum: a split that added c_0 x̃_k alone at the end measured 2.1× the
// round-off, 4.8e-17 against 2.3e-17 mean at β = 1.5, and broke the order test of fvi-midpoint).
// Only the last of these additions involves x̃_k: so the window is split before it —
// older_window_block adds the columns before newest_start() onto the tail in place, newest_block
// the last step with x̃_k — and the second thread of a team of two can run the first part one step
// ahead. One thread runs both in a row: the same additions in the same order.
Eigen::Index newest_start(Eigen::Index window) {
  return window % 4 == 0 ? window - 4 : window - 1;
}

FRACVI_HOT_KERNEL
void older_window_block(const internal::FastHistoryBlock& blk) {
  const Eigen::Index n = blk.rows, older = newest_start(blk.window);
  double* __restrict sum = blk.tail;
  const double* head = blk.head_reversed;
  Eigen::Index c = 0;
  for (; c + 4 <= older; c += 4) {
    const double* c0 = internal::window_column(blk, c);
    const double* c1 = internal::window_column(blk, c + 1);
    const double* c2 = internal::window_column(blk, c + 2);
    const double* c3 = internal::window_column(blk, c + 3);
    const double h0 = head[c], h1 = head[c + 1], h2 = head[c + 2], h3 = head[c + 3];
    FRACVI_INDEPENDENT_ITERATIONS
    for (Eigen::Index i = 0; i < n; ++i)
      sum[i] += (h0 * c0[i] + h1 * c1[i]) + (h2 * c2[i] + h3 * c3[i]);
  }
  for (; c < older; ++c) {
    const double* __restrict col = internal::window_column(blk, c);
    const double weight = head[c];
    for (Eigen::Index i = 0; i < n; ++i) sum[i] += weight * col[i];
  }
}

// The older windows of the pushes k … k + steps − 1 of one pass (pushes[s] is push k + s's block),
// for n0 = 4 kGroups + 4 — the default windows, 16 (Grünwald–Letnikov) and 32 (BDF2): push
// k + s's window value c is push k's value c + s, so one loop over the rows loads the
// 4 kGroups + steps − 1 older values once for all the pushes, instead of each push's 4 kGroups
// columns and its tail kGroups times. Each push's additions are older_window_block's in the same
// order (a group of four summed pairwise, onto the tail oldest group first): the same numbers.
// Other windows run older_window_block push by push.
template <int kGroups, int kSteps>
[[gnu::always_inline]] inline void older_windows_of(const internal::FastHistoryBlock* pushes) {
  constexpr int kOlder = 4 * kGroups, kColumns = kOlder + kSteps - 1;
  const Eigen::Index n = pushes[0].rows;
  const double* col[kColumns];
  for (int c = 0; c < kColumns; ++c) col[c] = internal::window_column(pushes[0], c);
  double* tail[kSteps];
  for (int s = 0; s < kSteps; ++s) tail[s] = pushes[s].tail;
  double h[kOlder];
  for (int c = 0; c < kOlder; ++c) h[c] = pushes[0].head_reversed[c];
  FRACVI_INDEPENDENT_ITERATIONS
  for (Eigen::Index i = 0; i < n; ++i) {
    double v[kColumns];
#pragma GCC unroll 64
    for (int c = 0; c < kColumns; ++c) v[c] = col[c][i];
#pragma GCC unroll 4
    for (int s = 0; s < kSteps; ++s) {
      double t = tail[s][i];
#pragma GCC unroll 16
      for (int g = 0; g < kOlder; g += 4) {
        t += (h[g] * v[s + g] + h[g + 1] * v[s + g + 1]) +
             (h[g + 2] * v[s + g + 2] + h[g + 3] * v[s + g + 3]);
      }
      tail[s][i] = t;
    }
  }
}

template <int kGroups, int kSteps>
FRACVI_HOT_KERNEL void older_windows_avx2(const internal::FastHistoryBlock* pushes) {
  older_windows_of<kGroups, kSteps>(pushes);
}

// The same with 32 vector registers (x86-64-v4, 256-bit vectors: internal/vectorize.hpp), which
// hold n0 = 16's 15 older values, 12 weights and a row vector's tail (AVX2's 16 spill them).
template <int kGroups, int kSteps>
FRACVI_WIDE_REGISTERS_KERNEL void older_windows_wide(const internal::FastHistoryBlock* pushes) {
  older_windows_of<kGroups, kSteps>(pushes);
}

template <int kGroups>
void older_windows_here(const internal::FastHistoryBlock* pushes, int steps) {
  const bool wide = internal::wide_registers();
  switch (steps) {
    case 2:
      return wide ? older_windows_wide<kGroups, 2>(pushes) : older_windows_avx2<kGroups, 2>(pushes);
    case 3:
      return wide ? older_windows_wide<kGroups, 3>(pushes) : older_windows_avx2<kGroups, 3>(pushes);
    default:
      return wide ? older_windows_wide<kGroups, 4>(pushes) : older_windows_avx2<kGroups, 4>(pushes);
  }
}

void older_windows_of_pass(const internal::FastHistoryBlock* pushes, int steps) {
  if (steps >= 2 && pushes[0].window == 16) return older_windows_here<3>(pushes, steps);
  if (steps >= 2 && pushes[0].window == 32) return older_windows_here<7>(pushes, steps);
  for (int s = 0; s < steps; ++s) older_window_block(pushes[s]);
}

// x̃_k into the ring (its slot held x̃_{k−n0}, read by the recursions before), and the sum = the
// tail with the older window + the last addition: the last group of four with x̃_k as its fourth
// value, or the last remainder term c_0 x̃_k.
FRACVI_HOT_KERNEL
void newest_block(const internal::FastHistoryBlock& blk) {
  const Eigen::Index n = blk.rows;
  const double* __restrict x = blk.entering;
  {
    double* __restrict slot = blk.slot;
    for (Eigen::Index i = 0; i < n; ++i) slot[i] = x[i];
  }
  double* __restrict sum = blk.sum;
  const double* __restrict partial = blk.tail;
  const Eigen::Index c = newest_start(blk.window);
  const double* head = blk.head_reversed;
  if (blk.window - c == 4) {
    const double* __restrict c0 = internal::window_column(blk, c);
    const double* __restrict c1 = internal::window_column(blk, c + 1);
    const double* __restrict c2 = internal::window_column(blk, c + 2);
    const double h0 = head[c], h1 = head[c + 1], h2 = head[c + 2], h3 = head[c + 3];
    FRACVI_INDEPENDENT_ITERATIONS
    for (Eigen::Index i = 0; i < n; ++i)
      sum[i] = partial[i] + ((h0 * c0[i] + h1 * c1[i]) + (h2 * c2[i] + h3 * x[i]));
  } else {
    const double weight = head[c];
    for (Eigen::Index i = 0; i < n; ++i) sum[i] = partial[i] + weight * x[i];
  }
}

// The same update for a system of fewer than kAcrossTermsBelow degrees of freedom: along the
// degrees of freedom there is nothing to vectorise (at d = 1 recursion_block's loops run one
// iteration per recursion: ≈ 30 % of a d = 1 step, bench/RESULTS.md), so each row runs along its K
// recursions instead (the four new Y_j of a group in one vector). The additions keep the kernels'
// order exactly — groups of four summed pairwise, then into the tail in ascending j; the window
// likewise onto the tail — so a row's sum is bit for bit that
// of the same row inside a larger system (tested for K = 29 … 63). That order matters: the window's
// terms cancel from O(|x̃|) to O(h^β |x̃|), and eight interleaved partial sums measured 4× the
// round-off of the sum (mean |Ŝ − S| 9e-17 against 2.3e-17, d = 1, N = 10^5, ε = 1e-13, against the
// exact sum in long double).
constexpr Eigen::Index kAcrossTermsBelow = 4;

// Row i from recursion j on (the earlier ones are in `tail`): the groups of four, the remaining
// terms, then x̃_k into the ring and the window onto the tail. stride and ld are the state's and
// the ring's (1 at d = 1).
[[gnu::always_inline]] inline void finish_row(const internal::FastHistoryBlock& blk, Eigen::Index i,
                                              Eigen::Index j, double tail, Eigen::Index stride,
                                              Eigen::Index ld) {
  const Eigen::Index terms = blk.terms;
  const double x = blk.leaving[i];
  double* const y = blk.state + i;
  for (; j + 4 <= terms; j += 4) {
    double v[4];
    for (Eigen::Index l = 0; l < 4; ++l) {
      v[l] = blk.decay[j + l] * y[(j + l) * stride] + x;
      y[(j + l) * stride] = v[l];
    }
    tail += (blk.weights[j] * v[0] + blk.weights[j + 1] * v[1]) +
            (blk.weights[j + 2] * v[2] + blk.weights[j + 3] * v[3]);
  }
  for (; j < terms; ++j) {
    const double v = blk.decay[j] * y[j * stride] + x;
    y[j * stride] = v;
    tail += blk.weights[j] * v;
  }
  blk.tail[i] = tail;
  // x̃_k enters the ring after x̃_{k−n0} was read: the same memory (see recursion_block).
  blk.slot[i] = blk.entering[i];
  // The window's values oldest first, from ring column `first` on, wrapping at n0.
  const double* row = blk.ring + i;
  const double* head = blk.head_reversed;
  const Eigen::Index n0 = blk.window;
  const auto value = [&](Eigen::Index c) {
    return *internal::ring_window_column(row, ld, n0, blk.first, c);
  };
  double sum = tail;
  Eigen::Index c = 0;
  for (; c + 4 <= n0; c += 4) {
    sum += (head[c] * value(c) + head[c + 1] * value(c + 1)) +
           (head[c + 2] * value(c + 2) + head[c + 3] * value(c + 3));
  }
  for (; c < n0; ++c) sum += head[c] * value(c);
  blk.sum[i] = sum;
}

// d = 2, 3: each row along its K recursions (the four new Y_j of a group in one vector).
[[gnu::always_inline]] inline void rows_across_terms(const internal::FastHistoryBlock& blk) {
  for (Eigen::Index i = 0; i < blk.rows; ++i) {
    finish_row(blk, i, 0, 0.0, blk.state_stride, blk.ring_stride);
  }
}

// d = 1. The K recursions are stored (with their e^{−λ_j} and w_j) so that each block of
// kInterleave = 16 terms holds its four groups of four interleaved: term 16b + 4g + l at 16b + 4l
// + g (interleaved_index()). Then the terms l = 0 … 3 of the groups g = 0 … 3 are four contiguous
// vectors, and the group sums (w_0 v_0 + w_1 v_1) + (w_2 v_2 + w_3 v_3) of four groups are one
// vector expression — the same expression as finish_row's per group, so the same roundings (FMAs
// included in the x86-64-v3 clone) — added to the tail in ascending order. Stored in order, GCC
// vectorised the d = 1 row across groups with ≈ 3 shuffles per term (≈ 430 instructions per push
// at K = 50, callgrind; ≈ 300 like this). The terms after the last whole block, and the window (a
// sliding ring), take finish_row's loops.
constexpr Eigen::Index kInterleave = 16;

[[gnu::always_inline]] inline void one_row_across_terms(const internal::FastHistoryBlock& blk) {
  const double x = *blk.leaving;
  double* const y = blk.state;
  double tail = 0.0;
  Eigen::Index j = 0;
  for (; j + kInterleave <= blk.terms; j += kInterleave) {
    double v[kInterleave];
    for (Eigen::Index l = 0; l < kInterleave; ++l) {
      v[l] = blk.decay[j + l] * y[j + l] + x;
      y[j + l] = v[l];
    }
    const double* w = blk.weights + j;
    double group[4];
    for (Eigen::Index g = 0; g < 4; ++g) {
      group[g] =
          (w[g] * v[g] + w[4 + g] * v[4 + g]) + (w[8 + g] * v[8 + g] + w[12 + g] * v[12 + g]);
    }
    for (const double q : group) tail += q;
  }
  finish_row(blk, 0, j, tail, 1, 1);
}

FRACVI_HOT_KERNEL
void push_rows_across_terms(const internal::FastHistoryBlock& blk) {
  if (blk.rows == 1 && blk.state_stride == 1 && blk.ring_stride == 1) {
    one_row_across_terms(blk);
  } else {
    rows_across_terms(blk);
  }
}

// Where term j of K is stored at d = 1 (an involution: the same map restores the order).
Eigen::Index interleaved_index(Eigen::Index j, Eigen::Index terms) {
  if (j >= terms / kInterleave * kInterleave) return j;
  const Eigen::Index block = j - j % kInterleave, r = j % kInterleave;
  return block + 4 * (r % 4) + r / 4;
}

template <class Vector>
void interleave(Vector& v) {
  const Vector in_order = v;
  for (Eigen::Index j = 0; j < v.size(); ++j) v(interleaved_index(j, v.size())) = in_order(j);
}

std::shared_ptr<const ExponentialFit> gl_fit(double order, Eigen::Index dimension,
                                             std::size_t capacity, double tolerance) {
  if (dimension < 1 || capacity < 1) {
    throw std::invalid_argument("FastHistory: dimension = " + std::to_string(dimension) +
                                " and capacity = " + std::to_string(capacity) + " must be >= 1");
  }
  ExponentialFitOptions options;
  options.order = order;
  options.tolerance = tolerance;
  options.max_lag = fast_history_fit_lag(capacity);
  return shared_exponential_fit(options);
}

}  // namespace

std::size_t fast_history_fit_lag(std::size_t capacity) {
  const std::size_t max_lag = capacity > 1 ? capacity - 1 : std::size_t{1};
  // No rounding where bit_ceil would overflow; fit_exponentials rejects such lags anyway.
  return max_lag > (std::size_t{1} << 62) ? max_lag : std::bit_ceil(max_lag);
}

FastHistory::FastHistory(std::shared_ptr<const ExponentialFit> fit, Eigen::Index dimension,
                         std::size_t capacity)
    : fit_(checked_fit(std::move(fit), dimension, capacity)),
      capacity_(capacity),
      run_ahead_(*this, {kParallelWork, kRunAheadWork, kBalancedRunAheadFrom}) {
  window_ = static_cast<Eigen::Index>(fit_->window);
  head_reversed_.resize(window_);
  for (Eigen::Index i = 0; i < window_; ++i)
    head_reversed_(i) = fit_->head[static_cast<std::size_t>(window_ - 1 - i)];
  ring_.setZero(dimension, window_);
  const auto k = static_cast<Eigen::Index>(fit_->terms());
  decay_.resize(k);
  weights_.resize(k);
  for (Eigen::Index j = 0; j < k; ++j) {
    decay_(j) = std::exp(-fit_->lambdas[static_cast<std::size_t>(j)]);
    weights_(j) = fit_->weights[static_cast<std::size_t>(j)];
  }
  if (dimension == 1) {
    interleave(decay_);
    interleave(weights_);
  }
  state_.setZero(dimension, k);
  tails_.setZero(dimension, kPassSteps);
  sum_.setZero(dimension);
  configure_threads(0);
}

FastHistory::FastHistory(double order, Eigen::Index dimension, std::size_t capacity,
                         double tolerance)
    : FastHistory(gl_fit(order, dimension, capacity, tolerance), dimension, capacity) {}

FastHistory::~FastHistory() = default;

namespace {

// Blocks of kBlock rows keep the tail's block in L1 while the K columns pass over it.
constexpr Eigen::Index kBlock = 256;

}  // namespace

// The block of rows [b, b + n) of a push whose new value x̃ is `entering` (null for the
// recursions alone), x̃_{k−n0} in ring column `slot`, the window starting at column `first`, its
// tail in column `tail` of tails_.
internal::FastHistoryBlock FastHistory::block(Eigen::Index b, Eigen::Index n, Eigen::Index terms,
                                              Eigen::Index slot, Eigen::Index first,
                                              const double* entering, Eigen::Index tail) {
  return {n,
          terms,
          state_.rows(),
          window_,
          ring_.rows(),
          first,
          state_.data() + b,
          tails_.col(tail).data() + b,
          sum_.data() + b,
          ring_.col(slot).data() + b,
          entering == nullptr ? nullptr : entering + b,
          ring_.col(slot).data() + b,
          ring_.data() + b,
          decay_.data(),
          weights_.data(),
          head_reversed_.data()};
}

void FastHistory::run_ahead(Eigen::Index lo, Eigen::Index hi, Eigen::Index leaving_slot,
                            Eigen::Index first) {
  if (by_groups_) {
    // The team of two by row groups: the passes end_row_push() planned for the next push, each
    // pass's rows split in the proportion [lo, hi) of d (whole cache lines), so that the share
    // RunAheadBalance sets applies to whichever group's turn it is.
    const Eigen::Index d = ring_.rows();
    for (int i = 0; i < group_pass_count_; ++i) {
      const GroupPass& pass = group_passes_[i];
      const auto row = [&](Eigen::Index r) {
        return r == d ? pass.hi : pass.lo + (pass.hi - pass.lo) * r / d / 8 * 8;
      };
      if (row(lo) < row(hi)) group_pass(pass, row(lo), row(hi));
    }
    return;
  }
  const Eigen::Index terms = state_.cols();
  for (Eigen::Index b = lo; b < hi; b += kBlock) {
    const Eigen::Index n = std::min(kBlock, hi - b);
    const internal::FastHistoryBlock rows =
        block(b, n, terms, leaving_slot, first, nullptr, tail_column_);
    recursion_block(rows);
    older_window_block(rows);
  }
}

void FastHistory::push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) {
  assert(size_ < capacity_ && x_tilde.size() == ring_.rows());
  const Eigen::Index d = ring_.rows();
  if (d < kAcrossTermsBelow) {
    // Far below kParallelWork: one block on this thread, without the team's bookkeeping (a third
    // of a d = 1 push's instructions went there, callgrind); never run ahead (no second thread,
    // and visit_state refuses a small system's checkpoint that says so).
    const auto n0 = static_cast<std::size_t>(window_);
    push_rows_across_terms(
        block(0, d, size_ >= n0 ? state_.cols() : 0, static_cast<Eigen::Index>(size_ % n0),
              static_cast<Eigen::Index>((size_ + 1) % n0), x_tilde.data(), tail_column_));
    run_ahead_.count_single_push();
    ++size_;
    return;
  }
  begin_row_push(x_tilde.data());
  if (pending_.by_groups) rows_ahead(0, 1);
  // A team of two runs the next push ahead (the caller only makes the window's last addition); a
  // larger team splits the rows.
  internal::for_blocks(d, pending_.turn.split,
                       [this](Eigen::Index lo, Eigen::Index hi) { push_rows(lo, hi); });
  end_row_push();
}

bool FastHistory::pushes_rows() const {
  return ring_.rows() >= kAcrossTermsBelow && run_ahead_.chooser().team() == 1;
}

void FastHistory::begin_row_push(const double* x_tilde) {
  assert(size_ < capacity_ && ring_.rows() >= kAcrossTermsBelow);
  push_flush_bits_ = internal::flush_bits();
  const auto n0 = static_cast<std::size_t>(window_);
  RowPush& p = pending_;
  p.entering = x_tilde;
  p.slot = static_cast<Eigen::Index>(size_ % n0);
  // After the push the last n0 values x̃_{k−n0+1} … x̃_k are the ring columns first, first + 1, …
  // (mod n0) with first = (k + 1) mod n0; before k = n0 − 1 the missing ones are the zeros the
  // ring was cleared to.
  p.first = static_cast<Eigen::Index>((size_ + 1) % n0);
  p.own = tail_column_;
  p.by_groups = by_groups_ && size_ >= n0;
  if (p.by_groups) {
    // The team of two by groups: its thread ran the passes planned for this push (end_row_push),
    // then planning again finds none; a push that ran on one thread posted none, and the caller
    // runs them (push(): rows_ahead). The stepper's groups post nothing (next_ran).
    p.turn = run_ahead_.begin(size_, n0, capacity_, !groups_by_team_);
    plan_group_passes();
    p.turn.ahead = true;  // push_rows() adds x̃ alone
    p.run_recursions = false;
    p.steps = 1;
    return;
  }
  // The next push's recursions ran in an earlier pass (later_ > 0): no thread runs them again.
  p.turn = run_ahead_.begin(size_, n0, capacity_, later_ > 0);
  // One thread runs this push's recursions and no thread runs the next push's: run the next
  // pushes' too, up to kPassSteps in all, in one pass over the state (recursion_block_steps) — push
  // k + s's leaving value x̃_{k+s−n0} is in ring column (k + s) mod n0 until push k + s, and its
  // tail goes to the s-th tails_ column from this push's — and their older windows once x̃_k is in
  // the ring, while the ring's rows are in cache. Push k + s's older window ends with x̃_{k+s−g},
  // g = n0 − newest_start(n0) (4 when n0 is a multiple of 4, else 1): so a pass covers at most
  // g + 1 pushes. Each later push then runs as one run ahead (the same numbers), only adding x̃.
  p.run_recursions = size_ >= n0 && !p.turn.ahead;
  const auto gap = static_cast<std::size_t>(window_ - newest_start(window_));
  p.steps = p.run_recursions && p.turn.split == 1 && !p.turn.post_next
                ? static_cast<int>(std::min(
                      {static_cast<std::size_t>(kPassSteps), capacity_ - size_, n0, gap + 1}))
                : 1;
}

void FastHistory::plan_group_passes() {
  // Group q's turn is at the pushes k ≡ q (mod groups_): its pass runs the recursions and older
  // windows of pushes k … k + groups_ − 1 (push k + s's older window ends with x̃_{k+s−g}, g ≥
  // groups_, so x̃_k is not needed). A group whose ready pushes ran out before its turn (the first
  // push with recursions, a loaded checkpoint) gets a pass up to its turn. Planning again for the
  // same push finds nothing to add.
  group_pass_count_ = 0;
  for (int q = 0; q < groups_; ++q) {
    const auto turn_in = static_cast<int>(
        (static_cast<std::size_t>(q) + groups_ - size_ % static_cast<std::size_t>(groups_)) %
        static_cast<std::size_t>(groups_));
    if (turn_in != 0 && group_ready_[q] > 0) continue;
    const auto target = static_cast<int>(
        std::min(static_cast<std::size_t>(turn_in == 0 ? groups_ : turn_in), capacity_ - size_));
    if (target > group_ready_[q]) {
      group_passes_[group_pass_count_++] = {group_bounds_[q], group_bounds_[q + 1], group_ready_[q],
                                            target - group_ready_[q]};
      group_ready_[q] = target;
    }
  }
}

void FastHistory::rows_ahead(int share, int shares) {
  assert(pending_.by_groups && shares >= 1 && share >= 0 && share < shares);
  for (int i = 0; i < group_pass_count_; ++i) {
    const GroupPass& pass = group_passes_[i];
    // Contiguous shares of whole cache lines (8 rows).
    const Eigen::Index n = pass.hi - pass.lo;
    const Eigen::Index lo = pass.lo + n * share / shares / 8 * 8;
    const Eigen::Index hi =
        share + 1 == shares ? pass.hi : pass.lo + n * (share + 1) / shares / 8 * 8;
    group_pass(pass, lo, hi);
  }
}

void FastHistory::group_pass(const GroupPass& pass, Eigen::Index lo, Eigen::Index hi) {
  // The one-thread pass of several pushes (push_rows with steps > 1) on these rows, with the
  // older windows of all of them: push k + s's leaving value x̃_{k+s−n0} is in ring column
  // (k + s) mod n0, its window starts at column (k + s + 1) mod n0, its tail is tails_ column
  // (tail_column_ + s) mod kPassSteps.
  const auto n0 = static_cast<std::size_t>(window_);
  const Eigen::Index terms = state_.cols();
  for (Eigen::Index b = lo; b < hi; b += kBlock) {
    const Eigen::Index n = std::min(kBlock, hi - b);
    const double* leaving[kPassSteps];
    double* tails[kPassSteps];
    internal::FastHistoryBlock pushes[kPassSteps];
    for (int s = 0; s < pass.steps; ++s) {
      const std::size_t k = size_ + static_cast<std::size_t>(pass.from + s);
      const auto column = (tail_column_ + pass.from + s) % kPassSteps;
      pushes[s] = block(b, n, terms, static_cast<Eigen::Index>(k % n0),
                        static_cast<Eigen::Index>((k + 1) % n0), nullptr, column);
      leaving[s] = pushes[s].leaving;
      tails[s] = pushes[s].tail;
    }
    if (pass.steps == 1) {
      recursion_block(pushes[0]);
    } else {
      recursion_block_steps(pushes[0], pass.steps, leaving, tails);
    }
    older_windows_of_pass(pushes, pass.steps);
  }
}

void FastHistory::even_groups() {
  const int most = *std::max_element(group_ready_.begin(), group_ready_.begin() + groups_);
  if (most > kPassSteps) {
    throw std::logic_error("FastHistory: a push begun by rows was not ended");
  }
  // These passes would have run in the pushes, with their flush bits (the step's: IntegratorOptions
  // ::flush_subnormals); a checkpoint or a change of threads between steps runs them here, outside
  // the step. Without the pushes' bits, values in the subnormal range came out differently: a run
  // of the example chain on two threads that wrote checkpoints differed from one that did not.
  const internal::FlushBitsAdopted as_pushed(push_flush_bits_);
  for (int q = 0; q < groups_; ++q) {
    if (group_ready_[q] < most) {
      const GroupPass pass{group_bounds_[q], group_bounds_[q + 1], group_ready_[q],
                           most - group_ready_[q]};
      group_pass(pass, pass.lo, pass.hi);
      group_ready_[q] = most;
    }
  }
  later_ = most > 0 ? static_cast<std::size_t>(most - 1) : 0;
  run_ahead_.set_ahead(most > 0);
}

void FastHistory::set_rows_ahead(bool on) {
  if (on && !pushes_rows()) {
    throw std::logic_error("FastHistory: rows ahead without a push by rows");
  }
  if (groups_by_team_ || on == by_groups_) return;
  switch_groups(on);
}

void FastHistory::switch_groups(bool on) {
  run_ahead_.finish();
  if (on) {
    // As many groups as pushes a pass can run ahead (4, or 1 when n0 is not a multiple of 4).
    groups_ =
        static_cast<int>(std::min(Eigen::Index{kAheadGroups}, window_ - newest_start(window_)));
    const Eigen::Index d = ring_.rows();
    for (int q = 0; q < groups_; ++q) group_bounds_[q] = d * q / groups_ / 8 * 8;
    group_bounds_[groups_] = d;
    const int ready = run_ahead_.ahead() ? static_cast<int>(later_) + 1 : 0;
    std::fill(group_ready_.begin(), group_ready_.end(), ready);
    later_ = 0;
    run_ahead_.set_ahead(false);
  } else {
    even_groups();
  }
  group_pass_count_ = 0;
  by_groups_ = on;
}

void FastHistory::push_rows(Eigen::Index lo, Eigen::Index hi) {
  // One pass per block of degrees of freedom: (1) x̃_{k−n0} leaves the window (it sits in the slot
  // x̃_k is about to take) and enters every recursion, Y_j ← e^{−λ_j} Y_j + x̃_{k−n0}, and the
  // tail Σ_j w_j Y_j is formed — unless they were run ahead; (2) x̃_k enters the ring; (3) the
  // sum = window · exact weights + tail, returned by sum(). Y_j is column j of the d × K state, so
  // the recursions run along the degrees of freedom (long contiguous vectors). Each row's
  // operations do not depend on [lo, hi).
  const RowPush& p = pending_;
  const auto n0 = static_cast<std::size_t>(window_);
  const Eigen::Index terms = state_.cols();
  const auto column = [&](int s) { return (p.own + s) % kPassSteps; };
  for (Eigen::Index b = lo; b < hi; b += kBlock) {
    const Eigen::Index n = std::min(kBlock, hi - b);
    const internal::FastHistoryBlock rows =
        block(b, n, p.run_recursions ? terms : 0, p.slot, p.first, p.entering, p.own);
    if (p.steps > 1) {
      const double* leaving[kPassSteps];
      double* tails[kPassSteps];
      for (int s = 0; s < p.steps; ++s) {
        leaving[s] = ring_.col(static_cast<Eigen::Index>((size_ + s) % n0)).data() + b;
        tails[s] = tails_.col(column(s)).data() + b;
      }
      recursion_block_steps(rows, p.steps, leaving, tails);
      // The pass's older windows (push k + s's starts at ring column (k + s + 1) mod n0): with n0
      // a multiple of 4 they end with x̃_{k+s−4} and all go before x̃_k enters; otherwise the pass
      // covers two pushes and the second one's ends with x̃_k, after it.
      internal::FastHistoryBlock pushes[kPassSteps];
      pushes[0] = rows;
      for (int s = 1; s < p.steps; ++s) {
        const auto window_first = static_cast<Eigen::Index>((size_ + 1 + s) % n0);
        pushes[s] = block(b, n, terms, p.slot, window_first, nullptr, column(s));
      }
      const bool before_newest = newest_start(window_) == window_ - 4;
      older_windows_of_pass(pushes, before_newest ? p.steps : 1);
      newest_block(rows);
      if (!before_newest) older_windows_of_pass(pushes + 1, p.steps - 1);
      continue;
    }
    if (!p.turn.ahead) {
      recursion_block(rows);  // with no recursions yet (terms = 0), a zero tail
      older_window_block(rows);
    }
    newest_block(rows);
  }
}

void FastHistory::end_row_push() {
  const RowPush& p = pending_;
  ++size_;
  if (p.by_groups) {
    for (int q = 0; q < groups_; ++q) --group_ready_[q];
    tail_column_ = (p.own + 1) % kPassSteps;
  }
  if (groups_by_team_ && p.turn.post_next) {
    // The team of two by groups: the next push's passes (x̃_k is in the ring: the next push's
    // older windows end before x̃_{k+1}) go to its thread, which runs them while the caller
    // computes the next step (run_ahead above).
    plan_group_passes();
    run_ahead_.end(p.turn, p.first, p.first);
    return;
  }
  if (p.by_groups) {
    run_ahead_.end(p.turn, p.first, p.first);  // posts nothing
    return;
  }
  if (p.steps > 1) later_ = static_cast<std::size_t>(p.steps - 1);  // it was 0: this push not ahead
  const bool next_ran = later_ > 0;  // the next push's tail is complete
  if (next_ran) {
    tail_column_ = (p.own + 1) % kPassSteps;
    --later_;
  }
  run_ahead_.end(p.turn, p.first,
                 static_cast<Eigen::Index>((size_ + 1) % static_cast<std::size_t>(window_)));
  if (next_ran) run_ahead_.set_ahead(true);
}

void FastHistory::sum(Eigen::Ref<Eigen::VectorXd> out) const {
  assert(size_ >= 1 && out.size() == ring_.rows());
  // sum_ is formed by push(), never by the second thread.
  internal::copy_elements(sum_.data(), out.data(), out.size());
}

void FastHistory::configure_threads(int threads) {
  run_ahead_.configure(threads, ring_.rows(), ring_.rows() * (state_.cols() + window_));
  // A team of two runs the next push's passes by row groups: each push its thread runs the
  // recursions and older windows of one group's rows for four pushes in one pass (the four-push
  // pass of one thread, a quarter of the rows at a time) instead of one push's for all rows (one
  // push a pass moves the state through the caches each push: ≈ 2× the work, bench/RESULTS.md).
  // Where the window allows no groups of four (n0 not a multiple of 4), one push a pass, as before.
  const bool by_team = run_ahead_.chooser().team() == 2 && ring_.rows() >= kAcrossTermsBelow &&
                       window_ - newest_start(window_) >= kAheadGroups;
  if (by_team != groups_by_team_) {
    groups_by_team_ = false;
    if (by_team != by_groups_) switch_groups(by_team);
    groups_by_team_ = by_team;
  }
}

void FastHistory::set_threads(int threads) {
  if (by_groups_ && !groups_by_team_ && threads != 1) switch_groups(false);
  configure_threads(threads);
}

void FastHistory::set_run_ahead_rows(Eigen::Index rows) {
  if (rows < 0) {
    throw std::invalid_argument("FastHistory: run-ahead rows = " + std::to_string(rows) +
                                " must be >= 0 (0: balanced by timing)");
  }
  run_ahead_.set_fixed_rows(rows);
}

void FastHistory::visit_state(StateArchive& archive) {
  // The fit (λ_j, w_j, the window's exact weights) is rebuilt by the constructor from the same
  // options; its sizes are checked so that a checkpoint of another fit is refused.
  run_ahead_.finish();
  // Run ahead by row groups, the groups are first brought even (the same numbers), so that the
  // records are those of the pushes without groups.
  if (by_groups_ && !archive.loading()) even_groups();
  archive.expect("fast.dimension", static_cast<std::size_t>(ring_.rows()));
  archive.expect("fast.capacity", capacity_);
  archive.expect("fast.window", static_cast<std::size_t>(window_));
  archive.expect("fast.terms", static_cast<std::size_t>(state_.cols()));
  archive.count("fast.size", size_);
  if (size_ > capacity_) throw CheckpointError("checkpoint record 'fast.size' exceeds capacity");
  archive.dense("fast.ring", ring_);
  if (ring_.rows() == 1) {
    // The record keeps the order Y_0 … Y_{K−1} (the same checkpoint for any layout).
    Eigen::ArrayXd in_order = state_.row(0).transpose();
    interleave(in_order);  // an involution: stored → in order
    archive.dense("fast.recursions", in_order);
    interleave(in_order);
    state_.row(0) = in_order.transpose();
  } else {
    archive.dense("fast.recursions", state_);
  }
  // The next push's tail, then those of the later pushes that a pass has run (fast.later of them,
  // in order; the record has room for kPassSteps − 1 — a team of two by groups has planned the
  // next push's passes, up to kPassSteps pushes ready — zeros beyond): the same records whichever
  // tails_ column each sits in. (Checkpoints of the former layout, kPassSteps − 2 later tails in
  // 'fast.later_tails', are refused by name.)
  Eigen::MatrixXd in_order(ring_.rows(), kPassSteps);
  for (Eigen::Index s = 0; s < in_order.cols(); ++s)
    in_order.col(s) = tails_.col((tail_column_ + s) % kPassSteps);
  Eigen::VectorXd next = in_order.col(0);
  Eigen::MatrixXd later = in_order.rightCols(kPassSteps - 1);
  if (!archive.loading()) {
    for (Eigen::Index s = static_cast<Eigen::Index>(later_); s < later.cols(); ++s)
      later.col(s).setZero();
  }
  archive.dense("fast.tail", next);
  archive.count("fast.later", later_);
  archive.dense("fast.ahead_tails", later);
  if (archive.loading()) {
    tail_column_ = 0;
    tails_.setZero();
    tails_.col(0) = next;
    tails_.rightCols(kPassSteps - 1) = later;
  }
  archive.dense("fast.sum", sum_);
  // Whether the recursions and the tail already include the next push's x̃ (run ahead).
  bool ahead = run_ahead_.ahead();
  archive.flag("fast.ahead", ahead);
  if (ahead != run_ahead_.ahead()) run_ahead_.set_ahead(ahead);  // restored
  if (ahead && (size_ < static_cast<std::size_t>(window_) || size_ >= capacity_ ||
                ring_.rows() < kAcrossTermsBelow)) {
    throw CheckpointError("checkpoint record 'fast.ahead' is set where no push runs ahead");
  }
  if (later_ > static_cast<std::size_t>(kPassSteps - 1) || (later_ > 0 && !ahead) ||
      (later_ > 0 && size_ + later_ >= capacity_)) {
    throw CheckpointError("checkpoint record 'fast.later' = " + std::to_string(later_) +
                          " does not fit the state (at most " + std::to_string(kPassSteps - 1) +
                          ", with 'fast.ahead' set and the pushes within the capacity)");
  }
  if (by_groups_) {  // the groups' ready pushes from the records' form
    std::fill(group_ready_.begin(), group_ready_.end(), ahead ? static_cast<int>(later_) + 1 : 0);
    later_ = 0;
    run_ahead_.set_ahead(false);
    group_pass_count_ = 0;
  }
}

void FastHistory::clear() {
  run_ahead_.finish();
  ring_.setZero();
  state_.setZero();
  tails_.setZero();
  tail_column_ = 0;
  later_ = 0;
  group_ready_.fill(0);
  group_pass_count_ = 0;
  sum_.setZero();
  size_ = 0;
  run_ahead_.reset();
}

bool fast_history_pays(std::size_t capacity, Eigen::Index dimension) {
  if (capacity >= kFastHistoryCrossover) return true;
  const auto n = static_cast<double>(capacity), d = static_cast<double>(dimension);
  return 0.5 * n * n * d > 100.0 * n * d + 2e7;
}

std::unique_ptr<History> make_fast_history(const ConvolutionQuadrature& quadrature,
                                           Eigen::Index dimension, std::size_t capacity,
                                           double tolerance) {
  if (quadrature.scheme == CqScheme::kGrunwaldLetnikov && quadrature.lag == 0) {
    return std::make_unique<FastHistory>(quadrature.order, dimension, capacity, tolerance);
  }
  if (dimension < 1 || capacity < 1) {
    throw std::invalid_argument("make_fast_history: dimension = " + std::to_string(dimension) +
                                " and capacity = " + std::to_string(capacity) + " must be >= 1");
  }
  ExponentialFitOptions options;
  options.scheme = quadrature.scheme;
  options.order = quadrature.order;
  options.lag = quadrature.lag;
  options.tolerance = tolerance;
  options.max_lag = fast_history_fit_lag(capacity);
  return std::make_unique<FastHistory>(shared_exponential_fit(options), dimension, capacity);
}

}  // namespace fracvi
