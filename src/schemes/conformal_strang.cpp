// conformal-strang: the conformal-symplectic Strang splitting of M x'' + R x' + ∇U(x, t) = f(t)
// (2α = 1): the damping flow v ← e^{−M⁻¹R h/2} v solved exactly, around one Störmer–Verlet step
// of the conservative part (McLachlan & Perlmutter 2001; Bhatt, Floyd & Moore 2016;
// docs/theory/baselines.md §3):
//
//   v ← E v,  v ← v − (h/2) M⁻¹(∇U(x_k, t_k) − f(t_k)),  x_{k+1} = x_k + h v,
//   v ← v − (h/2) M⁻¹(∇U(x_{k+1}, t_{k+1}) − f(t_{k+1})),  v ← E v,     E = e^{−M⁻¹R h/2}.
//
// Second order, explicit. It maps the symplectic form to e^{−tr(M⁻¹R) h}× itself (conformal
// symplecticity), so the decay of phase-space volume is exact. Only viscous damping has an exact
// flow of this kind: fractional orders are refused.
// Energy account: each damping half-step removes exactly ½vᵀMv − ½(Ev)ᵀM(Ev) (booked as W); the
// Verlet step's energy error, O(h²), is what remains in the balance.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <memory>

#include "baseline_support.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// e^{−M⁻¹R τ} for symmetric M > 0, R ≥ 0: with RΦ = MΦΛ, ΦᵀMΦ = I, it is Φ e^{−Λτ} ΦᵀM.
Eigen::MatrixXd damping_flow(const Eigen::MatrixXd& mass, const Eigen::MatrixXd& damping,
                             double tau) {
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> modes(damping, mass);
  const Eigen::MatrixXd& phi = modes.eigenvectors();
  return phi * (-tau * modes.eigenvalues().array()).exp().matrix().asDiagonal() * phi.transpose() *
         mass;
}

Eigen::VectorXd diagonal_of(const ModelMatrix& a) {
  return a.is_sparse() ? Eigen::VectorXd(a.sparse().diagonal())
                       : Eigen::VectorXd(a.dense().diagonal());
}

