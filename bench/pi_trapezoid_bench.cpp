// pi-trapezoid's two histories (issue 12): whole runs of N steps with the direct product sums
// (O(N²·d)) and with the FFT-blocked sums of OnlineConvolution (O(N log² N · d)), on
//
//   d = 1    Garrappa's multi-term example y'' + 0.5 D^{3/2} y + y = 0, y(0) = 1, y'(0) = 0 on
//            [0, 20] (the published-numbers problem), and the same with 2α = 0.6;
//   d = 100  a linear chain M = I, R = 0.5 I, K tridiagonal (2, −1), 2α = 1.5, t ∈ [0, 20].
//
// One iteration is one whole run (integrate(): construction, weights and FFT plans included, no
// mirror, no diagnostics, last state stored). BM_PiTrapezoid/d/N/fft: fft = 0 direct, 1 FFT.
// The crossover that sets pi-trapezoid's kFftCrossover (method.history = "auto") and the ratios
// are in bench/RESULTS.md ("pi-trapezoid history"). Not part of the tests.
#include <benchmark/benchmark.h>

#include <cstddef>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace {

fracvi::InitialValueProblem problem(Eigen::Index d, std::size_t steps, double beta) {
  fracvi::InitialValueProblem p;
  Eigen::MatrixXd stiffness = Eigen::MatrixXd::Identity(d, d);
  if (d > 1) {
    stiffness = 2.0 * stiffness;
    stiffness.diagonal(1).setConstant(-1.0);
    stiffness.diagonal(-1).setConstant(-1.0);
  }
  p.model.mass = Eigen::MatrixXd::Identity(d, d);
  p.model.damping = 0.5 * Eigen::MatrixXd::Identity(d, d);
  p.model.alpha = beta / 2.0;
  p.model.convention = fracvi::Convention::kCaputo;
  p.model.potential = fracvi::make_quadratic_potential(stiffness);
  p.x0 = Eigen::VectorXd::Ones(d);
  p.v0 = Eigen::VectorXd::Zero(d);
  p.t_end = 20.0;
  p.steps = steps;
  return p;
}

void BM_PiTrapezoid(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto steps = static_cast<std::size_t>(state.range(1));
  const double beta = state.range(3) == 0 ? 1.5 : 0.6;
  const fracvi::InitialValueProblem p = problem(d, steps, beta);
  fracvi::IntegratorOptions options;
  options.history = state.range(2) != 0 ? fracvi::HistoryKind::kFast : fracvi::HistoryKind::kDirect;
  options.mirror = false;
  options.diagnostics = false;
  options.save_every = steps;
  const fracvi::Method method = *fracvi::parse_method("pi-trapezoid");
  for (auto _ : state) {
    const fracvi::Solution sol = fracvi::integrate(p, method, options);
    benchmark::DoNotOptimize(sol.x.data());
  }
  state.counters["ns_per_step"] =
      benchmark::Counter(static_cast<double>(steps), benchmark::Counter::kIsIterationInvariantRate |
                                                         benchmark::Counter::kInvert);
}

void arguments(benchmark::internal::Benchmark* b) {
  for (long beta : {0, 1}) {
    for (long n : {128, 256, 512, 1024, 2048, 8192, 40960})
      for (long fft : {0, 1}) b->Args({1, n, fft, beta});
  }
  for (long n : {128, 256, 512, 1024, 4096})
    for (long fft : {0, 1}) b->Args({100, n, fft, 0});
}

BENCHMARK(BM_PiTrapezoid)->Apply(arguments)->ArgNames({"d", "N", "fft", "beta06"});

}  // namespace

BENCHMARK_MAIN();
