// Per-step cost of the schemes (issue 11): fvi-lobatto2/3/4 against fvi-gl, fvi-bdf2 and
// fvi-midpoint, on
//
//   d = 1      the Caputo fractional oscillator y'' + 0.5 D^{3/2} y + y = 0, y(0) = 1, y'(0) = 0
//              (the work–precision problem of issue 11);
//   d = 100,   the fractional chain M x'' + R D^{3/2} x + ∇U(x) = 0 (Caputo), fixed ends, M = I and
//   d = 1000   R = 0.5 I stored sparse, U = Σ_bonds ½ r² (linear) or ½ r² + ¼ r⁴ (β-FPUT),
//              x_i(0) = 0.5 sin(π i/(d + 1)), v(0) = 0 (bench/fractional_chain.cpp's chain);
//
// h = 0.01, N = 2000 steps per run, fast history (ε = 1e-10) for every scheme (it pays from
// N ≈ 20–40 once fitted, bench/RESULTS.md), no mirror run, no energy bookkeeping, only the last
// state stored. One benchmark iteration is one whole run of N steps; the Integrator's construction
// (weights, the history's fit, the factorisation of a constant stage matrix) is outside the timed
// region. Counters: ns_per_step (wall time of the N steps / N), cpu_ns_per_step (the thread's CPU
// time / N) and newton_per_step.
//
// At the end the program prints the table of ns per step and the ratio to fvi-gl measured in the
// same run (bench/RESULTS.md, "Per-step cost of the schemes"). Not part of the tests.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace {

constexpr double kH = 0.01;
constexpr std::size_t kSteps = 2000;

const std::vector<std::string>& schemes() {
  static const std::vector<std::string> names{"fvi-gl",       "fvi-bdf2",     "fvi-midpoint",
                                              "fvi-lobatto2", "fvi-lobatto3", "fvi-lobatto4"};
  return names;
}

// Problem kinds: 0 the oscillator (d = 1), 1 the linear chain, 2 the β-FPUT chain.
const char* kind_name(int kind) {
  return kind == 0 ? "oscillator" : (kind == 1 ? "linear chain" : "FPUT chain");
}

fracvi::InitialValueProblem make_problem(int kind, Eigen::Index d) {
  fracvi::InitialValueProblem p;
  p.model.alpha = 0.75;  // 2α = 1.5
  p.model.convention = fracvi::Convention::kCaputo;
  if (kind == 0) {
    p.model.mass = Eigen::MatrixXd::Identity(1, 1);
    p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.5);
    p.model.potential = fracvi::make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
    p.x0 = Eigen::VectorXd::Constant(1, 1.0);
    p.v0 = Eigen::VectorXd::Zero(1);
  } else {
    p.model.mass = fracvi::ModelMatrix::identity(d, 1.0);
    p.model.damping = fracvi::ModelMatrix::identity(d, 0.5);
    fracvi::ChainOptions chain;
    chain.dimension = d;
    chain.stiffness = 1.0;
    chain.quartic = kind == 2 ? 1.0 : 0.0;
    p.model.potential = fracvi::make_chain_potential(chain);
    p.x0.resize(d);
    for (Eigen::Index i = 0; i < d; ++i) {
      p.x0[i] = 0.5 * std::sin(M_PI * static_cast<double>(i + 1) / static_cast<double>(d + 1));
    }
    p.v0 = Eigen::VectorXd::Zero(d);
  }
  p.steps = kSteps;
  p.t_end = kH * static_cast<double>(kSteps);
  return p;
}

