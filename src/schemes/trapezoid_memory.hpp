// The memory of the midpoint schemes with trapezoidal (Tustin) damping (internal): fvi-midpoint
// samples it at midpoint values, lda-midpoint at node values (docs/theory/fvi_midpoint.md,
// docs/theory/baselines.md §2).
//
// NodeAveragedTrapezoid: the node average of the trapezoidal CQ of order β, whose generating
// function is ½(1 + ζ) δ(ζ)^β = 2^{β−1} (1 + ζ)^{1−β} (1 − ζ)^β, δ(ζ) = 2(1 − ζ)/(1 + ζ), on a
// sequence u_0, u_1, …, evaluated as two Grünwald–Letnikov sums: y = (1 − ζ)^β u (weights c^{(β)},
// Σ|c| ≤ 2^β) and then (1 + ζ)^{1−β} y, whose weights are (−1)^m c^{(1−β)}_m (a GL history of
// order 1 − β fed with (−1)^j y_j). The trapezoidal weights themselves grow like m^{β−1} for β > 1;
// summed directly they would lose ε h^{−β} Σ|ω̂| ‖u‖, while y = O(h^β) keeps the second sum's
// round-off small. Both histories have lag 1 (the current weight ω̂_0 = 2^{β−1} acts on the unknown
// u_j, in Newton's matrix); one whose weights beyond lag 0 all vanish (order 0) is left out.
//
// TaylorCellForce: x = P + x̃, P(t) = x_0 + (t − t_0) v_0, and P's damping force as its exact cell
// average G^P_j = R (Φ(t_{j+1} − t_0) − Φ(t_j − t_0))/h, Φ(τ) = ∫_0^τ D^β P per unit R:
//   v_0 term: D^β τ = τ^{1−β}/Γ(2−β) → Φ = τ^{2−β}/Γ(3−β) (0 < β < 2; none for Caputo β > 1);
//   x_0 term: Riemann–Liouville, 0 < β < 1: D^β 1 = τ^{−β}/Γ(1−β) → Φ = τ^{1−β}/Γ(2−β).
#pragma once

#include <limits>
#include <string>
#include "fracvi/schemes/registry.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <cstddef>
#include <memory>

#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/schemes/options.hpp"
#include "power_differences.hpp"

namespace fracvi::internal {

class NodeAveragedTrapezoid {
 public:
  /// Capacity: the number of pushes.
  NodeAveragedTrapezoid(double beta, Eigen::Index dimension, std::size_t capacity,
                        const IntegratorOptions& options)
      : current_weight_(std::pow(2.0, beta - 1.0)),
        difference_(make(beta, dimension, capacity, options)),
        average_(make(1.0 - beta, dimension, capacity, options)) {
    s1_.setZero(dimension);
    part_.setZero(dimension);
  }

  /// ω̂_0 = 2^{β−1}, the weight of the current value.
  [[nodiscard]] double current_weight() const { return current_weight_; }

  /// The known part at index j (j = 0, 1, … in the order of the pushes):
  /// out = 2^{β−1} (s1 + (−1)^j Σ_{m≥1} c^{(1−β)}_m z_{j−m}), s1 = Σ_{m≥1} c^{(β)}_m u_{j−m},
  /// z_i = (−1)^i (u_i + s1_i), so that the full sum is ω̂_0 u_j + out. Keeps s1 for push(j).
  void known(std::size_t j, Eigen::VectorXd& out) {
    s1_.setZero();
    out.setZero();
    if (j == 0) return;
    if (difference_ != nullptr) difference_->sum(s1_);
    if (average_ != nullptr) {
      average_->sum(part_);
      out = (j % 2 == 0 ? 1.0 : -1.0) * part_;
    }
    out = current_weight_ * (out + s1_);
  }
  /// u_j into the memory, after known(j).
  void push(std::size_t j, const Eigen::VectorXd& u) {
    if (difference_ != nullptr) difference_->push(u);
    if (average_ != nullptr) {
      part_ = u + s1_;
      if (j % 2 == 1) part_ = -part_;
      average_->push(part_);
    }
  }
  [[nodiscard]] std::string_view kind() const {
    return difference_ ? difference_->kind() : (average_ ? average_->kind() : "none");
  }
  /// Saves or restores both histories and the carried sums (core/state_archive.hpp).
  void visit_state(StateArchive& archive) {
    archive.optional("trapezoid.difference", difference_.get());
    archive.optional("trapezoid.average", average_.get());
    archive.dense("trapezoid.s1", s1_);
    archive.dense("trapezoid.part", part_);
  }
  [[nodiscard]] std::size_t memory_bytes() const {
    return (difference_ ? difference_->memory_bytes() : 0) +
           (average_ ? average_->memory_bytes() : 0);
  }
  /// Both histories as one (History::report): their exponentials added (the recursions per
  /// degree of freedom of a step), the longer window, their thread use added.
  [[nodiscard]] HistoryReport report() const {
    const HistoryReport a = difference_ ? difference_->report() : HistoryReport{};
    const HistoryReport b = average_ ? average_->report() : HistoryReport{};
    return {kind(), a.bytes + b.bytes, a.exponentials + b.exponentials,
            std::max(a.window, b.window), a.threads + b.threads};
  }

