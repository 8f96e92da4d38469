// Problem set-ups shared by the integrator tests (tests/integrate) and the method-parameterised
// suite (tests/schemes/scheme_suite_test.cpp): one builder per problem, so that a test of one
// scheme and the suite's test of every scheme run the same problem. Each builder names its users.
// All systems are d = 2 with SPD, non-diagonal, mutually non-commuting M and R.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstddef>
#include <memory>

#include "fracvi/model/autodiff_potential.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/model/potential.hpp"
#include "linear_oscillator_reference.hpp"
#include "power_law_solution.hpp"
#include "test_potentials.hpp"

namespace fracvi::test {

// ---------------------------------------------------------------------------------------------
// Coupled pendula (invariance_test, allocation_test; the suite's mirror, failure, allocation,
// invariance and stability cases).

/// M of the coupled pendula.
// Garrappa's multi-term example (the issue-17 problem): y'' + 0.5 D^{3/2}y + y = 0 (Caputo),
// y(0) = 1, y'(0) = 0 on [0, 20]; exact y(20) = kCaputoOscillatorExact (published, checked
// against the Laplace inversion in published_numbers_test).
inline constexpr double kCaputoOscillatorExact = -0.061964539893443569;
inline InitialValueProblem caputo_oscillator(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.5);
  p.model.alpha = 0.75;
  p.model.convention = Convention::kCaputo;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 20.0;
  p.steps = steps;
  return p;
}

inline Eigen::MatrixXd pendula_mass() {
  return Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
}
/// R of the coupled pendula, λ_max(M⁻¹R) = 0.75.
inline Eigen::MatrixXd pendula_damping() {
  return Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
}

/// The coupled pendula (pendulum_pair()), forced with f = (0.3 sin 2t, −0.2 cos t), Caputo,
/// x0 = (1.2, −0.4), v0 = (0.5, 0.8), on [0, t_end] (invariance_test; the suite).
inline InitialValueProblem forced_pendula(double alpha, std::size_t steps, double t_end = 4.0) {
  InitialValueProblem p;
  p.model.mass = pendula_mass();
  p.model.damping = pendula_damping();
  p.model.alpha = alpha;
  p.model.convention = Convention::kCaputo;
  p.model.potential = pendulum_pair();
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = -0.2 * std::cos(t);
  };
  p.x0 = Eigen::VectorXd{{1.2, -0.4}};
  p.v0 = Eigen::VectorXd{{0.5, 0.8}};
  p.t_end = t_end;
  p.steps = steps;
  return p;
}

/// Theorem 4.3: the problem in z for x = Λz, i.e. ΛᵀMΛ, ΛᵀRΛ, U∘Λ, forcing Λᵀf and data Λ⁻¹x0,
/// Λ⁻¹v0 (invariance_test; the suite). transform_damping = false keeps R untransformed: the
/// negative control.
inline InitialValueProblem transformed_problem(const InitialValueProblem& x,
                                               const Eigen::MatrixXd& lambda,
                                               bool transform_damping = true) {
  InitialValueProblem z = x;
  const Eigen::MatrixXd lt = lambda.transpose();
  z.model.mass = lt * x.model.mass.to_dense() * lambda;
  if (transform_damping) z.model.damping = lt * x.model.damping.to_dense() * lambda;
  z.model.potential = std::make_shared<const TransformedPotential>(x.model.potential, lambda);
  const Forcing fx = x.model.forcing;
  z.model.forcing = [fx, lt](double t, Eigen::Ref<Eigen::VectorXd> out) {
    Eigen::VectorXd f(lt.cols());
    fx(t, f);
    out = lt * f;
  };
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(lambda);
  z.x0 = lu.solve(x.x0);
  z.v0 = lu.solve(x.v0);
  return z;
}

// ---------------------------------------------------------------------------------------------
// The energy-balance problem (energy_balance_test; the suite's balance cases).

/// U = ½xᵀKx − bᵀx (quadratic, time-independent), forcing f = cos(1.3 t) (0.5, −0.2), damping
/// damping_scale · R with λ_max(M⁻¹R) = 0.31, on [0, 5]. Riemann–Liouville with 2α > 1 and
/// x0 ≠ 0 is ill-posed: the RL problem starts from x0 = 0.
inline InitialValueProblem balance_problem(double alpha, Convention convention, std::size_t steps,
                                           double damping_scale = 1.0) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{2.0, 0.5}, {0.5, 1.0}};
  p.model.damping = damping_scale * Eigen::MatrixXd{{0.4, 0.1}, {0.1, 0.3}};
  p.model.alpha = alpha;
  p.model.convention = convention;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd{{3.0, -1.0}, {-1.0, 2.0}},
                                               Eigen::VectorXd{{0.2, 0.1}});
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.5 * std::cos(1.3 * t);
    f(1) = -0.2 * std::cos(1.3 * t);
  };
  p.x0 =
      convention == Convention::kCaputo ? Eigen::VectorXd{{1.0, -0.5}} : Eigen::VectorXd::Zero(2);
  p.v0 = Eigen::VectorXd{{0.2, 0.7}};
  p.t_end = 5.0;
  p.steps = steps;
  return p;
}

