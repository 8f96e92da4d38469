// Benchmark 2 of issue 6: a long fractional run of a large system.
//
//   fractional FPUT chain, damping order β = 2α = 1.5 (Caputo), d = 1000 (fixed ends, diagonal M
//   and R, quartic springs), N = 10^6 steps, fast history at ε = 1e-10, states stored every
//   10^4 steps, no mirror run.
//
// Prints the wall time, the history's memory, the process's peak resident memory, Newton
// iterations per step, and the same run on one thread (the 2-core speed-up) — both in one
// process, so the ratio is measured under the same conditions. Arguments (all optional):
//   fractional_chain [d=1000] [N=1000000] [threads=0] [compare_one_thread=1] [quartic=1]
//                    [history_tolerance=1e-10]
// Not part of the tests (bench/RESULTS.md records the numbers).
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"

namespace {

struct Measured {
  double seconds;
  fracvi::Solution solution;
};

Measured run(Eigen::Index d, std::size_t n, int threads, double quartic, double tolerance) {
  fracvi::InitialValueProblem p;
  p.model.mass = fracvi::ModelMatrix::identity(d, 1.0);
  p.model.damping = fracvi::ModelMatrix::identity(d, 0.5);
  p.model.alpha = 0.75;  // β = 1.5
  p.model.convention = fracvi::Convention::kCaputo;
  fracvi::ChainOptions chain;
  chain.dimension = d;
  chain.stiffness = 1.0;
  chain.quartic = quartic;
  chain.threads = threads;
  p.model.potential = fracvi::make_chain_potential(chain);
  p.x0.resize(d);
  for (Eigen::Index i = 0; i < d; ++i) {
    p.x0[i] = 0.5 * std::sin(M_PI * static_cast<double>(i + 1) / static_cast<double>(d + 1));
  }
  p.v0 = Eigen::VectorXd::Zero(d);
  p.t_end = 0.01 * static_cast<double>(n);  // h = 0.01
  p.steps = n;
  fracvi::IntegratorOptions o;
  o.history = fracvi::HistoryKind::kFast;
  o.history_tolerance = tolerance;
  o.mirror = false;
  o.save_every = 10000;
  o.threads = threads;
  const auto start = std::chrono::steady_clock::now();
  fracvi::Solution sol = fracvi::integrate(p, fracvi::fvi_gl(), o);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return {seconds, std::move(sol)};
}

void report(const char* label, const Measured& m, std::size_t n) {
  const fracvi::Solution& s = m.solution;
  std::printf(
      "%-10s wall %.2f s  (%.2f us/step)  status %s  newton/step %.2f  history %.2f MB  "
      "solver %s  K %zu  final energy %.6g  balance %.2e\n",
      label, m.seconds, 1e6 * m.seconds / static_cast<double>(n),
      std::string(fracvi::to_string(s.status)).c_str(),
      static_cast<double>(s.newton_iterations) / static_cast<double>(s.steps_done),
      static_cast<double>(s.history_bytes) / 1e6, s.linear_solver.c_str(), s.history_exponentials,
      s.energy(s.energy.size() - 1), s.max_balance_error);
}

}  // namespace

int main(int argc, char** argv) {
  const Eigen::Index d = argc > 1 ? std::atol(argv[1]) : 1000;
  const std::size_t n = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1000000;
  const int threads = argc > 3 ? std::atoi(argv[3]) : 0;
  const bool compare = argc > 4 ? std::atoi(argv[4]) != 0 : true;
  const double quartic = argc > 5 ? std::atof(argv[5]) : 1.0;
  const double tolerance = argc > 6 ? std::atof(argv[6]) : 1e-10;
  std::printf("fractional FPUT chain: d = %ld, N = %zu, beta = 1.5, quartic = %g, eps = %g\n",
              static_cast<long>(d), n, quartic, tolerance);
  const Measured all = run(d, n, threads, quartic, tolerance);
  report("threads=all", all, n);
  if (compare) {
    const Measured one = run(d, n, 1, quartic, tolerance);
    report("threads=1", one, n);
    std::printf("speed-up on all cores: %.2f\n", one.seconds / all.seconds);
  }
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::printf("peak resident memory of the process: %.1f MB\n",
              static_cast<double>(usage.ru_maxrss) / 1024.0);
  return 0;
}
