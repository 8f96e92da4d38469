// fvi-midpoint: the restricted discrete variational principle with the midpoint discrete
// Lagrangian and Δ^α_± the trapezoidal (Tustin) convolution quadrature, δ(ζ) = 2(1 − ζ)/(1 + ζ),
// acting on midpoint values x̄_j = (x_j + x_{j+1})/2 (docs/theory/fvi_midpoint.md).
//
// The restricted variation composes Δ^α_− and Δ^α_+ into the trapezoidal CQ of order β = 2α on
// midpoint values, G_j = R h^{−β} Σ_m ω_m x̃̄_{j−m}, and routes it to the nodes like the potential
// gradient: the x-equation at node k is
//
//   M (x_{k+1} − 2x_k + x_{k−1})/h² + ½(G_k + G_{k−1}) + ½∇U_f(x̄_k, t_{k+½}) + ½∇U_f(x̄_{k−1},
//   t_{k−½}) = 0,
//
// a midpoint discrete Lagrange–d'Alembert step with the midpoint force g_k = ∇U_f(x̄_k) + G_k.
// Because G_k contains x̄_k, the damping is implicit: the characteristic equation of the linear
// test problem is the Tustin image M s_h² + R s_h^β + K = 0, s_h = 2(1 − ζ)/(h(1 + ζ)), of the
// continuous one, so the scheme is stable for every h (docs/theory/fvi_midpoint.md §5, measured).
//
// Solved in the momentum form (p_k the node momenta, exact discrete Legendre transforms):
//   M Δ_k/h + (h/2)(∇U_f(x̄_k, t_{k+½}) + G_k) = p_k,     p_{k+1} = 2MΔ_k/h − p_k,
// with G_k = G̃_k + G^P_k:
//  * x = P + x̃, P(t) = x_0 + (t − t_0) v_0 (Taylor split, as fvi-bdf2): the memory acts on
//    x̃̄_j = x̄_j − P(t_{j+½}) = O(h²) near t_0, which the second-order CQ needs;
//  * G̃ is computed from its node average Ĝ_k = ½(G̃_k + G̃_{k−1}) by G̃_k = 2Ĝ_k − G̃_{k−1},
//    G̃_{−1} = 0 (exact algebra: G̃_k + G̃_{k−1} = 2Ĝ_k to one rounding, so the x-equation sees
//    Ĝ only). Ĝ = R h^{−β} · (1 + ζ)/2 · (2(1 − ζ)/(1 + ζ))^β x̃̄ = R h^{−β} 2^{β−1} (1 + ζ)^{1−β}
//    [(1 − ζ)^β x̃̄] is evaluated as two Grünwald–Letnikov sums: y = (1 − ζ)^β x̃̄ (weights c^{(β)},
//    Σ|c| ≤ 2^β) and then (1 + ζ)^{1−β} y, whose weights are (−1)^m c^{(1−β)}_m (a GL history of
//    order 1 − β fed with (−1)^j y_j). The trapezoidal weights themselves grow like m^{β−1} for
//    β > 1 and the node-averaged ones decay only like m^{β−2}: summed directly on x̃̄ they would
//    lose ε h^{−β} Σ|ω̂| ‖x‖, while y = O(h^β) keeps the second sum's round-off small;
//  * G^P_k = R (1/h)∫_{t_k}^{t_{k+1}} D^β P: P's damping force as an exact cell average, so that
//    the momentum receives P's exact impulse whatever the singularity of D^β P at t_0.
// Newton's matrix is M + (h²/2) ω̂_0 h^{−β} R + (h²/4)∇²U (ω̂_0 = 2^{β−1}; M + (h/2)R for β = 1).
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <limits>
#include <memory>

#include "forcing_moments.hpp"
#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "fracvi/solve/vector_passes.hpp"
#include "mass_solver.hpp"
#include "mirror_run.hpp"
#include "scheme_rows.hpp"
#include "trapezoid_memory.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

