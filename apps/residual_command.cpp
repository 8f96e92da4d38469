// `fracvi residual`: the residual of the restricted fractional Euler–Lagrange equations (`FracEL`,
// Theorem 4.2) of a problem's Lagrangian along given curves x(t), y(t).
#include <cmath>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/lagrangian/continuous_residual.hpp"

namespace fracvi::cli {

Command add_residual_command(CLI::App& parent) {
  struct Options {
    std::string file;
    std::vector<std::string> overrides;
    std::string x, y;
    std::vector<double> t;
    double tolerance = ContinuousResidualOptions{}.tolerance;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "residual",
      "Print, for each time T, the residuals of the restricted fractional Euler-Lagrange "
      "equations (FracEL) of the problem's Lagrangian along the curves x(t), y(t) on [time.start, "
      "time.end]: T, then the d components of dL/dx - d/dt dL/dxdot + D^alpha_-(dL/d dy), then "
      "the d components of dL/dy - d/dt dL/dydot + D^alpha_+(dL/d dx), 17 significant digits. "
      "Riemann-Liouville operators; x(time.start) and y(time.end) need not vanish (the endpoint "
      "singularities are split off in closed form where the coupling of dx and dy is affine with "
      "a constant coefficient). Exit status: 0 success, 2 bad input.");
  app->add_option("problem", opt->file, "problem file (TOML): [model] and [time] are used")
      ->required();
  app->add_option("--set", opt->overrides, "override a problem value (repeatable)");
  app->add_option("--x", opt->x, "x(t): d formulas in t, comma-separated, e.g. \"sin(t),t^2\"")
      ->required();
  app->add_option("--y", opt->y, "y(t): d formulas in t, e.g. the mirror x(a + b - t)")->required();
  app->add_option("--t", opt->t, "evaluation times in [time.start, time.end], comma-separated")
      ->required()
      ->delimiter(',');
  app->add_option("--tolerance", opt->tolerance,
                  "relative tolerance of the tanh-sinh quadratures (default 1e-12)");

  auto run = [opt]() {
    const LagrangianProblem problem = load_lagrangian_problem(opt->file, opt->overrides);
    const ProblemSpec& spec = problem.spec;
    const std::shared_ptr<const Lagrangian>& lagrangian = problem.lagrangian;
    const Curve x = parse_curve("--x", opt->x, spec.dim);
    const Curve y = parse_curve("--y", opt->y, spec.dim);
    for (double t : opt->t) {
      if (!(t >= spec.start && t <= spec.end)) {
        throw UsageError("--t = " + format_number(t) + " is outside [time.start, time.end] = [" +
                         format_number(spec.start) + ", " + format_number(spec.end) + "]");
      }
    }
    if (!(opt->tolerance > 0.0 && opt->tolerance < 1.0)) {
      throw UsageError("--tolerance = " + format_number(opt->tolerance) + " must be in (0, 1)");
    }
    ContinuousResidualOptions options;
    options.tolerance = opt->tolerance;
    std::string out;
    for (double t : opt->t) {
      ContinuousElResidual r;
      try {
        r = fractional_el_residual(*lagrangian, spec.alpha, x, y, spec.start, spec.end, t, options);
      } catch (const std::domain_error& e) {
        throw UsageError(e.what());
      }
      out += format_number(t);
      for (Eigen::Index i = 0; i < r.x_equation.size(); ++i)
        out += ' ' + format_number(r.x_equation(i));
      for (Eigen::Index i = 0; i < r.y_equation.size(); ++i)
        out += ' ' + format_number(r.y_equation(i));
      out += '\n';
    }
    std::cout << out;
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
