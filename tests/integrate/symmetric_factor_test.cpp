// The banded (LAPACK) and sparse (Eigen LDLᵀ) factorisations of a step's Newton matrix, against a
// dense LU of the same matrix; the automatic choice; the LU fallback for indefinite matrices.
#include "fracvi/solve/symmetric_factor.hpp"

#include <gtest/gtest.h>
#include <lapacke.h>

#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>

namespace fracvi::internal {
namespace {

// A pattern from the non-zeros of a dense symmetric matrix, and the factor filled with its values.
struct Filled {
  std::shared_ptr<SymmetricPattern> pattern;
  std::unique_ptr<SymmetricFactor> factor;
};

std::shared_ptr<SymmetricPattern> pattern_of(const Eigen::MatrixXd& a) {
  auto p = std::make_shared<SymmetricPattern>(a.rows());
  p->add(ModelMatrix(Eigen::SparseMatrix<double>(a.sparseView())));
  p->finalize();
  return p;
}

Filled filled(const Eigen::MatrixXd& a, LinearSolver solver) {
  Filled f{pattern_of(a), nullptr};
  f.factor = std::make_unique<SymmetricFactor>(f.pattern, solver);
  std::span<double> v = f.factor->values();
  for (std::size_t e = 0; e < f.pattern->size(); ++e) {
    const auto& entry = f.pattern->entries()[e];
    v[e] = a(entry.row, entry.col);
  }
  return f;
}

// Symmetric banded matrix of bandwidth b with a diagonal shift (shift large: positive definite).
Eigen::MatrixXd banded(Eigen::Index d, Eigen::Index b, double shift, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(d, d);
  for (Eigen::Index j = 0; j < d; ++j) {
    for (Eigen::Index i = std::max<Eigen::Index>(0, j - b); i < j; ++i) a(i, j) = a(j, i) = u(rng);
    a(j, j) = shift + u(rng);
  }
  return a;
}

double solve_error(SymmetricFactor& f, const Eigen::MatrixXd& a, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n;
  Eigen::VectorXd rhs(a.rows());
  for (auto& r : rhs) r = n(rng);
  const Eigen::VectorXd reference = a.partialPivLu().solve(rhs);
  Eigen::VectorXd x = rhs;
  f.solve_in_place(x);
  return (x - reference).cwiseAbs().maxCoeff() / reference.cwiseAbs().maxCoeff();
}

TEST(SymmetricFactor, BandedCholeskyMatchesDenseLu) {
  for (const Eigen::Index b : {0, 1, 3, 10}) {
    const Eigen::MatrixXd a = banded(300, b, 2.0 * static_cast<double>(b) + 2.0, 7u);
    Filled f = filled(a, LinearSolver::kBanded);
    EXPECT_EQ(f.pattern->bandwidth(), b);
    ASSERT_TRUE(f.factor->factor());
    EXPECT_LE(solve_error(*f.factor, a, 3u), 1e-13) << "bandwidth " << b;
  }
}

// Tridiagonal matrices from 512 rows on are solved in 16 chunks side by side, each corrected by a
// multiple of its neighbour's boundary value (symmetric_factor.cpp), when every off-diagonal of the
// LDLᵀ factor is at most 1/2 in size; otherwise by LAPACK's dpttrs. Both must give the dense LU's
// solution: the chain's weak coupling (spikes that underflow after a few elements), couplings
// whose spikes run over whole chunks, one whose factor's |e| ≈ 0.65 > 1/2 (LAPACK), sizes that
// leave the last chunk longer, and the smallest chunked size.
TEST(SymmetricFactor, ChunkedTridiagonalSolveMatchesDenseLu) {
  for (const Eigen::Index d : {511, 512, 1000, 1023, 2049}) {
    for (const double coupling : {2.5e-5, 0.3, 0.45, 10.0}) {
      Eigen::MatrixXd a = Eigen::MatrixXd::Zero(d, d);
      std::mt19937 rng(static_cast<unsigned>(d));
      std::uniform_real_distribution<double> u(0.5, 1.0);
      for (Eigen::Index i = 0; i < d; ++i) a(i, i) = 1.0 + 2.0 * coupling;
      for (Eigen::Index i = 0; i + 1 < d; ++i) a(i, i + 1) = a(i + 1, i) = -coupling * u(rng);
      Filled f = filled(a, LinearSolver::kBanded);
      ASSERT_TRUE(f.factor->factor());
      // Eigenvalues in [1, 1 + 4·coupling] (Gershgorin): a few ulps × the condition number.
      EXPECT_LE(solve_error(*f.factor, a, 9u), 1e-14 * (1.0 + 4.0 * coupling))
          << "d " << d << ", coupling " << coupling;
    }
  }
}

// The chunked solve, written out as plainly as it was before it ran the chunks as SIMD lanes
// (symmetric_factor.cpp): the recurrences chunk by chunk, then the spikes' corrections. The lanes
// must give its numbers bit for bit (each element gets the same operations in the same order).
std::vector<double> sequential_chunked_solve(const std::vector<double>& d,
                                             const std::vector<double>& l, std::vector<double> x) {
  constexpr std::size_t kChunks = 16;
  const std::size_t n = x.size(), c = n / kChunks;
  // The spikes g (forward, chunks 1 … 15) and h (backward, chunks 0 … 14), to where they underflow.
  std::vector<double> g(n, 0.0), h(n, 0.0);
  std::vector<std::size_t> g_reach(kChunks, 0), h_reach(kChunks, 0);
  for (std::size_t p = 1; p < kChunks; ++p) {
    double v = 1.0;
    for (std::size_t i = p * c; i < (p + 1 < kChunks ? (p + 1) * c : n); ++i, ++g_reach[p]) {
      v = v * -l[i - 1];
      if (std::abs(v) < DBL_MIN) break;
      g[i] = v;
    }
  }
  for (std::size_t p = 0; p + 1 < kChunks; ++p) {
    double v = 1.0;
    for (std::size_t i = (p + 1) * c; i-- > p * c; ++h_reach[p]) {
      v = v * -l[i];
      if (std::abs(v) < DBL_MIN) break;
      h[i] = v;
    }
  }
  for (std::size_t p = 0; p < kChunks; ++p) {
    for (std::size_t i = p * c + 1; i < (p + 1 < kChunks ? (p + 1) * c : n); ++i) {
      x[i] = x[i] - l[i - 1] * x[i - 1];
    }
  }
  for (std::size_t p = 1; p < kChunks; ++p) {
    const double before = x[p * c - 1];
    for (std::size_t i = p * c; i < p * c + g_reach[p]; ++i) x[i] = x[i] + g[i] * before;
  }
  for (std::size_t i = 0; i < n; ++i) x[i] = x[i] * (1.0 / d[i]);
  for (std::size_t p = kChunks; p-- > 0;) {
    // Each chunk from carry 0 at its end, but the last chunk's last row, which is final.
    std::size_t i = p + 1 < kChunks ? (p + 1) * c : n - 1;
    double carry = p + 1 < kChunks ? 0.0 : x[n - 1];
    while (i-- > p * c) {
      x[i] = x[i] - l[i] * carry;
      carry = x[i];
    }
  }
  for (std::size_t p = kChunks - 1; p-- > 0;) {
    const double after = x[(p + 1) * c];
    for (std::size_t i = (p + 1) * c - h_reach[p]; i < (p + 1) * c; ++i) x[i] = x[i] + h[i] * after;
  }
  return x;
}

// Couplings whose spikes reach over whole chunks, a few rows, one row, and sizes that leave the
// last chunk longer; right-hand sides with signed zeros (a correction by a spike's exact zero
// would turn −0 into +0) and magnitudes over 600 decades.
TEST(SymmetricFactor, ChunkedTridiagonalSolveIsTheSequentialOneBitForBit) {
  for (const std::size_t n : {512u, 517u, 1000u, 1023u, 2049u}) {
    for (const double coupling : {2.5e-5, 0.3, 1e-40, 1e-200}) {
      const auto m = static_cast<Eigen::Index>(n);
      Eigen::MatrixXd a = Eigen::MatrixXd::Zero(m, m);
      std::mt19937 rng(static_cast<unsigned>(n + 3));
      std::uniform_real_distribution<double> u(0.5, 1.0);
      for (Eigen::Index i = 0; i < m; ++i) a(i, i) = 1.0 + 2.0 * coupling * u(rng) + u(rng);
      for (Eigen::Index i = 0; i + 1 < m; ++i) a(i, i + 1) = a(i + 1, i) = -coupling * u(rng);
      Filled f = filled(a, LinearSolver::kBanded);
      ASSERT_TRUE(f.factor->factor());
      std::vector<double> diag(n), off(n, 0.0), d(n), l(n, 0.0);
      for (std::size_t i = 0; i < n; ++i)
        diag[i] = a(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i));
      for (std::size_t i = 0; i + 1 < n; ++i)
        off[i] = a(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i + 1));
      ASSERT_TRUE(tridiagonal_ldlt(n, diag.data(), off.data(), d.data(), l.data()));
      std::normal_distribution<double> normal;
      std::uniform_int_distribution<int> decade(-300, 300);
      Eigen::VectorXd x(m);
      for (auto& r : x) r = normal(rng) * std::pow(10.0, decade(rng));
      for (std::size_t i = 0; i < n; i += 37) x(static_cast<Eigen::Index>(i)) = i % 2 ? 0.0 : -0.0;
      const std::vector<double> reference =
          sequential_chunked_solve(d, l, std::vector<double>(x.data(), x.data() + m));
      f.factor->solve_in_place(x);
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(x(static_cast<Eigen::Index>(i))),
                  std::bit_cast<std::uint64_t>(reference[i]))
            << "n " << n << ", coupling " << coupling << ", row " << i;
      }
    }
  }
}

