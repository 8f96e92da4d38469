// Value + gradient + Hessian of a potential: the expression engine's compiled tape against the
// same derivatives written by hand in C++. The ratio engine/hand is the cost of reading U from a
// problem file instead of compiling it in. Both cycle through the same 256 random points so
// nothing is constant-folded; the hand-written code is in this translation unit and may be
// inlined (the best case for it).
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fracvi/expression/expression.hpp"

namespace {

using fracvi::CompiledDerivatives;
using fracvi::Expression;

constexpr std::size_t kPoints = 256;

std::vector<std::vector<double>> random_points(std::size_t dim) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  std::vector<std::vector<double>> p(kPoints, std::vector<double>(dim));
  for (auto& x : p)
    for (double& xi : x) xi = u(rng);
  return p;
}

// Runs the engine on `text` (derivatives with respect to all variables, sparse Hessian).
void engine(benchmark::State& state, const std::string& text, std::vector<std::string> vars) {
  const std::size_t n = vars.size();
  const CompiledDerivatives c(Expression::parse(text, std::move(vars)));
  auto ws = c.make_workspace();
  const auto points = random_points(n);
  std::vector<double> g(n), h(c.hessian_pattern().size());
  std::size_t i = 0;
  for (auto _ : state) {
    const double v = c.evaluate(points[i++ % kPoints], g, h, ws);
    benchmark::DoNotOptimize(v);
    benchmark::DoNotOptimize(g.data());
    benchmark::DoNotOptimize(h.data());
    benchmark::ClobberMemory();
  }
  state.counters["tape"] = static_cast<double>(c.tape_size());
  state.counters["hessian_nnz"] = static_cast<double>(c.hessian_pattern().size());
}

template <class F>
void hand(benchmark::State& state, std::size_t n, std::size_t nnz, F f) {
  const auto points = random_points(n);
  std::vector<double> g(n), h(nnz);
  std::size_t i = 0;
  for (auto _ : state) {
    const double v = f(points[i++ % kPoints].data(), g.data(), h.data());
    benchmark::DoNotOptimize(v);
    benchmark::DoNotOptimize(g.data());
    benchmark::DoNotOptimize(h.data());
    benchmark::ClobberMemory();
  }
}

// --- Duffing: U = x^4/4 − x^2/2 -------------------------------------------------------------

void BM_Duffing_Engine(benchmark::State& state) {
  engine(state, "x1^4/4 - x1^2/2", {"x1"});
}
void BM_Duffing_Hand(benchmark::State& state) {
  hand(state, 1, 1, [](const double* x, double* g, double* h) {
    const double x1 = x[0], x2 = x1 * x1;
    g[0] = x2 * x1 - x1;
    h[0] = 3 * x2 - 1;
    return x2 * x2 / 4 - x2 / 2;
  });
}

// --- Pendulum: U = 1 − cos x ----------------------------------------------------------------

void BM_Pendulum_Engine(benchmark::State& state) {
  engine(state, "1 - cos(x1)", {"x1"});
}
void BM_Pendulum_Hand(benchmark::State& state) {
  hand(state, 1, 1, [](const double* x, double* g, double* h) {
    const double c = std::cos(x[0]);
    g[0] = std::sin(x[0]);
    h[0] = c;
    return 1 - c;
  });
}

// --- Coupled 2-D: Duffing + harmonic + bilinear + cosine coupling ---------------------------

const std::string kCoupled = "x1^4/4 - x1^2/2 + x2^2/2 + 0.3*x1*x2 + 0.1*cos(x1 - x2)";
void BM_Coupled2D_Engine(benchmark::State& state) {
  engine(state, kCoupled, {"x1", "x2"});
}
void BM_Coupled2D_Hand(benchmark::State& state) {
  hand(state, 2, 3, [](const double* x, double* g, double* h) {
    const double x1 = x[0], x2 = x[1], sq = x1 * x1;
    const double c = 0.1 * std::cos(x1 - x2), s = 0.1 * std::sin(x1 - x2);
    g[0] = sq * x1 - x1 + 0.3 * x2 - s;
    g[1] = x2 + 0.3 * x1 + s;
    h[0] = 3 * sq - 1 - c;  // (0,0)
    h[1] = 0.3 + c;         // (0,1)
    h[2] = 1 - c;           // (1,1)
    return sq * sq / 4 - sq / 2 + x2 * x2 / 2 + 0.3 * x1 * x2 + c;
  });
}

