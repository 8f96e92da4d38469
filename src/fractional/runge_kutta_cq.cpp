#include "fracvi/fractional/runge_kutta_cq.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unsupported/Eigen/MatrixFunctions>
#include <utility>

#include "tail_compression.hpp"

namespace fracvi {

namespace {

using detail::sample_lags;
using detail::trapezoidal_step;

constexpr double kPi = std::numbers::pi;

// Relative truncation of the x = ln z range (each end) for the accurate weights: far below the
// double precision of the result.
constexpr double kWeightTruncation = 1e-19;
// Target of the trapezoidal discretisation error for the accurate weights, and the factor applied
// to the step that the model of trapezoidal_step() gives (measured against the 50-digit
// references: see docs/theory/rkcq_weights.md).
constexpr double kWeightDiscretisation = 1e-17;
// The x-range is extended upwards at least to z = kFarNode (past the poles of (I + zA)^{−1}, at
// |z| ≤ 12, and the zero of r(−z) at z = 4 for s = 3) and then until kStopRun consecutive nodes
// are negligible.
constexpr double kFarNode = 100.0;
constexpr int kStopRun = 8;
// Hard bound on the number of nodes (never reached for the documented ranges).
constexpr int kMaxNodes = 20000;
constexpr std::size_t kMaxTailLag = std::size_t{1} << 50;

bool is_integer(double x) {
  return std::floor(x) == x;
}

ButcherTableau make_lobatto_iiic(int s) {
  ButcherTableau t;
  t.order = 2 * s - 2;
  t.name = "Lobatto IIIC (s = " + std::to_string(s) + ")";
  t.a.resize(s, s);
  t.b.resize(s);
  if (s == 2) {
    t.a << 0.5, -0.5,  //
        0.5, 0.5;
    t.b << 0.5, 0.5;
  } else if (s == 3) {
    t.a << 1.0 / 6, -1.0 / 3, 1.0 / 6,  //
        1.0 / 6, 5.0 / 12, -1.0 / 12,   //
        1.0 / 6, 2.0 / 3, 1.0 / 6;
    t.b << 1.0 / 6, 2.0 / 3, 1.0 / 6;
  } else {
    const double r5 = std::sqrt(5.0);
    t.a << 1.0 / 12, -r5 / 12, r5 / 12, -1.0 / 12,        //
        1.0 / 12, 1.0 / 4, (10 - 7 * r5) / 60, r5 / 60,   //
        1.0 / 12, (10 + 7 * r5) / 60, 1.0 / 4, -r5 / 60,  //
        1.0 / 12, 5.0 / 12, 5.0 / 12, 1.0 / 12;
    t.b << 1.0 / 12, 5.0 / 12, 5.0 / 12, 1.0 / 12;
  }
  t.c.resize(s);
  if (s == 2) {
    t.c << 0.0, 1.0;
  } else if (s == 3) {
    t.c << 0.0, 0.5, 1.0;
  } else {
    const double r5 = std::sqrt(5.0);
    t.c << 0.0, (5 - r5) / 10, (5 + r5) / 10, 1.0;
  }
  return t;
}

void check_stages(int stages, const char* who) {
  if (stages < 2 || stages > 4) {
    throw std::invalid_argument(std::string(who) + ": stages = " + std::to_string(stages) +
                                " must be 2, 3 or 4 (Lobatto IIIC)");
  }
}

// The (s − 2, s) Padé approximant of e^{−z}, r(−z) = P(z)/Q(z), and P(z) − Q(z), all as
// polynomials in z ≥ 0 with exact coefficients (lowest degree first). P − Q has only negative
// coefficients, so r(−z) − 1 = (P − Q)/Q is computed without cancellation.
struct Pade {
  std::vector<double> p, q, p_minus_q;
};

const Pade& pade(int s) {
  static const Pade two{{1.0}, {1.0, 1.0, 0.5}, {0.0, -1.0, -0.5}};
  static const Pade three{{1.0, -0.25}, {1.0, 0.75, 0.25, 1.0 / 24}, {0.0, -1.0, -0.25, -1.0 / 24}};
  static const Pade four{{1.0, -1.0 / 3, 1.0 / 30},
                         {1.0, 2.0 / 3, 0.2, 1.0 / 30, 1.0 / 360},
                         {0.0, -1.0, -1.0 / 6, -1.0 / 30, -1.0 / 360}};
  return s == 2 ? two : (s == 3 ? three : four);
}

double horner(const std::vector<double>& coefficients, double z) {
  double value = 0.0;
  for (auto it = coefficients.rbegin(); it != coefficients.rend(); ++it) value = value * z + *it;
  return value;
}

// log |r(−z)|, accurate to a few ulps of log r near z = 0 (log1p of the cancellation-free r − 1).
double log_abs_stability(int s, double z) {
  const Pade& f = pade(s);
  const double q = horner(f.q, z);
  const double rm1 = horner(f.p_minus_q, z) / q;
  if (rm1 > -0.5) return std::log1p(rm1);
  return std::log(std::abs(horner(f.p, z) / q));
}

// One trapezoidal node z = e^{kh} of W_j = −(sin πβ/π) ∫ z^β r(−z)^{j−1} u vᵀ dz:
// the term is q r^{j−1} u vᵀ with q = −(sin πβ/π) h z^{β+1}.
struct Node {
  double z = 0.0;
  double q = 0.0;
  double r = 0.0;              // r(−z)
  double log_abs_r = 0.0;      // log |r(−z)|
  double log_magnitude = 0.0;  // log(|q| ‖u‖∞ ‖v‖∞)
  Eigen::VectorXd u, v;
};

class NodeFactory {
 public:
  NodeFactory(int stages, double beta, double h)
      : tableau_(lobatto_iiic(stages)),
        stages_(stages),
        beta_(beta),
        h_(h),
        scale_(-std::sin(kPi * beta) / kPi) {}

