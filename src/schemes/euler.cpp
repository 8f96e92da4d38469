// euler-explicit and euler-implicit: the first-order system x' = v, M v' = −F − ∇U(x, t) + f(t)
// with the damping force F = R D^{2α} x by Grünwald–Letnikov weights, stepped by the forward and
// the backward Euler rule (docs/theory/baselines.md §1). Baselines for `fracvi compare`: neither
// is variational, and the explicit one is plain forward Euler (not symplectic Euler), so that its
// energy behaviour shows.
//
// The memory acts on the lowest-order variable that keeps its GL order below one:
//   2α < 1:  F_k = R h^{−2α} Σ_m c^{(2α)}_m x̃_{k−m},      x̃ = x − x_0 (Caputo), x (RL);
//   2α ≥ 1:  F_k = R h^{−γ} Σ_m c^{(γ)}_m ṽ_{k−m}, γ = 2α − 1,  ṽ = v − v_0 (Caputo, γ > 0), v,
// (D^{2α}_C x = D^{2α−1}_C x' for 2α > 1, and D^{2α}_RL x = D^{2α−1}_RL x' when x(0) = 0), so that
// 2α = 1 is F = R v exactly: the textbook Euler schemes of the damped oscillator.
//   explicit:  x_{k+1} = x_k + h v_k,      M v_{k+1} = M v_k − h (F_k + ∇U(x_k, t_k) − f(t_k));
//   implicit:  x_{k+1} = x_k + h v_{k+1},  M v_{k+1} = M v_k − h (F_{k+1} + ∇U(x_{k+1}, t_{k+1})
//              − f(t_{k+1})), solved for Δ = x_{k+1} − x_k by Newton.
// Energy account: the damping impulse of the step (h F_k or h F_{k+1}) against the mean velocity,
// plus ExternalWork; the balance error is O(h) (a consistency check, not exact).
#include <cmath>
#include <limits>
#include <memory>

#include "baseline_support.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/schemes/stability.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