// ---------------------------------------------------------------------------------------------
// The forced viscous oscillator, 2α = 1, exact by the matrix exponential (linear_test; the
// suite's damped and undamped oscillator cases).

/// M x'' + R x' + K x = f̂ cos(ωt), x0, v0 ≠ 0, on [0, 5].
struct ViscousOscillator {
  Eigen::MatrixXd M{{2.0, 0.5}, {0.5, 1.0}};
  Eigen::MatrixXd R{{0.4, 0.1}, {0.1, 0.3}};
  Eigen::MatrixXd K{{3.0, -1.0}, {-1.0, 2.0}};
  Eigen::VectorXd fhat{{0.5, -0.2}};
  double omega = 1.3;
  Eigen::VectorXd x0{{1.0, -0.5}};
  Eigen::VectorXd v0{{0.2, 0.7}};
  double t_end = 5.0;

  /// The problem with N = steps (R = 0 when !damped).
  [[nodiscard]] InitialValueProblem problem(std::size_t steps, bool damped = true) const {
    InitialValueProblem p;
    p.model.mass = M;
    p.model.damping = damped ? R : Eigen::MatrixXd::Zero(2, 2);
    p.model.alpha = 0.5;
    p.model.potential = make_quadratic_potential(K);
    const Eigen::VectorXd f = fhat;
    const double w = omega;
    p.model.forcing = [f, w](double t, Eigen::Ref<Eigen::VectorXd> out) {
      out = std::cos(w * t) * f;
    };
    p.x0 = x0;
    p.v0 = v0;
    p.t0 = 0.0;
    p.t_end = t_end;
    p.steps = steps;
    return p;
  }
};

// ---------------------------------------------------------------------------------------------
// Genuinely fractional damping against independent references (fractional_convergence_test; the
// suite's power-law and Caputo-data cases).

/// The reference tests' M, R and K.
inline Eigen::MatrixXd reference_mass() {
  return Eigen::MatrixXd{{2.0, 0.3}, {0.3, 1.0}};
}
inline Eigen::MatrixXd reference_damping() {
  return Eigen::MatrixXd{{0.4, 0.1}, {0.1, 0.2}};
}
inline Eigen::MatrixXd reference_stiffness() {
  return Eigen::MatrixXd{{5.0, -1.0}, {-1.0, 3.0}};
}

/// The manufactured solution x = c t^p, c = (1, −0.5), of the reference system with damping order
/// β = 2α and cubic spring ε (power_law_solution.hpp).
inline PowerLawSolution power_law(double beta, double cubic, double p) {
  PowerLawSolution s;
  s.mass = reference_mass();
  s.damping = reference_damping();
  s.stiffness = reference_stiffness();
  s.beta = beta;
  s.cubic = cubic;
  s.p = p;
  s.c = Eigen::Vector2d(1.0, -0.5);
  return s;
}

/// The initial value problem of `s` on [0, t_end]: zero data, s's forcing, U quadratic (ε = 0) or
/// the cubic spring.
inline InitialValueProblem power_law_problem(const PowerLawSolution& s, std::size_t steps,
                                             Convention convention, double t_end) {
  InitialValueProblem problem;
  problem.model.mass = s.mass;
  problem.model.damping = s.damping;
  problem.model.alpha = 0.5 * s.beta;
  problem.model.convention = convention;
  if (s.cubic == 0.0) {
    problem.model.potential = make_quadratic_potential(s.stiffness);
  } else {
    problem.model.potential = std::make_shared<const CubicSpringPotential>(s.stiffness, s.cubic);
  }
  problem.model.forcing = [s](double t, Eigen::Ref<Eigen::VectorXd> out) { out = s.forcing(t); };
  problem.x0 = Eigen::VectorXd::Zero(2);
  problem.v0 = Eigen::VectorXd::Zero(2);
  problem.t0 = 0.0;
  problem.t_end = t_end;
  problem.steps = steps;
  return problem;
}

/// The unforced linear fractional oscillator of the reference system with nonzero data
/// x0 = (1, −0.5), v0 = (0.3, 0.8) (linear_oscillator_reference.hpp).
inline LinearOscillator fractional_oscillator(double beta, Convention convention) {
  LinearOscillator ref;
  ref.mass = reference_mass();
  ref.damping = reference_damping();
  ref.stiffness = reference_stiffness();
  ref.beta = beta;
  ref.x0 = Eigen::Vector2d(1.0, -0.5);
  ref.v0 = Eigen::Vector2d(0.3, 0.8);
  ref.convention = convention == Convention::kCaputo ? ReferenceConvention::kCaputo
                                                     : ReferenceConvention::kRiemannLiouville;
  return ref;
}

/// The initial value problem of `ref` (its M, R, K, β and data; no forcing) on [0, t_end].
inline InitialValueProblem oscillator_problem(const LinearOscillator& ref, Convention convention,
                                              std::size_t steps, double t_end) {
  InitialValueProblem problem;
  problem.model.mass = ref.mass;
  problem.model.damping = ref.damping;
  problem.model.alpha = 0.5 * ref.beta;
  problem.model.convention = convention;
  problem.model.potential = make_quadratic_potential(ref.stiffness);
  problem.x0 = ref.x0;
  problem.v0 = ref.v0;
  problem.t_end = t_end;
  problem.steps = steps;
  return problem;
}