class TrapezoidalMidpointStepper final : public Stepper {
 public:
  TrapezoidalMidpointStepper(const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        options_(options),
        beta_(problem.model.damping_order()),
        d_(problem.model.dimension()),
        n_steps_(problem.steps),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        has_forcing_(static_cast<bool>(problem.model.forcing)),
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
                options.linear_solver, problem.model.state_force.get()) {
    // x = P + x̃ for β > 0 (D^0 is the identity: nothing to split); P's force as exact cell
    // averages (TaylorCellForce, trapezoid_memory.hpp).
    split_ = polynomial_force_.split();
    for (Eigen::VectorXd* vec :
         {&x_cur_, &x_next_, &v_cur_, &p_, &p_next_, &g_tilde_, &g_total_, &g_poly_, &g_poly_prev_,
          &g_hat_, &q_, &sum_, &mid_tilde_, &rhs_, &mid_, &dx_, &tmp_, &x_first_, &f_mid_}) {
      vec->setZero(d_);
    }
    if (damped_) memory_ = make_memory();
    // Diagonal M and R' (every chain) from kVectorPassesFrom: the step around Newton's solve is two
    // passes (trapezoid_known_pass, trapezoid_step_pass) instead of about twenty Eigen
    // expressions; smaller systems keep those (and their bits: the second pass sums G·Δ in another
    // order than Eigen's dot).
    fused_passes_ = damped_ && d_ >= kVectorPassesFrom && mass_solver_.diagonal() != nullptr &&
                    force_matrix_.stored_diagonal() != nullptr;
    x_cur_ = problem.x0;
    v_cur_ = problem.v0;
    mass_.multiply(problem.v0, p_);
    q_ = p_;
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
  [[nodiscard]] bool mirror_run(MirrorRows& rows) const override;

  void visit_state(StateArchive& archive) override {
    visit_step_index(archive, d_, n_steps_, k_);
    archive.dense("fvi_midpoint.x", x_cur_);
    archive.dense("fvi_midpoint.v", v_cur_);
    archive.dense("fvi_midpoint.p", p_);
    archive.dense("fvi_midpoint.q", q_);                      // q_k of the node equation
    archive.dense("fvi_midpoint.g_tilde", g_tilde_);          // G̃_{k−1}
    archive.dense("fvi_midpoint.g_poly_prev", g_poly_prev_);  // G^P_{k−1}
    archive.dense("fvi_midpoint.increment", dx_);             // Newton's predictor Δ_{k−1}
    newton_.visit_state(archive, "fvi_midpoint.newton");      // its kept Jacobian
    archive.dense("fvi_midpoint.x1", x_first_);               // the mirror run starts from x_0, x_1
    archive.number("fvi_midpoint.work", work_);
    archive.number("fvi_midpoint.supplied", supplied_);
    archive.optional("fvi_midpoint.memory", memory_.get());
  }

 private:
  Status advance() override;

  // The node-averaged trapezoidal memory over the midpoint values x̃̄_0, x̃̄_1, …
  // (trapezoid_memory.hpp): Ĝ_j = R h^{−β} (ω̂_0 x̃̄_j + known part).
  [[nodiscard]] std::unique_ptr<NodeAveragedTrapezoid> make_memory() const {
    return std::make_unique<NodeAveragedTrapezoid>(beta_, d_, n_steps_ + 1, options_);
  }

  [[nodiscard]] double half_time(std::size_t i) const {
    return problem_.t0 + (static_cast<double>(i) + 0.5) * h_;
  }
  [[nodiscard]] double potential_value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
    return problem_.model.potential ? problem_.model.potential->value(x, t) : 0.0;
  }
  // P(t_{j+½}) = x_0 + (j + ½) h v_0, subtracted from x̄_j.
  void subtract_polynomial_midpoint(std::size_t j, Eigen::VectorXd& v) const {
    subtract_polynomial_midpoint(j, problem_.x0, problem_.v0, v);
  }
  // The same with the initial data x0, v0 given (the mirror run's own copies).
  void subtract_polynomial_midpoint(std::size_t j, const Eigen::VectorXd& x0,
                                    const Eigen::VectorXd& v0, Eigen::VectorXd& v) const {
    if (!split_) return;
    v -= x0;
    v -= ((static_cast<double>(j) + 0.5) * h_) * v0;
  }
  // G^P_j = R (Φ(t_{j+1} − t_0) − Φ(t_j − t_0))/h, the cell average of P's damping force.
  void polynomial_force(std::size_t j, Eigen::VectorXd& out) const { polynomial_force_(j, out); }

