// The solve with the tridiagonal LDLᵀ factor of a chain's Newton matrix, alone: J = I + s K with
// K the fixed-end chain's stiffness (2 on the diagonal, −1 beside it) and s = h²/4 for h = 0.01
// (the fractional_chain benchmark's J, whose spikes reach over whole chunks at d = 1000).
//
//   BM_TridiagonalSolve/d   SymmetricFactor::solve_in_place on the banded path: for d ≥ 512 the
//                           chunked solve (src/solve/symmetric_factor.cpp), below it LAPACK's
//                           dpttrs
//   BM_TridiagonalFactor/d  SymmetricFactor::factor() of the same J: the chunked LDLᵀ, the spikes
//                           and the solve's interleaved copies of e, g and 1/d
//
// bench/RESULTS.md records the numbers (issue 17: the chunk-interleaved solve).
#include <benchmark/benchmark.h>

#include <memory>

#include "fracvi/solve/symmetric_factor.hpp"

namespace {

// J = I + s K with its values filled in, not factored.
fracvi::internal::SymmetricFactor chain_matrix(Eigen::Index d) {
  const double s = 0.01 * 0.01 / 4.0;
  auto pattern = std::make_shared<fracvi::internal::SymmetricPattern>(d);
  Eigen::SparseMatrix<double> k(d, d);
  for (Eigen::Index i = 0; i < d; ++i) {
    k.insert(i, i) = 2.0;
    if (i + 1 < d) k.insert(i, i + 1) = k.insert(i + 1, i) = -1.0;
  }
  pattern->add(fracvi::ModelMatrix(k));
  pattern->finalize();
  fracvi::internal::SymmetricFactor factor(pattern, fracvi::LinearSolver::kBanded);
  std::span<double> values = factor.values();
  for (Eigen::Index i = 0; i < d; ++i) {
    values[pattern->index_of(i, i)] = 1.0 + 2.0 * s;
    if (i + 1 < d) values[pattern->index_of(i, i + 1)] = -s;
  }
  return factor;
}

void BM_TridiagonalSolve(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  fracvi::internal::SymmetricFactor factor = chain_matrix(d);
  if (!factor.factor()) state.SkipWithError("not positive definite");
  // J⁻¹ has eigenvalues in [1/(1 + 4s), 1]: x stays far from the denormals over the iterations.
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(d, 1.0, 2.0);
  for (auto _ : state) {
    factor.solve_in_place(x);
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * d);
}

void BM_TridiagonalFactor(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  fracvi::internal::SymmetricFactor factor = chain_matrix(d);
  for (auto _ : state) {
    if (!factor.factor()) state.SkipWithError("not positive definite");
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * d);
}

}  // namespace

BENCHMARK(BM_TridiagonalSolve)->Arg(511)->Arg(512)->Arg(1000)->Arg(4000)->Arg(10000);
BENCHMARK(BM_TridiagonalFactor)->Arg(1000)->Arg(10000);

BENCHMARK_MAIN();