 private:
  static std::unique_ptr<History> make(double order, Eigen::Index dimension, std::size_t capacity,
                                       const IntegratorOptions& options) {
    if (order == 0.0) return nullptr;
    auto history = make_history(options.history, {CqScheme::kGrunwaldLetnikov, order, /*lag=*/1},
                                dimension, capacity, stepper_history_tolerance(options));
    history->set_threads(options.threads);
    return history;
  }

  double current_weight_;
  std::unique_ptr<History> difference_, average_;
  Eigen::VectorXd s1_, part_;
};

class TaylorCellForce {
 public:
  /// `damping` is R (symmetric part); split() is false without damping or for β = 0.
  TaylorCellForce(const InitialValueProblem& problem, const ModelMatrix& damping, double h) {
    const double beta = problem.model.damping_order();
    const bool caputo = problem.model.convention == Convention::kCaputo;
    const Eigen::Index d = problem.model.dimension();
    r_x0_.setZero(d);
    r_v0_.setZero(d);
    split_ = !problem.model.is_undamped() && beta > 0.0;
    if (!split_) return;
    if (beta < 2.0 && !(caputo && beta > 1.0)) {
      phi_v_ = std::pow(h, 2.0 - beta) / boost::math::tgamma(3.0 - beta) / h;
      pv_ = 2.0 - beta;
    }
    if (!caputo && beta < 1.0) {
      phi_x_ = std::pow(h, 1.0 - beta) / boost::math::tgamma(2.0 - beta) / h;
      px_ = 1.0 - beta;
    }
    damping.multiply(problem.x0, r_x0_);
    damping.multiply(problem.v0, r_v0_);
  }
  /// The memory acts on x − P (else on x).
  [[nodiscard]] bool split() const { return split_; }
  /// out = G^P_j, the cell average of P's damping force over cell j.
  void operator()(std::size_t j, Eigen::VectorXd& out) const {
    out.setZero();
    if (phi_v_ != 0.0) out += (phi_v_ * forward_difference_of_power(j, pv_)) * r_v0_;
    if (phi_x_ != 0.0) out += (phi_x_ * forward_difference_of_power(j, px_)) * r_x0_;
  }

 private:
  bool split_ = false;
  double phi_v_ = 0.0, pv_ = 0.0, phi_x_ = 0.0, px_ = 0.0;
  Eigen::VectorXd r_x0_, r_v0_;
};

// The registry rules both trapezoidal-damping schemes (fvi-midpoint, lda-midpoint) share.
inline std::string trapezoid_applicability(const InitialValueProblem& problem) {
  if (problem.model.damping_order() < 2.0 || problem.model.is_undamped()) return {};
  return "model.alpha = 1 (2alpha = 2) is outside 0 <= 2alpha < 2: the trapezoidal damping of "
         "order 2 amplifies round-off in the momenta; use fvi-gl or fvi-bdf2";
}
inline StabilityBound implicit_damping_bound(const InitialValueProblem&) {
  return StabilityBound{.stable = true,
                        .largest_step = std::numeric_limits<double>::infinity(),
                        .sharp = true,
                        .rule = "implicit damping: stable for every h"};
}

}  // namespace fracvi::internal
