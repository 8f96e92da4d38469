// `fracvi derivative`: the continuous Riemann–Liouville derivative D^α_± f(t) (paper `RL`) of a
// formula f(t), by tanh–sinh quadrature with f' taken exactly from the expression engine.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/fractional/riemann_liouville.hpp"

namespace fracvi::cli {

namespace {

Expression parse_function_of_t(const std::string& flag, const std::string& text) {
  try {
    return Expression::parse(text, {"t"});
  } catch (const ExpressionError& e) {
    throw UsageError(flag + " = \"" + text + "\": " + e.reason() + " at column " +
                     std::to_string(e.column() + 1) + " (a formula in t)");
  }
}

}  // namespace

Command add_derivative_command(CLI::App& parent) {
  struct Options {
    double alpha = 0.5;
    std::string side = "left";
    std::string f;
    std::string exact;
    double a = 0.0, b = 1.0;
    std::vector<double> t;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "derivative",
      "Print t and the Riemann-Liouville derivative D^ALPHA f(t) on [A, B] (the paper's RL: left "
      "= D_-, memory of the past from A; right = D_+, memory of the future from B, with "
      "D^1_+ f = -f'), 17 significant digits per line. Accurate to about 1e-12 relative for "
      "smooth f, also with an integrable singularity at the terminal (log t at A = 0); a "
      "non-integrable one (1/t) is refused.");
  app->add_option("--alpha", opt->alpha, "order ALPHA in [0, 1]")->required();
  app->add_option("--side", opt->side, "left (D_-) or right (D_+)")->default_val("left");
  app->add_option("--f", opt->f, "the function: a formula in t, e.g. \"sin(t)\"")->required();
  app->add_option("--a", opt->a, "left end A of the interval")->required();
  app->add_option("--b", opt->b, "right end B of the interval (> A)")->required();
  app->add_option("--t", opt->t, "evaluation points in [A, B], comma-separated")
      ->required()
      ->delimiter(',');
  app->add_option("--exact", opt->exact,
                  "optional closed form of the derivative (a formula in t): adds the columns "
                  "exact value and difference");

  auto run = [opt]() {
    const auto& o = *opt;
    if (!(o.alpha >= 0.0 && o.alpha <= 1.0)) {
      throw UsageError("--alpha = " + format_number(o.alpha) +
                       " is outside [0, 1] (the Lagrangian order alpha of the paper)");
    }
    Side side;
    if (o.side == "left") {
      side = Side::kLeft;
    } else if (o.side == "right") {
      side = Side::kRight;
    } else {
      throw UsageError("--side = '" + o.side + "' must be left or right");
    }
    if (!std::isfinite(o.a) || !std::isfinite(o.b) || !(o.a < o.b)) {
      throw UsageError("--a = " + format_number(o.a) + ", --b = " + format_number(o.b) +
                       ": need finite A < B");
    }
    for (double t : o.t) {
      if (!(t >= o.a && t <= o.b)) {
        throw UsageError("--t = " + format_number(t) + " is outside [A, B] = [" +
                         format_number(o.a) + ", " + format_number(o.b) + "]");
      }
    }
    const Expression f = parse_function_of_t("--f", o.f);
    const Expression df = f.derivative(0);
    std::optional<Expression> exact;
    if (!o.exact.empty()) exact = parse_function_of_t("--exact", o.exact);

    const auto f_fn = [&f](double t) { return f({t}); };
    const auto df_fn = [&df](double t) { return df({t}); };
    std::string out;
    for (double t : o.t) {
      double value = 0.0;
      try {
        value = rl_derivative(o.alpha, side, f_fn, df_fn, o.a, o.b, t);
      } catch (const std::exception& e) {
        // Boost's tanh-sinh quadrature refuses an integrand that is infinite inside [a, b]
        // (evaluation_error, e.g. f = 1/t on [0, 1]): the function is not one this command can
        // differentiate, so it is bad input, said in one line.
        throw UsageError("--f = \"" + o.f + "\": the quadrature of D^alpha f(" + format_number(t) +
                         ") failed (" + e.what() + ")");
      }
      out += format_number(t) + ' ' + format_number(value);
      if (exact) {
        const double e = (*exact)({t});
        out += ' ' + format_number(e) + ' ' + format_number(value - e);
      }
      out += '\n';
    }
    std::cout << out;
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
