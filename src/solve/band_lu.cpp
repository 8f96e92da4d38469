#include "fracvi/solve/band_lu.hpp"

#include <lapacke.h>

#include <algorithm>
#include <type_traits>
#include <utility>

#include "fracvi/internal/vectorize.hpp"

namespace fracvi::internal {

static_assert(std::is_same_v<lapack_int, int>, "BandLu stores LAPACK's pivots as int");

BandLu::BandLu(Eigen::Index n, Eigen::Index kl, Eigen::Index ku)
    : n_(n), kl_(kl), ku_(ku), rows_(2 * kl + ku + 1), factor_ku_(ku) {
  const auto size = static_cast<std::size_t>(n);
  band_.assign(static_cast<std::size_t>(rows_) * size, 0.0);
  pivots_.assign(size, 0);
  packed_lower_.assign(static_cast<std::size_t>(kl) * size, 0.0);
  packed_upper_.assign(static_cast<std::size_t>(kl + ku + 1) * size, 0.0);
  reciprocal_.assign(size, 0.0);
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
  // 1.1 MB instead of the 1.6 MB band storage twice). U is packed scaled by rows, D⁻¹U with
  // D = diag(U), and D⁻¹ kept: the backward substitution then multiplies where dgbtrs divides
  // (the division's latency was on the solve's dependency chain: solve_in_place below).
  const Eigen::Index kv = kl_ + ku_, ub = factor_ku_;
  pivoted_ = false;
  for (Eigen::Index j = 0; j < n_; ++j) {  // ascending: 1/U(j − r, j − r) is known at column j
    const double* column = band_.data() + j * rows_;
    std::copy_n(column + kv + 1, kl_, packed_lower_.data() + j * kl_);
    reciprocal_[static_cast<std::size_t>(j)] = 1.0 / column[kv];
    pivoted_ = pivoted_ || pivots_[static_cast<std::size_t>(j)] - 1 != j;
    double* packed = packed_upper_.data() + j * (ub + 1);
    packed[0] = 1.0;                        // D⁻¹U's diagonal (not read)
    for (Eigen::Index r = 1; r <= ub; ++r)  // (D⁻¹U)(j − r, j) = U(j − r, j) / U(j − r, j − r)
      packed[r] = j >= r ? column[kv - r] * reciprocal_[static_cast<std::size_t>(j - r)] : 0.0;
  }
  return true;
}

namespace {

// The solve's two substitutions are chains of dependent operations (each x_j waits for the
// update from x_{j−1}, or x_{j+1} backwards): plain loops over x pay a store and a reload on that
// chain per entry, ≈ 12–15 ns per unknown (kl = ku = 3, n = 2000: 30 µs a solve). For the bands
// of the Lobatto stage systems of chains (b = 1) in the stage order StageMatrix chooses so that
// they need no row interchange (fvi_lobatto.cpp) — (kl, ku) = (s − 2, s): (1, 3) for s = 3,
// (2, 4) for s = 4, in the x-step and the mirror's y-step (measured; also with the springs'
// stiffness at 0, whose Hessian keeps its tridiagonal pattern) — SlidingSolve keeps the next KL
// (forwards) or UB (backwards) partial values in registers, so only the arithmetic remains on the
// chain. Other bands, and factors with interchanges, take the plain loops.
template <int KL, int UB>
struct SlidingSolve {
  // Forward: y = L⁻¹x (no interchanges), then D⁻¹y into x. Backward: x ← (D⁻¹U)⁻¹x.
  [[gnu::always_inline]] static inline void run(Eigen::Index n, const double* lower,
                                                const double* upper, const double* reciprocal,
                                                double* x) {
    Eigen::Index j = 0;
    if (n > KL + UB + 1) {
      double w[KL];  // x_{j+1} … x_{j+KL}, each with the updates of x_0 … x_{j−1}
      for (int i = 0; i < KL; ++i) w[i] = x[i + 1];
      double xj = x[0];
      for (; j + KL + 1 < n; ++j) {
        const double* m = lower + j * KL;
        const double entering = x[j + KL + 1];
        x[j] = xj * reciprocal[j];
        const double final = xj;
        xj = w[0] - m[0] * final;
        for (int i = 0; i + 1 < KL; ++i) w[i] = w[i + 1] - m[i + 1] * final;
        if constexpr (KL > 0) w[KL - 1] = entering;
      }
      x[j] = xj;
      for (int i = 0; i < KL; ++i) x[j + 1 + i] = w[i];
    }
    for (; j < n; ++j) {  // the last rows: the plain loop
      const double xj = x[j];
      x[j] = xj * reciprocal[j];
      const double* m = lower + j * KL;
      const Eigen::Index below = std::min<Eigen::Index>(KL, n - 1 - j);
      for (Eigen::Index i = 0; i < below; ++i) x[j + 1 + i] -= m[i] * xj;
    }
    j = n - 1;
    if (n > KL + UB + 1) {
      double w[UB];  // x_{j−1} … x_{j−UB}, each with the updates of x_{j+1} … x_{n−1}
      for (int r = 0; r < UB; ++r) w[r] = x[j - 1 - r];
      double xj = x[j];
      for (; j - UB - 1 >= 0; --j) {
        const double* c = upper + j * (UB + 1);
        const double entering = x[j - UB - 1];
        x[j] = xj;
        const double final = xj;
        xj = w[0] - c[1] * final;
        for (int r = 1; r < UB; ++r) w[r - 1] = w[r] - c[r + 1] * final;
        if constexpr (UB > 0) w[UB - 1] = entering;
      }
      x[j] = xj;
      for (int r = 0; r < UB; ++r) x[j - 1 - r] = w[r];
    }
    for (; j >= 0; --j) {
      const double* c = upper + j * (UB + 1);
      const double xj = x[j];
      const Eigen::Index above = std::min<Eigen::Index>(UB, j);
      for (Eigen::Index r = 1; r <= above; ++r) x[j - r] -= c[r] * xj;
    }
  }
};

FRACVI_HOT_KERNEL
bool sliding_solve(Eigen::Index n, Eigen::Index kl, Eigen::Index ub, const double* lower,
                   const double* upper, const double* reciprocal, double* x) {
  if (kl == 1 && ub == 3) {
    SlidingSolve<1, 3>::run(n, lower, upper, reciprocal, x);
  } else if (kl == 2 && ub == 4) {
    SlidingSolve<2, 4>::run(n, lower, upper, reciprocal, x);
  } else {
    return false;
  }
  return true;
}

}  // namespace

// What dgbtrs does for one right-hand side — the row interchanges and L's multipliers column by
// column, then U backwards — with U's rows scaled by D⁻¹ (factor()): x_j is multiplied by
// 1/U(j, j) once final in the forward pass, and the backward pass only subtracts. Not dgbtrs's
// numbers bit for bit (D⁻¹U's entries are rounded once more); backward stable like it
// (tests/integrate/band_lu_test.cpp).
void BandLu::solve_in_place(double* x) const noexcept {
  if (!pivoted_ && sliding_solve(n_, kl_, factor_ku_, packed_lower_.data(), packed_upper_.data(),
                                 reciprocal_.data(), x)) {
    return;
  }
  for (Eigen::Index j = 0; j + 1 < n_; ++j) {
    const Eigen::Index pivot = pivots_[static_cast<std::size_t>(j)] - 1;
    if (pivot != j) std::swap(x[pivot], x[j]);
    const double xj = x[j];
    x[j] = xj * reciprocal_[static_cast<std::size_t>(j)];  // final: later interchanges are below
    const double* multipliers = packed_lower_.data() + j * kl_;
    const Eigen::Index below = std::min(kl_, n_ - 1 - j);
    for (Eigen::Index i = 0; i < below; ++i) x[j + 1 + i] -= multipliers[i] * xj;
  }
  if (n_ > 0) x[n_ - 1] *= reciprocal_[static_cast<std::size_t>(n_ - 1)];
  const Eigen::Index ub = factor_ku_;
  for (Eigen::Index j = n_ - 1; j >= 0; --j) {
    const double* column = packed_upper_.data() + j * (ub + 1);  // column[r] = (D⁻¹U)(j − r, j)
    const double xj = x[j];
    const Eigen::Index above = std::min(ub, j);
    for (Eigen::Index r = 1; r <= above; ++r) x[j - r] -= column[r] * xj;
  }
}

}  // namespace fracvi::internal
