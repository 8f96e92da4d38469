#include "fracvi/memory/history.hpp"

#include "fracvi/memory/fast_history.hpp"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fracvi/fractional/convolution.hpp"
#include "fracvi/fractional/weights.hpp"

namespace fracvi {

DirectHistory::DirectHistory(ConvolutionQuadrature quadrature, Eigen::Index dimension,
                             std::size_t capacity)
    : quadrature_(quadrature), dimension_(dimension) {
  const double order = quadrature.order;
  if (!std::isfinite(order)) {
    throw std::invalid_argument("DirectHistory: order = " + std::to_string(order) +
                                " must be finite");
  }
  if (dimension < 1 || capacity < 1) {
    throw std::invalid_argument("DirectHistory: dimension = " + std::to_string(dimension) +
                                " and capacity = " + std::to_string(capacity) + " must be >= 1");
  }
  weights_ = quadrature.weights(capacity);
  values_.assign(capacity * static_cast<std::size_t>(dimension), 0.0);
}

void DirectHistory::push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) {
  assert(size_ < capacity() && x_tilde.size() == dimension_);
  Eigen::Map<Eigen::VectorXd>(values_.data() + size_ * static_cast<std::size_t>(dimension_),
                              dimension_) = x_tilde;
  ++size_;
}

void DirectHistory::sum(Eigen::Ref<Eigen::VectorXd> out) const {
  assert(size_ >= 1 && out.size() == dimension_);
  // Σ_{m=0}^{k} c_m x̃_{k−m}, walking the stored values in memory order (j = k − m ascending).
  const std::size_t k = size_ - 1;
  const auto d = static_cast<std::size_t>(dimension_);
  out.setZero();
  accumulate_causal(
      weights_, k,
      [&](std::size_t j) {
        return Eigen::Map<const Eigen::VectorXd>(values_.data() + j * d, dimension_);
      },
      out);
}

void DirectHistory::visit_state(StateArchive& archive) {
  archive.expect("direct.dimension", static_cast<std::size_t>(dimension_));
  archive.expect("direct.capacity", capacity());
  archive.count("direct.size", size_);
  if (size_ > capacity()) throw CheckpointError("checkpoint record 'direct.size' exceeds capacity");
  // Only the pushed values: the rest of the buffer is never read before it is pushed again.
  archive.doubles("direct.values",
                  std::span<double>(values_.data(), size_ * static_cast<std::size_t>(dimension_)));
}

LocalHistory::LocalHistory(ConvolutionQuadrature quadrature, Eigen::Index dimension)
    : quadrature_(quadrature) {
  if (!quadrature.is_local()) {
    throw std::invalid_argument("LocalHistory: " + quadrature.describe() +
                                " has no terminating weights (order must be 0, 1 or 2, GL or "
                                "BDF2; use DirectHistory otherwise)");
  }
  if (dimension < 1) {
    throw std::invalid_argument("LocalHistory: dimension = " + std::to_string(dimension) +
                                " must be >= 1");
  }
  // δ^0 = 1, GL: (1 − ζ), (1 − ζ)², BDF2: (3/2 − 2ζ + ζ²/2)^{1,2}; exact dyadic coefficients
  // (gl_weights gives the same GL rows, exactly).
  const std::vector<double> w = quadrature.local_weights();
  width_ = static_cast<int>(w.size());
  for (int i = 0; i < width_; ++i) weights_[i] = w[static_cast<std::size_t>(i)];
  window_.setZero(dimension, width_);
}

std::size_t LocalHistory::capacity() const {
  return static_cast<std::size_t>(-1);
}

void LocalHistory::push(const Eigen::Ref<const Eigen::VectorXd>& x_tilde) {
  assert(x_tilde.size() == window_.rows());
  window_.col(static_cast<Eigen::Index>(size_ % static_cast<std::size_t>(width_))) = x_tilde;
  ++size_;
}

void LocalHistory::sum(Eigen::Ref<Eigen::VectorXd> out) const {
  assert(size_ >= 1 && out.size() == window_.rows());
  // Lemma 5.3 for order 1: x̃_k − x̃_{k−1}; terms before x̃_0 are absent (the sums of `DiscEqs`
  // start at index 0). Accumulated oldest first, in the same order as DirectHistory, so that both
  // give bitwise identical sums (the dropped weights are exact zeros).
  const std::size_t k = size_ - 1;
  const auto w = static_cast<std::size_t>(width_);
  const std::size_t first = k + 1 >= w ? k + 1 - w : 0;
  out.setZero();
  accumulate_causal(
      weights_, k, [&](std::size_t j) { return window_.col(static_cast<Eigen::Index>(j % w)); },
      out, first);
}

void LocalHistory::visit_state(StateArchive& archive) {
  archive.expect("local.dimension", static_cast<std::size_t>(window_.rows()));
  archive.expect("local.width", static_cast<std::size_t>(width_));
  archive.count("local.size", size_);
  archive.dense("local.window", window_);
}

void History::begin_row_push(const double*) {
  throw std::logic_error(std::string(kind()) + " history: no push split by rows");
}

void History::push_rows(Eigen::Index, Eigen::Index) {
  throw std::logic_error(std::string(kind()) + " history: no push split by rows");
}

void History::end_row_push() {
  throw std::logic_error(std::string(kind()) + " history: no push split by rows");
}

void History::set_rows_ahead(bool) {
  throw std::logic_error(std::string(kind()) + " history: no push split by rows");
}

void History::rows_ahead(int, int) {
  throw std::logic_error(std::string(kind()) + " history: no push split by rows");
}

std::optional<HistoryKind> parse_history_kind(std::string_view name) {
  if (name == "auto") return HistoryKind::kAuto;
  if (name == "direct") return HistoryKind::kDirect;
  if (name == "fast") return HistoryKind::kFast;
  return std::nullopt;
}

std::string_view to_string(HistoryKind kind) {
  switch (kind) {
    case HistoryKind::kAuto: return "auto";
    case HistoryKind::kDirect: return "direct";
    case HistoryKind::kFast: return "fast";
  }
  return "unknown";
}

std::unique_ptr<History> make_history(HistoryKind kind, const ConvolutionQuadrature& quadrature,
                                      Eigen::Index dimension, std::size_t capacity,
                                      double tolerance) {
  if (kind != HistoryKind::kDirect && quadrature.is_local()) {
    return std::make_unique<LocalHistory>(quadrature, dimension);
  }
  // Fits exist for the non-integer GL weights of orders −1 < β < 2 and BDF2 weights of orders
  // 0 < β < 2, with any lag (exponential_fit.hpp); every other non-local quadrature is summed
  // directly, and asking for a fast history of it is an error.
  const double lowest = quadrature.scheme == CqScheme::kGrunwaldLetnikov ? -1.0 : 0.0;
  const bool fit_exists = quadrature.scheme != CqScheme::kTrapezoidal &&
                          quadrature.order != std::round(quadrature.order) &&
                          quadrature.order > lowest && quadrature.order < 2.0;
  if (kind == HistoryKind::kFast && !fit_exists) {
    throw std::invalid_argument("method.history = \"fast\" is not available for the " +
                                quadrature.describe() +
                                " (no sum-of-exponentials fit of its weights yet); use \"auto\" "
                                "or \"direct\"");
  }
  if (kind == HistoryKind::kFast ||
      (kind == HistoryKind::kAuto && fit_exists && fast_history_pays(capacity, dimension))) {
    return make_fast_history(quadrature, dimension, capacity, tolerance);
  }
  return std::make_unique<DirectHistory>(quadrature, dimension, capacity);
}

}  // namespace fracvi