class ConformalStrangStepper final : public Stepper {
 public:
  ConformalStrangStepper(const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        d_(problem.model.dimension()),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        diagnostics_(options.diagnostics),
        mass_(problem.model.mass.symmetric_part()),
        mass_solver_(mass_, mass_, options.linear_solver),
        external_(problem) {
    if (damped_) {
      const ModelMatrix damping = problem.model.damping.symmetric_part();
      if (mass_.is_diagonal() && damping.is_diagonal()) {
        // Chains: the flow is diagonal, e^{−r_i h/(2 m_i)}.
        const Eigen::VectorXd m = diagonal_of(mass_), r = diagonal_of(damping);
        flow_ = ModelMatrix::diagonal((-(0.5 * h_) * (r.array() / m.array())).exp().matrix());
      } else {
        if (d_ > kMaxDenseDimension) {
          throw ValidationError(
              "method.scheme = \"conformal-strang\" needs the dense damping flow e^(-M^-1 R h/2) "
              "for non-diagonal M or R (d = " +
              std::to_string(d_) + " > " + std::to_string(kMaxDenseDimension) + ")");
        }
        flow_ = ModelMatrix(damping_flow(mass_.to_dense(), damping.to_dense(), 0.5 * h_));
      }
    }
    for (Eigen::VectorXd* vec : {&x_, &x_next_, &v_, &p_, &grad_, &accel_, &tmp_}) {
      vec->setZero(d_);
    }
    x_ = problem.x0;
    v_ = problem.v0;
    mass_.multiply(v_, p_);
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return LinearSolver::kDense; }
  void visit_state(StateArchive& archive) override {
    visit_step_index(archive, d_, problem_.steps, k_);
    archive.dense("conformal_strang.x", x_);
    archive.dense("conformal_strang.v", v_);
    archive.dense("conformal_strang.p", p_);
    archive.dense("conformal_strang.acceleration", accel_);  // kept from step to step (FSAL)
    archive.number("conformal_strang.work", work_);
    archive.number("conformal_strang.supplied", supplied_);
    external_.visit_state(archive);
  }

 private:
  // accel = M⁻¹(f(t) − ∇U(x, t)).
  void acceleration(const Eigen::VectorXd& x, double t) {
    grad_.setZero();
    if (problem_.model.potential) problem_.model.potential->gradient(x, t, grad_);
    if (problem_.model.forcing) {
      problem_.model.forcing(t, tmp_);
      grad_ -= tmp_;
    }
    grad_ = -grad_;
    mass_solver_.inverse(grad_, accel_);
  }
  // v ← E v; returns the kinetic energy it removed.
  double damp() {
    if (!damped_) return 0.0;
    mass_.multiply(v_, tmp_);
    const double before = 0.5 * v_.dot(tmp_);
    flow_.multiply(v_, tmp_);
    v_.swap(tmp_);
    if (!diagnostics_) return 0.0;
    mass_.multiply(v_, tmp_);
    return before - 0.5 * v_.dot(tmp_);
  }

  Status advance() override {
    const std::size_t k = k_;
    const double t = problem_.time(static_cast<double>(k));
    const double t_next = problem_.time(static_cast<double>(k + 1));
    double dissipated = damp();
    if (k == 0) acceleration(x_, t);  // afterwards kept from the previous step (FSAL)
    v_ += (0.5 * h_) * accel_;
    x_next_ = x_ + h_ * v_;
    if (!x_next_.allFinite()) return fail(Status::kNonFinite, "non-finite position");
    acceleration(x_next_, t_next);
    v_ += (0.5 * h_) * accel_;
    dissipated += damp();
    if (!v_.allFinite()) return fail(Status::kNonFinite, "non-finite velocity");
    if (diagnostics_) {
      work_ += dissipated;
      const double supplied = external_.step(k, x_, x_next_);
      work_ -= supplied;
      supplied_ += supplied;
    }
    x_.swap(x_next_);
    mass_.multiply(v_, p_);
    set_iterations(0);
    ++k_;
    return Status::kSuccess;
  }

  const InitialValueProblem& problem_;
  Eigen::Index d_;
  double h_;
  bool damped_, diagnostics_;
  ModelMatrix mass_, flow_;
  MassSolver mass_solver_;
  ExternalWork external_;
  std::size_t k_ = 0;
  Eigen::VectorXd x_, x_next_, v_, p_, grad_, accel_, tmp_;
  double work_ = 0.0, supplied_ = 0.0;
};

// The one-step matrix of the linear test problem, S = D V D on (x, v), D = diag(I, E) and V the
// Verlet step of M x'' + K x = 0 (A = M⁻¹K): stable while its spectral radius is ≤ 1.
bool strang_stable(const LinearTestProblem& test, double h) {
  const Eigen::Index d = test.mass.rows();
  const Eigen::LLT<Eigen::MatrixXd> llt(test.mass);
  const Eigen::MatrixXd a = llt.solve(test.stiffness);
  const Eigen::MatrixXd id = Eigen::MatrixXd::Identity(d, d);
  const Eigen::MatrixXd b = id - 0.5 * h * h * a;
  Eigen::MatrixXd verlet(2 * d, 2 * d);
  verlet << b, h * id, -0.5 * h * a * (id + b), b;
  Eigen::MatrixXd flow = Eigen::MatrixXd::Identity(2 * d, 2 * d);
  flow.bottomRightCorner(d, d) = damping_flow(test.mass, test.damping, 0.5 * h);
  const Eigen::MatrixXd step = flow * verlet * flow;
  // Inside the bound the undamped modes sit on the unit circle (|λ| = 1 to round-off).
  return step.eigenvalues().cwiseAbs().maxCoeff() <= 1.0 + 1e-9;
}

StabilityBound strang_bound(const InitialValueProblem& problem) {
  if (problem.model.dimension() > kMaxStabilityDimension) return unchecked_bound(problem);
  const LinearTestProblem test = linear_test_problem(problem);
  const std::string what = "spectral radius of the Strang step of the linear test problem <= 1";
  if (test.mass.rows() <= kMaxCharacteristicDimension) {
    const double h_star =
        largest_stable_step([&](double h) { return strang_stable(test, h); }, problem.step_size());
    return step_bound(problem, h_star, test.exact, what + " (K = Hess U(x0))");
  }
  // Large d: the Verlet bound h < 2/ω_max of the undamped modes, which the damping half-steps do
  // not move for a single mode (docs/theory/baselines.md §3); estimated for non-commuting M⁻¹R.
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> modes(test.stiffness, test.mass,
                                                                        Eigen::EigenvaluesOnly);
  const double omega = std::sqrt(std::max(0.0, modes.eigenvalues().maxCoeff()));
  const double h_star = omega > 0.0 ? 2.0 / omega : std::numeric_limits<double>::infinity();
  return step_bound(problem, h_star, false, "h omega_max < 2 (Verlet; estimated for large d)");
}

}  // namespace

const SchemeInfo kConformalStrang{
    .name = "conformal-strang",
    .summary =
        "conformal-symplectic Strang splitting: exact damping half-steps around Stoermer-Verlet "
        "(baseline)",
    .reference = "McLachlan & Perlmutter 2001; Bhatt, Floyd & Moore 2016",
    .order_rule = "2",
    .stages = 1,
    .variational = false,
    .variational_quadrature = std::nullopt,
    .has_mirror = false,
    .exact_balance = false,
    .fast_history = false,
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = false,
    .checkpoints = true,
    .no_state_force =
        "its splitting solves the damping flow exactly and has no sub-step for a "
        "velocity-dependent force",
    .applies_to = "2alpha = 1 (or R = 0)",
    .stability_rule = "Verlet's h omega_max < 2 (with damping: spectral radius of the step <= 1)",
    .declared_order = [](const MechanicalModel&) { return 2; },
    .applicability =
        [](const InitialValueProblem& problem) {
          if (problem.model.damping_order() == 1.0 || problem.model.is_undamped()) {
            return std::string();
          }
          return "model.alpha = " + format_number(problem.model.alpha) +
                 " (2alpha = " + format_number(problem.model.damping_order()) +
                 ") is not 1/2: the exact damping flow e^(-M^-1 R t) exists only for viscous "
                 "damping (2alpha = 1)";
        },
    .stability = strang_bound,
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<ConformalStrangStepper>(problem, options);
    },
};

}  // namespace fracvi::internal
