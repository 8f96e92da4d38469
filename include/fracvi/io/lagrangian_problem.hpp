// Lagrangian problems from problem files (`[model] lagrangian = "…"`, `[boundary]`), for the
// commands `fracvi bvp`, `fracvi residual` and `fracvi run`.
//
// Which general Lagrangians `fracvi run` (an initial value problem) accepts, and how that is
// detected (docs/theory/discrete_euler_lagrange.md §6):
//  1. forward_step_class(): the x-equation of `DiscFracEL` must not involve y, and ∂L/∂ẋ must not
//     depend on x (structural, from the exact symbolic Hessian pattern);
//  2. mechanical_form(): L must be ½ẋᵀMẋ − U(x, t) − (D^α_−x)ᵀR D^α_+y + (terms in y, ẏ, D^α_+y
//     only) with constant M, R — checked symbolically: the second derivatives in ẋ and in
//     (D^α_−x, D^α_+y) are constants, ∂L/∂ẋ depends on ẋ only, ∂L/∂D^α_+y on D^α_−x only, and
//     ∂L/∂x on (x, t) only. Then U(x, t) = L(t, 0, …) − L(t, x, 0, …) and the x-equation is exactly
//     the integrator's `DiscEqs` (the y-part of L does not enter it).
// Lagrangians that pass 1 but not 2 (velocity-dependent masses, memory inside the potential, …)
// would need a general one-step solver and a start value derived for them; `fracvi run` refuses
// them with the reason and points to `fracvi bvp`, which solves every L.
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "fracvi/io/problem_file.hpp"
#include "fracvi/lagrangian/bvp.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {

/// The Lagrangian of a validated spec on [time.start, time.end]: an ExpressionLagrangian for
/// `[model] lagrangian`, the MechanicalLagrangian (`PartLagrangian`) of the mechanical fields
/// otherwise. The Lagrangian uses the paper's Riemann–Liouville operators: a mechanical spec with
/// convention "caputo" and fractional damping (2α ∉ {0, 1}, R ≠ 0) is a different model and is
/// refused (ValidationError).
std::shared_ptr<const Lagrangian> make_lagrangian(const ProblemSpec& spec);

/// The δ of Δ^α_± of `[method] scheme`'s boundary value form (SchemeInfo::variational_quadrature:
/// GL for fvi-gl, BDF2 for fvi-bdf2). ValidationError naming method.scheme, its value and the
/// rule when the scheme is unknown or has no boundary value form.
CqScheme boundary_value_quadrature(const ProblemSpec& spec);

/// The boundary value problem of a spec with `[boundary]` (ValidationError without it), its grid's
/// quadrature that of `[method] scheme` (boundary_value_quadrature). Also refuses a Lagrangian
/// whose Hessian in the velocities (ẋ, ẏ) is singular at the starting iterate (the straight lines
/// between the end points): the discrete equations are then not solvable.
BoundaryValueProblem make_boundary_value_problem(const ProblemSpec& spec);
/// method.newton_max_iterations → max_iterations; the residual tolerance stays at its default.
BvpOptions make_bvp_options(const ProblemSpec& spec);

/// `PartLagrangian` data recovered from an expression Lagrangian (see the file comment), with
/// α = alpha and the Riemann–Liouville convention, or the reason why L is not of that form.
struct MechanicalForm {
  std::optional<MechanicalModel> model;
  std::string reason;
};
MechanicalForm mechanical_form(const std::shared_ptr<const ExpressionLagrangian>& lagrangian,
                               double alpha);

/// The initial value problem of a spec with `[model] lagrangian` and `[initial]`, for the
/// integrator. Throws ValidationError with the reason (and a pointer to `fracvi bvp`) if L is not
/// of mechanical form, and if its velocity Hessian M is singular.
InitialValueProblem make_lagrangian_initial_value_problem(const ProblemSpec& spec);

/// Throws ValidationError if ∂²L/∂ẋ² (and, with include_y, ∂²L/∂ẏ²) is singular relative to
/// its largest eigenvalue at the phase point (t, z); `where` names the point in the message.
void check_velocity_hessian(const Lagrangian& lagrangian, double t,
                            const Eigen::Ref<const Eigen::VectorXd>& z, const std::string& where,
                            bool include_y = true);

/// summary.json of `fracvi bvp`: status, message, scheme, residual norm, floor and history, Newton
/// and GMRES iterations, linear solver, action sum, wall time, the mirror diagnostic max_k |y_k −
/// x_{N−k}|, the end states, and the resolved problem.
nlohmann::json make_bvp_summary(const ProblemSpec& spec, const BvpSolution& solution);

/// Writes trajectory.csv (header `t,x1..xd,y1..yd,residual_x,residual_y`: the max-norms of the
/// x- and y-equation at k, 0 at the end points; every spec.every-th row and the last; 17
/// significant digits), summary.json and problem.toml into `dir` (created if needed), each through
/// a temporary file and a rename.
void write_bvp_output(const std::filesystem::path& dir, const ProblemSpec& spec,
                      const BvpSolution& solution);

}  // namespace fracvi
