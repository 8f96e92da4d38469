// The one convolution of the memory terms, written once.
//
// Every fractional term of the discrete setting is a convolution with convolution-quadrature
// weights w (fractional/convolution_quadrature.hpp):
//
//     causal ("past", Δ^α_−, the damping sum of the steppers):   Σ_{m=0}^{k}   w_m z_{k−m},
//     anti-causal ("future", Δ^α_+, the mirror y-equation):       Σ_{m=0}^{N−k} w_m z_{k+m},
//
// and the anti-causal sum is the causal one of the reversed series (z'_j = z_{N−j}, k' = N − k).
// Two forms serve every caller:
//  * accumulate_causal(): one index k, any value type (double, an Eigen vector, an AutoDiff
//    scalar): the direct and local histories of the integrator and the templated phase points of
//    the action sum (differentiated by AutoDiff in the tests).
//  * SeriesConvolution: a whole series k = 0 … n−1 at once, directly for short series and by a
//    zero-padded real FFT (O(n log n)) for long ones: the discrete operators Δ^α_±, the action
//    sum's phase points and equations (DiscFracEL), and the BVP.
#pragma once

#include <complex>
#include <cstddef>
#include <vector>

namespace fracvi {

/// acc += Σ_{j=first}^{k} w_{k−j} z(j): the causal sum Σ_{m=0}^{k−first} w_m z_{k−m}, accumulated
/// oldest value first (j ascending). Terms with j < first are left out (a local history keeps only
/// the values whose weights are nonzero). Every direct memory sum uses this one order, so that
/// the direct and the local history give bitwise identical sums (the dropped weights are exact
/// zeros) and the integrator's results do not depend on which of them ran.
template <class Weights, class Series, class Accumulator>
void accumulate_causal(const Weights& w, std::size_t k, const Series& z, Accumulator&& acc,
                       std::size_t first = 0) {
  for (std::size_t j = first; j <= k; ++j) acc += w[k - j] * z(j);
}

/// Series of this length and longer are convolved by FFT (the direct sum below: O(n²) is cheaper
/// for short series; docs/theory/discrete_euler_lagrange.md §6).
inline constexpr std::size_t kFftConvolutionThreshold = 257;

/// out_k = scale · Σ_{m=0}^{k} w_m s_{k−m}, k = 0 … n−1, for series s of length n = w.size().
class SeriesConvolution {
 public:
  SeriesConvolution() = default;
  /// The weights w_0 … w_{n−1} fix the series length n; `scale` multiplies every sum (h^{−α}).
  SeriesConvolution(std::vector<double> weights, double scale);

  [[nodiscard]] std::size_t length() const { return weights_.size(); }
  [[nodiscard]] const std::vector<double>& weights() const { return weights_; }
  [[nodiscard]] double scale() const { return scale_; }
  [[nodiscard]] bool uses_fft() const { return fft_size_ != 0; }

  /// The series s_k = s[k·stride], results to out[k·out_stride] (added when `accumulate`).
  /// `reverse`: s and out are read and written backwards, giving the anti-causal sum
  /// scale · Σ_{m=0}^{n−1−k} w_m s_{k+m}. Allocates a work buffer only on the FFT path.
  void apply(const double* s, std::ptrdiff_t stride, double* out, std::ptrdiff_t out_stride,
             bool reverse = false, bool accumulate = false) const;

 private:
  std::vector<double> weights_;
  double scale_ = 1.0;
  int fft_size_ = 0;  // 0: direct sums
  std::vector<std::complex<double>> weight_spectrum_;
};

}  // namespace fracvi