/// The damped 2-D oscillator of the RKCQ paper's published numbers: q'' + 0.25 q' + 0.5 q = 0,
/// q(0) = (0.8, −0.5), q'(0) = (0.4, 0), on [0, 30] (tests/schemes/published_numbers_test.cpp).
inline InitialValueProblem published_oscillator_2d(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(2, 2);
  p.model.damping = 0.25 * Eigen::MatrixXd::Identity(2, 2);
  p.model.alpha = 0.5;
  p.model.potential = make_quadratic_potential(0.5 * Eigen::MatrixXd::Identity(2, 2));
  p.x0 = Eigen::Vector2d(0.8, -0.5);
  p.v0 = Eigen::Vector2d(0.4, 0.0);
  p.t_end = 30.0;
  p.steps = steps;
  return p;
}

// ---------------------------------------------------------------------------------------------
// A forced fractional Duffing oscillator, d = 1 (fast_trajectory_test, online_convolution_test):
// x'' + 0.4 D^{2α}x + x + x³ = 0.3 cos(1.1 t), Caputo, x0 = 1.5, v0 = −0.2, t ∈ [0, 200]; it
// amplifies round-off (a one-ulp change of x0 moves it by 4e-12 … 2e-11 relative over 2·10^4
// steps).

struct DuffingScalar {
  template <class T>
  T operator()(const Eigen::Matrix<T, 1, 1>& x, T) const {
    return T(0.5) * x(0) * x(0) + T(0.25) * x(0) * x(0) * x(0) * x(0);
  }
};

inline InitialValueProblem forced_duffing(double alpha, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Constant(1, 1, 1.0);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.4);
  p.model.alpha = alpha;
  p.model.convention = Convention::kCaputo;
  p.model.potential = make_autodiff_potential<1>(DuffingScalar{}, 1, {.time_dependent = false});
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) { f(0) = 0.3 * std::cos(1.1 * t); };
  p.x0 = Eigen::VectorXd::Constant(1, 1.5);
  p.v0 = Eigen::VectorXd::Constant(1, -0.2);
  p.t_end = 200.0;
  p.steps = steps;
  return p;
}

/// The periodic β-FPUT chain U = Σ_i ½ r_i² + ¼ r_i⁴ over the d bonds of a ring (r_i = x_{i+1} −
/// x_i, x_d ≡ x_0): its Hessian couples x_0 and x_{d−1}, bandwidth d − 1 (the sparse
/// factorisations' case).
inline std::shared_ptr<const Potential> periodic_fput_chain(Eigen::Index d) {
  ChainOptions chain;
  chain.dimension = d;
  chain.quartic = 1.0;
  chain.boundary = ChainBoundary::kPeriodic;
  return make_chain_potential(chain);
}

// ---------------------------------------------------------------------------------------------
// A fixed chain of d masses (uneven, or all 1; M and R = 0.4 I stored diagonal), linear or with
// quartic springs (β-FPUT), damping of order 2α (Caputo by default) with x_0 and v_0 both non-zero
// (x̃ subtracts both), and a load f(t) on every mass (step_by_rows_test; fvi_lobatto_test's one
// pass over the rows).
inline InitialValueProblem forced_chain(Eigen::Index d, bool unit_mass, std::size_t steps,
                                        double onsite = 0.5, double t_end = 3.0,
                                        Convention convention = Convention::kCaputo,
                                        double alpha = 0.75, double quartic = 0.0) {
  InitialValueProblem p;
  Eigen::VectorXd masses(d);
  for (Eigen::Index i = 0; i < d; ++i)
    masses[i] = unit_mass ? 1.0 : 1.0 + 0.3 * std::sin(0.7 * static_cast<double>(i));
  p.model.mass = ModelMatrix::diagonal(masses);
  p.model.damping = ModelMatrix::identity(d, 0.4);
  p.model.alpha = alpha;
  p.model.convention = convention;
  ChainOptions c;
  c.dimension = d;
  c.stiffness = 2.0;
  c.onsite = onsite;
  c.cubic = 0.0;
  c.quartic = quartic;
  p.model.potential = make_chain_potential(c);
  p.model.forcing = [d](double t, Eigen::Ref<Eigen::VectorXd> f) {
    for (Eigen::Index i = 0; i < d; ++i) f[i] = 0.1 * std::cos(t + 0.01 * static_cast<double>(i));
  };
  p.x0.resize(d);
  p.v0.resize(d);
  for (Eigen::Index i = 0; i < d; ++i) {
    const double xi = M_PI * static_cast<double>(i + 1) / static_cast<double>(d + 1);
    p.x0[i] = 0.4 * std::sin(3.0 * xi);
    p.v0[i] = 0.3 * std::cos(5.0 * xi);
  }
  p.t_end = t_end;
  p.steps = steps;
  return p;
}

}  // namespace fracvi::test
