#include "fracvi/io/run.hpp"

#include <algorithm>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/analysis/error_estimate.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {

PreparedRun prepare_run(ProblemSpec spec) {
  const std::string source = spec.source;
  if (spec.position.size() == 0) {
    throw ProblemFileError(source +
                           ": [initial] position missing: fracvi run solves an initial value "
                           "problem; this file poses a boundary value problem ([boundary]), "
                           "solve it with fracvi bvp");
  }
  try {
    PreparedRun run;
    run.problem = spec.lagrangian.empty() ? make_initial_value_problem(spec)
                                          : make_lagrangian_initial_value_problem(spec);
    run.options = make_integrator_options(spec);
    validate(run.problem);
    validate(run.options);
    const bool automatic = spec.scheme == kAutoScheme;
    // "auto" with checkpoints takes a scheme that can write them.
    const auto can_checkpoint = [&spec](const SchemeInfo& info) {
      return spec.checkpoint_every == 0 || info.checkpoints;
    };
    const auto method =
        automatic ? std::optional<Method>(choose_scheme(run.problem, run.options, can_checkpoint))
                  : parse_method(spec.scheme);
    if (!method) {  // the reader accepts only registered names; a spec built in code may not
      throw ProblemFileError(source + ": method.scheme = \"" + spec.scheme +
                             "\" is not a known scheme (available: " + scheme_names() + ")");
    }
    run.method = *method;
    if (spec.checkpoint_every > 0 && !run.method.info().checkpoints) {
      throw ProblemFileError(
          source + ": output.checkpoint_every = " + std::to_string(spec.checkpoint_every) +
          " is not available for method.scheme = \"" + std::string(run.method.name()) + "\"" +
          (automatic ? " (chosen by \"auto\")" : "") +
          ": its stepper cannot save its state yet (schemes with checkpoints: " +
          scheme_names_with(&SchemeInfo::checkpoints) + "); set it to 0");
    }
    check_applicable(run.problem, run.method, run.options);
    check_storage(run.problem, run.options);
    run.spec = std::move(spec);
    return run;
  } catch (const ProblemFileError&) {
    throw;
  } catch (const ExpressionError& e) {
    throw ProblemFileError(source + ": " + e.reason() + " at column " +
                           std::to_string(e.column() + 1));
  } catch (const ValidationError& e) {
    throw ProblemFileError(source + ": " + e.what());
  }
}

Solution solve_prepared(const PreparedRun& prepared, std::unique_ptr<Integrator> integrator,
                        const std::function<void(std::size_t)>& on_step) {
  if (prepared.options.tolerance > 0.0) {
    // method.tolerance: N doubled from time.steps until the error estimate meets it.
    integrator.reset();
    return integrate_to_tolerance(prepared.problem, prepared.method, prepared.options);
  }
  if (!integrator) {
    integrator = std::make_unique<Integrator>(prepared.problem, prepared.method, prepared.options);
  }
  // Accuracy, not consistency: Richardson from companion runs (analysis/error_estimate.hpp), on a
  // second thread alongside the run where that applies (the same runs, the same estimate).
  std::optional<ConcurrentErrorEstimate> concurrent;
  if (ConcurrentErrorEstimate::applies(prepared.problem, prepared.options)) {
    concurrent.emplace(prepared.problem, prepared.method, prepared.options,
                       stored_steps(prepared.problem.steps, prepared.options.save_every));
  }
  if (on_step) {
    integrator->run([&on_step](const StepView& s) { on_step(s.k); });
  } else {
    integrator->run();
  }
  Solution solution = integrator->take_solution();
  if (concurrent) {
    concurrent->finish(solution);
  } else {
    estimate_error(prepared.problem, prepared.method, prepared.options, solution);
  }
  return solution;
}

PreparedBvp prepare_bvp(ProblemSpec spec) {
  const std::string source = spec.source;
  try {
    PreparedBvp bvp;
    bvp.problem = make_boundary_value_problem(spec);
    bvp.options = make_bvp_options(spec);
    validate(bvp.options);
    bvp.spec = std::move(spec);
    return bvp;
  } catch (const ProblemFileError&) {
    throw;
  } catch (const ExpressionError& e) {
    throw ProblemFileError(source + ": " + e.reason() + " at column " +
                           std::to_string(e.column() + 1));
  } catch (const ValidationError& e) {
    throw ProblemFileError(source + ": " + e.what());
  }
}

namespace {

// One run of a study (convergence, comparison): spec with `scheme` and `steps`, every step stored
// (errors are taken on the whole grid, whatever output.every), no mirror run, no error estimate,
// no tolerance doubling — a study measures the true error of x and the cost of the integration
// alone.
PreparedRun prepare_study_run(const ProblemSpec& spec, const std::string& scheme,
                              std::size_t steps) {
  ProblemSpec copy = spec;
  copy.scheme = scheme;
  copy.steps = static_cast<long long>(steps);
  copy.tolerance = 0.0;
  PreparedRun prepared = prepare_run(std::move(copy));
  prepared.options.mirror = false;
  prepared.options.error_estimate = ErrorEstimateKind::kNone;
  prepared.options.save_every = 1;
  prepared.options.output_times.clear();  // whole runs on the grid: no stop at a terminal event
  prepared.options.events.clear();
  return prepared;
}

}  // namespace

ConvergenceStudy convergence_study(const ProblemSpec& spec, std::span<const std::size_t> steps,
                                   std::span<const std::string> exact,
                                   std::size_t reference_steps) {
  const RunWithSteps run = [&spec](std::size_t n) {
    const PreparedRun prepared = prepare_study_run(spec, spec.scheme, n);
    return integrate(prepared.problem, prepared.method, prepared.options);
  };
  return convergence_study(spec.name, spec.end - spec.start, run, steps, exact, reference_steps);
}

