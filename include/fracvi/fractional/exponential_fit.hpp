// Sums of decaying exponentials for the tail of the convolution-quadrature weights (DESIGN §6).
//
// The damping sum of `DiscEqs` is Σ_{m=0}^{k} c_m x̃_{k−m} with c_m the coefficients of
// (1 − ζ)^β, β = 2α (DESIGN §3.1). For non-integer β and m > β these weights have the exact
// integral representation (Euler's Beta integral with t = e^{−s}, and the reflection formula
// Γ(−β)Γ(1 + β) = −π / sin πβ):
//
//     c_m = Γ(m − β) / (Γ(−β) Γ(m + 1)) = −(sin πβ / π) ∫_0^∞ e^{−(m−β)s} (1 − e^{−s})^β ds
//         = ∫_0^∞ e^{−m s} ρ(s) ds,         ρ(s) = −(sin πβ / π) (e^s − 1)^β,
//
// so c_m is a Laplace transform in the lag m. Substituting s = e^u makes the integrand
// e^{−m e^u} ρ(e^u) e^u smooth, exponentially decaying at both ends (like e^{(1+β)u} as u → −∞,
// doubly exponentially as u → +∞) and analytic in the strip |Im u| < π/2, so the trapezoidal
// rule in u with step h converges like e^{−π²/h} uniformly in m (relative error). Each node
// s_j = e^{u_j} becomes one exponential: c_m ≈ Σ_j q_j e^{−s_j m}, q_j = h s_j ρ(s_j). The range
// of u is cut where the neglected mass is below ε at the largest lag N_max (lower end,
// s ≈ ε^{1/(1+β)}/N_max) and at the first tail lag n0 (upper end, s ≈ log(1/ε)/n0), so the
// quadrature has J ≈ (log N_max + log(1/ε)/(1+β)) / h nodes with h ≈ π²/log(1/ε): J grows like
// log N · log(1/ε).
//
// Compression. The J nodes are far from minimal. We sample the exact weights at lags
// m_i ∈ [n0, N_max] (every integer up to n0 + 256, then 60 per decade), form the relative-error
// matrix A_ij = q_j e^{−s_j (m_i − n0)} / |c_{m_i}|, order its columns by a column-pivoted QR
// (the interpolative-decomposition choice of the most independent exponentials), and for each
// candidate K solve the least-squares problem min ‖A_S v − sign(c)‖ over the first K pivots S.
// The smallest K whose weights w_j = q_j v_j reproduce every weight of a denser verification set
// (every integer in [n0, n0 + 4096] and 200 lags per decade up to N_max) to relative error ≤ ε/2
// is kept. The nodes stay a subset of the quadrature nodes, so all λ_j are real and positive
// (every recursion decays); the weights stay real. Measured K, fit times and errors are in
// docs/theory/fast_history.md and tests/integrate/fast_history_test.cpp.
//
// Other convolution quadratures. BDF2 (δ(ζ) = (1 − ζ)(3 − ζ)/2) has the same structure: on the
// branch cut ζ = e^s ∈ (1, ∞) the generating function δ(ζ)^β jumps, and for m > 2β
//   ω_m = ∫_0^∞ e^{−ms} ρ₂(s) ds,  ρ₂(s) = −(sin πβ/π)(e^s − 1)^β ((3 − e^s)/2)^β  (s < ln 3),
//                                  ρ₂(s) = −(sin 2πβ/π)(e^s − 1)^β ((e^s − 3)/2)^β (s > ln 3),
// which is implemented (with a window n0 = 32, so the non-smooth point s = ln 3 weighs less than
// 3^{−32} relative). The trapezoidal (Tustin) weights are not: (1 + ζ)^{−β} puts a branch point
// on the unit circle at ζ = −1, so the weights carry an oscillating tail (−1)^m m^{β−1} that
// decays more slowly than the smooth part for β < 1 and grows for β > 1 (see
// docs/theory/fast_history.md for the path: negative-base exponentials (−e^{−μ})^m from the cut
// ζ ∈ (−∞, −1), plus the exact recursion for (1 + ζ)^{−2} when β > 1).
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "fracvi/fractional/weights.hpp"

