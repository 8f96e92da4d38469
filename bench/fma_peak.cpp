// The machine's peak rate of double-precision multiply–adds on one core, and what it puts under a
// fractional step: the memory term of the fast history (docs/theory/fast_history.md) costs, per
// degree of freedom and step, one multiply–add per exponential for its recursion, one per
// exponential for the tail's sum and one per column of the exact window — 2K + n0 in all — so no
// implementation of the same history can take less than d (2K + n0) / peak per step on one core.
//
// Twelve independent accumulators (latency 4 cycles × two FMA ports, with margin) of 256-bit
// (AVX2 + FMA) and, where the CPU has it, 512-bit (AVX-512F) vectors, in registers; each loop runs
// three times and the best is kept. Arguments (all optional):
//   fma_peak [d=1000] [K=33] [n0=16]
// Not part of the tests (bench/RESULTS.md records the numbers).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace {

using Clock = std::chrono::steady_clock;
constexpr long kRepeats = 100'000'000;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// GCC's vector types: `x * a + b` is one multiply–add instruction where the target has FMA (GCC
// contracts in C++ whatever the -std), of the vector's width.
using Vector4 = double __attribute__((vector_size(32)));
using Vector8 = double __attribute__((vector_size(64)));

// Multiply–adds per second of twelve independent accumulators of V; `sink` keeps them alive.
// Inlined into the wrappers below, whose targets give the instructions.
template <class V, int kLanes>
[[gnu::always_inline]] inline double rate(double& sink) {
  const V a = V{} + 0.999999, b = V{} + 1e-7;
  // Different starting values: equal ones would let the compiler compute one accumulator for all.
  V x0 = V{} + 1.0, x1 = V{} + 1.001, x2 = V{} + 1.002, x3 = V{} + 1.003, x4 = V{} + 1.004,
    x5 = V{} + 1.005, x6 = V{} + 1.006, x7 = V{} + 1.007, x8 = V{} + 1.008, x9 = V{} + 1.009,
    x10 = V{} + 1.010, x11 = V{} + 1.011;
  const auto t0 = Clock::now();
  for (long n = 0; n < kRepeats; ++n) {
    x0 = x0 * a + b, x1 = x1 * a + b, x2 = x2 * a + b, x3 = x3 * a + b, x4 = x4 * a + b;
    x5 = x5 * a + b, x6 = x6 * a + b, x7 = x7 * a + b, x8 = x8 * a + b, x9 = x9 * a + b;
    x10 = x10 * a + b, x11 = x11 * a + b;
  }
  const double s = seconds_since(t0);
  const V all = ((x0 + x1) + (x2 + x3)) + ((x4 + x5) + (x6 + x7)) + ((x8 + x9) + (x10 + x11));
  for (int i = 0; i < kLanes; ++i) sink += all[i];
  return static_cast<double>(kRepeats) * 12 * kLanes / s;
}

// 4 lanes of 256 bits (AVX2 + FMA).
__attribute__((target("avx2,fma"), noinline)) double rate_256(double& sink) {
  return rate<Vector4, 4>(sink);
}

// 8 lanes of 512 bits (AVX-512F).
__attribute__((target("avx512f"), noinline)) double rate_512(double& sink) {
  return rate<Vector8, 8>(sink);
}

template <class Rate>
double best_of_three(Rate rate, double& sink) {
  double best = 0.0;
  for (int r = 0; r < 3; ++r) best = std::max(best, rate(sink));
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  const long d = argc > 1 ? std::atol(argv[1]) : 1000;
  const long terms = argc > 2 ? std::atol(argv[2]) : 33;
  const long window = argc > 3 ? std::atol(argv[3]) : 16;
  if (d < 1 || terms < 0 || window < 0) {
    std::fprintf(stderr, "fma_peak: d >= 1, K >= 0 and n0 >= 0\n");
    return 2;
  }
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) {
    std::fprintf(stderr, "fma_peak: this CPU has no AVX2 + FMA\n");
    return 1;
  }
  double sink = 0.0;
  const double peak_256 = best_of_three(rate_256, sink);
  double peak = peak_256;
  std::printf("256-bit (AVX2 + FMA): %.2f G multiply-adds/s on one core\n", peak_256 * 1e-9);
  if (__builtin_cpu_supports("avx512f")) {
    const double peak_512 = best_of_three(rate_512, sink);
    peak = std::max(peak, peak_512);
    std::printf("512-bit (AVX-512F):   %.2f G multiply-adds/s on one core\n", peak_512 * 1e-9);
  }
  const double per_step = static_cast<double>(d) * static_cast<double>(2 * terms + window);
  std::printf(
      "memory term, d = %ld, K = %ld, n0 = %ld: %ld multiply-adds per DOF and step, at least "
      "%.2f us a step on one core at the peak rate\n",
      d, terms, window, 2 * terms + window, per_step / peak * 1e6);
  std::printf("(checksum %g)\n", sink);
  return 0;
}
