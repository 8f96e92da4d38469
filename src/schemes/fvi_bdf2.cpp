// fvi-bdf2: the restricted discrete variational principle with Δ^α_± the BDF2 convolution
// quadrature (δ(ζ) = (1 − ζ) + (1 − ζ)²/2), whose composition is the BDF2 CQ of order 2α, and the
// midpoint discrete Lagrangian (second order). The memory acts on x − P, P = x_0 + (t − t_0) v_0,
// and P's damping force enters in closed form (cell averages): docs/theory/fvi_bdf2.md derives the
// equations, the mirror equation, the start and the stability bound.
#include "cq_midpoint_stepper.hpp"
#include "fracvi/schemes/stability.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

const SchemeInfo kFviBdf2{
    .name = "fvi-bdf2",
    .summary = "FVI with BDF2 convolution-quadrature memory and the midpoint discrete Lagrangian",
    .reference = "Hariz, Jimenez & Ober-Bloebaum, J Nonlinear Sci 2025 (arXiv 2403.18362)",
    .order_rule = "2",
    .stages = 1,
    .variational = true,
    .variational_quadrature = CqScheme::kBdf2,
    .has_mirror = true,
    .exact_balance = true,
    .fast_history = true,
    .history_budget_ceiling = kMeasuredHistoryCeiling,  // κ measured for it (history_budget.hpp)
    .momentum_quadrature = CqScheme::kBdf2,
    .forcing_moments = true,  // method.load = "moments": the cell average of f
    .checkpoints = true,
    .explicit_euler_start = true,  // CqMidpointStepper's negative control
    .no_state_force = "",
    .applies_to = "every model",
    .stability_rule = "lambda_max(M^-1 R) h^(2-2alpha) 4^(2alpha-1) < 1",
    .declared_order = [](const MechanicalModel&) { return 2; },
    .applicability = [](const InitialValueProblem&) { return std::string(); },
    .stability =
        [](const InitialValueProblem& problem) {
          return explicit_memory_bound(problem, {CqScheme::kBdf2, problem.model.damping_order()});
        },
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<CqMidpointStepper>(problem, options, CqScheme::kBdf2,
                                                 MemoryStart::kTaylorSplit);
    },
};

}  // namespace fracvi::internal
