// Band LU with partial pivoting of a general n × n matrix of lower bandwidth kl and upper
// bandwidth ku (internal; public for tests): LAPACK's dgbtrf factors, the solve is dgbtrs's
// substitutions in plain loops over the factor packed after each factorisation, with U's rows
// scaled by its diagonal so that the backward pass multiplies instead of dividing.
//
// Used by the Lobatto schemes' stage matrix (not symmetric; fvi_lobatto.cpp) and by the midpoint
// schemes' band backend when J is not positive definite (symmetric_factor.cpp).
//
// Why not dgbtrs: it takes each column through a level-2 BLAS call (dger for L, dtbsv for U); with
// Debian's reference BLAS those calls on columns of 3–6 entries were 30 % of an fvi-lobatto3 step
// of the β-FPUT chain at d = 1000 (perf), and the step ran 1.2–1.6× slower than with Eigen's
// sparse LU (bench/RESULTS.md). Here L's multipliers (kl per column) and D⁻¹U's columns (diagonal
// upwards; D = diag(U), whose reciprocals are kept) are copied contiguously after dgbtrf, U's band
// only ku widened by the farthest row interchange (kl + ku at most): a solve streams two dense
// arrays. Without interchanges and for the bands of chains' Lobatto stage systems ((kl, ku) =
// (1, 3), (2, 4)) the substitutions keep the next values in registers (band_lu.cpp, SlidingSolve).
//
// All storage is sized at construction: factor() and solve_in_place() do not allocate.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace fracvi::internal {

class BandLu {
 public:
  BandLu() = default;
  /// Storage for an n × n matrix with bandwidths kl, ku (all zero).
  BandLu(Eigen::Index n, Eigen::Index kl, Eigen::Index ku);

  /// Bytes of LAPACK band storage for these sizes (the packed factor adds at most as much again).
  [[nodiscard]] static double storage_bytes(Eigen::Index n, Eigen::Index kl, Eigen::Index ku);

  /// U's bandwidth in the current factor: ku + the farthest row interchange (≤ kl + ku).
  [[nodiscard]] Eigen::Index factor_upper_bandwidth() const { return factor_ku_; }

  /// LAPACK's column-major band storage with kl extra rows for the fill of row interchanges
  /// (ldab = 2kl + ku + 1): A(i, j), |i − j| within the band, at band()[offset(i, j)]. Fill it
  /// (entries outside the matrix's band must be zero), then factor(); factor() overwrites it.
  [[nodiscard]] std::vector<double>& band() { return band_; }
  [[nodiscard]] const std::vector<double>& band() const { return band_; }
  [[nodiscard]] std::size_t offset(Eigen::Index i, Eigen::Index j) const {
    return static_cast<std::size_t>(kl_ + ku_ + i - j + j * rows_);
  }

  /// Factors the matrix in band() (dgbtrf) and packs the factor. Returns false if U has an exact
  /// zero pivot (dgbtrf's info > 0: singular).
  bool factor() noexcept;
  /// x ← A⁻¹x, x of length n. No allocation.
  void solve_in_place(double* x) const noexcept;

 private:
  Eigen::Index n_ = 0, kl_ = 0, ku_ = 0, rows_ = 0, factor_ku_ = 0;
  std::vector<double> band_;
  std::vector<int> pivots_;           // dgbtrf's, 1-based
  std::vector<double> packed_lower_;  // L's multipliers, kl per column
  std::vector<double> packed_upper_;  // D⁻¹U's columns from the diagonal up, kl + ku + 1 per column
  std::vector<double> reciprocal_;  // D⁻¹: 1 / U(j, j)
  bool pivoted_ = false;            // any row interchange in the current factor
};

}  // namespace fracvi::internal
