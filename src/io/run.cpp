#include "fracvi/io/run.hpp"

#include <string>
#include <utility>

#include "fracvi/expression/expression.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/lagrangian/problem.hpp"

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

}  // namespace fracvi
