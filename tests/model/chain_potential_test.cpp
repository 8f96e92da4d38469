// The built-in FPUT chain against the same potential written as a formula and differentiated by
// the expression engine (an independent implementation: symbolic derivatives of a parsed string),
// for every boundary, with all four coefficients non-zero; plus its sparse Hessian interface and
// its input checks.
#include "fracvi/model/chain_potential.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "fracvi/model/expression_potential.hpp"

namespace fracvi {
namespace {

constexpr double kK = 1.3, kA = 0.7, kB = 2.1, kC = 0.4;

// V(r) = k/2 r² + a/3 r³ + b/4 r⁴ of the bond from x_i to x_j (names x1..xd; "0" is a wall);
// `linear`: k/2 r² only.
std::string bond(const std::string& xi, const std::string& xj, bool linear) {
  const std::string r = "((" + xj + ")-(" + xi + "))";
  const std::string quadratic = "+" + std::to_string(kK) + "/2*" + r + "^2";
  if (linear) return quadratic;
  return quadratic + "+" + std::to_string(kA) + "/3*" + r + "^3+" + std::to_string(kB) + "/4*" + r +
         "^4";
}

std::string chain_formula(Eigen::Index d, ChainBoundary boundary, bool linear = false) {
  auto x = [](Eigen::Index i) { return "x" + std::to_string(i + 1); };
  std::string u = "0";
  for (Eigen::Index i = 0; i < d; ++i) u += "+" + std::to_string(kC) + "/2*" + x(i) + "^2";
  for (Eigen::Index i = 0; i + 1 < d; ++i) u += bond(x(i), x(i + 1), linear);
  if (boundary == ChainBoundary::kFixed) u += bond("0", x(0), linear) + bond(x(d - 1), "0", linear);
  if (boundary == ChainBoundary::kPeriodic) u += bond(x(d - 1), x(0), linear);
  return u;
}

ChainOptions options(Eigen::Index d, ChainBoundary boundary) {
  ChainOptions o;
  o.dimension = d;
  o.stiffness = kK;
  o.cubic = kA;
  o.quartic = kB;
  o.onsite = kC;
  o.boundary = boundary;
  return o;
}

// The chain with options o against the formula, at five random states: value, gradient, dense
// and sparse Hessian, and the sparsity pattern.
void expect_chain_matches_formula(const ChainOptions& o, bool linear, unsigned seed) {
  const Eigen::Index d = o.dimension;
  const ChainPotential chain(o);
  const ExpressionPotential formula(d, chain_formula(d, o.boundary, linear));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd x(d);
    for (auto& xi : x) xi = u(rng);
    const double scale = std::abs(formula.value(x, 0.0)) + 1.0;
    EXPECT_NEAR(chain.value(x, 0.0), formula.value(x, 0.0), 1e-14 * scale);
    Eigen::VectorXd g1(d), g2(d);
    chain.gradient(x, 0.0, g1);
    formula.gradient(x, 0.0, g2);
    EXPECT_LE((g1 - g2).cwiseAbs().maxCoeff(), 1e-13);
    Eigen::MatrixXd h1(d, d), h2(d, d);
    chain.hessian(x, 0.0, h1);
    formula.hessian(x, 0.0, h2);
    EXPECT_LE((h1 - h2).cwiseAbs().maxCoeff(), 1e-13);
    // The sparse values reproduce the dense Hessian entry by entry, and the pattern covers every
    // entry the formula's symbolic Hessian can make non-zero.
    const auto pattern = chain.hessian_pattern();
    std::vector<double> values(pattern.size());
    chain.hessian_values(x, 0.0, values);
    Eigen::MatrixXd from_sparse = Eigen::MatrixXd::Zero(d, d);
    for (std::size_t e = 0; e < pattern.size(); ++e) {
      ASSERT_LE(pattern[e].row, pattern[e].col);
      from_sparse(pattern[e].row, pattern[e].col) += values[e];
      if (pattern[e].row != pattern[e].col)
        from_sparse(pattern[e].col, pattern[e].row) += values[e];
    }
    EXPECT_LE((from_sparse - h2).cwiseAbs().maxCoeff(), 1e-13);
  }
  for (const auto& e : formula.hessian_pattern()) {
    bool found = false;
    for (const auto& c : chain.hessian_pattern()) found |= (c.row == e.row && c.col == e.col);
    EXPECT_TRUE(found) << "(" << e.row << ", " << e.col << ")";
  }
}

class ChainVsFormula : public ::testing::TestWithParam<ChainBoundary> {};

TEST_P(ChainVsFormula, ValueGradientHessianAgree) {
  expect_chain_matches_formula(options(7, GetParam()), false, 5);
}

// A linear chain (cubic = quartic = 0) has its own interior kernels (chain_potential.cpp): d = 37
// puts a vector body and a remainder in them, for every boundary.
TEST_P(ChainVsFormula, LinearChainKernelsAgree) {
  ChainOptions o = options(37, GetParam());
  o.cubic = o.quartic = 0.0;
  expect_chain_matches_formula(o, true, 11);
}

INSTANTIATE_TEST_SUITE_P(Boundaries, ChainVsFormula,
                         ::testing::Values(ChainBoundary::kFixed, ChainBoundary::kFree,
                                           ChainBoundary::kPeriodic));

TEST(ChainPotential, LinearChainHasConstantHessian) {
  ChainOptions o = options(5, ChainBoundary::kFixed);
  o.cubic = o.quartic = 0.0;
  EXPECT_TRUE(ChainPotential(o).has_constant_hessian());
  EXPECT_FALSE(ChainPotential(options(5, ChainBoundary::kFixed)).has_constant_hessian());
  EXPECT_TRUE(ChainPotential(o).has_sparse_hessian());
  EXPECT_FALSE(ChainPotential(o).is_time_dependent());
}

TEST(ChainPotential, PatternSizeIsLinearInD) {
  for (const auto b : {ChainBoundary::kFixed, ChainBoundary::kFree, ChainBoundary::kPeriodic}) {
    const ChainPotential chain(options(1000, b));
    EXPECT_EQ(chain.hessian_pattern().size(), b == ChainBoundary::kPeriodic ? 2000u : 1999u);
  }
}

// Several threads split the loops over d; every gradient and Hessian entry is computed by the same
// operations whichever thread does it (bitwise equal), the value's sum only regroups.
TEST(ChainPotential, ThreadsGiveTheSameResult) {
  constexpr Eigen::Index kD = 3 * kChainParallelDofs;
  ChainOptions one = options(kD, ChainBoundary::kPeriodic), two = one;
  one.threads = 1;
  two.threads = 2;
  const ChainPotential serial(one), parallel(two);
  Eigen::VectorXd x(kD);
  for (Eigen::Index i = 0; i < kD; ++i) x[i] = 0.3 * std::sin(0.001 * static_cast<double>(i * i));
  Eigen::VectorXd g1(kD), g2(kD);
  serial.gradient(x, 0.0, g1);
  parallel.gradient(x, 0.0, g2);
  EXPECT_EQ(g1, g2);
  std::vector<double> h1(serial.hessian_pattern().size()), h2(h1.size());
  serial.hessian_values(x, 0.0, h1);
  parallel.hessian_values(x, 0.0, h2);
  EXPECT_EQ(h1, h2);
  EXPECT_NEAR(serial.value(x, 0.0), parallel.value(x, 0.0), 1e-12 * serial.value(x, 0.0));
}

// gradient_rows: any range of the gradient, computed alone, is gradient()'s bit for bit (every
// boundary, linear and nonlinear springs, ranges that start or end at the chain's ends); a
// potential without it throws.
TEST(ChainPotential, GradientRowsAreTheGradientsRows) {
  constexpr Eigen::Index kD = 203;
  for (const auto b : {ChainBoundary::kFixed, ChainBoundary::kFree, ChainBoundary::kPeriodic}) {
    for (const bool linear : {true, false}) {
      ChainOptions o = options(kD, b);
      if (linear) o.cubic = o.quartic = 0.0;
      const ChainPotential chain(o);
      ASSERT_TRUE(chain.has_gradient_rows());
      Eigen::VectorXd x(kD);
      for (Eigen::Index i = 0; i < kD; ++i)
        x[i] = 0.3 * std::sin(0.01 * static_cast<double>(i * i));
      Eigen::VectorXd whole(kD);
      chain.gradient(x, 0.0, whole);
      Eigen::VectorXd rows = Eigen::VectorXd::Constant(kD, std::nan(""));
      for (const auto& [lo, hi] :
           {std::pair<Eigen::Index, Eigen::Index>{100, 203}, {0, 1}, {1, 37}, {37, 100}}) {
        chain.gradient_rows(x, 0.0, rows.data(), lo, hi);
      }
      for (Eigen::Index i = 0; i < kD; ++i) {
        EXPECT_EQ(std::bit_cast<std::uint64_t>(rows[i]), std::bit_cast<std::uint64_t>(whole[i]))
            << "row " << i << ", boundary " << static_cast<int>(b) << ", linear " << linear;
      }
    }
  }
  const QuadraticPotential quadratic(Eigen::MatrixXd::Identity(3, 3));
  EXPECT_FALSE(quadratic.has_gradient_rows());
  double g[3];
  EXPECT_THROW(quadratic.gradient_rows(Eigen::VectorXd::Zero(3), 0.0, g, 0, 3), std::logic_error);
}

TEST(ChainPotential, RejectsBadOptions) {
  auto message = [](const ChainOptions& o) {
    try {
      ChainPotential p(o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message(options(2, ChainBoundary::kPeriodic)),
            "chain.dim = 2 must be >= 3 for boundary = periodic");
  EXPECT_EQ(message(options(1, ChainBoundary::kFree)),
            "chain.dim = 1 must be >= 2 for boundary = free");
  EXPECT_EQ(message(options(0, ChainBoundary::kFixed)),
            "chain.dim = 0 must be >= 1 for boundary = fixed");
  ChainOptions o = options(4, ChainBoundary::kFixed);
  o.quartic = std::numeric_limits<double>::infinity();
  EXPECT_EQ(message(o), "chain.quartic must be finite");
  o = options(4, ChainBoundary::kFixed);
  o.threads = -1;
  EXPECT_EQ(message(o), "chain.threads = -1 must be >= 0 (0 = all cores)");
  EXPECT_EQ(parse_chain_boundary("periodic"), ChainBoundary::kPeriodic);
  EXPECT_FALSE(parse_chain_boundary("circular").has_value());
}

}  // namespace
}  // namespace fracvi
