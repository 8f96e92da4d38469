// pi-trapezoid: product integration with the trapezoidal rule for the Caputo problem written as a
// Volterra equation — the method of Garrappa's MT_FDE_PI2_IM (multi-term FDEs, implicit, order 2;
// Garrappa, Mathematics 6(2) 16, 2018; docs/theory/baselines.md §5). Applying I² to
// M x'' + R D^{2α} x = G(t, x) := f(t) − ∇U(x, t) gives
//
//   M (x − x_0 − t v_0) + R I^{2−2α}(x − T)(t) = I² G(t),   T = 0 (2α = 0), x_0 (0 < 2α ≤ 1),
//                                                              x_0 + t v_0 (2α > 1),
//
// and every fractional integral is replaced by the integral of the piecewise-linear interpolant:
//   I^γ g(t_n) ≈ h^γ/Γ(γ+2) [a^{(γ)}_{n,0} g_0 + Σ_{j=1}^{n} a^{(γ)}_{n−j} g_j],
//   a_0 = 1, a_m = (m−1)^{γ+1} − 2m^{γ+1} + (m+1)^{γ+1}, a_{n,0} = (n−1)^{γ+1} − (n−1−γ) n^γ.
// The j = n terms hold x_n: (M + s R) x_n + (h²/6) ∇U_f(x_n, t_n) = known, by Newton.
// Velocities from the differentiated equation, by the same rule:
//   2α ≤ 1:  M (v_n − v_0) = I¹G(t_n) − R I^{1−2α}(x − T)(t_n),
//   2α > 1:  M (v_n − v_0) + R I^{2−2α}(v − v_0)(t_n) = I¹G(t_n)   (a linear solve with M + s R).
// The last term of each is J_n = ∫_0^{t_n} R D^{2α}x, the damping impulse: the energy account books
// (J_n − J_{n−1})·½(v_{n−1} + v_n), O(h²).
// History: method.history = "direct" sums every product directly, O(n·d) per step; "fast" (and
// "auto" from kFftCrossover steps) accumulates them by OnlineConvolution, the FFT-blocked sums of
// Hairer, Lubich & Schlichte (Garrappa's codes use the same), O(log² n · d) per step. Both keep the
// values, O(N·d) memory. The load I²G has the weights a^{(2)}_m = 6m: a two-term recursion there.
#include <Eigen/Eigenvalues>
#include <boost/math/special_functions/gamma.hpp>
#include <boost/math/special_functions/zeta.hpp>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "baseline_support.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/core/matrix.hpp"
#include "fracvi/memory/online_convolution.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"
#include "power_differences.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The product-trapezoidal weights of I^γ on a grid of n_max steps, stored reversed so that the
// history sum is one contiguous matrix–vector product.
class ProductTrapezoid {
 public:
  ProductTrapezoid(double gamma, double h, std::size_t n_max)
      : gamma_(gamma),
        scale_(std::pow(h, gamma) / boost::math::tgamma(gamma + 2.0)),
        reversed_(static_cast<Eigen::Index>(n_max + 1)) {
    const auto n = static_cast<Eigen::Index>(n_max);
    for (Eigen::Index m = 0; m <= n; ++m) {
      const double a =
          m == 0 ? 1.0 : second_difference_of_power(static_cast<std::size_t>(m), gamma + 1.0);
      reversed_[n - m] = a;
    }
  }
  /// h^γ/Γ(γ+2)
  [[nodiscard]] double scale() const { return scale_; }
  /// a_0 … a_{n_max}
  [[nodiscard]] Eigen::VectorXd weights() const { return reversed_.reverse(); }
  /// a_{n,0}, the weight of g_0 at t_n.
  [[nodiscard]] double first_weight(std::size_t n) const {
    return taylor_remainder_of_power(n, gamma_ + 1.0);
  }
  /// out = a_{n,0} g_0 + Σ_{j=1}^{n−1} a_{n−j} g_j (the part without g_n), rows g_j of `values`.
  void known(std::size_t n, const RowMatrixXd& values, Eigen::VectorXd& out) const {
    out.noalias() = first_weight(n) * values.row(0).transpose();
    if (n >= 2) {
      const auto count = static_cast<Eigen::Index>(n - 1);
      const Eigen::Index first = reversed_.size() - static_cast<Eigen::Index>(n);  // a_{n−1}
      out.noalias() += values.middleRows(1, count).transpose() * reversed_.segment(first, count);
    }
  }