// The chunked LDLᵀ factorisation (tridiagonal_ldlt) gives LAPACK's dpttrf's numbers bit for bit,
// and its factor solves the system as a dense LU does: random symmetric positive definite
// tridiagonal matrices of sizes below, at and above the chunked sizes (not multiples of 16, tiny),
// with the chain's weak coupling, moderate coupling, diagonally dominant strong coupling, and the
// 1-D Laplacian with a small shift (|l| → 1: a wrong chunk start is forgotten slowly, the re-runs
// are long).
TEST(SymmetricFactor, ChunkedTridiagonalLdltIsDpttrf) {
  for (const std::size_t n :
       {1u, 2u, 3u, 15u, 16u, 17u, 31u, 32u, 33u, 47u, 100u, 511u, 512u, 1000u, 1023u, 2049u}) {
    for (const double coupling : {2.5e-5, 0.3, 10.0, -1.0}) {  // −1: the shifted Laplacian
      std::mt19937 rng(static_cast<unsigned>(n * 7 + 1));
      std::uniform_real_distribution<double> u(0.5, 1.0);
      std::vector<double> a(n), e(n, 0.0);
      for (std::size_t i = 0; i + 1 < n; ++i) e[i] = coupling < 0.0 ? -1.0 : -coupling * u(rng);
      for (std::size_t i = 0; i < n; ++i) {
        a[i] = coupling < 0.0 ? 2.0 + 1e-3 : 1.0 + 2.0 * coupling * u(rng) + u(rng);
      }
      if (coupling > 0.0) {  // diagonally dominant: positive definite
        for (std::size_t i = 0; i < n; ++i) {
          a[i] += std::abs(i > 0 ? e[i - 1] : 0.0) + std::abs(i + 1 < n ? e[i] : 0.0);
        }
      }
      std::vector<double> d(n), l(n, 0.0), lapack_d = a, lapack_l = e;
      ASSERT_TRUE(tridiagonal_ldlt(n, a.data(), e.data(), d.data(), l.data()));
      ASSERT_EQ(LAPACKE_dpttrf_work(static_cast<lapack_int>(n), lapack_d.data(), lapack_l.data()),
                0);
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(d[i]), std::bit_cast<std::uint64_t>(lapack_d[i]))
            << "n " << n << ", coupling " << coupling << ", d_" << i;
        if (i + 1 < n) {
          ASSERT_EQ(std::bit_cast<std::uint64_t>(l[i]), std::bit_cast<std::uint64_t>(lapack_l[i]))
              << "n " << n << ", coupling " << coupling << ", l_" << i;
        }
      }
      // L D Lᵀ x = b by the two recurrences, against the dense LU of A.
      const auto m = static_cast<Eigen::Index>(n);
      Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(m, m);
      for (Eigen::Index i = 0; i < m; ++i) dense(i, i) = a[static_cast<std::size_t>(i)];
      for (Eigen::Index i = 0; i + 1 < m; ++i) {
        dense(i, i + 1) = dense(i + 1, i) = e[static_cast<std::size_t>(i)];
      }
      std::normal_distribution<double> normal;
      Eigen::VectorXd rhs(m);
      for (auto& r : rhs) r = normal(rng);
      Eigen::VectorXd x = rhs;
      for (Eigen::Index i = 1; i < m; ++i) x(i) -= l[static_cast<std::size_t>(i - 1)] * x(i - 1);
      for (Eigen::Index i = 0; i < m; ++i) x(i) /= d[static_cast<std::size_t>(i)];
      for (Eigen::Index i = m - 1; i-- > 0;) x(i) -= l[static_cast<std::size_t>(i)] * x(i + 1);
      const Eigen::VectorXd reference = dense.partialPivLu().solve(rhs);
      // A few ulps × the condition number: ≤ 1 + 4·coupling (Gershgorin, ≥ 1 the smallest
      // eigenvalue) for the dominant ones, ≈ 4/(1e−3 + (π/(n+1))²) ≤ 4000 for the Laplacian.
      const double condition = coupling < 0.0 ? 4e3 : 1.0 + 4.0 * coupling;
      EXPECT_LE((x - reference).cwiseAbs().maxCoeff() / reference.cwiseAbs().maxCoeff(),
                1e-14 * condition)
          << "n " << n << ", coupling " << coupling;
    }
  }
}

