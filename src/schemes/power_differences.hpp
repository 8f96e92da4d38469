// Differences of powers k^p on the integer grid without the cancellation of the direct formulas
// for large k (internal): the exact force of the removed Taylor polynomial (fvi-bdf2,
// fvi-midpoint, lda-midpoint) and the product-integration weights (pi-trapezoid).
#pragma once

#include <cmath>
#include <cstddef>

namespace fracvi::internal {

/// (k + 1)^p − k^p.
inline double forward_difference_of_power(std::size_t k, double p) {
  if (k == 0) return 1.0;
  const double kk = static_cast<double>(k);
  return std::pow(kk, p) * std::expm1(p * std::log1p(1.0 / kk));
}

/// (k+1)^p − 2k^p + (k−1)^p for k ≥ 1: k^p · 2 Σ_{j≥1} binom(p, 2j) k^{−2j} (the series converges
/// geometrically for k ≥ 2).
inline double second_difference_of_power(std::size_t k, double p) {
  if (k == 1) return std::pow(2.0, p) - 2.0;
  const double u2 = 1.0 / (static_cast<double>(k) * static_cast<double>(k));
  double binom = 1.0, power = 1.0, sum = 0.0;
  for (int m = 1; m <= 120; ++m) {
    binom *= (p - m + 1) / m;  // binom(p, m)
    if (m % 2 == 1) continue;
    power *= u2;
    const double term = binom * power;
    sum += term;
    if (std::abs(term) <= 1e-18 * std::abs(sum)) break;
  }
  return std::pow(static_cast<double>(k), p) * 2.0 * sum;
}

/// (k − 1)^p − k^p + p k^{p−1} for k ≥ 1 (the first weight of the product trapezoidal rule):
/// k^p Σ_{j≥2} binom(p, j) (−1/k)^j for k ≥ 16, directly below.
inline double taylor_remainder_of_power(std::size_t k, double p) {
  const double kk = static_cast<double>(k);
  if (k < 16) return std::pow(kk - 1.0, p) - std::pow(kk, p) + p * std::pow(kk, p - 1.0);
  double binom = p, power = 1.0, sum = 0.0;
  for (int m = 2; m <= 200; ++m) {
    binom *= (p - m + 1) / m;  // binom(p, m)
    power *= -1.0 / kk;
    const double term = binom * power * (-1.0 / kk);
    sum += term;
    if (std::abs(term) <= 1e-18 * std::abs(sum) || binom == 0.0) break;
  }
  return std::pow(kk, p) * sum;
}

}  // namespace fracvi::internal
