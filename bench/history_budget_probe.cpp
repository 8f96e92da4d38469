// Measurements behind docs/theory/fast_history.md §10 (issue 17), on the Caputo oscillator's
// scale x̃ = cos t − 1, t ∈ [0, 20], β = 1.5, h = 20/N:
//
//   history_budget_probe sum N eps...     the fast sum's error max_k |Ŝ_k − S_k| against the exact
//                                         sum in long double (16 checkpoints), for n0 = 16 and 128,
//                                         plain and in the difference form (§10.5: the weights of
//                                         order β − 1 on x̃_k − x̃_{k−1});
//   history_budget_probe recursions N eps the tail Σ_j w_j Y_j of the recursions in double, with
//                                         Neumaier-compensated recursions, and in long double
//                                         (§10.6).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "fracvi/fractional/exponential_fit.hpp"

namespace {

using LongDouble = long double;
constexpr double kBeta = 1.5;
constexpr double kDamping = 0.5;  // R of the oscillator: the force error is R h^{−β} × the sum's

double step(std::size_t n) {
  return 20.0 / static_cast<double>(n);
}

std::size_t fit_lag(std::size_t n) {
  std::size_t lag = 1;
  while (lag < n) lag *= 2;
  return lag;
}

void sum_errors(std::size_t n, const std::vector<double>& tolerances) {
  const double h = step(n);
  std::vector<double> x(n + 1);
  for (std::size_t i = 0; i <= n; ++i) x[i] = std::cos(static_cast<double>(i) * h) - 1.0;
  std::vector<LongDouble> c(n + 1);
  c[0] = 1;
  for (std::size_t m = 1; m <= n; ++m) {
    c[m] = c[m - 1] * (static_cast<LongDouble>(m) - 1 - kBeta) / static_cast<LongDouble>(m);
  }
  std::vector<std::size_t> checks;
  std::vector<LongDouble> exact;
  for (std::size_t j = 1; j <= 16; ++j) {
    const std::size_t k = n * j / 16;
    LongDouble s = 0;
    for (std::size_t m = 0; m <= k; ++m) s += c[m] * x[k - m];
    checks.push_back(k);
    exact.push_back(s);
  }
  for (const bool difference : {false, true}) {
    std::vector<double> input(n + 1);
    for (std::size_t i = 0; i <= n; ++i) input[i] = difference ? x[i] - (i ? x[i - 1] : 0.0) : x[i];
    for (const double eps : tolerances) {
      for (const std::size_t n0 : {std::size_t{16}, std::size_t{128}}) {
        fracvi::ExponentialFitOptions o;
        o.order = difference ? kBeta - 1.0 : kBeta;
        o.tolerance = eps;
        o.max_lag = fit_lag(n);
        o.window = n0;
        const fracvi::ExponentialFit fit = fracvi::fit_exponentials(o);
        const std::size_t terms = fit.terms();
        std::vector<double> decay(terms), y(terms, 0.0);
        for (std::size_t j = 0; j < terms; ++j) decay[j] = std::exp(-fit.lambdas[j]);
        double worst = 0.0;
        std::size_t next = 0;
        for (std::size_t k = 0; k <= n && next < checks.size(); ++k) {
          if (k >= n0) {
            for (std::size_t j = 0; j < terms; ++j) y[j] = decay[j] * y[j] + input[k - n0];
          }
          if (k != checks[next]) continue;
          double s = 0.0;
          for (std::size_t m = 0; m < n0 && m <= k; ++m) s += fit.head[m] * input[k - m];
          for (std::size_t j = 0; j < terms; ++j) s += fit.weights[j] * y[j];
          worst = std::max(worst, static_cast<double>(std::abs(s - exact[next])));
          ++next;
        }
        std::printf(
            "N = %zu %s eps = %.0e n0 = %3zu K = %2zu  max|S_fast - S| = %.3e  "
            "R h^-beta x that = %.3e\n",
            n, difference ? "difference" : "plain     ", eps, n0, terms, worst,
            kDamping * std::pow(h, -kBeta) * worst);
      }
    }
  }
}

void recursion_round_off(std::size_t n, double eps) {
  fracvi::ExponentialFitOptions o;
  o.order = kBeta;
  o.tolerance = eps;
  o.max_lag = fit_lag(n);
  const fracvi::ExponentialFit fit = fracvi::fit_exponentials(o);
  const std::size_t terms = fit.terms(), n0 = fit.window;
  std::vector<double> decay(terms), plain(terms, 0.0), compensated(terms, 0.0), carry(terms, 0.0);
  std::vector<LongDouble> wide(terms, 0.0);
  for (std::size_t j = 0; j < terms; ++j) decay[j] = std::exp(-fit.lambdas[j]);
  const double h = step(n);
  double plain_gap = 0.0, compensated_gap = 0.0, largest = 0.0;
  for (std::size_t k = n0; k <= n; ++k) {
    const double x = std::cos(static_cast<double>(k - n0) * h) - 1.0;
    for (std::size_t j = 0; j < terms; ++j) {
      plain[j] = decay[j] * plain[j] + x;
      wide[j] = static_cast<LongDouble>(decay[j]) * wide[j] + x;
      // Neumaier: the product's rounding error by fma, the sum's by TwoSum, carried per term.
      const double product = decay[j] * compensated[j];
      const double rest = x + (decay[j] * carry[j] + std::fma(decay[j], compensated[j], -product));
      const double total = product + rest;
      carry[j] =
          std::abs(product) >= std::abs(rest) ? (product - total) + rest : (rest - total) + product;
      compensated[j] = total;
    }
    if (k % 1024 != 0 && k != n) continue;
    LongDouble tail_wide = 0;
    double tail_plain = 0.0, tail_compensated = 0.0;
    for (std::size_t j = 0; j < terms; ++j) {
      tail_wide += fit.weights[j] * wide[j];
      tail_plain += fit.weights[j] * plain[j];
      tail_compensated += fit.weights[j] * (compensated[j] + carry[j]);
    }
    plain_gap = std::max(plain_gap, static_cast<double>(std::abs(tail_plain - tail_wide)));
    compensated_gap =
        std::max(compensated_gap, static_cast<double>(std::abs(tail_compensated - tail_wide)));
    largest = std::max(largest, static_cast<double>(std::abs(tail_wide)));
  }
  std::printf(
      "N = %zu eps = %.0e K = %zu: max|tail| = %.3e; double vs long double %.3e, "
      "compensated vs long double %.3e\n",
      n, eps, terms, largest, plain_gap, compensated_gap);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (argc < 4 || (mode != "sum" && mode != "recursions")) {
    std::fprintf(stderr, "usage: %s sum N eps... | recursions N eps\n", argv[0]);
    return 2;
  }
  const std::size_t n = std::strtoull(argv[2], nullptr, 10);
  std::vector<double> tolerances;
  for (int a = 3; a < argc; ++a) tolerances.push_back(std::atof(argv[a]));
  if (mode == "sum") {
    sum_errors(n, tolerances);
  } else {
    recursion_round_off(n, tolerances.front());
  }
  return 0;
}
