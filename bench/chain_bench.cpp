// Benchmarks 3 and 4 of issue 6: one time step on the α = 1/2 (viscous) damped FPUT chain,
//
//     M x'' + R x' + ∇U(x) = 0,   U = Σ_bonds ½ r² + (a/3) r³ + (b/4) r⁴ (fixed ends),
//     M = I, R = 0.1 I (both stored sparse, diagonal), a = 0.25, b = 1, h = 0.02,
//
// for d = 10 … 10^5, three ways, all on the same data structures (banded path):
//
//   BM_ChainFviStep/d/diag  one Integrator::step() of fvi-gl (α = 1/2: Lemma 5.3; the velocity
//                           v = M⁻¹p included; diag = 1 adds the energy bookkeeping)
//   BM_ChainMidpointStep/d  implicit midpoint with the damping at the midpoint, solved by the same
//                           Newton (internal::MidpointNewton, A = M + (h/2)R, tridiagonal J)
//   BM_ChainVerletStep/d    explicit Störmer–Verlet (velocity form), damping explicit
//
// Counters: newton_per_step (Newton iterations per step) and ns_per_newton (step time divided by
// iterations: the cost of one iteration — gradient, Hessian, tridiagonal factorisation, solve —
// plus its share of the step's O(d) vector work). The initial state x_i = 0.5 sin(0.3 i) stretches
// every bond by ~0.15, so the quartic term matters at every d.
//
// Ratios are what matters; run with --benchmark_repetitions=5 --benchmark_report_aggregates_only
// for medians. bench/RESULTS.md records the numbers.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/solve/midpoint_newton.hpp"

namespace {

constexpr double kH = 0.02;

fracvi::InitialValueProblem fput_chain(Eigen::Index d, std::size_t steps) {
  fracvi::InitialValueProblem p;
  p.model.mass = fracvi::ModelMatrix::identity(d, 1.0);
  p.model.damping = fracvi::ModelMatrix::identity(d, 0.1);
  p.model.alpha = 0.5;
  fracvi::ChainOptions chain;
  chain.dimension = d;
  chain.cubic = 0.25;
  chain.quartic = 1.0;
  p.model.potential = fracvi::make_chain_potential(chain);
  p.x0.resize(d);
  for (Eigen::Index i = 0; i < d; ++i) p.x0[i] = 0.5 * std::sin(0.3 * static_cast<double>(i));
  p.v0 = Eigen::VectorXd::Zero(d);
  p.steps = steps;
  p.t_end = kH * static_cast<double>(steps);
  return p;
}

std::size_t steps_for(Eigen::Index d) {
  return static_cast<std::size_t>(std::max<Eigen::Index>(200, 2000000 / (d + 10)));
}

void BM_ChainFviStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const fracvi::InitialValueProblem p = fput_chain(d, steps_for(d));
  fracvi::IntegratorOptions o;
  o.mirror = false;
  o.diagnostics = state.range(1) != 0;
  o.save_every = p.steps;
  auto integ = std::make_unique<fracvi::Integrator>(p, fracvi::fvi_gl(), o);
  std::size_t iterations = 0, steps = 0;
  for (auto _ : state) {
    if (integ->status() != fracvi::Status::kRunning) {
      state.PauseTiming();
      iterations += integ->solution().newton_iterations;
      integ = std::make_unique<fracvi::Integrator>(p, fracvi::fvi_gl(), o);
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(integ->step());
    ++steps;
  }
  iterations += integ->solution().newton_iterations;
  state.counters["newton_per_step"] = static_cast<double>(iterations) / static_cast<double>(steps);
  state.counters["ns_per_newton"] = benchmark::Counter(
      static_cast<double>(iterations), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_ChainMidpointStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const fracvi::InitialValueProblem p = fput_chain(d, steps_for(d));
  const fracvi::ModelMatrix a = linear_combination(p.model.mass, 0.5 * kH, p.model.damping);
  fracvi::internal::MidpointNewton newton(a, kH, p.model.potential.get(), fracvi::NewtonOptions{});
  Eigen::VectorXd x = p.x0, v = p.v0, c(d), delta = kH * p.v0;
  std::size_t iterations = 0, steps = 0, k = 0;
  for (auto _ : state) {
    if (k == p.steps) {
      k = 0;
      x = p.x0;
      v = p.v0;
      delta = kH * p.v0;
    }
    // (M + (h/2)R) Δ + (h²/2)∇U(x + Δ/2) = h M v, then v' = 2Δ/h − v.
    p.model.mass.multiply(v, c);
    c *= kH;
    const auto report = newton.solve(x, (static_cast<double>(k) + 0.5) * kH, c, nullptr, delta);
    iterations += static_cast<std::size_t>(report.iterations);
    x += delta;
    v = (2.0 / kH) * delta - v;
    ++k;
    ++steps;
    benchmark::DoNotOptimize(x.data());
  }
  state.SetLabel(std::string(to_string(newton.linear_solver())));
  state.counters["newton_per_step"] = static_cast<double>(iterations) / static_cast<double>(steps);
  state.counters["ns_per_newton"] = benchmark::Counter(
      static_cast<double>(iterations), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// Velocity Verlet with explicit damping: a(x, v) = M⁻¹(−∇U(x) − R v), M = I.
void BM_ChainVerletStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const fracvi::InitialValueProblem p = fput_chain(d, steps_for(d));
  Eigen::VectorXd x = p.x0, v = p.v0, g(d), acc(d), v_half(d), rv(d);
  auto acceleration = [&](const Eigen::VectorXd& xx, const Eigen::VectorXd& vv) {
    p.model.potential->gradient(xx, 0.0, g);
    p.model.damping.multiply(vv, rv);
    acc = -g - rv;
  };
  std::size_t k = 0;
  acceleration(x, v);
  for (auto _ : state) {
    if (k == p.steps) {
      k = 0;
      x = p.x0;
      v = p.v0;
      acceleration(x, v);
    }
    v_half = v + (0.5 * kH) * acc;
    x += kH * v_half;
    acceleration(x, v_half);
    v = v_half + (0.5 * kH) * acc;
    ++k;
    benchmark::DoNotOptimize(x.data());
  }
}

void sizes(benchmark::internal::Benchmark* b, bool with_diag) {
  for (const int d : {10, 100, 1000, 10000, 100000}) {
    if (with_diag) {
      b->Args({d, 1})->Args({d, 0});
    } else {
      b->Arg(d);
    }
  }
}

BENCHMARK(BM_ChainFviStep)->Apply([](auto* b) { sizes(b, true); });
BENCHMARK(BM_ChainMidpointStep)->Apply([](auto* b) { sizes(b, false); });
BENCHMARK(BM_ChainVerletStep)->Apply([](auto* b) { sizes(b, false); });

}  // namespace

BENCHMARK_MAIN();
