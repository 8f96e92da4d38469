// The expression engine: grammar, values, exact derivatives, sparsity, errors, no allocation.
#include "fracvi/expression/expression.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <new>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

// Counts heap allocations in this test executable (the evaluation loop must not allocate).
namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// noinline: once inlined, GCC pairs the free() with `new` at the call site and warns
// (-Wmismatched-new-delete), although replacing both is exactly what the standard allows.
[[gnu::noinline]] void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void operator delete(void* p) noexcept {
  std::free(p);
}
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
// Closed forms and the engine evaluate the same quantity by different sequences of fewer than
// ~30 correctly rounded operations, at points chosen away from cancellation, so they agree to
// a few tens of ulps relative to max(1, |value|).
constexpr double kClosedFormTol = 64 * kEps;

void expect_close(double got, double ref, const std::string& what) {
  EXPECT_NEAR(got, ref, kClosedFormTol * std::max(1.0, std::abs(ref))) << what;
}

double eval(std::string_view text, std::vector<std::string> vars, std::vector<double> values) {
  return Expression::parse(text, std::move(vars))(values);
}

// ---------------------------------------------------------------------------------------------
// Values

TEST(ExpressionValues, EveryFunctionAndOperatorMatchesStdMath) {
  const std::vector<std::string> v{"x", "y"};
  using F = std::function<double(double)>;
  const std::vector<std::pair<std::string, F>> unary = {
      {"sin(x)", [](double x) { return std::sin(x); }},
      {"cos(x)", [](double x) { return std::cos(x); }},
      {"tan(x)", [](double x) { return std::tan(x); }},
      {"exp(x)", [](double x) { return std::exp(x); }},
      {"log(x)", [](double x) { return std::log(x); }},
      {"sqrt(x)", [](double x) { return std::sqrt(x); }},
      {"abs(x)", [](double x) { return std::abs(x); }},
      {"sinh(x)", [](double x) { return std::sinh(x); }},
      {"cosh(x)", [](double x) { return std::cosh(x); }},
      {"tanh(x)", [](double x) { return std::tanh(x); }},
      {"atan(x)", [](double x) { return std::atan(x); }},
      {"-x", [](double x) { return -x; }},
      {"+x", [](double x) { return x; }},
      {"sign(x)", [](double x) { return x > 0 ? 1.0 : -1.0; }},
  };
  for (double x : {0.3, 1.7, 2.9, -0.4, -2.2}) {
    for (const auto& [text, f] : unary) {
      if (x < 0 && (text == "log(x)" || text == "sqrt(x)")) continue;
      // One operation, the same libm call: bitwise equal.
      EXPECT_EQ(eval(text, v, {x, 0.0}), f(x)) << text << " at " << x;
    }
  }
  for (double x : {0.3, 1.7, -2.2}) {
    for (double y : {0.6, -1.3, 2.5}) {
      EXPECT_EQ(eval("x + y", v, {x, y}), x + y);
      EXPECT_EQ(eval("x - y", v, {x, y}), x - y);
      EXPECT_EQ(eval("x * y", v, {x, y}), x * y);
      EXPECT_EQ(eval("x / y", v, {x, y}), x / y);
      if (x > 0) {
        EXPECT_EQ(eval("x ^ y", v, {x, y}), std::pow(x, y));
        EXPECT_EQ(eval("pow(x, y)", v, {x, y}), std::pow(x, y));
      }
    }
    // Integer powers are repeated multiplication: within a few ulps of std::pow.
    for (int n : {-5, -2, -1, 2, 3, 4, 7, 16, 40}) {
      const double ref = std::pow(x, n);
      EXPECT_NEAR(eval("x^" + std::to_string(n), v, {x, 0.0}), ref, 8 * kEps * std::abs(ref))
          << "n=" << n;
    }
    EXPECT_EQ(eval("x^0.5", v, {x * x, 0.0}), std::sqrt(x * x));
  }
  EXPECT_EQ(eval("pi", {}, {}), std::numbers::pi);
  EXPECT_EQ(eval("sign(0)", {}, {}), 0.0);
}

TEST(ExpressionValues, PrecedenceAndAssociativity) {
  const std::vector<std::string> v{"x", "y", "z"};
  const std::vector<double> p{2.0, 3.0, 0.5};
  const std::vector<std::pair<std::string, double>> cases = {
      {"-x^2", -4.0},  // ^ binds tighter than unary minus
      {"-2^2", -4.0},
      {"(-2)^2", 4.0},
      {"2^3^2", 512.0},  // right-associative
      {"(2^3)^2", 64.0},
      {"x^-1", 0.5},
      {"2^-x^2", 1.0 / 16.0},  // 2^(-(x^2))
      {"x^y^z", std::pow(2.0, std::pow(3.0, 0.5))},
      {"1 - 2 - 3", -4.0},  // left-associative
      {"8 / 4 / 2", 1.0},
      {"2 + 3 * 4", 14.0},
      {"(2 + 3) * 4", 20.0},
      {"2 * 3 ^ 2", 18.0},
      {"x * -y", -6.0},
      {"--x", 2.0},
      {"-+-x", 2.0},
      {"x - -y", 5.0},
      {"12 / x * y", 18.0},
      {"x / y / z", 2.0 / 3.0 / 0.5},
      {"-x * y", -6.0},
      {"sin(x)^2 + cos(x)^2", std::pow(std::sin(2.0), 2) + std::pow(std::cos(2.0), 2)},
      {" \t1\n+\r2 *\fx ", 5.0},  // whitespace anywhere
      {"pow(x, y) - x^y", 0.0},
  };
  for (const auto& [text, ref] : cases) {
    EXPECT_NEAR(eval(text, v, p), ref, 4 * kEps * std::max(1.0, std::abs(ref))) << text;
  }
}

TEST(ExpressionValues, EveryNumberNotation) {
  const std::vector<std::pair<std::string, double>> cases = {
      {"123", 123.0},   {"1.5", 1.5},       {".5", 0.5},      {"5.", 5.0},      {"1e-3", 1e-3},
      {"1E+3", 1000.0}, {"2.5e2", 250.0},   {"0", 0.0},       {"0.0", 0.0},     {"00.5", 0.5},
      {"0x1F", 31.0},   {"0X1f", 31.0},     {"0x1.8p1", 3.0}, {"0x1p-2", 0.25}, {"0x.8p0", 0.5},
      {"1e0", 1.0},     {"0x10 + 1", 17.0}, {"0x1e-3", 27.0},  // hex digit 'e', then minus: C reads
                                                               // 0x1e - 3
  };
  for (const auto& [text, ref] : cases) EXPECT_EQ(eval(text, {}, {}), ref) << text;
}

