// fvi-lobatto2/3/4 are variational: along their trajectories the restricted gradient of the
// Lobatto action sum vanishes (docs/theory/fvi_lobatto.md §2–§5).
//
// Ground truth, written here independently of the stepper: the action sum on stage values
//   A_d = Σ_n [ L_d(X_n; t_n) + L_d^y(Y_n; t_n)
//               − h Σ_i b_i (D^α_h X̃)_{n,i}ᵀ R (D^α_{h,+} Ỹ)_{n,i} − Σ_k (L_{n,k}·X_{n,k} +
//               L^y_{n,k}·Y_{n,k}) ],
//   L_d(X_n; t_n) = h Σ_a b_a [½ V_aᵀ M V_a − U_f(X_{n,a}, t_{n,a})],  V = X Dᵀ/h,
//   (D^α_h X̃)_n = h^{−α} Σ_{j≤n} W^{(α)}_j X̃_{n−j},  (D^α_{h,+} Ỹ)_n = h^{−α} Σ_{j} J W^{(α)}_j J
//   Ỹ_{n+j},
// with the block weights of order α (not 2α: the two half-order operators compose into the
// scheme's 2α memory only through the Lobatto IIIC symmetry W_jᵀB = J B W_j J, fvi_lobatto.md
// (1.1)), X̃ = X − P, Ỹ = Y − P(a + b − t), L_d^y with U_f at the mirrored times, and the loads
// L_{n,k} = h R ∫_0^1 ℓ_k(σ) D^{2α}P(t_n + σh) dσ by Boost's tanh–sinh quadrature (the stepper
// uses closed forms, Gauss–Legendre and a binomial series). A_d is differentiated by Eigen's
// AutoDiff with respect to every distinct stage value of X and of Y (shared nodes counted once),
// and the restricted gradient is ∂A_d/∂X + ∂A_d/∂Y (δX = δY = η) at the internal stages and
// interior nodes.
//
// The test drives the registered stepper by hand (Stepper::stage_values() gives each interval's
// stages), sets Y_m = J X_{N−1−m} (the mirror) and checks that the restricted gradient vanishes to
// round-off, and that its derivative at the two end nodes is p_N − p_0 (the start p_0 = M v_0 and
// the stepper's output momentum p_N). Negative control: W_j in place of J W_j J in the y-memory
// (the routing the symmetry lemma replaces) misses by O(1).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include <boost/math/quadrature/tanh_sinh.hpp>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "../support/variational_fixture.hpp"
#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/schemes/registry.hpp"
#include "fracvi/schemes/stepper.hpp"

