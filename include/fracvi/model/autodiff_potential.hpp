// A Potential from a user functor, differentiated by Eigen's forward-mode AutoDiff.
//
// The user writes U once, templated on the scalar type (Ceres/Drake style):
//
//   struct Duffing {
//     template <class T>
//     T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>& x, T t) const {
//       using std::cos;  // let ADL pick Eigen's AutoDiff overloads
//       return T(0.5) * x(0) * x(0) + T(0.25) * x(0) * x(0) * x(0) * x(0) - T(0.1) * cos(t) * x(0);
//     }
//   };
//   auto U = fracvi::make_autodiff_potential(Duffing{}, /*dim=*/1);
//
// or, with a compile-time dimension (no heap allocation in any evaluation):
//
//   struct Duffing2 { template <class T> T operator()(const Eigen::Matrix<T, 2, 1>& x, T t) const;
//   }; auto U = fracvi::make_autodiff_potential<2>(Duffing2{});
//
// The gradient uses AutoDiffScalar<Matrix<double, Dim, 1>>; the Hessian nests it once more
// (AutoDiffScalar<Matrix<AutoDiffScalar<…>, Dim, 1>>), i.e. forward-over-forward. Derivatives are
// taken at one point (x, t); nothing is ever differentiated through the history sum (STYLE.md).
//
// Beginner bugs (as Ceres warns): write literals as T(0.5), not 0.5, when they meet a T in an
// operation Eigen cannot promote; call math functions unqualified after `using std::sin;` so that
// argument-dependent lookup finds the AutoDiff overloads. t is passed as a T with zero derivatives.
#pragma once

// Eigen/Dense must precede the unsupported AutoDiff module (it relies on Eigen::internal traits).
#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "fracvi/model/potential.hpp"

namespace fracvi {

struct AutodiffPotentialOptions {
  /// Set to false if U does not depend on t (saves two value() calls per step in the energy
  /// bookkeeping; see Potential::is_time_dependent()).
  bool time_dependent = true;
  /// Set to true only if U is quadratic in x (Hessian independent of x and t): the problem is then
  /// solved as a linear one, with the Hessian taken once.
  bool constant_hessian = false;
};

namespace internal {

// GCC 12 reports -Wmaybe-uninitialized for fixed-size AutoDiffScalar vectors passed to the user's
// functor (every entry is assigned before the call; a known false positive with Eigen's fixed-size
// storage). Silenced here so that user code built with -Werror is not broken by this header.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

template <class Functor, int Dim>
class AutodiffPotential final : public Potential {
 public:
  using Vector = Eigen::Matrix<double, Dim, 1>;
  using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, Dim, 1>>;
  using DualVector = Eigen::Matrix<Dual, Dim, 1>;
  using Dual2 = Eigen::AutoDiffScalar<Eigen::Matrix<Dual, Dim, 1>>;
  using Dual2Vector = Eigen::Matrix<Dual2, Dim, 1>;

  AutodiffPotential(Functor functor, Eigen::Index dim, AutodiffPotentialOptions options)
      : functor_(std::move(functor)), dim_(dim), options_(options) {}

  [[nodiscard]] Eigen::Index dimension() const override { return dim_; }

  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    const Vector xv = x;
    return functor_(xv, t);
  }

  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    const int n = static_cast<int>(dim_);
    DualVector xa(n);
    for (int i = 0; i < n; ++i) xa(i) = Dual(x(i), n, i);
    const Dual ta(t, Eigen::Matrix<double, Dim, 1>::Zero(n));
    const Dual r = functor_(xa, ta);
    // A result that does not depend on x carries an empty derivative vector.
    if (r.derivatives().size() == n) {
      g = r.derivatives();
    } else {
      g.setZero();
    }
  }

  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    const int n = static_cast<int>(dim_);
    const Eigen::Matrix<double, Dim, 1> zero = Eigen::Matrix<double, Dim, 1>::Zero(n);
    Dual2Vector xa(n);
    for (int i = 0; i < n; ++i) {
      xa(i).value() = Dual(x(i), n, i);
      xa(i).derivatives().resize(n);
      for (int j = 0; j < n; ++j) xa(i).derivatives()(j) = Dual(i == j ? 1.0 : 0.0, zero);
    }
    Dual2 ta;
    ta.value() = Dual(t, zero);
    ta.derivatives().resize(n);
    for (int j = 0; j < n; ++j) ta.derivatives()(j) = Dual(0.0, zero);
    const Dual2 r = functor_(xa, ta);
    H.setZero();
    if (r.derivatives().size() != n) return;
    for (int i = 0; i < n; ++i) {
      const auto& row = r.derivatives()(i).derivatives();
      if (row.size() == n) H.row(i) = row.transpose();
    }
  }

  [[nodiscard]] bool has_constant_hessian() const override { return options_.constant_hessian; }
  [[nodiscard]] bool is_time_dependent() const override { return options_.time_dependent; }

 private:
  Functor functor_;
  Eigen::Index dim_;
  AutodiffPotentialOptions options_;
};

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

}  // namespace internal

/// Wraps `functor` (see the file comment for its signature) as a Potential of dimension `dim`.
/// With Dim = Eigen::Dynamic (default) `dim` is required; with a fixed Dim it defaults to Dim and
/// must equal it. Throws std::invalid_argument on a bad dimension.
template <int Dim = Eigen::Dynamic, class Functor>
std::shared_ptr<const Potential> make_autodiff_potential(Functor functor, Eigen::Index dim = Dim,
                                                         AutodiffPotentialOptions options = {}) {
  if (dim < 1 || (Dim != Eigen::Dynamic && dim != Dim)) {
    throw std::invalid_argument(
        "make_autodiff_potential: dim = " + std::to_string(dim) + " must be >= 1" +
        (Dim != Eigen::Dynamic ? " and equal the compile-time dimension " + std::to_string(Dim)
                               : std::string()));
  }
  return std::make_shared<const internal::AutodiffPotential<Functor, Dim>>(std::move(functor), dim,
                                                                           options);
}

}  // namespace fracvi
