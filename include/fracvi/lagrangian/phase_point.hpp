// A point of the fractional phase space 𝔗R^d (the paper's Def. 3.4, coordinates `TotalCoord`):
//
//     (x, y, ẋ, ẏ, D^α_− x, D^α_+ y) ∈ R^d × R^d × R^d × R^d × R^d × R^d,
//
// plus the time t for Lagrangians that depend on it explicitly. A user Lagrangian reads these by
// name (p.x, p.dy_alpha, …), never by position, so that a wrong block cannot be picked silently
// (STYLE.md: the Ceres beginner bug).
//
// Internally the six blocks are stored flat, z = [x; y; ẋ; ẏ; D^α_−x; D^α_+y] ∈ R^{6d}, in the
// paper's order: block m (0-based) is the argument whose partial derivative the paper writes
// D_{m+1}L in `DiscFracEL` (D_1 = ∂/∂x, …, D_5 = ∂/∂D^α_−x, D_6 = ∂/∂D^α_+y).
#pragma once

#include <Eigen/Core>
#include <cassert>

namespace fracvi {

/// The blocks of a flat phase vector z ∈ R^{6d}; block m holds components m·d … m·d + d − 1.
enum class PhaseBlock : int {
  kX = 0,        ///< x          (the paper's D_1 L is ∂L/∂x)
  kY = 1,        ///< y          (D_2)
  kXdot = 2,     ///< ẋ          (D_3)
  kYdot = 3,     ///< ẏ          (D_4)
  kDxAlpha = 4,  ///< D^α_− x    (D_5)
  kDyAlpha = 5,  ///< D^α_+ y    (D_6)
};
inline constexpr int kPhaseBlockCount = 6;

/// First index of block b in a flat vector for dimension d.
constexpr Eigen::Index block_offset(PhaseBlock b, Eigen::Index d) {
  return static_cast<Eigen::Index>(b) * d;
}

/// A phase point with named fields, templated on the scalar so that one user functor serves
/// plain evaluation and (nested) automatic differentiation.
template <class T>
struct PhasePoint {
  using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1>;

  T t{};            ///< time (only for Lagrangians with explicit time dependence)
  Vector x;         ///< x
  Vector y;         ///< y, the mirror variable (y(t) = x(a + b − t) on solutions, Remark 4.5)
  Vector xdot;      ///< ẋ
  Vector ydot;      ///< ẏ
  Vector dx_alpha;  ///< D^α_− x (retarded Riemann–Liouville derivative, `RL`)
  Vector dy_alpha;  ///< D^α_+ y (advanced Riemann–Liouville derivative)

  [[nodiscard]] Eigen::Index dimension() const { return x.size(); }

  /// The named fields of the flat vector z = [x; y; ẋ; ẏ; D^α_−x; D^α_+y] (size 6d).
  template <class Derived>
  static PhasePoint from_flat(const T& time, const Eigen::MatrixBase<Derived>& z) {
    assert(z.size() % kPhaseBlockCount == 0);
    const Eigen::Index d = z.size() / kPhaseBlockCount;
    PhasePoint p;
    p.t = time;
    p.x = z.segment(0 * d, d);
    p.y = z.segment(1 * d, d);
    p.xdot = z.segment(2 * d, d);
    p.ydot = z.segment(3 * d, d);
    p.dx_alpha = z.segment(4 * d, d);
    p.dy_alpha = z.segment(5 * d, d);
    return p;
  }

  /// The flat vector z (size 6d).
  [[nodiscard]] Vector to_flat() const {
    const Eigen::Index d = dimension();
    Vector z(kPhaseBlockCount * d);
    z << x, y, xdot, ydot, dx_alpha, dy_alpha;
    return z;
  }
};

}  // namespace fracvi
