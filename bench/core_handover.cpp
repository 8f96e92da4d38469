// What it costs this machine to hand data from one core to the other — the price a team of two
// pays every step (the fast history's run-ahead thread: the caller's x̃ column to the thread, the
// thread's tail back to the caller; d doubles each way).
//
// Two threads pinned to CPUs 0 and 1 take turns through one atomic: each reads the d doubles the
// other wrote last (a sum) and writes d of its own. Prints the round trip in µs, and the same
// loop on one thread (no hand-over) for comparison. Then whether CPUs 0 and 1 are two cores or two
// hardware threads of one core (as a virtual machine's vCPUs may be, whatever lscpu says): 32
// independent multiply–add chains (bound by the core's arithmetic, not by latency) run alone on
// CPU 0, then on CPUs 0 and 1 at once; two hardware threads of one core share its arithmetic units
// and each runs at about half the rate. Arguments (optional):
//   core_handover [d=1000] [rounds=100000]
// Not part of the tests (bench/RESULTS.md records the numbers).
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

#include "fracvi/internal/vectorize.hpp"

namespace {

bool pin_to(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
}

// Reads `from` (their sum, so the loads cannot be dropped) and writes `to`.
double take_turn(const std::vector<double>& from, std::vector<double>& to) {
  double sum = 0.0;
  for (const double v : from) sum += v;
  for (std::size_t i = 0; i < to.size(); ++i) to[i] = sum + static_cast<double>(i);
  return sum;
}

// 32 independent chains a ← a m + c, n rounds (vectorised: the history's kernels' target); returns
// the multiply–adds per second.
FRACVI_HOT_KERNEL
double multiply_add_rate(long n, double* out) {
  double acc[32];
  for (int i = 0; i < 32; ++i) acc[i] = 1.0 + 1e-3 * i;
  const double m = 0.9999999, c = 1e-9;
  const auto start = std::chrono::steady_clock::now();
  for (long r = 0; r < n; ++r) {
    for (int i = 0; i < 32; ++i) acc[i] = acc[i] * m + c;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double sum = 0.0;
  for (const double a : acc) sum += a;
  *out = sum;
  return 32.0 * static_cast<double>(n) / seconds;
}

}  // namespace

int main(int argc, char** argv) {
  const long d = argc > 1 ? std::atol(argv[1]) : 1000;
  const long rounds = argc > 2 ? std::atol(argv[2]) : 100000;
  if (d < 1 || rounds < 1) {
    std::fprintf(stderr, "core_handover: d = %ld and rounds = %ld must be >= 1\n", d, rounds);
    return 2;
  }
  std::vector<double> a(static_cast<std::size_t>(d), 1.0), b(static_cast<std::size_t>(d), 2.0);
  using Clock = std::chrono::steady_clock;

  // One thread: both turns in a row, no hand-over.
  volatile double sink = 0.0;
  auto start = Clock::now();
  for (long r = 0; r < rounds; ++r) {
    sink = sink + take_turn(b, a);
    sink = sink + take_turn(a, b);
  }
  const double alone = std::chrono::duration<double>(Clock::now() - start).count();

  std::atomic<int> turn{0};
  bool pinned = true;
  std::thread other([&] {
    pinned = pin_to(1) && pinned;
    double local = 0.0;
    for (long r = 0; r < rounds; ++r) {
      while (turn.load(std::memory_order_acquire) != 1) {
      }
      local += take_turn(a, b);
      turn.store(0, std::memory_order_release);
    }
    sink = sink + local;
  });
  pinned = pin_to(0) && pinned;
  start = Clock::now();
  for (long r = 0; r < rounds; ++r) {
    sink = sink + take_turn(b, a);
    turn.store(1, std::memory_order_release);
    while (turn.load(std::memory_order_acquire) != 0) {
    }
  }
  const double handed = std::chrono::duration<double>(Clock::now() - start).count();
  other.join();
  std::printf("d = %ld doubles each way, %ld rounds%s\n", d, rounds,
              pinned ? "" : " (pinning to CPUs 0 and 1 failed: the threads may share a core)");
  std::printf("one thread, both turns:      %.3f us a round\n",
              alone / static_cast<double>(rounds) * 1e6);
  std::printf("two cores, handed over:      %.3f us a round trip\n",
              handed / static_cast<double>(rounds) * 1e6);

  // Arithmetic throughput alone and on both CPUs at once.
  const long n = 20000000;
  double out = 0.0;
  pin_to(0);
  const double alone_rate = multiply_add_rate(n, &out);
  std::atomic<int> ready{0};
  double rate1 = 0.0, out1 = 0.0;
  std::thread second([&] {
    pin_to(1);
    ready.fetch_add(1);
    while (ready.load() < 2) {
    }
    rate1 = multiply_add_rate(n, &out1);
  });
  ready.fetch_add(1);
  while (ready.load() < 2) {
  }
  const double rate0 = multiply_add_rate(n, &out);
  second.join();
  sink = sink + out + out1;
  const double share = std::min(rate0, rate1) / alone_rate;
  std::printf(
      "multiply-adds alone on CPU 0: %.2f G/s; on CPUs 0 and 1 at once: %.2f and %.2f G/s "
      "(%.2f of alone)\n",
      alone_rate * 1e-9, rate0 * 1e-9, rate1 * 1e-9, share);
  std::printf("%s\n", share < 0.7   ? "CPUs 0 and 1 share one core's arithmetic (hardware threads)"
                      : share > 0.9 ? "CPUs 0 and 1 are separate cores"
                                    : "CPUs 0 and 1: in between (a busy machine?)");
  return 0;
}
