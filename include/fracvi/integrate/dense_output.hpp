// Dense output between grid points, and events (docs/theory/dense_output.md).
//
// Between t_k and t_{k+1} = t_k + h the state is the cubic Hermite interpolant of the two grid
// states (x_k, v_k) and (x_{k+1}, v_{k+1}), s = (t − t_k)/h ∈ [0, 1]:
//   x(t) = h00(s) x_k + h h10(s) v_k + h01(s) x_{k+1} + h h11(s) v_{k+1},
//   h00 = (1 + 2s)(1 − s)², h10 = s(1 − s)², h01 = s²(3 − 2s), h11 = s²(s − 1),
// and v(t) = dx/dt, its derivative. With exact data it is O(h⁴) in x and O(h³) in v; with the
// scheme's data of order p in x and v it is O(h^min(p, 4)) in x and O(h^min(p, 3)) in v
// (measured: tests/integrate/dense_output_test.cpp). It needs nothing but the grid states, so
// it is the same for every scheme and for fractional damping (whose acceleration involves the
// memory sum). At s = 0 and s = 1 it returns the grid states exactly (the formula is not
// evaluated there).
#pragma once

#include <Eigen/Core>
#include <string>
#include <string_view>

#include "fracvi/core/event.hpp"
#include "fracvi/integrate/solution.hpp"

namespace fracvi {

/// The interpolant at s ∈ [0, 1] of the step [t_k, t_k + h] from (xa, va) at t_k and (xb, vb)
/// at t_k + h, into x and v (sized by the caller: allocation-free).
void hermite_interpolate(double s, double h, const Eigen::Ref<const Eigen::VectorXd>& xa,
                         const Eigen::Ref<const Eigen::VectorXd>& va,
                         const Eigen::Ref<const Eigen::VectorXd>& xb,
                         const Eigen::Ref<const Eigen::VectorXd>& vb, Eigen::Ref<Eigen::VectorXd> x,
                         Eigen::Ref<Eigen::VectorXd> v);

/// sol(t): the state at t from the stored rows of a Solution (the same interpolant as the run's
/// output_times). The two rows around t must be consecutive steps (save_every = 1, or t within
/// [t_{N−1}, t_N] of the last stride); throws ValidationError naming t and the rule otherwise, or
/// when t is outside [t_0, last stored time].
void interpolate(const Solution& solution, double t, Eigen::Ref<Eigen::VectorXd> x,
                 Eigen::Ref<Eigen::VectorXd> v);

/// An event from a formula in t, x1…xd, v1…vd (the expression engine, fracvi/expression): the
/// problem files' [[events]]. Throws ValidationError naming `field` for an unknown symbol or a
/// malformed formula. Evaluation does not allocate (after its first call on a thread).
Event formula_event(std::string name, std::string_view formula, Eigen::Index dimension,
                    EventDirection direction, bool terminal, const std::string& field);

/// Checks output_times (finite, ascending, in [t0, t_end]) and events (named, distinct names, a
/// function); ValidationError naming the field, the value and the rule.
void validate_output(const std::vector<double>& output_times, const std::vector<Event>& events,
                     double t0, double t_end);

}  // namespace fracvi
