// lda-midpoint: the discrete Lagrange–d'Alembert principle (Marsden–West 2001, §3.2) with the
// midpoint discrete Lagrangian L_d = h L(x̄_k, Δ_k/h) and the damping as a discrete force at the
// midpoint, f_d^± = −(h/2) F_{k+½} (docs/theory/baselines.md §2):
//
//   M Δ_k/h + (h/2)(∇U_f(x̄_k, t_{k+½}) + F_{k+½}) = p_k,   p_{k+1} = 2MΔ_k/h − p_k.
//
// F_{k+½} is the damping force at the midpoint: R Δ_k/h for 2α = 1; for fractional orders the
// average of the trapezoidal (Tustin) CQ at the two nodes, F_{k+½} = ½(T_k + T_{k+1}),
// T_j = R h^{−2α} Σ_m ω_m x̃_{j−m}, δ(ζ) = 2(1 − ζ)/(1 + ζ). Its generating function on the node
// sequence is 2^{2α−1}(1 + ζ)^{1−2α}(1 − ζ)^{2α} (ζ the shift to the previous node), evaluated as
// two Grünwald–Letnikov sums like fvi-midpoint's memory (which is the same formula on midpoint
// values; docs/theory/fvi_midpoint.md): the two schemes differ only in where the memory samples x,
// and for 2α = 1 this one is R Δ_k/h exactly ((1 + ζ)/2 · δ(ζ) = 1 − ζ).
// x = P + x̃, P(t) = x_0 + (t − t_0) v_0 as in fvi-midpoint; P's force enters as its exact cell
// average (so that its impulse is exact). Not variational in the restricted sense (no mirror),
// but the discrete energy balance is exact for quadratic U: E_{k+1} − E_k = −(F_{k+½} − f)·Δ_k.
#include <cmath>
#include <limits>
#include <memory>

#include "forcing_moments.hpp"
#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"
#include "scheme_rows.hpp"
#include "trapezoid_memory.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

