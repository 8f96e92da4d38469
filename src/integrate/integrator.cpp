#include "fracvi/integrate/integrator.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <string>
#include <utility>

#include "fracvi/integrate/midpoint_newton.hpp"

namespace fracvi {

namespace {

// Shortest round-trip representation ("1e-20", not std::to_string's "0.000000").
std::string fmt(double value) {
  std::array<char, 64> buf{};
  const auto result = std::to_chars(buf.data(), buf.data() + buf.size(), value);
  return {buf.data(), result.ptr};
}

}  // namespace

void validate(const IntegratorOptions& options) {
  const NewtonOptions& n = options.newton;
  if (!std::isfinite(n.relative_tolerance) || n.relative_tolerance < 0.0) {
    throw ValidationError("options.newton.relative_tolerance = " + fmt(n.relative_tolerance) +
                          " must be finite and >= 0");
  }
  if (!std::isfinite(n.absolute_tolerance) || n.absolute_tolerance < 0.0) {
    throw ValidationError("options.newton.absolute_tolerance = " + fmt(n.absolute_tolerance) +
                          " must be finite and >= 0");
  }
  if (n.relative_tolerance == 0.0 && n.absolute_tolerance == 0.0) {
    throw ValidationError(
        "options.newton.relative_tolerance and absolute_tolerance are both 0: at least one must be "
        "positive");
  }
  if (n.max_iterations < 1) {
    throw ValidationError("options.newton.max_iterations = " + std::to_string(n.max_iterations) +
                          " must be >= 1");
  }
  if (options.history != HistoryKind::kAuto && options.history != HistoryKind::kDirect &&
      options.history != HistoryKind::kFast) {
    throw ValidationError("options.history has an unknown value");
  }
  if (!(options.history_tolerance >= 1e-13 && options.history_tolerance <= 1e-3)) {
    throw ValidationError(
        "options.history_tolerance = " + std::to_string(options.history_tolerance) +
        " must be in [1e-13, 1e-3] (per-weight relative accuracy of the fast "
        "history)");
  }
  if (options.save_every < 1) {
    throw ValidationError("options.save_every = 0 must be >= 1 (store every n-th step)");
  }
  if (options.threads < 0) {
    throw ValidationError("options.threads = " + std::to_string(options.threads) +
                          " must be >= 0 (0 = all cores)");
  }
  if (!parse_linear_solver(to_string(options.linear_solver))) {
    throw ValidationError("options.linear_solver has an unknown value");
  }
  if (options.start != StartValue::kDiscreteLegendre &&
      options.start != StartValue::kExplicitEuler) {
    throw ValidationError("options.start has an unknown value");
  }
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const InitialValueProblem& validated(const InitialValueProblem& problem, const Method& method,
                                     const IntegratorOptions& options) {
  validate(problem);
  validate(options);
  if (method.scheme != Scheme::kFviGl) throw ValidationError("method has an unknown scheme");
  return problem;
}

// v = M⁻¹p and w = M⁻¹(R' s) for the scaled damping R' = R h^{−2α}: a dense M keeps its explicit
// inverse and M⁻¹R (one matrix–vector product each, as before the structured path existed); a
// sparse M is factored once, banded or sparse like the Newton matrix, and w costs one product with
// R and one solve.
class MassSolver {
 public:
  MassSolver(const ModelMatrix& mass, const ModelMatrix& damping, LinearSolver solver)
      : dense_(!mass.is_sparse() || solver == LinearSolver::kDense) {
    const Eigen::Index d = mass.rows();
    if (dense_) {
      if (d > internal::kMaxDenseDimension) {
        throw ValidationError("model.mass would be inverted dense (d = " + std::to_string(d) +
                              " > " + std::to_string(internal::kMaxDenseDimension) +
                              "): store M sparse (e.g. ModelMatrix::identity, a scalar or vector "
                              "mass in a problem file) and use linear_solver = auto");
      }
      const Eigen::MatrixXd m = mass.to_dense();
      const Eigen::LLT<Eigen::MatrixXd> llt(m);
      minv_damping_ = ModelMatrix(Eigen::MatrixXd(llt.solve(damping.to_dense())));
      const Eigen::MatrixXd inverse = llt.solve(Eigen::MatrixXd::Identity(d, d));
      inverse_ = ModelMatrix(Eigen::MatrixXd(0.5 * (inverse + inverse.transpose())));
      return;
    }
    auto pattern = std::make_shared<internal::SymmetricPattern>(d);
    pattern->add(mass);
    pattern->finalize();
    LinearSolver backend =
        solver == LinearSolver::kAuto ? internal::choose_factorization(*pattern) : solver;
    if (backend == LinearSolver::kDense) backend = LinearSolver::kSparse;  // M is stored sparse
    factor_ = std::make_unique<internal::SymmetricFactor>(pattern, backend);
    std::span<double> values = factor_->values();
    for (const auto& [at, value] : internal::scatter_upper(*pattern, mass)) values[at] += value;
    if (!factor_->factor()) {
      throw ValidationError("model.mass could not be factored (not positive definite)");
    }
    damping_ = damping;
    scratch_.resize(d);
    // Diagonal M (chains): the solve is a quotient, fused with the product by a diagonal R' — the
    // same roundings as the factor's division, one pass instead of two or three.
    if (mass.is_diagonal()) mass_diagonal_ = mass.sparse().diagonal();
    if (mass.is_diagonal() && damping.is_sparse() && damping.is_diagonal()) {
      damping_diagonal_ = damping.sparse().diagonal();
    }
  }

  // out = M⁻¹ p
  void inverse(const Eigen::Ref<const Eigen::VectorXd>& p, Eigen::Ref<Eigen::VectorXd> out) const {
    if (dense_) {
      inverse_.multiply(p, out);
    } else if (mass_diagonal_.size() > 0) {
      out.array() = p.array() / mass_diagonal_.array();
    } else {
      out = p;
      factor_->solve_in_place(out);
    }
  }
  // out = M⁻¹ R' s
  void inverse_damping(const Eigen::Ref<const Eigen::VectorXd>& s,
                       Eigen::Ref<Eigen::VectorXd> out) {
    if (dense_) {
      minv_damping_.multiply(s, out);
    } else if (damping_diagonal_.size() > 0) {
      out.array() = (damping_diagonal_.array() * s.array()) / mass_diagonal_.array();
    } else {
      damping_.multiply(s, scratch_);
      inverse(scratch_, out);
    }
  }

 private:
  bool dense_;
  ModelMatrix inverse_, minv_damping_;  // dense path: M⁻¹ and M⁻¹R' (1 × 1 products inline)
  std::unique_ptr<internal::SymmetricFactor> factor_;
  ModelMatrix damping_;
  Eigen::VectorXd scratch_;
  Eigen::VectorXd mass_diagonal_, damping_diagonal_;  // when M (and R') are diagonal
};

// Stored rows for N steps every s steps: 0, s, 2s, …, and N.
std::size_t stored_rows(std::size_t n_steps, std::size_t every) {
  return n_steps / every + 1 + (n_steps % every != 0 ? 1 : 0);
}

}  // namespace

struct Integrator::Impl {
  InitialValueProblem problem;
  Method method;
  IntegratorOptions options;