// A pivot that is not positive is reported as by dpttrf wherever it is: in the first chunk, in a
// later chunk (whose speculative start, a_s, is positive) and in the last row.
TEST(SymmetricFactor, ChunkedTridiagonalLdltReportsNonPositivePivot) {
  for (const std::size_t n : {3u, 40u, 1000u}) {
    for (const std::size_t bad : {std::size_t{1}, n / 2 + 1, n - 1}) {
      std::vector<double> a(n, 3.0), e(n, -1.0), d(n), l(n);
      a[bad] = 0.2;  // d_bad = 0.2 − 1/d_{bad−1} < 0 (d_{bad−1} ≈ 2.6)
      EXPECT_FALSE(tridiagonal_ldlt(n, a.data(), e.data(), d.data(), l.data()))
          << "n " << n << ", row " << bad;
      std::vector<double> lapack_d = a, lapack_l = e;
      EXPECT_EQ(LAPACKE_dpttrf_work(static_cast<lapack_int>(n), lapack_d.data(), lapack_l.data()),
                static_cast<lapack_int>(bad + 1));
    }
  }
}

// J = M + (h²/4)∇²U is indefinite when U is concave enough and h large: Cholesky fails, the band
// LU with pivoting takes over.
// (Bandwidth 1 has its own LAPACK routines, dpttrf and dgttrf; bandwidth 0 divides.)
TEST(SymmetricFactor, IndefiniteBandedFallsBackToLu) {
  for (const Eigen::Index b : {0, 1, 2}) {
    const Eigen::MatrixXd a = banded(200, b, 0.0, 11u);
    ASSERT_LT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(a).eigenvalues().minCoeff(), 0.0);
    Filled f = filled(a, LinearSolver::kBanded);
    ASSERT_TRUE(f.factor->factor());
    EXPECT_LE(solve_error(*f.factor, a, 5u), 1e-10) << "bandwidth " << b;
  }
}

