// The compression step shared by the two sum-of-decays fits of the fractional layer (internal):
// fit_exponentials() (scalar CQ weights, exponential_fit.cpp) and fit_rkcq_tail() (Runge–Kutta
// CQ block weights, runge_kutta_cq.cpp). Both start from the nodes of a trapezoidal rule in the
// log of the Laplace (or Stieltjes) variable, rank them by a column-pivoted QR of a relative-error
// design matrix, and keep the smallest K whose least-squares refit passes a verification
// (docs/theory/fast_history.md §3–4, docs/theory/rkcq_weights.md §10).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

namespace fracvi::detail {

// Share of ε given to the truncation of the node range (each end) and to the trapezoidal
// discretisation; the compression then has to land within ε/2 (kVerifySafety) on the
// verification lags, which leaves room for the lags between them.
inline constexpr double kTruncationShare = 0.01;
inline constexpr double kDiscretisationShare = 0.1;
inline constexpr double kVerifySafety = 0.5;
// Least-squares rows: every lag of the first kFitDense, then kFitPerDecade per decade.
inline constexpr std::size_t kFitDense = 256;
inline constexpr double kFitPerDecade = 60.0;
// Verification lags: every lag of the first kVerifyDense, then kVerifyPerDecade per decade. The
// error oscillates in ln m with a period of about the node spacing (≥ 0.3), so 200 per decade
// (spacing 0.012 in ln m) samples each oscillation ≥ 25 times.
inline constexpr std::size_t kVerifyDense = 4096;
inline constexpr double kVerifyPerDecade = 200.0;
// Step of the sweep over K before the bisection (select_pivoted_terms()).
inline constexpr std::size_t kSweepStep = 8;

// Integers first..min(last, first + dense), then about per_decade log-spaced integers up to last
// (inclusive), strictly increasing.
inline std::vector<std::size_t> sample_lags(std::size_t first, std::size_t last, std::size_t dense,
                                            double per_decade) {
  std::vector<std::size_t> lags;
  const std::size_t dense_end = std::min(last, first + dense);
  for (std::size_t m = first; m <= dense_end; ++m) lags.push_back(m);
  if (dense_end < last) {
    const double a = std::log10(static_cast<double>(dense_end));
    const double b = std::log10(static_cast<double>(last));
    const auto n = static_cast<std::size_t>(std::ceil((b - a) * per_decade));
    for (std::size_t i = 1; i <= n; ++i) {
      const double m =
          std::round(std::pow(10.0, a + (b - a) * static_cast<double>(i) / static_cast<double>(n)));
      const auto mi = std::min(last, static_cast<std::size_t>(m));
      if (mi > lags.back()) lags.push_back(mi);
    }
    if (lags.back() != last) lags.push_back(last);
  }
  return lags;
}

// Largest step h whose trapezoidal aliasing error stays below `target`. The leading aliasing term
// of ∫ e^{−m e^u} e^{(1+β)u} du is 2|Γ(1 + β − 2πi/h)|/Γ(1 + β) relative, and Stirling gives
// E(h) ≈ 2√(2π) (2π/h)^{β+1/2} e^{−π²/h} / Γ(1 + β) (this model matches the measured errors
// within a factor 2 for β ∈ [0.3, 1.8], h ∈ [0.3, 0.5]). Solved for y = 1/h by fixed point.
inline double trapezoidal_step(double beta, double target) {
  constexpr double kPi = std::numbers::pi;
  const double rhs = std::log(2.0 * std::sqrt(2.0 * kPi) / (std::tgamma(1.0 + beta) * target));
  double y = 3.0;
  for (int it = 0; it < 60; ++it) y = (rhs + (beta + 0.5) * std::log(2.0 * kPi * y)) / (kPi * kPi);
  return 1.0 / y;
}

// The smallest selection along the pivot order that passes. `a` is the design matrix (rows:
// sampled lags, scaled to relative error; columns: the candidate terms, scaled by their
// quadrature weights `column_scale` so that the all-ones vector reproduces the quadrature — the
// pivoting then ranks the terms by their contribution to the relative error and the refit
// coefficients stay O(1)), `b` the scaled weights. For K columns (the first K pivots) the
// least-squares refit x gives the term weights column_scale[col_t]·x_t, and
// evaluate(columns, weights) returns a selection with a member `error` (the verified error).
// A sweep in steps of `sweep_step` along the pivot order finds the first K with error ≤ `accept`
// (the error is not monotone in K near full rank, where the least-squares weights start to wiggle
// between the rows), then bisection below it. Returns the selection of the smallest passing K, or
// the one with all columns if none passes (the caller checks its error).
template <class Evaluate>
auto select_pivoted_terms(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                          const std::vector<double>& column_scale, double accept,
                          std::size_t sweep_step, Evaluate&& evaluate) {
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> pivoted(a);
  const auto& perm = pivoted.colsPermutation().indices();
  const std::size_t candidates = column_scale.size();
  const auto solve = [&](std::size_t k) {
    std::vector<std::size_t> columns(k);
    Eigen::MatrixXd a_sel(a.rows(), static_cast<Eigen::Index>(k));
    for (std::size_t t = 0; t < k; ++t) {
      columns[t] = static_cast<std::size_t>(perm(static_cast<Eigen::Index>(t)));
      a_sel.col(static_cast<Eigen::Index>(t)) = a.col(static_cast<Eigen::Index>(columns[t]));
    }
    const Eigen::VectorXd x = a_sel.householderQr().solve(b);
    std::vector<double> weights(k);
    for (std::size_t t = 0; t < k; ++t)
      weights[t] = column_scale[columns[t]] * x(static_cast<Eigen::Index>(t));
    return evaluate(columns, weights);
  };
  using Selection = decltype(solve(std::size_t{0}));
  Selection best;
  std::size_t hi = 0;
  for (std::size_t k = std::min(sweep_step, candidates);;
       k = std::min(k + sweep_step, candidates)) {
    Selection trial = solve(k);
    if (trial.error <= accept || k == candidates) {
      hi = k;
      best = std::move(trial);
      break;
    }
  }
  if (best.error <= accept) {
    std::size_t lo = hi > sweep_step ? hi - sweep_step + 1 : 1;
    while (lo < hi) {
      const std::size_t mid = (lo + hi) / 2;
      Selection trial = solve(mid);
      if (trial.error <= accept) {
        hi = mid;
        best = std::move(trial);
      } else {
        lo = mid + 1;
      }
    }
  }
  return best;
}

}  // namespace fracvi::detail
