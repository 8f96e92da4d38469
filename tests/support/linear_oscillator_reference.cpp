#include "linear_oscillator_reference.hpp"

#include <algorithm>
#include <boost/math/quadrature/exp_sinh.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

// Derivation of the Caputo Laplace rule used in laplace_transform (n = ⌈β⌉):
//   D^β_C x = I^{n−β} x^{(n)}, so L{D^β_C x} = s^{β−n} L{x^{(n)}}
//           = s^{β−n} (s^n X − Σ_{k<n} s^{n−1−k} x^{(k)}(0)) = s^β X − Σ_{k<n} s^{β−1−k}
//           x^{(k)}(0):
//   β < 1 (n = 1): s^β X − s^{β−1} x0;  1 < β < 2 (n = 2): s^β X − s^{β−1} x0 − s^{β−2} v0;
//   β = 1: s X − x0 (both formulas agree, s^{β−2} v0 term absent).
// With L{x''} = s² X − s x0 − v0 the transformed equation is
//   (M s² + R s^β + K) X = (M s + R s^{β−1}) x0 + (M + [β > 1] R s^{β−2}) v0.
// RL: D^β_RL x = d/dt I^{1−β} x, L = s L{I^{1−β} x} − (I^{1−β} x)(0⁺) = s^β X, since
// |I^{1−β} x (t)| ≤ max|x| t^{1−β}/Γ(2−β) → 0.

