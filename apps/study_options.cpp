// The options `fracvi convergence` and `fracvi compare` share (cli.hpp, StudyOptions).
#include <string>

#include "cli.hpp"

namespace fracvi::cli {

void add_study_options(CLI::App* app, StudyOptions& opt, const std::string& output,
                       const std::string& plots) {
  app->add_option("problem", opt.file, "problem file (TOML)")->required();
  app->add_option("--steps", opt.steps, "step counts, increasing, comma-separated")
      ->required()
      ->delimiter(',');
  app->add_option("--reference", opt.reference,
                  "exact x(t): d formulas in t, comma-separated (overrides [reference])")
      ->delimiter(',');
  app->add_option("--reference-steps", opt.reference_steps,
                  "reference by a fine run with this many steps, a larger multiple of every "
                  "--steps entry (used instead of the file's [reference] when given)");
  app->add_option("--set", opt.overrides, "override a problem value (repeatable)");
  app->add_option("--out", opt.out,
                  "output directory (default ./fracvi-out/<problem name>" + output + ")");
  app->add_flag("--no-plot", opt.no_plot, "do not draw " + plots);
}

}  // namespace fracvi::cli
