// What a run leaves behind: trajectory.csv, summary.json and problem.toml in one directory.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <ostream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/integrate/solution.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

/// U of a validated spec: the caller's potential object (ProblemSpec::potential_object: Python
/// callables), the built-in chain of [model.chain] (with the [method] threads) or the expression
/// potential of model.potential.
std::shared_ptr<const Potential> make_potential(const ProblemSpec& spec);
/// The mechanical model of a validated spec: M, R, α, convention, U (make_potential) and the
/// force: formulas in t alone as f(t), formulas mentioning x or v as g(x, v, t)
/// (make_expression_forces), or the caller's g (ProblemSpec::force_object: Python callables).
MechanicalModel make_mechanical_model(const ProblemSpec& spec);
/// The initial value problem of a validated spec: its model (make_mechanical_model), initial
/// data and grid.
InitialValueProblem make_initial_value_problem(const ProblemSpec& spec);
/// The [method] options (Newton, history, linear_solver, threads) and save_every = output.every.
IntegratorOptions make_integrator_options(const ProblemSpec& spec);

/// JSON value of a double; non-finite numbers become null (JSON has no NaN).
nlohmann::json json_number(double v);
/// Row `row` of `m` as a JSON array (non-finite entries null; empty if m has no rows).
nlohmann::json json_row(const RowMatrixXd& m, Eigen::Index row);
/// Appends v with 17 significant digits (enough to round-trip every double).
void append_csv_number(std::string& out, double v);
/// A new temporary's name beside `file`: file.tmp.<pid>.<n>, unique in this process (a later run
/// into the directory removes those of dead processes).
std::filesystem::path temporary_path(const std::filesystem::path& file);
/// Writes `content` to a temporary beside `file` (temporary_path: unique, so that concurrent
/// writers never share one) and renames it to `file`, so that a crash never leaves a half-written
/// file under the final name. Throws OutputError on I/O failure (naming the file and the system's
/// reason) after removing the temporary.
void write_file_atomically(const std::filesystem::path& file, const std::string& content);
/// Same, with the content streamed by `write` (a large trajectory is never held as one string).
void write_file_atomically(const std::filesystem::path& file,
                           const std::function<void(std::ostream&)>& write);

/// An output directory or file that cannot be created or written.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Creates `dir` (and its parents) if needed and checks that a file can be created in it — before
/// a run starts, so that hours of work are never lost to an output directory that was a file,
/// unwritable or a name too long. Throws OutputError "<dir>: <reason>" (exists and is not a
/// directory, permission denied, file name too long, read-only file system, …). The probe file it
/// writes is removed again.
void prepare_output_directory(const std::filesystem::path& dir);

/// An exclusive claim on an output directory for as long as it lives (an advisory flock on
/// `<dir>/.fracvi.lock`, removed again on release): a second process that claims the same
/// directory gets OutputError "<dir>: in use by another fracvi run (pid N) …" at once, instead of
/// the two runs interleaving their files (issue 14: two runs into one directory left one run's
/// trajectory beside the other's summary). Claims by the same process nest (the CLI claims the
/// directory before the run, write_run_output() again while writing).
/// The first claim removes the temporaries (`<file>.tmp.<pid>.<n>`, the write probe) that runs
/// killed while writing left behind, if their process is gone; those of live processes are kept.
class OutputLock {
 public:
  explicit OutputLock(const std::filesystem::path& dir);
  ~OutputLock();
  OutputLock(OutputLock&& other) noexcept : key_(std::move(other.key_)) { other.key_.clear(); }
  OutputLock& operator=(OutputLock&&) = delete;
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  std::string key_;  // the lock file's path; empty when moved from
};

/// summary.json's content: status, message, steps, final state, diagnostics, statistics and the
/// fully resolved problem (so the run can be reproduced from its output).
nlohmann::json make_summary(const ProblemSpec& spec, const Solution& solution);

/// trajectory.csv of write_run_output: `t,x1..xd,v1..vd,energy,dissipated,balance`, one line per
/// stored row, 17 significant digits (every double reads back to itself), written atomically.
void write_trajectory_csv(const std::filesystem::path& file, const Solution& solution);

/// times.csv (`[output] times`): `t,x1..xd,v1..vd`, one line per requested time the run reached,
/// the dense output (Solution::output_t, output_x, output_v).
void write_times_csv(const std::filesystem::path& file, const Solution& solution);

/// events.csv (`[[events]]`): `event,direction,step,t,x1..xd,v1..vd`, one line per crossing in
/// time order (Solution::events; direction "rising" or "falling", step the k + 1 of the interval
/// (t_k, t_{k+1}] that holds it).
void write_events_csv(const std::filesystem::path& file, const Solution& solution);

/// Reads back what make_summary() wrote about the solution itself (status, message, steps, the
/// statistics, the error estimate, the tolerance runs, the event crossings; null numbers are NaN)
/// into `solution`, whose arrays are left alone: the inverse of make_summary for everything but
/// the final state, the states at output.times and the problem, which trajectory.csv, times.csv
/// and problem.toml hold. Event names are indexed in order of first crossing. Throws OutputError
/// "<what>:
/// "<key>" <rule>" for a missing field or one of the wrong type.
void read_summary(const nlohmann::json& summary, Solution& solution, const std::string& what);

/// trajectory.npz: NumPy's archive (io/npz.hpp) of the arrays t, step (int64), x, v, energy,
/// dissipated, balance as stored, the names and dtypes np.savez gives fracvi.write's.
void write_trajectory_npz(const std::filesystem::path& file, const Solution& solution);

/// Writes trajectory.csv (header `t,x1..xd,v1..vd,energy,dissipated,balance`, one line per stored
/// row of the solution — every save_every-th step and the last computed one, as the integrator
/// kept them — 17 significant digits), or trajectory.npz for output.format = "npz" (the other
/// one of an earlier run is removed, so that the directory holds one trajectory), times.csv and
/// events.csv when the problem asks for them, problem.toml and, last, summary.json into `dir`
/// (created if needed), under an OutputLock of `dir`. An earlier summary.json is removed first,
/// so that a directory with a summary.json holds one complete run. Files are written to
/// temporaries and renamed, so a crash never leaves a half-written file under the final name.
/// `format`, when not empty, writes the trajectory in that format ("csv" or "npz") instead of
/// output.format, the problem.toml written unchanged (Python's fracvi.write(..., format=)).
void write_run_output(const std::filesystem::path& dir, const ProblemSpec& spec,
                      const Solution& solution, std::string_view format = {});

}  // namespace fracvi