  const InitialValueProblem& problem_;
  IntegratorOptions options_;
  double beta_;
  Eigen::Index d_;
  std::size_t n_steps_;
  double h_;
  bool damped_, has_forcing_, u_time_dependent_, diagnostics_;
  MidpointForce midpoint_force_;  // f at t_{k+½}, or its cell average (method.load)
  double current_weight_;
  TaylorCellForce polynomial_force_;
  bool split_ = false;
  bool fused_passes_ = false;  // trapezoid_step_pass (constructor)

  ModelMatrix mass_, damping_, force_matrix_;
  MassSolver mass_solver_;
  ModelMatrix newton_matrix_;  // M + (h²/2) ω̂_0 R'
  MidpointNewton newton_;
  std::unique_ptr<NodeAveragedTrapezoid> memory_;

  std::size_t k_ = 0;
  Eigen::VectorXd x_cur_, x_next_, v_cur_, p_, p_next_, q_, g_tilde_, g_total_, g_hat_, g_poly_,
      g_poly_prev_, sum_, mid_tilde_, rhs_, mid_, dx_, tmp_, x_first_, f_mid_;
  double work_ = 0.0, supplied_ = 0.0;
};

Status TrapezoidalMidpointStepper::advance() {
  const std::size_t k = k_;
  const Eigen::VectorXd& xk = x_cur_;
  const double t_half = half_time(k);
  const Eigen::VectorXd* f_ptr = nullptr;
  if (has_forcing_) {
    midpoint_force_(k, t_half, f_mid_);
    f_ptr = &f_mid_;
  }
  // The node equation in the form MΔ_k/h + (h/2)∇U_f(x̄_k) + hĜ_k = q_k with
  // q_k = MΔ_{k−1}/h − (h/2)∇U_f(x̄_{k−1}) (q_0 = p_0) and Ĝ_k = R'(ω̂_0 x̃̄_k + S_k) + Ĝ^P_k,
  // R' = R h^{−β}, S_k the known memory (known_memory()), Ĝ^P_k = ½(G^P_k + G^P_{k−1})
  // (G^P_{−1} = 0); x̃̄_k = x_k + Δ/2 − P(t_{k+½}) holds the unknown. Only Ĝ enters: the split
  // G_k = 2Ĝ_k − G_{k−1} is needed for the output momentum alone, so its rounding (a neutral,
  // alternating mode of the pair (p, G)) cannot reach the trajectory.
  // (M + (h²/2) ω̂_0 R')Δ + (h²/2)∇U_f(x_k + Δ/2) = h q_k − h² (known part of Ĝ_k).
  if (damped_) {
    memory_->known(k, sum_);
    polynomial_force(k, g_poly_);
  }
  if (fused_passes_) {
    trapezoid_known_pass(force_matrix_.stored_diagonal()->data(), xk.data(),
                         split_ ? problem_.x0.data() : nullptr, (static_cast<double>(k) + 0.5) * h_,
                         problem_.v0.data(), current_weight_, sum_.data(), g_poly_.data(),
                         g_poly_prev_.data(), q_.data(), h_, mid_tilde_.data(), rhs_.data(), d_);
  } else {
    if (damped_) {
      mid_tilde_ = xk;
      subtract_polynomial_midpoint(k, mid_tilde_);
      tmp_ = current_weight_ * mid_tilde_ + sum_;
      force_matrix_.multiply(tmp_, g_hat_);
      g_hat_ += 0.5 * (g_poly_ + g_poly_prev_);
    }
    rhs_ = h_ * q_;
    if (damped_) rhs_ -= (h_ * h_) * g_hat_;
  }
  if (k == 0) dx_ = h_ * problem_.v0;  // predictor; afterwards the previous increment
  const NewtonReport report = newton_.solve(xk, t_half, rhs_, f_ptr, dx_);
  if (const Status s = newton_outcome(report, "M + (h^2/2) w0 h^-2alpha R + (h^2/4) Hess U");
      s != Status::kSuccess)
    return s;
  TrapezoidPass fused;  // the pass below, for diagonal M and R' from kVectorPassesFrom
  if (fused_passes_) {
    fused = trapezoid_step_pass(mass_solver_.diagonal()->data(), mass_solver_.unit_mass(),
                                force_matrix_.stored_diagonal()->data(), xk.data(), dx_.data(),
                                2.0 / h_, current_weight_, sum_.data(), g_poly_.data(),
                                g_poly_prev_.data(), h_, x_next_.data(), q_.data(),
                                mid_tilde_.data(), g_tilde_.data(), g_total_.data(), p_next_.data(),
                                tmp_.data(), diagnostics_, d_);
    if (!fused.finite_position) return fail(Status::kNonFinite, "non-finite position");
    g_poly_prev_.swap(g_poly_);
    memory_->push(k, mid_tilde_);
  } else {
    x_next_ = xk + dx_;
    if (!x_next_.allFinite()) return fail(Status::kNonFinite, "non-finite position");

    // q_{k+1} = MΔ_k/h − (h/2)∇U_f(x̄_k) = 2MΔ_k/h − q_k + hĜ_k.
    mass_.multiply(dx_, p_next_);
    q_ = p_next_ * (2.0 / h_) - q_;
    if (damped_) {
      // x̃̄_k and the full Ĝ_k; then G̃_k = 2Ĝ̃_k − G̃_{k−1} and G_k = G̃_k + G^P_k.
      mid_tilde_ += 0.5 * dx_;
      tmp_ = current_weight_ * mid_tilde_ + sum_;
      force_matrix_.multiply(tmp_, g_total_);  // Ĝ̃_k (x̃ part)
      g_tilde_ = 2.0 * g_total_ - g_tilde_;
      q_ += h_ * g_total_;
      q_ += (0.5 * h_) * (g_poly_ + g_poly_prev_);
      g_total_ = g_tilde_ + g_poly_;
      g_poly_prev_.swap(g_poly_);
      memory_->push(k, mid_tilde_);
    }
    // The node momentum (right Legendre transform of cell k): p_{k+1} = q_{k+1} − (h/2)G_k.
    p_next_ = q_;
    if (damped_) p_next_ -= (0.5 * h_) * g_total_;
    mass_solver_.inverse(p_next_, tmp_);
  }
  if (diagnostics_) {
    // E_{k+1} − E_k = −(G_k − f)·Δ_k for quadratic U (the midpoint rule: ∇U(x̄)·Δ = ΔU), plus
    // the explicit time dependence of U.
    if (damped_) work_ += fused_passes_ ? fused.work : g_total_.dot(dx_);
    // Subtracted term by term as before (bit-for-bit the same W_k), and summed for supplied_.
    if (has_forcing_) {
      const double fw = f_mid_.dot(dx_);
      work_ -= fw;
      supplied_ += fw;
    }
    // The discrete work of g (docs/theory/forces.md §2), as in CqMidpointStepper.
    if (newton_.has_state_force()) {
      const double gw = newton_.state_force_work(xk, dx_, t_half);
      work_ -= gw;
      supplied_ += gw;
    }
    if (u_time_dependent_) {
      mid_ = xk + 0.5 * dx_;
      const double du = potential_value(mid_, problem_.time(static_cast<double>(k + 1))) -
                        potential_value(mid_, problem_.time(static_cast<double>(k)));
      work_ -= du;
      supplied_ += du;
    }
  }
  // p_{k+1} and v_{k+1} are in p_next_ and tmp_ until both checks pass: a failed step leaves
  // x_k, v_k, p_k for the Integrator's last row.
  if (!(fused_passes_ ? fused.finite_velocity : tmp_.allFinite()))
    return fail(Status::kNonFinite, "non-finite velocity");
  p_.swap(p_next_);
  v_cur_.swap(tmp_);
  if (k == 0) x_first_ = x_next_;  // the mirror run starts from x_0, x_1
  x_cur_.swap(x_next_);
  ++k_;
  return Status::kSuccess;
}

