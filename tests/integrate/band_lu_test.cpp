// internal::BandLu (solve/band_lu.hpp): dgbtrf's factor, solved by loops over the packed factor
// (U scaled by its diagonal; registers along the band without interchanges). References: LAPACK's
// own dgbtrs on the same factor and Eigen's dense LU of the same matrix (to the condition number
// times round-off), and the backward error, on band matrices with kl ≠ ku whose pivoting
// interchanges rows and on diagonally dominant ones of the chains' bands (no interchange).
#include "fracvi/solve/band_lu.hpp"

#include <gtest/gtest.h>
#include <lapacke.h>

#include <Eigen/Dense>
#include <random>
#include <vector>

namespace fracvi::internal {
namespace {

// An n × n matrix with bandwidths kl, ku and random entries in [−1, 1]; a diagonal of `diagonal`
// plus noise: small, so that partial pivoting interchanges rows.
Eigen::MatrixXd band_matrix(Eigen::Index n, Eigen::Index kl, Eigen::Index ku, double diagonal,
                            unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = std::max<Eigen::Index>(0, j - ku); i <= std::min(n - 1, j + kl); ++i)
      a(i, j) = u(rng) + (i == j ? diagonal : 0.0);
  return a;
}

BandLu filled(const Eigen::MatrixXd& a, Eigen::Index kl, Eigen::Index ku) {
  BandLu lu(a.rows(), kl, ku);
  for (Eigen::Index j = 0; j < a.cols(); ++j)
    for (Eigen::Index i = std::max<Eigen::Index>(0, j - ku); i <= std::min(a.rows() - 1, j + kl);
         ++i)
      lu.band()[lu.offset(i, j)] = a(i, j);
  return lu;
}

struct Shape {
  Eigen::Index n, kl, ku;
  double diagonal;
};

TEST(BandLu, SolvesLikeDgbtrsAndDenseLu) {
  int interchanged = 0, unpivoted_chain_bands = 0;
  for (const Shape& shape :
       {Shape{1, 0, 0, 2.0}, Shape{7, 1, 3, 0.0}, Shape{200, 1, 3, 0.0}, Shape{200, 3, 1, 0.1},
        Shape{300, 2, 4, 0.0}, Shape{250, 5, 5, 4.0}, Shape{64, 0, 2, 3.0}, Shape{64, 2, 0, 3.0},
        Shape{300, 1, 1, 5.0}, Shape{300, 2, 2, 7.0}, Shape{300, 1, 3, 7.0}, Shape{300, 2, 4, 9.0},
        Shape{7, 2, 4, 9.0}, Shape{6, 1, 3, 9.0}, Shape{3, 1, 1, 5.0}}) {
    const Eigen::MatrixXd a = band_matrix(shape.n, shape.kl, shape.ku, shape.diagonal, 7u);
    BandLu lu = filled(a, shape.kl, shape.ku);
    const std::vector<double> band = lu.band();  // before factor() overwrites it
    ASSERT_TRUE(lu.factor()) << shape.n << " " << shape.kl << " " << shape.ku;
    EXPECT_GE(lu.factor_upper_bandwidth(), shape.ku);
    EXPECT_LE(lu.factor_upper_bandwidth(), shape.kl + shape.ku);
    if (lu.factor_upper_bandwidth() > shape.ku) ++interchanged;

    // dgbtrf + dgbtrs on a copy of the same band storage.
    std::vector<double> lapack = band;
    std::vector<lapack_int> pivots(static_cast<std::size_t>(shape.n));
    const auto n = static_cast<lapack_int>(shape.n);
    const auto kl = static_cast<lapack_int>(shape.kl), ku = static_cast<lapack_int>(shape.ku);
    ASSERT_EQ(LAPACKE_dgbtrf_work(LAPACK_COL_MAJOR, n, n, kl, ku, lapack.data(), 2 * kl + ku + 1,
                                  pivots.data()),
              0);
    const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(shape.n, -1.0, 2.0).array().sin();
    Eigen::VectorXd x = rhs, reference = rhs;
    lu.solve_in_place(x.data());
    ASSERT_EQ(LAPACKE_dgbtrs_work(LAPACK_COL_MAJOR, 'N', n, kl, ku, 1, lapack.data(),
                                  2 * kl + ku + 1, pivots.data(), reference.data(), n),
              0);
    // Backward stable: the normwise backward error ‖Ax − b‖/(‖A‖‖x‖ + ‖b‖) at round-off (random
    // band matrices with a small diagonal are ill-conditioned, so the forward error against
    // dgbtrs's and the dense LU's solutions is bounded by the condition number times that). Not
    // dgbtrs's numbers bit for bit: D⁻¹U is rounded once more, and x_j is multiplied by 1/U(j, j).
    const Eigen::VectorXd dense = a.partialPivLu().solve(rhs);
    const double backward = (a * x - rhs).norm() / (a.norm() * x.norm() + rhs.norm());
    EXPECT_LE(backward, 1e-15);
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
    const double condition = svd.singularValues()(0) / svd.singularValues().tail(1)(0);
    EXPECT_LE((x - dense).norm() / dense.norm(), 1e-15 * condition);
    EXPECT_LE((x - reference).norm() / reference.norm(), 1e-15 * condition);
    if (lu.factor_upper_bandwidth() == shape.ku && shape.kl >= 1 && shape.kl <= 2 &&
        shape.ku == shape.kl + 2) {
      ++unpivoted_chain_bands;
    }
  }
  EXPECT_GE(interchanged, 3);           // the packed U really was widened on these matrices
  EXPECT_GE(unpivoted_chain_bands, 4);  // and the register path ran: (1, 3), (2, 4), no interchange
}

// Refactoring new values in the same storage (a Newton iteration) gives the new solution: the
// packing of the previous factor (a different interchange pattern) leaves nothing behind.
TEST(BandLu, RefactorsInPlace) {
  BandLu lu(120, 2, 3);
  for (const auto& [diagonal, seed] :
       {std::pair{0.0, 1u}, std::pair{10.0, 2u}, std::pair{0.0, 3u}}) {
    const Eigen::MatrixXd a = band_matrix(120, 2, 3, diagonal, seed);
    const BandLu fresh = filled(a, 2, 3);
    lu.band() = fresh.band();  // same size: no reallocation
    ASSERT_TRUE(lu.factor());
    if (diagonal > 5.0) {
      EXPECT_EQ(lu.factor_upper_bandwidth(), 3);  // diagonally dominant: no interchange
    }
    const Eigen::VectorXd rhs = Eigen::VectorXd::Ones(120);
    Eigen::VectorXd x = rhs;
    lu.solve_in_place(x.data());
    EXPECT_LE((a * x - rhs).norm() / (a.norm() * x.norm() + rhs.norm()), 1e-15) << "seed " << seed;
  }
}

TEST(BandLu, SingularMatrixIsReported) {
  Eigen::MatrixXd a = band_matrix(50, 2, 1, 3.0, 5u);
  a.col(20).setZero();
  BandLu lu = filled(a, 2, 1);
  EXPECT_FALSE(lu.factor());
}

TEST(BandLu, StorageSize) {
  EXPECT_DOUBLE_EQ(BandLu::storage_bytes(1000, 3, 5), 8.0 * (2 * 3 + 5 + 1) * 1000);
  EXPECT_EQ(BandLu(1000, 3, 5).band().size(), std::size_t{12000});
}

}  // namespace
}  // namespace fracvi::internal
