// dopri5: Boost.Odeint's adaptive Dormand–Prince 5(4) with step-size control and dense output on
// the first-order system x' = v, M v' = f(t) − R x' − ∇U(x, t) (docs/theory/baselines.md §4):
// what a SciPy user reaches for (solve_ivp's RK45). Only for 2α = 1 or R = 0 (a fractional memory
// is not an ODE). The controller keeps the local error below method.abs_tolerance +
// method.rel_tolerance·|z| per internal step; the grid t_k only samples the dense output (fifth-
// order Hermite-type interpolation of the stages), so the error follows the tolerances, not h.
// Energy account: the damping work ∫ v·Rv dt by R(x_{k+1} − x_k)·½(v_k + v_{k+1}) on the grid and
// ExternalWork: O(h²) on the grid whatever the tolerance (a consistency check).
// A non-conservative force g(x, v, t) is part of the right-hand side (explicit evaluation); its
// work ∫ g·v dt is booked like the damping's, by ½(g_k + g_{k+1})·(x_{k+1} − x_k).
#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "baseline_support.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "mass_solver.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

namespace {

namespace odeint = boost::numeric::odeint;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using State = std::vector<double>;
using Dopri5 = odeint::runge_kutta_dopri5<State>;
using DenseStepper = odeint::result_of::make_dense_output<Dopri5>::type;

class Dopri5Stepper final : public Stepper {
 public:
  Dopri5Stepper(const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        d_(problem.model.dimension()),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        diagnostics_(options.diagnostics),
        mass_(problem.model.mass.symmetric_part()),
        damping_(problem.model.damping.symmetric_part()),
        mass_solver_(mass_, damping_, options.linear_solver),
        dense_(odeint::make_dense_output(options.abs_tolerance, options.rel_tolerance, Dopri5())),
        external_(problem) {
    for (Eigen::VectorXd* vec : {&x_, &v_, &p_, &force_, &tmp_, &dx_, &rdx_, &g_, &g_next_})
      vec->setZero(d_);
    x_ = problem.x0;
    v_ = problem.v0;
    if (problem.model.state_force && diagnostics_)
      problem.model.state_force->value(x_, v_, problem.t0, g_);
    mass_.multiply(v_, p_);
    z_.assign(static_cast<std::size_t>(2 * d_), 0.0);
    pack(z_);
    // Odeint sizes its stage vectors on the first step: one step here, then a restart, so that
    // the step loop does not allocate. A callback that throws now throws again in step 1, where
    // it is reported.
    dense_.initialize(z_, problem.t0, h_);
    try {
      dense_.do_step(std::ref(*this));
    } catch (...) {  // NOLINT(bugprone-empty-catch): reported by the first step
    }
    dense_.initialize(z_, problem.t0, h_);
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return LinearSolver::kDense; }

  // The right-hand side (Odeint's system): z = (x, v), dz = (v, M⁻¹(f − Rv − ∇U)).
  void operator()(const State& z, State& dz, double t) {
    const Eigen::Map<const Eigen::VectorXd> x(z.data(), d_), v(z.data() + d_, d_);
    force_.setZero();
    if (problem_.model.potential) problem_.model.potential->gradient(x, t, force_);
    if (damped_) {
      damping_.multiply(v, tmp_);
      force_ += tmp_;
    }
    if (problem_.model.forcing) {
      problem_.model.forcing(t, tmp_);
      force_ -= tmp_;
    }
    if (problem_.model.state_force) {
      problem_.model.state_force->value(x, v, t, tmp_);
      force_ -= tmp_;
    }
    force_ = -force_;
    Eigen::Map<Eigen::VectorXd>(dz.data(), d_) = v;
    mass_solver_.inverse(force_, Eigen::Map<Eigen::VectorXd>(dz.data() + d_, d_));
  }

 private:
  void pack(State& z) const {
    Eigen::Map<Eigen::VectorXd>(z.data(), d_) = x_;
    Eigen::Map<Eigen::VectorXd>(z.data() + d_, d_) = v_;
  }

  Status advance() override {
    const std::size_t k = k_;
    const double t_next = problem_.time(static_cast<double>(k + 1));
    try {
      // Internal steps until the dense output covers t_{k+1}.
      while (dense_.current_time() < t_next) {
        dense_.do_step(std::ref(*this));
        if (!std::isfinite(dense_.current_time_step())) {
          return fail(Status::kNonFinite, "non-finite step size of the dopri5 controller");
        }
      }
    } catch (const odeint::step_adjustment_error& e) {
      return fail(Status::kNonFinite,
                  "the dopri5 step-size control failed (%s): the solution is not finite or the "
                  "problem is too stiff for method.abs_tolerance/rel_tolerance",
                  e.what());
    }
    dense_.calc_state(t_next, z_);
    const Eigen::Map<const Eigen::VectorXd> x_next(z_.data(), d_), v_next(z_.data() + d_, d_);
    if (!x_next.allFinite()) return fail(Status::kNonFinite, "non-finite position");
    if (!v_next.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");
    if (diagnostics_) {
      dx_ = x_next - x_;
      if (damped_) {
        damping_.multiply(dx_, rdx_);
        work_ += 0.5 * rdx_.dot(v_ + v_next);
      }
      tmp_ = x_next;
      double supplied = external_.step(k, x_, tmp_);
      if (problem_.model.state_force) {
        problem_.model.state_force->value(x_next, v_next, t_next, g_next_);
        supplied += 0.5 * (g_ + g_next_).dot(dx_);
        g_.swap(g_next_);
      }
      work_ -= supplied;
      supplied_ += supplied;
    }
    x_ = x_next;
    v_ = v_next;
    mass_.multiply(v_, p_);
    set_iterations(0);
    ++k_;
    return Status::kSuccess;
  }

  const InitialValueProblem& problem_;
  Eigen::Index d_;
  double h_;
  bool damped_, diagnostics_;
  ModelMatrix mass_, damping_;
  MassSolver mass_solver_;
  DenseStepper dense_;
  ExternalWork external_;
  State z_;
  std::size_t k_ = 0;
  Eigen::VectorXd x_, v_, p_, force_, tmp_, dx_, rdx_;
  Eigen::VectorXd g_, g_next_;  // g(x_k, v_k, t_k) and at k + 1 (energy account)
  double work_ = 0.0, supplied_ = 0.0;
};

}  // namespace

const SchemeInfo kDopri5{
    .name = "dopri5",
    .summary =
        "Boost.Odeint adaptive Dormand-Prince 5(4), dense output at the grid (baseline; like "
        "SciPy's RK45)",
    .reference = "Dormand & Prince 1980; Boost.Odeint runge_kutta_dopri5",
    .order_rule = "5 (adaptive: the error follows the tolerances, not h)",
    .stages = 7,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = false,
    .fast_history = false,
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = false,
    .adaptive = true,
    .no_state_force = "",
    .applies_to = "2alpha = 1 (or R = 0)",
    .stability_rule = "adaptive: the step-size controller keeps it stable (every output h)",
    .declared_order = [](const MechanicalModel&) { return 5; },
    .applicability =
        [](const InitialValueProblem& problem) {
          if (problem.model.damping_order() == 1.0 || problem.model.is_undamped()) {
            return std::string();
          }
          return "model.alpha = " + format_number(problem.model.alpha) +
                 " (2alpha = " + format_number(problem.model.damping_order()) +
                 ") is not 1/2: dopri5 integrates an ODE and a fractional damping memory is not "
                 "one (use it for 2alpha = 1 or R = 0)";
        },
    .stability =
        [](const InitialValueProblem&) {
          return StabilityBound{.stable = true,
                                .largest_step = std::numeric_limits<double>::infinity(),
                                .sharp = true,
                                .rule = "adaptive step: stable for every output step h"};
        },
    .make_stepper = [](const InitialValueProblem& problem, const IntegratorOptions& options)
        -> std::unique_ptr<Stepper> { return std::make_unique<Dopri5Stepper>(problem, options); },
};

}  // namespace fracvi::internal