// The y-equation (mirror_run.hpp) with D_k = R h^{−β} Σ_m ω̂_m ỹ̄_{k−1+m} + Ĝ^P_k (the node
// average over midpoints, ỹ̄_i mirroring x̃̄_{N−1−i}), its own forward-running pair of histories
// over ȳ_{N−1}, ȳ_{N−2}, … and P's force of the mirrored cells. The weight ω̂_0 of the unknown
// midpoint ȳ_{k−1} = y_k + Δ/2 is in the Newton matrix, as in the x-run.
bool TrapezoidalMidpointStepper::mirror_run(MirrorRows& rows) const {
  struct Damping {
    const TrapezoidalMidpointStepper& self;
    std::size_t n;
    std::unique_ptr<NodeAveragedTrapezoid> memory;
    Eigen::VectorXd s, ytil, poly_a, poly_b;
    // Its own copies of what it reads every step (mirror_run.hpp).
    ModelMatrix force_matrix = self.force_matrix_;
    TaylorCellForce polynomial_force = self.polynomial_force_;
    Eigen::VectorXd x0 = self.problem_.x0, v0 = self.problem_.v0;
    // The midpoint between `lo` and `hi` (midpoint i of y, mirroring x-midpoint N − 1 − i) minus P.
    void mid_tilde(const Eigen::VectorXd& lo, const Eigen::VectorXd& hi, std::size_t i) {
      ytil = 0.5 * (lo + hi);
      self.subtract_polynomial_midpoint(n - 1 - i, x0, v0, ytil);
    }
    void start(const Eigen::VectorXd& y_n, const Eigen::VectorXd& y_n1) {
      if (!self.damped_) return;
      memory = self.make_memory();
      // Midpoint i of y is the (N − 1 − i)-th of the forward-running memory.
      mid_tilde(y_n1, y_n, n - 1);
      memory->known(0, s);
      memory->push(0, ytil);
    }
    void known(std::size_t k, const Eigen::VectorXd& y_k, Eigen::VectorXd& out) {
      out.setZero();
      if (!self.damped_) return;
      // R'(ω̂_0 (y_k − P) + S) + ½(G^P_{N−k} + G^P_{N−k−1}): the unknown half Δ/2 of ȳ_{k−1} is
      // in the Newton matrix; node k mirrors x-node N − k.
      memory->known(n - k, s);
      ytil = y_k;
      self.subtract_polynomial_midpoint(n - k, x0, v0, ytil);
      s += self.current_weight_ * ytil;
      force_matrix.multiply(s, out);
      polynomial_force(n - k, poly_a);
      polynomial_force(n - k - 1, poly_b);
      out += 0.5 * (poly_a + poly_b);
    }
    void accept(std::size_t k, const Eigen::VectorXd& y_km1, const Eigen::VectorXd& y_k) {
      if (!self.damped_) return;
      mid_tilde(y_km1, y_k, k - 1);
      memory->push(n - k, ytil);
    }
  };
  const Eigen::VectorXd work = Eigen::VectorXd::Zero(d_);
  Damping damping{*this, n_steps_, nullptr, work, work, work, work};
  return backward_mirror_run(problem_, options_, mass_, newton_matrix_, h_, x_first_, rows,
                             damping);
}

}  // namespace

