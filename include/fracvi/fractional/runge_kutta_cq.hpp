// Runge–Kutta convolution quadrature (Lubich & Ostermann 1993) with the Lobatto IIIC methods:
// the s × s block weights of s^β as a value (docs/theory/rkcq_weights.md).
//
// For an s-stage Runge–Kutta method (A, b, c) the stage vector of the discrete operator at step n,
// acting on the stage values g_m = (g(t_m + c_i h))_{i=1..s}, is
//
//     (K(∂_t^h) g)_n = Σ_{j=0}^{n} K_j g_{n−j},   Σ_j K_j ζ^j = K(Δ(ζ)/h),
//     Δ(ζ) = (A + ζ/(1 − ζ) 𝟙bᵀ)^{−1}.
//
// For K(s) = s^β, K_j = h^{−β} W_j with W_j the Taylor coefficients of Δ(ζ)^β (independent of h).
// Lobatto IIIC is stiffly accurate (bᵀ = e_sᵀA) and its first column is b_1 𝟙 (Ae_1 = b_1 𝟙), so
//
//     Δ(ζ) = A^{−1}(I − ζ 𝟙e_sᵀ) = A^{−1} − (ζ/b_1) e_1 e_sᵀ         (affine in ζ).
//
// Integer β: W_j = 0 beyond j = β, W_0 = A^{−β}, and for β = 1, W_1 = −A^{−1}𝟙e_sᵀ; for β = 2,
// W_1 = −(A^{−1}A^{−1}𝟙e_sᵀ + A^{−1}𝟙e_sᵀA^{−1}) and W_2 = 0 (e_sᵀA^{−1}𝟙 = e_sᵀe_1/b_1 = 0).
//
// Non-integer 0 < β < 2 and j ≥ 2 (the real-axis, or Stieltjes, representation of s^β; derivation
// in the theory note):
//
//     W_j = −(sin πβ/π) ∫_0^∞ z^β r(−z)^{j−1} u(z) v(z)ᵀ dz,
//     u(z) = (I + zA)^{−1}𝟙,  v(z)ᵀ = bᵀ(I + zA)^{−1},  r(−z) = e_sᵀ u(z) (stability function),
//
// evaluated by the trapezoidal rule in x = ln z (geometric convergence, like the scalar fit in
// exponential_fit.hpp) with log r(−z) = log1p(−z e_sᵀ(I + zA)^{−1}c) so that r^{j−1} keeps its
// relative accuracy for j up to 10^7 and beyond. W_0 and W_1 come from the matrix power of the
// 2s × 2s block matrix [[A^{−1}, D_1], [0, A^{−1}]] (Eigen's Schur–Padé MatrixPower), whose
// power is [[W_0, W_1], [0, W_0]]. Measured accuracy against 50-digit references
// (tests/fractional/rkcq_reference.py): see the theory note.
//
// The same quadrature is the fast history's tail: node z_k gives the scalar decay r(−z_k) per lag
// and the rank-one block u_k v_kᵀ, so W_j ≈ Σ_k γ_k r(−z_k)^{j−n0} u_k v_kᵀ (fit_rkcq_tail()).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

namespace fracvi {

/// The Butcher tableau of an s-stage Runge–Kutta method.
struct ButcherTableau {
  Eigen::MatrixXd a;  ///< s × s
  Eigen::VectorXd b;  ///< weights
  Eigen::VectorXd c;  ///< nodes (c = A𝟙)
  int order = 0;      ///< classical order p
  std::string name;   ///< e.g. "Lobatto IIIC (s = 3)"

  [[nodiscard]] int stages() const { return static_cast<int>(b.size()); }
};

/// The s-stage Lobatto IIIC method, s = 2, 3, 4 (orders 2s − 2 = 2, 4, 6; stiffly accurate,
/// L-stable, algebraically stable). Coefficients as in Hairer & Wanner, Solving Ordinary
/// Differential Equations II, 2nd ed., Sect. IV.5 (Chipman 1971): c are the Lobatto points,
/// a_{i1} = b_1, and A satisfies C(s − 1). Throws std::invalid_argument for other s.
const ButcherTableau& lobatto_iiic(int stages);

/// The stability function of Lobatto IIIC on the negative axis, r(−z) = e_sᵀ(I + zA)^{−1}𝟙 for
/// z ≥ 0: the (s − 2, s) Padé approximant of e^{−z}. In (0, 1) for s = 2 and 4; negative for
/// z > 4 when s = 3 (r(−z) = (1 − z/4)/(1 + 3z/4 + z²/4 + z³/24)).
double lobatto_iiic_stability(int stages, double z);

/// s × s blocks W_0 … W_{count−1}, stored contiguously (column-major blocks).
class BlockWeights {
 public:
  BlockWeights() = default;
  BlockWeights(int stages, std::size_t count)
      : stages_(stages), count_(count), data_(static_cast<std::size_t>(stages * stages) * count) {}

  [[nodiscard]] int stages() const { return stages_; }
  [[nodiscard]] std::size_t size() const { return count_; }
  [[nodiscard]] Eigen::Map<const Eigen::MatrixXd> operator[](std::size_t j) const {
    return {data_.data() + block_offset(j), stages_, stages_};
  }
  [[nodiscard]] Eigen::Map<Eigen::MatrixXd> operator[](std::size_t j) {
    return {data_.data() + block_offset(j), stages_, stages_};
  }
  [[nodiscard]] const std::vector<double>& data() const { return data_; }

