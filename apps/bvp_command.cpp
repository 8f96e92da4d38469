// `fracvi bvp`: the variational boundary value problem of the restricted discrete principle
// (`DiscFracEL` for all interior x_k, y_k at once, Newton with the exact structured Jacobian), with
// the Δ^α_± of `[method] scheme` (make_boundary_value_problem; a scheme without a boundary value
// form is bad input, exit status 2).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"

namespace fracvi::cli {

Command add_bvp_command(CLI::App& parent) {
  struct Options {
    std::string file;
    std::string out;
    std::vector<std::string> overrides;
    std::string sum = "extended";
    std::string solver = "auto";
    double tolerance = BvpOptions{}.residual_tolerance;
    bool quiet = false;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "bvp",
      "Solve the variational boundary value problem x(a) = start, x(b) = end, y(a) = end, "
      "y(b) = start of the restricted discrete fractional Euler-Lagrange equations (DiscFracEL) "
      "for the problem's Lagrangian ([model] lagrangian, or the mechanical fields) by Newton's "
      "method, with the fractional differences of [method] scheme (fvi-gl: Grunwald-Letnikov, "
      "fvi-bdf2: BDF2 convolution quadrature), and write trajectory.csv (t, x, y, residuals), "
      "summary.json and problem.toml. "
      "Exit status: 0 converged, 1 numerical failure (best iterate written), 2 bad input.");
  app->add_option("problem", opt->file, "problem file (TOML) with a [boundary] section")
      ->required();
  app->add_option("--out", opt->out, "output directory (default ./fracvi-out/<problem name>)");
  app->add_option("--set", opt->overrides,
                  "override a problem value, e.g. --set boundary.end=[0.5] (repeatable)");
  app->add_option("--sum", opt->sum,
                  "extended (default: the paper's printed DiscFracEL; DiscEqs for the mechanical "
                  "L) or printed (the exact equations of DiscActSum as printed, sum to N-1)");
  app->add_option("--solver", opt->solver,
                  "linear solver: auto, dense (LU of the assembled Jacobian) or krylov (GMRES "
                  "with a banded preconditioner)");
  CLI::Option* tolerance = app->add_option(
      "--tolerance", opt->tolerance,
      "converged when every equation is at most this in absolute value (default: 1e-10, or the "
      "round-off floor of the equations when that is larger, as it is for many steps)");
  app->add_flag("--quiet", opt->quiet, "print nothing but errors");

  auto run = [opt, tolerance]() {
    PreparedBvp prepared;
    try {
      prepared = prepare_bvp(load_problem(opt->file, opt->overrides));
    } catch (const ProblemFileError& e) {
      throw UsageError(e.what());
    }
    const ProblemSpec& spec = prepared.spec;
    BoundaryValueProblem& problem = prepared.problem;
    BvpOptions& options = prepared.options;
    try {
      if (opt->sum == "extended") {
        problem.sum = ActionSum::kExtended;
      } else if (opt->sum == "printed") {
        problem.sum = ActionSum::kPrinted;
      } else {
        throw UsageError("--sum = '" + opt->sum + "' must be extended or printed");
      }
      if (opt->solver == "auto") {
        options.linear_solver = BvpLinearSolver::kAuto;
      } else if (opt->solver == "dense") {
        options.linear_solver = BvpLinearSolver::kDense;
      } else if (opt->solver == "krylov") {
        options.linear_solver = BvpLinearSolver::kKrylov;
      } else {
        throw UsageError("--solver = '" + opt->solver + "' must be auto, dense or krylov");
      }
      if (!(opt->tolerance > 0.0)) {
        throw UsageError("--tolerance = " + format_number(opt->tolerance) + " must be positive");
      }
      options.residual_tolerance = opt->tolerance;
      // A tolerance the user gave is taken as given; the default rises to the round-off floor.
      options.above_round_off = tolerance->count() == 0;
      validate(options);
    } catch (const ValidationError& e) {
      throw UsageError(spec.source + ": " + e.what());
    }
    const std::filesystem::path dir =
        prepare_output(opt->out, default_output(spec.name, "", opt->overrides));
    const BvpSolution solution = solve_bvp(problem, options);
    if (!write_results("bvp", dir, [&] { write_bvp_output(dir, spec, solution); })) {
      return kExitNumericalFailure;
    }
    if (!opt->quiet) {
      const Eigen::Index n = solution.x.rows() - 1;
      std::printf("fracvi bvp: %s  (d = %lld, alpha = %g, N = %lld, %s, %s action sum)\n",
                  spec.name.c_str(), static_cast<long long>(spec.dim), spec.alpha,
                  static_cast<long long>(spec.steps), spec.scheme.c_str(), solution.sum.c_str());
      std::printf("  status            %s%s%s\n",
                  solution.ok() ? "success" : to_string(solution.status).data(),
                  solution.message.empty() ? "" : ": ", solution.message.c_str());
      std::printf("  residual          max |F| = %.3e  (tolerance %.1e, round-off floor ~%.1e)\n",
                  solution.residual_norm, solution.residual_tolerance, solution.residual_floor);
      std::printf("  newton            %d iterations, %zu GMRES iterations, %s\n",
                  solution.newton_iterations, solution.linear_iterations,
                  solution.linear_solver.c_str());
      std::printf("  x(a) -> x(b)      %s -> %s\n", row_text(solution.x, 0).c_str(),
                  row_text(solution.x, n).c_str());
      std::printf("  mirror            max |y_k - x_(N-k)| = %.3e\n",
                  (solution.y - solution.x.colwise().reverse()).cwiseAbs().maxCoeff());
      std::printf("  wall time         %.3f s\n", solution.wall_time_seconds);
      std::printf("  output            %s/{trajectory.csv,summary.json,problem.toml}\n",
                  dir.string().c_str());
    } else if (!solution.ok()) {
      char where[64];
      std::snprintf(where, sizeof where, "best iterate written: max |F| = %.3e",
                    solution.residual_norm);
      report_quiet_failure("bvp", spec.name, solution.status, solution.message, where, dir);
    }
    return solution.ok() ? kExitSuccess : kExitNumericalFailure;
  };
  return {app, run};
}

}  // namespace fracvi::cli
