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

FastBlockHistory::FastBlockHistory(std::shared_ptr<const RkcqTail> tail, std::size_t lag,
                                   Eigen::Index dimension, std::size_t capacity)
    : tail_(checked_tail(std::move(tail), lag, dimension, capacity)),
      lag_(lag),
      capacity_(capacity) {
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
  ring_.setZero(2 * window_ * s, dimension);
  const auto k = static_cast<Eigen::Index>(tail_->terms());
  decay_.resize(k);
  right_.resize(k, s);
  left_.resize(k, s);
  for (Eigen::Index i = 0; i < k; ++i) {
    const auto u = static_cast<std::size_t>(i);
    decay_(i) = tail_->decays[u];
    right_.row(i) = tail_->right[u].transpose();
    left_.row(i) = tail_->gammas[u] * tail_->left[u].transpose();
  }
  state_.setZero(k, dimension);
  sum_.setZero(dimension, s);
}

void FastBlockHistory::push(const Eigen::Ref<const Eigen::MatrixXd>& block) {
  assert(size_ < capacity_ && block.rows() == sum_.rows() && block.cols() == stages_);
  const Eigen::Index s = stages_, n0 = window_, terms = decay_.size();
  const auto slot = static_cast<Eigen::Index>(size_ % static_cast<std::size_t>(n0));
  const bool recurse = size_ >= static_cast<std::size_t>(n0);
  // After the push the last n0 blocks Z_{k−n0+1} … Z_k sit at ring positions first … first + n0 − 1
  // (each position s rows); before k = n0 − 1 the missing ones are the zeros the ring was cleared
  // to.
  const auto first = static_cast<Eigen::Index>((size_ + 1) % static_cast<std::size_t>(n0));
  const Eigen::Index ring_rows = ring_.rows(), d = sum_.rows();
  const double* __restrict decay = decay_.data();
  // Per degree of freedom r (all its data contiguous: ring column r, state column r): (1) the
  // stage vector of Z_{k−n0} leaves the window (it sits in the slot Z_k is about to take) and
  // enters every recursion, Y_i ← r_i Y_i + Z_{k−n0} v_i, and the tail Σ_i γ_i Y_i u_iᵀ is formed;
  // (2) Z_k enters the ring; (3) the sum = window · exact blocks + tail. The loops over the K
  // terms and over the n0·s window entries are contiguous and vectorise.
  auto update = [&](Eigen::Index lo, Eigen::Index hi) {
    for (Eigen::Index r = lo; r < hi; ++r) {
      double* __restrict ring = ring_.data() + r * ring_rows;
      double tail[4] = {0.0, 0.0, 0.0, 0.0};  // s ≤ 4
      if (recurse) {
        double* __restrict y = state_.data() + r * terms;
        for (Eigen::Index i = 0; i < terms; ++i) y[i] *= decay[i];
        for (Eigen::Index e = 0; e < s; ++e) {
          const double x = ring[slot * s + e];
          const double* __restrict v = right_.data() + e * terms;
          for (Eigen::Index i = 0; i < terms; ++i) y[i] += x * v[i];
        }
        for (Eigen::Index c = 0; c < s; ++c) {
          const double* __restrict u = left_.data() + c * terms;
          double t = 0.0;
          for (Eigen::Index i = 0; i < terms; ++i) t += u[i] * y[i];
          tail[c] = t;
        }
      }
      for (Eigen::Index e = 0; e < s; ++e) {
        const double z = block(r, e);
        ring[slot * s + e] = z;
        ring[(slot + n0) * s + e] = z;
      }
      const double* __restrict window = ring + first * s;
      const Eigen::Index width = n0 * s;
      for (Eigen::Index c = 0; c < s; ++c) {
        const double* __restrict h = head_.data() + c * width;
        double t = 0.0;
        for (Eigen::Index q = 0; q < width; ++q) t += window[q] * h[q];
        sum_(r, c) = t + tail[c];
      }
    }
  };
  const Eigen::Index work = d * (terms * (2 * s + 1) + n0 * s * s);
  internal::for_blocks(d, internal::team_size(threads_, work, kParallelWork), update);
  ++size_;
}

void FastBlockHistory::sum(Eigen::Ref<Eigen::MatrixXd> out) const {
  assert(size_ >= 1 && out.rows() == sum_.rows() && out.cols() == sum_.cols());
  out = sum_;  // formed by push()
}

void FastBlockHistory::set_threads(int threads) {
  threads_ = threads;
  const Eigen::Index d = sum_.rows(), terms = decay_.size();
  internal::start_threads(internal::team_size(
      threads_, d * (terms * (2 * stages_ + 1) + window_ * stages_ * stages_), kParallelWork));
}

void FastBlockHistory::visit_state(StateArchive& archive) {
  // The tail's fit is rebuilt by the constructor from the same options (the shared cache); its
  // sizes are checked so that a checkpoint of another fit is refused.
  archive.expect("block_fast.dimension", static_cast<std::size_t>(sum_.rows()));
  archive.expect("block_fast.stages", static_cast<std::size_t>(stages_));
  archive.expect("block_fast.capacity", capacity_);
  archive.expect("block_fast.window", static_cast<std::size_t>(window_));
  archive.expect("block_fast.terms", static_cast<std::size_t>(decay_.size()));
  archive.count("block_fast.size", size_);
  if (size_ > capacity_) {
    throw CheckpointError("checkpoint record 'block_fast.size' exceeds capacity");
  }
  archive.dense("block_fast.ring", ring_);
  archive.dense("block_fast.recursions", state_);
  archive.dense("block_fast.sum", sum_);
}

void FastBlockHistory::clear() {
  ring_.setZero();
  state_.setZero();
  sum_.setZero();
  size_ = 0;
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
