#include "fracvi/solve/symmetric_factor.hpp"

#include <lapacke.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

namespace fracvi {

std::optional<LinearSolver> parse_linear_solver(std::string_view name) {
  if (name == "auto") return LinearSolver::kAuto;
  if (name == "dense") return LinearSolver::kDense;
  if (name == "banded") return LinearSolver::kBanded;
  if (name == "sparse") return LinearSolver::kSparse;
  return std::nullopt;
}

std::string_view to_string(LinearSolver solver) {
  switch (solver) {
    case LinearSolver::kAuto: return "auto";
    case LinearSolver::kDense: return "dense";
    case LinearSolver::kBanded: return "banded";
    case LinearSolver::kSparse: return "sparse";
  }
  return "unknown";
}

namespace internal {

SymmetricPattern::SymmetricPattern(Eigen::Index dimension) : d_(dimension) {
  if (dimension < 1) {
    throw std::invalid_argument("SymmetricPattern: dimension = " + std::to_string(dimension) +
                                " must be >= 1");
  }
  entries_.reserve(static_cast<std::size_t>(dimension));
  for (Eigen::Index i = 0; i < dimension; ++i) entries_.push_back({i, i});
}

void SymmetricPattern::add(const ModelMatrix& a) {
  if (final_) throw std::logic_error("SymmetricPattern::add after finalize()");
  if (!a.is_sparse()) {
    for (Eigen::Index j = 0; j < a.cols(); ++j)
      for (Eigen::Index i = 0; i <= j; ++i) entries_.push_back({i, j});
    return;
  }
  const ModelMatrix::Sparse& s = a.sparse();
  for (Eigen::Index j = 0; j < s.outerSize(); ++j) {
    for (ModelMatrix::Sparse::InnerIterator it(s, j); it; ++it) {
      entries_.push_back({std::min(it.row(), it.col()), std::max(it.row(), it.col())});
    }
  }
}

void SymmetricPattern::add(const Potential& potential) {
  if (final_) throw std::logic_error("SymmetricPattern::add after finalize()");
  if (!potential.has_sparse_hessian()) {
    for (Eigen::Index j = 0; j < d_; ++j)
      for (Eigen::Index i = 0; i <= j; ++i) entries_.push_back({i, j});
    return;
  }
  for (const auto& e : potential.hessian_pattern()) {
    if (e.row < 0 || e.col < 0 || e.row >= d_ || e.col >= d_) {
      throw std::invalid_argument("Potential::hessian_pattern has entry (" + std::to_string(e.row) +
                                  ", " + std::to_string(e.col) + ") outside the " +
                                  std::to_string(d_) + " x " + std::to_string(d_) + " matrix");
    }
    entries_.push_back({std::min(e.row, e.col), std::max(e.row, e.col)});
  }
}

void SymmetricPattern::finalize() {
  auto by_column = [](const Potential::HessianEntry& a, const Potential::HessianEntry& b) {
    return a.col != b.col ? a.col < b.col : a.row < b.row;
  };
  std::sort(entries_.begin(), entries_.end(), by_column);
  entries_.erase(
      std::unique(entries_.begin(), entries_.end(),
                  [](const auto& a, const auto& b) { return a.row == b.row && a.col == b.col; }),
      entries_.end());
  column_start_.assign(static_cast<std::size_t>(d_) + 1, 0);
  for (const auto& e : entries_) ++column_start_[static_cast<std::size_t>(e.col) + 1];
  for (std::size_t j = 0; j < static_cast<std::size_t>(d_); ++j)
    column_start_[j + 1] += column_start_[j];
  final_ = true;
}

std::size_t SymmetricPattern::index_of(Eigen::Index row, Eigen::Index col) const {
  if (!final_) throw std::logic_error("SymmetricPattern::index_of before finalize()");
  const Eigen::Index r = std::min(row, col), c = std::max(row, col);
  if (r < 0 || c >= d_) throw std::out_of_range("SymmetricPattern::index_of: outside the matrix");
  const auto first =
      entries_.begin() + static_cast<std::ptrdiff_t>(column_start_[static_cast<std::size_t>(c)]);
  const auto last = entries_.begin() +
                    static_cast<std::ptrdiff_t>(column_start_[static_cast<std::size_t>(c) + 1]);
  const auto it =
      std::lower_bound(first, last, r, [](const auto& e, Eigen::Index v) { return e.row < v; });
  if (it == last || it->row != r) {
    throw std::out_of_range("SymmetricPattern::index_of: (" + std::to_string(r) + ", " +
                            std::to_string(c) + ") is not in the pattern");
  }
  return static_cast<std::size_t>(it - entries_.begin());
}

Eigen::Index SymmetricPattern::bandwidth() const {
  Eigen::Index b = 0;
  for (const auto& e : entries_) b = std::max(b, e.col - e.row);
  return b;
}

LinearSolver choose_factorization(const SymmetricPattern& pattern) {
  const auto d = static_cast<double>(pattern.dimension());
  const double upper_entries = 0.5 * d * (d + 1.0);
  if (pattern.dimension() <= 4 || static_cast<double>(pattern.size()) > 0.25 * upper_entries) {
    return LinearSolver::kDense;
  }
  return pattern.bandwidth() <= kMaxAutoBandwidth ? LinearSolver::kBanded : LinearSolver::kSparse;
}

// LAPACK band storage (column-major). Cholesky, UPLO = 'U': ldab = kd + 1, A(i, j) at
// (kd + i − j) + j·ldab for j − kd ≤ i ≤ j. LU (dgbtrf, kl = ku = kd): ldab = 3kd + 1 (kd extra
// rows for the fill of row interchanges), A(i, j) at (2kd + i − j) + j·ldab for |i − j| ≤ kd.
// Bandwidths 0 and 1 have their own routines: a diagonal is divided by, and a tridiagonal matrix
// goes to LAPACK's dpttrf/dpttrs (LDLᵀ, positive definite) or dgttrf/dgttrs (LU with pivoting),
// which are plain loops — the general band routines call a level-2 BLAS kernel per column, and for
// a chain of 1000 masses that made the factorisation 22 µs instead of a few.
struct SymmetricFactor::Banded {
  lapack_int n = 0, kd = 0, ldab_chol = 0, ldab_lu = 0;
  std::vector<double> chol, lu;
  std::vector<lapack_int> pivots;
  std::vector<std::size_t> chol_at, lu_upper_at, lu_lower_at;  // per pattern entry
  bool use_lu = false;
  // kd ≤ 1: diagonal and first off-diagonal (copies for the LU fallback: dl, d, du, du2).
  std::vector<double> diag, off, lu_dl, lu_d, lu_du, lu_du2;
  std::vector<std::size_t> tri_at;  // per pattern entry: i for (i, i), n + i for (i, i + 1)
};

struct SymmetricFactor::Sparse {
  Eigen::SparseMatrix<double> matrix;  // upper triangle, values in pattern order
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper, Eigen::AMDOrdering<int>> ldlt;
  mutable Eigen::VectorXd scratch;
};

SymmetricFactor::SymmetricFactor(std::shared_ptr<const SymmetricPattern> pattern,
                                 LinearSolver solver)
    : pattern_(std::move(pattern)), backend_(solver) {
  if (!pattern_) throw std::invalid_argument("SymmetricFactor: pattern is null");
  if (solver != LinearSolver::kBanded && solver != LinearSolver::kSparse) {
    throw std::invalid_argument("SymmetricFactor: backend must be banded or sparse");
  }
  const SymmetricPattern& p = *pattern_;
  values_.assign(p.size(), 0.0);
  const Eigen::Index d = p.dimension();
  if (solver == LinearSolver::kBanded) {
    banded_ = std::make_unique<Banded>();
    Banded& b = *banded_;
    b.n = static_cast<lapack_int>(d);
    b.kd = static_cast<lapack_int>(p.bandwidth());
    b.ldab_chol = b.kd + 1;
    b.ldab_lu = 3 * b.kd + 1;
    b.chol.assign(static_cast<std::size_t>(b.ldab_chol) * static_cast<std::size_t>(d), 0.0);
    b.lu.assign(static_cast<std::size_t>(b.ldab_lu) * static_cast<std::size_t>(d), 0.0);
    b.pivots.assign(static_cast<std::size_t>(d), 0);
    const auto kd = static_cast<std::size_t>(b.kd);
    const auto n = static_cast<std::size_t>(d);
    if (b.kd <= 1) {
      b.diag.assign(n, 0.0);
      b.off.assign(n, 0.0);
      for (std::vector<double>* v : {&b.lu_dl, &b.lu_d, &b.lu_du, &b.lu_du2}) v->assign(n, 0.0);
      for (const auto& e : p.entries()) {
        const auto i = static_cast<std::size_t>(e.row);
        b.tri_at.push_back(e.row == e.col ? i : n + i);
      }
      b.chol.clear();
      b.lu.clear();
    } else {
      for (const auto& e : p.entries()) {
        const auto i = static_cast<std::size_t>(e.row), j = static_cast<std::size_t>(e.col);
        b.chol_at.push_back(kd + i - j + j * static_cast<std::size_t>(b.ldab_chol));
        b.lu_upper_at.push_back(2 * kd + i - j + j * static_cast<std::size_t>(b.ldab_lu));
        b.lu_lower_at.push_back(2 * kd + j - i + i * static_cast<std::size_t>(b.ldab_lu));
      }
    }
  } else {
    sparse_ = std::make_unique<Sparse>();
    Sparse& s = *sparse_;
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(p.size());
    for (const auto& e : p.entries()) triplets.emplace_back(e.row, e.col, 1.0);
    s.matrix.resize(d, d);
    s.matrix.setFromTriplets(triplets.begin(), triplets.end());
    s.matrix.makeCompressed();
    s.ldlt.analyzePattern(s.matrix);
    s.scratch.resize(d);
  }
}

SymmetricFactor::~SymmetricFactor() = default;
SymmetricFactor::SymmetricFactor(SymmetricFactor&&) noexcept = default;
SymmetricFactor& SymmetricFactor::operator=(SymmetricFactor&&) noexcept = default;

bool SymmetricFactor::factor() noexcept {
  if (banded_ && banded_->kd <= 1) return factor_tridiagonal();
  if (banded_) {
    Banded& b = *banded_;
    std::fill(b.chol.begin(), b.chol.end(), 0.0);
    for (std::size_t e = 0; e < values_.size(); ++e) b.chol[b.chol_at[e]] = values_[e];
    b.use_lu = false;
    if (LAPACKE_dpbtrf_work(LAPACK_COL_MAJOR, 'U', b.n, b.kd, b.chol.data(), b.ldab_chol) == 0) {
      return true;
    }
    // Not positive definite: band LU with partial pivoting.
    b.use_lu = true;
    std::fill(b.lu.begin(), b.lu.end(), 0.0);
    const auto& entries = pattern_->entries();
    for (std::size_t e = 0; e < values_.size(); ++e) {
      b.lu[b.lu_upper_at[e]] = values_[e];
      if (entries[e].row != entries[e].col) b.lu[b.lu_lower_at[e]] = values_[e];
    }
    return LAPACKE_dgbtrf_work(LAPACK_COL_MAJOR, b.n, b.n, b.kd, b.kd, b.lu.data(), b.ldab_lu,
                               b.pivots.data()) == 0;
  }
  Sparse& s = *sparse_;
  std::copy(values_.begin(), values_.end(), s.matrix.valuePtr());
  s.ldlt.factorize(s.matrix);
  return s.ldlt.info() == Eigen::Success;
}

bool SymmetricFactor::factor_tridiagonal() noexcept {
  Banded& b = *banded_;
  const auto n = static_cast<std::size_t>(b.n);
  std::fill(b.diag.begin(), b.diag.end(), 0.0);
  std::fill(b.off.begin(), b.off.end(), 0.0);
  for (std::size_t e = 0; e < values_.size(); ++e) {
    const std::size_t at = b.tri_at[e];
    (at < n ? b.diag[at] : b.off[at - n]) = values_[e];
  }
  b.use_lu = false;
  if (b.kd == 0) {  // diagonal: solve_in_place divides
    return std::all_of(b.diag.begin(), b.diag.end(), [](double v) { return v != 0.0; });
  }
  std::copy(b.diag.begin(), b.diag.end(), b.lu_d.begin());  // kept for the fallback
  std::copy(b.off.begin(), b.off.end(), b.lu_du.begin());
  if (LAPACKE_dpttrf_work(b.n, b.diag.data(), b.off.data()) == 0) return true;
  b.use_lu = true;  // not positive definite: tridiagonal LU with partial pivoting
  std::copy(b.lu_du.begin(), b.lu_du.end(), b.lu_dl.begin());
  return LAPACKE_dgttrf_work(b.n, b.lu_dl.data(), b.lu_d.data(), b.lu_du.data(), b.lu_du2.data(),
                             b.pivots.data()) == 0;
}

void SymmetricFactor::solve_in_place(Eigen::Ref<Eigen::VectorXd> rhs) const noexcept {
  if (banded_ && banded_->kd == 0) {
    rhs.array() /= Eigen::Map<const Eigen::ArrayXd>(banded_->diag.data(), rhs.size());
    return;
  }
  if (banded_ && banded_->kd == 1) {
    const Banded& b = *banded_;
    if (b.use_lu) {
      LAPACKE_dgttrs_work(LAPACK_COL_MAJOR, 'N', b.n, 1, b.lu_dl.data(), b.lu_d.data(),
                          b.lu_du.data(), b.lu_du2.data(), b.pivots.data(), rhs.data(), b.n);
    } else {
      LAPACKE_dpttrs_work(LAPACK_COL_MAJOR, b.n, 1, b.diag.data(), b.off.data(), rhs.data(), b.n);
    }
    return;
  }
  if (banded_) {
    const Banded& b = *banded_;
    if (b.use_lu) {
      LAPACKE_dgbtrs_work(LAPACK_COL_MAJOR, 'N', b.n, b.kd, b.kd, 1, b.lu.data(), b.ldab_lu,
                          b.pivots.data(), rhs.data(), b.n);
    } else {
      LAPACKE_dpbtrs_work(LAPACK_COL_MAJOR, 'U', b.n, b.kd, 1, b.chol.data(), b.ldab_chol,
                          rhs.data(), b.n);
    }
    return;
  }
  const Sparse& s = *sparse_;
  s.scratch = rhs;
  rhs = s.ldlt.solve(s.scratch);
}

std::vector<std::pair<std::size_t, double>> scatter_upper(const SymmetricPattern& pattern,
                                                          const ModelMatrix& a) {
  std::vector<std::pair<std::size_t, double>> out;
  if (!a.is_sparse()) {
    const Eigen::MatrixXd& m = a.dense();
    for (Eigen::Index j = 0; j < m.cols(); ++j)
      for (Eigen::Index i = 0; i <= j; ++i)
        if (m(i, j) != 0.0) out.emplace_back(pattern.index_of(i, j), m(i, j));
    return out;
  }
  const ModelMatrix::Sparse& s = a.sparse();
  for (Eigen::Index j = 0; j < s.outerSize(); ++j) {
    for (ModelMatrix::Sparse::InnerIterator it(s, j); it; ++it) {
      if (it.row() <= it.col()) out.emplace_back(pattern.index_of(it.row(), it.col()), it.value());
    }
  }
  return out;
}

}  // namespace internal
}  // namespace fracvi