 private:
  [[nodiscard]] std::size_t block_offset(std::size_t j) const {
    return static_cast<std::size_t>(stages_ * stages_) * j;
  }
  int stages_ = 0;
  std::size_t count_ = 0;
  std::vector<double> data_;
};

/// Runge–Kutta convolution quadrature of s^order with the s-stage Lobatto IIIC method, as a value
/// (the block analogue of ConvolutionQuadrature). For a step h the operator is
/// h^{−order} Σ_j W_j (stage vector)_{n−j}.
struct RungeKuttaCq {
  int stages = 2;      ///< s ∈ {2, 3, 4}
  double order = 1.0;  ///< β ∈ [0, 2] (the damping sum of the mechanical schemes uses β = 2α)
  /// The first `lag` blocks are left out: weights(count)[j] = W_{j+lag}, weight(j) = W_{j+lag}
  /// (as ConvolutionQuadrature::lag). A scheme whose W_0 acts on the unknown stage values (and
  /// sits in Newton's matrix) keeps the known blocks in a block history with lag 1.
  std::size_t lag = 0;

  /// Throws std::invalid_argument unless stages ∈ {2, 3, 4} and 0 ≤ order ≤ 2 (finite).
  void validate() const;

  /// Δ(ζ) = A^{−1} − (ζ/b_1) e_1 e_sᵀ (see the top of this header).
  [[nodiscard]] Eigen::MatrixXd delta(double zeta) const;

  /// W_lag … W_{lag+count−1}. Integer orders exactly (up to the rounding of A^{−1}); otherwise
  /// every entry to a few ulps (measured ≤ 5.3e-15 relative for lags up to 10^7 against 50-digit
  /// references, docs/theory/rkcq_weights.md). Cost ≈ 0.04 s per 10^4 blocks, 0.4 s per 10^5.
  [[nodiscard]] BlockWeights weights(std::size_t count) const;
  /// W_{j+lag} alone (any j; cost independent of j: ≈ 10^{−4} s).
  [[nodiscard]] Eigen::MatrixXd weight(std::size_t j) const;

  /// True for integer orders (0, 1, 2): the weights terminate after order + 1 blocks.
  [[nodiscard]] bool is_local() const;

  /// e.g. "Lobatto IIIC (s = 3) RKCQ of order 1.5", "… of order 1.5 from lag 1".
  [[nodiscard]] std::string describe() const;

  friend bool operator==(const RungeKuttaCq&, const RungeKuttaCq&) = default;
};

/// Options of the tail representation of the block weights (fit_rkcq_tail()).
struct RkcqTailOptions {
  int stages = 2;
  double order = 0.5;          ///< β, non-integer, 0 < β < 2
  double tolerance = 1e-10;    ///< ε: max over tail lags of max|W̃_j − W_j| / max|W_j|
  std::size_t max_lag = 1000;  ///< the representation holds for window ≤ j ≤ max_lag
  std::size_t window = 16;     ///< n0 ≥ 2: W_0 … W_{n0−1} are kept exactly (head)
  bool compress = true;        ///< false: the raw trapezoidal nodes (for tests and docs)
};

/// W_j for j < window exactly (head), and for window ≤ j ≤ max_lag
///     W_j ≈ Σ_i decays[i]^{j − window} · coefficient(i),  coefficient(i) = gammas[i] u_i v_iᵀ
/// (rank one). decays[i] = r(−z_i) ∈ (−1, 1) (negative for Lobatto IIIC s = 3 when z_i > 4).
struct RkcqTail {
  int stages = 0;
  double order = 0.0;
  double tolerance = 0.0;
  std::size_t max_lag = 0;
  std::size_t window = 0;
  BlockWeights head;
  std::vector<double> nodes;           ///< z_i > 0, ascending
  std::vector<double> decays;          ///< r(−z_i)
  std::vector<double> gammas;          ///< scalar factors γ_i
  std::vector<Eigen::VectorXd> left;   ///< u_i = (I + z_i A)^{−1}𝟙
  std::vector<Eigen::VectorXd> right;  ///< v_i = (I + z_i Aᵀ)^{−1} b

  // Diagnostics.
  std::size_t quadrature_nodes = 0;  ///< nodes before compression
  double max_relative_error = 0.0;   ///< measured on the verification lags (normwise, max norm)
  std::size_t verification_lags = 0;
  double seconds = 0.0;

  [[nodiscard]] std::size_t terms() const { return decays.size(); }
  [[nodiscard]] Eigen::MatrixXd coefficient(std::size_t i) const;
  /// The represented block: head[j] for j < window, the sum otherwise.
  [[nodiscard]] Eigen::MatrixXd weight(std::size_t j) const;
};

/// Builds the tail representation. Throws std::invalid_argument for an integer or out-of-range
/// order, stages ∉ {2, 3, 4}, a tolerance outside [1e-13, 1e-3], window < 2, max_lag > 2^50;
/// std::runtime_error if the verification cannot reach the tolerance.
RkcqTail fit_rkcq_tail(const RkcqTailOptions& options);

}  // namespace fracvi