// CPU time of this thread: on the shared 2-vCPU machine the wall time of a busy run includes the
// time slices other processes take; the thread's CPU time does not (threads = 1 below).
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Arguments: scheme index, problem kind, d.
void BM_SchemeStep(benchmark::State& state) {
  const std::string& name = schemes()[static_cast<std::size_t>(state.range(0))];
  const int kind = static_cast<int>(state.range(1));
  const auto d = static_cast<Eigen::Index>(state.range(2));
  const fracvi::InitialValueProblem p = make_problem(kind, d);
  const fracvi::Method method = *fracvi::parse_method(name);
  fracvi::IntegratorOptions o;
  o.mirror = false;
  o.diagnostics = false;
  o.save_every = kSteps;
  o.history = fracvi::HistoryKind::kFast;
  o.history_tolerance = 1e-10;
  o.threads = 1;
  std::size_t steps = 0, iterations = 0;
  double seconds = 0.0, cpu_seconds = 0.0;
  std::string solver;
  for (auto _ : state) {
    state.PauseTiming();
    auto integ = std::make_unique<fracvi::Integrator>(p, method, o);
    state.ResumeTiming();
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = thread_cpu_seconds();
    for (std::size_t k = 0; k < kSteps; ++k) benchmark::DoNotOptimize(integ->step());
    cpu_seconds += thread_cpu_seconds() - cpu_start;
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    state.PauseTiming();
    if (integ->status() != fracvi::Status::kSuccess) {
      state.SkipWithError(integ->solution().message.c_str());
      break;
    }
    steps += kSteps;
    iterations += integ->solution().newton_iterations;
    solver = integ->solution().linear_solver;
    state.ResumeTiming();
  }
  state.SetLabel(name + ", " + kind_name(kind) + ", " + solver);
  if (steps > 0) {
    state.counters["ns_per_step"] = 1e9 * seconds / static_cast<double>(steps);
    state.counters["cpu_ns_per_step"] = 1e9 * cpu_seconds / static_cast<double>(steps);
    state.counters["newton_per_step"] =
        static_cast<double>(iterations) / static_cast<double>(steps);
  }
}

void arguments(benchmark::internal::Benchmark* b) {
  for (int kind = 0; kind <= 2; ++kind) {
    for (const int d : {1, 100, 1000}) {
      if ((kind == 0) != (d == 1)) continue;
      for (int s = 0; s < static_cast<int>(schemes().size()); ++s) b->Args({s, kind, d});
    }
  }
}

BENCHMARK(BM_SchemeStep)->Apply(arguments)->Unit(benchmark::kMillisecond)->UseRealTime();

// The console output plus, at the end, ns per step and the ratio to fvi-gl of the same run.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      const auto wall = run.counters.find("ns_per_step");
      const auto cpu = run.counters.find("cpu_ns_per_step");
      if (run.error_occurred || wall == run.counters.end() || cpu == run.counters.end()) continue;
      // The label is "scheme, kind, solver"; the name ends with /scheme/kind/d.
      const std::string label = run.report_label;
      const std::string scheme = label.substr(0, label.find(','));
      const std::string rest = label.substr(label.find(',') + 2);
      // BM_SchemeStep/<scheme>/<kind>/<d>/real_time
      std::string name = run.benchmark_name();
      name = name.substr(0, name.rfind("/real_time"));
      const std::string d = name.substr(name.rfind('/') + 1);
      const std::string row = rest.substr(0, rest.find(',')) + ", d = " + d;
      if (std::find(rows_.begin(), rows_.end(), row) == rows_.end()) rows_.push_back(row);
      cells_[{row, scheme}] = {wall->second.value, cpu->second.value,
                               rest.substr(rest.find(',') + 2)};
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf(
        "\n| problem | scheme | solver | CPU ns/step | / fvi-gl | wall ns/step | / fvi-gl |\n"
        "|---|---|---|---|---|---|---|\n");
    for (const std::string& row : rows_) {
      const auto gl = cells_.find({row, "fvi-gl"});
      for (const std::string& scheme : schemes()) {
        const auto cell = cells_.find({row, scheme});
        if (cell == cells_.end()) continue;
        const Cell& c = cell->second;
        const double cpu_ratio = gl == cells_.end() ? std::nan("") : c.cpu / gl->second.cpu;
        const double wall_ratio = gl == cells_.end() ? std::nan("") : c.wall / gl->second.wall;
        std::printf("| %s | %s | %s | %.0f | %.2f | %.0f | %.2f |\n", row.c_str(), scheme.c_str(),
                    c.solver.c_str(), c.cpu, cpu_ratio, c.wall, wall_ratio);
      }
    }
  }

 private:
  std::vector<std::string> rows_;
  struct Cell {
    double wall, cpu;
    std::string solver;
  };
  std::map<std::pair<std::string, std::string>, Cell> cells_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
