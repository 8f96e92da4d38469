// `fracvi weights`: the first N convolution-quadrature weights of s^β.
#include <iostream>
#include <memory>
#include <string>

#include "cli.hpp"
#include "fracvi/fractional/weights.hpp"

namespace fracvi::cli {

Command add_weights_command(CLI::App& parent) {
  struct Options {
    double order = 0.0;
    std::string scheme = "gl";
    long long count = 0;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "weights",
      "Print the first N weights w_n of a convolution quadrature of s^BETA, one per line with 17 "
      "significant digits: the Taylor coefficients of delta(z)^BETA. With --scheme gl these are "
      "the Grunwald-Letnikov weights (the paper's alpha_n for BETA = alpha; the damping sum of "
      "DiscEqs uses BETA = 2*alpha).");
  app->add_option("--order", opt->order, "order BETA (any finite real; the paper uses [0, 2])")
      ->required();
  app->add_option("--scheme", opt->scheme,
                  "generating function: gl (1-z), bdf2 ((1-z)+(1-z)^2/2), trapezoidal "
                  "(2(1-z)/(1+z))")
      ->default_val("gl");
  app->add_option("-n,--count", opt->count, "number of weights N (> 0)")->required();

  auto run = [opt]() {
    const auto scheme = parse_cq_scheme(opt->scheme);
    if (!scheme) {
      throw UsageError("--scheme = '" + opt->scheme +
                       "' is not a known scheme (choose gl, bdf2 or trapezoidal)");
    }
    if (!std::isfinite(opt->order)) {
      throw UsageError("--order = " + format_number(opt->order) + " must be a finite number");
    }
    if (opt->count <= 0) {
      throw UsageError("-n = " + std::to_string(opt->count) + " must be a positive integer");
    }
    if (opt->count > 100'000'000) {
      throw UsageError("-n = " + std::to_string(opt->count) +
                       " is more than 100000000 weights; ask for fewer");
    }
    const auto w = cq_weights(*scheme, opt->order, static_cast<std::size_t>(opt->count));
    std::string out;
    out.reserve(w.size() * 25);
    for (double wk : w) (out += format_number(wk)) += '\n';
    std::cout << out;
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
