// The fast history's recursions one step per pass over their state (as FastHistory runs them:
// four recursions share one load and store of the tail, memory/fast_history.cpp) against two
// steps per pass: the state Y_j is loaded once, advanced by x̃_{k+1} and then by x̃_{k+2}, and
// both steps' tails are formed on the way. Each element's operations are the same in the same
// order, so both give the same numbers bit for bit (checked, printed); the second moves half the
// state through the caches. Two steps per pass is possible because the recursions take only
// values older than the exact window (n0 ≥ 2 lags), which are known two steps ahead.
//
// Stand-alone (the library's kernel attribute only: the x86-64-v3 clone, as the history's kernels
// carry), one thread. Arguments (optional):
//   recursion_blocking [d=1000] [K=28] [steps=20000]
// Not part of the tests (bench/RESULTS.md records the numbers).
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "fracvi/internal/vectorize.hpp"

namespace {

using Clock = std::chrono::steady_clock;

struct Terms {
  const double* decay;    // e^{−λ_j h}
  const double* weights;  // w_j
};

// One step (kTwoSteps false): Y_j ← a_j Y_j + x1, tail1 = Σ_j w_j Y_j (groups of four summed
// pairwise, ascending j). Two steps in one pass (true): then x2 enters too and its terms go to
// tail2 — the same operations per element as two one-step calls. (The loop of FastHistory's
// kernels, memory/fast_history.cpp, repeated here because those are internal to the library.)
template <bool kTwoSteps>
[[gnu::always_inline]] inline void pass(long n, long terms, double* state, Terms t,
                                        const double* x1, const double* x2, double* tail1,
                                        double* tail2) {
  for (long j = 0; j < terms; j += 4) {
    double* y0 = state + j * n;
    double* y1 = y0 + n;
    double* y2 = y1 + n;
    double* y3 = y2 + n;
    const double a0 = t.decay[j], a1 = t.decay[j + 1], a2 = t.decay[j + 2], a3 = t.decay[j + 3];
    const double w0 = t.weights[j], w1 = t.weights[j + 1], w2 = t.weights[j + 2],
                 w3 = t.weights[j + 3];
    const bool first = j == 0;
#pragma GCC ivdep
    for (long i = 0; i < n; ++i) {
      const double v0 = a0 * y0[i] + x1[i], v1 = a1 * y1[i] + x1[i];
      const double v2 = a2 * y2[i] + x1[i], v3 = a3 * y3[i] + x1[i];
      tail1[i] = (first ? 0.0 : tail1[i]) + ((w0 * v0 + w1 * v1) + (w2 * v2 + w3 * v3));
      if constexpr (kTwoSteps) {
        const double u0 = a0 * v0 + x2[i], u1 = a1 * v1 + x2[i];
        const double u2 = a2 * v2 + x2[i], u3 = a3 * v3 + x2[i];
        y0[i] = u0;
        y1[i] = u1;
        y2[i] = u2;
        y3[i] = u3;
        tail2[i] = (first ? 0.0 : tail2[i]) + ((w0 * u0 + w1 * u1) + (w2 * u2 + w3 * u3));
      } else {
        y0[i] = v0;
        y1[i] = v1;
        y2[i] = v2;
        y3[i] = v3;
      }
    }
  }
}

FRACVI_HOT_KERNEL __attribute__((noinline)) void one_step(long n, long terms, double* state,
                                                          Terms t, const double* x, double* tail) {
  pass<false>(n, terms, state, t, x, nullptr, tail, nullptr);
}

FRACVI_HOT_KERNEL __attribute__((noinline)) void two_steps(long n, long terms, double* state,
                                                           Terms t, const double* x1,
                                                           const double* x2, double* tail1,
                                                           double* tail2) {
  pass<true>(n, terms, state, t, x1, x2, tail1, tail2);
}

}  // namespace

int main(int argc, char** argv) {
  const long d = argc > 1 ? std::atol(argv[1]) : 1000;
  const long terms = argc > 2 ? std::atol(argv[2]) : 28;
  const long steps = argc > 3 ? std::atol(argv[3]) : 20000;
  if (d < 1 || terms < 4 || terms % 4 != 0 || steps < 2 || steps % 2 != 0) {
    std::fprintf(stderr, "recursion_blocking: d >= 1, K a multiple of 4, steps even and >= 2\n");
    return 2;
  }
  const auto size = static_cast<std::size_t>(d), all = static_cast<std::size_t>(d * terms);
  std::vector<double> decay(static_cast<std::size_t>(terms)), weights(decay.size());
  for (std::size_t j = 0; j < decay.size(); ++j) {
    decay[j] = 0.999 - 0.01 * static_cast<double>(j);
    weights[j] = 1e-3 * static_cast<double>(j + 1);
  }
  std::vector<double> x(2 * size);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 1e-3 * static_cast<double>(i % 17);
  const Terms t{decay.data(), weights.data()};
  std::vector<double> state_a(all, 0.1), state_b(all, 0.1);
  std::vector<double> tail_a1(size), tail_a2(size), tail_b1(size), tail_b2(size);

  double check_a = 0.0, check_b = 0.0;
  auto start = Clock::now();
  for (long s = 0; s < steps; s += 2) {
    one_step(d, terms, state_a.data(), t, x.data(), tail_a1.data());
    one_step(d, terms, state_a.data(), t, x.data() + d, tail_a2.data());
    check_a += tail_a1[size / 2] + tail_a2[size / 3];
  }
  const double per_step = std::chrono::duration<double>(Clock::now() - start).count();
  start = Clock::now();
  for (long s = 0; s < steps; s += 2) {
    two_steps(d, terms, state_b.data(), t, x.data(), x.data() + d, tail_b1.data(), tail_b2.data());
    check_b += tail_b1[size / 2] + tail_b2[size / 3];
  }
  const double blocked = std::chrono::duration<double>(Clock::now() - start).count();
  const bool same =
      std::memcmp(state_a.data(), state_b.data(), all * sizeof(double)) == 0 && check_a == check_b;
  const auto per = [&](double seconds) { return seconds / static_cast<double>(steps) * 1e6; };
  std::printf(
      "d = %ld, K = %ld: one step a pass %.3f us a step, two steps a pass %.3f us a step "
      "(%.2fx), same numbers bit for bit: %s\n",
      d, terms, per(per_step), per(blocked), per_step / blocked, same ? "yes" : "NO");
  return same ? 0 : 1;
}