  [[nodiscard]] Node make(int k) const {
    Node n;
    const double x = static_cast<double>(k) * h_;
    n.z = std::exp(x);
    n.q = scale_ * h_ * std::exp((beta_ + 1.0) * x);
    const Eigen::MatrixXd m = Eigen::MatrixXd::Identity(stages_, stages_) + n.z * tableau_.a;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(m);
    n.u = lu.solve(Eigen::VectorXd::Ones(stages_));
    n.v = lu.transpose().solve(tableau_.b);
    const Pade& f = pade(stages_);
    n.r = horner(f.p, n.z) / horner(f.q, n.z);
    n.log_abs_r = log_abs_stability(stages_, n.z);
    n.log_magnitude =
        std::log(std::abs(n.q) * n.u.cwiseAbs().maxCoeff() * n.v.cwiseAbs().maxCoeff());
    return n;
  }

  // A lower bound for the size of max|W_j| (its asymptotic value (|sin πβ|/π) Γ(1 + β) j^{−1−β}
  // max b ≥ ... times min b / max b), used only to cut negligible nodes.
  [[nodiscard]] double log_size(std::size_t j) const {
    return std::log(std::abs(scale_) * std::tgamma(1.0 + beta_) * tableau_.b.minCoeff()) -
           (1.0 + beta_) * std::log(static_cast<double>(std::max<std::size_t>(j, 1)));
  }

  // Nodes for the lags j_lo ≤ j ≤ j_hi (2 ≤ j_lo), relative truncation tau at each end.
  [[nodiscard]] std::vector<Node> nodes(std::size_t j_lo, std::size_t j_hi, double tau) const {
    // Lower end: ∫_0^{z_min} (|sin πβ|/π) z^β dz ≤ tau |W_{j_hi}|.
    const double log_z_min =
        std::log(tau * std::tgamma(2.0 + beta_) * tableau_.b.minCoeff()) / (1.0 + beta_) -
        std::log(static_cast<double>(j_hi));
    const int k_lo = static_cast<int>(std::floor(log_z_min / h_));
    const double threshold = std::log(tau) + log_size(j_lo) + std::log(h_);
    const double far = std::max(kFarNode, 50.0 / static_cast<double>(j_lo));
    std::vector<Node> out;
    int run = 0;
    for (int k = k_lo; k < k_lo + kMaxNodes; ++k) {
      Node n = make(k);
      const double log_term = n.log_magnitude + static_cast<double>(j_lo - 1) * n.log_abs_r;
      const bool negligible = !(log_term > threshold);
      out.push_back(std::move(n));
      run = negligible ? run + 1 : 0;
      if (run >= kStopRun && out.back().z >= far) break;
    }
    return out;
  }

  [[nodiscard]] double step() const { return h_; }