const SchemeInfo kFviMidpoint{
    .name = "fvi-midpoint",
    .summary =
        "FVI with the midpoint discrete Lagrangian and trapezoidal (Tustin) CQ memory on "
        "midpoint values; implicit damping",
    .reference =
        "Hariz, Jimenez & Ober-Bloebaum (arXiv 2403.18362, 2510.11082); "
        "docs/theory/fvi_midpoint.md",
    .order_rule = "2",
    .stages = 1,
    .variational = true,
    .variational_quadrature = std::nullopt,  // its Δ^α_± act on midpoint values: no BVP form yet
    .has_mirror = true,
    .exact_balance = true,
    .fast_history = true,  // both memory sums are GL sums (orders 2α and 1 − 2α, lag 1)
    .history_budget_ceiling = kMeasuredHistoryCeiling,  // κ measured for it (history_budget.hpp)
    .momentum_quadrature = CqScheme::kTrapezoidal,
    .forcing_moments = true,  // method.load = "moments": the cell average of f
    .checkpoints = true,
    .no_state_force = "",
    .applies_to = "0 <= 2alpha < 2",
    .stability_rule =
        "stable for every h (implicit damping; the Tustin image of the continuous "
        "characteristic equation)",
    .declared_order = [](const MechanicalModel&) { return 2; },
    // 2α = 2: the trapezoidal CQ of s² has a double pole at ζ = −1, so the momenta amplify
    // position round-off linearly in N (measured: docs/theory/fvi_midpoint.md); fvi-gl and
    // fvi-bdf2 are local there.
    .applicability = trapezoid_applicability,
    .stability = implicit_damping_bound,
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<TrapezoidalMidpointStepper>(problem, options);
    },
};

}  // namespace fracvi::internal
