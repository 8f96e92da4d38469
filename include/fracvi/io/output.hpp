// What a run leaves behind: trajectory.csv, summary.json and problem.toml in one directory.
#pragma once

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/integrate/solution.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

/// U of a validated spec: the built-in chain of [model.chain] (with the [method] threads) or the
/// expression potential of model.potential.
std::shared_ptr<const Potential> make_potential(const ProblemSpec& spec);
/// The initial value problem of a validated spec: the potential (make_potential; the force enters
/// as −f(t)·x), M, R, α, convention, initial data, grid.
InitialValueProblem make_initial_value_problem(const ProblemSpec& spec);
/// The [method] options (Newton, history, linear_solver, threads) and save_every = output.every.
IntegratorOptions make_integrator_options(const ProblemSpec& spec);

/// JSON value of a double; non-finite numbers become null (JSON has no NaN).
nlohmann::json json_number(double v);
/// Row `row` of `m` as a JSON array (non-finite entries null; empty if m has no rows).
nlohmann::json json_row(const RowMatrixXd& m, Eigen::Index row);
/// Appends v with 17 significant digits (enough to round-trip every double).
void append_csv_number(std::string& out, double v);
/// Writes `content` to file.tmp and renames it to `file`, so that a crash never leaves a
/// half-written file under the final name. Throws std::runtime_error on I/O failure.
void write_file_atomically(const std::filesystem::path& file, const std::string& content);

/// summary.json's content: status, message, steps, final state, diagnostics, statistics and the
/// fully resolved problem (so the run can be reproduced from its output).
nlohmann::json make_summary(const ProblemSpec& spec, const Solution& solution);

/// Writes trajectory.csv (header `t,x1..xd,v1..vd,energy,dissipated,balance`, one line per
/// stored row of the solution — every save_every-th step and the last computed one, as the
/// integrator kept them — 17 significant digits), summary.json and
/// problem.toml into `dir` (created if needed). Files are written to temporaries and renamed, so
/// a crash never leaves a half-written file under the final name.
void write_run_output(const std::filesystem::path& dir, const ProblemSpec& spec,
                      const Solution& solution);

}  // namespace fracvi
