// Runge–Kutta convolution-quadrature block weights with Lobatto IIIC (docs/theory/rkcq_weights.md).
#include "fracvi/fractional/runge_kutta_cq.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <tuple>
#include <unsupported/Eigen/FFT>
#include <unsupported/Eigen/MatrixFunctions>
#include <utility>
#include <vector>

namespace fracvi {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

struct Reference {
  int stages;
  double order;
  long long lag;
  int row;
  int col;
  double value;
};

// 50-digit values from tests/fractional/rkcq_reference.py (independent of the library's method:
// Cauchy integrals on |ζ| = 2/5 and Dunford–Taylor integrals on hyperbolas, in mpmath).
const std::vector<Reference>& references() {
  static const std::vector<Reference> table = {
#include "rkcq_reference_data.inc"
  };
  return table;
}

Eigen::MatrixXd delta_by_definition(int s, double zeta) {
  const ButcherTableau& t = lobatto_iiic(s);
  const Eigen::MatrixXd ones_bt = Eigen::VectorXd::Ones(s) * t.b.transpose();
  return (t.a + zeta / (1.0 - zeta) * ones_bt).inverse();
}

// m^β by a complex eigendecomposition in long double (m diagonalisable, spectrum in Re λ > 0).
Eigen::MatrixXd eigen_power(const Eigen::MatrixXd& m, double beta) {
  using MatrixXcld = Eigen::Matrix<std::complex<long double>, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::ComplexEigenSolver<MatrixXcld> eig(m.cast<std::complex<long double>>());
  const auto lambda = eig.eigenvalues();
  MatrixXcld d = MatrixXcld::Zero(m.rows(), m.cols());
  for (Eigen::Index i = 0; i < m.rows(); ++i) d(i, i) = std::pow(lambda(i), (long double)beta);
  const MatrixXcld p = eig.eigenvectors() * d * eig.eigenvectors().inverse();
  return p.real().cast<double>();
}

double max_abs(const Eigen::MatrixXd& m) {
  return m.cwiseAbs().maxCoeff();
}

TEST(LobattoIIIC, TableauSatisfiesItsDefiningConditions) {
  for (int s = 2; s <= 4; ++s) {
    const ButcherTableau& t = lobatto_iiic(s);
    ASSERT_EQ(t.stages(), s);
    EXPECT_EQ(t.order, 2 * s - 2);
    // c = A𝟙, stiffly accurate (last row = b), first column = b_1 𝟙, c_1 = 0, c_s = 1.
    EXPECT_LT((t.a * Eigen::VectorXd::Ones(s) - t.c).cwiseAbs().maxCoeff(), 4 * kEps);
    EXPECT_LT((t.a.row(s - 1).transpose() - t.b).cwiseAbs().maxCoeff(), 4 * kEps);
    EXPECT_LT((t.a.col(0) - t.b(0) * Eigen::VectorXd::Ones(s)).cwiseAbs().maxCoeff(), 4 * kEps);
    EXPECT_EQ(t.c(0), 0.0);
    EXPECT_EQ(t.c(s - 1), 1.0);
    // B(2s − 2): Σ b_i c_i^{k−1} = 1/k; C(s − 1): Σ_j a_ij c_j^{k−1} = c_i^k / k.
    for (int k = 1; k <= 2 * s - 2; ++k) {
      EXPECT_NEAR(t.b.dot(t.c.array().pow(k - 1).matrix()), 1.0 / k, 8 * kEps) << s << " " << k;
    }
    for (int k = 1; k <= s - 1; ++k) {
      const Eigen::VectorXd lhs = t.a * t.c.array().pow(k - 1).matrix();
      const Eigen::VectorXd rhs = t.c.array().pow(k) / k;
      EXPECT_LT((lhs - rhs).cwiseAbs().maxCoeff(), 8 * kEps) << s << " " << k;
    }
    // B(2s − 1) fails: the order is exactly 2s − 2.
    EXPECT_GT(std::abs(t.b.dot(t.c.array().pow(2 * s - 2).matrix()) - 1.0 / (2 * s - 1)), 1e-4);
  }
  // The integer inverses (the generating functions of the RKCQ paper's code).
  Eigen::MatrixXd inv2(2, 2), inv3(3, 3);
  inv2 << 1, 1, -1, 1;
  inv3 << 3, 4, -1, -1, 0, 1, 1, -4, 3;
  EXPECT_LT(max_abs(RungeKuttaCq{2, 1.0}.delta(0.0) - inv2), 8 * kEps);
  EXPECT_LT(max_abs(RungeKuttaCq{3, 1.0}.delta(0.0) - inv3), 32 * kEps);
  EXPECT_THROW(lobatto_iiic(5), std::invalid_argument);
  EXPECT_THROW(lobatto_iiic(1), std::invalid_argument);
}

TEST(LobattoIIIC, StabilityFunctionIsTheTableausAndThePadeApproximant) {
  for (int s = 2; s <= 4; ++s) {
    const ButcherTableau& t = lobatto_iiic(s);
    for (double z : {1e-8, 1e-3, 0.1, 0.5, 1.0, 3.0, 4.5, 10.0, 100.0}) {
      const Eigen::MatrixXd m = Eigen::MatrixXd::Identity(s, s) + z * t.a;
      const double from_tableau = m.partialPivLu().solve(Eigen::VectorXd::Ones(s))(s - 1);
      const double generic = 1.0 - z * t.b.dot(m.partialPivLu().solve(Eigen::VectorXd::Ones(s)));
      const double r = lobatto_iiic_stability(s, z);
      EXPECT_NEAR(r, from_tableau, 64 * kEps * std::max(1.0, z)) << s << " " << z;
      EXPECT_NEAR(r, generic, 64 * kEps * std::max(1.0, z)) << s << " " << z;
      EXPECT_LE(std::abs(r), 1.0);
    }
    // Order 2s − 2: r(−z) − e^{−z} = O(z^{2s−1}).
    const double z = 1e-2;
    EXPECT_LT(std::abs(lobatto_iiic_stability(s, z) - std::exp(-z)), std::pow(z, 2 * s - 1));
  }
  EXPECT_LT(lobatto_iiic_stability(3, 10.0), 0.0);  // the s = 3 decays change sign beyond z = 4
  EXPECT_GT(lobatto_iiic_stability(4, 10.0), 0.0);
}

TEST(RungeKuttaCq, DeltaIsAffineByStiffAccuracy) {
  for (int s = 2; s <= 4; ++s) {
    for (double zeta : {0.0, 0.3, -0.7, 0.9}) {
      const Eigen::MatrixXd d = RungeKuttaCq{s, 0.5}.delta(zeta);
      const Eigen::MatrixXd ref = delta_by_definition(s, zeta);
      EXPECT_LT(max_abs(d - ref), 64 * kEps * max_abs(ref)) << s << " " << zeta;
    }
  }
}

TEST(RungeKuttaCq, IntegerOrdersAreExact) {
  for (int s = 2; s <= 4; ++s) {
    const ButcherTableau& t = lobatto_iiic(s);
    const Eigen::MatrixXd a_inv = t.a.inverse();
    const Eigen::MatrixXd ones_es = Eigen::VectorXd::Ones(s) * Eigen::RowVectorXd::Unit(s, s - 1);
    const double tol = 64 * kEps * max_abs(a_inv);
    // β = 0: the identity.
    const BlockWeights w0 = RungeKuttaCq{s, 0.0}.weights(5);
    EXPECT_EQ(Eigen::MatrixXd(w0[0]), Eigen::MatrixXd::Identity(s, s));
    for (std::size_t j = 1; j < 5; ++j) EXPECT_EQ(max_abs(w0[j]), 0.0);
    // β = 1: W_0 = A^{−1}, W_1 = −A^{−1}𝟙e_sᵀ, nothing beyond.
    const BlockWeights w1 = RungeKuttaCq{s, 1.0}.weights(6);
    EXPECT_LT(max_abs(w1[0] - a_inv), tol);
    EXPECT_LT(max_abs(w1[1] + a_inv * ones_es), tol);
    for (std::size_t j = 2; j < 6; ++j) EXPECT_EQ(max_abs(w1[j]), 0.0);
    // β = 2: the square of Δ(ζ) = W_0 + ζ W_1.
    const BlockWeights w2 = RungeKuttaCq{s, 2.0}.weights(6);
    EXPECT_LT(max_abs(w2[0] - a_inv * a_inv), tol * max_abs(a_inv));
    EXPECT_LT(max_abs(w2[1] + a_inv * a_inv * ones_es + a_inv * ones_es * a_inv),
              tol * max_abs(a_inv));
    for (std::size_t j = 2; j < 6; ++j) EXPECT_EQ(max_abs(w2[j]), 0.0);
    // Single lags agree, far lags are zero.
    EXPECT_EQ(max_abs(RungeKuttaCq{s, 1.0}.weight(1) - w1[1]), 0.0);
    EXPECT_EQ(max_abs(RungeKuttaCq{s, 2.0}.weight(10000000)), 0.0);
    EXPECT_TRUE((RungeKuttaCq{s, 2.0}.is_local()));
    EXPECT_FALSE((RungeKuttaCq{s, 1.5}.is_local()));
  }
}

TEST(RungeKuttaCq, WeightsMatchTheHighPrecisionReferences) {
  // Entrywise relative error, except for entries below 1e-3 max|W_j| (they arise only from
  // cancellation in small lags), which are held to 1e-15 max|W_j|·1e2 = 1e-13 max|W_j| as well.
  struct Key {
    int s;
    double order;
    long long lag;
    bool operator<(const Key& o) const {
      return std::tie(s, order, lag) < std::tie(o.s, o.order, o.lag);
    }
  };
  std::map<Key, std::vector<const Reference*>> blocks;
  for (const Reference& r : references()) blocks[{r.stages, r.order, r.lag}].push_back(&r);
  ASSERT_GT(blocks.size(), 100U);
  std::map<std::pair<int, double>, std::map<long long, std::pair<double, double>>> table;
  double worst_entry = 0.0, worst_norm = 0.0;
  for (const auto& [key, entries] : blocks) {
    const RungeKuttaCq cq{key.s, key.order};
    const Eigen::MatrixXd w = cq.weight(static_cast<std::size_t>(key.lag));
    double scale = 0.0;
    for (const Reference* r : entries) scale = std::max(scale, std::abs(r->value));
    double entry_error = 0.0, norm_error = 0.0;
    for (const Reference* r : entries) {
      const double err = std::abs(w(r->row, r->col) - r->value);
      norm_error = std::max(norm_error, err / scale);
      const double denominator = std::max(std::abs(r->value), 1e-3 * scale);
      entry_error = std::max(entry_error, err / denominator);
    }
    table[{key.s, key.order}][key.lag] = {entry_error, norm_error};
    worst_entry = std::max(worst_entry, entry_error);
    worst_norm = std::max(worst_norm, norm_error);
    EXPECT_LT(entry_error, 1e-13) << "s=" << key.s << " beta=" << key.order << " lag=" << key.lag;
  }
  // The measured table (docs/theory/rkcq_weights.md).
  for (const auto& [sb, lags] : table) {
    std::printf("s=%d beta=%-5g", sb.first, sb.second);
    for (const auto& [lag, e] : lags) std::printf(" %lld:%.1e", lag, e.first);
    std::printf("\n");
  }
  std::printf("worst entrywise %.2e, worst normwise %.2e\n", worst_entry, worst_norm);
}

TEST(RungeKuttaCq, GeneratingFunctionSumRule) {
  // Σ_j W_j ζ^j = Δ(ζ)^β inside the unit disc (the series converges like |ζ|^j): Δ(ζ)^β by an
  // eigendecomposition in extended precision, independent of the weights' quadrature.
  for (int s = 2; s <= 4; ++s) {
    for (double beta : {1e-3, 0.3, 0.7, 0.999, 1.001, 1.5, 1.9, 1.999}) {
      const RungeKuttaCq cq{s, beta};
      const BlockWeights w = cq.weights(120);
      for (double zeta : {0.3, -0.6}) {
        Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(s, s);
        double zj = 1.0;
        for (std::size_t j = 0; j < w.size(); ++j, zj *= zeta) sum += zj * w[j];
        const Eigen::MatrixXd ref = eigen_power(delta_by_definition(s, zeta), beta);
        EXPECT_LT(max_abs(sum - ref), 1e-14 * max_abs(ref))
            << "s=" << s << " beta=" << beta << " zeta=" << zeta;
      }
    }
  }
}

TEST(RungeKuttaCq, OrdersAddUnderConvolution) {
  // Δ^{β1} Δ^{β2} = Δ^{β1+β2}: the block convolution of two weight sequences is the weight
  // sequence of the sum of the orders, exactly the integer one when the sum is 1 or 2.
  for (int s = 2; s <= 4; ++s) {
    for (const auto& [b1, b2] :
         {std::pair{0.5, 0.5}, std::pair{0.3, 0.7}, std::pair{0.75, 1.25}, std::pair{0.2, 1.3}}) {
      const std::size_t n = 200;
      const BlockWeights w1 = RungeKuttaCq{s, b1}.weights(n);
      const BlockWeights w2 = RungeKuttaCq{s, b2}.weights(n);
      const BlockWeights w = RungeKuttaCq{s, b1 + b2}.weights(n);
      double worst = 0.0;
      for (std::size_t j = 0; j < n; ++j) {
        Eigen::MatrixXd conv = Eigen::MatrixXd::Zero(s, s);
        double magnitude = 0.0;
        for (std::size_t m = 0; m <= j; ++m) {
          conv += w1[m] * w2[j - m];
          magnitude = std::max(magnitude, max_abs(w1[m] * w2[j - m]));
        }
        // Round-off of the sum of j + 1 products of size `magnitude`.
        worst = std::max(worst, max_abs(conv - w[j]) / magnitude);
      }
      EXPECT_LT(worst, 2e-14) << "s=" << s << " " << b1 << "+" << b2;
    }
  }
}

TEST(RungeKuttaCq, SingleLagsAgreeWithTheSequenceAndTheAsymptotics) {
  for (int s = 2; s <= 4; ++s) {
    for (double beta : {0.1, 0.5, 1.1, 1.95}) {
      const RungeKuttaCq cq{s, beta};
      const BlockWeights w = cq.weights(3000);
      for (std::size_t j : {0UL, 1UL, 2UL, 3UL, 7UL, 50UL, 999UL, 2999UL}) {
        const Eigen::MatrixXd single = cq.weight(j);
        EXPECT_LT(max_abs(single - w[j]), 1e-14 * max_abs(single)) << s << " " << beta << " " << j;
      }
      // W_j ~ j^{−1−β}/Γ(−β) 𝟙bᵀ (1 + O(1/j)).
      const std::size_t j = 10000000;
      const Eigen::MatrixXd lead = std::pow(static_cast<double>(j), -1.0 - beta) /
                                   std::tgamma(-beta) * Eigen::VectorXd::Ones(s) *
                                   lobatto_iiic(s).b.transpose();
      EXPECT_LT(max_abs(cq.weight(j) - lead), 1e-5 * max_abs(lead)) << s << " " << beta;
    }
  }
}

TEST(RungeKuttaCq, StiffAccuracyRowRelation) {
  // bᵀΔ(ζ) = (1 − ζ) e_sᵀ (stiff accuracy: e_sᵀA = bᵀ, and Δ(ζ)^{−1} = A + ζ/(1 − ζ)𝟙bᵀ), so
  // bᵀ W_j^{(β)} = e_sᵀ (W_j^{(β−1)} − W_{j−1}^{(β−1)}) for 1 ≤ β ≤ 2: the b-weighted rows of one
  // order are the backward difference of the last-stage rows of the order below.
  for (int s = 2; s <= 4; ++s) {
    const Eigen::VectorXd b = lobatto_iiic(s).b;
    for (double beta : {1.0, 1.3, 1.5, 1.9, 2.0}) {
      const std::size_t n = 2000;
      const BlockWeights w = RungeKuttaCq{s, beta}.weights(n);
      const BlockWeights v = RungeKuttaCq{s, beta - 1.0}.weights(n);
      for (std::size_t j = 0; j < n; ++j) {
        const Eigen::RowVectorXd lhs = b.transpose() * w[j];
        Eigen::RowVectorXd rhs = v[j].row(s - 1);
        double scale = max_abs(v[j]);
        if (j > 0) {
          rhs -= v[j - 1].row(s - 1);
          scale = std::max(scale, max_abs(v[j - 1]));
        }
        // The difference cancels: its error is that of W^{(β−1)}, relative to their size.
        ASSERT_LE((lhs - rhs).cwiseAbs().maxCoeff(), 1e-14 * scale)
            << "s=" << s << " beta=" << beta << " j=" << j;
      }
    }
  }
}

TEST(RungeKuttaCq, RejectsBadInput) {
  EXPECT_THROW((RungeKuttaCq{5, 0.5}.weights(3)), std::invalid_argument);
  EXPECT_THROW((RungeKuttaCq{2, -0.5}.weight(3)), std::invalid_argument);
  EXPECT_THROW((RungeKuttaCq{2, 2.5}.weight(3)), std::invalid_argument);
  EXPECT_THROW((RungeKuttaCq{2, std::nan("")}.weight(3)), std::invalid_argument);
  EXPECT_EQ((RungeKuttaCq{3, 1.5}.describe()), "Lobatto IIIC (s = 3) RKCQ of order 1.5");
}

void fft_contour_errors(std::size_t n);

// The contour-integral + FFT evaluation of the RKCQ paper's code (convw_rk.jl): samples of
// Δ(ζ)^β on |ζ| = λ, λ = (1e-15)^{1/(2 N_fft)}, N_fft = 2^{⌈log2 3N⌉}, an FFT, and λ^{−j}. Its
// error against the 50-digit references, next to the library's, for the record (the numbers are
// in docs/theory/rkcq_weights.md); the test asserts only that the library is the accurate one.
TEST(RungeKuttaCq, FftContourEvaluationLosesDigits) {
  for (const std::size_t n : {1000UL, 10000UL}) {
    fft_contour_errors(n);
  }
}

void fft_contour_errors(std::size_t n) {
  std::size_t n_fft = 1;
  while (n_fft < 3 * n) n_fft *= 2;
  const double radius = std::pow(1e-15, 1.0 / (2.0 * static_cast<double>(n_fft)));
  std::map<std::tuple<int, double, long long>, Eigen::MatrixXd> refs;
  for (const Reference& r : references()) {
    auto& m = refs[{r.stages, r.order, r.lag}];
    if (m.size() == 0) m = Eigen::MatrixXd::Zero(r.stages, r.stages);
    m(r.row, r.col) = r.value;
  }
  for (int s = 2; s <= 4; ++s) {
    for (double beta : {0.5, 1.5}) {
      const RungeKuttaCq cq{s, beta};
      std::vector<std::vector<std::complex<double>>> samples(
          static_cast<std::size_t>(s * s), std::vector<std::complex<double>>(n_fft));
      for (std::size_t k = 0; k < n_fft; ++k) {
        const std::complex<double> zeta = std::polar(
            radius, 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n_fft));
        Eigen::MatrixXcd d = cq.delta(0.0).cast<std::complex<double>>();
        d(0, s - 1) -= zeta / lobatto_iiic(s).b(0);
        const Eigen::ComplexEigenSolver<Eigen::MatrixXcd> eig(d);
        const Eigen::VectorXcd pw = eig.eigenvalues().array().pow(beta);
        const Eigen::MatrixXcd f =
            eig.eigenvectors() * pw.asDiagonal() * eig.eigenvectors().inverse();
        for (int e = 0; e < s * s; ++e) samples[static_cast<std::size_t>(e)][k] = f.data()[e];
      }
      Eigen::FFT<double> fft;
      std::vector<Eigen::MatrixXd> w(n + 1, Eigen::MatrixXd(s, s));
      for (int e = 0; e < s * s; ++e) {
        std::vector<std::complex<double>> out;
        fft.fwd(out, samples[static_cast<std::size_t>(e)]);
        for (std::size_t j = 0; j <= n; ++j) {
          w[j].data()[e] = (out[j] * std::pow(radius, -static_cast<double>(j))).real() /
                           static_cast<double>(n_fft);
        }
      }
      std::printf("s=%d beta=%g FFT contour (N=%zu): ", s, beta, n);
      for (long long lag : {2LL, 10LL, 100LL, 1000LL, 10000LL}) {
        if (lag > static_cast<long long>(n)) break;
        const Eigen::MatrixXd& ref = refs.at({s, beta, lag});
        const double fft_error = max_abs(w[static_cast<std::size_t>(lag)] - ref) / max_abs(ref);
        const double our_error =
            max_abs(cq.weight(static_cast<std::size_t>(lag)) - ref) / max_abs(ref);
        std::printf(" lag %lld: %.1e (library %.1e)", lag, fft_error, our_error);
        EXPECT_LT(our_error, 1e-13);
      }
      std::printf("\n");
    }
  }
}