TEST(SymmetricFactor, SingularMatrixIsReported) {
  for (const Eigen::Index b : {0, 1, 3}) {
    Eigen::MatrixXd a = banded(50, b, 8.0, 2u);
    a.row(10).setZero();
    a.col(10).setZero();
    for (const LinearSolver s : {LinearSolver::kBanded, LinearSolver::kSparse}) {
      Filled f = filled(a, s);
      EXPECT_FALSE(f.factor->factor()) << to_string(s) << ", bandwidth " << b;
    }
  }
}

// A periodic chain: tridiagonal plus the corners, bandwidth d − 1 — the sparse LDLᵀ's case.
TEST(SymmetricFactor, SparseLdltSolvesPeriodicChain) {
  constexpr Eigen::Index kD = 400;
  Eigen::MatrixXd a = banded(kD, 1, 3.0, 13u);
  a(0, kD - 1) = a(kD - 1, 0) = -0.9;
  Filled f = filled(a, LinearSolver::kSparse);
  ASSERT_TRUE(f.factor->factor());
  EXPECT_LE(solve_error(*f.factor, a, 17u), 1e-13);
  EXPECT_EQ(choose_factorization(*f.pattern), LinearSolver::kSparse);
  // Refactoring with new values on the same pattern (a Newton iteration) gives the new solution.
  a.diagonal().array() += 1.0;
  std::span<double> v = f.factor->values();
  for (std::size_t e = 0; e < f.pattern->size(); ++e) {
    const auto& entry = f.pattern->entries()[e];
    v[e] = a(entry.row, entry.col);
  }
  ASSERT_TRUE(f.factor->factor());
  EXPECT_LE(solve_error(*f.factor, a, 19u), 1e-13);
}