namespace {

// One run of the compared problem (prepare_study_run); a refusal of the scheme becomes
// NotApplicable.
Solution run_for_comparison(const ProblemSpec& spec, const std::string& scheme, std::size_t steps,
                            const std::function<void(IntegratorOptions&)>& adjust = {}) {
  try {
    PreparedRun prepared = prepare_study_run(spec, scheme, steps);
    if (adjust) adjust(prepared.options);
    return integrate(prepared.problem, prepared.method, prepared.options);
  } catch (const ProblemFileError& e) {
    throw NotApplicable(e.what());
  } catch (const ValidationError& e) {
    throw NotApplicable(e.what());
  }
}

// The reference from exact formulas x(t): positions, and E(t) = ½ ẋᵀMẋ + U(x, t) with ẋ the
// exact t-derivative of the formulas (no finite differences).
ComparisonReference exact_reference(const ProblemSpec& spec,
                                    std::span<const std::string> formulas) {
  if (static_cast<Eigen::Index>(formulas.size()) != spec.dim) {
    throw std::invalid_argument("the reference has " + std::to_string(formulas.size()) +
                                " formulas, the problem's dimension is " +
                                std::to_string(spec.dim));
  }
  std::vector<Expression> x;
  try {
    x = parse_reference(formulas);
  } catch (const ExpressionError& e) {
    throw std::invalid_argument("reference: " + e.reason() + " at column " +
                                std::to_string(e.column() + 1));
  }
  std::vector<Expression> v;
  v.reserve(x.size());
  for (const Expression& xi : x) v.push_back(xi.derivative("t"));
  // The model (M, U) of the problem, whatever scheme: prepare_run with the problem's own scheme
  // validates it; a problem that cannot run at all has no comparison either.
  const auto model = std::make_shared<const MechanicalModel>(prepare_run(spec).problem.model);
  ComparisonReference reference;
  reference.description = "exact solution";
  reference.position = [x](std::size_t, std::size_t, double t, Eigen::Ref<Eigen::VectorXd> out) {
    for (std::size_t i = 0; i < x.size(); ++i) out[static_cast<Eigen::Index>(i)] = x[i]({t});
  };
  reference.energy = [x, v, model](std::size_t, std::size_t, double t) {
    const auto d = static_cast<Eigen::Index>(x.size());
    Eigen::VectorXd q(d), qdot(d), mq(d);
    for (Eigen::Index i = 0; i < d; ++i) {
      q[i] = x[static_cast<std::size_t>(i)]({t});
      qdot[i] = v[static_cast<std::size_t>(i)]({t});
    }
    model->mass.multiply(qdot, mq);
    return 0.5 * qdot.dot(mq) + (model->potential ? model->potential->value(q, t) : 0.0);
  };
  reference.energy_description = "E = ½ẋᵀMẋ + U(x, t) of the exact solution";
  return reference;
}

// The default scheme of the fine reference run (run.hpp, ComparisonSetup::reference_scheme).
std::string default_reference_scheme(const ProblemSpec& spec, std::size_t steps) {
  for (const char* name : {"dopri5", "fvi-lobatto4", "fvi-lobatto3", "fvi-midpoint"}) {
    ProblemSpec copy = spec;
    copy.scheme = name;
    copy.steps = static_cast<long long>(steps);
    try {
      prepare_run(std::move(copy));
      return name;
    } catch (const ProblemFileError&) {
      // does not apply: try the next one
    }
  }
  return spec.scheme;
}

}  // namespace

Comparison compare_schemes(const ProblemSpec& spec, const ComparisonSetup& setup) {
  for (const std::string& scheme : setup.schemes) {
    if (!parse_method(scheme)) {
      throw std::invalid_argument("--schemes: \"" + scheme +
                                  "\" is not a known scheme (available: " + scheme_names() + ")");
    }
  }
  const std::vector<std::string>& exact = setup.exact.empty() ? spec.reference : setup.exact;
  ComparisonReference reference;
  if (!exact.empty() && setup.reference_steps == 0) {
    reference = exact_reference(spec, exact);
  } else {
    const std::size_t nf = setup.reference_steps;
    check_reference_steps(nf, setup.steps);
    const std::string scheme = setup.reference_scheme.empty() ? default_reference_scheme(spec, nf)
                                                              : setup.reference_scheme;
    const SchemeInfo* info = find_scheme(scheme);
    const bool adaptive = info != nullptr && info->adaptive;
    Solution fine;
    try {
      fine = run_for_comparison(spec, scheme, nf, [&](IntegratorOptions& o) {
        // The reference's own errors well below the compared ones: tight adaptive tolerances,
        // the fast history's tightest accuracy.
        if (adaptive) o.abs_tolerance = o.rel_tolerance = 1e-13;
        o.history_tolerance = kMinHistoryTolerance;
      });
    } catch (const NotApplicable& e) {
      throw std::invalid_argument(std::string("the reference scheme cannot run: ") + e.what());
    }
    if (!fine.ok()) throw std::runtime_error("the reference run failed: " + fine.message);
    reference =
        fine_run_reference(std::move(fine), scheme + " with " + std::to_string(nf) + " steps" +
                                                (adaptive ? " (tolerances 1e-13)" : ""));
  }
  const RunScheme run = [&spec](const std::string& scheme, std::size_t n) {
    return run_for_comparison(spec, scheme, n);
  };
  return compare_schemes(spec.name, spec.start, spec.end - spec.start, setup.schemes, setup.steps,
                         run, reference, setup.options);
}

}  // namespace fracvi
