#include "fracvi/model/chain_potential.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "fracvi/internal/parallel.hpp"
#include "fracvi/internal/vectorize.hpp"

namespace fracvi {

std::optional<ChainBoundary> parse_chain_boundary(std::string_view name) {
  if (name == "fixed") return ChainBoundary::kFixed;
  if (name == "free") return ChainBoundary::kFree;
  if (name == "periodic") return ChainBoundary::kPeriodic;
  return std::nullopt;
}

std::string_view to_string(ChainBoundary boundary) {
  switch (boundary) {
    case ChainBoundary::kFixed: return "fixed";
    case ChainBoundary::kFree: return "free";
    case ChainBoundary::kPeriodic: return "periodic";
  }
  return "unknown";
}

namespace {

// V(r) = ½ k r² + (a/3) r³ + (b/4) r⁴ and its derivatives.
struct Spring {
  double k, a, b;
  // V(r) = k r²/2 + a r³/3 + b r⁴/4; for a double or an Eigen array expression (one expression,
  // so that an array's result holds no reference to a local).
  template <class R>
  [[nodiscard]] auto energy(const R& r) const {
    return r * r * (0.5 * k + r * (a / 3.0 + 0.25 * b * r));
  }
  [[nodiscard]] double force(double r) const { return r * (k + r * (a + b * r)); }  // V'
  [[nodiscard]] bool linear() const { return a == 0.0 && b == 0.0; }
  [[nodiscard]] double stiffness(double r) const { return k + r * (2.0 * a + 3.0 * b * r); }  // V''
};

// The neighbours of i: x_{i−1} and x_{i+1} with the boundary's convention, and whether the bond
// exists (free ends have one bond only).
struct Neighbours {
  double left = 0.0, right = 0.0;
  bool has_left = true, has_right = true;
};

Neighbours neighbours(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Index i, Eigen::Index d,
                      ChainBoundary boundary) {
  Neighbours n;
  switch (boundary) {
    case ChainBoundary::kFixed:  // walls at rest
      n.left = i > 0 ? x[i - 1] : 0.0;
      n.right = i + 1 < d ? x[i + 1] : 0.0;
      break;
    case ChainBoundary::kFree:
      n.has_left = i > 0;
      n.has_right = i + 1 < d;
      n.left = n.has_left ? x[i - 1] : 0.0;
      n.right = n.has_right ? x[i + 1] : 0.0;
      break;
    case ChainBoundary::kPeriodic:
      n.left = x[i > 0 ? i - 1 : d - 1];
      n.right = x[i + 1 < d ? i + 1 : 0];
      break;
  }
  return n;
}

// Runs edge(i) for the end masses 0 and d − 1 and interior(i) for 0 < i < d − 1 within [lo, hi):
// the interior loop has no boundary branches, so the compiler vectorises it. An interior callable
// of two indices gets the interior range [first, last) at once (a reduction written as one Eigen
// expression, which a per-index loop with a running sum would not vectorise).
template <class Edge, class Interior>
void by_position(Eigen::Index lo, Eigen::Index hi, Eigen::Index d, Edge&& edge,
                 Interior&& interior) {
  const Eigen::Index first = std::max<Eigen::Index>(lo, 1), last = std::min(hi, d - 1);
  if (lo == 0) edge(Eigen::Index{0});
  if constexpr (std::is_invocable_v<Interior, Eigen::Index, Eigen::Index>) {
    if (last > first) interior(first, last);  // the whole interior range [first, last) at once
  } else {
    for (Eigen::Index i = first; i < last; ++i) interior(i);
  }
  if (hi == d && d > 1) edge(d - 1);
}

int chain_threads(const ChainOptions& o) {
  return internal::team_size(o.threads, o.dimension, kChainParallelDofs);
}

// The interior masses' part of the gradient and of the energy, over [first, last): a large
// chain's share of its step (the force once per Newton iteration, the energy every step), with an
// x86-64-v3 clone (internal/vectorize.hpp). d = 1000, linear chain, one thread, perf samples of the
// portable build against a whole x86-64-v3 build: 384 → 169 (gradient), 320 → 132 (energy). Only
// the loop is in the clone: the end masses' neighbours() call from inside a clone, after its
// 256-bit loop, left the upper halves of the vector registers dirty (GCC put no vzeroupper before
// that call) and every SSE instruction of the rest of the step ran slow — the step took 23–31 µs
// against 15–17.
// A linear spring (a = b = 0) has its own clones, with the bond's polynomial folded to its
// constant: k + r (0 + 0·r) is k exactly for finite r (0·r is ±0, 0 + ±0 is +0, r·(+0) is ±0 and
// k ± 0 is k), and ½k + r (0/3 + ¼·0·r) is ½k, so the linear kernels do the same roundings in the
// same expression tree with two multiplications and two multiply–adds fewer per mass (chain
// force 4.6 → 2.8 k instructions a step at d = 1000, energy 3.6 → 2.8 k; every example's
// trajectory cmp-equal).
template <bool kLinear>
[[gnu::always_inline]] inline void gradient_loop(const double* x, double* g, Eigen::Index first,
                                                 Eigen::Index last, Spring v, double c) {
  for (Eigen::Index i = first; i < last; ++i) {
    if constexpr (kLinear) {
      g[i] = c * x[i] + (x[i] - x[i - 1]) * v.k - (x[i + 1] - x[i]) * v.k;
    } else {
      g[i] = c * x[i] + v.force(x[i] - x[i - 1]) - v.force(x[i + 1] - x[i]);
    }
  }
}

// Σ over the interior masses of the onsite energy and the right bond's, in any order (a running
// sum over the masses would be a chain of dependent additions, ≈ 4 cycles a mass).
template <bool kLinear>
[[gnu::always_inline]] inline double energy_loop(const double* x, Eigen::Index first,
                                                 Eigen::Index last, Spring v, double c) {
  const double half_k = 0.5 * v.k;
  double total = 0.0;
#pragma omp simd reduction(+ : total)
  for (Eigen::Index i = first; i < last; ++i) {
    const double r = x[i + 1] - x[i];
    if constexpr (kLinear) {
      total += (0.5 * c) * (x[i] * x[i]) + r * r * half_k;
    } else {
      total += (0.5 * c) * (x[i] * x[i]) + v.energy(r);
    }
  }
  return total;
}

FRACVI_HOT_KERNEL
void chain_gradient_interior(const double* x, double* g, Eigen::Index first, Eigen::Index last,
                             Spring v, double c) {
  gradient_loop<false>(x, g, first, last, v, c);
}
FRACVI_HOT_KERNEL
void linear_chain_gradient_interior(const double* x, double* g, Eigen::Index first,
                                    Eigen::Index last, Spring v, double c) {
  gradient_loop<true>(x, g, first, last, v, c);
}
FRACVI_HOT_KERNEL
double chain_energy_interior(const double* x, Eigen::Index first, Eigen::Index last, Spring v,
                             double c) {
  return energy_loop<false>(x, first, last, v, c);
}
FRACVI_HOT_KERNEL
double linear_chain_energy_interior(const double* x, Eigen::Index first, Eigen::Index last,
                                    Spring v, double c) {
  return energy_loop<true>(x, first, last, v, c);
}

}  // namespace

ChainPotential::ChainPotential(const ChainOptions& options) : options_(options) {
  const Eigen::Index d = options.dimension;
  const Eigen::Index minimum = options.boundary == ChainBoundary::kPeriodic ? 3
                               : options.boundary == ChainBoundary::kFree   ? 2
                                                                            : 1;
  if (d < minimum) {
    throw std::invalid_argument("chain.dim = " + std::to_string(d) +
                                " must be >= " + std::to_string(minimum) +
                                " for boundary = " + std::string(to_string(options.boundary)));
  }
  const std::pair<const char*, double> coefficients[] = {{"chain.stiffness", options.stiffness},
                                                         {"chain.cubic", options.cubic},
                                                         {"chain.quartic", options.quartic},
                                                         {"chain.onsite", options.onsite}};
  for (const auto& [name, value] : coefficients) {
    if (!std::isfinite(value)) {
      throw std::invalid_argument(std::string(name) + " must be finite");
    }
  }
  if (options.threads < 0) {
    throw std::invalid_argument("chain.threads = " + std::to_string(options.threads) +
                                " must be >= 0 (0 = all cores)");
  }
  internal::start_threads(chain_threads(options_));  // set-up, not the step loop, allocates
}

double ChainPotential::value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const {
  const Spring v{options_.stiffness, options_.cubic, options_.quartic};
  const Eigen::Index d = options_.dimension;
  const ChainBoundary boundary = options_.boundary;
  const double c = options_.onsite;
  // Each bond once, as the right bond of its left mass (the fixed chain adds the left wall bond).
  // The interior's energies as one vectorised sum (chain_energy_interior): a running sum over the
  // masses is a chain of dependent additions, ≈ 4 cycles a mass (4.5 % of the linear chain's step
  // at d = 1000 in perf, for an energy evaluated every step).
  return internal::sum_blocks(d, chain_threads(options_), [&](Eigen::Index lo, Eigen::Index hi) {
    double total = 0.0;
    by_position(
        lo, hi, d,
        [&](Eigen::Index i) {
          const Neighbours n = neighbours(x, i, d, boundary);
          double e = 0.5 * c * x[i] * x[i];
          if (n.has_right) e += v.energy(n.right - x[i]);
          if (i == 0 && boundary == ChainBoundary::kFixed) e += v.energy(x[0]);
          total += e;
        },
        [&](Eigen::Index first, Eigen::Index last) {
          total += v.linear() ? linear_chain_energy_interior(x.data(), first, last, v, c)
                              : chain_energy_interior(x.data(), first, last, v, c);
        });
    return total;
  });
}

void ChainPotential::gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                              Eigen::Ref<Eigen::VectorXd> g) const {
  internal::for_blocks(
      options_.dimension, chain_threads(options_),
      [&](Eigen::Index lo, Eigen::Index hi) { gradient_rows(x, t, g.data(), lo, hi); });
}

