// The mechanical model of the paper (Cor. 4.4, `Damping`, generalised to any α and full matrices)
//
//     M x'' + R D^{2α} x + ∇U(x, t) = f(t) + g(x, x', t),   x ∈ R^d,
//
// and the initial value problem posed on it.
//
// Conventions (DESIGN §2):
//  * `alpha` is the paper's Lagrangian order α ∈ [0, 1]; the damping term has order 2α ∈ [0, 2]
//    (damping_order()). α = 1/2 is viscous damping R x'; α = 3/4 is Bagley–Torvik R D^{3/2} x.
//  * Riemann–Liouville vs Caputo: Caputo applies the memory operator to
//        x̃(t) = x(t) − x(0) − [2α > 1] t v(0)          (nothing subtracted when 2α = 0),
//    Riemann–Liouville to x itself. With zero initial data they coincide; for 2α = 1 (viscous
//    damping) they coincide always. Riemann–Liouville with 2α > 1 and x(0) ≠ 0 is ill-posed (the
//    damping force x(0) t^{−2α}/Γ(1−2α) is not integrable) and is rejected by validate().
//  * Forcing f(t) enters as the time-dependent potential −f(t)·x: the scheme evaluates it where it
//    evaluates U (midpoints (x_k + x_{k+1})/2 at t_{k+1/2}), so the discrete equations stay
//    variational. The energy E = ½ vᵀMv + U(x, t) does not contain −f·x; the work of f is booked in
//    the dissipated work instead (solution.hpp).
//  * A non-conservative force g(x, v, t) (state_force.hpp: van der Pol, feedback, friction) has no
//    potential; the variational schemes add it the discrete Lagrange–d'Alembert way
//    (docs/theory/forces.md) and book its discrete work in W_k like that of f. f(t) stays a
//    separate field so that a force in t alone keeps its path (and its published numbers) exactly.
#pragma once

#include "fracvi/core/error.hpp"

#include <Eigen/Dense>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/expression/expression.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/model/state_force.hpp"

namespace fracvi {

/// Meaning of the fractional damping derivative D^{2α} (DESIGN §2).
enum class Convention {
  kRiemannLiouville,  ///< the paper's operator (eq. `RL`); GL sums act on x itself
  kCaputo,            ///< GL sums act on x − x(0) − [2α > 1] t v(0)
};

/// "riemann-liouville" / "caputo" (the names used by the CLI and problem files).
std::optional<Convention> parse_convention(std::string_view name);
std::string_view to_string(Convention convention);

/// f(t) written into out (size d on entry). Must not allocate or throw if the step loop is to stay
/// allocation-free.
using Forcing = std::function<void(double t, Eigen::Ref<Eigen::VectorXd> out)>;

/// The smallest positive α accepted. Below it D^{2α}x differs from x (α = 0) by about 2α·|log t|
/// relative, under 1e-10 on any run, while the memory weights (of size 2α) approach the subnormal
/// range, where the fast history's fit cannot be verified (issue 14: α = 1e-308 looped forever).
inline constexpr double kMinPositiveAlpha = 1e-12;

/// M x'' + R D^{2α} x + ∇U(x, t) = f(t) + g(x, x', t).
struct MechanicalModel {
  /// M, symmetric positive definite, d × d. Dense or sparse (model_matrix.hpp): large systems store
  /// it sparse, e.g. ModelMatrix::identity(d, m).
  ModelMatrix mass;
  /// R, symmetric positive semidefinite, d × d (zero or empty: conservative). Dense or sparse.
  ModelMatrix damping;
  double alpha = 0.5;  ///< Lagrangian order α ∈ {0} ∪ [kMinPositiveAlpha, 1]; damping order 2α
  /// Caputo is the default because it is well posed for all initial data; with zero initial data,
  /// or α = 1/2, the two conventions give identical trajectories.
  Convention convention = Convention::kCaputo;
  std::shared_ptr<const Potential> potential;  ///< U; null means U ≡ 0
  Forcing forcing;                             ///< f; empty means f ≡ 0
  /// The formulas in t that `forcing` evaluates, one per component, when it was made from
  /// formulas (problem files, Python: make_expression_forces); empty otherwise. A scheme that
  /// needs f's form reads them (method.split = "series": its power laws in t − t0); whoever
  /// replaces `forcing` replaces or clears them.
  std::vector<Expression> forcing_formulas;
  /// g(x, v, t), the non-conservative force; null means g ≡ 0. Schemes without a discrete
  /// Lagrange–d'Alembert form for it refuse it before step 1 (SchemeInfo::no_state_force).
  std::shared_ptr<const StateForce> state_force;

  [[nodiscard]] Eigen::Index dimension() const { return mass.rows(); }
  [[nodiscard]] double damping_order() const { return 2.0 * alpha; }
  /// True when R is exactly zero (the scheme is then the conservative midpoint variational
  /// integrator, order 2).
  [[nodiscard]] bool is_undamped() const;
};

/// The initial value problem on the uniform grid t_k = t0 + k h, h = (t_end − t0)/steps.
struct InitialValueProblem {
  MechanicalModel model;
  Eigen::VectorXd x0;  ///< x(t0)
  Eigen::VectorXd v0;  ///< x'(t0)
  double t0 = 0.0;
  double t_end = 1.0;
  std::size_t steps = 100;  ///< N ≥ 1

  [[nodiscard]] double step_size() const { return (t_end - t0) / static_cast<double>(steps); }
  /// t_k = t0 + k h, computed the same way everywhere (the mirror check relies on it).
  [[nodiscard]] double time(double k) const { return t0 + k * step_size(); }
};

/// The round-off level 100·d·ε·scale below which the asymmetry and the negative eigenvalues of a
/// d × d matrix with largest entry `scale` are attributed to rounding (matrices assembled as
/// products, e.g. ΛᵀMΛ, are symmetric only to a few ulps × size). One rule for validate() and the
/// problem-file reader.
double roundoff_tolerance(Eigen::Index dimension, double scale);

/// Checks the model alone (sizes, finiteness, symmetry, definiteness, α range, potential
/// dimension). Throws ValidationError.
void validate(const MechanicalModel& model);

/// Checks the model, the initial data and the grid, including the ill-posed combination
/// Riemann–Liouville + 2α > 1 + x0 ≠ 0. Throws ValidationError.
void validate(const InitialValueProblem& problem);

/// Why Riemann–Liouville damping of order 2α > 1 with x(0) ≠ 0 is refused (one sentence, for the
/// messages of validate() and the problem-file reader). For 1 < 2α < 2 the force of the constant
/// x(0), x(0) t^{−2α}/Γ(1−2α), is not integrable at 0. At 2α = 2 that reason is false
/// (1/Γ(−1) = 0: the pointwise force vanishes); the obstruction is the memory itself, which sums x
/// extended by 0 before t = 0: its second difference kicks the first step with −R x(0)/h², an
/// impulse −R x(0)/h that grows without bound as h → 0 (the discrete x(0)δ'(t)).
std::string riemann_liouville_obstruction(double damping_order);

}  // namespace fracvi