class LdaMidpointStepper final : public Stepper {
 public:
  LdaMidpointStepper(const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        beta_(problem.model.damping_order()),
        d_(problem.model.dimension()),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        u_time_dependent_(problem.model.potential && problem.model.potential->is_time_dependent()),
        diagnostics_(options.diagnostics),
        midpoint_force_(problem, options.load),
        current_weight_(std::pow(2.0, beta_ - 1.0)),  // ω̂_0
        polynomial_force_(problem, problem.model.damping.symmetric_part(), h_),
        mass_(problem.model.mass.symmetric_part()),
        damping_(problem.model.damping.symmetric_part()),
        force_matrix_(damping_.scaled(std::pow(h_, -beta_))),
        mass_solver_(mass_, force_matrix_, options.linear_solver),
        newton_matrix_(
            damped_ ? linear_combination(mass_, 0.5 * h_ * h_ * current_weight_, force_matrix_)
                    : mass_),
        newton_(newton_matrix_, h_, problem.model.potential.get(), options.newton, problem.t0,
                options.linear_solver) {
    // The memory acts on x − P (TaylorCellForce: P's force as exact cell averages).
    split_ = polynomial_force_.split();
    for (Eigen::VectorXd* vec : {&x_cur_, &x_next_, &v_cur_, &p_, &u_, &base_, &g_, &g_poly_, &sum_,
                                 &rhs_, &mid_, &dx_, &f_mid_}) {
      vec->setZero(d_);
    }
    x_cur_ = problem.x0;
    v_cur_ = problem.v0;
    mass_.multiply(problem.v0, p_);
    if (damped_) {
      // The node-averaged trapezoidal memory over u_j = x̃_j (trapezoid_memory.hpp), from u_0.
      memory_ = std::make_unique<NodeAveragedTrapezoid>(beta_, d_, problem.steps + 1, options);
      u_ = problem.x0;
      if (split_) u_ -= problem.x0;
      memory_->known(0, sum_);
      memory_->push(0, u_);
    }
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_cur_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_cur_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return newton_.linear_solver(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    return newton_.factorizations();
  }
  [[nodiscard]] HistoryReport history() const override {
    return memory_ ? memory_->report() : HistoryReport{};
  }
  void visit_state(StateArchive& archive) override {
    visit_step_index(archive, d_, problem_.steps, k_);
    archive.dense("lda_midpoint.x", x_cur_);
    archive.dense("lda_midpoint.v", v_cur_);
    archive.dense("lda_midpoint.p", p_);
    archive.dense("lda_midpoint.u", u_);                  // x̃_k, the memory's last value
    archive.dense("lda_midpoint.increment", dx_);         // Newton's predictor Δ_{k−1}
    newton_.visit_state(archive, "lda_midpoint.newton");  // its kept Jacobian
    archive.number("lda_midpoint.work", work_);
    archive.number("lda_midpoint.supplied", supplied_);
    archive.optional("lda_midpoint.memory", memory_.get());
  }

 private:
  Status advance() override {
    const std::size_t k = k_;
    const Eigen::VectorXd& xk = x_cur_;
    const double t_half = problem_.t0 + (static_cast<double>(k) + 0.5) * h_;
    const Eigen::VectorXd* f_ptr = nullptr;
    if (problem_.model.forcing) {
      midpoint_force_(k, t_half, f_mid_);
      f_ptr = &f_mid_;
    }
    // F_{k+½} = R'(ω̂_0 u_{k+1} + sum) + G^P_k with u_{k+1} = u_k + Δ − h v_0 (split): the part
    // without Δ is `base`, the ω̂_0 R'Δ part sits in Newton's matrix.
    rhs_ = h_ * p_;
    if (damped_) {
      memory_->known(k + 1, sum_);
      base_ = u_;
      if (split_) base_ -= h_ * problem_.v0;
      base_ = current_weight_ * base_ + sum_;
      force_matrix_.multiply(base_, g_);
      polynomial_force_(k, g_poly_);
      g_ += g_poly_;
      rhs_ -= (0.5 * h_ * h_) * g_;
    }
    if (k == 0) dx_ = h_ * problem_.v0;  // predictor; afterwards the previous increment
    const NewtonReport report = newton_.solve(xk, t_half, rhs_, f_ptr, dx_);
    if (const Status s = newton_outcome(report, "M + (h^2/2) w0 h^-2alpha R + (h^2/4) Hess U");
        s != Status::kSuccess)
      return s;
    x_next_ = xk + dx_;
    if (!x_next_.allFinite()) return fail(Status::kNonFinite, "non-finite position");
    if (damped_) {
      // The full F_{k+½} (for the energy account) and u_{k+1} into the memory.
      force_matrix_.multiply(dx_, mid_);
      g_ += current_weight_ * mid_;
      u_ += dx_;
      if (split_) u_ -= h_ * problem_.v0;
      memory_->push(k + 1, u_);
    }
    // p_{k+1} = 2MΔ_k/h − p_k (the two discrete Legendre transforms of cell k).
    mass_.multiply(dx_, mid_);
    p_ = mid_ * (2.0 / h_) - p_;
    if (diagnostics_) {
      // E_{k+1} − E_k = −(F_{k+½} − f)·Δ_k for quadratic U (midpoint rule), plus ∂_t U.
      if (damped_) work_ += g_.dot(dx_);
      if (f_ptr != nullptr) {
        const double fw = f_mid_.dot(dx_);
        work_ -= fw;
        supplied_ += fw;
      }
      if (u_time_dependent_) {
        mid_ = xk + 0.5 * dx_;
        const double du =
            problem_.model.potential->value(mid_, problem_.time(static_cast<double>(k + 1))) -
            problem_.model.potential->value(mid_, problem_.time(static_cast<double>(k)));
        work_ -= du;
        supplied_ += du;
      }
    }
    mass_solver_.inverse(p_, v_cur_);
    if (!v_cur_.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");
    x_cur_.swap(x_next_);
    ++k_;
    return Status::kSuccess;
  }

  const InitialValueProblem& problem_;
  double beta_;
  Eigen::Index d_;
  double h_;
  bool damped_, u_time_dependent_, diagnostics_;
  MidpointForce midpoint_force_;
  double current_weight_;
  TaylorCellForce polynomial_force_;
  bool split_ = false;
  ModelMatrix mass_, damping_, force_matrix_;
  MassSolver mass_solver_;
  ModelMatrix newton_matrix_;  // M + (h²/2) ω̂_0 R'
  MidpointNewton newton_;
  std::unique_ptr<NodeAveragedTrapezoid> memory_;
  std::size_t k_ = 0;
  Eigen::VectorXd x_cur_, x_next_, v_cur_, p_, u_, base_, g_, g_poly_, sum_, rhs_, mid_, dx_,
      f_mid_;
  double work_ = 0.0, supplied_ = 0.0;
};

}  // namespace

const SchemeInfo kLdaMidpoint{
    .name = "lda-midpoint",
    .summary =
        "discrete Lagrange-d'Alembert, midpoint discrete Lagrangian, damping force at the "
        "midpoint (trapezoidal CQ for fractional orders)",
    .reference = "Marsden & West, Acta Numerica 2001, 3.2; docs/theory/baselines.md",
    .order_rule = "2",
    .stages = 1,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = true,  // the discrete balance E_{k+1} − E_k = −(F_{k+½} − f)·Δ_k
    .fast_history = true,   // two GL sums (orders 2α and 1 − 2α, lag 1), as fvi-midpoint
    .momentum_quadrature = CqScheme::kTrapezoidal,
    .forcing_moments = true,  // method.load = "moments": the cell average of f
    .checkpoints = true,
    .no_state_force =
        "this baseline reproduces the published Lagrange-d'Alembert scheme with f(t) only",
    .applies_to = "0 <= 2alpha < 2",
    .stability_rule =
        "stable for every h (implicit damping; the Tustin image of the continuous "
        "characteristic equation)",
    .declared_order = [](const MechanicalModel&) { return 2; },
    .applicability = trapezoid_applicability,
    .stability = implicit_damping_bound,
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<LdaMidpointStepper>(problem, options);
    },
};

}  // namespace fracvi::internal
