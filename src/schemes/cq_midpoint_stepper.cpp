#include "cq_midpoint_stepper.hpp"

#include "fracvi/internal/parallel.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/solve/vector_passes.hpp"
#include "mirror_run.hpp"
#include "power_differences.hpp"

#include <algorithm>
#include <boost/math/special_functions/gamma.hpp>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>

namespace fracvi::internal {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

CqMidpointStepper::CqMidpointStepper(const InitialValueProblem& problem,
                                     const IntegratorOptions& options, CqScheme generating_function,
                                     MemoryStart memory_start)
    : problem_(problem),
      options_(options),
      damping_sum_{generating_function, problem.model.damping_order()},
      memory_start_(memory_start),
      d_(problem.model.dimension()),
      n_steps_(problem.steps),
      h_(problem.step_size()),
      damped_(!problem.model.is_undamped()),
      viscous_local_(memory_start == MemoryStart::kPaperStart && damping_sum_.order == 1.0 &&
                     options.history != HistoryKind::kDirect),
      use_history_(damped_ && !viscous_local_),
      has_forcing_(static_cast<bool>(problem.model.forcing)),
      midpoint_force_(problem, options.load),
      u_time_dependent_(problem.model.potential && problem.model.potential->is_time_dependent()),
      diagnostics_(options.diagnostics),
      mass_(problem.model.mass.symmetric_part()),
      damping_(problem.model.damping.symmetric_part()),
      force_matrix_(damping_.scaled(std::pow(h_, -damping_sum_.order))),
      mass_solver_(mass_, force_matrix_, options.linear_solver),
      newton_(mass_, h_, problem.model.potential.get(), options.newton, problem.t0,
              options.linear_solver, problem.model.state_force.get()) {
  const double order = damping_sum_.order;
  const bool caputo = problem.model.convention == Convention::kCaputo;
  if (memory_start == MemoryStart::kPaperStart) {
    shift_x0_ = caputo && order > 0.0 && order != 1.0;
    shift_v0_ = caputo && order > 1.0;
    // Weight of the impulse h F_0 in p⁺_0 = M v_0 − w h F_0 (start_step.md §2a): ½ (the
    // trapezoidal split of a smooth force), or 1 for Riemann–Liouville with 0 < 2α < 1, where
    // F_0 = R h^{−2α} x_0 stands for the singular force R x_0 t^{−2α}/Γ(1−2α) and only the full
    // left-rectangle weight of the GL sums is consistent.
    start_force_weight_ = !caputo && order > 0.0 && order < 1.0 ? 1.0 : 0.5;
  } else {
    // x = P + x̃, P(t) = x_0 + (t − t_0) v_0; D^{2α}P in closed form. D^0 is the identity: no split.
    shift_x0_ = shift_v0_ = order > 0.0;
    start_force_weight_ = 0.5;
    // H(τ) = ∫_0^τ∫_0^σ D^{2α}P, the double antiderivative of P's damping force (per unit R):
    //   v_0 term: D^{2α}τ = τ^{1−2α}/Γ(2−2α)  →  H = τ^{3−2α}/Γ(4−2α)  (0 < 2α < 2; RL and
    //             Caputo alike for 2α ≤ 1; the Caputo derivative of τ vanishes for 2α > 1);
    //   x_0 term: Riemann–Liouville only, 0 < 2α < 1: D^{2α}1 = τ^{−2α}/Γ(1−2α) → H =
    //             τ^{2−2α}/Γ(3−2α) (2α > 1 with x_0 ≠ 0 is refused as ill-posed; integer orders
    //             have none).
    if (order > 0.0 && order < 2.0 && !(caputo && order > 1.0)) {
      jv_ = 1.0 / boost::math::tgamma(4.0 - order);
      ev_ = 3.0 - order;
    }
    if (!caputo && order > 0.0 && order < 1.0) {
      jx_ = 1.0 / boost::math::tgamma(3.0 - order);
      ex_ = 2.0 - order;
    }
    poly_scale_ = std::pow(h_, order - 2.0);
  }
  if (use_history_) {
    history_ = make_history(options.history, damping_sum_, d_, n_steps_ + 1,
                            stepper_history_tolerance(options));
    history_->set_threads(options.threads);
  }
  for (Eigen::VectorXd* vec :
       {&x_cur_, &x_next_, &v_cur_, &v_next_, &x_first_, &p_, &p_plus_, &p_minus_, &force_,
        &force_next_, &w_, &sum_, &x_tilde_, &f_mid_, &rhs_, &mid_, &grad_, &dx_}) {
    vec->setZero(d_);
  }
  fused_passes_ =
      damped_ && mass_solver_.diagonal() != nullptr && force_matrix_.stored_diagonal() != nullptr;
  if (fused_passes_) {
    tilde_x0_ = shift_x0_ ? problem.x0 : Eigen::VectorXd::Zero(d_);
    tilde_v0_ = shift_v0_ ? problem.v0 : Eigen::VectorXd::Zero(d_);
    // The health check's weights √M_ii, as the Integrator takes them (its mass_norm).
    if (d_ >= kVectorPassesFrom && !mass_solver_.unit_mass())
      root_mass_ = health_weights(problem.model.mass);
  }
  g_mid_.setZero(d_);
  // The step split by rows (step_by_rows): the fused passes, the fast history pushed by rows (one
  // thread in it: the team is the step's); a linear solve whose residual goes by rows, or else
  // Newton's solve on one thread.
  // (From kVectorPassesFrom on, whatever row_split_from: the split's momentum pass forms the
  // energy account's F·v and F·M⁻¹F, which advance() reads only from there.)
  by_rows_ = fused_passes_ && d_ >= std::max(options.row_split_from, kVectorPassesFrom) &&
             use_history_ && options.start != StartValue::kExplicitEuler;
  split_newton_ = newton_.solves_by_rows();
  if (by_rows_) {
    history_->set_threads(1);
    by_rows_ = history_->pushes_rows();
    if (!by_rows_) history_->set_threads(options.threads);
  }
  if (by_rows_) {
    // Parts of whole cache lines (64 bytes: the vector kernels' and the history's row blocks).
    for (int p = 0; p < kRowParts; ++p) part_bounds_[p] = d_ * p / kRowParts / 8 * 8;
    part_bounds_[kRowParts] = d_;
    row_team_.configure(options.threads, std::min(team_size(options.threads, d_, 1), kRowParts));
    history_window_ = history_->report().window;
    start_threads(row_team_.team());
  }

  // The state at k = 0: x_0, v_0, p_0 = M v_0 and the damping force F_0.
  x_cur_ = problem.x0;
  v_cur_ = problem.v0;
  mass_.multiply(problem.v0, p_);
  if (damped_) {
    if (viscous_local_) {
      // Lemma 5.3's backward difference needs x_{−1}; the consistent force at t_0 is R v_0.
      damping_.multiply(problem.v0, force_);
      mass_solver_.inverse(force_, w_);
    } else if (memory_start_ == MemoryStart::kPaperStart && damping_sum_.order == 1.0) {
      // 2α = 1 with the direct history (a check of Lemma 5.3 against the full sum): the history
      // holds x_0, the force at t_0 is still R v_0.
      tilde(problem.x0, 0, x_tilde_);
      history_->push(x_tilde_);
      damping_.multiply(problem.v0, force_);
      mass_solver_.inverse(force_, w_);
    } else {
      tilde(problem.x0, 0, x_tilde_);
      history_->push(x_tilde_);
      history_->sum(sum_);
      // F_0 stands for the impulse over [t_0, t_½]: (2/h)·∫ of P's force there.
      if (memory_start_ == MemoryStart::kTaylorSplit)
        add_polynomial_force(0, problem_.x0, problem_.v0, sum_);
      force_matrix_.multiply(sum_, force_);
      mass_solver_.inverse_damping(sum_, force_, w_);
    }
  }
  if (diagnostics_) {
    fv_ = force_.dot(problem.v0);
    fw_ = force_.dot(w_);
    work_ = 0.0;
    supplied_ = 0.0;
  } else {
    work_ = supplied_ = kNaN;
  }
}

void CqMidpointStepper::tilde(const Eigen::Ref<const Eigen::VectorXd>& x, std::size_t i,
                              Eigen::VectorXd& out) const {
  // One pass, the roundings of x, then −x_0, then −t_i v_0 in turn.
  const double t = static_cast<double>(i) * h_;
  shifted_pass(x.data(), shift_x0_ ? problem_.x0.data() : nullptr, t,
               shift_v0_ ? problem_.v0.data() : nullptr, out.data(), d_);
}

void CqMidpointStepper::add_polynomial_force(std::size_t k, const Eigen::VectorXd& x0,
                                             const Eigen::VectorXd& v0, Eigen::VectorXd& s) const {
  add_polynomial_force(k, x0, v0, s, 0, s.size());
}

void CqMidpointStepper::add_polynomial_force(std::size_t k, const Eigen::VectorXd& x0,
                                             const Eigen::VectorXd& v0, Eigen::VectorXd& s,
                                             Eigen::Index lo, Eigen::Index hi) const {
  // P's force at node k in the x-equation M(x_{k+1} − 2x_k + x_{k−1})/h² + F_k + … = 0 is the
  // second difference of H: (H(t_{k+1}) − 2H(t_k) + H(t_{k−1}))/h², which the scheme integrates
  // exactly (P's part of the solution is reproduced to round-off, whatever the singularity of its
  // force at t_0). At k = 0 the start p⁺_0 = M v_0 − (h/2)F_0 reproduces x(t_1) when F_0 =
  // 2H(h)/h². In the units of the history sum (F = R h^{−2α} s): s += h^{2α−2} · (…) with H(τ) = a
  // τ^e.
  auto add = [&](double a, double e, const Eigen::VectorXd& vec) {
    const double second = k == 0 ? 2.0 : second_difference_of_power(k, e);  // × h^e
    // Element by element c·vec_i, then the sum (the same on any range of rows).
    s.segment(lo, hi - lo) +=
        (poly_scale_ * a * std::pow(h_, e) * second) * vec.segment(lo, hi - lo);
  };
  if (jx_ != 0.0) add(jx_, ex_, x0);
  if (jv_ != 0.0) add(jv_, ev_, v0);
}

Status CqMidpointStepper::advance() {
  const Eigen::VectorXd& xk = x_cur_;
  const std::size_t k = k_;
  const double tk = time(k), t_half = half_time(k), t_next = time(k + 1);
  const Eigen::VectorXd* f_ptr = nullptr;
  if (has_forcing_) {
    midpoint_force_(k, t_half, f_mid_);
    f_ptr = &f_mid_;
  }

  const bool euler_start = k == 0 && options_.start == StartValue::kExplicitEuler;
  // The fused passes below form p⁻_{k+1} from Δ_k (not the Euler start's).
  const bool fused = fused_passes_ && !euler_start;
  const bool vector_sums = fused && d_ >= kVectorPassesFrom;
  const bool vector_dots = diagnostics_ && d_ >= kVectorPassesFrom;
  double mass_squares = 0.0;
  MomentumPass momentum;
  if (by_rows_) {
    if (const Status s = step_by_rows(f_ptr, momentum, mass_squares); s != Status::kSuccess)
      return s;
  } else {
    const double* damping_sum = sum_.data();  // Σ c_m x̃_{k+1−m}, in units of R h^{−2α}
    if (euler_start) {
      // Negative control only: x_1 = x_0 + h v_0, momentum from its discrete Legendre transform.
      dx_ = h_ * problem_.v0;
      mid_ = xk + 0.5 * dx_;
      newton_.effective_gradient(mid_, t_half, f_ptr, grad_);
      if (newton_.has_state_force()) {
        newton_.state_force(mid_, dx_, t_half, g_mid_);
        grad_ -= g_mid_;
      }
      mass_.multiply(dx_, p_minus_);
      p_minus_ *= 1.0 / h_;
      p_minus_ -= (0.5 * h_) * grad_;
      set_iterations(0);
    } else {
      // p⁺_k = p_k − (h/2) F_k, then M Δ_k + (h²/2)∇U_f(x_k + Δ_k/2, t_{k+½}) = h p⁺_k for the
      // increment Δ_k = x_{k+1} − x_k. Predictor: the previous increment (h v_0 at k = 0).
      // p⁺_k and the right-hand side h p⁺_k in one pass (the same roundings as two).
      const double impulse = (k == 0 ? start_force_weight_ : 0.5) * h_;
      start_momentum_pass(p_.data(), force_.data(), impulse, h_, p_plus_.data(), rhs_.data(), d_);
      if (k == 0) dx_ = h_ * problem_.v0;
      const NewtonReport report = newton_.solve(xk, t_half, rhs_, f_ptr, dx_);
      if (const Status s = newton_outcome(report, "M + (h^2/4) Hess U"); s != Status::kSuccess)
        return s;
      // p⁻_{k+1} = 2MΔ_k/h − p⁺_k (the two one-sided momenta average to M Δ_k/h).
      if (!fused) {
        mass_.multiply(dx_, p_minus_);
        // One pass, the same roundings as *= then −= (the element passes here and below:
        // vector_passes.hpp; an Eigen expression's set-up costs more than its work at d = 1).
        scale_and_subtract_pass(2.0 / h_, p_plus_.data(), p_minus_.data(), d_);
      }
    }
    // x_{k+1} and its check in one pass; with a diagonal M, p⁻_{k+1} and x̃_{k+1} in the same pass.
    // From kVectorPassesFrom on, the same pass sums the health check's ‖x_{k+1}‖²_M (step_sums()).
    const bool position_finite =
        fused
            ? new_position_pass(mass_solver_.diagonal()->data(), mass_solver_.unit_mass(),
                                dx_.data(), 2.0 / h_, p_plus_.data(), xk.data(), tilde_x0_.data(),
                                static_cast<double>(k + 1) * h_, tilde_v0_.data(), p_minus_.data(),
                                x_next_.data(), use_history_ ? x_tilde_.data() : nullptr, d_,
                                root_mass_.data(), vector_sums ? &mass_squares : nullptr)
            : add_and_check(xk.data(), dx_.data(), x_next_.data(), d_);
    if (!position_finite) return fail(Status::kNonFinite, "non-finite position");

    // Damping force at the new point, grid momentum p_{k+1} = p⁻_{k+1} − (h/2)F_{k+1}, velocity.
    if (viscous_local_ && damped_) {
      // Lemma 5.3 without a history object: Σ c_m x_{k+1−m} = x_{k+1} − x_k. Written as
      // (−x_k) + x_{k+1}, the same floating-point operations as the direct sum (bitwise equal).
      sum_ = x_next_ - xk;
    } else if (damped_) {
      if (!fused) tilde(x_next_, k + 1, x_tilde_);
      history_->push(x_tilde_);
      // The momentum pass reads the sum where the history keeps it (FastHistory): no copy, 80 KB a
      // step at d = 10^4, unless P's force is added to it.
      const double* kept = fused_passes_ && memory_start_ != MemoryStart::kTaylorSplit
                               ? history_->kept_sum()
                               : nullptr;
      if (kept != nullptr) {
        damping_sum = kept;
      } else {
        history_->sum(sum_);
        if (memory_start_ == MemoryStart::kTaylorSplit)
          add_polynomial_force(k + 1, problem_.x0, problem_.v0, sum_);
      }
    }
    // With diagonal M and R', F_{k+1}, p_{k+1}, v_{k+1} and the energy account's F·v and F·M⁻¹F
    // (from kVectorPassesFrom on, in dot_pass's order) in one pass; for M = I, M⁻¹F_{k+1} is
    // F_{k+1}.
    if (fused_passes_) {
      momentum = new_momentum_pass(
          force_matrix_.stored_diagonal()->data(), damping_sum, p_minus_.data(), 0.5 * h_,
          mass_solver_.diagonal()->data(), mass_solver_.unit_mass(), force_next_.data(), p_.data(),
          v_next_.data(), diagnostics_ && !vector_dots ? w_.data() : nullptr, vector_dots, d_);
    } else {
      if (damped_) force_matrix_.multiply(sum_, force_next_);
      subtract_scaled_pass(p_minus_.data(), 0.5 * h_, force_next_.data(), p_.data(), d_);
      mass_solver_.inverse(p_, v_next_);
    }
  }

  // Energy account (solution.hpp; start_step.md §4).
  double fv_next = 0.0, fw_next = 0.0;
  if (diagnostics_) {
    const Eigen::VectorXd& minv_force =
        fused_passes_ && mass_solver_.unit_mass() ? force_next_ : w_;
    if (fused_passes_ && vector_dots) {
      fv_next = momentum.fv;
      fw_next = momentum.fw;
    } else {
      if (damped_ && !fused_passes_) mass_solver_.inverse_damping(sum_, force_next_, w_);
      fv_next = step_dot(force_next_, v_next_);
      fw_next = step_dot(force_next_, minv_force);
    }
    work_ += 0.5 * h_ * (fv_ + fv_next) + 0.125 * h_ * h_ * (fw_next - fw_);
    // The extra start impulse (w − ½) h F_0 of the singular RL force: the kinetic energy it
    // changes exactly, T(p_0 − ½hF_0) − T(p_0 − whF_0) = (w − ½) h F_0·v_0 − ½(w² − ¼) h²
    // F_0ᵀM⁻¹F_0 (docs/theory/start_step.md §2a), so that the balance stays exact for quadratic U.
    // (Booking only the first term left an O(1) balance error at step 1: 3.7 against E_0 = 0.5 for
    // 2α = 0.9, R = 5, x_0 = 1, h = 0.01.)
    if (k == 0) {
      const double w = start_force_weight_;
      work_ += (w - 0.5) * h_ * fv_ - 0.5 * (w * w - 0.25) * h_ * h_ * fw_;
    }
    // Subtracted term by term as before (bit-for-bit the same W_k), and summed for supplied_.
    if (has_forcing_) {
      const double fw = f_mid_.dot(dx_);
      work_ -= fw;
      supplied_ += fw;
    }
    // The discrete work of g: f⁻_k + f⁺_k = h g(x̄_k, Δ_k/h, t_{k+½}) against Δ_k/h (the midpoint
    // rule of the Lagrange–d'Alembert principle; docs/theory/forces.md §2), exact in the balance
    // for quadratic U like that of f.
    if (newton_.has_state_force()) {
      const double gw = newton_.state_force_work(xk, dx_, t_half);
      work_ -= gw;
      supplied_ += gw;
    }
    if (u_time_dependent_) {
      mid_ = xk + 0.5 * dx_;
      const double du = potential_value(mid_, t_next) - potential_value(mid_, tk);
      work_ -= du;
      supplied_ += du;
    }
  }
  if (!(fused_passes_ ? momentum.finite : all_finite_pass(v_next_.data(), d_))) {
    return fail(Status::kNonFinite, "non-finite velocity");
  }

  if (k == 0) x_first_ = x_next_;  // the mirror run starts from x_0, x_1
  ++k_;
  if (vector_sums) {
    step_sums_.step = k_;
    step_sums_.has_mass_squares = true;
    step_sums_.mass_squares = mass_squares;
    step_sums_.has_velocity_momentum = vector_dots;  // the momentum pass's v·p
    step_sums_.velocity_momentum = momentum.vp;
  }
  x_cur_.swap(x_next_);
  v_cur_.swap(v_next_);
  force_.swap(force_next_);
  fv_ = fv_next;
  fw_ = fw_next;
  return Status::kSuccess;
}

// The step from p⁺_k to the momentum pass, rows [lo, hi) of each of kRowParts parts at a time,
// in rounds between which every part's rows must be done: (1) p⁺_k and h p⁺_k, the predictor,
// and for a linear step (split_newton_) the midpoint — formed at the end of the previous step's
// rounds when it was split too; (2) a linear step's residual (the potential's gradient reads the
// neighbouring rows' midpoints), then its solve on one thread (the tridiagonal solve is bound by
// its recurrences' latency: in two halves on two threads each half took as long as the whole,
// and on one thread the halves took twice as long; bench/RESULTS.md) — or else Newton's whole
// solve on one thread (its iterations, kept Jacobian and stopping rule as in advance()); (3) a
// linear step's correction, and x_{k+1}, p⁻_{k+1} and x̃_{k+1}; (4), unless some values are
// non-finite, the history's push, the momentum pass and the next step's round (1). Every
// element's operations are advance()'s, so the trajectory is the same bit for bit whatever the
// team (and as with the whole passes); the sums are formed part by part and added in part order,
// so they too are the same for any team (and differ from the whole passes' in their last bits).
// Each part's rows stay on one core: at d = 10^4 a half of the history's state (≈ 1 MB) fits the
// core's L2, where the whole state did not (bench/RESULTS.md).
Status CqMidpointStepper::step_by_rows(const Eigen::VectorXd* forcing, MomentumPass& momentum,
                                       double& mass_squares) {
  const std::size_t k = k_;
  const double t_half = half_time(k);
  const double impulse = (k == 0 ? start_force_weight_ : 0.5) * h_;
  const double* f = forcing != nullptr ? forcing->data() : nullptr;
  const double* m = mass_solver_.diagonal()->data();
  const bool unit_mass = mass_solver_.unit_mass();
  const double* root_mass = root_mass_.size() > 0 ? root_mass_.data() : nullptr;
  const bool dots = diagnostics_;  // d ≥ kVectorPassesFrom: the momentum pass sums F·v, F·M⁻¹F
  const bool taylor_split = memory_start_ == MemoryStart::kTaylorSplit;
  struct alignas(64) Part {  // a part's results, a cache line each (written by its thread)
    bool residual_finite = false, position_finite = false;
    CorrectionPass correction;
    double mass_squares = 0.0;
    MomentumPass momentum;
  };
  std::array<Part, kRowParts> parts{};
  const bool factored = !split_newton_ || newton_.factor_ok();
  NewtonReport report;        // Newton's on one thread (!split_newton_), written by thread 0
  std::exception_ptr thrown;  // what it threw (a user's potential), rethrown after the rounds
  // Round (1) ran at the end of the previous step's rounds (next_started_), unless that step was
  // not split or a checkpoint was loaded since; this step's does so for the next (if any).
  const bool started = next_started_;
  next_started_ = false;
  const bool start_next = k + 1 < n_steps_;
  // The steps before the history's window is full skip its recursions: the choice measures
  // again from the first step with them (as the history's own team does; a first trial of one
  // thread on those cheap steps lost the team a whole hold at d = 2·10^4).
  if (history_->size() == history_window_) row_team_.restart();
  const int threads = row_team_.measuring()
                          ? row_team_.next_by_period(std::chrono::steady_clock::now())
                          : row_team_.next();
  ++row_steps_;
  if (threads > 1) ++row_team_steps_;
  // With Newton's solve on one thread, the team's other threads run the history's work that does
  // not need x̃_{k+1} meanwhile (History::set_rows_ahead). One thread keeps the push's own passes:
  // after the solve, the groups' passes made its next solve's residual slower (one thread,
  // β-FPUT d = 10^4: 155 against 146 µs a step; bench/RESULTS.md).
  if (!split_newton_) history_->set_rows_ahead(threads > 1);
  // Begun before the rounds (its bookkeeping; with the groups ahead, their recursions run in round
  // (2)): a step that fails before round (4) leaves the pushed values and the sum as they were.
  if (factored) history_->begin_row_push(x_tilde_.data());
  // Thread `me` of `team` runs the parts [me P/team, (me + 1) P/team), P = kRowParts; `barrier`
  // waits for the team.
  auto step = [&](int me, int team, auto&& barrier) {
    auto each = [&](auto&& rows) {
      for (int p = me * kRowParts / team; p < (me + 1) * kRowParts / team; ++p)
        rows(parts[p], part_bounds_[p], part_bounds_[p + 1]);
    };
    if (!started) {
      each([&](Part&, Eigen::Index lo, Eigen::Index hi) {
        start_momentum_pass(p_.data() + lo, force_.data() + lo, impulse, h_, p_plus_.data() + lo,
                            rhs_.data() + lo, hi - lo);
        if (k == 0) {
          for (Eigen::Index i = lo; i < hi; ++i) dx_[i] = h_ * problem_.v0[i];
        }
        if (split_newton_) newton_.rows_midpoint(x_cur_.data(), dx_.data(), lo, hi);
      });
      barrier();
    }
    if (!factored) return;
    if (split_newton_) {
      each([&](Part& part, Eigen::Index lo, Eigen::Index hi) {
        part.residual_finite = newton_.rows_residual(t_half, f, rhs_.data(), dx_.data(), lo, hi);
      });
      barrier();
      if (me == 0) newton_.solve_residual();
    } else {
      if (me == 0) {
        try {
          report = newton_.solve(x_cur_, t_half, rhs_, forcing, dx_);
        } catch (...) {
          thrown = std::current_exception();
        }
      }
      // Meanwhile the other threads run the history's work that does not need x̃_{k+1}.
      if (me > 0) history_->rows_ahead(me - 1, team - 1);
    }
    barrier();
    if (thrown || report.status != Status::kSuccess) return;
    each([&](Part& part, Eigen::Index lo, Eigen::Index hi) {
      if (split_newton_) {
        part.correction = newton_.rows_correction(x_cur_.data(), dx_.data(), lo, hi);
      } else {
        part.residual_finite = true;  // solve() checked them
      }
      part.position_finite = new_position_pass(
          m + lo, unit_mass, dx_.data() + lo, 2.0 / h_, p_plus_.data() + lo, x_cur_.data() + lo,
          tilde_x0_.data() + lo, static_cast<double>(k + 1) * h_, tilde_v0_.data() + lo,
          p_minus_.data() + lo, x_next_.data() + lo, x_tilde_.data() + lo, hi - lo,
          root_mass != nullptr ? root_mass + lo : nullptr, &part.mass_squares);
    });
    barrier();
    const bool finite = std::all_of(parts.begin(), parts.end(), [](const Part& q) {
      return q.residual_finite && q.correction.finite && std::isfinite(q.correction.size) &&
             q.position_finite;
    });
    if (!finite) return;
    const double* kept = history_->kept_sum();
    each([&](Part& part, Eigen::Index lo, Eigen::Index hi) {
      history_->push_rows(lo, hi);
      const double* damping_sum = kept + lo;
      if (taylor_split) {  // advance()'s sum() copy and P's force, on these rows
        copy_elements(kept + lo, sum_.data() + lo, hi - lo);
        add_polynomial_force(k + 1, problem_.x0, problem_.v0, sum_, lo, hi);
        damping_sum = sum_.data() + lo;
      }
      part.momentum = new_momentum_pass(force_matrix_.stored_diagonal()->data() + lo, damping_sum,
                                        p_minus_.data() + lo, 0.5 * h_, m + lo, unit_mass,
                                        force_next_.data() + lo, p_.data() + lo,
                                        v_next_.data() + lo, nullptr, dots, hi - lo);
      // Round (1) of the next step, from p_{k+1}, F_{k+1}, x_{k+1} and the predictor Δ_k while
      // these rows are in cache: the end of this step's rounds is the next one's first barrier.
      if (start_next) {
        start_momentum_pass(p_.data() + lo, force_next_.data() + lo, 0.5 * h_, h_,
                            p_plus_.data() + lo, rhs_.data() + lo, hi - lo);
        if (split_newton_) newton_.rows_midpoint(x_next_.data(), dx_.data(), lo, hi);
      }
    });
  };
  if (threads > 1) {
    const unsigned flush = flush_bits();  // the team computes as the caller does
#pragma omp parallel num_threads(threads)
    {
      adopt_flush_bits(flush);
      step(omp_get_thread_num(), omp_get_num_threads(), [] {
#pragma omp barrier
      });
    }
  } else {
    step(0, 1, [] {});
  }

  if (thrown) std::rethrow_exception(thrown);
  if (split_newton_) {
    // solve()'s report of its one correction.
    report.iterations = 1;
    if (!factored) {
      report.status = Status::kNewtonFailure;
      report.singular = true;
      report.correction = std::numeric_limits<double>::infinity();
    } else if (!std::all_of(parts.begin(), parts.end(),
                            [](const Part& q) { return q.residual_finite; })) {
      report.status = Status::kNonFinite;
    } else {
      bool finite = true;
      for (const Part& q : parts) {
        report.correction = std::max(report.correction, q.correction.size);
        finite = finite && q.correction.finite;
      }
      if (!finite || !std::isfinite(report.correction)) report.status = Status::kNonFinite;
    }
  }
  // advance()'s failures in its order.
  if (const Status s = newton_outcome(report, "M + (h^2/4) Hess U"); s != Status::kSuccess)
    return s;
  if (!std::all_of(parts.begin(), parts.end(), [](const Part& q) { return q.position_finite; }))
    return fail(Status::kNonFinite, "non-finite position");
  history_->end_row_push();
  next_started_ = start_next;  // round (4) ran
  mass_squares = 0.0;
  momentum = MomentumPass{};
  for (const Part& q : parts) {
    mass_squares += q.mass_squares;
    momentum.finite = momentum.finite && q.momentum.finite;
    momentum.fv += q.momentum.fv;
    momentum.fw += q.momentum.fw;
    momentum.vp += q.momentum.vp;
  }
  return Status::kSuccess;
}

HistoryReport CqMidpointStepper::history() const {
  if (!history_) return {};
  HistoryReport report = history_->report();
  if (by_rows_) {
    // The step's team, not the history's (one thread inside the split step).
    report.threads = {row_team_.team(),
                      row_team_.measuring(),
                      row_steps_,
                      row_team_steps_,
                      row_team_.decisions(),
                      row_team_.team_won(),
                      row_team_.team_dropped(),
                      true};
  }
  return report;
}

void CqMidpointStepper::visit_state(StateArchive& archive) {
  next_started_ = false;  // a loaded state: the next step forms its own p⁺ and midpoint
  visit_step_index(archive, d_, n_steps_, k_);
  archive.dense("cq_midpoint.x", x_cur_);
  archive.dense("cq_midpoint.v", v_cur_);
  archive.dense("cq_midpoint.p", p_);
  archive.dense("cq_midpoint.force", force_);  // F_k
  // Newton's predictor is the previous increment Δ_{k−1}: it changes the iterates, hence the
  // last bits of a nonlinear step.
  archive.dense("cq_midpoint.increment", dx_);
  newton_.visit_state(archive, "cq_midpoint.newton");  // and Newton's kept Jacobian
  archive.dense("cq_midpoint.x1", x_first_);           // the mirror run starts from x_0, x_1
  archive.number("cq_midpoint.fv", fv_);
  archive.number("cq_midpoint.fw", fw_);
  archive.number("cq_midpoint.work", work_);
  archive.number("cq_midpoint.supplied", supplied_);
  archive.optional("cq_midpoint.history", history_.get());
}

// The y-equation (mirror_run.hpp) with D_k = R h^{−2α} Σ_{m=0}^{N−k} ω_m ỹ_{k+m}, all of it known
// (explicit memory): a forward-running history fed with ỹ_N, ỹ_{N−1}, …, ỹ_j = y_j − y_N −
// (t_N − t_j) v_0 (the shift of the reversed clock); kTaylorSplit adds P's force of the mirrored
// node. The damping reads its own copies of R h^{−2α}, x_0 and v_0 (mirror_run.hpp).
bool CqMidpointStepper::mirror_run(MirrorRows& rows) const {
  struct Damping {
    const CqMidpointStepper& self;
    std::unique_ptr<History> hist;
    Eigen::VectorXd shifted, s;
    std::size_t n;
    ModelMatrix force_matrix = self.force_matrix_;
    Eigen::VectorXd x0 = self.problem_.x0, v0 = self.problem_.v0;
    void push(const Eigen::VectorXd& y, std::size_t j) {
      // ỹ_j in one pass, the same roundings as y, then −x_0, then −(t_N − t_j) v_0.
      const double span = static_cast<double>(n - j) * self.h_;
      shifted_pass(y.data(), self.shift_x0_ ? x0.data() : nullptr, span,
                   self.shift_v0_ ? v0.data() : nullptr, shifted.data(), self.d_);
      hist->push(shifted);
    }
    void start(const Eigen::VectorXd& y_n, const Eigen::VectorXd& y_n1) {
      if (!self.damped_) return;
      hist = make_history(self.options_.history, self.damping_sum_, self.d_, n + 1,
                          stepper_history_tolerance(self.options_));
      hist->set_threads(self.options_.threads);
      push(y_n, n);
      push(y_n1, n - 1);
    }
    void known(std::size_t k, const Eigen::VectorXd&, Eigen::VectorXd& out) {
      out.setZero();
      if (!self.damped_) return;
      hist->sum(s);
      // Node k mirrors the x-index N − k.
      if (self.memory_start_ == MemoryStart::kTaylorSplit)
        self.add_polynomial_force(n - k, x0, v0, s);
      force_matrix.multiply(s, out);
    }
    void accept(std::size_t k, const Eigen::VectorXd& y_km1, const Eigen::VectorXd&) {
      if (self.damped_) push(y_km1, k - 1);
    }
  } damping{*this, nullptr, Eigen::VectorXd(d_), Eigen::VectorXd(d_), n_steps_};
  return backward_mirror_run(problem_, options_, mass_, mass_, h_, x_first_, rows, damping);
}

}  // namespace fracvi::internal
