#include "fracvi/io/run.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <utility>

#include "fracvi/expression/expression.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/output.hpp"

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
    const auto method = parse_method(spec.scheme);
    if (!method) {  // the reader accepts only registered names; a spec built in code may not
      throw ProblemFileError(source + ": method.scheme = \"" + spec.scheme +
                             "\" is not a known scheme (available: " + scheme_names() + ")");
    }
    run.method = *method;
    if (spec.checkpoint_every > 0 && !run.method.info().checkpoints) {
      throw ProblemFileError(
          source + ": output.checkpoint_every = " + std::to_string(spec.checkpoint_every) +
          " is not available for method.scheme = \"" + spec.scheme +
          "\": its stepper cannot save its state yet (schemes with "
          "checkpoints: " +
          scheme_names_with(&SchemeInfo::checkpoints) + "); set it to 0");
    }
    validate(run.problem);
    validate(run.options);
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

ConvergenceStudy convergence_study(const ProblemSpec& spec, std::span<const std::size_t> steps,
                                   std::span<const std::string> exact,
                                   std::size_t reference_steps) {
  const RunWithSteps run = [&spec](std::size_t n) {
    ProblemSpec copy = spec;
    copy.steps = static_cast<long long>(n);
    PreparedRun prepared = prepare_run(std::move(copy));
    prepared.options.mirror = false;  // the study measures x only; the mirror run doubles the cost
    prepared.options.error_estimate = ErrorEstimateKind::kNone;  // it measures the true error
    prepared.options.save_every = 1;  // errors are taken on the whole grid, whatever output.every
    return integrate(prepared.problem, prepared.method, prepared.options);
  };
  return convergence_study(spec.name, spec.end - spec.start, run, steps, exact, reference_steps);
}

}  // namespace fracvi
