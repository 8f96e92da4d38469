// The fractional Taylor expansion of a linear problem at t_0 (method.split = "series"; internal
// to the Lobatto schemes, docs/theory/fvi_lobatto.md §13).
//
// For M x'' + R D^β x + K x = Σ_φ b_φ τ^φ (M, R, K constant; the right-hand side a finite sum of
// power laws, φ ≥ 0: the power-law forcing f minus g_0 = ∇U(0) at φ = 0) the solution is
// x(t_0 + τ) = Σ_γ c_γ τ^γ over the exponents γ = k + l(2 − β) (and 2 − β + … for
// Riemann–Liouville data, φ + 2 + … for the loads) generated from c_0 = x_0, c_1 = v_0. With
// D^β τ^γ = g(γ) τ^{γ−β}, g(γ) = Γ(γ + 1)/Γ(γ + 1 − β) (0 for the Caputo derivative of τ^0, and
// of τ^1 when β > 1), the coefficient of τ^e in the equation is
//
//   (e + 2)(e + 1) M c_{e+2} + g(e + β) R c_{e+β} + K c_e = b_e,
//
// which gives c_{e+2} from coefficients of lower exponents (e + β < e + 2 for β < 2): the exponents
// are processed in increasing order of e.
#pragma once

#include <Eigen/Dense>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <map>
#include <set>
#include <vector>

namespace fracvi::internal {

struct SeriesTerm {
  double exponent = 0.0;        // γ
  Eigen::VectorXd coefficient;  // c_γ
};

/// g(γ) with D^β τ^γ = g(γ) τ^{γ−β}; `caputo` makes the derivative of 1 (and of τ for β > 1)
/// zero.
inline double power_derivative_factor(double gamma, double beta, bool caputo) {
  const bool integer = std::abs(gamma - std::round(gamma)) < 1e-12;
  if (caputo && integer && std::round(gamma) < std::ceil(beta - 1e-12)) return 0.0;
  const double shifted = gamma + 1.0 - beta;
  if (shifted <= 0.0 && std::abs(shifted - std::round(shifted)) < 1e-12) return 0.0;  // 1/Γ(−k)
  return boost::math::tgamma(gamma + 1.0) / boost::math::tgamma(shifted);
}

/// The terms c_γ τ^γ of the expansion with 1 < γ ≤ largest (x_0 and v_0, the Taylor polynomial,
/// are not returned), in increasing γ; terms whose coefficient is exactly zero are left out.
/// Exponents as integer keys (10⁻⁹ resolution): sums of 1, 2, ±β and the loads' exponents must
/// meet exactly.
inline long long exponent_key(double e) {
  return std::llround(e * 1e9);
}

inline std::vector<SeriesTerm> fractional_series(const Eigen::MatrixXd& mass,
                                                 const Eigen::MatrixXd& damping,
                                                 const Eigen::MatrixXd& stiffness,
                                                 const std::vector<SeriesTerm>& loads, double beta,
                                                 bool caputo, const Eigen::VectorXd& x0,
                                                 const Eigen::VectorXd& v0, double largest) {
  auto key = exponent_key;
  auto exponent = [](long long k) { return static_cast<double>(k) / 1e9; };
  const Eigen::FullPivLU<Eigen::MatrixXd> mass_lu(mass);
  std::map<long long, Eigen::VectorXd> c;
  std::set<long long> equations;
  auto add_solution = [&](double gamma, const Eigen::VectorXd& value) {
    c[key(gamma)] = value;
    equations.insert(key(gamma));
    if (power_derivative_factor(gamma, beta, caputo) != 0.0) equations.insert(key(gamma - beta));
  };
  std::map<long long, Eigen::VectorXd> load;  // b_φ
  for (const SeriesTerm& term : loads) {
    const auto [it, inserted] = load.try_emplace(key(term.exponent), term.coefficient);
    if (!inserted) it->second += term.coefficient;
    equations.insert(it->first);
  }
  add_solution(0.0, x0);
  add_solution(1.0, v0);
  const Eigen::Index d = x0.size();
  std::set<long long> done;
  while (true) {
    auto next = equations.begin();
    while (next != equations.end() && done.count(*next) != 0) ++next;
    if (next == equations.end()) break;
    const long long k = *next;
    done.insert(k);
    const double e = exponent(k);
    if (e + 2.0 > largest + 1e-9) continue;
    const double factor = (e + 2.0) * (e + 1.0);
    if (std::abs(factor) < 1e-12) continue;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(d);
    if (const auto it = load.find(k); it != load.end()) rhs += it->second;
    if (const auto it = c.find(k); it != c.end()) rhs -= stiffness * it->second;
    if (const auto it = c.find(key(e + beta)); it != c.end()) {
      rhs -= power_derivative_factor(exponent(it->first), beta, caputo) * (damping * it->second);
    }
    add_solution(e + 2.0, mass_lu.solve(rhs) / factor);
  }
  std::vector<SeriesTerm> terms;
  for (const auto& [k, value] : c) {
    const double gamma = exponent(k);
    if (gamma <= 1.0 + 1e-9 || !value.allFinite() || value.isZero(0.0)) continue;
    terms.push_back({gamma, value});
  }
  return terms;
}

}  // namespace fracvi::internal
