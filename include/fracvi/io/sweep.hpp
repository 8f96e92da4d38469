// Parameter sweeps (`fracvi sweep`, Python's fracvi.sweep; docs/sweep-file.md): one base problem,
// a set of parameters over fields of the one schema (io/problem_schema.hpp), and the cases they
// combine into. A case is the base problem with `--set path=value` overrides (the reader's
// apply_override, so a swept value is checked exactly like a value in a file), run in-process
// through solve_prepared() — the numbers of a case do not depend on which thread, process or MPI
// rank ran it.
//
// The results table (results.csv) has one row per case, written as the case finishes; a row is
// one line appended with one write(2) to a file opened O_APPEND, so a killed process leaves whole
// rows (and at worst a torn last line from a machine crash, which --resume drops). When the sweep
// ends the table is rewritten atomically in case order. sweep.json beside it fingerprints the
// cases, so that --resume refuses the table of a different sweep.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

/// A sweep file or document that cannot be used (syntax, unknown key, unknown field, a range
/// without a count, zipped lists of different lengths, …). what() is one line naming the key.
class SweepError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

enum class SweepCombine { kGrid, kZip };
/// What is kept per case: the row without the final state, the row with it (x1..xd, v1..vd), or
/// the row and the run's own output directory cases/<case>/ (trajectory.csv, summary.json,
/// problem.toml).
enum class SweepSave { kSummary, kFinal, kTrajectory };

/// One swept field and its values, each as the TOML text of the value ("0.35", "\"fvi-gl\"",
/// "[1.0, 0.0]"); doubles with 17 significant digits, so the case runs with the exact value.
struct SweepParameter {
  std::string path;  ///< "model.alpha", "model.chain.cubic", "time.steps", …
  std::vector<std::string> values;
};

struct SweepCase {
  std::size_t index = 0;            ///< 0-based; the row order of the final results.csv
  std::vector<std::string> values;  ///< one per parameter, TOML text
  /// Why the case was refused before any run (the reader's or prepare_run's message), or "".
  std::string invalid;
  Eigen::Index dim = 0;  ///< model.dim of the case (0 when invalid)
};

struct SweepSpec {
  std::string source;       ///< the sweep file, for messages
  nlohmann::json base;      ///< the base problem as a JSON object (parse_problem_json)
  std::string base_source;  ///< the base problem file, or "<source> [problem]"
  std::vector<SweepParameter> parameters;
  SweepCombine combine = SweepCombine::kGrid;
  SweepSave save = SweepSave::kFinal;
  /// method.threads is swept, or set by the base problem to a number other than 0 (the default,
  /// all cores): the user chose the threads per case.
  bool threads_given = false;
  std::vector<SweepCase> cases;   ///< expanded and each validated (SweepCase::invalid)
  std::uint64_t fingerprint = 0;  ///< of the base problem and every case's values
};

/// Builds a sweep from a document {"base": "path" | "problem": {…}, "sweep": {"combine",
/// "save", "parameters": […]}} where "parameters" is an array of [path, values] pairs in the
/// order of the grid (the first varies slowest). A relative base path is taken from `directory`.
/// Every case is expanded and validated here (parse_problem_json with its overrides, then
/// prepare_run); an invalid case is kept with SweepCase::invalid set, never run. Throws
/// SweepError for a document that is not a sweep.
SweepSpec make_sweep(const nlohmann::json& document, const std::string& source,
                     const std::filesystem::path& directory);

/// Reads a sweep file (TOML; docs/sweep-file.md) and make_sweep()s it, with the parameters in the
/// order they are written.
SweepSpec load_sweep(const std::filesystem::path& file);

/// The overrides ("path=value") of one case.
std::vector<std::string> case_overrides(const SweepSpec& sweep, const SweepCase& c);

/// " (case 7: model.alpha=0.35, model.damping=2)": a case named by its parameters.
std::string case_label(const SweepSpec& sweep, const SweepCase& c);

/// results.csv's header: case, the parameter paths, status, message, …, wall_seconds.
std::vector<std::string> sweep_columns(const SweepSpec& sweep);

struct SweepCaseOptions {
  /// Run each case with method.threads = 1 unless the sweep sets it (SweepSpec::threads_given):
  /// cases run side by side must not each start a thread per core.
  bool single_thread = false;
  /// Where save = "trajectory" writes cases/<case>/ (empty: nothing written).
  std::filesystem::path out;
};

/// Runs one case (an invalid one is only reported) and returns its row as one CSV line with a
/// trailing newline, the columns of sweep_columns(). Never throws for a failing case: its status
/// (the Solution's, "invalid" for a case refused up front, "error" for an exception) and message
/// are in the row.
std::string run_sweep_case(const SweepSpec& sweep, const SweepCase& c,
                           const SweepCaseOptions& options);

/// Runs `cases` (indices into sweep.cases) on `jobs` threads, each taking the next case when it is
/// free (runs differ in cost by orders of magnitude), and calls `on_row(index, row)` (serialised:
/// one call at a time) as each finishes. Stops handing out cases once `*stop` is true (the running
/// ones finish). Returns the number of cases run.
std::size_t run_sweep_local(const SweepSpec& sweep, const std::vector<std::size_t>& cases, int jobs,
                            const SweepCaseOptions& options,
                            const std::function<void(std::size_t, const std::string&)>& on_row,
                            const std::atomic<bool>* stop = nullptr);

/// The results table of a sweep in an output directory: results.csv (rows appended as cases
/// finish) and sweep.json (the fingerprint, the columns, the cases).
class SweepTable {
 public:
  /// Opens `dir` (created if needed) and claims it (OutputLock: a second sweep or run into it is
  /// refused with OutputError while this one lives). Without `resume`, a directory that already
  /// holds a results.csv is refused (SweepError: nothing is overwritten); with it, the rows of the
  /// same sweep (sweep.json's fingerprint must match) are kept, a torn last line is dropped, and
  /// done() lists their cases.
  SweepTable(const std::filesystem::path& dir, const SweepSpec& sweep, bool resume);
  SweepTable(const SweepTable&) = delete;
  SweepTable& operator=(const SweepTable&) = delete;
  ~SweepTable();

  /// Cases whose row is in the table.
  [[nodiscard]] const std::set<std::size_t>& done() const { return done_; }
  /// The rows (case, CSV line), in the order they came (case order after finish()).
  [[nodiscard]] const std::vector<std::pair<std::size_t, std::string>>& rows() const {
    return rows_;
  }
  /// Appends the row of case `index` (thread-safe; one write(2)).
  void append(std::size_t index, const std::string& row);
  /// Rewrites results.csv in case order (atomically: temporary and rename).
  void finish();
  [[nodiscard]] std::filesystem::path file() const { return dir_ / "results.csv"; }

 private:
  std::filesystem::path dir_;
  std::optional<OutputLock> lock_;
  std::string header_;
  std::set<std::size_t> done_;
  std::vector<std::pair<std::size_t, std::string>> rows_;
  std::mutex mutex_;
  int fd_ = -1;
  double last_sync_ = 0.0;
};

/// Splits one CSV line (RFC 4180 quoting, no trailing newline) into its fields.
std::vector<std::string> split_csv_line(std::string_view line);

}  // namespace fracvi
