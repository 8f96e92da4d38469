// Lagrangians L(t, x, y, ẋ, ẏ, D^α_−x, D^α_+y) on the fractional phase space (`TotalCoord`,
// `ActFunc`), with first and second derivatives at one point.
//
// Everything that needs L — the continuous residual of `FracEL`, the action sum `DiscActSum`, the
// residual of `DiscFracEL` and the Newton solver of the variational boundary value problem — talks
// to this interface only, so the built-in mechanical model (`PartLagrangian`) is one Lagrangian
// among others, not a separate code path. Three implementations:
//
//  * make_autodiff_lagrangian(functor, d): a user functor templated on the scalar type, reading a
//    PhasePoint<T> by name (Ceres/Drake style):
//
//        struct MyLagrangian {
//          template <class T>
//          T operator()(const fracvi::PhasePoint<T>& p) const {
//            using std::cos;  // unqualified maths calls, so that ADL finds Eigen's AutoDiff ones
//            return T(0.5) * (T(1) + p.x(0) * p.x(0)) * p.xdot.squaredNorm()
//                   + T(0.5) * p.ydot.squaredNorm() - cos(p.x(0)) - cos(p.y(0))
//                   - T(0.3) * p.dx_alpha.dot(p.dy_alpha);
//          }
//        };
//        auto L = fracvi::make_autodiff_lagrangian(MyLagrangian{}, /*d=*/1);
//
//    The gradient comes from Eigen's forward AutoDiff (AutoDiffScalar<VectorXd>), the Hessian from
//    the same type nested once (forward over forward), both at one point (STYLE.md). Write
//    literals as T(0.5) where Eigen cannot promote a double.
//  * ExpressionLagrangian(d, text): a formula from a problem file in the variables
//    x1..xd, y1..yd, xdot1..xdotd, ydot1..ydotd, dx1..dxd (D^α_−x), dy1..dyd (D^α_+y) and t, with
//    exact symbolic derivatives compiled into one tape (fracvi/expression/expression.hpp).
//  * MechanicalLagrangian(model, a, b): `PartLagrangian` with the quadratic kinetic energies of
//    Corollary 4.4, generalised to SPD M, symmetric R, time-dependent U and forcing:
//
//        L = ½ẋᵀMẋ − U_f(x, t) + ½ẏᵀMẏ − U_f(y, a + b − t) − (D^α_−x)ᵀ R D^α_+y,
//        U_f(x, t) = U(x, t) − f(t)·x.
//
//    y is x in reversed time (Remark 4.5), so the y-part carries the mirrored time a + b − t; on a
//    grid its midpoint values are then exactly the ones the integrator's mirror run uses.
//
// Thread safety: all const members may be called concurrently.
#pragma once

// Eigen/Dense must precede the unsupported AutoDiff module.
#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/expression/expression.hpp"
#include "fracvi/lagrangian/phase_point.hpp"
#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {

/// L and its derivatives at one point (t, z), z = [x; y; ẋ; ẏ; D^α_−x; D^α_+y] ∈ R^{6d}.
struct LagrangianDerivatives {
  double value = 0.0;
  Eigen::VectorXd gradient;  ///< ∇_z L (6d): block m is the paper's D_{m+1}L
  Eigen::MatrixXd hessian;   ///< ∇²_z L (6d × 6d), symmetric
  /// ∂_t ∇_z L restricted to the blocks ẋ, ẏ, D^α_−x, D^α_+y (4d entries, in that order): the
  /// explicit time dependence of the four partial derivatives whose time derivative along a curve
  /// `FracEL` needs (d/dt ∂L/∂ẋ, and the functions under D^α_±). ∂_t of ∂L/∂x, ∂L/∂y is never
  /// needed, and a potential does not provide it.
  Eigen::VectorXd time_gradient;

  /// Sizes the members for dimension d (no-op if already sized).
  void resize(Eigen::Index d);
};

/// Which entries of ∇²_z L (6d × 6d) can be nonzero.
using HessianPattern = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;

class Lagrangian {
 public:
  virtual ~Lagrangian() = default;

  /// d: each of the six blocks of z has d components.
  [[nodiscard]] virtual Eigen::Index dimension() const = 0;

