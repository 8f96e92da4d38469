// The fused element passes of the CQ midpoint step for diagonal M and R' (new_position_pass,
// new_momentum_pass, solve/vector_passes.hpp) against the passes they replace, applied one after
// another: the same numbers bit for bit, below kVectorPassesFrom (the inlined loops) and above it
// (the kernels and their x86-64-v3 clones), the sums they form for the Integrator (v·p, ‖x‖²_M)
// bit for bit those of its own passes, and the same finiteness verdicts. fvi-midpoint's two
// passes against its Eigen expressions: bit for bit below kVectorPassesFrom, to round-off above
// (FMAs in the clone).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>

#include "fracvi/model/model_matrix.hpp"
#include "fracvi/solve/vector_passes.hpp"

namespace fracvi::internal {
namespace {

Eigen::VectorXd random_vector(Eigen::Index n, std::mt19937& rng, double lo = -2.0,
                              double hi = 2.0) {
  std::uniform_real_distribution<double> u(lo, hi);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v[i] = u(rng);
  return v;
}

bool bitwise_equal(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  if (a.size() != b.size()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    if (std::signbit(a[i]) != std::signbit(b[i])) return false;
    if (!(a[i] == b[i]) && !(std::isnan(a[i]) && std::isnan(b[i]))) return false;
  }
  return true;
}

// The sizes of both dispatch branches.
constexpr Eigen::Index kSizes[] = {5, kVectorPassesFrom + 69, 1003};

TEST(StepPasses, NewPositionIsTheSeparatePassesBitForBit) {
  std::mt19937 rng(7);
  for (const Eigen::Index n : kSizes) {
    for (const bool unit : {true, false}) {
      for (const int shift : {0, 1, 2, 3}) {  // bit 0: x_0 shifted, bit 1: v_0 shifted
        const Eigen::VectorXd m = unit ? Eigen::VectorXd::Ones(n) : random_vector(n, rng, 0.5, 3.0);
        const Eigen::VectorXd dx = random_vector(n, rng, -1e-2, 1e-2);
        const Eigen::VectorXd p_plus = random_vector(n, rng), a = random_vector(n, rng);
        const Eigen::VectorXd x0 = random_vector(n, rng), v0 = random_vector(n, rng);
        const double s = 2.0 / 0.01, t = 0.37;
        const bool sx = (shift & 1) != 0, sv = (shift & 2) != 0;
        // The passes one after another, as the step runs them without fusion.
        Eigen::VectorXd p_minus_ref(n), next_ref(n), tilde_ref(n);
        ModelMatrix::diagonal(m).multiply(dx, p_minus_ref);
        scale_and_subtract_pass(s, p_plus.data(), p_minus_ref.data(), n);
        ASSERT_TRUE(add_and_check(a.data(), dx.data(), next_ref.data(), n));
        shifted_pass(next_ref.data(), sx ? x0.data() : nullptr, t, sv ? v0.data() : nullptr,
                     tilde_ref.data(), n);
        // Fused: a term left out is a zero vector.
        const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
        Eigen::VectorXd p_minus(n), next(n), tilde(n);
        ASSERT_TRUE(new_position_pass(m.data(), unit, dx.data(), s, p_plus.data(), a.data(),
                                      sx ? x0.data() : zero.data(), t, sv ? v0.data() : zero.data(),
                                      p_minus.data(), next.data(), tilde.data(), n));
        EXPECT_TRUE(bitwise_equal(p_minus, p_minus_ref)) << "n = " << n;
        EXPECT_TRUE(bitwise_equal(next, next_ref)) << "n = " << n;
        EXPECT_TRUE(bitwise_equal(tilde, tilde_ref)) << "n = " << n << ", shift " << shift;
        // With the health check's Σ (√m_i x_i)², as weighted_squares_pass sums it (n ≥
        // kVectorPassesFrom, where the step forms it): the other outputs alike.
        if (n >= kVectorPassesFrom) {
          const Eigen::VectorXd root_mass = m.cwiseSqrt();
          const double squares_ref = weighted_squares_pass(root_mass.data(), next_ref.data(), n);
          double squares = -1.0;
          Eigen::VectorXd tilde2(n);
          ASSERT_TRUE(new_position_pass(m.data(), unit, dx.data(), s, p_plus.data(), a.data(),
                                        sx ? x0.data() : zero.data(), t,
                                        sv ? v0.data() : zero.data(), p_minus.data(), next.data(),
                                        shift == 3 ? nullptr : tilde2.data(), n,
                                        unit ? nullptr : root_mass.data(), &squares));
          EXPECT_EQ(squares, squares_ref) << "n = " << n << ", unit " << unit;
          EXPECT_TRUE(bitwise_equal(p_minus, p_minus_ref));
          EXPECT_TRUE(bitwise_equal(next, next_ref));
          if (shift != 3) {
            EXPECT_TRUE(bitwise_equal(tilde2, tilde_ref));
          }
        }
        // Without x̃ (no history): the other outputs alike, x̃ untouched.
        Eigen::VectorXd untouched = Eigen::VectorXd::Constant(n, 5.0);
        ASSERT_TRUE(new_position_pass(m.data(), unit, dx.data(), s, p_plus.data(), a.data(),
                                      x0.data(), t, v0.data(), p_minus.data(), next.data(), nullptr,
                                      n));
        EXPECT_TRUE(bitwise_equal(p_minus, p_minus_ref));
        EXPECT_TRUE(bitwise_equal(next, next_ref));
        EXPECT_TRUE((untouched.array() == 5.0).all());
      }
    }
  }
}

TEST(StepPasses, NewMomentumIsTheSeparatePassesBitForBit) {
  std::mt19937 rng(11);
  for (const Eigen::Index n : kSizes) {
    for (const bool unit : {true, false}) {
      const Eigen::VectorXd m = unit ? Eigen::VectorXd::Ones(n) : random_vector(n, rng, 0.5, 3.0);
      const Eigen::VectorXd r = random_vector(n, rng, 0.1, 50.0);
      const Eigen::VectorXd sum = random_vector(n, rng), p_minus = random_vector(n, rng);
      const double c = 0.005;
      // R' s, p⁻ − c F, then the mass solver's quotients (a copy for M = I).
      Eigen::VectorXd force_ref(n), p_ref(n), v_ref(n), w_ref(n);
      ModelMatrix::diagonal(r).multiply(sum, force_ref);
      subtract_scaled_pass(p_minus.data(), c, force_ref.data(), p_ref.data(), n);
      if (unit) {
        v_ref = p_ref;
        w_ref = force_ref;
      } else {
        v_ref.array() = p_ref.array() / m.array();
        w_ref.array() = force_ref.array() / m.array();
      }
      // The energy account's sums as the step forms them without fusion (dot_pass from
      // kVectorPassesFrom on).
      const double fv_ref = dot_pass(force_ref.data(), v_ref.data(), n);
      const double fw_ref = dot_pass(force_ref.data(), w_ref.data(), n);
      const double vp_ref = dot_pass(v_ref.data(), p_ref.data(), n);  // the kinetic energy's
      for (const bool with_w : {true, false}) {
        for (const bool with_dots : {true, false}) {
          if (with_dots && n < kVectorPassesFrom) continue;  // the step keeps Eigen's sums there
          Eigen::VectorXd force(n), p(n), v(n), w = Eigen::VectorXd::Constant(n, 5.0);
          const MomentumPass pass = new_momentum_pass(
              r.data(), sum.data(), p_minus.data(), c, m.data(), unit, force.data(), p.data(),
              v.data(), with_w ? w.data() : nullptr, with_dots, n);
          ASSERT_TRUE(pass.finite);
          EXPECT_TRUE(bitwise_equal(force, force_ref)) << "n = " << n << ", unit " << unit;
          EXPECT_TRUE(bitwise_equal(p, p_ref));
          EXPECT_TRUE(bitwise_equal(v, v_ref));
          // w: the quotients when asked for and M ≠ I; for M = I the step takes F itself.
          if (with_w && !unit) {
            EXPECT_TRUE(bitwise_equal(w, w_ref));
          } else {
            EXPECT_TRUE((w.array() == 5.0).all());
          }
          if (with_dots) {  // with or without w stored
            EXPECT_EQ(pass.fv, fv_ref) << "n = " << n << ", unit " << unit;
            EXPECT_EQ(pass.fw, fw_ref) << "n = " << n << ", unit " << unit;
            EXPECT_EQ(pass.vp, vp_ref) << "n = " << n << ", unit " << unit;
          }
        }
      }
    }
  }
}

TEST(StepPasses, NonFiniteValuesAreReported) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::mt19937 rng(3);
  for (const Eigen::Index n : kSizes) {
    const Eigen::VectorXd m = random_vector(n, rng, 0.5, 3.0), x = random_vector(n, rng);
    for (const bool unit : {true, false}) {
      Eigen::VectorXd dx = random_vector(n, rng), out1(n), out2(n), out3(n);
      EXPECT_TRUE(new_position_pass(m.data(), unit, dx.data(), 2.0, x.data(), x.data(), x.data(),
                                    0.1, x.data(), out1.data(), out2.data(), out3.data(), n));
      dx[n - 1] = kInf;  // the last element: the simd loop's remainder above kVectorPassesFrom
      EXPECT_FALSE(new_position_pass(m.data(), unit, dx.data(), 2.0, x.data(), x.data(), x.data(),
                                     0.1, x.data(), out1.data(), out2.data(), out3.data(), n));
    }
    Eigen::VectorXd out1(n), out2(n), out3(n), out4(n);
    Eigen::VectorXd sum = random_vector(n, rng);
    for (const bool unit : {true, false}) {
      sum[0] = 1.0;
      EXPECT_TRUE(new_momentum_pass(m.data(), sum.data(), x.data(), 0.5, m.data(), unit,
                                    out1.data(), out2.data(), out3.data(), out4.data(), false, n)
                      .finite);
      sum[0] = kNaN;
      EXPECT_FALSE(new_momentum_pass(m.data(), sum.data(), x.data(), 0.5, m.data(), unit,
                                     out1.data(), out2.data(), out3.data(), out4.data(), false, n)
                       .finite);
    }
  }
}

// Equal to round-off: below kVectorPassesFrom bit for bit (the inlined loops, compiled like the
// Eigen expressions); above it the x86-64-v3 clone fuses a·b + c into FMAs on CPUs with AVX2, so
// each element may differ by a few roundings of its largest term.
void expect_round_off_equal(const Eigen::VectorXd& a, const Eigen::VectorXd& ref, Eigen::Index n,
                            const char* what) {
  if (n < kVectorPassesFrom) {
    EXPECT_TRUE(bitwise_equal(a, ref)) << what << ", n = " << n;
    return;
  }
  const double scale = 1.0 + ref.cwiseAbs().maxCoeff();
  EXPECT_LE((a - ref).cwiseAbs().maxCoeff(), 64 * std::numeric_limits<double>::epsilon() * scale)
      << what << ", n = " << n;
}

// fvi-midpoint's two passes around Newton's solve (trapezoid_known_pass, trapezoid_step_pass)
// against the Eigen expressions the step runs for other matrices (schemes/fvi_midpoint.cpp), in
// their order: with and without the Taylor split, M = I and M ≠ I.
TEST(StepPasses, TrapezoidPassesAreTheEigenExpressions) {
  std::mt19937 rng(19);
  for (const Eigen::Index n : kSizes) {
    for (const bool unit : {true, false}) {
      for (const bool split : {true, false}) {
        const double h = 0.01, w = std::pow(2.0, 0.5), t = 3.5 * h;
        const Eigen::VectorXd m = unit ? Eigen::VectorXd::Ones(n) : random_vector(n, rng, 0.5, 3.0);
        const Eigen::VectorXd r = random_vector(n, rng, 0.1, 50.0);
        const Eigen::VectorXd xk = random_vector(n, rng), x0 = random_vector(n, rng);
        const Eigen::VectorXd v0 = random_vector(n, rng), sum = random_vector(n, rng);
        const Eigen::VectorXd g_poly = random_vector(n, rng), g_poly_prev = random_vector(n, rng);
        const Eigen::VectorXd q = random_vector(n, rng), g_tilde = random_vector(n, rng);
        const Eigen::VectorXd dx = random_vector(n, rng, -1e-2, 1e-2);
        const ModelMatrix force_matrix = ModelMatrix::diagonal(r);
        // Before the solve.
        Eigen::VectorXd mid_ref = xk, g_hat(n), rhs_ref(n);
        if (split) {
          mid_ref -= x0;
          mid_ref -= t * v0;
        }
        Eigen::VectorXd tmp = w * mid_ref + sum;
        force_matrix.multiply(tmp, g_hat);
        g_hat += 0.5 * (g_poly + g_poly_prev);
        rhs_ref = h * q;
        rhs_ref -= (h * h) * g_hat;
        Eigen::VectorXd mid(n), rhs(n);
        trapezoid_known_pass(r.data(), xk.data(), split ? x0.data() : nullptr, t, v0.data(), w,
                             sum.data(), g_poly.data(), g_poly_prev.data(), q.data(), h, mid.data(),
                             rhs.data(), n);
        expect_round_off_equal(mid, mid_ref, n, "x̃̄ before");
        expect_round_off_equal(rhs, rhs_ref, n, "rhs");
        // After the solve (from the same x̃̄, so that the second pass is compared alone).
        Eigen::VectorXd next_ref = xk + dx, p_next(n), q_ref = q, g_tilde_ref = g_tilde;
        Eigen::VectorXd g_total_ref(n), p_ref(n), v_ref(n);
        ModelMatrix::diagonal(m).multiply(dx, p_next);
        q_ref = p_next * (2.0 / h) - q_ref;
        Eigen::VectorXd mid_after_ref = mid_ref;
        mid_after_ref += 0.5 * dx;
        tmp = w * mid_after_ref + sum;
        force_matrix.multiply(tmp, g_total_ref);
        g_tilde_ref = 2.0 * g_total_ref - g_tilde_ref;
        q_ref += h * g_total_ref;
        q_ref += (0.5 * h) * (g_poly + g_poly_prev);
        g_total_ref = g_tilde_ref + g_poly;
        p_ref = q_ref;
        p_ref -= (0.5 * h) * g_total_ref;
        v_ref.array() = p_ref.array() / m.array();
        const double work_ref = g_total_ref.dot(dx);
        for (const bool with_work : {true, false}) {
          Eigen::VectorXd next(n), q_out = q, mid_out = mid_ref, g_tilde_out = g_tilde;
          Eigen::VectorXd g_total(n), p(n), v(n);
          const TrapezoidPass pass = trapezoid_step_pass(
              m.data(), unit, r.data(), xk.data(), dx.data(), 2.0 / h, w, sum.data(), g_poly.data(),
              g_poly_prev.data(), h, next.data(), q_out.data(), mid_out.data(), g_tilde_out.data(),
              g_total.data(), p.data(), v.data(), with_work, n);
          EXPECT_TRUE(pass.finite_position && pass.finite_velocity);
          expect_round_off_equal(next, next_ref, n, "x_{k+1}");
          expect_round_off_equal(mid_out, mid_after_ref, n, "x̃̄ after");
          expect_round_off_equal(q_out, q_ref, n, "q");
          expect_round_off_equal(g_tilde_out, g_tilde_ref, n, "G̃");
          expect_round_off_equal(g_total, g_total_ref, n, "G");
          expect_round_off_equal(p, p_ref, n, "p");
          expect_round_off_equal(v, v_ref, n, "v");
          if (with_work) {
            // Eigen's dot and the simd reduction sum in different orders.
            EXPECT_NEAR(pass.work, work_ref,
                        1e-13 * g_total_ref.cwiseAbs().dot(dx.cwiseAbs()) + 1e-300);
          } else {
            EXPECT_EQ(pass.work, 0.0);
          }
        }
        // A non-finite increment and a non-finite velocity are reported (the last element: the
        // simd loop's remainder above kVectorPassesFrom).
        Eigen::VectorXd bad = dx, next(n), q_out = q, mid_out = mid_ref, g_tilde_out = g_tilde;
        Eigen::VectorXd g_total(n), p(n), v(n);
        bad[n - 1] = std::numeric_limits<double>::infinity();
        TrapezoidPass pass = trapezoid_step_pass(
            m.data(), unit, r.data(), xk.data(), bad.data(), 2.0 / h, w, sum.data(), g_poly.data(),
            g_poly_prev.data(), h, next.data(), q_out.data(), mid_out.data(), g_tilde_out.data(),
            g_total.data(), p.data(), v.data(), false, n);
        EXPECT_FALSE(pass.finite_position);
        Eigen::VectorXd bad_sum = sum;
        bad_sum[n - 1] = std::numeric_limits<double>::quiet_NaN();
        q_out = q;
        mid_out = mid_ref;
        g_tilde_out = g_tilde;
        pass = trapezoid_step_pass(m.data(), unit, r.data(), xk.data(), dx.data(), 2.0 / h, w,
                                   bad_sum.data(), g_poly.data(), g_poly_prev.data(), h,
                                   next.data(), q_out.data(), mid_out.data(), g_tilde_out.data(),
                                   g_total.data(), p.data(), v.data(), false, n);
        EXPECT_TRUE(pass.finite_position);
        EXPECT_FALSE(pass.finite_velocity);
      }
    }
  }
}

}  // namespace
}  // namespace fracvi::internal