TEST(ExpressionValues, ConstantFoldingAndHashConsing) {
  const auto e = Expression::parse("sin(x)^2 + sin(x)^3", {"x"});
  EXPECT_EQ(e.node_count(), 5U);  // x, sin(x), ^2, ^3, + : sin(x) is one shared node
  EXPECT_TRUE(Expression::parse("2*pi - 1", {"x"}).is_constant());
  EXPECT_EQ(Expression::parse("x - x", {"x"}).to_string(), "0");
  EXPECT_EQ(Expression::parse("x*y - y*x", {"x", "y"}).to_string(), "0");  // commutative order
  EXPECT_EQ(Expression::parse("0*sin(x) + 1*y + 0", {"x", "y"}).to_string(), "y");
  EXPECT_FALSE(Expression::parse("0*sin(x) + y", {"x", "y"}).depends_on(0));
  EXPECT_EQ(Expression::parse("x^(1+2)", {"x"})({-2.0}), -8.0);  // folded to an integer power
}

// ---------------------------------------------------------------------------------------------
// Derivatives

struct Reference {
  std::function<double(const std::vector<double>&)> value;
  std::vector<std::function<double(const std::vector<double>&)>> gradient;              // wrt
  std::vector<std::vector<std::function<double(const std::vector<double>&)>>> hessian;  // wrt²
};

// Checks CompiledDerivatives (sparse and dense) and Expression::derivative against closed forms.
void check_against_closed_form(const std::string& text, const std::vector<std::string>& vars,
                               const std::vector<std::size_t>& wrt, const Reference& ref,
                               const std::vector<std::vector<double>>& points) {
  const auto f = Expression::parse(text, vars);
  CompiledDerivatives c(f, wrt);
  const std::size_t m = wrt.size();
  for (const auto& p : points) {
    const std::string at = text + " at point #" + std::to_string(&p - points.data());
    std::vector<double> g(m), hv(c.hessian_pattern().size());
    Eigen::MatrixXd H(m, m);
    expect_close(c.evaluate(p, g, hv), ref.value(p), at + " value");
    std::vector<double> g2(m);
    expect_close(c.evaluate_dense(p, g2, H), ref.value(p), at + " value (dense)");
    expect_close(f(p), ref.value(p), at + " value (Expression)");
    for (std::size_t k = 0; k < m; ++k) {
      expect_close(g[k], ref.gradient[k](p), at + " g" + std::to_string(k));
      EXPECT_EQ(g2[k], g[k]);
      const auto dk = f.derivative(wrt[k]);
      expect_close(dk(p), ref.gradient[k](p), at + " derivative() " + std::to_string(k));
      for (std::size_t l = 0; l < m; ++l) {
        const double h = ref.hessian[k][l](p);
        expect_close(H(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(l)), h,
                     at + " H" + std::to_string(k) + std::to_string(l));
        expect_close(dk.derivative(wrt[l])(p), h, at + " second derivative()");
      }
    }
    for (std::size_t e = 0; e < hv.size(); ++e) {
      const auto [r, col] = c.hessian_pattern()[e];
      EXPECT_EQ(hv[e], H(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(col)));
    }
  }
}

using P = const std::vector<double>&;

TEST(ExpressionDerivatives, Pendulum) {
  check_against_closed_form("1 - cos(x1)", {"x1"}, {0},
                            {[](P p) { return 1 - std::cos(p[0]); },
                             {[](P p) { return std::sin(p[0]); }},
                             {{[](P p) { return std::cos(p[0]); }}}},
                            {{0.3}, {-2.0}, {3.0}});
  const auto f = Expression::parse("1 - cos(x1)", {"x1"});
  EXPECT_EQ(f.derivative(0).to_string(), "sin(x1)");
  EXPECT_EQ(f.derivative("x1").derivative(0).to_string(), "cos(x1)");
}

TEST(ExpressionDerivatives, DuffingWithCoupling) {
  const std::string text = "x1^4/4 - x1^2/2 + 0.3*x1*x2";
  check_against_closed_form(
      text, {"x1", "x2"}, {0, 1},
      {[](P p) { return std::pow(p[0], 4) / 4 - p[0] * p[0] / 2 + 0.3 * p[0] * p[1]; },
       {[](P p) { return p[0] * p[0] * p[0] - p[0] + 0.3 * p[1]; }, [](P p) { return 0.3 * p[0]; }},
       {{[](P p) { return 3 * p[0] * p[0] - 1; }, [](P) { return 0.3; }},
        {[](P) { return 0.3; }, [](P) { return 0.0; }}}},
      {{0.4, -1.1}, {-1.7, 0.8}, {2.3, 2.0}});
  const auto f = Expression::parse(text, {"x1", "x2"});
  EXPECT_EQ(f.derivative(0).to_string(), "x1^3 - x1 + 0.3*x2");
  CompiledDerivatives c(f);
  EXPECT_EQ(c.hessian_pattern(), (std::vector<HessianEntry>{{0, 0}, {0, 1}}));  // H22 = 0
  EXPECT_FALSE(c.hessian_is_constant());
  EXPECT_EQ(f.polynomial_degree(), 4);
}

TEST(ExpressionDerivatives, GaussianTimesSineWithRespectToASubset) {
  // Variables (t, x1, x2); derivatives with respect to x1, x2 only, t a parameter.
  const auto e = [](P p) { return std::exp(-p[1] * p[1]); };
  check_against_closed_form(
      "exp(-x1^2)*sin(t*x2)", {"t", "x1", "x2"}, {1, 2},
      {[=](P p) { return e(p) * std::sin(p[0] * p[2]); },
       {[=](P p) { return -2 * p[1] * e(p) * std::sin(p[0] * p[2]); },
        [=](P p) { return p[0] * e(p) * std::cos(p[0] * p[2]); }},
       {{[=](P p) { return (4 * p[1] * p[1] - 2) * e(p) * std::sin(p[0] * p[2]); },
         [=](P p) { return -2 * p[1] * p[0] * e(p) * std::cos(p[0] * p[2]); }},
        {[=](P p) { return -2 * p[1] * p[0] * e(p) * std::cos(p[0] * p[2]); },
         [=](P p) { return -p[0] * p[0] * e(p) * std::sin(p[0] * p[2]); }}}},
      {{0.7, 0.3, 1.2}, {1.9, -1.3, -0.4}, {-0.6, 0.9, 2.2}});
}