namespace fracvi {
namespace {

using namespace test::variational;  // NOLINT(google-build-using-namespace): the shared fixture

struct Case {
  int stages;
  double alpha;
  Convention convention;
  Eigen::Vector2d x0, v0;
};

// How gtest prints a case (also in ctest's test list), instead of its bytes.
void PrintTo(const Case& c, std::ostream* os) {
  *os << "s = " << c.stages << ", " << to_string(c.convention) << ", alpha " << c.alpha;
}

// The Lobatto nodes: D_{ak} = ℓ_k'(c_a) and the monomial coefficients of ℓ_k (independently of
// the stepper: from the Vandermonde matrix).
struct Nodes {
  Eigen::VectorXd b, c;
  Eigen::MatrixXd D, basis;
  explicit Nodes(int s) {
    const ButcherTableau& t = lobatto_iiic(s);
    b = t.b;
    c = t.c;
    Eigen::MatrixXd vandermonde(s, s), dvander(s, s);
    for (int a = 0; a < s; ++a) {
      for (int m = 0; m < s; ++m) {
        vandermonde(a, m) = std::pow(c(a), m);
        dvander(a, m) = m == 0 ? 0.0 : m * std::pow(c(a), m - 1);
      }
    }
    basis = vandermonde.transpose().inverse();  // ℓ_k(σ) = Σ_m basis(k, m) σ^m
    D = dvander * basis.transpose();            // D_{ak} = Σ_m m c_a^{m−1} basis(k, m)
  }
  [[nodiscard]] double lagrange(int k, double sigma) const {
    double value = 0.0;
    for (Eigen::Index m = basis.cols() - 1; m >= 0; --m) value = value * sigma + basis(k, m);
    return value;
  }
};

// D^{2α}P per unit R at τ = t − a (the Taylor polynomial's damping force): v_0 τ^{1−2α}/Γ(2−2α)
// (not for Caputo 2α > 1) and, Riemann–Liouville 0 < 2α < 1, x_0 τ^{−2α}/Γ(1−2α).
Eigen::Vector2d polynomial_force(const Case& c, double tau) {
  const double beta = 2.0 * c.alpha;
  Eigen::Vector2d out = Eigen::Vector2d::Zero();
  if (!(c.convention == Convention::kCaputo && beta > 1.0)) {
    out += std::pow(tau, 1.0 - beta) / boost::math::tgamma(2.0 - beta) * c.v0;
  }
  if (c.convention == Convention::kRiemannLiouville && beta < 1.0) {
    out += std::pow(tau, -beta) / boost::math::tgamma(1.0 - beta) * c.x0;
  }
  return out;
}

class LobattoVariational : public ::testing::TestWithParam<Case> {};

TEST_P(LobattoVariational, RestrictedGradientVanishesOnTheTrajectory) {
  const Case& cs = GetParam();
  const int s = cs.stages;
  const Eigen::Index d = kDim, n = 8;
  const double t_a = 0.5, t_b = 2.5, h = (t_b - t_a) / static_cast<double>(n);
  const double beta = 2.0 * cs.alpha;
  const InitialValueProblem problem =
      test::variational::problem(cs.alpha, cs.convention, cs.x0, cs.v0, t_a, t_b, n);
  const SchemeInfo& info = *find_scheme("fvi-lobatto" + std::to_string(s));
  IntegratorOptions options;
  options.newton.relative_tolerance = 1e-16;  // floored at round-off by the stepper
  options.history = HistoryKind::kDirect;
  const std::unique_ptr<Stepper> stepper = info.make_stepper(problem, options);
  std::vector<Eigen::MatrixXd> X;  // X[m]: d × s
  for (Eigen::Index m = 0; m < n; ++m) {
    ASSERT_EQ(stepper->step(), Status::kSuccess) << stepper->failure_message();
    X.push_back(*stepper->stage_values());
  }
  const Eigen::MatrixXd J = Eigen::MatrixXd::Identity(s, s).rowwise().reverse();
  std::vector<Eigen::MatrixXd> Y(static_cast<std::size_t>(n));
  for (Eigen::Index m = 0; m < n; ++m)
    Y[static_cast<std::size_t>(m)] = X[static_cast<std::size_t>(n - 1 - m)] * J;

  const Nodes nodes(s);
  const RungeKuttaCq half{s, cs.alpha, 0};
  const BlockWeights w = half.weights(static_cast<std::size_t>(n));
  const Eigen::Matrix2d M = mass(), R = damping();
  const bool split = beta > 0.0;
  auto P = [&](double t) -> Eigen::Vector2d {
    return split ? Eigen::Vector2d(cs.x0 + (t - t_a) * cs.v0) : Eigen::Vector2d::Zero();
  };
  // Loads L_{m,k} (x) by tanh–sinh; the y-loads are the mirrored ones.
  boost::math::quadrature::tanh_sinh<double> quadrature;
  std::vector<Eigen::MatrixXd> loads(static_cast<std::size_t>(n), Eigen::MatrixXd::Zero(d, s));
  for (Eigen::Index m = 0; m < n; ++m) {
    for (int k = 0; k < s; ++k) {
      for (Eigen::Index i = 0; i < d; ++i) {
        const double value = quadrature.integrate(
            [&](double sigma) {
              return nodes.lagrange(k, sigma) *
                     polynomial_force(cs, (static_cast<double>(m) + sigma) * h)(i);
            },
            0.0, 1.0);
        loads[static_cast<std::size_t>(m)](i, k) = value;
      }
      loads[static_cast<std::size_t>(m)].col(k) = h * R * loads[static_cast<std::size_t>(m)].col(k);
    }
  }

  // Distinct values: X_{m,a} for (m, a) with a < s − 1, plus the last node; likewise Y.
  const Eigen::Index per_curve = (n * (s - 1) + 1) * d;
  auto slot = [&](Eigen::Index m, int a) { return (m * (s - 1) + a) * d; };  // a = s − 1 → next
  Eigen::VectorXd values(2 * per_curve);
  for (Eigen::Index m = 0; m < n; ++m)
    for (int a = 0; a < s; ++a) {
      values.segment(slot(m, a), d) = X[static_cast<std::size_t>(m)].col(a);
      values.segment(per_curve + slot(m, a), d) = Y[static_cast<std::size_t>(m)].col(a);
    }

  // A_d, with `mirror_memory` true for the J W_j J routing (the scheme) and false for the control.
  auto action = [&](bool mirror_memory, Eigen::VectorXd& gx, Eigen::VectorXd& gy) {
    const Eigen::Index total = values.size();
    std::vector<DualMatrix> Xd, Yd, Xt, Yt;
    for (Eigen::Index m = 0; m < n; ++m) {
      DualMatrix xm(d, s), ym(d, s);
      for (int a = 0; a < s; ++a)
        for (Eigen::Index i = 0; i < d; ++i) {
          const Eigen::Index ix = slot(m, a) + i, iy = per_curve + slot(m, a) + i;
          xm(i, a) = Dual(values(ix), static_cast<int>(total), static_cast<int>(ix));
          ym(i, a) = Dual(values(iy), static_cast<int>(total), static_cast<int>(iy));
        }
      Xd.push_back(xm);
      Yd.push_back(ym);
      DualMatrix xt = xm, yt = ym;
      for (int a = 0; a < s; ++a) {
        const double t = problem.t0 + (static_cast<double>(m) + nodes.c(a)) * h;
        const Eigen::Vector2d px = P(t), py = P(problem.t0 + problem.t_end - t);
        for (Eigen::Index i = 0; i < d; ++i) {
          xt(i, a) -= px(i);
          yt(i, a) -= py(i);
        }
      }
      Xt.push_back(xt);
      Yt.push_back(yt);
    }
    Dual A = Dual(0.0, Eigen::VectorXd::Zero(total));
    const double hp = std::pow(h, -cs.alpha);
    for (Eigen::Index m = 0; m < n; ++m) {
      const auto mm = static_cast<std::size_t>(m);
      // Lagrangians.
      const DualMatrix vx = Xd[mm] * nodes.D.transpose().cast<Dual>() / h;
      const DualMatrix vy = Yd[mm] * nodes.D.transpose().cast<Dual>() / h;
      for (int q = 0; q < s; ++q) {
        const double t = t_a + (static_cast<double>(m) + nodes.c(q)) * h;
        const Eigen::Matrix<Dual, Eigen::Dynamic, 1> xq = Xd[mm].col(q), yq = Yd[mm].col(q);
        const Eigen::Matrix<Dual, Eigen::Dynamic, 1> vxq = vx.col(q), vyq = vy.col(q);
        A += h * nodes.b(q) *
             (0.5 * bilinear<Dual>(M, vxq, vxq) + 0.5 * bilinear<Dual>(M, vyq, vyq) -
              potential_f<Dual>(xq, t) - potential_f<Dual>(yq, t_a + t_b - t));
      }
      // The memory pairing: −h Σ_i b_i (D^α X̃)_{m,i}ᵀ R (D^α_+ Ỹ)_{m,i}.
      // Started from the j = 0 term (a bare zero Dual has no derivative vector).
      auto routed = [&](std::size_t j) -> Eigen::MatrixXd {
        return mirror_memory ? Eigen::MatrixXd(J * w[j] * J) : Eigen::MatrixXd(w[j]);
      };
      DualMatrix dx = Xt[mm] * Eigen::MatrixXd(w[0].transpose()).cast<Dual>();
      DualMatrix dy = Yt[mm] * Eigen::MatrixXd(routed(0).transpose()).cast<Dual>();
      for (std::size_t j = 1; j <= mm; ++j)
        dx += Xt[mm - j] * Eigen::MatrixXd(w[j].transpose()).cast<Dual>();
      for (std::size_t j = 1; mm + j < static_cast<std::size_t>(n); ++j)
        dy += Yt[mm + j] * Eigen::MatrixXd(routed(j).transpose()).cast<Dual>();
      for (int q = 0; q < s; ++q) {
        const Eigen::Matrix<Dual, Eigen::Dynamic, 1> dxq = dx.col(q) * hp, dyq = dy.col(q) * hp;
        A -= h * nodes.b(q) * bilinear<Dual>(R, dxq, dyq);
      }
      // Loads of P's damping force (x: interval m; y: the mirrored interval, stages reversed).
      for (int k = 0; k < s; ++k)
        for (Eigen::Index i = 0; i < d; ++i) {
          A -= loads[mm](i, k) * Xd[mm](i, k);
          A -= loads[static_cast<std::size_t>(n - 1 - m)](i, s - 1 - k) * Yd[mm](i, k);
        }
    }
    gx = A.derivatives().head(per_curve);
    gy = A.derivatives().tail(per_curve);
  };

  Eigen::VectorXd gx, gy;
  action(true, gx, gy);
  // Restricted gradient at the internal stages and the interior nodes (exclude the end nodes).
  const Eigen::VectorXd restricted = (gx + gy).segment(d, per_curve - 2 * d);
  const double scale = std::max(gx.cwiseAbs().maxCoeff(), gy.cwiseAbs().maxCoeff());
  const double residual = restricted.cwiseAbs().maxCoeff();
  const double tolerance = equation_tolerance(n * s, scale) * s;
  // The ends, where no restricted variation lives: ∂A_d/∂η at node 0 is F^x_{0,1} + F^y_{0,1} =
  // −p_0 − q_0 (the start equation p_0 + F^x_{0,1} = 0 and the y-momentum q_0 = −F^y_{0,1}), and
  // the mirror's q_0 = −p_N; at node N it is F^x_{N−1,s} + F^y_{N−1,s} = p_N + q_N, q_N = −p_0.
  // Both equal p_N − p_0, with p_0 = M v_0 (the start) and p_N the stepper's output momentum.
  const Eigen::VectorXd jump = stepper->momentum() - M * cs.v0;
  const Eigen::VectorXd ends = (gx + gy).head(d) - jump;
  const Eigen::VectorXd ends_last = (gx + gy).tail(d) - jump;
  const Eigen::Vector2d start(std::max(ends.cwiseAbs().maxCoeff(), ends_last.cwiseAbs().maxCoeff()),
                              0.0);
  Eigen::VectorXd cx, cy;
  action(false, cx, cy);
  const double control = (cx + cy).segment(d, per_curve - 2 * d).cwiseAbs().maxCoeff();
  std::printf(
      "  s = %d, alpha = %.2f, %s: max|restricted gradient| = %.3e (tolerance %.3e, terms "
      "%.2e), ends %.3e; control (W_j for J W_j J) %.3e\n",
      s, cs.alpha, std::string(to_string(cs.convention)).c_str(), residual, tolerance, scale,
      start.cwiseAbs().maxCoeff(), control);
  EXPECT_LE(residual, tolerance);
  EXPECT_LE(start.cwiseAbs().maxCoeff(), tolerance);
  if (beta != 0.0) {
    EXPECT_GE(control, kControlFactor * tolerance);
  }
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  const Case& c = info.param;
  return "s" + std::to_string(c.stages) + "_" + test::name_tag(to_string(c.convention)) +
         "_alpha_" + test::name_tag(c.alpha);
}

const Eigen::Vector2d kX0{0.4, -0.3}, kV0{0.2, 0.5}, kZero{0.0, 0.0};

INSTANTIATE_TEST_SUITE_P(Lobatto, LobattoVariational,
                         ::testing::Values(Case{2, 0.3, Convention::kCaputo, kX0, kV0},
                                           Case{3, 0.3, Convention::kCaputo, kX0, kV0},
                                           Case{4, 0.3, Convention::kCaputo, kX0, kV0},
                                           Case{3, 0.5, Convention::kCaputo, kX0, kV0},
                                           Case{2, 0.75, Convention::kCaputo, kX0, kV0},
                                           Case{3, 0.75, Convention::kCaputo, kX0, kV0},
                                           Case{4, 0.75, Convention::kCaputo, kX0, kV0},
                                           Case{3, 0.3, Convention::kRiemannLiouville, kX0, kV0},
                                           Case{4, 0.3, Convention::kRiemannLiouville, kX0, kZero},
                                           Case{3, 0.75, Convention::kRiemannLiouville, kZero,
                                                kV0}),
                         case_name);

}  // namespace
}  // namespace fracvi