TEST(SymmetricFactor, AutomaticChoiceFollowsTheStructure) {
  EXPECT_EQ(choose_factorization(*pattern_of(banded(1000, 1, 3.0, 1u))), LinearSolver::kBanded);
  EXPECT_EQ(choose_factorization(*pattern_of(banded(1000, kMaxAutoBandwidth, 3.0, 1u))),
            LinearSolver::kBanded);
  EXPECT_EQ(choose_factorization(*pattern_of(banded(1000, kMaxAutoBandwidth + 1, 3.0, 1u))),
            LinearSolver::kSparse);
  EXPECT_EQ(choose_factorization(*pattern_of(banded(40, 30, 3.0, 1u))), LinearSolver::kDense);
  EXPECT_EQ(choose_factorization(*pattern_of(banded(4, 1, 3.0, 1u))), LinearSolver::kDense);
}

TEST(SymmetricFactor, PatternIndexAndErrors) {
  SymmetricPattern p(5);
  p.add(ModelMatrix::identity(5, 2.0));
  p.finalize();
  EXPECT_EQ(p.size(), 5u);
  EXPECT_EQ(p.index_of(3, 3), 3u);
  EXPECT_THROW(static_cast<void>(p.index_of(1, 2)), std::out_of_range);
  EXPECT_THROW(SymmetricFactor(std::make_shared<SymmetricPattern>(p), LinearSolver::kDense),
               std::invalid_argument);
  EXPECT_EQ(parse_linear_solver("banded"), LinearSolver::kBanded);
  EXPECT_FALSE(parse_linear_solver("cholesky").has_value());
}

}  // namespace
}  // namespace fracvi::internal
