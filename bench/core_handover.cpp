// What it costs this machine to hand data from one core to the other — the price a team of two
// pays every step (the fast history's run-ahead thread: the caller's x̃ column to the thread, the
// thread's tail back to the caller; d doubles each way).
//
// Two threads pinned to CPUs 0 and 1 take turns through one atomic: each reads the d doubles the
// other wrote last (a sum) and writes d of its own. Prints the round trip in µs, and the same
// loop on one thread (no hand-over) for comparison. Arguments (optional):
//   core_handover [d=1000] [rounds=100000]
// Not part of the tests (bench/RESULTS.md records the numbers).
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

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
  return 0;
}