class EulerStepper final : public Stepper {
 public:
  EulerStepper(const InitialValueProblem& problem, const IntegratorOptions& options, bool implicit)
      : problem_(problem),
        implicit_(implicit),
        d_(problem.model.dimension()),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        on_velocity_(problem.model.damping_order() >= 1.0),
        gamma_(on_velocity_ ? problem.model.damping_order() - 1.0 : problem.model.damping_order()),
        shift_(problem.model.convention == Convention::kCaputo && gamma_ > 0.0),
        diagnostics_(options.diagnostics),
        mass_(problem.model.mass.symmetric_part()),
        force_matrix_(problem.model.damping.symmetric_part().scaled(std::pow(h_, -gamma_))),
        mass_solver_(mass_, force_matrix_, options.linear_solver),
        // Implicit: (M + a R')Δ + h²∇U_f(x_k + Δ, t_{k+1}) = b with a = h² (memory on x) or h
        // (on v). MidpointNewton solves A Δ' + (h'²/2)∇U_f(x_k + Δ'/2) = c: with Δ' = 2Δ,
        // h' = 2h and c = 2b it is this equation (Jacobian A + h²∇²U).
        newton_matrix_(damped_
                           ? linear_combination(mass_, on_velocity_ ? h_ : h_ * h_, force_matrix_)
                           : mass_),
        newton_(newton_matrix_, 2.0 * h_, problem.model.potential.get(), options.newton, problem.t0,
                options.linear_solver),
        external_(problem) {
    if (damped_ && gamma_ > 0.0) {
      // Explicit: the whole sum at known states; implicit: the known part (lag 1).
      const ConvolutionQuadrature q{CqScheme::kGrunwaldLetnikov, gamma_, implicit ? 1u : 0u};
      history_ = make_history(options.history, q, d_, problem.steps + 2,
                              stepper_history_tolerance(options));
      history_->set_threads(options.threads);
    }
    for (Eigen::VectorXd* vec : {&x_, &x_next_, &v_, &v_next_, &p_, &z_, &sum_, &force_, &grad_,
                                 &f_, &rhs_, &dx_, &tmp_}) {
      vec->setZero(d_);
    }
    x_ = problem.x0;
    v_ = problem.v0;
    mass_.multiply(v_, p_);
    if (history_) {
      memory_variable(x_, v_, z_);
      history_->push(z_);
    }
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return newton_.linear_solver(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    // The explicit step only borrows Newton's effective gradient (a linear U's constructor
    // factors all the same).
    return implicit_ ? newton_.factorizations() : 0;
  }
  [[nodiscard]] HistoryReport history() const override {
    return history_ ? history_->report() : HistoryReport{};
  }
  void visit_state(StateArchive& archive) override {
    visit_step_index(archive, d_, problem_.steps, k_);
    archive.dense("euler.x", x_);
    archive.dense("euler.v", v_);
    archive.dense("euler.p", p_);
    archive.number("euler.work", work_);
    archive.number("euler.supplied", supplied_);
    newton_.visit_state(archive, "euler.newton");  // its kept Jacobian (the iterates' last bits)
    external_.visit_state(archive);
    archive.optional("euler.history", history_.get());
  }

 private:
  // z̃ = x − x_0 or v − v_0 (Caputo, γ > 0), else x or v.
  void memory_variable(const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                       Eigen::VectorXd& out) const {
    out = on_velocity_ ? v : x;
    if (shift_) out -= on_velocity_ ? problem_.v0 : problem_.x0;
  }

  Status advance() override {
    const std::size_t k = k_;
    const double t = problem_.time(static_cast<double>(implicit_ ? k + 1 : k));
    const Eigen::VectorXd* f_ptr = nullptr;
    if (problem_.model.forcing) {
      problem_.model.forcing(t, f_);
      f_ptr = &f_;
    }
    if (!implicit_) {
      // F_k = R' Σ_m c_m z̃_{k−m} (all known), then the forward Euler update.
      force_.setZero();
      if (damped_) {
        if (history_) {
          history_->sum(sum_);
        } else {
          memory_variable(x_, v_, sum_);
        }
        force_matrix_.multiply(sum_, force_);
      }
      newton_.effective_gradient(x_, t, f_ptr, grad_);
      tmp_ = force_ + grad_;
      mass_solver_.inverse(tmp_, v_next_);
      v_next_ = v_ - h_ * v_next_;
      dx_ = h_ * v_;
      x_next_ = x_ + dx_;
      set_iterations(0);
    } else {
      // b = h M v_k − h² R'(c_0 z̃_k + S) (on x) or − h² R'(S − v_0 shift) (on v); c = 2b.
      mass_.multiply(v_, rhs_);
      rhs_ *= h_;
      if (damped_) {
        sum_.setZero();
        if (history_) history_->sum(sum_);
        if (on_velocity_) {
          if (shift_) sum_ -= problem_.v0;
        } else {
          memory_variable(x_, v_, tmp_);
          sum_ += tmp_;
        }
        force_matrix_.multiply(sum_, tmp_);
        rhs_ -= (h_ * h_) * tmp_;
      }
      rhs_ *= 2.0;
      dx_ = (2.0 * h_) * v_;  // predictor Δ' = 2 h v_k
      const NewtonReport report = newton_.solve(x_, t, rhs_, f_ptr, dx_);
      if (const Status s = newton_outcome(report, "M + a h^-2alpha R + h^2 Hess U");
          s != Status::kSuccess)
        return s;
      dx_ *= 0.5;
      x_next_ = x_ + dx_;
      v_next_ = dx_ * (1.0 / h_);
      // F_{k+1} = R'(c_0 z̃_{k+1} + S) for the energy account.
      if (damped_ && diagnostics_) {
        memory_variable(x_next_, v_next_, tmp_);
        if (history_) tmp_ += sum_after_shift();
        force_matrix_.multiply(tmp_, force_);
      }
    }
    if (!x_next_.allFinite()) return fail(Status::kNonFinite, "non-finite position");
    if (!v_next_.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");
    if (history_) {
      memory_variable(x_next_, v_next_, z_);
      history_->push(z_);
    }
    if (diagnostics_) {
      // The damping impulse h F against the mean velocity (Δx/h for the explicit rule would
      // pair it with v_k only): O(h) like the scheme.
      if (damped_) work_ += 0.5 * h_ * force_.dot(v_ + v_next_);
      const double supplied = external_.step(k, x_, x_next_);
      work_ -= supplied;
      supplied_ += supplied;
    }
    x_.swap(x_next_);
    v_.swap(v_next_);
    mass_.multiply(v_, p_);
    ++k_;
    return Status::kSuccess;
  }

  // The known GL part S of the implicit step (the history sum before the push of z̃_{k+1}).
  [[nodiscard]] const Eigen::VectorXd& sum_after_shift() {
    history_->sum(sum_);
    return sum_;
  }

  const InitialValueProblem& problem_;
  bool implicit_;
  Eigen::Index d_;
  double h_;
  bool damped_, on_velocity_;
  double gamma_;
  bool shift_, diagnostics_;
  ModelMatrix mass_, force_matrix_;  // M and R' = R h^{−γ}
  MassSolver mass_solver_;
  ModelMatrix newton_matrix_;
  MidpointNewton newton_;
  ExternalWork external_;
  std::unique_ptr<History> history_;
  std::size_t k_ = 0;
  Eigen::VectorXd x_, x_next_, v_, v_next_, p_, z_, sum_, force_, grad_, f_, rhs_, dx_, tmp_;
  double work_ = 0.0, supplied_ = 0.0;
};

// The scalar modes (k, r) of the pencils (K, M) and (R, M) at their extremes: the bound of a
// system whose M⁻¹K and M⁻¹R do not commute is then only estimated (d > 16).
struct ScalarModes {
  double k_min, k_max, r_min, r_max;
};
ScalarModes scalar_modes(const LinearTestProblem& test) {
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> k(test.stiffness, test.mass,
                                                                    Eigen::EigenvaluesOnly);
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> r(test.damping, test.mass,
                                                                    Eigen::EigenvaluesOnly);
  return {k.eigenvalues().minCoeff(), k.eigenvalues().maxCoeff(), r.eigenvalues().minCoeff(),
          r.eigenvalues().maxCoeff()};
}

// The explicit rule's characteristic symbol (docs/theory/baselines.md §1.2), x_k ∝ ξ^{−k}:
//   memory on x: (1 − ξ)² M + h² ξ² K + h^{2−2α} ξ² (1 − ξ)^{2α} R,
//   memory on v: (1 − ξ)² M + h² ξ² K + h^{2−2α} ξ (1 − ξ)^{2α} R.
StabilityBound explicit_euler_bound(const InitialValueProblem& problem) {
  if (problem.model.dimension() > kMaxStabilityDimension) return unchecked_bound(problem);
  const LinearTestProblem test = linear_test_problem(problem);
  const double beta = problem.model.damping_order();
  const bool on_velocity = beta >= 1.0;
  const Eigen::Index d = test.mass.rows();
  auto stable_for = [&](const Eigen::MatrixXd& m, const Eigen::MatrixXd& k,
                        const Eigen::MatrixXd& r) {
    const Eigen::MatrixXcd mc = m.cast<std::complex<double>>(), kc = k.cast<std::complex<double>>(),
                           rc = r.cast<std::complex<double>>();
    return [=](double h) {
      const CharacteristicSymbol symbol = [&](std::complex<double> xi, Eigen::MatrixXcd& a) {
        const std::complex<double> w = 1.0 - xi;
        const std::complex<double> memory =
            std::pow(h, 2.0 - beta) * (on_velocity ? xi : xi * xi) * one_minus_power(xi, beta);
        a = (w * w) * mc + (h * h * xi * xi) * kc + memory * rc;
      };
      return characteristic_roots_inside(symbol, m.rows()) == 0;
    };
  };
  const std::string what =
      "no root of det[(1-xi)^2 M + h^2 xi^2 K + h^(2-2alpha) xi^" +
      std::string(on_velocity ? "1" : "2") +
      " (1-xi)^(2alpha) R] in |xi| <= 1 (K = Hess U(x0); forward Euler: no stable h without "
      "damping)";
  const double h0 = problem.step_size();
  // Without damping the roots ξ^{−1} = 1 ± ih√(k/m) lie outside the unit circle for every h: the
  // argument principle on |ξ| = 1 − 1e-7 would miss them only because they approach the circle
  // as h → 0 (growth 1 + h²k/(2m) per step), so this case is settled exactly.
  if (problem.model.is_undamped() && !test.stiffness.isZero(0.0)) {
    return step_bound(problem, 0.0, true, what);
  }
  if (d <= kMaxCharacteristicDimension) {
    const double h_star =
        largest_stable_step(stable_for(test.mass, test.stiffness, test.damping), h0);
    return step_bound(problem, h_star, test.exact, what);
  }
  const ScalarModes modes = scalar_modes(test);
  double h_star = std::numeric_limits<double>::infinity();
  const Eigen::MatrixXd one = Eigen::MatrixXd::Ones(1, 1);
  for (const double k : {modes.k_min, modes.k_max}) {
    for (const double r : {modes.r_min, modes.r_max}) {
      h_star = std::min(h_star, largest_stable_step(stable_for(one, k * one, r * one), h0));
    }
  }
  return step_bound(problem, h_star, false,
                    what + ", estimated from the extreme modes of (K, M) and (R, M) for d > " +
                        std::to_string(kMaxCharacteristicDimension));
}

std::string euler_applicability(const InitialValueProblem&) {
  return "";
}

}  // namespace

const SchemeInfo kEulerExplicit{
    .name = "euler-explicit",
    .summary = "forward Euler on (x, v), Grunwald-Letnikov memory (baseline; not symplectic)",
    .reference = "textbook explicit Euler; docs/theory/baselines.md",
    .order_rule = "1",
    .stages = 1,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = false,
    .fast_history = true,
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = false,
    .checkpoints = true,
    .no_state_force = "this baseline takes f(t) only",
    .applies_to = "every model (no stable h without damping)",
    .stability_rule =
        "all characteristic roots inside the unit disc, computed for the problem's M, R and "
        "K = Hess U(x0) (docs/theory/baselines.md); no stable h without damping",
    .declared_order = [](const MechanicalModel&) { return 1; },
    .applicability = euler_applicability,
    .stability = explicit_euler_bound,
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<EulerStepper>(problem, options, /*implicit=*/false);
    },
};

const SchemeInfo kEulerImplicit{
    .name = "euler-implicit",
    .summary = "backward Euler on (x, v), Grunwald-Letnikov memory (baseline)",
    .reference = "textbook implicit Euler; docs/theory/baselines.md",
    .order_rule = "1",
    .stages = 1,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = false,
    .fast_history = true,
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = false,
    .checkpoints = true,
    .no_state_force = "this baseline takes f(t) only",
    .applies_to = "every model",
    .stability_rule = "stable for every h (implicit damping and stiffness)",
    .declared_order = [](const MechanicalModel&) { return 1; },
    .applicability = euler_applicability,
    .stability =
        [](const InitialValueProblem&) {
          return StabilityBound{.stable = true,
                                .largest_step = std::numeric_limits<double>::infinity(),
                                .sharp = true,
                                .rule = "implicit Euler: stable for every h"};
        },
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<EulerStepper>(problem, options, /*implicit=*/true);
    },
};

}  // namespace fracvi::internal