 private:
  const ButcherTableau& tableau_;
  int stages_;
  double beta_;
  double h_;
  double scale_;
};

// W_j = Σ_k q_k r_k^{j−1} u_k v_kᵀ over the nodes whose term exceeds tau·|W_j| (j ≥ 2).
void accumulate(const std::vector<Node>& nodes, std::size_t j, double log_cut,
                Eigen::Ref<Eigen::MatrixXd> out) {
  out.setZero();
  const double power = static_cast<double>(j - 1);
  const bool odd = (j - 1) % 2 == 1;
  for (const Node& n : nodes) {
    const double log_power = power * n.log_abs_r;
    if (!(n.log_magnitude + log_power > log_cut)) continue;
    double w = n.q * std::exp(log_power);
    if (odd && n.r < 0.0) w = -w;
    out.noalias() += (w * n.u) * n.v.transpose();
  }
}

// W_0, W_1 for a non-integer order: the power of the 2s × 2s block matrix [[D0, D1], [0, D0]],
// whose β-th power is [[W_0, W_1], [0, W_0]] (the Taylor coefficients of Δ(ζ)^β modulo ζ²). Eigen's
// Schur–Padé MatrixPower in double precision reaches only 1e-13 relative in the smaller entries
// (measured against the 50-digit references, s = 4, β = 0.3); in x87 extended precision
// (64-bit mantissa) the same algorithm leaves the double result correctly rounded to a few ulps.
std::pair<Eigen::MatrixXd, Eigen::MatrixXd> first_two(const RungeKuttaCq& cq) {
  using MatrixXld = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  const int s = cq.stages;
  const ButcherTableau& tableau = lobatto_iiic(s);
  // A and A^{−1} in extended precision (√5 for s = 4 rounded in long double).
  MatrixXld a = tableau.a.cast<long double>();
  if (s == 4) {
    const long double r5 = std::sqrt(5.0L);
    a << 1.0L / 12, -r5 / 12, r5 / 12, -1.0L / 12,          //
        1.0L / 12, 1.0L / 4, (10 - 7 * r5) / 60, r5 / 60,   //
        1.0L / 12, (10 + 7 * r5) / 60, 1.0L / 4, -r5 / 60,  //
        1.0L / 12, 5.0L / 12, 5.0L / 12, 1.0L / 12;
  } else if (s == 3) {
    a << 1.0L / 6, -1.0L / 3, 1.0L / 6,   //
        1.0L / 6, 5.0L / 12, -1.0L / 12,  //
        1.0L / 6, 2.0L / 3, 1.0L / 6;
  }
  const MatrixXld d0 = a.fullPivLu().inverse();
  MatrixXld t = MatrixXld::Zero(2 * s, 2 * s);
  t.topLeftCorner(s, s) = d0;
  t.bottomRightCorner(s, s) = d0;
  t(0, 2 * s - 1) = -1.0L / a(s - 1, 0);  // D1 = −(1/b_1) e_1 e_sᵀ, b_1 = a_{s1}
  Eigen::MatrixPower<MatrixXld> power(t);
  const MatrixXld p = power(static_cast<long double>(cq.order));
  return {p.topLeftCorner(s, s).cast<double>(), p.topRightCorner(s, s).cast<double>()};
}

// Exact weights of an integer order, lags 0 … count − 1.
void integer_weights(const RungeKuttaCq& cq, BlockWeights& out) {
  const Eigen::MatrixXd d0 = cq.delta(0.0);
  const Eigen::MatrixXd d1 = cq.delta(1.0) - d0;  // exactly −(1/b_1) e_1 e_sᵀ
  for (std::size_t j = 0; j < out.size(); ++j) out[j].setZero();
  const auto n = static_cast<int>(cq.order);
  if (n == 0) {
    if (out.size() > 0) out[0].setIdentity();
  } else if (n == 1) {
    if (out.size() > 0) out[0] = d0;
    if (out.size() > 1) out[1] = d1;
  } else {
    if (out.size() > 0) out[0] = d0 * d0;
    if (out.size() > 1) out[1] = d0 * d1 + d1 * d0;
    if (out.size() > 2) out[2] = d1 * d1;  // zero: e_sᵀe_1 = 0
  }
}

double weight_step(double beta) {
  return trapezoidal_step(beta, kWeightDiscretisation);
}

}  // namespace

const ButcherTableau& lobatto_iiic(int stages) {
  check_stages(stages, "lobatto_iiic");
  static const ButcherTableau two = make_lobatto_iiic(2);
  static const ButcherTableau three = make_lobatto_iiic(3);
  static const ButcherTableau four = make_lobatto_iiic(4);
  return stages == 2 ? two : (stages == 3 ? three : four);
}

double lobatto_iiic_stability(int stages, double z) {
  check_stages(stages, "lobatto_iiic_stability");
  const Pade& f = pade(stages);
  return horner(f.p, z) / horner(f.q, z);
}

void RungeKuttaCq::validate() const {
  check_stages(stages, "RungeKuttaCq");
  if (!std::isfinite(order) || order < 0.0 || order > 2.0) {
    throw std::invalid_argument("RungeKuttaCq: order = " + std::to_string(order) +
                                " must be in [0, 2]");
  }
}

Eigen::MatrixXd RungeKuttaCq::delta(double zeta) const {
  validate();
  const ButcherTableau& t = lobatto_iiic(stages);
  Eigen::MatrixXd d = t.a.fullPivLu().inverse();
  d(0, stages - 1) -= zeta / t.b(0);
  return d;
}

bool RungeKuttaCq::is_local() const {
  return is_integer(order);
}

std::string RungeKuttaCq::describe() const {
  std::string o = std::to_string(order);
  o.erase(o.find_last_not_of('0') + 1);
  if (!o.empty() && o.back() == '.') o.pop_back();
  std::string text = lobatto_iiic(stages).name + " RKCQ of order " + o;
  if (lag != 0) text += " from lag " + std::to_string(lag);
  return text;
}

BlockWeights RungeKuttaCq::weights(std::size_t count) const {
  validate();
  if (lag != 0) {
    // The plain weights W_0 … W_{lag+count−1}, the first `lag` blocks dropped.
    const BlockWeights plain = RungeKuttaCq{stages, order}.weights(count + lag);
    BlockWeights out(stages, count);
    for (std::size_t j = 0; j < count; ++j) out[j] = plain[j + lag];
    return out;
  }
  BlockWeights out(stages, count);
  if (is_local()) {
    integer_weights(*this, out);
    return out;
  }
  if (count == 0) return out;
  const auto [w0, w1] = first_two(*this);
  out[0] = w0;
  if (count > 1) out[1] = w1;
  if (count <= 2) return out;
  const NodeFactory factory(stages, order, weight_step(order));
  const std::vector<Node> nodes = factory.nodes(2, count - 1, kWeightTruncation);
  const double log_tau = std::log(kWeightTruncation) + std::log(factory.step());
  for (std::size_t j = 2; j < count; ++j) {
    accumulate(nodes, j, log_tau + factory.log_size(j), out[j]);
  }
  return out;
}

Eigen::MatrixXd RungeKuttaCq::weight(std::size_t j) const {
  validate();
  if (lag != 0) return RungeKuttaCq{stages, order}.weight(j + lag);
  if (is_local()) {
    if (j > 2) return Eigen::MatrixXd::Zero(stages, stages);
    return Eigen::MatrixXd(weights(j + 1)[j]);
  }
  if (j < 2) {
    const auto [w0, w1] = first_two(*this);
    return j == 0 ? w0 : w1;
  }
  const NodeFactory factory(stages, order, weight_step(order));
  const std::vector<Node> nodes = factory.nodes(j, j, kWeightTruncation);
  Eigen::MatrixXd w(stages, stages);
  accumulate(nodes, j, std::log(kWeightTruncation) + std::log(factory.step()) + factory.log_size(j),
             w);
  return w;
}

}  // namespace fracvi

