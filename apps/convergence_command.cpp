// `fracvi convergence`: observed order of the scheme on a problem, against an exact solution or a
// much finer run.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/analysis/convergence.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"
#include "fracvi/schemes/registry.hpp"
#include "plot.hpp"

namespace fracvi::cli {

Command add_convergence_command(CLI::App& parent) {
  auto opt = std::make_shared<StudyOptions>();
  CLI::App* app = parent.add_subcommand(
      "convergence",
      "Run a problem with several step counts and print h | max error over the grid | observed "
      "order, plus the least-squares order; write convergence.csv and a log-log "
      "convergence.png. The reference is the exact solution ([reference] position in the file, "
      "or --reference) or, without one, a run with --reference-steps steps.");
  add_study_options(app, *opt, "-convergence", "convergence.png");

  auto run = [opt]() {
    ProblemSpec spec;
    try {
      spec = prepare_run(load_problem(opt->file, opt->overrides)).spec;
    } catch (const ProblemFileError& e) {
      throw UsageError(e.what());
    }
    std::vector<std::string> exact = opt->reference.empty() ? spec.reference : opt->reference;
    if (!opt->reference.empty() && static_cast<Eigen::Index>(exact.size()) != spec.dim) {
      throw UsageError("--reference has " + std::to_string(exact.size()) +
                       " formulas, the problem's dimension is " + std::to_string(spec.dim));
    }
    if (opt->reference_steps > 0 && opt->reference.empty()) exact.clear();
    // The output directory before the study (which may run for long), but bad input found by
    // the study itself (--steps, a step count beyond the stability bound) leaves no directory.
    const std::filesystem::path fallback =
        default_output(spec.name, "-convergence", opt->overrides);
    const std::filesystem::path dir = prepare_output(opt->out, fallback);
    const auto refuse = [&](const std::string& what) {
      abandon_output(dir);
      throw UsageError(what);
    };
    ConvergenceStudy study;
    try {
      study = convergence_study(spec, opt->steps, exact, opt->reference_steps);
    } catch (const ExpressionError& e) {
      refuse("--reference: " + e.reason() + " at column " + std::to_string(e.column() + 1));
    } catch (const std::invalid_argument& e) {
      refuse(e.what());
    }

    std::printf("fracvi convergence: %s  (alpha = %g, scheme %s, declared order %d)\n",
                spec.name.c_str(), spec.alpha, spec.scheme.c_str(), study.declared_order);
    std::printf("reference: %s\n", study.reference.c_str());
    std::printf("%10s  %12s  %12s  %14s  %9s\n", "N", "h", "max error", "observed order",
                "wall [s]");
    std::string csv = "steps,h,error,observed_order,wall_seconds,status\n";
    bool all_ok = true;
    for (const auto& r : study.rows) {
      std::printf(
          "%10zu  %12.5e  %12.5e  %14s  %9.3f%s\n", r.steps, r.h, r.error,
          std::isnan(r.observed_order) ? "-" : format_number(r.observed_order).substr(0, 6).c_str(),
          r.wall_seconds, r.status == "success" ? "" : ("  " + r.status).c_str());
      csv += std::to_string(r.steps) + ',' + format_number(r.h) + ',' + format_number(r.error) +
             ',' + format_number(r.observed_order) + ',' + format_number(r.wall_seconds) + ',' +
             r.status + '\n';
      all_ok = all_ok && r.status == "success";
    }
    std::printf("least-squares order: %.4f (declared %d)\n", study.fitted_order,
                study.declared_order);
    if (const SchemeInfo* info = find_scheme(spec.scheme); info != nullptr && info->adaptive) {
      // The grid only samples an adaptive scheme's dense output: no order in h is expected.
      std::printf(
          "note: %s is adaptive; its error follows method.abs_tolerance and rel_tolerance, not h "
          "(vary those to see its order)\n",
          spec.scheme.c_str());
    }

    const nlohmann::json meta{{"problem", to_json(spec)},
                              {"reference", study.reference},
                              {"declared_order", study.declared_order},
                              {"fitted_order", study.fitted_order},
                              {"method", spec.scheme}};
    if (!write_results("convergence", dir, [&] {
          write_file_atomically(dir / "convergence.csv", csv);
          write_file_atomically(dir / "convergence.json", meta.dump(2) + "\n");
        })) {
      return kExitNumericalFailure;
    }
    std::string note;
    if (!opt->no_plot) note = draw_convergence_plot(dir);
    std::printf(
        "wrote %s/convergence.csv%s\n", dir.string().c_str(),
        note.empty() ? (opt->no_plot ? "" : ", convergence.png") : ("; plot " + note).c_str());
    return all_ok ? kExitSuccess : kExitNumericalFailure;
  };
  return {app, run};
}

}  // namespace fracvi::cli