TEST(RkcqTail, ReproducesTheWeightsToTheTolerance) {
  for (int s = 2; s <= 4; ++s) {
    for (double beta : {0.3, 1.5}) {
      for (double tol : {1e-6, 1e-10}) {
        RkcqTailOptions o;
        o.stages = s;
        o.order = beta;
        o.tolerance = tol;
        o.max_lag = 100000;
        o.window = 16;
        const RkcqTail tail = fit_rkcq_tail(o);
        const RungeKuttaCq cq{s, beta};
        const BlockWeights w = cq.weights(20001);
        double worst = 0.0;
        for (std::size_t j = 0; j < w.size(); ++j) {
          worst = std::max(worst, max_abs(tail.weight(j) - w[j]) / max_abs(w[j]));
        }
        for (std::size_t j : {30001UL, 54321UL, 99999UL, 100000UL}) {
          const Eigen::MatrixXd ref = cq.weight(j);
          worst = std::max(worst, max_abs(tail.weight(j) - ref) / max_abs(ref));
        }
        std::printf("tail s=%d beta=%g tol=%g: K=%zu (of %zu), error %.2e, %.3f s\n", s, beta, tol,
                    tail.terms(), tail.quadrature_nodes, worst, tail.seconds);
        EXPECT_LE(worst, tol) << s << " " << beta << " " << tol;
        for (std::size_t i = 0; i < tail.terms(); ++i) {
          EXPECT_LT(std::abs(tail.decays[i]), 1.0);
          EXPECT_EQ(tail.decays[i], lobatto_iiic_stability(s, tail.nodes[i]));
          const Eigen::MatrixXd c = tail.coefficient(i);
          Eigen::JacobiSVD<Eigen::MatrixXd> svd(c);
          EXPECT_LT(svd.singularValues()(1), 1e-14 * svd.singularValues()(0));  // rank one
        }
      }
    }
  }
}

