#include "fracvi/fractional/exponential_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>

#include "tail_compression.hpp"

namespace fracvi {

namespace {

using detail::sample_lags;
using detail::trapezoidal_step;

constexpr double kPi = std::numbers::pi;

// Shares of ε, least-squares rows and verification lags: tail_compression.hpp.
using detail::kDiscretisationShare;
using detail::kFitDense;
using detail::kFitPerDecade;
using detail::kTruncationShare;
using detail::kVerifyDense;
using detail::kVerifyPerDecade;
using detail::kVerifySafety;
// If the verification fails even with all J nodes, retry with a finer step (never observed).
constexpr int kMaxAttempts = 4;
constexpr double kStepShrink = 0.8;
// BDF2 reference weights: ((3 − ζ)/2)^β has coefficients O(3^{−n}); 41 terms reach 3^{−40} ≈ 1e−19.
constexpr std::size_t kBdf2Terms = 41;

// Lags up to 2^50 keep m − β representable to ~1e-3 absolute, which Gamma(m − β)/Gamma(m + 1)
// tolerates (its relative sensitivity to m is (1 + β)/m); real runs are many orders below.
constexpr std::size_t kMaxFitLag = std::size_t{1} << 50;

bool is_integer(double x) {
  return std::floor(x) == x;
}

// The Laplace density times e^{−n0 s}: c_m = ∫ e^{−(m − n0)s} [ρ(s) e^{−n0 s}] ds (see header).
double shifted_density(CqScheme scheme, double beta, double n0, double s) {
  const double log_em1 = std::log(std::expm1(s));
  if (scheme == CqScheme::kGrunwaldLetnikov) {
    return -(std::sin(kPi * beta) / kPi) * std::exp(beta * log_em1 - n0 * s);
  }
  // BDF2: the second factor ((3 − ζ)/2)^β is real on (1, 3) and jumps again beyond ζ = 3.
  const double es = std::exp(s);
  if (es < 3.0) {
    return -(std::sin(kPi * beta) / kPi) *
           std::exp(beta * log_em1 + beta * std::log((3.0 - es) / 2.0) - n0 * s);
  }
  if (es == 3.0) return 0.0;
  return -(std::sin(2.0 * kPi * beta) / kPi) *
         std::exp(beta * log_em1 + beta * std::log((es - 3.0) / 2.0) - n0 * s);
}

struct Quadrature {
  std::vector<double> nodes;    // s_j
  std::vector<double> weights;  // q_j (shifted by the window)
};

Quadrature trapezoidal_nodes(CqScheme scheme, double beta, double eps, std::size_t window, double h,
                             double c_window, double c_max_lag) {
  // |ρ(s)| e^{−m s} ≤ P s^β for m ≥ β (GL) and m ≥ 2β (BDF2), and |ρ(s)| ≤ P e^{a s}.
  const double p =
      scheme == CqScheme::kGrunwaldLetnikov
          ? std::abs(std::sin(kPi * beta)) / kPi
          : std::max(std::abs(std::sin(kPi * beta)), std::abs(std::sin(2 * kPi * beta))) / kPi;
  const double a = scheme == CqScheme::kGrunwaldLetnikov ? beta : 2.0 * beta;
  const double n0 = static_cast<double>(window);
  const double target = kTruncationShare * eps;
  // Lower end: ∫_{−∞}^{u_lo} P e^{(1+β)u} du ≤ target·|c_N| at the largest lag.
  const double u_lo = std::log(target * c_max_lag * (1.0 + beta) / p) / (1.0 + beta);
  // Upper end: ∫_{s_hi}^{∞} P e^{−(n0 − a)s} ds ≤ target·|c_{n0}| at the first tail lag.
  const double s_hi = std::max(std::log(p / (target * c_window * (n0 - a))) / (n0 - a), 1e-3);
  const double u_hi = std::log(s_hi);
  // A bounded node count: an order whose weights underflow (c_max_lag = 0) would put u_lo at −∞.
  constexpr double kMaxNodes = 1e6;
  if (!std::isfinite(u_lo) || !std::isfinite(u_hi) || (u_hi - u_lo) / h > kMaxNodes) {
    throw std::invalid_argument(
        "fit_exponentials: the weights of order " + std::to_string(beta) +
        " are below the double range at the largest lag (no sum of exponentials can be verified)");
  }
  Quadrature quad;
  for (double u = u_hi; u >= u_lo; u -= h) {
    const double s = std::exp(u);
    const double q = h * s * shifted_density(scheme, beta, n0, s);
    if (q != 0.0 && std::isfinite(q)) {
      quad.nodes.push_back(s);
      quad.weights.push_back(q);
    }
  }
  return quad;
}

void validate(const ExponentialFitOptions& o, std::size_t window) {
  const auto fail = [](const std::string& msg) {
    throw std::invalid_argument("fit_exponentials: " + msg);
  };
  if (o.scheme == CqScheme::kTrapezoidal) {
    fail(
        "scheme = trapezoidal is not supported: its weights carry an oscillating tail "
        "(−1)^m m^{β−1} (branch point of (1 + ζ)^{−β} at ζ = −1); see "
        "docs/theory/fast_history.md");
  }
  // GL: the representation c_m = −(sin πβ/π) ∫ e^{−(m−β)s}(1 − e^{−s})^β ds holds for β > −1
  // (integrable at s = 0); BDF2's is used for 0 < β < 2 only.
  const double lowest = o.scheme == CqScheme::kGrunwaldLetnikov ? -1.0 : 0.0;
  if (!std::isfinite(o.order) || !(o.order > lowest) || !(o.order < 2.0) || is_integer(o.order)) {
    fail("order = " + std::to_string(o.order) + " must be non-integer in (" +
         (o.scheme == CqScheme::kGrunwaldLetnikov ? "-1" : "0") +
         ", 2) (integer orders >= 0 have finitely many weights: use LocalHistory)");
  }
  if (!(o.tolerance >= kMinFitTolerance) || !(o.tolerance <= kMaxFitTolerance)) {
    fail("tolerance = " + std::to_string(o.tolerance) + " must be in [1e-13, 1e-3]");
  }
  if (o.max_lag < 1) fail("max_lag = 0 must be >= 1");
  if (o.max_lag > kMaxFitLag) {
    fail("max_lag = " + std::to_string(o.max_lag) +
         " must be <= 2^50 (beyond, m − β is not representable to the accuracy the reference "
         "weights need)");
  }
  const std::size_t min_window = o.scheme == CqScheme::kBdf2 ? 5 : 2;  // m > β resp. m > 2β
  if (window < min_window) {
    fail("window = " + std::to_string(window) + " must be >= " + std::to_string(min_window) +
         " (the integral representation needs m > " + (o.scheme == CqScheme::kBdf2 ? "2β" : "β") +
         ")");
  }
}

struct Selection {
  std::vector<std::size_t> columns;
  std::vector<double> weights;
  double error = 0.0;
  double cancellation = 1.0;
};

}  // namespace

double ExponentialFit::weight(std::size_t m) const {
  if (m < window) return head[m];
  const double shift = static_cast<double>(m - window);
  double c = 0.0;
  for (std::size_t j = 0; j < lambdas.size(); ++j) c += weights[j] * std::exp(-lambdas[j] * shift);
  return c;
}

std::size_t default_fit_window(CqScheme scheme) {
  return scheme == CqScheme::kBdf2 ? 32 : 16;
}

double cq_weight(CqScheme scheme, double order, std::size_t m) {
  switch (scheme) {
    case CqScheme::kGrunwaldLetnikov: return gl_weight(order, m);
    case CqScheme::kTrapezoidal: return cq_weights(scheme, order, m + 1).back();
    case CqScheme::kBdf2: break;
  }
  if (m < 2 * kBdf2Terms) return cq_weights(scheme, order, m + 1).back();
  // δ(ζ)^β = ((3 − ζ)/2)^β (1 − ζ)^β, ((3 − ζ)/2)^β = (3/2)^β Σ_n α_n 3^{−n} ζ^n.
  std::array<double, kBdf2Terms> q{};
  q[0] = std::pow(1.5, order);
  for (std::size_t n = 1; n < kBdf2Terms; ++n) {
    q[n] = q[n - 1] * (static_cast<double>(n) - 1.0 - order) / (3.0 * static_cast<double>(n));
  }
  // c_{m−n} for n = kBdf2Terms − 1 … 0 by the recurrence from one Gamma-ratio anchor.
  std::size_t j = m - (kBdf2Terms - 1);
  double c = gl_weight(order, j);
  double sum = q[kBdf2Terms - 1] * c;
  for (std::size_t n = kBdf2Terms - 1; n-- > 0;) {
    c *= (static_cast<double>(j) - order) / static_cast<double>(j + 1);
    ++j;
    sum += q[n] * c;
  }
  return sum;
}

ExponentialFit fit_exponentials(const ExponentialFitOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t lagged_window =
      options.window == 0 ? default_fit_window(options.scheme) : options.window;
  validate(options, lagged_window);
  const double beta = options.order;
  const double eps = options.tolerance;
  // A lagged fit (weights c_{m+lag}) is the fit of the plain weights with the window n0 + lag and
  // lags up to max_lag + lag: below, `window` and the lags index the plain sequence; the shift
  // m − window of the tail is the same in both indexings.
  const std::size_t window = lagged_window + options.lag;
  const std::size_t max_lag = options.max_lag + options.lag;

  ExponentialFit fit;
  fit.scheme = options.scheme;
  fit.order = beta;
  fit.tolerance = eps;
  fit.max_lag = options.max_lag;
  fit.window = lagged_window;
  fit.lag = options.lag;
  fit.head = cq_weights(options.scheme, beta, window);
  fit.head.erase(fit.head.begin(), fit.head.begin() + static_cast<std::ptrdiff_t>(options.lag));
  const auto finish = [&]() {
    fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return fit;
  };
  if (max_lag < window) return finish();  // every lag is in the exact window

  // Exact weights at the least-squares rows and at the verification lags.
  const std::vector<std::size_t> fit_lags = sample_lags(window, max_lag, kFitDense, kFitPerDecade);
  const std::vector<std::size_t> check_lags =
      sample_lags(window, max_lag, kVerifyDense, kVerifyPerDecade);
  const auto rows = static_cast<Eigen::Index>(fit_lags.size());
  const auto checks = static_cast<Eigen::Index>(check_lags.size());
  Eigen::VectorXd c_fit(rows), c_check(checks);
  {
    // The check lags contain the fit lags' dense part; evaluate each lag once.
    std::map<std::size_t, double> exact;
    for (const std::size_t m : check_lags) exact[m] = cq_weight(options.scheme, beta, m);
    for (Eigen::Index i = 0; i < rows; ++i) {
      const auto it = exact.find(fit_lags[i]);
      c_fit(i) = it != exact.end() ? it->second : cq_weight(options.scheme, beta, fit_lags[i]);
    }
    for (Eigen::Index i = 0; i < checks; ++i) c_check(i) = exact[check_lags[i]];
  }
  fit.verification_lags = check_lags.size();

  const double h0 = trapezoidal_step(beta, kDiscretisationShare * eps);
  double last_error = 0.0;
  for (int attempt = 0; attempt < kMaxAttempts; ++attempt) {
    const double h = h0 * std::pow(kStepShrink, attempt);
    const Quadrature quad = trapezoidal_nodes(options.scheme, beta, eps, window, h,
                                              std::abs(c_check(0)), std::abs(c_check(checks - 1)));
    const auto nodes = static_cast<Eigen::Index>(quad.nodes.size());
    fit.quadrature_nodes = quad.nodes.size();
    fit.quadrature_step = h;

    // E_check(v, j) = e^{−s_j (m_v − n0)}: the exponentials at the verification lags.
    Eigen::MatrixXd e_check(checks, nodes);
    for (Eigen::Index j = 0; j < nodes; ++j)
      for (Eigen::Index v = 0; v < checks; ++v)
        e_check(v, j) = std::exp(-quad.nodes[j] * static_cast<double>(check_lags[v] - window));

    const auto evaluate = [&](const std::vector<std::size_t>& cols, const std::vector<double>& w) {
      Selection sel{cols, w, 0.0, 1.0};
      for (Eigen::Index v = 0; v < checks; ++v) {
        double approx = 0.0, magnitude = 0.0;
        for (std::size_t k = 0; k < cols.size(); ++k) {
          const double term = w[k] * e_check(v, static_cast<Eigen::Index>(cols[k]));
          approx += term;
          magnitude += std::abs(term);
        }
        sel.error = std::max(sel.error, std::abs(approx / c_check(v) - 1.0));
        sel.cancellation = std::max(sel.cancellation, magnitude / std::abs(c_check(v)));
      }
      return sel;
    };

    Selection best;
    if (!options.compress) {
      std::vector<std::size_t> all(quad.nodes.size());
      std::iota(all.begin(), all.end(), std::size_t{0});
      best = evaluate(all, quad.weights);
    } else {
      // Relative-error design matrix, columns scaled by the quadrature weights so that the
      // all-ones vector reproduces the quadrature: the pivoting then ranks the exponentials by
      // their contribution to the relative error, and v stays O(1).
      Eigen::MatrixXd a(rows, nodes);
      Eigen::VectorXd b(rows);
      for (Eigen::Index i = 0; i < rows; ++i) {
        const double scale = 1.0 / std::abs(c_fit(i));
        b(i) = c_fit(i) * scale;
        for (Eigen::Index j = 0; j < nodes; ++j) {
          a(i, j) = quad.weights[j] * scale *
                    std::exp(-quad.nodes[j] * static_cast<double>(fit_lags[i] - window));
        }
      }
      best = detail::select_pivoted_terms(a, b, quad.weights, kVerifySafety * eps,
                                          detail::kSweepStep, evaluate);
    }
    last_error = best.error;
    if (!options.compress || best.error <= kVerifySafety * eps) {
      // Ascending λ.
      std::vector<std::size_t> order(best.columns.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
        return quad.nodes[best.columns[x]] < quad.nodes[best.columns[y]];
      });
      for (const std::size_t t : order) {
        fit.lambdas.push_back(quad.nodes[best.columns[t]]);
        fit.weights.push_back(best.weights[t]);
      }
      fit.max_relative_error = best.error;
      fit.cancellation = best.cancellation;
      return finish();
    }
  }
  throw std::runtime_error("fit_exponentials: could not verify the tolerance " +
                           std::to_string(eps) + " (measured relative error " +
                           std::to_string(last_error) + ")");
}