  Eigen::Index d;
  std::size_t n_steps;
  double h;
  double order;      // damping order 2α
  bool damped;       // R ≠ 0
  bool viscous;      // 2α = 1: Lemma 5.3, F_k = R (x_k − x_{k−1})/h, F_0 = R v_0
  bool use_history;  // damped, and not the local α = 1/2 path
  bool shift_x0;     // Caputo: x̃ = x − x_0 …
  bool shift_v0;     // … − t v_0 (2α > 1)
  // Weight of the impulse h F_0 in the start p⁺_0 = M v_0 − w h F_0 (start_step.md §2a): ½ (the
  // trapezoidal split of a smooth force), or 1 for Riemann–Liouville with 0 < 2α < 1, where F_0 =
  // R h^{−2α} x_0 stands for the singular force R x_0 t^{−2α}/Γ(1−2α) and only the full
  // left-rectangle weight of the GL sums is consistent (½ leaves a momentum defect
  // (h^{1−2α}/2) R x_0 and costs the order: 1 − 2α instead of 1).
  double start_force_weight;
  bool has_forcing;
  bool u_time_dependent;
  double damping_scale;  // h^{−2α}

  ModelMatrix mass, damping;  // symmetrised M, R (dense or sparse, as given)
  ModelMatrix force_matrix;   // R h^{−2α}: F = (R h^{−2α}) s in one pass over s
  MassSolver mass_solver;
  std::unique_ptr<History> history;
  internal::MidpointNewton newton;

