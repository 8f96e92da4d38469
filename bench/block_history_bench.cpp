// The block (Runge–Kutta CQ) fast history against s scalar fast histories, per step (issue 17
// item 2: "the block histories within 1.5× of s scalar histories per step").
//
//   BM_ScalarHistories/d/s  s FastHistory objects (Grünwald–Letnikov weights of s^β), each
//                           push + sum per step: what s independent scalar memories cost
//   BM_BlockHistory/d/s     one FastBlockHistory of the s-stage Lobatto IIIC CQ (lag 1, as the
//                           fvi-lobatto steppers use it), push + sum of a d × s block per step
//
// Both at β = 1.5 (the chain of bench/fractional_chain), ε = 1e-10, capacity 2^20 (the fits of a
// 10^6-step run), n = 4096 pushes per iteration after a clear (the window fills after 16, so the
// time per step is the steady one), on one thread each: the work of a step, not the thread
// choice (by default the block history, with (2s + 1)/2 times the work, is offered a run-ahead
// thread from smaller d than the scalar one, and the choice's trials made the ratio vary).
// Counters: ns_per_step, K (tail terms), n0 (exact window). The ratio block / (s scalar) is read
// off one run (bench/RESULTS.md):
//   block_history_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cstddef>
#include <memory>
#include <random>
#include <vector>

#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/memory/block_history.hpp"
#include "fracvi/memory/fast_history.hpp"

namespace {

constexpr double kOrder = 1.5;
constexpr std::size_t kCapacity = std::size_t{1} << 20;
constexpr std::size_t kSteps = 4096;
constexpr Eigen::Index kInputColumns = 64;

Eigen::MatrixXd input(Eigen::Index rows, Eigen::Index columns) {
  std::mt19937_64 gen(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd xs(rows, columns);
  for (Eigen::Index k = 0; k < columns; ++k)
    for (Eigen::Index i = 0; i < rows; ++i) xs(i, k) = normal(gen);
  return xs;
}

void per_step_counter(benchmark::State& state) {
  state.counters["ns_per_step"] = benchmark::Counter(
      static_cast<double>(kSteps),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_ScalarHistories(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto s = static_cast<int>(state.range(1));
  std::vector<std::unique_ptr<fracvi::FastHistory>> histories;
  for (int i = 0; i < s; ++i)
    histories.push_back(std::make_unique<fracvi::FastHistory>(kOrder, d, kCapacity));
  for (auto& h : histories) h->set_threads(1);
  state.counters["K"] = static_cast<double>(histories.front()->terms());
  state.counters["n0"] = static_cast<double>(histories.front()->window());
  const Eigen::MatrixXd xs = input(d, kInputColumns * s);
  Eigen::VectorXd out(d);
  double checksum = 0.0;
  for (auto _ : state) {
    for (auto& h : histories) h->clear();
    for (std::size_t k = 0; k < kSteps; ++k) {
      const Eigen::Index c = static_cast<Eigen::Index>(k % kInputColumns) * s;
      for (int i = 0; i < s; ++i) {
        histories[static_cast<std::size_t>(i)]->push(xs.col(c + i));
        histories[static_cast<std::size_t>(i)]->sum(out);
        checksum += out(0);
      }
    }
    benchmark::DoNotOptimize(checksum);
  }
  per_step_counter(state);
}

void BM_BlockHistory(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto s = static_cast<int>(state.range(1));
  const fracvi::RungeKuttaCq quadrature{s, kOrder, 1};
  const std::unique_ptr<fracvi::BlockHistory> history =
      fracvi::make_fast_block_history(quadrature, d, kCapacity);
  history->set_threads(1);
  const fracvi::HistoryReport report = history->report();
  state.counters["K"] = static_cast<double>(report.exponentials);
  state.counters["n0"] = static_cast<double>(report.window);
  const Eigen::MatrixXd xs = input(d, kInputColumns * s);
  Eigen::MatrixXd out(d, s);
  double checksum = 0.0;
  for (auto _ : state) {
    history->clear();
    for (std::size_t k = 0; k < kSteps; ++k) {
      const Eigen::Index c = static_cast<Eigen::Index>(k % kInputColumns) * s;
      history->push(xs.middleCols(c, s));
      history->sum(out);
      checksum += out(0, 0);
    }
    benchmark::DoNotOptimize(checksum);
  }
  per_step_counter(state);
}

void sizes(benchmark::internal::Benchmark* b) {
  for (const long d : {1L, 100L, 1000L})
    for (const long s : {2L, 3L, 4L}) b->Args({d, s});
}

}  // namespace

BENCHMARK(BM_ScalarHistories)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BlockHistory)->Apply(sizes)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
