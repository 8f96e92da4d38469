// fvi-gl: the paper's scheme `DiscEqs` — midpoint discrete Lagrangian, Δ^α_± by Grünwald–Letnikov
// weights (δ(ζ) = 1 − ζ), the damping memory at known states; Lemma 5.3 for α = 1/2.
// Start and energy account: docs/theory/start_step.md. The stepper is the DiscEqs family's
// (cq_midpoint_stepper.hpp) with the paper's start.
#include "cq_midpoint_stepper.hpp"
#include "fracvi/schemes/stability.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

const SchemeInfo kFviGl{
    .name = "fvi-gl",
    .summary = "the paper's FVI (DiscEqs): midpoint discrete Lagrangian, Grunwald-Letnikov memory",
    .reference = "Jimenez & Ober-Bloebaum, DiscEqs and Lemma 5.3",
    .order_rule = "1 (2 when R = 0)",
    .stages = 1,
    .variational = true,
    .variational_quadrature = CqScheme::kGrunwaldLetnikov,
    .has_mirror = true,
    .exact_balance = true,
    .fast_history = true,
    .history_budget_ceiling = kMeasuredHistoryCeiling,  // κ measured for it (history_budget.hpp)
    .momentum_quadrature = CqScheme::kGrunwaldLetnikov,
    .forcing_moments = true,  // method.load = "moments": the cell average of f
    .checkpoints = true,
    .explicit_euler_start = true,  // CqMidpointStepper's negative control
    .no_state_force = "",
    .applies_to = "every model",
    .stability_rule = "lambda_max(M^-1 R) (h/2)^(2-2alpha) < 1",
    // The GL sum (for α = 1/2 the backward difference of Lemma 5.3) is first order; without
    // damping the scheme is the conservative midpoint variational integrator, order 2.
    .declared_order = [](const MechanicalModel& model) { return model.is_undamped() ? 2 : 1; },
    .applicability = [](const InitialValueProblem&) { return std::string(); },
    .stability =
        [](const InitialValueProblem& problem) {
          return explicit_memory_bound(
              problem, {CqScheme::kGrunwaldLetnikov, problem.model.damping_order()});
        },
    .make_stepper = [](const InitialValueProblem& problem,
                       const IntegratorOptions& options) -> std::unique_ptr<Stepper> {
      return std::make_unique<CqMidpointStepper>(problem, options, CqScheme::kGrunwaldLetnikov,
                                                 MemoryStart::kPaperStart);
    },
};

}  // namespace fracvi::internal
