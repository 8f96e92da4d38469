// Shared pieces of the fracvi command line: error reporting and number formatting.
#pragma once

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "fracvi/core/status.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/lagrangian/continuous_residual.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"

namespace fracvi::cli {

/// Bad input from the user: reported as one line on stderr, exit status 2, nothing on stdout.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr int kExitSuccess = 0;
inline constexpr int kExitNumericalFailure = 1;
inline constexpr int kExitBadInput = 2;
/// Stopped by SIGINT, SIGTERM or SIGHUP (128 + SIGINT, the shell's convention for Ctrl-C); the
/// files hold everything computed up to the signal, with status `interrupted`.
inline constexpr int kExitInterrupted = 130;

/// 17 significant digits: enough to round-trip every double.
inline std::string format_number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// Row `row` of a row-major matrix as "[a, b, …]" with 10 significant digits (human summaries).
/// Rows longer than 8 entries show the first and last three: "[a, b, c, ..., x, y, z] (100000
/// entries)"; the files have all of them.
inline std::string row_text(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>&
        m,
    Eigen::Index row) {
  constexpr Eigen::Index kShown = 8, kEnds = 3;
  const Eigen::Index n = m.cols();
  std::string s = "[";
  for (Eigen::Index j = 0; j < n; ++j) {
    if (n > kShown && j == kEnds) {
      s += ", ...";
      j = n - kEnds - 1;
      continue;
    }
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%.10g", j ? ", " : "", m(row, j));
    s += buf;
  }
  s += "]";
  if (n > kShown) s += " (" + std::to_string(n) + " entries)";
  return s;
}

/// The output directory, prepared before any work (fracvi::prepare_output_directory) and claimed
/// for this process until it exits (fracvi::OutputLock): a directory that cannot be created or
/// written, or that another fracvi run is using, is bad input (exit 2) naming the option, found
/// before step 1. `given` is the --out argument ("" for the default `fallback`).
std::filesystem::path prepare_output(const std::string& given,
                                     const std::filesystem::path& fallback);

/// Gives up a directory of prepare_output() when the command refuses its input after all (found
/// by the computation itself): the claim is released and the directory removed if prepare_output
/// created it and it is still empty.
void abandon_output(const std::filesystem::path& dir);

/// The default output directory fracvi-out/<name><suffix>, with the --set overrides appended
/// (`-model.alpha=0.6`, characters other than letters, digits and ._=+- as '_'; past 80
/// characters a hash of them instead), so that runs of one file with different overrides, e.g. a
/// sweep from the shell, never share a directory; nothing is appended when the overrides set
/// `name` (the user named the run).
std::filesystem::path default_output(const std::string& name, const std::string& suffix,
                                     const std::vector<std::string>& overrides);

/// Writes a command's results with `write`; an I/O failure after the computation (disk full, the
/// directory removed meanwhile) is one line on stderr naming the directory and the reason, and
/// returns false (the command then exits 1: the results are lost, not the input wrong).
bool write_results(const char* command, const std::filesystem::path& dir,
                   const std::function<void()>& write);

/// --quiet silences a command's summary, not its failure: a run that did not succeed (exit 1)
/// prints one line on stderr, "fracvi <command>: <name>: <status>: <message> (<where>; files in
/// <dir>)" (issue 14).
void report_quiet_failure(const char* command, const std::string& name, Status status,
                          const std::string& message, const std::string& where,
                          const std::filesystem::path& dir);

/// Each command registers itself on the app and returns the function that runs it.
struct Command {
  CLI::App* app;
  std::function<int()> run;
};

Command add_weights_command(CLI::App& parent);
Command add_derivative_command(CLI::App& parent);
Command add_run_command(CLI::App& parent);
Command add_convergence_command(CLI::App& parent);
Command add_compare_command(CLI::App& parent);
Command add_plot_command(CLI::App& parent);
Command add_residual_command(CLI::App& parent);
Command add_bvp_command(CLI::App& parent);
Command add_methods_command(CLI::App& parent);
Command add_action_command(CLI::App& parent);
Command add_sweep_command(CLI::App& parent);

/// A problem file's spec and its Lagrangian (`fracvi residual`, `fracvi action`); UsageError for
/// bad input.
struct LagrangianProblem {
  ProblemSpec spec;
  std::shared_ptr<const Lagrangian> lagrangian;
};
LagrangianProblem load_lagrangian_problem(const std::string& file,
                                          const std::vector<std::string>& overrides);

/// d formulas in t separated by commas outside parentheses; UsageError naming the flag otherwise.
Curve parse_curve(const std::string& flag, const std::string& text, Eigen::Index d);

/// What `fracvi convergence` and `fracvi compare` share: the problem, the step counts, the
/// reference (exact formulas or a fine run), overrides, the output directory and --no-plot.
struct StudyOptions {
  std::string file;
  std::vector<std::size_t> steps;
  std::vector<std::string> reference;
  std::size_t reference_steps = 0;
  std::vector<std::string> overrides;
  std::string out;
  bool no_plot = false;
};
/// Declares the StudyOptions on a study command; `output` names its default directory
/// (./fracvi-out/<name><output>) and `plots` what --no-plot leaves out.
void add_study_options(CLI::App* app, StudyOptions& opt, const std::string& output,
                       const std::string& plots);

}  // namespace fracvi::cli
