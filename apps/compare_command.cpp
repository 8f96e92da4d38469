// `fracvi compare`: every scheme at every step count on one problem, against one reference
// (fracvi/analysis/comparison.hpp): compare.csv, energy.csv and the work–precision, error-vs-N and
// energy-tracking plots.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/analysis/comparison.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"
#include "fracvi/schemes/registry.hpp"
#include "plot.hpp"

namespace fracvi::cli {

namespace {

// A CSV field: quoted (with doubled quotes) when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string short_number(double v) {
  if (std::isnan(v)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3e", v);
  return buf;
}

void print_row(const ComparisonRow& r, std::size_t done, std::size_t total) {
  std::printf("%-17s %9zu  %10s  %10s  %10s  %10s  %10s  %9.4f  %s\n", r.scheme.c_str(), r.steps,
              short_number(r.max_error).c_str(), short_number(r.final_error).c_str(),
              short_number(r.energy_error).c_str(), short_number(r.dissipated_error).c_str(),
              short_number(r.balance_error).c_str(),
              std::isnan(r.wall_seconds) ? 0.0 : r.wall_seconds, r.status.c_str());
  std::fflush(stdout);
  if (isatty(fileno(stderr)) && done < total) {
    std::fprintf(stderr, "[%zu/%zu]\r", done, total);
    std::fflush(stderr);
  }
}

std::string compare_csv(const Comparison& c) {
  std::string csv =
      "scheme,steps,h,declared_order,status,final_error,max_error,energy_error,dissipated_error,"
      "balance_error,wall_seconds,newton_iterations,message\n";
  for (const auto& r : c.rows) {
    csv += r.scheme + ',' + std::to_string(r.steps) + ',' + format_number(r.h) + ',' +
           std::to_string(r.declared_order) + ',' + r.status + ',' + format_number(r.final_error) +
           ',' + format_number(r.max_error) + ',' + format_number(r.energy_error) + ',' +
           format_number(r.dissipated_error) + ',' + format_number(r.balance_error) + ',' +
           format_number(r.wall_seconds) + ',' + std::to_string(r.newton_iterations) + ',' +
           csv_field(r.message) + '\n';
  }
  return csv;
}

std::string energy_csv(const EnergyTrack& e) {
  std::string csv = "t,reference_energy,reference_dissipated";
  for (const auto& s : e.schemes) csv += ",energy:" + s + ",dissipated:" + s;
  csv += '\n';
  for (Eigen::Index k = 0; k < e.t.size(); ++k) {
    csv += format_number(e.t[k]) + ',' + format_number(e.reference_energy[k]) + ',' +
           format_number(e.reference_dissipated[k]);
    for (std::size_t j = 0; j < e.schemes.size(); ++j) {
      csv += ',' + format_number(e.energy[j][k]) + ',' + format_number(e.dissipated[j][k]);
    }
    csv += '\n';
  }
  return csv;
}

}  // namespace

Command add_compare_command(CLI::App& parent) {
  struct Options : StudyOptions {
    std::vector<std::string> schemes;
    std::string reference_scheme;
    std::size_t energy_steps = 0;
    int repeat = 1;
    bool quiet = false;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* app = parent.add_subcommand(
      "compare",
      "Run every scheme at every step count on one problem and measure each run against one "
      "reference: error at the end and over the grid, energy and dissipated-energy error, balance "
      "error, wall time, Newton iterations. Writes compare.csv, energy.csv and the plots "
      "work_precision.png, error_vs_steps.png, energy_tracking.png. The reference is the exact "
      "solution ([reference] position, or --reference) or a fine run (--reference-steps).");
  add_study_options(app, *opt, "-compare",
                    "work_precision.png, error_vs_steps.png, energy_tracking.png");
  app->add_option("--schemes", opt->schemes,
                  "schemes, comma-separated (default: every registered scheme; one that does not "
                  "apply is a row with the reason)")
      ->delimiter(',');
  app->add_option("--reference-scheme", opt->reference_scheme,
                  "the fine run's scheme (default: dopri5 at tolerances 1e-13 where it applies, "
                  "else fvi-lobatto4, fvi-lobatto3, fvi-midpoint)");
  app->add_option("--energy-steps", opt->energy_steps,
                  "the N of the energy-tracking figure (one of --steps; default: the middle one)");
  app->add_option("--repeat", opt->repeat, "runs per scheme and N; the best wall time is kept")
      ->check(CLI::PositiveNumber);
  app->add_flag("-q,--quiet", opt->quiet, "print only the summary lines, not the table");

  auto run = [opt]() {
    ProblemSpec spec;
    try {
      spec = load_problem(opt->file, opt->overrides);
    } catch (const ProblemFileError& e) {
      throw UsageError(e.what());
    }
    ComparisonSetup setup;
    setup.schemes = opt->schemes;
    if (setup.schemes.empty()) {
      for (const SchemeInfo* info : registered_schemes()) setup.schemes.emplace_back(info->name);
    }
    setup.steps = opt->steps;
    setup.exact = opt->reference;
    setup.reference_steps = opt->reference_steps;
    setup.reference_scheme = opt->reference_scheme;
    setup.options.repeat = opt->repeat;
    setup.options.energy_steps =
        opt->energy_steps != 0 ? opt->energy_steps : opt->steps[opt->steps.size() / 2];
    if (!opt->quiet) {
      setup.options.on_row = print_row;
      std::printf(
          "fracvi compare: %s  (alpha = %g, damping order %g, %zu schemes x %zu step "
          "counts)\n",
          spec.name.c_str(), spec.alpha, 2 * spec.alpha, setup.schemes.size(), setup.steps.size());
      std::printf("%-17s %9s  %10s  %10s  %10s  %10s  %10s  %9s  %s\n", "scheme", "N", "max error",
                  "final err", "energy err", "dissip err", "balance", "wall [s]", "status");
    }
    const std::filesystem::path fallback = default_output(spec.name, "-compare", opt->overrides);
    const std::filesystem::path dir = prepare_output(opt->out, fallback);
    Comparison result;
    try {
      result = compare_schemes(spec, setup);
    } catch (const std::invalid_argument& e) {
      abandon_output(dir);
      throw UsageError(e.what());
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "fracvi compare: %s\n", e.what());
      abandon_output(dir);
      return kExitNumericalFailure;
    }
    std::size_t failed = 0, refused = 0;
    for (const auto& r : result.rows) {
      failed += r.status != "success" && r.status != "not applicable";
      refused += r.status == "not applicable";
    }
    std::printf("reference: %s%s%s\n", result.reference.c_str(),
                result.energy_reference.empty() ? "" : "; energy reference: ",
                result.energy_reference.c_str());
    std::printf(
        "%zu runs: %zu succeeded, %zu failed, %zu not applicable (reasons in "
        "compare.csv)\n",
        result.rows.size(), result.rows.size() - failed - refused, failed, refused);
    std::vector<std::string> names, adaptive;
    for (const auto& r : result.rows) {
      if (!names.empty() && names.back() == r.scheme) continue;
      names.push_back(r.scheme);
      if (const SchemeInfo* info = find_scheme(r.scheme); info != nullptr && info->adaptive) {
        adaptive.push_back(r.scheme);  // the plots draw no order slope for these
      }
    }
    const nlohmann::json meta{{"problem", to_json(spec)},
                              {"reference", result.reference},
                              {"energy_reference", result.energy_reference},
                              {"energy_steps", result.energy.steps},
                              {"schemes", names},
                              {"adaptive", adaptive},
                              {"steps", setup.steps}};
    if (!write_results("compare", dir, [&] {
          write_file_atomically(dir / "compare.csv", compare_csv(result));
          if (result.energy.steps != 0) {
            write_file_atomically(dir / "energy.csv", energy_csv(result.energy));
          }
          write_file_atomically(dir / "compare.json", meta.dump(2) + "\n");
        })) {
      return kExitNumericalFailure;
    }
    std::string note;
    if (!opt->no_plot) note = draw_compare_plots(dir);
    std::printf("wrote %s/compare.csv%s\n", dir.string().c_str(),
                note.empty() ? (opt->no_plot ? ""
                                             : ", work_precision.png, error_vs_steps.png, "
                                               "energy_tracking.png")
                             : ("; plots " + note).c_str());
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