 private:
  double gamma_, scale_;
  Eigen::VectorXd reversed_;  // reversed_[n_max − m] = a_m
};

// Steps from which method.history = "auto" takes the FFT-blocked sums (bench/RESULTS.md,
// "pi-trapezoid history": below it the direct sums cost at most about as much).
constexpr std::size_t kFftCrossover = 512;

// The known part of one rule over one series, a_{n,0} z_0 + Σ_{j=1}^{n−1} a_{n−j} z_j: directly
// (ProductTrapezoid::known), or with the interior sum from an OnlineConvolution over z_1, z_2, …
// (its series index i is the row i + 1, so its s_{n−1} is the interior sum at t_n).
class ProductSum {
 public:
  ProductSum(const ProductTrapezoid& rule, bool fft, Eigen::Index d, std::size_t n_steps)
      : rule_(rule) {
    if (fft) online_.emplace(rule.weights(), d, n_steps, 1);
  }
  void known(std::size_t n, const RowMatrixXd& values, Eigen::VectorXd& out) const {
    if (!online_) return rule_.known(n, values, out);
    out.noalias() =
        rule_.first_weight(n) * values.row(0).transpose() + online_->pending(n - 1).transpose();
  }
  /// Row n ≥ 1 of values is final.
  void commit(std::size_t n, const RowMatrixXd& values) {
    if (online_) online_->commit(n - 1, values);
  }
  [[nodiscard]] std::size_t memory_bytes() const { return online_ ? online_->memory_bytes() : 0; }

 private:
  const ProductTrapezoid& rule_;
  std::optional<OnlineConvolution> online_;
};

bool use_fft(const IntegratorOptions& options, std::size_t n_steps) {
  return options.history == HistoryKind::kFast ||
         (options.history == HistoryKind::kAuto && n_steps >= kFftCrossover);
}