void ChainPotential::gradient_rows(const Eigen::Ref<const Eigen::VectorXd>& x, double, double* g,
                                   Eigen::Index lo, Eigen::Index hi) const {
  const Spring v{options_.stiffness, options_.cubic, options_.quartic};
  const Eigen::Index d = options_.dimension;
  const ChainBoundary boundary = options_.boundary;
  const double c = options_.onsite;
  by_position(
      lo, hi, d,
      [&](Eigen::Index i) {
        const Neighbours n = neighbours(x, i, d, boundary);
        double gi = c * x[i];
        if (n.has_left) gi += v.force(x[i] - n.left);
        if (n.has_right) gi -= v.force(n.right - x[i]);
        g[i] = gi;
      },
      [&](Eigen::Index first, Eigen::Index last) {
        if (v.linear()) {
          linear_chain_gradient_interior(x.data(), g, first, last, v, c);
        } else {
          chain_gradient_interior(x.data(), g, first, last, v, c);
        }
      });
}

std::vector<Potential::HessianEntry> ChainPotential::hessian_pattern() const {
  const Eigen::Index d = options_.dimension;
  std::vector<HessianEntry> pattern;
  pattern.reserve(static_cast<std::size_t>(2 * d));
  for (Eigen::Index i = 0; i < d; ++i) pattern.push_back({i, i});
  for (Eigen::Index i = 0; i + 1 < d; ++i) pattern.push_back({i, i + 1});
  if (options_.boundary == ChainBoundary::kPeriodic) pattern.push_back({0, d - 1});
  return pattern;
}

