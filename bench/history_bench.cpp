// FastHistory against DirectHistory: the time of a whole run of N push()+sum() steps, the way
// the integrator drives a history (β = 0.75, i.e. α = 0.375; rough random input).
//
//   BM_DirectRun/d/N   O(N² d): DirectHistory, every sum walks all stored values
//   BM_DirectGemvRun/d/N  the same sum as one matrix–vector product over the stored values
//                      (the best a direct O(N² d) sum can do; a lower bound for any tuning of
//                      DirectHistory, so the crossover against it is the conservative one)
//   BM_FastRun/d/N     O(N (n0 + K) d), K ≈ 7 per decade of N at ε = 1e-10 (counter "K")
//   BM_Fit/N           building the ExponentialFit for max_lag = N (once per process with the
//                      cache; excluded from BM_FastRun)
//
// Ratios, log–log slopes and the crossover are in docs/theory/fast_history.md, computed from
// one run (STYLE.md: absolute times on a shared VM are noise). Reproduce with
//   history_bench --benchmark_out=history.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <cstddef>
#include <random>
#include <vector>

#include "fracvi/fractional/exponential_fit.hpp"
#include "fracvi/fractional/weights.hpp"
#include "fracvi/memory/fast_history.hpp"
#include "fracvi/memory/history.hpp"

namespace {

constexpr double kOrder = 0.75;

Eigen::MatrixXd input(Eigen::Index d, Eigen::Index columns) {
  std::mt19937_64 gen(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd xs(d, columns);
  for (Eigen::Index k = 0; k < columns; ++k)
    for (Eigen::Index i = 0; i < d; ++i) xs(i, k) = normal(gen);
  return xs;
}

// One run of n steps; the input cycles through 1024 stored columns so that memory for the input
// does not grow with n.
template <class H>
void run(benchmark::State& state, H& history, std::size_t n) {
  const Eigen::Index d = history.dimension();
  const Eigen::MatrixXd xs = input(d, 1024);
  Eigen::VectorXd s(d);
  double checksum = 0.0;
  for (auto _ : state) {
    history.clear();
    for (std::size_t k = 0; k < n; ++k) {
      history.push(xs.col(static_cast<Eigen::Index>(k % 1024)));
      history.sum(s);
      checksum += s(0);
    }
    benchmark::DoNotOptimize(checksum);
  }
  state.counters["ns_per_step"] =
      benchmark::Counter(static_cast<double>(n), benchmark::Counter::kIsIterationInvariantRate |
                                                     benchmark::Counter::kInvert);
}

// Direct sum as one gemv: values stored column by column, weights stored reversed so that
// Σ_{j≤k} c_{k−j} x̃_j = X[:, 0..k] · r[N−1−k .. N−1].
class GemvDirectHistory {
 public:
  GemvDirectHistory(double order, Eigen::Index d, std::size_t capacity)
      : values_(d, static_cast<Eigen::Index>(capacity)),
        reversed_(static_cast<Eigen::Index>(capacity)) {
    const std::vector<double> c = fracvi::gl_weights(order, capacity);
    for (std::size_t i = 0; i < capacity; ++i)
      reversed_(static_cast<Eigen::Index>(i)) = c[capacity - 1 - i];
  }
  void push(const Eigen::Ref<const Eigen::VectorXd>& x) { values_.col(size_++) = x; }
  void sum(Eigen::Ref<Eigen::VectorXd> out) const {
    out.noalias() = values_.leftCols(size_) * reversed_.tail(size_);
  }
  void clear() { size_ = 0; }
  [[nodiscard]] Eigen::Index dimension() const { return values_.rows(); }

 private:
  Eigen::MatrixXd values_;
  Eigen::VectorXd reversed_;
  Eigen::Index size_ = 0;
};

void BM_DirectGemvRun(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto n = static_cast<std::size_t>(state.range(1));
  GemvDirectHistory history(kOrder, d, n);
  run(state, history, n);
}

void BM_DirectRun(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto n = static_cast<std::size_t>(state.range(1));
  fracvi::DirectHistory history(kOrder, d, n);
  run(state, history, n);
}

void BM_FastRun(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const auto n = static_cast<std::size_t>(state.range(1));
  fracvi::FastHistory history(kOrder, d, n);  // fit from the process-wide cache
  state.counters["K"] = static_cast<double>(history.terms());
  run(state, history, n);
}

void BM_Fit(benchmark::State& state) {
  fracvi::ExponentialFitOptions options;
  options.order = kOrder;
  options.max_lag = static_cast<std::size_t>(state.range(0));
  std::size_t terms = 0;
  for (auto _ : state) {
    const fracvi::ExponentialFit fit = fracvi::fit_exponentials(options);
    terms = fit.terms();
    benchmark::DoNotOptimize(terms);
  }
  state.counters["K"] = static_cast<double>(terms);
}

void direct_sizes(benchmark::internal::Benchmark* b) {
  for (const long n :
       {20L, 50L, 100L, 200L, 500L, 1'000L, 2'000L, 5'000L, 10'000L, 30'000L, 100'000L})
    b->Args({1, n});
  for (const long n :
       {20L, 50L, 100L, 200L, 500L, 1'000L, 2'000L, 5'000L, 10'000L, 30'000L, 100'000L})
    b->Args({100, n});
}

void fast_sizes(benchmark::internal::Benchmark* b) {
  for (const long n : {20L, 50L, 100L, 200L, 500L, 1'000L, 2'000L, 5'000L, 10'000L, 30'000L,
                       100'000L, 1'000'000L, 10'000'000L})
    b->Args({1, n});
  for (const long n : {20L, 50L, 100L, 200L, 500L, 1'000L, 2'000L, 5'000L, 10'000L, 30'000L,
                       100'000L, 1'000'000L, 10'000'000L})
    b->Args({100, n});
}

}  // namespace

BENCHMARK(BM_DirectRun)->Apply(direct_sizes)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DirectGemvRun)->Apply(direct_sizes)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FastRun)->Apply(fast_sizes)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Fit)
    ->Arg(1'000)
    ->Arg(10'000)
    ->Arg(100'000)
    ->Arg(1'000'000)
    ->Arg(10'000'000)
    ->Arg(100'000'000)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