namespace fracvi {

namespace {

// Tail fit: shares of ε, sampled lags and sweep step as in exponential_fit.cpp
// (tail_compression.hpp).

// Accurate W_j at the given lags (all ≥ 2) from one node set.
std::vector<Eigen::MatrixXd> accurate_weights(int s, double beta,
                                              const std::vector<std::size_t>& lags) {
  const NodeFactory factory(s, beta, weight_step(beta));
  const auto [lo, hi] = std::minmax_element(lags.begin(), lags.end());
  const std::vector<Node> nodes = factory.nodes(*lo, *hi, kWeightTruncation);
  const double log_tau = std::log(kWeightTruncation) + std::log(factory.step());
  std::vector<Eigen::MatrixXd> out(lags.size(), Eigen::MatrixXd(s, s));
  for (std::size_t i = 0; i < lags.size(); ++i) {
    accumulate(nodes, lags[i], log_tau + factory.log_size(lags[i]), out[i]);
  }
  return out;
}

double max_abs_coeff(const Eigen::MatrixXd& m) {
  return m.cwiseAbs().maxCoeff();
}

// sign(r)^n |r|^n for real r and integer n ≥ 0.
double signed_power(double r, double log_abs_r, std::size_t n) {
  if (n == 0) return 1.0;
  const double p = std::exp(static_cast<double>(n) * log_abs_r);
  return (r < 0.0 && n % 2 == 1) ? -p : p;
}

void validate_tail(const RkcqTailOptions& o) {
  const auto fail = [](const std::string& msg) {
    throw std::invalid_argument("fit_rkcq_tail: " + msg);
  };
  check_stages(o.stages, "fit_rkcq_tail");
  if (!std::isfinite(o.order) || !(o.order > 0.0) || !(o.order < 2.0) || is_integer(o.order)) {
    fail("order = " + std::to_string(o.order) +
         " must be non-integer in (0, 2) (integer orders have at most 3 nonzero blocks)");
  }
  if (!(o.tolerance >= 1e-13) || !(o.tolerance <= 1e-3)) {
    fail("tolerance = " + std::to_string(o.tolerance) + " must be in [1e-13, 1e-3]");
  }
  if (o.window < 2) fail("window = " + std::to_string(o.window) + " must be >= 2");
  if (o.max_lag > kMaxTailLag) fail("max_lag = " + std::to_string(o.max_lag) + " must be <= 2^50");
}

struct TailSelection {
  std::vector<std::size_t> columns;
  std::vector<double> gammas;
  double error = std::numeric_limits<double>::infinity();
};

}  // namespace

Eigen::MatrixXd RkcqTail::coefficient(std::size_t i) const {
  return gammas[i] * left[i] * right[i].transpose();
}

Eigen::MatrixXd RkcqTail::weight(std::size_t j) const {
  if (j < window) return Eigen::MatrixXd(head[j]);
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(stages, stages);
  const std::size_t n = j - window;
  for (std::size_t i = 0; i < decays.size(); ++i) {
    const double p = signed_power(decays[i], std::log(std::abs(decays[i])), n);
    w.noalias() += (gammas[i] * p * left[i]) * right[i].transpose();
  }
  return w;
}

RkcqTail fit_rkcq_tail(const RkcqTailOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  validate_tail(options);
  const int s = options.stages;
  const double beta = options.order;
  const double eps = options.tolerance;
  RkcqTail tail;
  tail.stages = s;
  tail.order = beta;
  tail.tolerance = eps;
  tail.max_lag = options.max_lag;
  tail.window = options.window;
  tail.head = RungeKuttaCq{s, beta}.weights(options.window);
  const auto finish = [&]() {
    tail.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return tail;
  };
  if (options.max_lag < options.window) return finish();

  const std::size_t n0 = options.window;
  const std::vector<std::size_t> fit_lags =
      sample_lags(n0, options.max_lag, detail::kFitDense, detail::kFitPerDecade);
  const std::vector<std::size_t> check_lags =
      sample_lags(n0, options.max_lag, detail::kVerifyDense, detail::kVerifyPerDecade);
  const std::vector<Eigen::MatrixXd> w_fit = accurate_weights(s, beta, fit_lags);
  const std::vector<Eigen::MatrixXd> w_check = accurate_weights(s, beta, check_lags);
  tail.verification_lags = check_lags.size();

  // The raw quadrature at the tolerance: γ_k = q_k r_k^{n0−1}, decay r_k.
  const NodeFactory factory(s, beta, trapezoidal_step(beta, detail::kDiscretisationShare * eps));
  std::vector<Node> all = factory.nodes(n0, options.max_lag, detail::kTruncationShare * eps);
  std::vector<Node> nodes;
  std::vector<double> gamma0;
  for (Node& n : all) {
    const double g = n.q * signed_power(n.r, n.log_abs_r, n0 - 1);
    // Keep a node if its term reaches 1e-3 ε of max|W_j| at some verification lag.
    bool keep = false;
    const double size = std::abs(g) * n.u.cwiseAbs().maxCoeff() * n.v.cwiseAbs().maxCoeff();
    for (std::size_t v = 0; v < check_lags.size() && !keep; v += 16) {
      keep = size * std::exp(static_cast<double>(check_lags[v] - n0) * n.log_abs_r) >
             1e-3 * eps * max_abs_coeff(w_check[v]);
    }
    if (keep) {
      gamma0.push_back(g);
      nodes.push_back(std::move(n));
    }
  }
  tail.quadrature_nodes = nodes.size();
  const auto cols = static_cast<Eigen::Index>(nodes.size());
  const Eigen::Index ss = s * s;

  // Terms at the verification lags, e_check(v·s² + entry, k) = r_k^{m_v − n0} (u_k v_kᵀ)_entry.
  const auto design = [&](const std::vector<std::size_t>& lags,
                          const std::vector<Eigen::MatrixXd>& reference, bool scale) {
    Eigen::MatrixXd m(static_cast<Eigen::Index>(lags.size()) * ss, cols);
    for (std::size_t v = 0; v < lags.size(); ++v) {
      const double inv = scale ? 1.0 / max_abs_coeff(reference[v]) : 1.0;
      for (Eigen::Index k = 0; k < cols; ++k) {
        const Node& n = nodes[static_cast<std::size_t>(k)];
        const double p = signed_power(n.r, n.log_abs_r, lags[v] - n0) * inv;
        const Eigen::MatrixXd block = (p * n.u) * n.v.transpose();
        m.block(static_cast<Eigen::Index>(v) * ss, k, ss, 1) =
            Eigen::Map<const Eigen::VectorXd>(block.data(), ss);
      }
    }
    return m;
  };
  const Eigen::MatrixXd e_check = design(check_lags, w_check, false);
  const auto evaluate = [&](const std::vector<std::size_t>& columns,
                            const std::vector<double>& gammas) {
    TailSelection sel{columns, gammas, 0.0};
    for (std::size_t v = 0; v < check_lags.size(); ++v) {
      double err = 0.0;
      for (Eigen::Index e = 0; e < ss; ++e) {
        double approx = 0.0;
        for (std::size_t t = 0; t < columns.size(); ++t) {
          approx += gammas[t] * e_check(static_cast<Eigen::Index>(v) * ss + e,
                                        static_cast<Eigen::Index>(columns[t]));
        }
        err = std::max(err, std::abs(approx - w_check[v].data()[e]));
      }
      sel.error = std::max(sel.error, err / max_abs_coeff(w_check[v]));
    }
    return sel;
  };

  TailSelection best;
  if (!options.compress) {
    std::vector<std::size_t> every(nodes.size());
    std::iota(every.begin(), every.end(), std::size_t{0});
    best = evaluate(every, gamma0);
  } else {
    // Relative-error design: columns scaled by γ_k so that the all-ones vector reproduces the
    // quadrature, rows by 1/max|W_j|.
    Eigen::MatrixXd a = design(fit_lags, w_fit, true);
    for (Eigen::Index k = 0; k < cols; ++k) a.col(k) *= gamma0[static_cast<std::size_t>(k)];
    Eigen::VectorXd b(static_cast<Eigen::Index>(fit_lags.size()) * ss);
    for (std::size_t v = 0; v < fit_lags.size(); ++v) {
      b.segment(static_cast<Eigen::Index>(v) * ss, ss) =
          Eigen::Map<const Eigen::VectorXd>(w_fit[v].data(), ss) / max_abs_coeff(w_fit[v]);
    }
    best = detail::select_pivoted_terms(a, b, gamma0, detail::kVerifySafety * eps,
                                        detail::kSweepStep, evaluate);
  }
  if (!(best.error <= (options.compress ? detail::kVerifySafety : 1.0) * eps)) {
    throw std::runtime_error("fit_rkcq_tail: could not verify the tolerance " +
                             std::to_string(eps) + " (measured relative error " +
                             std::to_string(best.error) + ")");
  }
  std::vector<std::size_t> order(best.columns.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    return nodes[best.columns[x]].z < nodes[best.columns[y]].z;
  });
  for (const std::size_t t : order) {
    const Node& n = nodes[best.columns[t]];
    tail.nodes.push_back(n.z);
    tail.decays.push_back(n.r);
    tail.gammas.push_back(best.gammas[t]);
    tail.left.push_back(n.u);
    tail.right.push_back(n.v);
  }
  tail.max_relative_error = best.error;
  return finish();
}

}  // namespace fracvi