// --- Chain of d − 1 quartic springs: U = Σ (x_{i+1} − x_i)^4, tridiagonal Hessian ------------

constexpr std::size_t kChain = 100;

void BM_Chain100_Engine(benchmark::State& state) {
  std::string text;
  std::vector<std::string> vars;
  for (std::size_t i = 1; i <= kChain; ++i) vars.push_back("x" + std::to_string(i));
  for (std::size_t i = 1; i < kChain; ++i)
    text += (i > 1 ? " + (x" : "(x") + std::to_string(i + 1) + " - x" + std::to_string(i) + ")^4";
  engine(state, text, vars);
}
void BM_Chain100_Hand(benchmark::State& state) {
  // Same sparse layout as the engine: row-major upper triangle (i,i), (i,i+1).
  hand(state, kChain, 2 * kChain - 1, [](const double* x, double* g, double* h) {
    double u = 0;
    for (std::size_t i = 0; i < kChain; ++i) g[i] = 0, h[2 * i] = 0;
    for (std::size_t i = 0; i + 1 < kChain; ++i) {
      const double s = x[i + 1] - x[i], s2 = s * s, f = 4 * s2 * s, k = 12 * s2;
      u += s2 * s2;
      g[i] -= f;
      g[i + 1] += f;
      h[2 * i] += k;
      h[2 * i + 1] = -k;
      h[2 * i + 2] += k;
    }
    return u;
  });
}

// --- Value only, through Expression::operator() (thread-local scratch) -----------------------

void BM_DuffingValue_Expression(benchmark::State& state) {
  const auto f = Expression::parse("x1^4/4 - x1^2/2", {"x1"});
  const auto points = random_points(1);
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(f(points[i++ % kPoints]));
}
void BM_DuffingValue_Hand(benchmark::State& state) {
  const auto points = random_points(1);
  std::size_t i = 0;
  for (auto _ : state) {
    const double x = points[i++ % kPoints][0], x2 = x * x;
    benchmark::DoNotOptimize(x2 * x2 / 4 - x2 / 2);
  }
}

// --- The force ∇U alone (what Newton evaluates every iteration): with and without the value ---

// Arg 0: CompiledDerivatives::evaluate(values, gradient) (value and gradient on one tape);
// arg 1: CompiledDerivatives::gradient (the gradient's instructions only).
void force(benchmark::State& state, const std::string& text, std::vector<std::string> vars) {
  const std::size_t n = vars.size();
  const CompiledDerivatives c(Expression::parse(text, std::move(vars)));
  auto ws = c.make_workspace();
  const auto points = random_points(n);
  std::vector<double> g(n);
  const bool gradient_only = state.range(0) == 1;
  std::size_t i = 0;
  for (auto _ : state) {
    if (gradient_only) {
      c.gradient(points[i++ % kPoints], g, ws);
    } else {
      benchmark::DoNotOptimize(c.evaluate(points[i++ % kPoints], g, ws));
    }
    benchmark::DoNotOptimize(g.data());
    benchmark::ClobberMemory();
  }
}
void BM_Force_Quadratic(benchmark::State& state) {
  force(state, "2*x1^2", {"x1"});
}
void BM_Force_Duffing(benchmark::State& state) {
  force(state, "x1^4/4 - x1^2/2", {"x1"});
}
void BM_Force_Coupled2D(benchmark::State& state) {
  force(state, kCoupled, {"x1", "x2"});
}

BENCHMARK(BM_Duffing_Engine);
BENCHMARK(BM_Duffing_Hand);
BENCHMARK(BM_Pendulum_Engine);
BENCHMARK(BM_Pendulum_Hand);
BENCHMARK(BM_Coupled2D_Engine);
BENCHMARK(BM_Coupled2D_Hand);
BENCHMARK(BM_Chain100_Engine);
BENCHMARK(BM_Chain100_Hand);
BENCHMARK(BM_DuffingValue_Expression);
BENCHMARK(BM_DuffingValue_Hand);
BENCHMARK(BM_Force_Quadratic)->Arg(0)->Arg(1);
BENCHMARK(BM_Force_Duffing)->Arg(0)->Arg(1);
BENCHMARK(BM_Force_Coupled2D)->Arg(0)->Arg(1);

}  // namespace

BENCHMARK_MAIN();