namespace {

using CacheKey = std::tuple<int, double, double, std::size_t, std::size_t, std::size_t, bool>;

struct FitCache {
  std::mutex mutex;
  std::map<CacheKey, std::shared_ptr<const ExponentialFit>> fits;
};

FitCache& fit_cache() {
  static FitCache cache;
  return cache;
}

}  // namespace

std::shared_ptr<const ExponentialFit> shared_exponential_fit(const ExponentialFitOptions& options) {
  ExponentialFitOptions resolved = options;
  if (resolved.window == 0) resolved.window = default_fit_window(resolved.scheme);
  // Validate before the lookup: a NaN order would compare equivalent to every key of the map.
  validate(resolved, resolved.window);
  const CacheKey key{static_cast<int>(resolved.scheme),
                     resolved.order,
                     resolved.tolerance,
                     resolved.max_lag,
                     resolved.window,
                     resolved.lag,
                     resolved.compress};
  FitCache& cache = fit_cache();
  {
    const std::lock_guard<std::mutex> lock(cache.mutex);
    const auto it = cache.fits.find(key);
    if (it != cache.fits.end()) return it->second;
  }
  // Fit outside the lock (milliseconds); if another thread got there first, keep its fit.
  auto fit = std::make_shared<const ExponentialFit>(fit_exponentials(resolved));
  const std::lock_guard<std::mutex> lock(cache.mutex);
  return cache.fits.emplace(key, std::move(fit)).first->second;
}

void clear_exponential_fit_cache() {
  FitCache& cache = fit_cache();
  const std::lock_guard<std::mutex> lock(cache.mutex);
  cache.fits.clear();
}

std::size_t exponential_fit_cache_size() {
  FitCache& cache = fit_cache();
  const std::lock_guard<std::mutex> lock(cache.mutex);
  return cache.fits.size();
}

}  // namespace fracvi
