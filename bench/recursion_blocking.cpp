// The fast history's recursions one step per pass over their state (four recursions share one
// load and store of the tail, as in memory/fast_history.cpp) against two and four steps per pass:
// the state Y_j is loaded once, advanced by x̃_{k+1}, x̃_{k+2}, … in turn, and each step's tail is
// formed on the way. Each element's operations are the same in the same order, so all give the
// same numbers bit for bit (checked, printed); B steps a pass move 1/B of the state through the
// caches. Several steps per pass are possible because the recursions take only values older than
// the exact window (n0 ≥ B lags), which are known B steps ahead.
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

// kSteps steps in one pass: Y_j ← a_j Y_j + x_s, tail_s = Σ_j w_j Y_j (groups of four summed
// pairwise, ascending j) for s = 0, 1, … in turn — the same operations per element as kSteps
// one-step passes. (The loop of FastHistory's kernel, memory/fast_history.cpp, repeated here
// because that one is internal to the library.)
template <int kSteps>
[[gnu::always_inline]] inline void pass(long n, long terms, double* state, Terms t,
                                        const double* const* xs, double* const* tails) {
  const double* x[kSteps];
  double* tail[kSteps];
  for (int s = 0; s < kSteps; ++s) {
    x[s] = xs[s];
    tail[s] = tails[s];
  }
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
      double v0 = y0[i], v1 = y1[i], v2 = y2[i], v3 = y3[i];
#pragma GCC unroll 4
      for (int s = 0; s < kSteps; ++s) {
        const double xi = x[s][i];
        v0 = a0 * v0 + xi;
        v1 = a1 * v1 + xi;
        v2 = a2 * v2 + xi;
        v3 = a3 * v3 + xi;
        tail[s][i] = (first ? 0.0 : tail[s][i]) + ((w0 * v0 + w1 * v1) + (w2 * v2 + w3 * v3));
      }
      y0[i] = v0;
      y1[i] = v1;
      y2[i] = v2;
      y3[i] = v3;
    }
  }
}

FRACVI_HOT_KERNEL __attribute__((noinline)) void one_step(long n, long terms, double* state,
                                                          Terms t, const double* const* x,
                                                          double* const* tails) {
  pass<1>(n, terms, state, t, x, tails);
}

FRACVI_HOT_KERNEL __attribute__((noinline)) void two_steps(long n, long terms, double* state,
                                                           Terms t, const double* const* x,
                                                           double* const* tails) {
  pass<2>(n, terms, state, t, x, tails);
}

FRACVI_HOT_KERNEL __attribute__((noinline)) void four_steps(long n, long terms, double* state,
                                                            Terms t, const double* const* x,
                                                            double* const* tails) {
  pass<4>(n, terms, state, t, x, tails);
}

}  // namespace

int main(int argc, char** argv) {
  const long d = argc > 1 ? std::atol(argv[1]) : 1000;
  const long terms = argc > 2 ? std::atol(argv[2]) : 28;
  const long steps = argc > 3 ? std::atol(argv[3]) : 20000;
  if (d < 1 || terms < 4 || terms % 4 != 0 || steps < 4 || steps % 4 != 0) {
    std::fprintf(stderr,
                 "recursion_blocking: d >= 1, K a multiple of 4, steps a multiple of 4 and >= 4\n");
    return 2;
  }
  const auto size = static_cast<std::size_t>(d), all = static_cast<std::size_t>(d * terms);
  std::vector<double> decay(static_cast<std::size_t>(terms)), weights(decay.size());
  for (std::size_t j = 0; j < decay.size(); ++j) {
    decay[j] = 0.999 - 0.01 * static_cast<double>(j);
    weights[j] = 1e-3 * static_cast<double>(j + 1);
  }
  std::vector<double> x(4 * size);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 1e-3 * static_cast<double>(i % 17 + 1);
  const Terms t{decay.data(), weights.data()};
  const double* xs[4] = {x.data(), x.data() + d, x.data() + 2 * d, x.data() + 3 * d};

  // Per way (one, two, four steps a pass): the state, four tails, a checksum of the tails.
  struct Way {
    std::vector<double> state, tails;
    double check = 0.0, seconds = 0.0;
  };
  Way ways[3];
  for (Way& w : ways) {
    w.state.assign(all, 0.1);
    w.tails.assign(4 * size, 0.0);
  }
  for (int way = 0; way < 3; ++way) {
    Way& w = ways[way];
    double* tails[4] = {w.tails.data(), w.tails.data() + d, w.tails.data() + 2 * d,
                        w.tails.data() + 3 * d};
    const auto start = Clock::now();
    for (long s = 0; s < steps; s += 4) {
      if (way == 0) {
        for (int q = 0; q < 4; ++q) one_step(d, terms, w.state.data(), t, xs + q, tails + q);
      } else if (way == 1) {
        two_steps(d, terms, w.state.data(), t, xs, tails);
        two_steps(d, terms, w.state.data(), t, xs + 2, tails + 2);
      } else {
        four_steps(d, terms, w.state.data(), t, xs, tails);
      }
      w.check += tails[0][size / 2] + tails[1][size / 3] + tails[2][size / 5] + tails[3][size / 7];
    }
    w.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  }
  bool same = true;
  for (int way = 1; way < 3; ++way) {
    same = same &&
           std::memcmp(ways[0].state.data(), ways[way].state.data(), all * sizeof(double)) == 0 &&
           ways[0].check == ways[way].check;
  }
  const auto per = [&](double seconds) { return seconds / static_cast<double>(steps) * 1e6; };
  std::printf(
      "d = %ld, K = %ld, us a step: one step a pass %.3f, two %.3f (%.2fx), four %.3f (%.2fx); "
      "same numbers bit for bit: %s\n",
      d, terms, per(ways[0].seconds), per(ways[1].seconds), ways[0].seconds / ways[1].seconds,
      per(ways[2].seconds), ways[0].seconds / ways[2].seconds, same ? "yes" : "NO");
  return same ? 0 : 1;
}