class PiTrapezoidStepper final : public Stepper {
 public:
  PiTrapezoidStepper(const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        beta_(problem.model.damping_order()),
        d_(problem.model.dimension()),
        n_steps_(problem.steps),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        diagnostics_(options.diagnostics),
        taylor_x0_(damped_ && beta_ > 0.0),
        taylor_v0_(damped_ && beta_ > 1.0),
        mass_(problem.model.mass.symmetric_part()),
        damping_(problem.model.damping.symmetric_part()),
        fft_(use_fft(options, n_steps_)),
        memory_(2.0 - beta_, h_, n_steps_),
        velocity_memory_(beta_ > 1.0 ? 2.0 - beta_ : 1.0 - beta_, h_, n_steps_),
        load_(2.0, h_, n_steps_),
        position_sum_(memory_, fft_ && damped_, d_, n_steps_),
        // 2α > 1: the rule of memory_ over e; otherwise velocity_memory_'s over d.
        velocity_sum_(taylor_v0_ ? memory_ : velocity_memory_, fft_ && damped_, d_, n_steps_),
        // A = M + s R with s = h^{2−2α}/Γ(4−2α); the Newton equation A Δ + (h²/6)∇U_f(x + Δ) = c
        // is MidpointNewton's A Δ' + (h'²/2)∇U_f(x + Δ'/2) = 2c with Δ' = 2Δ, h' = 2h/√6.
        newton_matrix_(damped_ ? linear_combination(mass_, memory_.scale(), damping_) : mass_),
        newton_(newton_matrix_, 2.0 * std::sqrt(load_.scale()), problem.model.potential.get(),
                options.newton, problem.t0, options.linear_solver),
        mass_solver_(mass_, damping_, options.linear_solver),
        velocity_solver_(newton_matrix_, damping_, options.linear_solver),
        external_(problem) {
    const auto rows = static_cast<Eigen::Index>(n_steps_ + 1);
    values_d_.setZero(damped_ ? rows : 1, d_);
    values_g_.setZero(fft_ ? 1 : rows, d_);  // the FFT path keeps G_0 and two running sums
    if (taylor_v0_) values_e_.setZero(rows, d_);
    for (Eigen::VectorXd* vec :
         {&x_, &v_, &p_, &x_next_, &v_next_, &g_, &f_, &rhs_, &sum_, &tmp_, &dx_, &impulse_,
          &impulse_next_, &load_sum_, &load_total_, &load_ramp_, &velocity_known_}) {
      vec->setZero(d_);
    }
    x_ = problem.x0;
    v_ = problem.v0;
    mass_.multiply(v_, p_);
    // Row 0: d_0 = x_0 − T(0), G_0 = f(t_0) − ∇U(x_0, t_0) (e_0 = 0). A callback that throws here
    // throws again in step 1, where it is reported; so evaluate G_0 lazily there.
    taylor(0, tmp_);
    values_d_.row(0) = (x_ - tmp_).transpose();
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return newton_.linear_solver(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    return newton_.factorizations();
  }
  [[nodiscard]] HistoryReport history() const override {
    return {fft_ ? "fft" : "direct",
            static_cast<std::size_t>(values_d_.size() + values_g_.size() + values_e_.size()) *
                    sizeof(double) +
                position_sum_.memory_bytes() + velocity_sum_.memory_bytes(),
            0,
            0,
            {}};
  }

 private:
  // T(t_n): the Taylor polynomial the damping term's Caputo derivative removes.
  void taylor(std::size_t n, Eigen::VectorXd& out) const {
    out.setZero();
    if (taylor_x0_) out += problem_.x0;
    if (taylor_v0_) out += (static_cast<double>(n) * h_) * problem_.v0;
  }
  // G(t, x) = f(t) − ∇U(x, t) into g_ (f_ holds f(t) or the pointer is null).
  void load(const Eigen::VectorXd& x, double t, const Eigen::VectorXd* f_ptr) {
    newton_.effective_gradient(x, t, f_ptr, g_);
    g_ = -g_;
  }

  Status advance() override {
    const std::size_t n = k_ + 1;
    const double t = problem_.time(static_cast<double>(n));
    const double tau = static_cast<double>(n) * h_;
    const Eigen::VectorXd* f_ptr = nullptr;
    if (n == 1) {
      if (problem_.model.forcing) {
        problem_.model.forcing(problem_.t0, f_);
        f_ptr = &f_;
      }
      load(x_, problem_.t0, f_ptr);
      values_g_.row(0) = g_.transpose();
      load_sum_ = (0.5 * h_) * g_;  // I¹G(t_1) without G_1
    }
    f_ptr = nullptr;
    if (problem_.model.forcing) {
      problem_.model.forcing(t, f_);
      f_ptr = &f_;
    }
    // c = M(x_0 + τ v_0) + s R (T_n − Hd) + (h²/6) H2 − A x_{n−1}.
    tmp_ = problem_.x0 + tau * problem_.v0;
    mass_.multiply(tmp_, rhs_);
    if (fft_) {
      sum_ = load_.first_weight(n) * values_g_.row(0).transpose() + load_ramp_;
    } else {
      load_.known(n, values_g_, sum_);
    }
    rhs_ += load_.scale() * sum_;
    if (damped_) {
      position_sum_.known(n, values_d_, sum_);
      taylor(n, tmp_);
      tmp_ -= sum_;
      damping_.multiply(tmp_, sum_);
      rhs_ += memory_.scale() * sum_;
    }
    newton_matrix_.multiply(x_, tmp_);
    rhs_ -= tmp_;
    rhs_ *= 2.0;
    dx_ = (2.0 * h_) * v_;  // predictor Δ' = 2 h v_{n−1}
    const NewtonReport report = newton_.solve(x_, t, rhs_, f_ptr, dx_);
    if (const Status s = newton_outcome(report, "M + s R + (h^2/6) Hess U"); s != Status::kSuccess)
      return s;
    x_next_ = x_ + 0.5 * dx_;
    if (!x_next_.allFinite()) return fail(Status::kNonFinite, "non-finite position");
    const auto row = static_cast<Eigen::Index>(n);
    if (damped_) {
      taylor(n, tmp_);
      values_d_.row(row) = (x_next_ - tmp_).transpose();
      position_sum_.commit(n, values_d_);
    }
    load(x_next_, t, f_ptr);
    if (fft_) {
      // a^{(2)}_m = (m−1)³ − 2m³ + (m+1)³ = 6m, so the interior sum at t_{n+1} is the one at
      // t_n plus 6 Σ_{j=1}^{n} G_j.
      load_total_ += g_;
      load_ramp_ += 6.0 * load_total_;
    } else {
      values_g_.row(row) = g_.transpose();
    }

    // Velocity and the damping impulse J_n.
    load_sum_ += (0.5 * h_) * g_;  // I¹G(t_n), trapezoidal
    impulse_next_.setZero();
    if (damped_ && beta_ > 1.0) {
      // (M + s R) v_n = M v_0 + s R (v_0 − He) + I¹G(t_n), He over e_j = v_j − v_0.
      velocity_sum_.known(n, values_e_, velocity_known_);
      tmp_ = problem_.v0 - velocity_known_;
      damping_.multiply(tmp_, sum_);
      mass_.multiply(problem_.v0, tmp_);
      tmp_ += memory_.scale() * sum_ + load_sum_;
      velocity_solver_.inverse(tmp_, v_next_);
      values_e_.row(row) = (v_next_ - problem_.v0).transpose();
      velocity_sum_.commit(n, values_e_);
      sum_ = velocity_known_ + values_e_.row(row).transpose();
      damping_.multiply(sum_, impulse_next_);
      impulse_next_ *= memory_.scale();
    } else {
      if (damped_) {
        velocity_sum_.known(n, values_d_, sum_);
        velocity_sum_.commit(n, values_d_);
        sum_ += values_d_.row(row).transpose();
        damping_.multiply(sum_, impulse_next_);
        impulse_next_ *= velocity_memory_.scale();
      }
      tmp_ = load_sum_ - impulse_next_;
      mass_solver_.inverse(tmp_, v_next_);
      v_next_ += problem_.v0;
    }
    load_sum_ += (0.5 * h_) * g_;  // the interior weight h of G_n for the next steps
    if (!v_next_.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");
    if (diagnostics_) {
      if (damped_) work_ += 0.5 * (impulse_next_ - impulse_).dot(v_ + v_next_);
      const double supplied = external_.step(k_, x_, x_next_);
      work_ -= supplied;
      supplied_ += supplied;
    }
    impulse_.swap(impulse_next_);
    x_.swap(x_next_);
    v_.swap(v_next_);
    mass_.multiply(v_, p_);
    ++k_;
    return Status::kSuccess;
  }

  const InitialValueProblem& problem_;
  double beta_;
  Eigen::Index d_;
  std::size_t n_steps_;
  double h_;
  bool damped_, diagnostics_, taylor_x0_, taylor_v0_;
  ModelMatrix mass_, damping_;
  bool fft_;  // OnlineConvolution sums (method.history = "fast", or "auto" for long runs)
  ProductTrapezoid memory_, velocity_memory_, load_;
  ProductSum position_sum_, velocity_sum_;  // memory_ over d; the velocity's rule over e or d
  ModelMatrix newton_matrix_;               // M + s R
  MidpointNewton newton_;
  MassSolver mass_solver_, velocity_solver_;  // M⁻¹ and (M + s R)⁻¹
  ExternalWork external_;
  RowMatrixXd values_d_, values_g_, values_e_;  // d_j = x_j − T_j, G_j, e_j = v_j − v_0
  std::size_t k_ = 0;
  Eigen::VectorXd x_, v_, p_, x_next_, v_next_, g_, f_, rhs_, sum_, tmp_, dx_, impulse_,
      impulse_next_, load_sum_;
  Eigen::VectorXd load_total_, load_ramp_;  // FFT path: Σ_{j=1}^{n} G_j and the I² interior sum
  Eigen::VectorXd velocity_known_;          // the velocity rule's known part at t_n
  double work_ = 0.0, supplied_ = 0.0;
};

// The symbol of the product-trapezoidal weights at the highest grid frequency ξ = −1:
// Σ_m a^{(γ)}_m (−1)^m = 4 η(−γ−1) (a_m are the second differences of m^{γ+1}, so Σ a_m ξ^m =
// (1 − ξ)² Li_{−γ−1}(ξ)/ξ, and Li_s(−1) = −η(s)), η(s) = (1 − 2^{1−s}) ζ(s). 1 for γ = 0, 0 for the
// trapezoidal rule γ = 1, −1/2 for γ = 2, negative for 1 < γ ≤ 2.
double symbol_at_minus_one(double gamma) {
  const double p = gamma + 1.0;
  return 4.0 * (1.0 - std::pow(2.0, 1.0 + p)) * boost::math::zeta(-p);
}

// The linear test problem's recursion M x_n + s_d R (a^{(2−2α)} * x)_n + (h²/6) K (a^{(2)} * x)_n
// = data has the symbol M + s_d A_{2−2α}(ξ) R + (h²/6) A_2(ξ) K; at ξ = −1 both A are ≤ 0 for
// 2α < 1 (kernel orders above one), and a root crosses the unit circle there when that matrix
// stops being positive definite (docs/theory/baselines.md §5).
StabilityBound pi_bound(const InitialValueProblem& problem) {
  if (problem.model.dimension() > kMaxStabilityDimension) return unchecked_bound(problem);
  const LinearTestProblem test = linear_test_problem(problem);
  const double beta = problem.model.damping_order();
  const bool damped = !problem.model.is_undamped();
  const double a_damping = damped ? symbol_at_minus_one(2.0 - beta) : 0.0;
  const double a_load = symbol_at_minus_one(2.0);  // −1/2
  const double gamma_factor = boost::math::tgamma(4.0 - beta);
  auto stable = [&](double h) {
    const Eigen::MatrixXd symbol =
        test.mass + (std::pow(h, 2.0 - beta) / gamma_factor * a_damping) * test.damping +
        (h * h / 6.0 * a_load) * test.stiffness;
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> pencil(symbol, test.mass,
                                                                           Eigen::EigenvaluesOnly);
    return pencil.eigenvalues().minCoeff() > 0.0;
  };
  const double h_star = largest_stable_step(stable, problem.step_size());
  // Sharp where measured (tests/schemes/scheme_suite_test.cpp (g): 2α = 0.5 and 1.5 grow by
  // 1e50 and 1e77 at 1.03 h*); for 2α = 1 the trapezoidal damping symbol vanishes at ξ = −1 but
  // not near it, and damping moves the crossing: there the bound is only sufficient (no growth
  // measured at 1.03 h* with λ_max(M⁻¹R) = 75).
  const bool sharp = test.exact && (beta != 1.0 || !damped);
  return step_bound(
      problem, h_star, sharp,
      "M + s A_(2-2alpha)(-1) R + (h^2/6) A_2(-1) K > 0 (s = h^(2-2alpha)/Gamma(4-2alpha), "
      "A_(2-2alpha)(-1) = " +
          format_number(a_damping) + ", A_2(-1) = -1/2, K = Hess U(x0))");
}

}  // namespace

const SchemeInfo kPiTrapezoid{
    .name = "pi-trapezoid",
    .summary =
        "product-integration trapezoidal rule on the Volterra form of the Caputo problem "
        "(Garrappa's MT_FDE_PI2_IM; baseline); direct or FFT-blocked (Hairer-Lubich-Schlichte) "
        "history",
    .reference = "Garrappa, Mathematics 6(2) 16, 2018 (FDE codes, MT_FDE_PI2_IM)",
    .order_rule = "2",
    .stages = 1,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = false,
    .fast_history = true,  // FFT-blocked sums (OnlineConvolution): O(log² N) per step
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = false,
    .no_state_force = "this baseline's product-integration step treats only f(t)",
    .applies_to = "Caputo (Riemann-Liouville with initial data where the two coincide)",
    .stability_rule =
        "M + s A_(2-2alpha)(-1) R + (h^2/6) A_2(-1) K > 0 at the highest frequency (A < 0 for "
        "2alpha < 1 and for K: h^2 lambda_max(M^-1 K) < 12 without damping)",
    .declared_order = [](const MechanicalModel&) { return 2; },
    .applicability =
        [](const InitialValueProblem& problem) {
          const MechanicalModel& model = problem.model;
          const double beta = model.damping_order();
          if (model.convention == Convention::kCaputo || model.is_undamped() ||
              beta == std::floor(beta)) {
            return std::string();
          }
          const bool x0_zero = (problem.x0.array() == 0.0).all();
          const bool v0_zero = (problem.v0.array() == 0.0).all();
          if (x0_zero && (beta < 1.0 || v0_zero)) return std::string();
          return std::string(
              "model.convention = \"riemann-liouville\" with nonzero initial data: pi-trapezoid "
              "solves the Caputo problem (the two coincide only for x0 = 0, and v0 = 0 when "
              "2alpha > 1); use convention = \"caputo\"");
        },
    .stability = pi_bound,
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<PiTrapezoidStepper>(problem, options);
    },
};

}  // namespace fracvi::internal