  Solution sol;
  std::size_t k = 0;
  std::size_t saved = 0;  // rows of sol filled
  Status status = Status::kRunning;

  // Workspace (sized once). x_k, v_k live here; stored rows are copies.
  Eigen::VectorXd x_cur, x_next, v_cur, v_next, x_first;
  Eigen::VectorXd p, p_plus, p_minus, force, force_next, w, w_next, sum, x_tilde, f_mid, rhs, mid,
      grad, dx;
  double fv = 0.0;  // F_k · v_k
  double fw = 0.0;  // F_k · M⁻¹F_k
  double e0 = 0.0;
  double work = 0.0;
  double energy_k = 0.0, work_k = 0.0, balance_k = 0.0;  // at step k

  std::array<char, 400> message{};
  std::chrono::steady_clock::time_point clock_start;
  bool clock_running = false;
  double run_seconds = 0.0;

  Impl(InitialValueProblem prob, Method meth, IntegratorOptions opts)
      : problem(std::move(prob)),
        method(meth),
        options(opts),
        d(problem.model.dimension()),
        n_steps(problem.steps),
        h(problem.step_size()),
        order(problem.model.damping_order()),
        damped(!problem.model.is_undamped()),
        viscous(order == 1.0),
        use_history(damped && !(viscous && options.history != HistoryKind::kDirect)),
        shift_x0(problem.model.convention == Convention::kCaputo && order > 0.0 && order != 1.0),
        shift_v0(problem.model.convention == Convention::kCaputo && order > 1.0),
        start_force_weight(problem.model.convention == Convention::kRiemannLiouville &&
                                   order > 0.0 && order < 1.0
                               ? 1.0
                               : 0.5),
        has_forcing(static_cast<bool>(problem.model.forcing)),
        u_time_dependent(problem.model.potential && problem.model.potential->is_time_dependent()),
        damping_scale(std::pow(h, -order)),
        mass(problem.model.mass.symmetric_part()),
        damping(problem.model.damping.symmetric_part()),
        force_matrix(damping.scaled(damping_scale)),
        mass_solver(mass, force_matrix, options.linear_solver),
        newton(mass, h, problem.model.potential.get(), options.newton, problem.t0,
               options.linear_solver) {
    if (use_history) {
      history = make_history(options.history, order, d, n_steps + 1, options.history_tolerance);
      history->set_threads(options.threads);
      sol.history_bytes = history->memory_bytes();
    }
    const auto rows = static_cast<Eigen::Index>(stored_rows(n_steps, options.save_every));
    sol.t = Eigen::VectorXd::Constant(rows, kNaN);
    sol.step.assign(static_cast<std::size_t>(rows), 0);
    sol.x = RowMatrixXd::Constant(rows, d, kNaN);
    sol.v = RowMatrixXd::Constant(rows, d, kNaN);
    sol.energy = Eigen::VectorXd::Constant(rows, kNaN);
    sol.dissipated = Eigen::VectorXd::Constant(rows, kNaN);
    sol.balance = Eigen::VectorXd::Constant(rows, kNaN);
    sol.method = std::string(method.name());
    sol.declared_order = method.declared_order(problem.model);
    sol.save_every = options.save_every;
    sol.linear_solver = std::string(to_string(newton.linear_solver()));
    for (Eigen::VectorXd* vec :
         {&x_cur, &x_next, &v_cur, &v_next, &x_first, &p, &p_plus, &p_minus, &force, &force_next,
          &w, &w_next, &sum, &x_tilde, &f_mid, &rhs, &mid, &grad, &dx}) {
      vec->setZero(d);
    }
    initial_state();
  }