TEST(ExpressionDerivatives, GeneralPowerUsesExpLogRule) {
  check_against_closed_form(
      "pow(x1, x2)", {"x1", "x2"}, {0, 1},
      {[](P p) { return std::pow(p[0], p[1]); },
       {[](P p) { return p[1] * std::pow(p[0], p[1] - 1); },
        [](P p) { return std::pow(p[0], p[1]) * std::log(p[0]); }},
       {{[](P p) { return p[1] * (p[1] - 1) * std::pow(p[0], p[1] - 2); },
         [](P p) { return std::pow(p[0], p[1] - 1) * (1 + p[1] * std::log(p[0])); }},
        {[](P p) { return std::pow(p[0], p[1] - 1) * (1 + p[1] * std::log(p[0])); },
         [](P p) { return std::pow(p[0], p[1]) * std::pow(std::log(p[0]), 2); }}}},
      {{1.3, 2.5}, {0.4, -0.7}, {2.9, 1.1}});
}

TEST(ExpressionDerivatives, RadialDistance) {
  const auto r = [](P p) { return std::hypot(p[0], p[1]); };
  Reference ref{r, {}, {}};
  for (std::size_t i = 0; i < 2; ++i) {
    ref.gradient.push_back([=](P p) { return p[i] / r(p); });
    ref.hessian.emplace_back();
    for (std::size_t j = 0; j < 2; ++j)
      ref.hessian[i].push_back(
          [=](P p) { return ((i == j ? r(p) * r(p) : 0.0) - p[i] * p[j]) / std::pow(r(p), 3); });
  }
  check_against_closed_form("sqrt(x1^2 + x2^2)", {"x1", "x2"}, {0, 1}, ref,
                            {{3.0, 4.0}, {-0.5, 1.2}, {0.8, -0.1}});
}

TEST(ExpressionDerivatives, AbsoluteValueHasSignAndZeroSecondDerivative) {
  const auto f = Expression::parse("abs(x1)", {"x1"});
  EXPECT_EQ(f.derivative(0).to_string(), "sign(x1)");
  EXPECT_TRUE(f.derivative(0).derivative(0).is_constant());
  CompiledDerivatives c(f);
  EXPECT_TRUE(c.hessian_pattern().empty());
  double g = 0;
  EXPECT_EQ(c.evaluate(std::vector<double>{-2.5}, std::span(&g, 1)), 2.5);
  EXPECT_EQ(g, -1.0);
  check_against_closed_form(
      "abs(x1^3 - 2)", {"x1"}, {0},
      {[](P p) { return std::abs(p[0] * p[0] * p[0] - 2); },
       {[](P p) { return (p[0] * p[0] * p[0] > 2 ? 3.0 : -3.0) * p[0] * p[0]; }},
       {{[](P p) { return (p[0] * p[0] * p[0] > 2 ? 6.0 : -6.0) * p[0]; }}}},
      {{0.5}, {1.5}, {-1.0}});
}

// min, max, atan2, floor, heaviside and e (issue 16 item 2): values as std math, derivatives by
// the rules of docs/problem-file.md, including at the kinks and jumps.
TEST(ExpressionFunctions, ValuesAsStdMath) {
  const std::vector<std::string> v{"x", "y"};
  for (double x : {0.3, -1.7, 2.0, -0.0}) {
    for (double y : {0.6, -1.7, 2.0, 0.0}) {
      EXPECT_EQ(eval("min(x, y)", v, {x, y}), std::min(x, y)) << x << " " << y;
      EXPECT_EQ(eval("max(x, y)", v, {x, y}), std::max(x, y)) << x << " " << y;
      EXPECT_EQ(eval("atan2(x, y)", v, {x, y}), std::atan2(x, y)) << x << " " << y;
    }
    EXPECT_EQ(eval("floor(x)", v, {x, 0}), std::floor(x));
    EXPECT_EQ(eval("heaviside(x)", v, {x, 0}), x > 0 ? 1.0 : (x < 0 ? 0.0 : 0.5));
  }
  EXPECT_EQ(eval("floor(-2.5)", {}, {}), -3.0);
  EXPECT_EQ(eval("heaviside(0)", {}, {}), 0.5);
  EXPECT_EQ(eval("e", {}, {}), std::numbers::e);
  EXPECT_EQ(eval("e^x", v, {2.0, 0}), std::pow(std::numbers::e, 2.0));
  EXPECT_EQ(eval("max(1, 2) + min(3, -4) + atan2(1, 1)", {}, {}), 2.0 - 4.0 + std::atan2(1, 1));
  // A NaN is kept (std::min would drop it in its second argument): the integrator then sees it.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const char* text : {"min(x, y)", "max(x, y)"}) {
    EXPECT_TRUE(std::isnan(eval(text, v, {1.0, nan}))) << text;
    EXPECT_TRUE(std::isnan(eval(text, v, {nan, 1.0}))) << text;
  }
  EXPECT_TRUE(std::isnan(eval("heaviside(x)", v, {nan, 0})));
}

TEST(ExpressionFunctions, DerivativeRules) {
  const std::vector<std::string> v{"x", "y"};
  const auto d = [&](const std::string& text, std::size_t var, std::vector<double> at) {
    return Expression::parse(text, v).derivative(var)(at);
  };
  // min/max: the derivative of the selected argument; at a tie the mean of the two.
  EXPECT_EQ(d("min(x^2, y)", 0, {1.5, 4.0}), 3.0);
  EXPECT_EQ(d("min(x^2, y)", 1, {1.5, 4.0}), 0.0);
  EXPECT_EQ(d("min(x^2, y)", 1, {3.0, 4.0}), 1.0);
  EXPECT_EQ(d("max(x^2, y)", 0, {3.0, 4.0}), 6.0);
  EXPECT_EQ(d("max(x^2, y)", 0, {2.0, 4.0}), 2.0);  // tie: (4 + 0)/2
  EXPECT_EQ(d("min(x^2, y)", 1, {2.0, 4.0}), 0.5);  // tie: (0 + 1)/2
  EXPECT_EQ(d("max(x, -x)", 0, {0.0, 0.0}), 0.0);   // |x| at its kink: the mean of ±1
  // atan2(y, x) is the angle of (x, y): d/dy = x/(x² + y²), d/dx = −y/(x² + y²).
  check_against_closed_form(
      "atan2(x2, x1)", {"x1", "x2"}, {0, 1},
      {[](P p) { return std::atan2(p[1], p[0]); },
       {[](P p) { return -p[1] / (p[0] * p[0] + p[1] * p[1]); },
        [](P p) { return p[0] / (p[0] * p[0] + p[1] * p[1]); }},
       {{[](P p) { return 2 * p[0] * p[1] / std::pow(p[0] * p[0] + p[1] * p[1], 2); },
         [](P p) { return (p[1] * p[1] - p[0] * p[0]) / std::pow(p[0] * p[0] + p[1] * p[1], 2); }},
        {[](P p) { return (p[1] * p[1] - p[0] * p[0]) / std::pow(p[0] * p[0] + p[1] * p[1], 2); },
         [](P p) { return -2 * p[0] * p[1] / std::pow(p[0] * p[0] + p[1] * p[1], 2); }}}},
      {{1.0, 0.5}, {-0.7, 1.2}, {-1.0, -0.3}});
  // floor and heaviside are piecewise constant: derivative 0 (the jumps are not seen).
  for (const char* text : {"floor(3*x)", "heaviside(x - 1)"}) {
    const auto f = Expression::parse(text, v);
    EXPECT_TRUE(f.derivative(0).is_constant()) << text;
    EXPECT_EQ(f.derivative(0)({0.4, 0.0}), 0.0) << text;
  }
  // A switched spring: U = heaviside(t - 1) x²/2 has U_x = heaviside(t - 1) x.
  EXPECT_EQ(Expression::parse("heaviside(t - 1)*x^2/2", {"x", "t"}).derivative(0)({3.0, 2.0}), 3.0);
  EXPECT_EQ(Expression::parse("heaviside(t - 1)*x^2/2", {"x", "t"}).derivative(0)({3.0, 0.5}), 0.0);
  // Smooth away from the kinks: agreement with central differences.
  const std::vector<std::string> formulas = {"max(x^2, y) - min(x*y, 1)", "atan2(y, x)*e",
                                             "x*floor(y) + heaviside(y)*y^2"};
  for (const auto& text : formulas) {
    const auto f = Expression::parse(text, v);
    for (const std::vector<double>& p : {std::vector{0.7, 1.3}, std::vector{-1.1, 0.4}}) {
      for (std::size_t k = 0; k < 2; ++k) {
        const double h = 1e-6;
        auto plus = p, minus = p;
        plus[k] += h;
        minus[k] -= h;
        EXPECT_NEAR(f.derivative(k)(p), (f(plus) - f(minus)) / (2 * h), 1e-8) << text << k;
      }
    }
  }
}

