// The shared setting of the tests that check a scheme against the restricted gradient of its
// action sum by automatic differentiation (tests/schemes/fvi_*_variational_test.cpp): d = 2, a
// non-diagonal SPD mass, a non-diagonal rank-1 PSD damping, coupled pendula with an explicitly
// time-dependent stiffness, a forcing folded into U_f(x, t) = U(x, t) − f(t)·x, the rounding
// tolerance, the problem for the integrator, and the parameters of the Taylor-split cases.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <cmath>
#include <limits>
#include <memory>
#include <ostream>
#include <string>

#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "test_names.hpp"

namespace fracvi::test::variational {

inline constexpr double kEps = std::numeric_limits<double>::epsilon();
inline constexpr Eigen::Index kDim = 2;
// Rounding factor of the tolerance kRoundoff · (N + 1) · ε · S (S: the largest term size). Both
// sides sum at most 2(N + 1) + 10 terms bounded by S (recursive summation: (terms)·ε·S each), and
// the composed weights ω^{(α)} * ω^{(α)} differ from ω^{(2α)} by their recurrences' rounding:
// |difference| ≤ ≈ 4(N + 1) ε S; kRoundoff = 8 leaves a factor 2.
inline constexpr double kRoundoff = 8.0;
// A negative control must miss its tolerance by this factor at least (the controls differ by a
// discretisation difference or an O(1) change, not by rounding; measured ≥ 1e8 × the tolerance).
inline constexpr double kControlFactor = 1e4;

using Dual = Eigen::AutoDiffScalar<Eigen::VectorXd>;
using DualMatrix = Eigen::Matrix<Dual, Eigen::Dynamic, Eigen::Dynamic>;

inline Eigen::Matrix2d mass() {
  return Eigen::Matrix2d{{1.5, 0.3}, {0.3, 1.0}};
}
// Positive *semi*definite, rank 1 (0.5·0.18 = 0.3²).
inline Eigen::Matrix2d damping() {
  return Eigen::Matrix2d{{0.5, -0.3}, {-0.3, 0.18}};
}

// Two coupled pendula with an explicitly time-dependent stiffness: nonlinear, non-separable.
struct CoupledPendula {
  template <class T>
  T operator()(const Eigen::Matrix<T, Eigen::Dynamic, 1>& x, T t) const {
    using std::cos;
    const T spring = x(1) - x(0);
    return T(9.81) * (T(1.0) - cos(x(0))) + T(4.0) * (T(1.0) - cos(x(1))) + spring * spring +
           T(0.1) * t * x(0) * x(0);
  }
};

inline void forcing(double t, Eigen::Ref<Eigen::VectorXd> f) {
  f(0) = 0.5 + 0.3 * std::sin(2.0 * t);
  f(1) = 0.2 + 0.1 * t;
}

inline std::shared_ptr<const Potential> pendula() {
  return make_autodiff_potential(CoupledPendula{}, kDim);
}

// Σ_ij u_i A_ij w_j, started from a term (not from a bare T(0), which has no derivative vector).
template <class T, class U, class W>
T bilinear(const Eigen::Matrix2d& A, const U& u, const W& w) {
  T s = u(0) * (A(0, 0) * w(0));
  for (Eigen::Index i = 0; i < kDim; ++i)
    for (Eigen::Index j = 0; j < kDim; ++j)
      if (i != 0 || j != 0) s += u(i) * (A(i, j) * w(j));
  return s;
}

// U_f(q, t) = U(q, t) − f(t)·q (the return type is T, not auto: AutoDiff sums are lazy
// expressions that would outlive q).
template <class T>
T potential_f(const Eigen::Matrix<T, Eigen::Dynamic, 1>& q, double t) {
  const T tt = T(0.0) * q(0) + T(t);  // a constant with a sized derivative vector
  Eigen::VectorXd f(kDim);
  forcing(t, f);
  return CoupledPendula{}(q, tt) - (q(0) * f(0) + q(1) * f(1));
}

inline double equation_tolerance(Eigen::Index steps, double scale) {
  return kRoundoff * static_cast<double>(steps + 1) * kEps * scale;
}

// max |a| over the interior columns 1 … N − 1 (where the restricted equations live).
inline double max_interior(const Eigen::MatrixXd& a, Eigen::Index n) {
  return a.middleCols(1, n - 1).cwiseAbs().maxCoeff();
}

// The problem the integrator runs: the fixture's M, R, U and f on [a, b] with N steps.
inline InitialValueProblem problem(double alpha, Convention convention, const Eigen::Vector2d& x0,
                                   const Eigen::Vector2d& v0, double a, double b,
                                   Eigen::Index steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd(mass());
  p.model.damping = Eigen::MatrixXd(damping());
  p.model.alpha = alpha;
  p.model.convention = convention;
  p.model.potential = pendula();
  p.model.forcing = forcing;
  p.x0 = x0;
  p.v0 = v0;
  p.t0 = a;
  p.t_end = b;
  p.steps = static_cast<std::size_t>(steps);
  return p;
}

/// Test-name suffix of the suites parameterised by α: "alpha_0_3".
inline std::string alpha_name(const ::testing::TestParamInfo<double>& param_info) {
  return "alpha_" + test::name_tag(param_info.param);
}

// A Taylor-split case: nonzero data, the convention decides which parts of P's force exist.
struct SplitCase {
  double alpha;
  Convention convention;
};

// How gtest prints a case (also in ctest's test list), instead of its bytes.
inline void PrintTo(const SplitCase& c, std::ostream* os) {
  *os << to_string(c.convention) << ", alpha " << c.alpha;
}

/// "caputo_alpha_0_3", "riemann_liouville_alpha_0_3".
inline std::string split_case_name(const ::testing::TestParamInfo<SplitCase>& param_info) {
  return test::name_tag(to_string(param_info.param.convention)) + "_alpha_" +
         test::name_tag(param_info.param.alpha);
}

inline const auto kSplitCases = ::testing::Values(
    SplitCase{0.3, Convention::kCaputo}, SplitCase{0.3, Convention::kRiemannLiouville},
    SplitCase{0.5, Convention::kCaputo}, SplitCase{0.75, Convention::kCaputo});

}  // namespace fracvi::test::variational
