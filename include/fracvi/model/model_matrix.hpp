// ModelMatrix: the mass matrix M and damping matrix R of the mechanical model, stored dense or
// sparse.
//
// Small systems give M and R as dense matrices; large ones (chains, lattices with d = 10^5) cannot
// (a dense 10^5 × 10^5 matrix is 80 GB) and give them sparse, usually diagonal. The integrator
// reads the storage to decide how to factor its Newton matrix M + (h²/4)∇²U (dense LU, banded
// Cholesky, or sparse LDLᵀ; solve/symmetric_factor.hpp): a sparse M together with a potential
// that declares a sparse Hessian keeps every step O(d).
//
// Both forms convert implicitly, so existing code that assigns an Eigen matrix keeps working:
//   model.mass = Eigen::MatrixXd::Identity(2, 2);                 // dense
//   model.mass = fracvi::ModelMatrix::identity(100000, 1.0);        // sparse, diagonal
//   model.damping = sparse_matrix;                                  // any Eigen sparse matrix
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCore>

namespace fracvi {

class ModelMatrix {
 public:
  using Sparse = Eigen::SparseMatrix<double>;  // column-major, compressed

  /// 0 × 0 (dense).
  ModelMatrix() = default;
  /// Dense storage (implicit: `model.mass = Eigen::MatrixXd::Identity(d, d)`).
  template <class Derived>
  ModelMatrix(const Eigen::MatrixBase<Derived>& dense)  // NOLINT(google-explicit-constructor)
      : dense_(dense) {}
  /// Sparse storage (implicit: `model.mass = sparse`). Explicit zeros are kept as structure.
  template <class Derived>
  ModelMatrix(
      const Eigen::SparseMatrixBase<Derived>& sparse)  // NOLINT(google-explicit-constructor)
      : sparse_(sparse), is_sparse_(true) {
    sparse_.makeCompressed();
    cache_diagonal();
  }

  /// A diagonal expression (`v.asDiagonal()`), stored sparse.
  template <class Derived>
  ModelMatrix(const Eigen::DiagonalBase<Derived>& diagonal)  // NOLINT(google-explicit-constructor)
      : ModelMatrix(ModelMatrix::diagonal(diagonal.diagonal())) {}

  /// value · I, stored sparse (diagonal).
  static ModelMatrix identity(Eigen::Index dimension, double value = 1.0);
  /// diag(values), stored sparse.
  static ModelMatrix diagonal(const Eigen::VectorXd& values);
  /// d × d zero, stored sparse with no entries.
  static ModelMatrix zero(Eigen::Index dimension);

  [[nodiscard]] Eigen::Index rows() const { return is_sparse_ ? sparse_.rows() : dense_.rows(); }
  [[nodiscard]] Eigen::Index cols() const { return is_sparse_ ? sparse_.cols() : dense_.cols(); }
  [[nodiscard]] bool is_sparse() const { return is_sparse_; }
  /// Stored entries (d² for dense storage).
  [[nodiscard]] Eigen::Index stored_entries() const {
    return is_sparse_ ? sparse_.nonZeros() : dense_.size();
  }

  /// The dense storage. Throws std::logic_error when the matrix is stored sparse (use to_dense()).
  [[nodiscard]] const Eigen::MatrixXd& dense() const;
  /// Mutable dense storage (same rule).
  [[nodiscard]] Eigen::MatrixXd& dense();
  /// The sparse storage. Throws std::logic_error when the matrix is stored dense.
  [[nodiscard]] const Sparse& sparse() const;
  /// A dense copy (of a 10^5 × 10^5 matrix that is 80 GB: small d only).
  [[nodiscard]] Eigen::MatrixXd to_dense() const;

  /// Entry (i, j) (0 outside the stored pattern).
  [[nodiscard]] double coeff(Eigen::Index i, Eigen::Index j) const;
  [[nodiscard]] double operator()(Eigen::Index i, Eigen::Index j) const { return coeff(i, j); }
  /// True when every entry is exactly 0.
  [[nodiscard]] bool is_zero() const;
  [[nodiscard]] bool all_finite() const;
  /// True when only diagonal entries are non-zero.
  [[nodiscard]] bool is_diagonal() const;
  /// The diagonal of a matrix stored sparse with only diagonal entries (what multiply() uses for
  /// it), else null.
  [[nodiscard]] const Eigen::VectorXd* stored_diagonal() const {
    return diagonal_.size() > 0 ? &diagonal_ : nullptr;
  }
  /// max |a_ij| (0 for an empty matrix).
  [[nodiscard]] double max_abs() const;
  /// max |a_ij − a_ji|.
  [[nodiscard]] double max_asymmetry() const;
  /// s·A in the same storage.
  [[nodiscard]] ModelMatrix scaled(double s) const;
  /// ½(A + Aᵀ) in the same storage.
  [[nodiscard]] ModelMatrix symmetric_part() const;

  /// y = A x (y has size rows() on entry; no allocation). Inline: small dense systems call it
  /// several times per step.
  void multiply(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const {
    if (x.size() == 1 && y.size() == 1) {
      // d = 1: one product, inline (the general paths made GCC call the whole function out of
      // line, ≈ 55 instructions a call). A sparse 1 × 1 matrix is diagonal: diagonal_ holds it.
      y[0] = (is_sparse_ ? diagonal_[0] : dense_(0, 0)) * x[0];
    } else {
      multiply_general(x, y);
    }
  }

 private:
  // A sparse matrix with only diagonal entries multiplies as a vector product (vectorised, no
  // zeroing pass): diagonal_ holds them, empty otherwise.
  void cache_diagonal();
  // multiply() for d > 1.
  void multiply_general(const Eigen::Ref<const Eigen::VectorXd>& x,
                        Eigen::Ref<Eigen::VectorXd> y) const;

  Eigen::MatrixXd dense_;
  Sparse sparse_;
  Eigen::VectorXd diagonal_;
  bool is_sparse_ = false;
};

/// a + s·b: sparse when both are sparse, dense otherwise. Sizes must agree (std::invalid_argument).
ModelMatrix linear_combination(const ModelMatrix& a, double s, const ModelMatrix& b);

}  // namespace fracvi
