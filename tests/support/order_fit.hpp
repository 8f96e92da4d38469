// Observed convergence orders: the one helper every order test uses (DESIGN §5, STYLE.md "Tests
// that prove something").
//
// The observed order is the least-squares slope of log(error) against log(h) over several step
// sizes, fitted only where the error is still the discretisation error:
//  * a point whose error is at or below `floor` (round-off plateau, e.g. round_off_floor(scale))
//    is dropped, and so is every finer point after it;
//  * walking from the coarsest step to the finest, once the error stops decreasing by at least
//    `min_reduction` per halving of h (default 1.2, i.e. a local order below log2 1.2 ≈ 0.26), that
//    point and every finer one are dropped: the error has hit a plateau (round-off, Newton
//    tolerance, reference accuracy) and the remaining points would bend the fit.
// At least `min_points` (default 3) points must remain; otherwise the fit reports why (valid is
// false, slope NaN), so an EXPECT on the slope fails with the table in the message instead of
// passing on two points.
//
// Usage:
//   const test::OrderFit fit = test::fit_order(hs, errors, {.floor =
//   test::round_off_floor(scale)}); std::printf("%s", fit.table("fvi-gl, damped
//   oscillator").c_str()); EXPECT_TRUE(fit.valid) << fit.table(); EXPECT_GE(fit.slope, declared -
//   0.1) << fit.table();
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <numeric>
#include <span>
#include <string>
#include <vector>

namespace fracvi::test {

/// Errors below kRoundOffPlateauFactor · ε · (solution scale) are treated as round-off. A run of
/// N steps accumulates rounding errors of ε·scale per step, between √N (random walk) and N (same
/// sign) times: for the N ≤ 10⁴ of the order tests, 10⁴ ε · scale ≈ 2e-12 · scale bounds that
/// accumulation, so an error above the floor is dominated by the discretisation.
inline constexpr double kRoundOffPlateauFactor = 1e4;

/// The round-off floor kRoundOffPlateauFactor · ε · scale for a solution of size `scale`
/// (max_k ‖x(t_k)‖_∞ of the reference).
inline double round_off_floor(double scale, double factor = kRoundOffPlateauFactor) {
  return factor * std::numeric_limits<double>::epsilon() * std::abs(scale);
}

/// A point stays in the fit while the error still drops by this factor per halving of h (a local
/// order ≥ log2 1.2 ≈ 0.26, well below any order we test, well above a plateau's ≈ 0).
inline constexpr double kPlateauReductionPerHalving = 1.2;

struct OrderFitOptions {
  /// Errors ≤ floor are round-off (0: no floor; non-positive and non-finite errors always drop).
  double floor = 0.0;
  /// Minimal error reduction per halving of h between consecutive kept points.
  double min_reduction = kPlateauReductionPerHalving;
  /// Fewer points than this left after masking: the fit is invalid.
  std::size_t min_points = 3;
};

struct OrderFit {
  std::vector<double> h;      ///< all step sizes, as given
  std::vector<double> error;  ///< all errors, as given
  /// Why point i was dropped ("" when it is used).
  std::vector<std::string> dropped;
  std::vector<std::size_t> used;  ///< indices of the points in the fit, coarsest first
  double slope = std::numeric_limits<double>::quiet_NaN();  ///< observed order (NaN if !valid)
  bool valid = false;   ///< at least min_points points were left
  std::string message;  ///< why the fit is invalid ("" when valid)

  /// "label\n   h  error  local order  used?\n … observed order p over n points" for test output.
  [[nodiscard]] std::string table(const std::string& label = "") const {
    std::string out;
    char line[200];
    if (!label.empty()) out += "[ order fit ] " + label + "\n";
    std::snprintf(line, sizeof line, "    %12s  %12s  %11s  %s\n", "h", "error", "local order",
                  "in fit");
    out += line;
    for (std::size_t i = 0; i < h.size(); ++i) {
      char local[32] = "";
      if (i > 0 && error[i] > 0.0 && error[i - 1] > 0.0) {
        std::snprintf(local, sizeof local, "%.4f",
                      std::log(error[i - 1] / error[i]) / std::log(h[i - 1] / h[i]));
      }
      std::snprintf(line, sizeof line, "    %12.5e  %12.5e  %11s  %s\n", h[i], error[i], local,
                    dropped[i].empty() ? "yes" : ("no: " + dropped[i]).c_str());
      out += line;
    }
    if (valid) {
      std::snprintf(line, sizeof line, "    observed order %.4f over %zu points\n", slope,
                    used.size());
    } else {
      std::snprintf(line, sizeof line, "    NO FIT: %s\n", message.c_str());
    }
    out += line;
    return out;
  }
};

/// Least-squares slope of log(error) against log(h) over the points that survive the masking
/// described at the top of this file. `h` and `error` have the same length; any order of h.
inline OrderFit fit_order(std::span<const double> h, std::span<const double> error,
                          const OrderFitOptions& options = {}) {
  OrderFit fit;
  fit.h.assign(h.begin(), h.end());
  fit.error.assign(error.begin(), error.end());
  const std::size_t n = std::min(h.size(), error.size());
  fit.h.resize(n);
  fit.error.resize(n);
  fit.dropped.assign(n, "");

  // Coarsest first.
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return fit.h[a] > fit.h[b]; });

  bool plateau = false;
  std::size_t last_kept = n;  // index of the previous kept point (n: none yet)
  for (const std::size_t i : order) {
    const double e = fit.error[i];
    char why[120];
    if (plateau) {
      fit.dropped[i] = "after the plateau";
    } else if (!(std::isfinite(e) && e > 0.0 && std::isfinite(fit.h[i]) && fit.h[i] > 0.0)) {
      fit.dropped[i] = "not a positive finite error";
      plateau = true;
    } else if (e <= options.floor) {
      std::snprintf(why, sizeof why, "below the round-off floor %.2e", options.floor);
      fit.dropped[i] = why;
      plateau = true;
    } else if (last_kept != n) {
      const double halvings = std::log2(fit.h[last_kept] / fit.h[i]);
      const double reduction = std::pow(fit.error[last_kept] / e, 1.0 / halvings);
      if (!(reduction >= options.min_reduction)) {
        std::snprintf(why, sizeof why, "error reduced only %.3f per halving (< %.2f)", reduction,
                      options.min_reduction);
        fit.dropped[i] = why;
        plateau = true;
      }
    }
    if (fit.dropped[i].empty()) {
      fit.used.push_back(i);
      last_kept = i;
    }
  }

  if (fit.used.size() < options.min_points) {
    fit.message = std::to_string(fit.used.size()) + " of " + std::to_string(n) +
                  " point(s) left after masking the plateau, " +
                  std::to_string(options.min_points) + " needed";
    return fit;
  }
  const auto m = static_cast<double>(fit.used.size());
  double sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0;
  for (const std::size_t i : fit.used) {
    const double lx = std::log(fit.h[i]);
    const double ly = std::log(fit.error[i]);
    sx += lx;
    sy += ly;
    sxx += lx * lx;
    sxy += lx * ly;
  }
  fit.slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
  fit.valid = true;
  return fit;
}

}  // namespace fracvi::test