  /// L(t, z).
  [[nodiscard]] virtual double value(double t,
                                     const Eigen::Ref<const Eigen::VectorXd>& z) const = 0;
  /// Returns L(t, z) and writes ∇_z L into g (size 6d on entry).
  virtual double gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                          Eigen::Ref<Eigen::VectorXd> g) const = 0;
  /// Value, gradient, Hessian and time_gradient (out is resized if needed).
  virtual void derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                           LagrangianDerivatives& out) const = 0;

  /// The structurally nonzero Hessian entries, if known (expressions and the mechanical model);
  /// nullopt for functors (treated as dense). Used to decide whether the x-equation can be
  /// stepped forward alone (forward_step_class()).
  [[nodiscard]] virtual std::optional<HessianPattern> hessian_pattern() const {
    return std::nullopt;
  }

  /// A one-line description for messages and summaries.
  [[nodiscard]] virtual std::string description() const = 0;

  /// Convenience: L at a named phase point.
  [[nodiscard]] double value(const PhasePoint<double>& p) const { return value(p.t, p.to_flat()); }
};

namespace internal {

/// Forward AutoDiff over the 6d phase coordinates (and t), and the same nested once.
using LagrangianDual = Eigen::AutoDiffScalar<Eigen::VectorXd>;
using LagrangianDual2 = Eigen::AutoDiffScalar<Eigen::Matrix<LagrangianDual, Eigen::Dynamic, 1>>;

template <class Functor>
class AutodiffLagrangian final : public Lagrangian {
 public:
  AutodiffLagrangian(Functor functor, Eigen::Index dim, std::string description)
      : functor_(std::move(functor)), dim_(dim), description_(std::move(description)) {}

  [[nodiscard]] Eigen::Index dimension() const override { return dim_; }
  [[nodiscard]] std::string description() const override { return description_; }

  [[nodiscard]] double value(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const override {
    const Eigen::VectorXd zc = z;
    return functor_(PhasePoint<double>::from_flat(t, zc));
  }

  double gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                  Eigen::Ref<Eigen::VectorXd> g) const override {
    using Dual = LagrangianDual;
    const Eigen::Index n = kPhaseBlockCount * dim_;
    Eigen::Matrix<Dual, Eigen::Dynamic, 1> zd(n);
    for (Eigen::Index i = 0; i < n; ++i)
      zd(i) = Dual(z(i), static_cast<int>(n), static_cast<int>(i));
    const Dual td(t, Eigen::VectorXd::Zero(n));
    const Dual r = functor_(PhasePoint<Dual>::from_flat(td, zd));
    // A result that does not depend on z carries an empty derivative vector.
    if (r.derivatives().size() == n) {
      g = r.derivatives();
    } else {
      g.setZero();
    }
    return r.value();
  }

  void derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                   LagrangianDerivatives& out) const override {
    using Dual = LagrangianDual;
    using Dual2 = LagrangianDual2;
    const Eigen::Index d = dim_;
    const Eigen::Index nz = kPhaseBlockCount * d;
    const Eigen::Index n = nz + 1;  // t is the last variable, for the mixed derivatives ∂_t ∇L
    out.resize(d);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
    Eigen::Matrix<Dual2, Eigen::Dynamic, 1> zd(nz);
    Dual2 td;
    auto seed = [&](Dual2& v, double value, Eigen::Index i) {
      v.value() = Dual(value, static_cast<int>(n), static_cast<int>(i));
      v.derivatives().resize(n);
      for (Eigen::Index j = 0; j < n; ++j) v.derivatives()(j) = Dual(i == j ? 1.0 : 0.0, zero);
    };
    for (Eigen::Index i = 0; i < nz; ++i) seed(zd(i), z(i), i);
    seed(td, t, nz);
    const Dual2 r = functor_(PhasePoint<Dual2>::from_flat(td, zd));
    out.value = r.value().value();
    out.gradient.setZero();
    out.hessian.setZero();
    out.time_gradient.setZero();
    if (r.derivatives().size() != n) return;  // L is constant
    for (Eigen::Index i = 0; i < nz; ++i) {
      const Dual& gi = r.derivatives()(i);
      out.gradient(i) = gi.value();
      if (gi.derivatives().size() != n) continue;  // ∂L/∂z_i is constant
      out.hessian.row(i) = gi.derivatives().head(nz).transpose();
      if (i >= 2 * d) out.time_gradient(i - 2 * d) = gi.derivatives()(nz);
    }
    // Forward-over-forward gives H(i, j) and H(j, i) from different sweeps; they agree to
    // round-off. Symmetrise so that Newton matrices built from H are exactly symmetric.
    out.hessian = (0.5 * (out.hessian + out.hessian.transpose())).eval();
  }

