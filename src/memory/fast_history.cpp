#include "fracvi/memory/fast_history.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "fracvi/internal/parallel.hpp"

namespace fracvi {

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
    : fit_(checked_fit(std::move(fit), dimension, capacity)), capacity_(capacity) {
  window_ = static_cast<Eigen::Index>(fit_->window);
  head_reversed_.resize(window_);
  for (Eigen::Index i = 0; i < window_; ++i)
    head_reversed_(i) = fit_->head[static_cast<std::size_t>(window_ - 1 - i)];
  ring_.setZero(dimension, 2 * window_);
  const auto k = static_cast<Eigen::Index>(fit_->terms());
  decay_.resize(k);
  weights_.resize(k);
  for (Eigen::Index j = 0; j < k; ++j) {
    decay_(j) = std::exp(-fit_->lambdas[static_cast<std::size_t>(j)]);
    weights_(j) = fit_->weights[static_cast<std::size_t>(j)];
  }
  state_.setZero(dimension, k);
  tail_.setZero(dimension);
  sum_.setZero(dimension);
}

FastHistory::FastHistory(double order, Eigen::Index dimension, std::size_t capacity,
                         double tolerance)
    : FastHistory(gl_fit(order, dimension, capacity, tolerance), dimension, capacity) {}

void FastHistory::push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) {
  assert(size_ < capacity_ && x_tilde.size() == ring_.rows());
  const auto n0 = static_cast<std::size_t>(window_);
  const auto slot = static_cast<Eigen::Index>(size_ % n0);
  const bool recurse = size_ >= n0;
  // After the push the last n0 values x̃_{k−n0+1} … x̃_k are the ring columns first … first + n0 − 1
  // with first = (k + 1) mod n0; before k = n0 − 1 the missing ones are the zeros the ring was
  // cleared to.
  const auto first = static_cast<Eigen::Index>((size_ + 1) % n0);
  const auto leaving = ring_.col(slot);
  const Eigen::Index terms = state_.cols(), stride = state_.rows();
  // One pass per block of degrees of freedom, all in one parallel region (each region costs a
  // barrier): (1) x̃_{k−n0} leaves the window (it sits in the slot x̃_k is about to take) and enters
  // every recursion, Y_j ← e^{−λ_j} Y_j + x̃_{k−n0}, and the tail Σ_j w_j Y_j is formed; (2) x̃_k
  // enters the ring; (3) the sum = window · exact weights + tail, returned by sum().
  // Y_j is column j of the d × K state, so the recursions run along the degrees of freedom (long
  // contiguous vectors); blocks of kBlock rows keep the tail's block in L1 while the K columns pass
  // over it.
  constexpr Eigen::Index kBlock = 256;
  auto update = [&](Eigen::Index lo, Eigen::Index hi) {
    for (Eigen::Index b = lo; b < hi; b += kBlock) {
      const Eigen::Index n = std::min(kBlock, hi - b);
      if (recurse) {
        // Plain loops over restrict pointers: the compiler vectorises them fully (the Eigen
        // block expressions of the same loop ran at half the speed).
        double* __restrict tail = tail_.data() + b;
        const double* __restrict x = leaving.data() + b;
        for (Eigen::Index i = 0; i < n; ++i) tail[i] = 0.0;
        for (Eigen::Index j = 0; j < terms; ++j) {
          double* __restrict y = state_.data() + j * stride + b;
          const double a = decay_(j), w = weights_(j);
          for (Eigen::Index i = 0; i < n; ++i) {
            const double yi = a * y[i] + x[i];
            y[i] = yi;
            tail[i] += w * yi;
          }
        }
      }
      ring_.col(slot).segment(b, n) = x_tilde.segment(b, n);
      ring_.col(slot + window_).segment(b, n) = x_tilde.segment(b, n);
      sum_.segment(b, n).noalias() = ring_.block(b, first, n, window_) * head_reversed_;
      sum_.segment(b, n) += tail_.segment(b, n);
    }
  };
  const Eigen::Index d = ring_.rows();
  internal::for_blocks(d, internal::team_size(threads_, d * (terms + window_), kParallelWork),
                       update);
  ++size_;
}

void FastHistory::sum(Eigen::Ref<Eigen::VectorXd> out) const {
  assert(size_ >= 1 && out.size() == ring_.rows());
  out = sum_;  // formed by push()
}

void FastHistory::set_threads(int threads) {
  threads_ = threads;
  const Eigen::Index d = ring_.rows();
  internal::start_threads(
      internal::team_size(threads_, d * (state_.cols() + window_), kParallelWork));
}

void FastHistory::visit_state(StateArchive& archive) {
  // The fit (λ_j, w_j, the window's exact weights) is rebuilt by the constructor from the same
  // options; its sizes are checked so that a checkpoint of another fit is refused.
  archive.expect("fast.dimension", static_cast<std::size_t>(ring_.rows()));
  archive.expect("fast.capacity", capacity_);
  archive.expect("fast.window", static_cast<std::size_t>(window_));
  archive.expect("fast.terms", static_cast<std::size_t>(state_.cols()));
  archive.count("fast.size", size_);
  if (size_ > capacity_) throw CheckpointError("checkpoint record 'fast.size' exceeds capacity");
  archive.dense("fast.ring", ring_);
  archive.dense("fast.recursions", state_);
  archive.dense("fast.tail", tail_);
  archive.dense("fast.sum", sum_);
}

void FastHistory::clear() {
  ring_.setZero();
  state_.setZero();
  tail_.setZero();
  sum_.setZero();
  size_ = 0;
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