TEST(RkcqTail, SmallWindowKeepsNegativeDecays) {
  // Lobatto IIIC s = 3 has r(−z) < 0 for z > 4: with window 2 those nodes matter at small lags.
  RkcqTailOptions o;
  o.stages = 3;
  o.order = 0.5;
  o.tolerance = 1e-10;
  o.max_lag = 1000;
  o.window = 2;
  o.compress = false;
  const RkcqTail tail = fit_rkcq_tail(o);
  EXPECT_TRUE(std::any_of(tail.decays.begin(), tail.decays.end(), [](double d) { return d < 0; }));
  const BlockWeights w = RungeKuttaCq{3, 0.5}.weights(1001);
  for (std::size_t j = 2; j <= 1000; ++j) {
    EXPECT_LE(max_abs(tail.weight(j) - w[j]), 1e-10 * max_abs(w[j])) << j;
  }
  EXPECT_THROW(fit_rkcq_tail({3, 1.0, 1e-10, 100, 16, true}), std::invalid_argument);
  EXPECT_THROW(fit_rkcq_tail({3, 0.5, 1e-16, 100, 16, true}), std::invalid_argument);
  EXPECT_THROW(fit_rkcq_tail({3, 0.5, 1e-10, 100, 1, true}), std::invalid_argument);
}

TEST(RungeKuttaCq, Timings) {
  for (int s : {2, 4}) {
    const RungeKuttaCq cq{s, 0.5};
    auto t0 = std::chrono::steady_clock::now();
    const BlockWeights w = cq.weights(100000);
    const double bulk =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    t0 = std::chrono::steady_clock::now();
    Eigen::MatrixXd single = cq.weight(10000000);
    const double one = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("s=%d: 1e5 weights %.3f s, W_1e7 alone %.2e s\n", s, bulk, one);
    EXPECT_EQ(w.size(), 100000U);
    EXPECT_TRUE(single.allFinite());
  }
}

}  // namespace
}  // namespace fracvi
