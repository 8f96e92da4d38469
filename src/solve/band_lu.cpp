#include "fracvi/solve/band_lu.hpp"

#include <lapacke.h>

#include <algorithm>
#include <type_traits>
#include <utility>

namespace fracvi::internal {

static_assert(std::is_same_v<lapack_int, int>, "BandLu stores LAPACK's pivots as int");

BandLu::BandLu(Eigen::Index n, Eigen::Index kl, Eigen::Index ku)
    : n_(n), kl_(kl), ku_(ku), rows_(2 * kl + ku + 1), factor_ku_(ku) {
  const auto size = static_cast<std::size_t>(n);
  band_.assign(static_cast<std::size_t>(rows_) * size, 0.0);
  pivots_.assign(size, 0);
  packed_lower_.assign(static_cast<std::size_t>(kl) * size, 0.0);
  packed_upper_.assign(static_cast<std::size_t>(kl + ku + 1) * size, 0.0);
}

double BandLu::storage_bytes(Eigen::Index n, Eigen::Index kl, Eigen::Index ku) {
  return 8.0 * static_cast<double>(2 * kl + ku + 1) * static_cast<double>(n);
}

bool BandLu::factor() noexcept {
  if (LAPACKE_dgbtrf_work(LAPACK_COL_MAJOR, static_cast<lapack_int>(n_),
                          static_cast<lapack_int>(n_), static_cast<lapack_int>(kl_),
                          static_cast<lapack_int>(ku_), band_.data(),
                          static_cast<lapack_int>(rows_), pivots_.data()) != 0) {
    return false;
  }
  // U's band: ku, widened by the farthest row interchange (row j taking row p brings that row's
  // reach p + ku, and eliminations only mix rows within it). Entries beyond it are the exact
  // zeros dgbtrf wrote; the solve skips them (no interchange: ku, not kl + ku).
  Eigen::Index farthest = 0;
  for (Eigen::Index j = 0; j < n_; ++j) {
    farthest = std::max<Eigen::Index>(farthest, pivots_[static_cast<std::size_t>(j)] - 1 - j);
  }
  factor_ku_ = ku_ + farthest;
  // The solve streams L's multipliers forwards and U's columns backwards: each packed
  // contiguously, without the band storage's unused rows (at d = 10^4, s = 3 a Lobatto solve reads
  // 1.1 MB instead of the 1.6 MB band storage twice).
  const Eigen::Index kv = kl_ + ku_, ub = factor_ku_;
  for (Eigen::Index j = 0; j < n_; ++j) {
    const double* column = band_.data() + j * rows_;
    std::copy_n(column + kv + 1, kl_, packed_lower_.data() + j * kl_);
    for (Eigen::Index r = 0; r <= ub; ++r)  // U(j, j), U(j − 1, j), …, U(j − ub, j)
      packed_upper_[static_cast<std::size_t>(j * (ub + 1) + r)] = column[kv - r];
  }
  return true;
}

// What dgbtrs does for one right-hand side: the row interchanges and L's multipliers column by
// column, then U backwards.
void BandLu::solve_in_place(double* x) const noexcept {
  for (Eigen::Index j = 0; j + 1 < n_; ++j) {
    const Eigen::Index pivot = pivots_[static_cast<std::size_t>(j)] - 1;
    if (pivot != j) std::swap(x[pivot], x[j]);
    const double xj = x[j];
    const double* multipliers = packed_lower_.data() + j * kl_;
    const Eigen::Index below = std::min(kl_, n_ - 1 - j);
    for (Eigen::Index i = 0; i < below; ++i) x[j + 1 + i] -= multipliers[i] * xj;
  }
  const Eigen::Index ub = factor_ku_;
  for (Eigen::Index j = n_ - 1; j >= 0; --j) {
    const double* column = packed_upper_.data() + j * (ub + 1);  // column[r] = U(j − r, j)
    x[j] /= column[0];
    const double xj = x[j];
    const Eigen::Index above = std::min(ub, j);
    for (Eigen::Index r = 1; r <= above; ++r) x[j - r] -= column[r] * xj;
  }
}

}  // namespace fracvi::internal