namespace {

// ∇²U entry by entry, shared by the sparse values and the dense matrix: diagonal(i, h_ii) for every
// i, upper(i, h_{i,i+1}) for i < d − 1, and corner(h_{0,d−1}) when periodic. Split over `threads`.
template <class Diagonal, class Upper, class Corner>
void hessian_entries(const ChainOptions& o, const Eigen::Ref<const Eigen::VectorXd>& x, int threads,
                     Diagonal&& diagonal, Upper&& upper, Corner&& corner) {
  const Spring v{o.stiffness, o.cubic, o.quartic};
  const Eigen::Index d = o.dimension;
  internal::for_blocks(d, threads, [&](Eigen::Index lo, Eigen::Index hi) {
    by_position(
        lo, hi, d,
        [&](Eigen::Index i) {
          const Neighbours n = neighbours(x, i, d, o.boundary);
          double hii = o.onsite;
          if (n.has_left) hii += v.stiffness(x[i] - n.left);
          if (n.has_right) hii += v.stiffness(n.right - x[i]);
          diagonal(i, hii);
          if (i + 1 < d) upper(i, -v.stiffness(x[i + 1] - x[i]));
        },
        [&](Eigen::Index i) {
          const double right = v.stiffness(x[i + 1] - x[i]);
          diagonal(i, o.onsite + v.stiffness(x[i] - x[i - 1]) + right);
          upper(i, -right);
        });
  });
  if (o.boundary == ChainBoundary::kPeriodic) corner(-v.stiffness(x[0] - x[d - 1]));
}

}  // namespace

void ChainPotential::hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                                    std::span<double> values) const {
  // Pattern order: the diagonal, then (i, i+1), then the corner (hessian_pattern()).
  const Eigen::Index d = options_.dimension;
  double* diagonal = values.data();
  double* upper = values.data() + d;
  hessian_entries(
      options_, x, chain_threads(options_), [&](Eigen::Index i, double h) { diagonal[i] = h; },
      [&](Eigen::Index i, double h) { upper[i] = h; },
      [&](double h) { values[static_cast<std::size_t>(2 * d - 1)] = h; });
}

void ChainPotential::hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                             Eigen::Ref<Eigen::MatrixXd> H) const {
  // The dense form (small chains on the dense path): one thread, no allocation.
  const Eigen::Index d = options_.dimension;
  H.setZero();
  hessian_entries(
      options_, x, 1, [&](Eigen::Index i, double h) { H(i, i) = h; },
      [&](Eigen::Index i, double h) { H(i, i + 1) = H(i + 1, i) = h; },
      [&](double h) { H(0, d - 1) = H(d - 1, 0) = h; });
}

std::shared_ptr<const Potential> make_chain_potential(const ChainOptions& options) {
  return std::make_shared<const ChainPotential>(options);
}

}  // namespace fracvi
