#include "fracvi/fractional/weights.hpp"

#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fracvi {

std::optional<CqScheme> parse_cq_scheme(std::string_view name) {
  if (name == "gl") return CqScheme::kGrunwaldLetnikov;
  if (name == "bdf2") return CqScheme::kBdf2;
  if (name == "trapezoidal") return CqScheme::kTrapezoidal;
  return std::nullopt;
}

std::string_view to_string(CqScheme scheme) {
  switch (scheme) {
    case CqScheme::kGrunwaldLetnikov: return "gl";
    case CqScheme::kBdf2: return "bdf2";
    case CqScheme::kTrapezoidal: return "trapezoidal";
  }
  return "unknown";
}

namespace {

bool is_nonnegative_integer(double order) {
  return order >= 0.0 && std::floor(order) == order;
}

void require_finite(double order, const char* where) {
  if (!std::isfinite(order)) {
    throw std::invalid_argument(std::string(where) + ": order = " + std::to_string(order) +
                                " must be finite");
  }
}

}  // namespace

double gl_weight(double order, std::size_t n) {
  require_finite(order, "gl_weight");
  if (n == 0) return 1.0;
  const double nd = static_cast<double>(n);
  if (is_nonnegative_integer(order)) {
    // (−1)^n binom(order, n): exact through the recurrence, zero beyond the degree.
    if (nd > order) return 0.0;
    double w = 1.0;
    for (std::size_t j = 1; j <= n; ++j)
      w *= (static_cast<double>(j) - 1.0 - order) / static_cast<double>(j);
    return w;
  }
  if (nd <= order + 1.0) {
    // Few leading weights of a large order: the recurrence is short and exact enough.
    double w = 1.0;
    for (std::size_t j = 1; j <= n; ++j)
      w *= (static_cast<double>(j) - 1.0 - order) / static_cast<double>(j);
    return w;
  }
  // α_n = Γ(n − β) / (Γ(−β) Γ(n + 1)); tgamma_delta_ratio(a, δ) = Γ(a)/Γ(a + δ).
  return boost::math::tgamma_delta_ratio(nd - order, 1.0 + order) / boost::math::tgamma(-order);
}

void gl_weights(double order, std::span<double> out) {
  require_finite(order, "gl_weights");
  if (out.empty()) return;
  const bool exact = is_nonnegative_integer(order);
  out[0] = 1.0;
  for (std::size_t n = 1; n < out.size(); ++n) {
    if (!exact && n % kGlAnchorInterval == 0 && static_cast<double>(n) > order + 1.0) {
      out[n] = gl_weight(order, n);  // re-anchor: stops the recurrence's error from growing
    } else {
      out[n] = out[n - 1] * ((static_cast<double>(n) - 1.0 - order) / static_cast<double>(n));
    }
  }
}

std::vector<double> gl_weights(double order, std::size_t count) {
  std::vector<double> w(count);
  gl_weights(order, std::span<double>(w));
  return w;
}

std::vector<double> rational_power_series(std::span<const double> p, std::span<const double> q,
                                          double order, std::size_t count) {
  require_finite(order, "rational_power_series");
  if (p.empty() || q.empty() || !(p[0] > 0.0) || !(q[0] > 0.0)) {
    throw std::invalid_argument(
        "rational_power_series: P(0) and Q(0) must be positive (the power is taken on the "
        "principal branch at ζ = 0)");
  }
  // A = P·Q and B = β (P′Q − PQ′), so that g′ A = B g.
  const std::size_t deg_a = p.size() + q.size() - 2;
  std::vector<double> a(deg_a + 1, 0.0), b(deg_a + 1, 0.0);
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = 0; j < q.size(); ++j) a[i + j] += p[i] * q[j];
  for (std::size_t i = 1; i < p.size(); ++i)  // P′Q
    for (std::size_t j = 0; j < q.size(); ++j)
      b[i - 1 + j] += order * static_cast<double>(i) * p[i] * q[j];
  for (std::size_t i = 0; i < p.size(); ++i)  // −PQ′
    for (std::size_t j = 1; j < q.size(); ++j)
      b[i + j - 1] -= order * static_cast<double>(j) * p[i] * q[j];

  std::vector<double> g(count, 0.0);
  if (count == 0) return g;
  g[0] = std::pow(p[0] / q[0], order);
  // Coefficient of ζ^n in g′A − Bg = 0:
  //   Σ_j A_j (n − j + 1) g_{n−j+1} = Σ_j B_j g_{n−j},  solved for g_{n+1} (j = 0 term).
  for (std::size_t n = 0; n + 1 < count; ++n) {
    double rhs = 0.0;
    for (std::size_t j = 0; j <= deg_a && j <= n; ++j) rhs += b[j] * g[n - j];
    for (std::size_t j = 1; j <= deg_a && j <= n + 1; ++j)
      rhs -= a[j] * static_cast<double>(n - j + 1) * g[n - j + 1];
    g[n + 1] = rhs / (a[0] * static_cast<double>(n + 1));
  }
  return g;
}

std::vector<double> cq_weights(CqScheme scheme, double order, std::size_t count) {
  switch (scheme) {
    case CqScheme::kGrunwaldLetnikov: return gl_weights(order, count);
    case CqScheme::kBdf2: {
      // (1 − ζ) + (1 − ζ)²/2 = 3/2 − 2ζ + ζ²/2
      const double p[] = {1.5, -2.0, 0.5}, q[] = {1.0};
      return rational_power_series(p, q, order, count);
    }
    case CqScheme::kTrapezoidal: {
      const double p[] = {2.0, -2.0}, q[] = {1.0, 1.0};
      return rational_power_series(p, q, order, count);
    }
  }
  throw std::invalid_argument("cq_weights: unknown scheme");
}

}  // namespace fracvi
