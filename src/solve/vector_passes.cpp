#include "fracvi/solve/vector_passes.hpp"

#include <algorithm>
#include <cmath>

#include "fracvi/internal/vectorize.hpp"

namespace fracvi::internal {

// Σ 0·v_i is ±0 when every v_i is finite and NaN otherwise (0·∞ = NaN), in any order
// (internal/vectorize.hpp, all_finite).

FRACVI_HOT_KERNEL
bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = a[i] + b[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_HOT_KERNEL
bool diagonal_residual(const double* m, const double* increment, double s, const double* g,
                       const double* c, double* out, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = (m[i] * increment[i] + s * g[i]) - c[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_HOT_KERNEL
bool general_residual(double s, const double* g, const double* c, double* out, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = (out[i] + s * g[i]) - c[i];
    out[i] = value;
    zero += 0.0 * value;
  }
  return zero == 0.0;
}

FRACVI_HOT_KERNEL
CorrectionPass apply_correction_pass(const double* delta, const double* a, double* increment,
                                     double* mid, Eigen::Index n, bool with_next) {
  double size = 0.0, scale = 0.0, zero = 0.0;
  if (with_next) {
#pragma omp simd reduction(max : size, scale) reduction(+ : zero)
    for (Eigen::Index i = 0; i < n; ++i) {
      const double updated = increment[i] - delta[i];
      increment[i] = updated;
      size = std::max(size, std::abs(delta[i]));
      zero += 0.0 * updated;
      scale = std::max(scale, std::abs(a[i] + updated));
      mid[i] = a[i] + 0.5 * updated;
    }
  } else {
#pragma omp simd reduction(max : size) reduction(+ : zero)
    for (Eigen::Index i = 0; i < n; ++i) {
      const double updated = increment[i] - delta[i];
      increment[i] = updated;
      size = std::max(size, std::abs(delta[i]));
      zero += 0.0 * updated;
    }
  }
  return {size, scale, zero == 0.0};
}

FRACVI_HOT_KERNEL
bool all_finite_pass(const double* v, Eigen::Index n) {
  double zero = 0.0;
#pragma omp simd reduction(+ : zero)
  for (Eigen::Index i = 0; i < n; ++i) zero += 0.0 * v[i];
  return zero == 0.0;
}

}  // namespace fracvi::internal