namespace fracvi::test {
namespace {

using Complex = std::complex<double>;
using MatrixXc = Eigen::MatrixXcd;
using VectorXc = Eigen::VectorXcd;
constexpr double kPi = std::numbers::pi;

/// s^γ on the principal branch for s = r e^{iθ} given in polar form (no branch ambiguity on the
/// cut).
Complex polar_pow(double r, double theta, double gamma) {
  return std::polar(std::pow(r, gamma), gamma * theta);
}

struct Polar {
  double r;
  double theta;
};

Polar to_polar(Complex s) {
  return {std::abs(s), std::arg(s)};
}

MatrixXc q_matrix(const LinearOscillator& p, Polar s) {
  const Complex s1 = std::polar(s.r, s.theta);
  return p.mass.cast<Complex>() * (s1 * s1) +
         p.damping.cast<Complex>() * polar_pow(s.r, s.theta, p.beta) + p.stiffness.cast<Complex>();
}

MatrixXc q_derivative(const LinearOscillator& p, Polar s) {
  const Complex s1 = std::polar(s.r, s.theta);
  return p.mass.cast<Complex>() * (2.0 * s1) +
         p.damping.cast<Complex>() * (p.beta * polar_pow(s.r, s.theta, p.beta - 1.0));
}

VectorXc numerator(const LinearOscillator& p, Polar s) {
  const Complex s1 = std::polar(s.r, s.theta);
  const VectorXc x0 = p.x0.cast<Complex>();
  const VectorXc v0 = p.v0.cast<Complex>();
  const MatrixXc m = p.mass.cast<Complex>();
  const MatrixXc r = p.damping.cast<Complex>();
  VectorXc out;
  if (p.convention == ReferenceConvention::kRiemannLiouville) {
    out = m * (s1 * x0 + v0);
  } else {
    out = (m * s1 + r * polar_pow(s.r, s.theta, p.beta - 1.0)) * x0 + m * v0;
    if (p.beta > 1.0) out += r * (polar_pow(s.r, s.theta, p.beta - 2.0) * v0);
  }
  // L{t^q} = Γ(q+1) s^{−q−1}.
  for (const PowerTerm& term : p.forcing) {
    out += term.coefficient.cast<Complex>() *
           (std::tgamma(term.exponent + 1.0) * polar_pow(s.r, s.theta, -term.exponent - 1.0));
  }
  return out;
}

Complex det_q(const LinearOscillator& p, Complex s) {
  return q_matrix(p, to_polar(s)).partialPivLu().determinant();
}

/// Total change of arg det Q along s(u), u ∈ [a, b], with adaptive subdivision so that no
/// sub-step turns the phase by more than π/8 and halves agree with the whole.
double phase_change(const LinearOscillator& p, const auto& path, double a, double b, Complex fa,
                    Complex fb, int depth) {
  const double whole = std::arg(fb / fa);
  const double mid = 0.5 * (a + b);
  const Complex fm = det_q(p, path(mid));
  const double left = std::arg(fm / fa);
  const double right = std::arg(fb / fm);
  if (depth > 40 || (std::abs(whole) < kPi / 8 && std::abs(left + right - whole) < 1e-10)) {
    return left + right;
  }
  return phase_change(p, path, a, mid, fa, fm, depth + 1) +
         phase_change(p, path, mid, b, fm, fb, depth + 1);
}

double path_phase(const LinearOscillator& p, const auto& path, double a, double b) {
  constexpr int kPieces = 256;
  double total = 0.0;
  Complex prev = det_q(p, path(a));
  for (int i = 1; i <= kPieces; ++i) {
    const double u1 = a + (b - a) * i / kPieces;
    const double u0 = a + (b - a) * (i - 1) / kPieces;
    const Complex next = det_q(p, path(u1));
    total += phase_change(p, path, u0, u1, prev, next, 0);
    prev = next;
  }
  return total;
}

/// Number of zeros of det Q in {Im s > 0, ε < |s| < ρ} by the argument principle.
int count_upper_zeros(const LinearOscillator& p, double rho) {
  static constexpr double kEps = 1e-8;
  const double log_eps = std::log(kEps);
  const double log_rho = std::log(rho);
  // Counter-clockwise boundary: [ε, ρ] on θ = 0, the arc |s| = ρ, the upper cut side θ = π back
  // from ρ to ε, and the small arc |s| = ε clockwise. Radial legs in log r (zeros near 0 and
  // near ρ are equally resolved).
  const auto positive_axis = [](double u) { return Complex(std::exp(u), 0.0); };
  const auto big_arc = [rho](double th) { return std::polar(rho, th); };
  const auto cut_side = [](double u) { return std::polar(std::exp(u), kPi); };
  const auto small_arc = [](double th) { return std::polar(kEps, th); };
  double total = path_phase(p, positive_axis, log_eps, log_rho);
  total += path_phase(p, big_arc, 0.0, kPi);
  total += path_phase(p, cut_side, log_rho, log_eps);
  total += path_phase(p, small_arc, kPi, 0.0);
  const double windings = total / (2 * kPi);
  const double rounded = std::round(windings);
  if (std::abs(windings - rounded) > 0.05) {
    throw std::runtime_error("argument principle: non-integer winding " + std::to_string(windings));
  }
  return static_cast<int>(rounded);
}

/// σ_min(Q(s)) relative to the size of its terms, ‖M‖|s|² + ‖R‖|s|^β + ‖K‖: how singular Q(s)
/// is (0 at a zero of det Q; a plain σ_min/σ_max would be 1 for d = 1).
double singularity(const LinearOscillator& p, Complex s) {
  const Polar ps = to_polar(s);
  const Eigen::JacobiSVD<MatrixXc> svd(q_matrix(p, ps));
  const auto& sv = svd.singularValues();
  const double scale =
      p.mass.norm() * ps.r * ps.r + p.damping.norm() * std::pow(ps.r, p.beta) + p.stiffness.norm();
  return sv(sv.size() - 1) / scale;
}

/// Newton on det Q(s), whose step is det/det' = 1/tr(Q^{-1} Q'), with the step length capped at
/// |s|/2 (so that iterates cannot jump across the branch point). No deflation: a root found from
/// one guess is simply found again from another and deduplicated by the caller; what counts is
/// that every accepted point is a zero (checked by singularity() ≤ kZeroTol).
std::optional<Complex> newton_zero(const LinearOscillator& p, Complex s) {
  constexpr double kZeroTol = 1e-11;
  for (int it = 0; it < 100; ++it) {
    if (singularity(p, s) <= 1e-15) return s;  // exactly singular: the LU solve below would fail
    const Polar ps = to_polar(s);
    const Complex slope = q_matrix(p, ps).fullPivLu().solve(q_derivative(p, ps)).trace();
    if (!std::isfinite(slope.real()) || !std::isfinite(slope.imag())) return std::nullopt;
    Complex step = 1.0 / slope;
    const double max_step = 0.5 * std::abs(s);
    if (std::abs(step) > max_step) step *= max_step / std::abs(step);
    s -= step;
    if (std::abs(step) <= 1e-14 * std::abs(s)) {
      if (singularity(p, s) <= kZeroTol) return s;
      return std::nullopt;
    }
  }
  return std::nullopt;
}

/// exp_sinh tables are built once (construction is the expensive part).
boost::math::quadrature::exp_sinh<double>& cut_integrator() {
  static boost::math::quadrature::exp_sinh<double> integrator;
  return integrator;
}

double gamma_power_ratio(double t, double mu) {
  // t^{μ−1}/Γ(μ); tgamma and pow are accurate to a few ulps where the terms are large.
  if (t == 0.0) return mu == 1.0 ? 1.0 : 0.0;
  if (mu < 170.0) return std::pow(t, mu - 1.0) / std::tgamma(mu);
  return std::exp((mu - 1.0) * std::log(t) - std::lgamma(mu));
}

}  // namespace

LinearOscillator LinearOscillator::scalar(double m, double r, double k, double beta, double x0,
                                          double v0, ReferenceConvention convention) {
  LinearOscillator p;
  p.mass = Eigen::MatrixXd::Constant(1, 1, m);
  p.damping = Eigen::MatrixXd::Constant(1, 1, r);
  p.stiffness = Eigen::MatrixXd::Constant(1, 1, k);
  p.beta = beta;
  p.x0 = Eigen::VectorXd::Constant(1, x0);
  p.v0 = Eigen::VectorXd::Constant(1, v0);
  p.convention = convention;
  return p;
}

void LinearOscillator::validate() const {
  const Eigen::Index d = mass.rows();
  if (d == 0 || mass.cols() != d || damping.rows() != d || damping.cols() != d ||
      stiffness.rows() != d || stiffness.cols() != d || x0.size() != d || v0.size() != d) {
    throw std::invalid_argument("LinearOscillator: inconsistent sizes");
  }
  if (!(beta > 0.0 && beta < 2.0)) {
    throw std::invalid_argument("LinearOscillator: beta must lie in (0, 2)");
  }
  if (convention == ReferenceConvention::kRiemannLiouville && beta >= 1.0) {
    throw std::invalid_argument("LinearOscillator: RL reference only for beta < 1");
  }
  for (const PowerTerm& term : forcing) {
    if (term.coefficient.size() != d || !(term.exponent > -1.0)) {
      throw std::invalid_argument("LinearOscillator: forcing term needs size d and exponent > -1");
    }
  }
}

Eigen::VectorXcd laplace_transform(const LinearOscillator& problem, double r, double theta) {
  const Polar s{r, theta};
  return q_matrix(problem, s).fullPivLu().solve(numerator(problem, s));
}

LaplaceInversion::LaplaceInversion(LinearOscillator problem) : problem_(std::move(problem)) {
  problem_.validate();
  const LinearOscillator& p = problem_;
  // Zeros of det Q satisfy s² uᴴMu + s^β uᴴRu + uᴴKu = 0 for a unit null vector u, so
  // |s|^{2−β} ≤ (‖R‖ + ‖K‖)/λ_min(M) whenever |s| ≥ 1: ρ = 2·max(1, that bound) encloses them.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> mass_eig(p.mass);
  const double lambda_min = mass_eig.eigenvalues().minCoeff();
  const double bound =
      std::pow((p.damping.norm() + p.stiffness.norm()) / lambda_min, 1.0 / (2.0 - p.beta));
  const double rho = 2.0 * std::max(1.0, bound);
  pole_count_ = count_upper_zeros(p, rho);

  // Starting guesses: the undamped frequencies i ω_j, then a polar grid of the upper half disc.
  std::vector<Complex> guesses;
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> modes(p.stiffness, p.mass);
  for (Eigen::Index j = 0; j < modes.eigenvalues().size(); ++j) {
    const double w2 = modes.eigenvalues()(j);
    if (w2 > 0.0) guesses.emplace_back(0.0, std::sqrt(w2));
  }
  for (int ir = 1; ir <= 8; ++ir) {
    for (int ith = 1; ith <= 8; ++ith) {
      guesses.push_back(std::polar(rho * ir / 9.0, kPi * ith / 9.0));
    }
  }
  for (const Complex g : guesses) {
    if (static_cast<int>(poles_.size()) >= pole_count_) break;  // all certified zeros found
    const auto z = newton_zero(p, g);
    if (!z) continue;
    Complex root = z->imag() < 0.0 ? std::conj(*z) : *z;
    if (!(root.imag() > 0.0) || std::abs(root) >= rho) continue;
    const bool duplicate = std::any_of(poles_.begin(), poles_.end(), [&](Complex f) {
      return std::abs(f - root) <= 1e-8 * std::abs(root);
    });
    if (!duplicate) poles_.push_back(root);
  }
  if (static_cast<int>(poles_.size()) != pole_count_) {
    throw std::runtime_error("LaplaceInversion: found " + std::to_string(poles_.size()) +
                             " zeros of det Q, argument principle counts " +
                             std::to_string(pole_count_));
  }

  // Residue of Q^{-1} at a simple zero: u vᵀ/(vᵀ Q' u), Q u = 0, vᵀ Q = 0 (u, v from the SVD).
  for (const Complex s : poles_) {
    const Polar ps = to_polar(s);
    const MatrixXc q = q_matrix(p, ps);
    const Eigen::JacobiSVD<MatrixXc> svd(q, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Index last = q.rows() - 1;
    const VectorXc u = svd.matrixV().col(last);
    const VectorXc v = svd.matrixU().col(last).conjugate();
    const Complex denom = v.transpose() * q_derivative(p, ps) * u;
    const Complex proj = v.transpose() * numerator(p, ps);
    residues_.push_back(u * (proj / denom));
  }
  // Radius of the small circle of the Hankel contour: inside every zero of det Q, so the
  // contour still separates the zeros (handled by residues) from the cut.
  circle_radius_ = 0.5;
  for (const Complex s : poles_) circle_radius_ = std::min(circle_radius_, 0.5 * std::abs(s));
}

Eigen::VectorXd LaplaceInversion::pole_part(double t) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(problem_.dim());
  for (std::size_t j = 0; j < poles_.size(); ++j) {
    // Each zero s_j in the upper half plane has its conjugate with the conjugate residue.
    out += 2.0 * (std::exp(poles_[j] * t) * residues_[j]).real();
  }
  return out;
}

Eigen::VectorXd LaplaceInversion::hankel_part(double t) const {
  const Eigen::Index d = problem_.dim();
  Eigen::VectorXd out(d);
  last_hankel_error_ = 0.0;
  for (Eigen::Index i = 0; i < d; ++i) {
    // Both sides of the cut, r ∈ [ε, ∞): −(1/π) ∫ e^{−rt} Im X(r e^{iπ}) dr.
    const auto cut_integrand = [&](double r) {
      // Beyond r = 1e100 the integrand is below C r^{β−3} (and overflow looms): drop it.
      const double decay = std::exp(-r * t);
      if (decay == 0.0 || r > 1e100) return 0.0;
      return decay * laplace_transform(problem_, r, kPi)(i).imag();
    };
    double error = 0.0;
    double l1 = 0.0;
    const double cut = cut_integrator().integrate(
        cut_integrand, circle_radius_, std::numeric_limits<double>::infinity(), 1e-13, &error, &l1);
    last_hankel_error_ = std::max(last_hankel_error_, l1 > 0.0 ? error / l1 : 0.0);
    // The circle |s| = ε, θ from −π to π: (1/2πi)∮ e^{st} X ds = (1/π) ∫_0^π Re[e^{st} s X(s)] dθ
    // by conjugate symmetry. Smooth in θ (X continues analytically across θ = π onto the next
    // sheet), so adaptive Gauss–Kronrod converges geometrically.
    const auto circle_integrand = [&](double theta) {
      const Complex s = std::polar(circle_radius_, theta);
      return (std::exp(s * t) * s * laplace_transform(problem_, circle_radius_, theta)(i)).real();
    };
    double circle_error = 0.0;
    const double circle = boost::math::quadrature::gauss_kronrod<double, 31>::integrate(
        circle_integrand, 0.0, kPi, 10, 1e-14, &circle_error);
    last_hankel_error_ = std::max(last_hankel_error_, circle_error);
    out(i) = -cut / kPi + circle / kPi;
  }
  return out;
}

Eigen::VectorXd LaplaceInversion::operator()(double t) const {
  return pole_part(t) + hankel_part(t);
}

SeriesValue series_solution(const LinearOscillator& problem, double t) {
  problem.validate();
  const LinearOscillator& p = problem;
  const Eigen::Index d = p.dim();
  const Eigen::LLT<Eigen::MatrixXd> mass_llt(p.mass);
  const Eigen::MatrixXd a = mass_llt.solve(p.damping);
  const Eigen::MatrixXd b = mass_llt.solve(p.stiffness);

  // Numerator P(s) = Σ_i P_i s^{e_i}; keep y_i = M^{-1} P_i.
  std::vector<std::pair<double, Eigen::VectorXd>> terms;
  terms.emplace_back(1.0, p.x0);
  terms.emplace_back(0.0, p.v0);
  if (p.convention == ReferenceConvention::kCaputo) {
    terms.emplace_back(p.beta - 1.0, a * p.x0);
    if (p.beta > 1.0) terms.emplace_back(p.beta - 2.0, a * p.v0);
  }
  for (const PowerTerm& term : p.forcing) {
    terms.emplace_back(-term.exponent - 1.0,
                       mass_llt.solve(term.coefficient) * std::tgamma(term.exponent + 1.0));
  }

  SeriesValue out{Eigen::VectorXd::Zero(d), 0.0, 0};
  std::vector<Eigen::MatrixXd> level{Eigen::MatrixXd::Identity(d, d)};  // C_{j, n−j}, j = 0..n
  constexpr int kMaxLevels = 600;
  int small_levels = 0;
  for (int n = 0; n < kMaxLevels; ++n) {
    double level_abs = 0.0;
    for (int j = 0; j <= n; ++j) {
      const int l = n - j;
      for (const auto& [e, y] : terms) {
        const double mu = 2.0 - e + (2.0 - p.beta) * j + 2.0 * l;
        const Eigen::VectorXd term = level[j] * y * gamma_power_ratio(t, mu);
        out.value += term;
        level_abs += term.lpNorm<Eigen::Infinity>();
      }
    }
    out.abs_sum += level_abs;
    out.levels = n + 1;
    // Stop after three consecutive negligible levels (terms decay super-exponentially there).
    small_levels = level_abs <= 1e-18 * out.abs_sum ? small_levels + 1 : 0;
    if (small_levels >= 3 && n > 4) break;
    std::vector<Eigen::MatrixXd> next(n + 2, Eigen::MatrixXd::Zero(d, d));
    for (int j = 0; j <= n + 1; ++j) {
      if (j >= 1) next[j] -= a * level[j - 1];  // C_{j−1, l}, l = n + 1 − j
      if (j <= n) next[j] -= b * level[j];      // C_{j, l−1}
    }
    level = std::move(next);
  }
  if (out.levels >= kMaxLevels) throw std::runtime_error("series_solution: no convergence");
  return out;
}

double mittag_leffler(double a, double b, double z) {
  double sum = 0.0;
  double abs_sum = 0.0;
  double zk = 1.0;
  for (int k = 0; k < 2000; ++k) {
    const double g = a * k + b;
    const double term =
        g < 170.0 ? zk / std::tgamma(g)
                  : std::copysign(std::exp(k * std::log(std::abs(z)) - std::lgamma(g)), zk);
    sum += term;
    abs_sum += std::abs(term);
    if (k > 4 && std::abs(term) <= 1e-18 * abs_sum) return sum;
    zk *= z;
  }
  throw std::runtime_error("mittag_leffler: no convergence");
}

}  // namespace fracvi::test
