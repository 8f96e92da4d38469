// OnlineConvolution: the memory sums of a Volterra-type scheme whose weights have no
// sum-of-exponentials fit (product integration, pi-trapezoid), in O(log² N) amortised work per
// step instead of the direct sum's O(N) — the fast convolution of Hairer, Lubich & Schlichte (SIAM
// J. Sci. Stat. Comput. 6(3), 1985), which Garrappa's FDE codes use for the same method.
//
// The sums are the strictly lower-triangular Toeplitz products
//
//     s_n = Σ_{j=0}^{n−1} w_{n−j} z_j,        n = 1, 2, …,
//
// of a series z_0, z_1, … of d-vectors that become known one at a time (z_n depends on s_n:
// the current weight w_0 belongs to the implicit equation of the step, not to the history).
// Every pair (n, j), j < n, lies in exactly one square block: with B = 2^b and b the highest bit in
// which n and j differ, j ∈ [2c·B, (2c+1)·B) and n ∈ [(2c+1)·B, (2c+2)·B). The block's sources are
// all known once z_{(2c+1)B−1} is, and its targets are all still ahead; and for k + 1 = (2c+1)·B
// the block size B is the lowest set bit of k + 1. So commit(k), called when z_k is final, applies
// exactly one block: the last B values times the B × B Toeplitz matrix of w_1 … w_{2B−1}, added
// to the next B sums. A level costs O(B log B) per 2B steps: O(log² N) per step over all levels.
// Blocks up to kDirectBlock are summed directly (B² multiply–adds per component); larger ones
// by a real FFT of length 2B per component (the circular product of length 2B is exact on the
// targets: their lags B … 2B−1 never wrap), with the weights' spectrum of every level computed
// at construction.
//
// The values stay with the caller (rows of a row-major matrix it fills as the run goes); the
// object keeps the partial sums s_n for all n ≤ capacity (O(N·d) memory, as the direct sum) and
// the spectra (O(N)). commit() and pending() never allocate: every FFT size is planned and its
// buffers sized at construction.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <cstddef>
#include <memory>
#include <vector>

#include "fracvi/core/matrix.hpp"

namespace fracvi {

class OnlineConvolution {
 public:
  /// Blocks of this size and smaller are applied directly. Measured on whole runs of commits
  /// (2026-11-26, loaded 2-core machine), limit 8, 16, 32, 64, 128: d = 1, N = 40960: 9.1, 9.7,
  /// 10.4, 17.9, 26.2 ms; d = 100, N = 4096: 64, 41, 46, 50, 42 ms.
  static constexpr std::size_t kDirectBlock = 32;

  /// The sums s_1 … s_{capacity−1} of the series held in rows first, first + 1, … of the
  /// caller's values matrix, with weights w_1 … w_{capacity−1} (weights[m] = w_m; weights[0] is
  /// not used). Throws std::invalid_argument if dimension < 1, capacity < 1 or weights has fewer
  /// than capacity entries.
  OnlineConvolution(const Eigen::Ref<const Eigen::VectorXd>& weights, Eigen::Index dimension,
                    std::size_t capacity, Eigen::Index first = 0);
  ~OnlineConvolution();
  OnlineConvolution(OnlineConvolution&&) noexcept;
  OnlineConvolution& operator=(OnlineConvolution&&) noexcept;

  /// z_k = values.row(first + k) is final; k must be the number of earlier commits. Adds the
  /// block that z_k completes to the sums s_{k+1} … (those below capacity).
  void commit(std::size_t k, const RowMatrixXd& values);
  /// s_n = Σ_{j<n} w_{n−j} z_j. Precondition: n ≤ committed() and n < capacity.
  [[nodiscard]] auto pending(std::size_t n) const {
    return pending_.row(static_cast<Eigen::Index>(n));
  }
  [[nodiscard]] std::size_t committed() const { return committed_; }
  [[nodiscard]] std::size_t capacity() const { return static_cast<std::size_t>(pending_.rows()); }
  /// Bytes held: the partial sums, the weights, the spectra and the FFT buffers.
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  struct Fft;  // Eigen's FFT object (kept out of this header) and its buffers
  Eigen::Index first_;
  Eigen::VectorXd weights_;  // w_0 … w_{capacity−1}
  RowMatrixXd pending_;      // row n: s_n so far
  // spectra_[b]: half spectrum of (0, w_1, …, w_{2B−1}) with B = 2^b, for the FFT levels.
  std::vector<std::vector<std::complex<double>>> spectra_;
  std::unique_ptr<Fft> fft_;
  std::size_t committed_ = 0;
};

}  // namespace fracvi