namespace fracvi {

/// Default per-weight relative tolerance ε of an exponential fit.
inline constexpr double kDefaultFitTolerance = 1e-10;
/// Accepted tolerances: below 1e-13 the reference weights themselves (a few ulps) and the
/// least-squares residual floor (≈ 1e-14) leave no margin; above 1e-3 a fit is pointless.
inline constexpr double kMinFitTolerance = 1e-13;
inline constexpr double kMaxFitTolerance = 1e-3;

struct ExponentialFitOptions {
  CqScheme scheme = CqScheme::kGrunwaldLetnikov;  ///< kGrunwaldLetnikov or kBdf2
  /// Non-integer; 0 < β < 2 for BDF2, −1 < β < 2 for GL (negative orders: the weights of the
  /// fractional integral, positive and decaying like m^{−β−1}; the same Laplace representation).
  double order = 0.5;
  double tolerance = kDefaultFitTolerance;  ///< ε: max relative error of every tail weight
  std::size_t max_lag = 1000;               ///< N_max: the fit holds for window ≤ m ≤ max_lag
  std::size_t window = 0;  ///< n0 exact weights; 0 picks default_fit_window(scheme)
  /// The fit represents ω_{m+lag} (ConvolutionQuadrature::lag): a lagged fit is the unlagged fit
  /// with window n0 + lag, its first `lag` head weights dropped (the tail is the same sum).
  std::size_t lag = 0;
  bool compress = true;  ///< false: keep the raw trapezoidal quadrature (for tests and docs)
};

/// c_m for m < window exactly (head), and for window ≤ m ≤ max_lag
///     c_m ≈ Σ_j weights[j] · exp(−lambdas[j] · (m − window))        (relative error ≤ tolerance).
/// The shift by the window keeps the weights at the size of the weights they represent.
struct ExponentialFit {
  CqScheme scheme = CqScheme::kGrunwaldLetnikov;
  double order = 0.0;
  double tolerance = 0.0;
  std::size_t max_lag = 0;
  std::size_t window = 0;
  std::size_t lag = 0;          ///< the represented weights are c_{m+lag}
  std::vector<double> head;     ///< exact c_lag … c_{lag+window−1}
  std::vector<double> lambdas;  ///< λ_j > 0, ascending
  std::vector<double> weights;  ///< w_j

  // Diagnostics of the construction.
  std::size_t quadrature_nodes = 0;  ///< J, the trapezoidal nodes before compression
  double quadrature_step = 0.0;      ///< h, the step in u = ln s
  double max_relative_error = 0.0;   ///< measured on the verification lags
  std::size_t verification_lags = 0;
  /// max over the verification lags of Σ_j |w_j| e^{−λ_j (m − n0)} / |c_m|: how much the
  /// exponential sum cancels (1 = none; round-off in the history sum scales with it).
  double cancellation = 1.0;
  double seconds = 0.0;  ///< wall time of fit_exponentials()

  /// K, the number of exponentials (the cost per step and DOF of the tail).
  [[nodiscard]] std::size_t terms() const { return lambdas.size(); }
  /// The represented weight: head[m] for m < window, the exponential sum otherwise.
  [[nodiscard]] double weight(std::size_t m) const;
};

/// 16 for Grünwald–Letnikov (K barely depends on it: doubling n0 saves ≈ 2 terms), 32 for BDF2
/// (the density's non-smooth point s = ln 3 then weighs < 3^{−32} relative).
std::size_t default_fit_window(CqScheme scheme);

/// Builds the fit described at the top of this header. Takes milliseconds (measured in
/// docs/theory/fast_history.md). Throws std::invalid_argument for an integer or out-of-range
/// order, a tolerance outside [kMinFitTolerance, kMaxFitTolerance], max_lag < 1 or > 2^50,
/// window < 2 (GL) / < 5 (BDF2), or the trapezoidal scheme; std::runtime_error if the
/// verification cannot reach the tolerance (never observed for the documented ranges).
ExponentialFit fit_exponentials(const ExponentialFitOptions& options);

/// fit_exponentials() through a process-wide, thread-safe cache keyed by all options (the
/// default window is resolved first). Fits are small (≈ 2 K doubles), the cache is never evicted;
/// clear_exponential_fit_cache() empties it.
std::shared_ptr<const ExponentialFit> shared_exponential_fit(const ExponentialFitOptions& options);
void clear_exponential_fit_cache();
std::size_t exponential_fit_cache_size();

/// The exact weight ω_m of a convolution quadrature at a single lag (the fit's reference):
/// GL: gl_weight(order, m); BDF2: ω = ((3 − ζ)/2)^β · (1 − ζ)^β as a 41-term convolution of
/// 3^{−n}-damped GL weights with GL weights anchored by gl_weight (relative error ≈ 1e-15);
/// trapezoidal: the O(m) series of cq_weights (use it for moderate m only).
double cq_weight(CqScheme scheme, double order, std::size_t m);

}  // namespace fracvi
