#include "fracvi/memory/online_convolution.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <unsupported/Eigen/FFT>

namespace fracvi {

struct OnlineConvolution::Fft {
  Eigen::FFT<double> fft;
  std::vector<double> signal;                  // 2B: one component of a source block, zero padded
  std::vector<std::complex<double>> spectrum;  // B + 1
};

namespace {

// b with 2^b = B, for a power of two B.
std::size_t level_of(std::size_t block) {
  std::size_t level = 0;
  while ((std::size_t{1} << level) < block) ++level;
  return level;
}

}  // namespace

OnlineConvolution::OnlineConvolution(const Eigen::Ref<const Eigen::VectorXd>& weights,
                                     Eigen::Index dimension, std::size_t capacity,
                                     Eigen::Index first)
    : first_(first), fft_(std::make_unique<Fft>()) {
  if (dimension < 1 || capacity < 1 || first < 0 ||
      weights.size() < static_cast<Eigen::Index>(capacity)) {
    throw std::invalid_argument(
        "OnlineConvolution: dimension and capacity must be >= 1, first >= 0 and the weights must "
        "cover every lag below the capacity (dimension " +
        std::to_string(dimension) + ", capacity " + std::to_string(capacity) + ", " +
        std::to_string(weights.size()) + " weights)");
  }
  weights_ = weights.head(static_cast<Eigen::Index>(capacity));
  pending_.setZero(static_cast<Eigen::Index>(capacity), dimension);
  // The FFT levels: blocks kDirectBlock < B < capacity (a block of B ≥ capacity has no target).
  fft_->fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::size_t largest = 0;
  for (std::size_t block = 2 * kDirectBlock; block < capacity; block *= 2) largest = block;
  if (largest == 0) return;
  spectra_.resize(level_of(largest) + 1);
  fft_->signal.assign(2 * largest, 0.0);
  fft_->spectrum.assign(largest + 1, {0.0, 0.0});
  for (std::size_t block = 2 * kDirectBlock; block <= largest; block *= 2) {
    // (0, w_1, …, w_{2B−1}); lags at or beyond the capacity never reach a target: zero.
    std::vector<double> kernel(2 * block, 0.0);
    for (std::size_t m = 1; m < 2 * block && m < capacity; ++m)
      kernel[m] = weights_[static_cast<Eigen::Index>(m)];
    auto& spectrum = spectra_[level_of(block)];
    spectrum.resize(block + 1);
    fft_->fft.fwd(spectrum.data(), kernel.data(), static_cast<Eigen::Index>(2 * block));
    // Plan the inverse too, so that commit() finds every plan and buffer in place.
    fft_->fft.inv(kernel.data(), spectrum.data(), static_cast<Eigen::Index>(2 * block));
  }
}

OnlineConvolution::~OnlineConvolution() = default;
OnlineConvolution::OnlineConvolution(OnlineConvolution&&) noexcept = default;
OnlineConvolution& OnlineConvolution::operator=(OnlineConvolution&&) noexcept = default;

std::size_t OnlineConvolution::memory_bytes() const {
  std::size_t bytes = static_cast<std::size_t>(weights_.size() + pending_.size()) * sizeof(double) +
                      fft_->signal.size() * sizeof(double) +
                      fft_->spectrum.size() * sizeof(std::complex<double>);
  for (const auto& s : spectra_) bytes += s.size() * sizeof(std::complex<double>);
  return bytes;
}

void OnlineConvolution::commit(std::size_t k, const RowMatrixXd& values) {
  if (k != committed_) {
    throw std::logic_error("OnlineConvolution::commit: values must be committed in order (got " +
                           std::to_string(k) + ", expected " + std::to_string(committed_) + ")");
  }
  ++committed_;
  const std::size_t block = (k + 1) & ~k;  // the lowest set bit of k + 1
  const std::size_t target = k + 1;        // the block's first target; its sources end at k
  const std::size_t capacity = this->capacity();
  if (target >= capacity) return;
  const std::size_t count = std::min(block, capacity - target);
  const Eigen::Index source = first_ + static_cast<Eigen::Index>(target - block);
  if (block <= kDirectBlock) {
    for (std::size_t r = 0; r < count; ++r) {
      auto sum = pending_.row(static_cast<Eigen::Index>(target + r));
      for (std::size_t i = 0; i < block; ++i) {
        sum += weights_[static_cast<Eigen::Index>(block + r - i)] *
               values.row(source + static_cast<Eigen::Index>(i));
      }
    }
    return;
  }
  const auto& kernel = spectra_[level_of(block)];
  const auto size = static_cast<Eigen::Index>(2 * block);
  double* signal = fft_->signal.data();
  std::complex<double>* spectrum = fft_->spectrum.data();
  for (Eigen::Index c = 0; c < pending_.cols(); ++c) {
    for (std::size_t i = 0; i < block; ++i)
      signal[i] = values(source + static_cast<Eigen::Index>(i), c);
    std::fill(signal + block, signal + 2 * block, 0.0);
    fft_->fft.fwd(spectrum, signal, size);
    for (std::size_t q = 0; q <= block; ++q) spectrum[q] *= kernel[q];
    fft_->fft.inv(signal, spectrum, size);
    // Circular product of length 2B: out_{B+r} = Σ_i z_{source+i} w_{B+r−i}, lags 1 … 2B−1.
    for (std::size_t r = 0; r < count; ++r)
      pending_(static_cast<Eigen::Index>(target + r), c) += signal[block + r];
  }
}

}  // namespace fracvi
