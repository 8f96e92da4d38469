#include "fracvi/fractional/convolution.hpp"

#include <unsupported/Eigen/FFT>

namespace fracvi {

SeriesConvolution::SeriesConvolution(std::vector<double> weights, double scale)
    : weights_(std::move(weights)), scale_(scale) {
  const std::size_t n = weights_.size();
  if (n < kFftConvolutionThreshold) return;
  // Linear convolution by a zero-padded real FFT: length ≥ 2n, so no wrap-around.
  std::size_t size = 1;
  while (size < 2 * n) size *= 2;
  fft_size_ = static_cast<int>(size);
  std::vector<double> padded(size, 0.0);
  for (std::size_t m = 0; m < n; ++m) padded[m] = scale_ * weights_[m];
  weight_spectrum_.resize(size / 2 + 1);
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  fft.fwd(weight_spectrum_.data(), padded.data(), fft_size_);
}

void SeriesConvolution::apply(const double* s, std::ptrdiff_t stride, double* out,
                              std::ptrdiff_t out_stride, bool reverse, bool accumulate) const {
  const auto n = static_cast<std::ptrdiff_t>(weights_.size());
  // Element k of the (possibly reversed) series, and where its result goes.
  auto in = [&](std::size_t k) {
    const auto i = static_cast<std::ptrdiff_t>(k);
    return s[(reverse ? n - 1 - i : i) * stride];
  };
  auto put = [&](std::size_t k, double v) {
    const auto i = static_cast<std::ptrdiff_t>(k);
    double& o = out[(reverse ? n - 1 - i : i) * out_stride];
    o = accumulate ? o + v : v;
  };
  if (fft_size_ == 0) {
    for (std::size_t k = 0; k < weights_.size(); ++k) {
      double acc = 0.0;
      accumulate_causal(weights_, k, in, acc);
      put(k, scale_ * acc);
    }
    return;
  }
  const auto size = static_cast<std::size_t>(fft_size_);
  std::vector<double> buffer(size, 0.0);
  for (std::size_t k = 0; k < weights_.size(); ++k) buffer[k] = in(k);
  std::vector<std::complex<double>> spectrum(size / 2 + 1);
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  fft.fwd(spectrum.data(), buffer.data(), fft_size_);
  for (std::size_t q = 0; q < spectrum.size(); ++q) spectrum[q] *= weight_spectrum_[q];
  fft.inv(buffer.data(), spectrum.data(), fft_size_);
  for (std::size_t k = 0; k < weights_.size(); ++k) put(k, buffer[k]);
}

}  // namespace fracvi