TEST(ExpressionFunctions, PrintingAndErrors) {
  const std::vector<std::string> v{"x", "y"};
  EXPECT_EQ(Expression::parse("min(x, y) + atan2(y, 2) + e", v).to_string(),
            "min(x, y) + atan2(y, 2) + e");
  const auto f = Expression::parse("max(x^2, y)", v);
  const auto again = Expression::parse(f.derivative(0).to_string(), v);
  EXPECT_EQ(again({1.0, 3.0}), f.derivative(0)({1.0, 3.0}));
  const auto message = [&](const std::string& text) {
    try {
      (void)Expression::parse(text, v);
    } catch (const ExpressionError& e) {
      return e.reason();
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("min(x)"), "function 'min' takes 2 arguments but was given 1");
  EXPECT_EQ(message("floor(x, y)"), "function 'floor' takes 1 argument but was given 2");
  EXPECT_EQ(message("atan2"), "function 'atan2' needs an argument list, e.g. atan2(x, 2)");
  EXPECT_EQ(message("e(x)"), "'e' is a constant, not a function (missing '*' before '('?)");
  EXPECT_NE(message("heavyside(x)").find("did you mean 'heaviside'?"), std::string::npos);
  EXPECT_THROW((void)Expression::parse("e", {"e"}), std::invalid_argument);  // reserved
}

TEST(ExpressionDerivatives, IntegerPowersWorkForNegativeBases) {
  check_against_closed_form("x1^3 + x1^-2", {"x1"}, {0},
                            {[](P p) { return std::pow(p[0], 3) + std::pow(p[0], -2); },
                             {[](P p) { return 3 * p[0] * p[0] - 2 * std::pow(p[0], -3); }},
                             {{[](P p) { return 6 * p[0] + 6 * std::pow(p[0], -4); }}}},
                            {{-2.0}, {-0.7}, {1.3}});
  // Negative control: a non-integer power of a negative base is NaN, as in std::pow.
  EXPECT_TRUE(std::isnan(eval("x^2.5", {"x"}, {-2.0})));
  EXPECT_TRUE(std::isnan(Expression::parse("x^2.5", {"x"}).derivative(0)({-2.0})));
}

TEST(ExpressionDerivatives, EveryFunction) {
  struct Case {
    std::string text;
    std::function<double(double)> d1, d2;
  };
  const auto sec2 = [](double x) { return 1 + std::tan(x) * std::tan(x); };
  const auto sech2 = [](double x) { return 1 - std::tanh(x) * std::tanh(x); };
  const std::vector<Case> cases = {
      {"sin(x)", [](double x) { return std::cos(x); }, [](double x) { return -std::sin(x); }},
      {"cos(x)", [](double x) { return -std::sin(x); }, [](double x) { return -std::cos(x); }},
      {"tan(x)", sec2, [=](double x) { return 2 * std::tan(x) * sec2(x); }},
      {"exp(2*x)", [](double x) { return 2 * std::exp(2 * x); },
       [](double x) { return 4 * std::exp(2 * x); }},
      {"log(x)", [](double x) { return 1 / x; }, [](double x) { return -1 / (x * x); }},
      {"sqrt(x)", [](double x) { return 0.5 / std::sqrt(x); },
       [](double x) { return -0.25 / (x * std::sqrt(x)); }},
      {"sinh(x)", [](double x) { return std::cosh(x); }, [](double x) { return std::sinh(x); }},
      {"cosh(x)", [](double x) { return std::sinh(x); }, [](double x) { return std::cosh(x); }},
      {"tanh(x)", sech2, [=](double x) { return -2 * std::tanh(x) * sech2(x); }},
      {"atan(x)", [](double x) { return 1 / (1 + x * x); },
       [](double x) { return -2 * x / ((1 + x * x) * (1 + x * x)); }},
      {"x^1.5", [](double x) { return 1.5 * std::sqrt(x); },
       [](double x) { return 0.75 / std::sqrt(x); }},
      {"2^x", [](double x) { return std::pow(2.0, x) * std::log(2.0); },
       [](double x) { return std::pow(2.0, x) * std::log(2.0) * std::log(2.0); }},
      {"x/(1 + x^2)", [](double x) { return (1 - x * x) / ((1 + x * x) * (1 + x * x)); },
       [](double x) { return 2 * x * (x * x - 3) / std::pow(1 + x * x, 3); }},
  };
  for (const auto& c : cases) {
    const auto f = Expression::parse(c.text, {"x"});
    CompiledDerivatives cd(f);
    for (double x : {0.35, 0.9, 1.4}) {
      double g = 0;
      Eigen::MatrixXd H(1, 1);
      cd.evaluate_dense(std::vector<double>{x}, std::span(&g, 1), H);
      expect_close(g, c.d1(x), c.text + " first");
      expect_close(H(0, 0), c.d2(x), c.text + " second");
    }
  }
}

// Central differences of the value (for the gradient) and of the exact gradient (for the
// Hessian) at random points: an independent check of every rule at once.
TEST(ExpressionDerivatives, AgreeWithCentralDifferencesAtRandomPoints) {
  const std::vector<std::string> vars{"t", "x1", "x2", "x3"};
  const std::vector<std::string> formulas = {
      "1 - cos(x1) + x2^2/2 - x3",
      "x1^4/4 - x1^2/2 + 0.3*x1*x2 + sin(t)*x3",
      "exp(-x1^2)*sin(t*x2) + atan(x3*x1)",
      "pow(abs(x1) + 1, x2) / (2 + cosh(x3))",
      "sqrt(x1^2 + x2^2 + x3^2 + 1) * tanh(x1 - x3) + log(2 + sin(x2))",
      "tan(0.3*x1*x2) + sinh(x3)/(1 + x1^2) - (x2 - x1)^5 + 2^x3",
  };
  // Error of a central difference with step h: h^2/6 |f'''| (truncation) + eps |f|/h
  // (rounding), the same with f -> df/dx_l for the Hessian. On the box [-1.5, 1.5]^4 the largest
  // terms come from (x2 - x1)^5: |f| <= 243, third and fourth derivatives <= 540 and 1080, so
  // with h = 1e-5 both errors stay below ~2e-8 (absolute, and such entries are large); kFdTol,
  // relative to max(1, |derivative|), leaves a margin of at least 5.
  constexpr double kH = 1e-5, kFdTol = 1e-7;
  std::mt19937_64 rng(20240601);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (const auto& text : formulas) {
    CompiledDerivatives c(Expression::parse(text, vars));
    const std::size_t n = vars.size();
    for (int trial = 0; trial < 20; ++trial) {
      std::vector<double> p(n), g(n), gp(n), gm(n);
      for (double& x : p) x = u(rng);
      Eigen::MatrixXd H(n, n), scratch(n, n);
      c.evaluate_dense(p, g, H);
      for (std::size_t k = 0; k < n; ++k) {
        auto pp = p, pm = p;
        pp[k] += kH;
        pm[k] -= kH;
        const double fd = (c.evaluate(pp) - c.evaluate(pm)) / (2 * kH);
        EXPECT_NEAR(g[k], fd, kFdTol * std::max(1.0, std::abs(fd))) << text << " g" << k;
        c.evaluate(pp, gp);
        c.evaluate(pm, gm);
        for (std::size_t l = 0; l < n; ++l) {
          const double fd2 = (gp[l] - gm[l]) / (2 * kH);
          EXPECT_NEAR(H(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(l)), fd2,
                      kFdTol * std::max(1.0, std::abs(fd2)))
              << text << " H" << k << l;
        }
      }
    }
  }
}

TEST(ExpressionDerivatives, ExactnessNegativeControl) {
  // The closed-form tolerance is tight enough to tell exact derivatives from the best central
  // difference: at x = 0.7 the engine matches sin(x) to kClosedFormTol while the optimal-step
  // central difference misses by more than 100 times that.
  CompiledDerivatives c(Expression::parse("1 - cos(x)", {"x"}));
  const double x = 0.7, h = std::cbrt(kEps);
  double g = 0;
  c.evaluate(std::vector<double>{x}, std::span(&g, 1));
  EXPECT_NEAR(g, std::sin(x), kClosedFormTol);
  const double fd =
      (c.evaluate(std::vector<double>{x + h}) - c.evaluate(std::vector<double>{x - h})) / (2 * h);
  EXPECT_GT(std::abs(fd - std::sin(x)), 100 * kClosedFormTol);
}

// ---------------------------------------------------------------------------------------------
// Sparsity

std::string chain_text(std::size_t d) {
  std::string text;
  for (std::size_t i = 1; i < d; ++i)
    text += (i > 1 ? " + " : "") + std::string("(x") + std::to_string(i + 1) + " - x" +
            std::to_string(i) + ")^4";
  return text;
}

std::vector<std::string> chain_vars(std::size_t d) {
  std::vector<std::string> v;
  for (std::size_t i = 1; i <= d; ++i) v.push_back("x" + std::to_string(i));
  return v;
}

TEST(ExpressionSparsity, ChainOfThousandSpringsHasLinearlyManyHessianEntries) {
  constexpr std::size_t d = 1000;
  const auto f = Expression::parse(chain_text(d), chain_vars(d));
  CompiledDerivatives c(f);
  EXPECT_EQ(c.gradient_pattern().size(), d);
  // Tridiagonal: d diagonal + (d − 1) off-diagonal entries in the upper triangle.
  ASSERT_EQ(c.hessian_pattern().size(), 2 * d - 1);
  for (const auto& e : c.hessian_pattern()) EXPECT_LE(e.col - e.row, 1U);
  // O(d) tape: a bounded number of instructions per spring.
  EXPECT_LE(c.tape_size(), 20 * d);
  RecordProperty("chain_1000_tape_size", std::to_string(c.tape_size()));

  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> x(d), g(d), hv(c.hessian_pattern().size());
  for (double& xi : x) xi = u(rng);
  const double value = c.evaluate(x, g, hv);
  double ref = 0;
  std::vector<double> gref(d, 0.0), diag(d, 0.0), off(d, 0.0);
  for (std::size_t i = 0; i + 1 < d; ++i) {
    const double s = x[i + 1] - x[i];
    ref += s * s * s * s;
    gref[i + 1] += 4 * s * s * s;
    gref[i] -= 4 * s * s * s;
    diag[i] += 12 * s * s;
    diag[i + 1] += 12 * s * s;
    off[i] = -12 * s * s;
  }
  // Sums of up to d positive terms: rounding grows like d·ε relative to the sum.
  EXPECT_NEAR(value, ref, static_cast<double>(d) * kEps * ref);
  for (std::size_t i = 0; i < d; ++i) expect_close(g[i], gref[i], "g" + std::to_string(i));
  for (std::size_t e = 0; e < hv.size(); ++e) {
    const auto [r, col] = c.hessian_pattern()[e];
    expect_close(hv[e], r == col ? diag[r] : off[r], "H entry " + std::to_string(e));
  }
}

TEST(ExpressionSparsity, DenseCouplingGivesTheFullTriangle) {
  // Negative control for the pattern: (Σ x_i)^2 couples everything.
  constexpr std::size_t d = 30;
  std::string text = "(x1";
  for (std::size_t i = 2; i <= d; ++i) text += " + x" + std::to_string(i);
  text += ")^2";
  CompiledDerivatives c(Expression::parse(text, chain_vars(d)));
  EXPECT_EQ(c.hessian_pattern().size(), d * (d + 1) / 2);
  EXPECT_TRUE(c.hessian_is_constant());
}

TEST(ExpressionSparsity, QuadraticPotentialsAreRecognised) {
  const std::vector<std::string> v{"x1", "x2", "t"};
  const auto quad = Expression::parse("x1^2/2 + 0.5*(x2 - x1)^2 - sin(t)*x1", v);
  const std::size_t positions[] = {0, 1};
  EXPECT_EQ(quad.polynomial_degree(positions), 2);
  EXPECT_FALSE(quad.polynomial_degree().has_value());  // sin(t) is not polynomial in t
  EXPECT_TRUE(CompiledDerivatives(quad, {0, 1}).hessian_is_constant());
  EXPECT_FALSE(
      CompiledDerivatives(Expression::parse("x1^2*cos(t)", v), {0, 1}).hessian_is_constant());
  EXPECT_FALSE(CompiledDerivatives(Expression::parse("x1^4", v), {0, 1}).hessian_is_constant());
  // Piecewise-linear potentials: every Hessian entry simplifies to 0 (abs → sign → 0), but the
  // gradient jumps, so the Hessian is not constant where it matters (not a "linear" problem).
  for (const char* kinked : {"abs(x1)", "max(x1, 0) + x2^2", "sign(x1)*x1", "min(x1, x2)",
                             "2*floor(x1) + x1", "heaviside(x2 - 1)*x2"}) {
    const CompiledDerivatives c(Expression::parse(kinked, v), {0, 1});
    EXPECT_TRUE(c.hessian_pattern().empty() || std::string(kinked) == "max(x1, 0) + x2^2")
        << kinked;
    EXPECT_FALSE(c.hessian_is_constant()) << kinked;
    EXPECT_TRUE(c.expression().has_kinks_in(positions)) << kinked;
  }
  EXPECT_FALSE(quad.has_kinks_in(positions));
  const std::size_t out_of_range[] = {3};
  EXPECT_THROW((void)quad.has_kinks_in(out_of_range), std::invalid_argument);
  EXPECT_THROW((void)quad.polynomial_degree(out_of_range), std::invalid_argument);
  EXPECT_FALSE(Expression::parse("sqrt(x1^2 + 1e-6) + abs(t)*x2", v).has_kinks_in(positions));
  // A kink in t alone is a coefficient: still quadratic in the positions.
  EXPECT_TRUE(
      CompiledDerivatives(Expression::parse("abs(t)*x1 + x2^2", v), {0, 1}).hessian_is_constant());

  const std::vector<std::string> x{"x"};
  EXPECT_EQ(Expression::parse("3", x).polynomial_degree(), 0);
  EXPECT_EQ(Expression::parse("x/2", x).polynomial_degree(), 1);
  EXPECT_EQ(Expression::parse("(x + 1)^2", x).polynomial_degree(), 2);
  EXPECT_EQ(Expression::parse("(x^2 + 1)^3 * x", x).polynomial_degree(), 7);
  EXPECT_FALSE(Expression::parse("1/x", x).polynomial_degree().has_value());
  EXPECT_FALSE(Expression::parse("x^-2", x).polynomial_degree().has_value());
  EXPECT_FALSE(Expression::parse("x^0.5", x).polynomial_degree().has_value());
  EXPECT_FALSE(Expression::parse("cos(x)", x).polynomial_degree().has_value());
  EXPECT_TRUE(Expression::parse("x^2 + 1", x).is_polynomial_of_degree_at_most(2));
  EXPECT_FALSE(Expression::parse("x^3", x).is_polynomial_of_degree_at_most(2));
}

// ---------------------------------------------------------------------------------------------
// Errors

ExpressionError error_of(std::string_view text, std::vector<std::string> vars) {
  try {
    (void)Expression::parse(text, std::move(vars));
  } catch (const ExpressionError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for '" << text << "'";
  return ExpressionError("", "", 0);
}

struct ErrorCase {
  std::string text;
  std::size_t column;
  std::string reason_contains;
};

TEST(ExpressionErrors, MessageShowsTheExpressionAndACaret) {
  const auto e = error_of("1 - cos(x3)", {"t", "x1", "x2"});
  EXPECT_EQ(e.column(), 8U);
  EXPECT_STREQ(e.what(),
               "unknown variable 'x3' (known: t, x1, x2)\n"
               "  1 - cos(x3)\n"
               "          ^");
  EXPECT_EQ(e.expression(), "1 - cos(x3)");
  const std::invalid_argument& base = e;  // catchable as the standard input error
  EXPECT_NE(std::string(base.what()).find("x3"), std::string::npos);
}

TEST(ExpressionErrors, EveryCaseReportsItsColumn) {
  const std::vector<std::string> v{"x1", "x2", "theta"};
  const std::vector<ErrorCase> cases = {
      {"", 0, "empty expression"},
      {"   ", 0, "empty expression"},
      {"x1 +", 4, "unexpected end of expression"},
      {"x1 * * x2", 5, "unexpected '*'"},
      {"x1**2", 3, "use '^' for powers"},
      {"(x1 + 2", 7, "missing ')' to close '(' at column 0"},
      {"sin(x1", 6, "missing ')' to close the call of 'sin'"},
      {"(x1 + 2 x2)", 8, "expected ')' to close '('"},
      {"x1 + 2)", 6, "unmatched ')'"},
      {"x1 x2", 3, "unexpected 'x2' after a complete expression (missing an operator"},
      {"x1 $ 2", 3, "unexpected character '$'"},
      {"x1 \u2212 1", 3, "Unicode minus"},
      {"thta + 1", 0, "unknown variable 'thta' (known: x1, x2, theta); did you mean 'theta'?"},
      {"x3", 0, "unknown variable 'x3' (known: x1, x2, theta)"},
      {"2*sni(x1)", 2, "unknown function 'sni'; did you mean 'sin'?"},
      {"Sqrt(x1)", 0, "did you mean 'sqrt'?"},
      {"foo(x1)", 0, "unknown function 'foo' (functions: sin, cos"},
      {"x1(2)", 0, "'x1' is a variable, not a function"},
      {"sin + 1", 0, "function 'sin' needs an argument list"},
      {"sin(x1, x2)", 0, "function 'sin' takes 1 argument but was given 2"},
      {"1 + pow(x1)", 4, "function 'pow' takes 2 arguments but was given 1"},
      {"cos()", 0, "takes 1 argument but was given 0"},
      {"x1/0", 2, "division by zero"},
      {"x1 / (1 - 1)", 3, "division by zero"},
      {"x1/(x2 - x2)", 2, "division by zero"},
      {"log(0) + x1", 0, "constant subexpression evaluates to -inf"},
      {"x1 + 1e308*10", 10, "evaluates to inf"},
      {"sqrt(-1)", 0, "evaluates to NaN"},
      {"1e400", 0, "out of the range of double"},
      {"x1 + 017", 5, "leading zero"},
      {"2x1", 0, "malformed number '2x1' (for a product write '2*x1')"},
      {"1.5f", 0, "C suffixes such as 'f' are not supported"},
      {"1.2.3", 0, "malformed number '1.2.3'"},
      {"0x", 0, "malformed number '0x'"},
      {"1e+", 0, "malformed number '1e+'"},
  };
  for (const auto& c : cases) {
    const auto e = error_of(c.text, v);
    EXPECT_EQ(e.column(), c.column) << "'" << c.text << "': " << e.what();
    EXPECT_NE(e.reason().find(c.reason_contains), std::string::npos)
        << "'" << c.text << "': " << e.reason();
  }
  // A tie between equally close names gives no suggestion.
  EXPECT_EQ(error_of("x3", v).reason().find("did you mean"), std::string::npos);
}

TEST(ExpressionErrors, DeepNestingIsAnErrorNotACrash) {
  const std::string deep = std::string(10000, '(') + "x" + std::string(10000, ')');
  EXPECT_NE(error_of(deep, {"x"}).reason().find("nested too deeply"), std::string::npos);
  EXPECT_NE(error_of(std::string(10000, '-') + "x", {"x"}).reason().find("nested too deeply"),
            std::string::npos);
  EXPECT_EQ(eval(std::string(50, '(') + "x" + std::string(50, ')'), {"x"}, {2.0}), 2.0);
}

TEST(ExpressionErrors, LongExpressionsShowAWindowAroundTheColumn) {
  auto text = chain_text(200) + " + y";
  const auto e = error_of(text, chain_vars(200));
  EXPECT_EQ(e.column(), text.size() - 1);
  const std::string what = e.what();
  const auto second = what.find('\n') + 1, third = what.find('\n', second) + 1;
  EXPECT_LT(third - second, 140U);  // the line is a window, not the whole formula
  EXPECT_EQ(what.substr(third).find('^'), what.substr(second, third - second).rfind('y'));
}

TEST(ExpressionErrors, BadVariableListsAndComponents) {
  EXPECT_THROW((void)Expression::parse("x", {"x", "x"}), std::invalid_argument);
  EXPECT_THROW((void)Expression::parse("1", {"sin"}), std::invalid_argument);
  EXPECT_THROW((void)Expression::parse("1", {"pi"}), std::invalid_argument);
  EXPECT_THROW((void)Expression::parse("1", {"1x"}), std::invalid_argument);
  EXPECT_THROW((void)Expression::parse("1", {""}), std::invalid_argument);

  const std::vector<std::string> force{"sin(t)", "0", "cos(q)"};
  try {
    (void)parse_expressions(force, {"t"});
    ADD_FAILURE();
  } catch (const ExpressionError& e) {
    EXPECT_EQ(e.reason().rfind("component 3 of 3: unknown variable 'q'", 0), 0U) << e.reason();
    EXPECT_EQ(e.column(), 4U);
    EXPECT_EQ(e.expression(), "cos(q)");
  }
  const auto ok = parse_expressions(std::span(force).first(2), {"t"});
  ASSERT_EQ(ok.size(), 2U);
  EXPECT_EQ(ok[0]({0.5}), std::sin(0.5));
  EXPECT_TRUE(ok[1].is_constant());

  const auto f = Expression::parse("x*y", {"x", "y"});
  EXPECT_THROW((void)f({1.0}), std::invalid_argument);
  EXPECT_THROW((void)f.derivative(2), std::invalid_argument);
  EXPECT_THROW((void)f.derivative("z"), std::invalid_argument);
  EXPECT_THROW(CompiledDerivatives(f, {0, 0}), std::invalid_argument);
  EXPECT_THROW(CompiledDerivatives(f, {5}), std::invalid_argument);
  CompiledDerivatives a(f), b(f);
  auto ws = a.make_workspace();
  EXPECT_THROW((void)b.evaluate(std::vector<double>{1.0, 2.0}, ws), std::invalid_argument);
  std::vector<double> g(3);
  EXPECT_THROW((void)a.evaluate(std::vector<double>{1.0, 2.0}, g, ws), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Printing, evaluation without allocation, threads

TEST(ExpressionPrinting, ToStringReparsesToTheSameValues) {
  const std::vector<std::string> vars{"t", "x1", "x2"};
  const std::vector<std::string> formulas = {
      "x1 - (x2 - t)",    "x1/(x2*t)",         "(x1 + x2)^2 - x1^-3",
      "-x1^2 + (-x1)^3",  "2^x1^x2 / (1 + t)", "exp(-x1^2)*sin(t*x2)",
      "pow(x1, x2) - pi", "x1 * -x2",          "1e-300*x1 + 0x1.8p1*x2",
      "abs(x1 - x2)/-t",  "sqrt(x1^2 + x2^2)", "atan(x1/x2) - tanh(t)",
  };
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.2, 1.8);
  for (const auto& text : formulas) {
    const auto f = Expression::parse(text, vars);
    for (const Expression& e : {f, f.derivative(1), f.derivative(1).derivative(2)}) {
      const auto again = Expression::parse(e.to_string(), vars);
      for (int i = 0; i < 5; ++i) {
        const std::vector<double> p{u(rng), u(rng), u(rng)};
        EXPECT_EQ(again(p), e(p)) << text << " -> " << e.to_string();
      }
      EXPECT_EQ(again.node_count(), e.node_count()) << e.to_string();
    }
  }
  EXPECT_EQ(Expression::parse("-x1^2 + pi", vars).to_string(), "pi - x1^2");
  // Long sums print without deep recursion and re-parse.
  const auto chain = Expression::parse(chain_text(1000), chain_vars(1000));
  EXPECT_EQ(Expression::parse(chain.to_string(), chain_vars(1000)).node_count(),
            chain.node_count());
  EXPECT_EQ(Expression().to_string(), "0");
}

TEST(ExpressionEvaluation, RepeatedEvaluationDoesNotAllocate) {
  constexpr std::size_t d = 50;
  const auto chain = Expression::parse(chain_text(d) + " + sin(x1)*exp(x2)", chain_vars(d));
  CompiledDerivatives c(chain);
  auto ws = c.make_workspace();
  std::vector<double> x(d, 0.1), g(d), hv(c.hessian_pattern().size());
  Eigen::MatrixXd H(d, d);
  const auto pendulum = Expression::parse("1 - cos(x1)", {"x1"});
  double sink = chain(x) + pendulum({0.3});  // warm-up: the thread-local scratch grows once

  // Negative control: the replaced operator new does see allocations.
  const long control = g_allocations.load();
  x.reserve(x.capacity() + 1);
  ASSERT_GT(g_allocations.load(), control);

  const long before = g_allocations.load();
  for (int k = 0; k < 1000; ++k) {
    x[k % d] += 1e-3;
    sink += c.evaluate(x, ws);
    sink += c.evaluate(x, g, ws);
    c.gradient(x, g, ws);
    sink += c.evaluate(x, g, hv, ws);
    sink += c.evaluate_dense(x, g, H, ws);
    sink += c.evaluate(x, g, hv);  // the object's own workspace
    sink += chain(x) + pendulum({0.3});
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_TRUE(std::isfinite(sink));
}

// gradient() runs the gradient's instructions without the value's: the same gradient bit for bit
// as evaluate(values, gradient) — also where a gradient entry is the value itself (exp), a
// variable (x1*x2), a constant or zero — from values copied in or written into the workspace's
// own variable slots.
TEST(ExpressionEvaluation, GradientOnlyEqualsTheGradientOfEvaluateBitForBit) {
  const std::vector<std::string> vars{"x1", "x2", "x3", "t"};
  for (const char* text : {"2*x1^2", "exp(x1) + x1*x2 + 3*x3", "0.5*(x1 - x2)^2*cos(t) + x2^4",
                           "sqrt(x1^2 + x2^2 + 0.1) - sin(t*x3)", "x2"}) {
    SCOPED_TRACE(text);
    const CompiledDerivatives c(Expression::parse(text, vars), {0, 1, 2});
    // Separate workspaces: slots left by evaluate() cannot stand in for gradient()'s own work.
    auto ws = c.make_workspace(), ws_only = c.make_workspace(), own = c.make_workspace();
    ASSERT_EQ(own.values().size(), vars.size());
    for (int k = 0; k < 50; ++k) {
      const std::vector<double> x{0.3 + 0.07 * k, -1.1 + 0.05 * k, 0.2 * k, 0.01 * k};
      std::vector<double> full(3), only(3, -7.0), in_place(3, -7.0);
      const double value = c.evaluate(x, full, ws);
      c.gradient(x, only, ws_only);
      std::copy(x.begin(), x.end(), own.values().begin());
      c.gradient(own.values(), in_place, own);
      EXPECT_EQ(only, full);
      EXPECT_EQ(in_place, full);
      EXPECT_EQ(c.evaluate(own.values(), own), value);  // the slots still hold x
    }
    std::vector<double> wrong(2), right(3);
    EXPECT_THROW(c.gradient(std::vector<double>(4, 0.0), wrong, ws), std::invalid_argument);
    EXPECT_THROW(c.gradient(std::vector<double>(3, 0.0), right, ws), std::invalid_argument);
  }
}

TEST(ExpressionEvaluation, ConstObjectWithPerThreadWorkspacesIsThreadSafe) {
  const auto f = Expression::parse("exp(-x1^2)*sin(t*x2) + x1^4", {"t", "x1", "x2"});
  const CompiledDerivatives c(f, {1, 2});
  auto run = [&](int seed, std::vector<double>& out) {
    auto ws = c.make_workspace();
    std::vector<double> g(2), h(c.hessian_pattern().size());
    for (int i = 0; i < 2000; ++i) {
      const double s = 0.001 * (i + seed);
      out.push_back(c.evaluate(std::vector<double>{s, -s, 2 * s}, g, h, ws) + g[0] + h[0] +
                    f({s, s, s}));
    }
  };
  std::vector<double> serial, a, b;
  run(0, serial);
  std::thread ta([&] { run(0, a); }), tb([&] { run(0, b); });
  ta.join();
  tb.join();
  EXPECT_EQ(a, serial);
  EXPECT_EQ(b, serial);
}

// power_laws(): the power-law forcings of method.split = "series" (fvi_lobatto.md §13.5).
TEST(Expression, PowerLawsOfSumsProductsAndPowers) {
  const std::vector<std::string> t{"t"};
  auto laws = [&](const std::string& text, double origin) {
    return Expression::parse(text, t).power_laws(0, origin);
  };
  auto expect_laws = [&](const std::string& text, double origin,
                         const std::vector<std::pair<double, double>>& expected) {
    const auto got = laws(text, origin);
    ASSERT_TRUE(got.has_value()) << text;
    ASSERT_EQ(got->size(), expected.size()) << text;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      EXPECT_DOUBLE_EQ((*got)[i].exponent, expected[i].first) << text;
      EXPECT_DOUBLE_EQ((*got)[i].coefficient, expected[i].second) << text;
    }
  };
  const double pi = std::numbers::pi;
  // The issue's Bagley–Torvik forcings, constants folded (sqrt(pi), 16/(5 sqrt(pi))).
  expect_laws("t^3 + 6*t + 16/(5*sqrt(pi))*t^2.5", 0.0,
              {{1.0, 6.0}, {2.5, 16.0 / (5.0 * std::sqrt(pi))}, {3.0, 1.0}});
  expect_laws("15/4*sqrt(t) + 15*sqrt(pi)/8*t + t^(5/2)", 0.0,
              {{0.5, 3.75}, {1.0, 15.0 * std::sqrt(pi) / 8.0}, {2.5, 1.0}});
  // Products, quotients by one term, integer powers of sums (expanded), equal powers merged,
  // cancellation dropped.
  expect_laws("(1 + t)^2 - t*t", 0.0, {{0.0, 1.0}, {1.0, 2.0}});
  expect_laws("t^3/(2*t^0.5) + pow(4*t, 1.5) - 7", 0.0, {{0.0, -7.0}, {1.5, 8.0}, {2.5, 0.5}});
  expect_laws("-(t - 2)^2", 2.0, {{2.0, -1.0}});
  // Around the origin t0: t − t0 is the variable; integer powers of t expand, t^2.5 does not.
  expect_laws("(t - 1)^1.5 + t", 1.0, {{0.0, 1.0}, {1.0, 1.0}, {1.5, 1.0}});
  expect_laws("t^2", 1.0, {{0.0, 1.0}, {1.0, 2.0}, {2.0, 1.0}});
  EXPECT_FALSE(laws("t^2.5", 1.0).has_value());
  // Not sums of power laws.
  for (const char* text : {"sin(t)", "sqrt(1 + t)", "exp(t)", "abs(t)", "t^t", "1/(1 + t)",
                           "(-t)^0.5", "heaviside(t - 1)"})
    EXPECT_FALSE(laws(text, 0.0).has_value()) << text;
  // Another variable.
  EXPECT_FALSE(Expression::parse("x*t", {"x", "t"}).power_laws(1, 0.0).has_value());
  EXPECT_THROW((void)Expression::parse("t", t).power_laws(1, 0.0), std::invalid_argument);
  // Negative exponents are reported (the caller decides): 1/t.
  expect_laws("1/t", 0.0, {{-1.0, 1.0}});
}

}  // namespace
}  // namespace fracvi