  Eigen::Map<Eigen::VectorXd> row(RowMatrixXd& m, std::size_t i) {
    return {m.row(static_cast<Eigen::Index>(i)).data(), d};
  }
  // t_i = t0 + i h, the same expression as InitialValueProblem::time() (h is its step_size()).
  [[nodiscard]] double time(std::size_t i) const { return problem.t0 + static_cast<double>(i) * h; }
  [[nodiscard]] double half_time(std::size_t i) const {  // t_{i+½}
    return problem.t0 + (static_cast<double>(i) + 0.5) * h;
  }
  [[nodiscard]] double potential_value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
    return problem.model.potential ? problem.model.potential->value(x, t) : 0.0;
  }

  // Copies the state at step k into the next stored row (steps 0, s, 2s, … and the last one).
  void store() {
    const auto i = static_cast<Eigen::Index>(saved);
    sol.t(i) = time(k);
    sol.step[saved] = k;
    row(sol.x, saved) = x_cur;
    row(sol.v, saved) = v_cur;
    sol.energy(i) = energy_k;
    sol.dissipated(i) = work_k;
    sol.balance(i) = balance_k;
    ++saved;
  }
  [[nodiscard]] bool stored(std::size_t step) const {
    return saved > 0 && sol.step[saved - 1] == step;
  }

  // x̃_i for the Caputo convention (start_step.md §3); x itself for Riemann–Liouville and 2α = 1.
  void tilde(const Eigen::Ref<const Eigen::VectorXd>& x, std::size_t i, Eigen::VectorXd& out) {
    out = x;
    if (shift_x0) out -= problem.x0;
    if (shift_v0) out -= (static_cast<double>(i) * h) * problem.v0;
  }

  // F = R h^{−2α} s and w = M⁻¹F for the history sum s of the latest pushed index.
  void damping_force(Eigen::VectorXd& f_out, Eigen::VectorXd& w_out) {
    history->sum(sum);
    force_matrix.multiply(sum, f_out);
    mass_solver.inverse_damping(sum, w_out);
  }

  void initial_state() {
    x_cur = problem.x0;
    v_cur = problem.v0;
    mass.multiply(problem.v0, p);
    if (damped) {
      if (use_history) {
        tilde(problem.x0, 0, x_tilde);
        history->push(x_tilde);
      }
      if (viscous) {
        // Lemma 5.3's backward difference needs x_{−1}; the consistent force at t_0 is R v_0.
        damping.multiply(problem.v0, force);
        mass_solver.inverse(force, w);
      } else {
        damping_force(force, w);
      }
    }
    if (options.diagnostics) {
      fv = force.dot(problem.v0);
      fw = force.dot(w);
      e0 = 0.5 * problem.v0.dot(p) + potential_value(problem.x0, problem.t0);
      work = 0.0;
      energy_k = e0;
      work_k = 0.0;
      balance_k = 0.0;
    } else {
      energy_k = work_k = balance_k = kNaN;
      sol.max_balance_error = kNaN;
    }
    store();
  }

  Status fail(Status s, const char* what, const char* detail = nullptr) noexcept {
    status = s;
    stop_clock();
    // The last completed step is part of the trajectory so far even between stored rows.
    if (!stored(k)) store();
    std::snprintf(message.data(), message.size(),
                  "%s at step %zu (computing x_%zu at t = %.17g)%s%s", what, k + 1, k + 1,
                  time(k + 1), detail != nullptr ? ": " : "", detail != nullptr ? detail : "");
    return status;
  }

  void stop_clock() noexcept {
    if (clock_running) {
      run_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
      clock_running = false;
    }
  }

  // User callbacks (potential, forcing) may throw; the loop reports that as a status instead.
  Status step() noexcept {
    try {
      return step_unguarded();
    } catch (const std::exception& e) {
      return fail(Status::kCallbackError, "the potential or the forcing threw", e.what());
    } catch (...) {
      return fail(Status::kCallbackError, "the potential or the forcing threw",
                  "unknown exception");
    }
  }

