// `fracvi action`: the action `ActFunc` of a problem's Lagrangian along given curves x(t), y(t),
// and its first variation along η (restricted, `ConsVariations`: δx = δy = η), with the pairing
// ∫(E_x + E_y)·η dt of Theorem `ConsFraEL` on request.
#include <cmath>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/lagrangian/action.hpp"

namespace fracvi::cli {

namespace {

// η must vanish at both ends for the restricted variation of `ConsVariations` (to round-off of a
// formula such as sin(pi*t/2) at t = 2).
constexpr double kEndTolerance = 1e-12;

void require_vanishing_ends(const std::string& flag, const Curve& eta, double a, double b) {
  Eigen::MatrixXd v(eta.dimension, 1);
  for (double t : {a, b}) {
    eta.evaluate(t, 0, v);
    const double worst = v.cwiseAbs().maxCoeff();
    if (!(worst <= kEndTolerance)) {
      throw UsageError(flag + " is " + format_number(worst) + " at t = " + format_number(t) +
                       ": a variation must vanish at time.start and time.end (|value| <= " +
                       format_number(kEndTolerance) + ")");
    }
  }
}

}  // namespace

Command add_action_command(CLI::App& parent) {
  struct Options {
    std::string file;
    std::vector<std::string> overrides;
    std::string x, y, eta, eta_y;
    bool pairing = false;
    double tolerance = ContinuousResidualOptions{}.tolerance;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "action",
      "Print the action A = integral of L(x, y, xdot, ydot, D^alpha_- x, D^alpha_+ y) dt (ActFunc) "
      "of the problem's Lagrangian along the curves x(t), y(t) on [time.start, time.end] "
      "('action A'); with --eta, its first variation dA = d/de A[x + e eta, y + e eta] at e = 0 "
      "(restricted: delta x = delta y = eta, exact derivative in e, 'variation dA'); with "
      "--eta-y, the unrestricted variation delta y = eta_y instead; with --pairing, also "
      "integral of (E_x . eta + E_y . eta_y) dt with E_x, E_y the FracEL residuals ('pairing P'), "
      "equal to dA for restricted variations (Theorem ConsFraEL; slow: one residual per "
      "quadrature node). 17 significant digits. Exit status: 0 success, 2 bad input.");
  app->add_option("problem", opt->file, "problem file (TOML): [model] and [time] are used")
      ->required();
  app->add_option("--set", opt->overrides, "override a problem value (repeatable)");
  app->add_option("--x", opt->x, "x(t): d formulas in t, comma-separated")->required();
  app->add_option("--y", opt->y, "y(t): d formulas in t, e.g. the mirror x(a + b - t)")->required();
  app->add_option("--eta", opt->eta,
                  "the variation eta(t) (d formulas in t), zero at time.start and time.end");
  app->add_option("--eta-y", opt->eta_y,
                  "a different variation of y (unrestricted variation; default: eta)");
  app->add_flag("--pairing", opt->pairing,
                "also print the pairing of the FracEL residuals with the variation (needs eta "
                "and its derivative to vanish at both ends)");
  app->add_option("--tolerance", opt->tolerance,
                  "relative tolerance of the tanh-sinh quadratures (default 1e-12)");

  auto run = [opt]() {
    const LagrangianProblem problem = load_lagrangian_problem(opt->file, opt->overrides);
    const ProblemSpec& spec = problem.spec;
    const Curve x = parse_curve("--x", opt->x, spec.dim);
    const Curve y = parse_curve("--y", opt->y, spec.dim);
    if (!(opt->tolerance > 0.0 && opt->tolerance < 1.0)) {
      throw UsageError("--tolerance = " + format_number(opt->tolerance) + " must be in (0, 1)");
    }
    if (opt->eta.empty() && (!opt->eta_y.empty() || opt->pairing)) {
      throw UsageError(std::string(opt->pairing ? "--pairing" : "--eta-y") +
                       " needs --eta (the variation of x)");
    }
    ContinuousResidualOptions options;
    options.tolerance = opt->tolerance;
    const double a = spec.start, b = spec.end;
    std::string out;
    try {
      out += "action " +
             format_number(action(*problem.lagrangian, spec.alpha, x, y, a, b, options)) + '\n';
      if (!opt->eta.empty()) {
        const Curve eta = parse_curve("--eta", opt->eta, spec.dim);
        const Curve eta_y = opt->eta_y.empty() ? eta : parse_curve("--eta-y", opt->eta_y, spec.dim);
        require_vanishing_ends("--eta", eta, a, b);
        require_vanishing_ends("--eta-y", eta_y, a, b);
        out += "variation " +
               format_number(action_variation(*problem.lagrangian, spec.alpha, x, y, eta, eta_y, a,
                                              b, options)) +
               '\n';
        if (opt->pairing) {
          out += "pairing " +
                 format_number(fracel_pairing(*problem.lagrangian, spec.alpha, x, y, eta, eta_y, a,
                                              b, options)) +
                 '\n';
        }
      }
    } catch (const std::domain_error& e) {
      throw UsageError(e.what());
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    std::cout << out;
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