 private:
  Functor functor_;
  Eigen::Index dim_;
  std::string description_;
};

}  // namespace internal

/// Wraps a functor `T operator()(const PhasePoint<T>&) const` (see the file comment) as a
/// Lagrangian of dimension d ≥ 1 (std::invalid_argument otherwise).
template <class Functor>
std::shared_ptr<const Lagrangian> make_autodiff_lagrangian(
    Functor functor, Eigen::Index d, std::string description = "autodiff Lagrangian") {
  if (d < 1) {
    throw std::invalid_argument("make_autodiff_lagrangian: d = " + std::to_string(d) +
                                " must be >= 1");
  }
  return std::make_shared<const internal::AutodiffLagrangian<Functor>>(std::move(functor), d,
                                                                       std::move(description));
}

/// A Lagrangian given as a formula (problem files: `[model] lagrangian = "…"`).
class ExpressionLagrangian final : public Lagrangian {
 public:
  /// Parses `text` in the variables of variable_names(d). A name that does not exist for this d
  /// (x3 when d = 2, xd1, …) or malformed text throws ExpressionError with the column.
  ExpressionLagrangian(Eigen::Index d, const std::string& text);

  /// x1..xd, y1..yd, xdot1..xdotd, ydot1..ydotd, dx1..dxd, dy1..dyd, t — the flat phase order
  /// followed by t (dx = D^α_−x, dy = D^α_+y).
  static std::vector<std::string> variable_names(Eigen::Index d);

  [[nodiscard]] Eigen::Index dimension() const override { return dim_; }
  [[nodiscard]] double value(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const override;
  double gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                  Eigen::Ref<Eigen::VectorXd> g) const override;
  void derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                   LagrangianDerivatives& out) const override;
  [[nodiscard]] std::optional<HessianPattern> hessian_pattern() const override { return pattern_; }
  [[nodiscard]] std::string description() const override;

  [[nodiscard]] const Expression& expression() const { return derivatives_.expression(); }

 private:
  struct Scratch;
  Scratch& scratch(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const;

  Eigen::Index dim_;
  CompiledDerivatives derivatives_;
  HessianPattern pattern_;
  std::uint64_t id_;
};

/// The mechanical Lagrangian of the file comment for the model on [a, b]. The Lagrangian uses the
/// paper's Riemann–Liouville operators; model.convention is not consulted here (the solvers that
/// take a MechanicalModel check it). Throws ValidationError for an invalid model or a ≥ b.
class MechanicalLagrangian final : public Lagrangian {
 public:
  MechanicalLagrangian(const MechanicalModel& model, double a, double b);

  [[nodiscard]] Eigen::Index dimension() const override { return mass_.rows(); }
  [[nodiscard]] double value(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const override;
  double gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                  Eigen::Ref<Eigen::VectorXd> g) const override;
  void derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                   LagrangianDerivatives& out) const override;
  [[nodiscard]] std::optional<HessianPattern> hessian_pattern() const override;
  [[nodiscard]] std::string description() const override;

 private:
  Eigen::MatrixXd mass_, damping_;
  std::shared_ptr<const Potential> potential_;
  Forcing forcing_;
  double a_plus_b_;
};

/// Which Lagrangians `fracvi run` (an initial value problem) can step forward, one x_{k+1} at a
/// time, from the x-equation of `DiscFracEL` alone (docs/theory/discrete_euler_lagrange.md §6):
///  (1) the x-equation must not involve y: ∂L/∂x, ∂L/∂ẋ and ∂L/∂(D^α_+y) may not depend on
///      y, ẏ or D^α_+y;
///  (2) ∂L/∂ẋ may not depend on x: L(k) pairs the midpoint S x_k with the backward difference
///      Δ_−x_k, so the term Δ_+ ∂L/∂ẋ(k) would bring in S x_{k+1} ∋ x_{k+2}.
/// Decided from hessian_pattern(); an unknown pattern (functors) is not accepted.
struct ForwardStepClass {
  bool forward_steppable = false;
  std::string reason;  ///< why not (names the offending pair of variables), empty if steppable
};
ForwardStepClass forward_step_class(const Lagrangian& lagrangian);

}  // namespace fracvi