  Status step_unguarded() {
    if (status != Status::kRunning) return status;
    if (!clock_running) {
      clock_start = std::chrono::steady_clock::now();
      clock_running = true;
    }
    const Eigen::VectorXd& xk = x_cur;
    const double tk = time(k), t_half = half_time(k), t_next = time(k + 1);
    const Eigen::VectorXd* f_ptr = nullptr;
    if (has_forcing) {
      problem.model.forcing(t_half, f_mid);
      f_ptr = &f_mid;
    }

    if (k == 0 && options.start == StartValue::kExplicitEuler) {
      // Negative control only: x_1 = x_0 + h v_0, momentum from its discrete Legendre transform.
      dx = h * problem.v0;
      mid = xk + 0.5 * dx;
      newton.effective_gradient(mid, t_half, f_ptr, grad);
      mass.multiply(dx, p_minus);
      p_minus *= 1.0 / h;
      p_minus -= (0.5 * h) * grad;
    } else {
      // p⁺_k = p_k − (h/2) F_k, then M Δ_k + (h²/2)∇U_f(x_k + Δ_k/2, t_{k+½}) = h p⁺_k for the
      // increment Δ_k = x_{k+1} − x_k. Predictor: the previous increment (h v_0 at k = 0).
      p_plus = p - ((k == 0 ? start_force_weight : 0.5) * h) * force;
      rhs = h * p_plus;
      if (k == 0) dx = h * problem.v0;
      const internal::NewtonReport report = newton.solve(xk, t_half, rhs, f_ptr, dx);
      sol.newton_iterations += static_cast<std::size_t>(report.iterations);
      sol.max_newton_iterations_per_step =
          std::max(sol.max_newton_iterations_per_step, static_cast<std::size_t>(report.iterations));
      if (report.status == Status::kNonFinite) {
        return fail(Status::kNonFinite, "non-finite Newton residual or iterate");
      }
      if (report.singular) {
        return fail(Status::kNewtonFailure,
                    "the Newton matrix M + (h^2/4) Hess U could not be factored (singular)");
      }
      if (report.status == Status::kNewtonFailure) {
        char what[200];
        std::snprintf(what, sizeof what,
                      "Newton did not converge within %d iterations (last correction %.3e > "
                      "tolerance %.3e)",
                      report.iterations, report.correction, report.tolerance);
        return fail(Status::kNewtonFailure, what);
      }
      // p⁻_{k+1} = 2MΔ_k/h − p⁺_k (the two one-sided momenta average to M Δ_k/h).
      mass.multiply(dx, p_minus);
      p_minus = p_minus * (2.0 / h) - p_plus;  // one pass, the same roundings as *= then -=
    }
    Eigen::VectorXd& x_new = x_next;
    Eigen::VectorXd& v_new = v_next;
    x_new = xk + dx;
    if (!x_new.allFinite()) return fail(Status::kNonFinite, "non-finite position");

    // Damping force at the new point, grid momentum p_{k+1} = p⁻_{k+1} − (h/2)F_{k+1}, velocity.
    if (damped && !use_history) {
      // Lemma 5.3 without a history object: Σ c_m x_{k+1−m} = x_{k+1} − x_k. Written as
      // (−x_k) + x_{k+1}, the same floating-point operations as the direct sum (bitwise equal).
      sum = x_new - xk;
    } else if (damped) {
      tilde(x_new, k + 1, x_tilde);
      history->push(x_tilde);
      history->sum(sum);
    }
    if (damped) {
      force_matrix.multiply(sum, force_next);
    }
    p = p_minus - (0.5 * h) * force_next;
    mass_solver.inverse(p, v_new);

    // Energy bookkeeping (solution.hpp; start_step.md §4).
    double energy = kNaN, balance = kNaN, fv_next = 0.0, fw_next = 0.0;
    if (options.diagnostics) {
      if (damped) {  // M⁻¹F_{k+1}, for the (h²/8) FᵀM⁻¹F end terms of W
        mass_solver.inverse_damping(sum, w_next);
      }
      energy = 0.5 * v_new.dot(p) + potential_value(x_new, t_next);
      fv_next = force_next.dot(v_new);
      fw_next = force_next.dot(w_next);
      work += 0.5 * h * (fv + fv_next) + 0.125 * h * h * (fw_next - fw);
      // The extra start impulse (w − ½) h F_0 of the singular RL force, booked with v_0.
      if (k == 0) work += (start_force_weight - 0.5) * h * fv;
      if (has_forcing) work -= f_mid.dot(dx);
      if (u_time_dependent) {
        mid = xk + 0.5 * dx;
        work -= potential_value(mid, t_next) - potential_value(mid, tk);
      }
      balance = energy + work - e0;
      if (!std::isfinite(energy) || !std::isfinite(work)) {
        return fail(Status::kNonFinite, "non-finite energy or dissipated work");
      }
    }
    if (!v_new.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");

    if (k == 0) x_first = x_new;  // the mirror run starts from x_0, x_1
    ++k;
    x_cur.swap(x_next);
    v_cur.swap(v_next);
    energy_k = energy;
    work_k = work;
    balance_k = balance;
    if (options.diagnostics) {
      sol.max_balance_error = std::max(sol.max_balance_error, std::abs(balance));
    }
    sol.steps_done = k;
    if (k % options.save_every == 0 || k == n_steps) store();
    force.swap(force_next);
    w.swap(w_next);
    fv = fv_next;
    fw = fw_next;
    if (k == n_steps) {
      status = Status::kSuccess;
      stop_clock();
    }
    return status;
  }

  // The second line of `DiscEqs`, solved backwards from y_N = x_0, y_{N−1} = x_1 for y_{k−1},
  // k = N−1 … 1, in its literal second-difference form (not the momentum form of the x-run), with
  // its own forward-running history: M(y_{k+1} − 2y_k + y_{k−1})/h² + R h^{−2α} Σ_{m=0}^{N−k} c_m
  // ỹ_{k+m} + ½∇U_f(ȳ_k) + ½∇U_f(ȳ_{k−1}) = 0. U and f are evaluated at the mirrored times
  // (y_j ≈ x(a + b − t_j)). Returns max ‖y_k − x_{N−k}‖_∞ over the stored rows x_{N−k}.
  [[nodiscard]] double mirror() const {
    try {
      return mirror_unguarded();
    } catch (...) {
      return kNaN;  // a throwing callback makes the check unavailable, not the run invalid
    }
  }

  [[nodiscard]] double mirror_unguarded() const {
    if (status != Status::kSuccess) return kNaN;
    const std::size_t n = n_steps;
    if (n < 2) return 0.0;
    internal::MidpointNewton solver(mass, h, problem.model.potential.get(), options.newton,
                                    problem.t0, options.linear_solver);
    std::unique_ptr<History> hist;
    if (damped) {
      hist = make_history(options.history, order, d, n + 1, options.history_tolerance);
      hist->set_threads(options.threads);
    }
    // ỹ_j = y_j − y_N − [2α > 1](t_N − t_j) v_0: the Caputo shift of the reversed clock.
    Eigen::VectorXd y_next = problem.x0, y_k = x_first, y_prev(d), shifted(d), s(d), fy(d), g(d),
                    f_tau(d), f_tau2(d), c(d), ym(d), step(d);
    // Δ = y_{k−1} − y_k; the equation is M(Δ_k − Δ_{k+1}) + h²F_k + (h²/2)(∇U_f(ȳ_k) +
    // ∇U_f(ȳ_{k−1})) = 0 (the second difference written with increments, which keeps round-off
    // out of the differences just as in the x-run).
    Eigen::VectorXd delta = y_k - y_next;
    auto push = [&](const Eigen::VectorXd& y, std::size_t j) {
      shifted = y;
      if (shift_x0) shifted -= problem.x0;
      if (shift_v0) shifted -= (static_cast<double>(n - j) * h) * problem.v0;
      hist->push(shifted);
    };
    if (damped) {
      push(y_next, n);
      push(y_k, n - 1);
    }
    // Stored rows in step order; y_{k−1} is compared with x_{N−k+1} when that step is stored.
    std::size_t next_row = 0;
    double err = 0.0;
    for (std::size_t kk = n - 1; kk >= 1; --kk) {
      fy.setZero();
      if (damped) {
        hist->sum(s);
        force_matrix.multiply(s, fy);
      }
      // ȳ_k = (y_{k+1} + y_k)/2 mirrors x̄ at t_{N−k−½}; ȳ_{k−1} mirrors x̄ at t_{N−k+½}.
      const double tau_known = half_time(n - kk - 1), tau_new = half_time(n - kk);
      const Eigen::VectorXd* f_known = nullptr;
      const Eigen::VectorXd* f_new = nullptr;
      if (has_forcing) {
        problem.model.forcing(tau_known, f_tau);
        problem.model.forcing(tau_new, f_tau2);
        f_known = &f_tau;
        f_new = &f_tau2;
      }
      ym = 0.5 * (y_next + y_k);
      solver.effective_gradient(ym, tau_known, f_known, g);
      mass.multiply(delta, c);
      c -= (h * h) * fy;
      c -= (0.5 * h * h) * g;
      step = delta;  // predictor
      const internal::NewtonReport report = solver.solve(y_k, tau_new, c, f_new, step);
      if (report.status != Status::kSuccess) return kNaN;
      delta = step;
      y_prev = y_k + delta;
      const std::size_t mirrored = n - kk + 1;  // y_{kk−1} ≈ x_{mirrored}
      while (next_row < saved && sol.step[next_row] < mirrored) ++next_row;
      if (next_row < saved && sol.step[next_row] == mirrored) {
        const Eigen::Map<const Eigen::VectorXd> x_row(
            sol.x.row(static_cast<Eigen::Index>(next_row)).data(), d);
        err = std::max(err, (y_prev - x_row).cwiseAbs().maxCoeff());
      }
      if (damped) push(y_prev, kk - 1);
      y_next.swap(y_k);
      y_k.swap(y_prev);
    }
    return err;
  }
};

Integrator::Integrator(InitialValueProblem problem, Method method, IntegratorOptions options)
    : impl_(std::make_unique<Impl>(validated(problem, method, options), method, options)) {}

Integrator::~Integrator() = default;
Integrator::Integrator(Integrator&&) noexcept = default;
Integrator& Integrator::operator=(Integrator&&) noexcept = default;

Status Integrator::step() noexcept {
  return impl_->step();
}
Status Integrator::status() const {
  return impl_->status;
}
std::size_t Integrator::steps_done() const {
  return impl_->k;
}
std::size_t Integrator::steps_total() const {
  return impl_->n_steps;
}
double Integrator::time() const {
  return impl_->time(impl_->k);
}

Eigen::Map<const Eigen::VectorXd> Integrator::position() const {
  return {impl_->x_cur.data(), impl_->d};
}
Eigen::Map<const Eigen::VectorXd> Integrator::velocity() const {
  return {impl_->v_cur.data(), impl_->d};
}

StepView Integrator::view() const {
  return StepView{impl_->k,        time(),        position(),      velocity(),
                  impl_->energy_k, impl_->work_k, impl_->balance_k};
}

LinearSolver Integrator::linear_solver() const {
  return impl_->newton.linear_solver();
}

const InitialValueProblem& Integrator::problem() const {
  return impl_->problem;
}
const Method& Integrator::method() const {
  return impl_->method;
}
const IntegratorOptions& Integrator::options() const {
  return impl_->options;
}
const Solution& Integrator::solution() const {
  return impl_->sol;
}

double Integrator::mirror_error() const {
  return impl_->mirror();
}

Solution Integrator::take_solution() {
  Impl& im = *impl_;
  im.stop_clock();
  double seconds = im.run_seconds;
  if (im.options.mirror && im.status == Status::kSuccess) {
    const auto start = std::chrono::steady_clock::now();
    im.sol.mirror_error = im.mirror();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (!im.stored(im.k)) im.store();  // stopped by the caller between stored rows
  Solution s = std::move(im.sol);
  s.status = im.status;
  s.steps_done = im.k;
  s.message = im.status == Status::kSuccess || im.status == Status::kRunning
                  ? std::string()
                  : std::string(im.message.data());
  if (im.status == Status::kRunning) {
    s.message = "stopped by the caller after " + std::to_string(im.k) + " of " +
                std::to_string(im.n_steps) + " steps";
  }
  const auto rows = static_cast<Eigen::Index>(im.saved);
  s.step.resize(im.saved);
  s.t.conservativeResize(rows);
  s.x.conservativeResize(rows, Eigen::NoChange);
  s.v.conservativeResize(rows, Eigen::NoChange);
  s.energy.conservativeResize(rows);
  s.dissipated.conservativeResize(rows);
  s.balance.conservativeResize(rows);
  s.wall_time_seconds = seconds;
  impl_.reset();
  return s;
}

Solution integrate(const InitialValueProblem& problem, const Method& method,
                   const IntegratorOptions& options) {
  Integrator integrator(problem, method, options);
  integrator.run();
  return integrator.take_solution();
}

}  // namespace fracvi
