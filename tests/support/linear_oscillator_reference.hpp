// Independent reference solutions for the linear fractional oscillator
//
//     M x'' + R D^β x + K x = 0,   x(0) = x0,  x'(0) = v0,   β = 2α ∈ (0, 2),
//
// used to measure the error of the `DiscEqs` integrator with nonzero initial data. Nothing here
// uses fracvi's own code (weights, history, integrator): a shared bug cannot cancel out.
//
// Laplace transform (verified term by term in linear_oscillator_reference.cpp; F(s) is the
// transform of the optional power-law forcing, added to each numerator below):
//   Caputo:  L{D^β_C x} = s^β X − s^{β−1} x0 − [β > 1] s^{β−2} v0, hence
//            X(s) = Q(s)^{-1} [ (M s + R s^{β−1}) x0 + (M + [β > 1] R s^{β−2}) v0 ],
//   RL (β < 1 only; for β ≥ 1 with x0 ≠ 0 the problem is ill-posed, DESIGN §2):
//            L{D^β_RL x} = s^β X − (I^{1−β} x)(0⁺) = s^β X   (x bounded near 0), hence
//            X(s) = Q(s)^{-1} M (s x0 + v0),
//   with Q(s) = M s² + R s^β + K on the principal branch.
//
// Two independent evaluations of x(t):
//  * LaplaceInversion — poles + branch cut. Deforming the Bromwich line onto a Hankel contour
//    around the cut (−∞, 0] (in from −∞ below the cut, round the circle |s| = ε, out above) gives
//        x(t) = Σ_{det Q(s_j) = 0} Res[e^{st} X(s), s_j]  −  (1/π) ∫_ε^∞ e^{−rt} Im X(r e^{iπ}) dr
//               + (1/π) ∫_0^π Re[e^{st} s X(s)]_{s = ε e^{iθ}} dθ.
//    The zeros of det Q on the principal sheet are found by Newton iteration from the undamped
//    frequencies and a grid of guesses, and their number is certified by the argument principle
//    on the upper half of the cut disc; residues come from the null vectors of Q(s_j). The cut
//    integral is done by Boost.Math exp_sinh (double-exponential, handles the algebraic decay
//    r^{β−4} at infinity), the circle by adaptive Gauss–Kronrod. Keeping the circle (instead of
//    letting ε → 0) also covers singular K, where s X(s) ↛ 0 at the branch point. Valid for all
//    t ≥ 0.
//  * series_solution — term-wise inversion of the expansion of X(s) at s = ∞ in powers of
//    s^{β−2} and s^{−2} (a bivariate Mittag-Leffler series, noncommuting matrices allowed).
//    Converges for every t, but cancels like e^{c t}: use for moderate t, check `abs_sum`.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <vector>

namespace fracvi::test {

/// The meaning of D^β in the reference problem (DESIGN §2).
enum class ReferenceConvention { kCaputo, kRiemannLiouville };

/// One term a t^q (q > −1) of a power-law forcing; its transform is a Γ(q+1) s^{−q−1}.
struct PowerTerm {
  Eigen::VectorXd coefficient;  ///< a
  double exponent = 0.0;        ///< q
};

/// M x'' + R D^β x + K x = f(t) with x(0) = x0, x'(0) = v0, f(t) = Σ_i a_i t^{q_i} (possibly
/// empty). M SPD, R symmetric PSD, K symmetric PSD.
struct LinearOscillator {
  Eigen::MatrixXd mass;
  Eigen::MatrixXd damping;
  Eigen::MatrixXd stiffness;
  double beta = 0.5;  ///< damping order 2α ∈ (0, 2)
  Eigen::VectorXd x0;
  Eigen::VectorXd v0;
  ReferenceConvention convention = ReferenceConvention::kCaputo;
  std::vector<PowerTerm> forcing;  ///< f(t) = Σ a_i t^{q_i}; empty means f ≡ 0

  /// Scalar convenience constructor (d = 1).
  static LinearOscillator scalar(double m, double r, double k, double beta, double x0, double v0,
                                 ReferenceConvention convention = ReferenceConvention::kCaputo);
  /// Throws std::invalid_argument for inconsistent sizes, β ∉ (0, 2), RL with β ≥ 1, or a
  /// forcing exponent ≤ −1.
  void validate() const;
  [[nodiscard]] Eigen::Index dim() const { return mass.rows(); }
};

/// X(s) for s = r e^{iθ}, r > 0, θ ∈ [−π, π] (principal branch, θ = ±π are the two cut sides).
Eigen::VectorXcd laplace_transform(const LinearOscillator& problem, double r, double theta);

/// Poles + branch-cut inversion of X(s) (see the file comment).
class LaplaceInversion {
 public:
  explicit LaplaceInversion(LinearOscillator problem);

  /// x(t), t ≥ 0.
  [[nodiscard]] Eigen::VectorXd operator()(double t) const;

  /// Zeros of det Q(s) with Im s > 0 on the principal sheet (the others are their conjugates).
  [[nodiscard]] const std::vector<std::complex<double>>& poles() const { return poles_; }
  /// Zeros of det Q in the upper half of the cut disc, counted by the argument principle.
  [[nodiscard]] int certified_pole_count() const { return pole_count_; }

  /// The residue part and the Hankel-contour part (both sides of the cut for |s| ≥ ε plus the
  /// circle |s| = ε around the branch point) separately, for diagnostics.
  [[nodiscard]] Eigen::VectorXd pole_part(double t) const;
  [[nodiscard]] Eigen::VectorXd hankel_part(double t) const;
  /// Largest quadrature error estimate (relative to the integrand's L1 norm for the cut) over the
  /// components in the last hankel_part call, for reporting.
  [[nodiscard]] double last_hankel_error() const { return last_hankel_error_; }

 private:
  LinearOscillator problem_;
  std::vector<std::complex<double>> poles_;
  std::vector<Eigen::VectorXcd> residues_;  ///< Res[X, s_j] (times e^{s_j t} gives the term)
  int pole_count_ = 0;
  double circle_radius_ = 0.5;  ///< ε of the Hankel contour, below every |s_j|
  mutable double last_hankel_error_ = 0.0;
};

/// Result of the series evaluation: the value and Σ|terms| (∞-norm), so round-off ≈ ε·abs_sum.
struct SeriesValue {
  Eigen::VectorXd value;
  double abs_sum = 0.0;
  int levels = 0;  ///< number of total-degree levels j + l summed
};

/// x(t) = Σ_{j,l,i} C_{j,l} M^{-1} P_i t^{μ−1}/Γ(μ), μ = 2 − e_i + (2−β) j + 2 l, where
/// Q(s)^{-1} = Σ C_{j,l} M^{-1} s^{−2+(β−2)j−2l}, C_{j,l} = −(A C_{j−1,l} + B C_{j,l−1}),
/// A = M^{-1}R, B = M^{-1}K, and P(s) = Σ_i P_i s^{e_i} is the numerator of X(s) (initial data
/// and forcing terms).
SeriesValue series_solution(const LinearOscillator& problem, double t);

/// E_{a,b}(z) = Σ_k z^k / Γ(a k + b) by its power series (moderate |z| only; a > 0).
double mittag_leffler(double a, double b, double z);

}  // namespace fracvi::test
