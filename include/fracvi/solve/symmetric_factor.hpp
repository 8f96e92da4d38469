// Factorisation of the symmetric matrices of a step, J = A + s·H with a fixed sparsity pattern
// (internal; public for benchmarks and tests).
//
// A is the mass matrix M (or M + (h/2)R for the implicit midpoint rule), H the potential's Hessian
// ∇²U and s = h²/4. The pattern of J is known at set-up (A's stored entries ∪ the potential's
// hessian_pattern()), its values change every Newton iteration. Three backends, chosen
// automatically from the structure (choose_factorization) or forced:
//
//   kDense   d × d LU with partial pivoting (Eigen). O(d³) per factorisation; small or dense
//            problems, and every problem whose M or Hessian is only available dense.
//   kBanded  LAPACK band Cholesky dpbtrf/dpbtrs on the bandwidth b of the pattern, falling back to
//            band LU with partial pivoting (BandLu: dgbtrf) when J is not positive definite (a
//            locally concave U with a large step); b = 1 uses a tridiagonal LDLᵀ
//            (tridiagonal_ldlt: dpttrf's numbers, chunked; fallback dgttrf/dgttrs), b = 0 divides
//            by the diagonal. O(d·b²) per factorisation, O(d·b) per solve: O(d) for chains.
//            Allocation-free: LAPACK works in preallocated storage.
//   kSparse  Eigen::SimplicialLDLT with an approximate-minimum-degree ordering, the ordering,
//            the permuted matrix and the symbolic analysis done once. For patterns whose
//            bandwidth is large but fill is small (2-D lattices, periodic chains).
//            Allocation-free up to d = 16384; beyond, Eigen's numeric factorisation takes its
//            work vectors from the heap (one allocation per factorisation up to d = 32768, three
//            beyond).
//
// Values are passed in pattern order: the caller computes once where each entry of A and of the
// Hessian lands (index_of) and scatters into values() every iteration — O(nnz), no search.
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"

namespace fracvi {

/// How the Newton matrix of a step is factored (IntegratorOptions::linear_solver).
enum class LinearSolver {
  kAuto,    ///< from the structure (choose_factorization)
  kDense,   ///< dense LU
  kBanded,  ///< LAPACK band Cholesky (band LU fallback)
  kSparse,  ///< sparse LDLᵀ (Eigen, AMD ordering)
};
std::optional<LinearSolver> parse_linear_solver(std::string_view name);
std::string_view to_string(LinearSolver solver);

/// Bandwidth up to which kAuto prefers the band factorisation to the sparse one: O(d·b²) with
/// LAPACK's blocked kernels beats a general sparse LDLᵀ for narrow bands, and it stays
/// allocation-free.
inline constexpr Eigen::Index kMaxAutoBandwidth = 64;

namespace internal {

/// The structure of J: d and its upper-triangle entries (row ≤ col), each once, sorted by column
/// then row; the diagonal is always included.
class SymmetricPattern {
 public:
  explicit SymmetricPattern(Eigen::Index dimension);
  /// Adds every stored entry of A (both triangles folded onto the upper one).
  void add(const ModelMatrix& a);
  /// Adds the potential's Hessian pattern (dense d × d if it has no sparse Hessian).
  void add(const Potential& potential);
  /// Freezes the pattern (sort, deduplicate). Must be called before index_of() or use.
  void finalize();

  [[nodiscard]] Eigen::Index dimension() const { return d_; }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }
  [[nodiscard]] const std::vector<Potential::HessianEntry>& entries() const { return entries_; }
  /// Position of (row, col) (either order) in entries(). Throws std::out_of_range if absent.
  [[nodiscard]] std::size_t index_of(Eigen::Index row, Eigen::Index col) const;
  /// max |row − col| over the entries.
  [[nodiscard]] Eigen::Index bandwidth() const;

 private:
  Eigen::Index d_;
  std::vector<Potential::HessianEntry> entries_;
  std::vector<std::size_t> column_start_;  // after finalize(): entries of column j
  bool final_ = false;
};

/// kDense, kBanded or kSparse for a pattern: dense when more than a quarter of the matrix is
/// structurally non-zero (or d ≤ 4), banded when the bandwidth is ≤ kMaxAutoBandwidth, sparse
/// otherwise.
LinearSolver choose_factorization(const SymmetricPattern& pattern);

/// J = Σ values[e] (E_{row,col} + E_{col,row}) [diagonal once], factored banded or sparse. (The
/// dense backend works on a d × d matrix directly: MidpointNewton and the integrator keep Eigen's
/// dense LU/Cholesky for it.)
class SymmetricFactor {
 public:
  /// solver must be kBanded or kSparse (std::invalid_argument otherwise). Allocates all storage.
  SymmetricFactor(std::shared_ptr<const SymmetricPattern> pattern, LinearSolver solver);
  ~SymmetricFactor();
  SymmetricFactor(SymmetricFactor&&) noexcept;
  SymmetricFactor& operator=(SymmetricFactor&&) noexcept;

  [[nodiscard]] LinearSolver backend() const { return backend_; }
  [[nodiscard]] const SymmetricPattern& pattern() const { return *pattern_; }

  /// The values of J in pattern order; fill them, then factor().
  [[nodiscard]] std::span<double> values() { return {values_.data(), values_.size()}; }
  /// Factors J from values(). Returns false if the matrix is numerically singular (or, for the
  /// sparse backend, the LDLᵀ breaks down). No allocation for kBanded, nor for kSparse with
  /// d ≤ 16384.
  bool factor() noexcept;
  /// rhs ← J⁻¹ rhs. No allocation.
  void solve_in_place(Eigen::Ref<Eigen::VectorXd> rhs) const noexcept;

 private:
  struct Banded;
  struct Sparse;
  bool factor_tridiagonal() noexcept;  // bandwidth 0 or 1
  static void prepare_chunked_solve(Banded& b) noexcept;
  static void tridiagonal_chunked_solve(const Banded& b, double* x) noexcept;
  std::shared_ptr<const SymmetricPattern> pattern_;
  LinearSolver backend_;
  std::vector<double> values_;
  std::unique_ptr<Banded> banded_;
  std::unique_ptr<Sparse> sparse_;
};

/// The LDLᵀ factorisation of the symmetric tridiagonal matrix with diagonal a[0, n) and
/// off-diagonal e[0, n − 1): the pivots d[0, n) and L's off-diagonal l[i] = e[i]/d[i] for i < n − 1
/// (l[n − 1] untouched), the numbers of LAPACK's dpttrf bit for bit, computed in chunks side by
/// side (symmetric_factor.cpp). Returns false if some d_i ≤ 0 (dpttrf's info > 0: J is not positive
/// definite, and d, l are not its factor). a and e must not overlap d and l. No allocation.
bool tridiagonal_ldlt(std::size_t n, const double* a, const double* e, double* d,
                      double* l) noexcept;

/// Where the stored entries of a ModelMatrix land in a pattern that contains them (its upper
/// triangle; lower entries map onto their mirror and are skipped, so a symmetric A is counted
/// once). Returns (pattern index, value) pairs in a fixed order.
std::vector<std::pair<std::size_t, double>> scatter_upper(const SymmetricPattern& pattern,
                                                          const ModelMatrix& a);

}  // namespace internal
}  // namespace fracvi
