// Problem files: the TOML description of a mechanical problem for `fracvi run`.
//
//   name = "damped-pendulum"
//   [model]    dim, mass, damping, alpha | damping_order, convention, potential, force
//              or dim, lagrangian, alpha (a general L(t, x, y, xdot, ydot, dx, dy); no mass,
//              damping, potential or force then, and the Riemann-Liouville convention)
//   [model.chain] stiffness, cubic, quartic, onsite, boundary (the built-in FPUT chain, instead
//              of potential)
//   [initial]  position, velocity   (arrays, one number, or formulas in i, d; optional when
//              [boundary] is given)
//   [boundary] start, end           (x(a) = y(b), x(b) = y(a): the BVP of `fracvi bvp`)
//   [time]     start, end, steps | step
//   [method]   scheme, newton_tolerance, newton_max_iterations, history, history_tolerance, mirror,
//              abs_tolerance, rel_tolerance,
//              linear_solver, threads
//   [output]   every                (the stride of the stored states)
//              checkpoint_every     (fracvi run's checkpoints, io/checkpoint.hpp)
//              times                (the state at these times too, by dense output)
//   [[events]] name, g, direction, terminal   (zero crossings of g(t, x, v); any number)
//   [reference] position   (optional exact solution: d formulas in t)
//
// Parsing validates everything before a single step is taken: unknown sections and keys are
// errors (with the nearest valid name suggested), and every message names the file, the key, the
// value and the rule. docs/problem-file.md is the reference for every key.
#pragma once

#include "fracvi/core/newton_options.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/registry.hpp"

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/model/state_force.hpp"

namespace fracvi {

/// Bad problem input. what() is one line: "<source>: <key> ...: <rule>".
class ProblemFileError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A fully resolved, validated problem: every default filled in.
struct ProblemSpec {
  std::string source = "<built-in>";  ///< file name, for messages
  std::string name = "problem";

  // [model]
  Eigen::Index dim = 1;
  /// M, symmetric positive definite. A number (m·I) or an array of d numbers (the diagonal) is
  /// stored sparse (ModelMatrix::identity / ::diagonal, O(d) memory), an array of d rows dense.
  ModelMatrix mass;
  ModelMatrix damping;                ///< R, symmetric positive semidefinite; the same forms
  double alpha = 0.5;                 ///< Lagrangian order; the damping order is 2α
  std::string convention = "caputo";  ///< "caputo" or "riemann-liouville"
  std::string potential = "0";        ///< U(x1..xd, t); "0" when `chain` is set
  /// A potential object given by the caller instead of a formula (the Python module's callables,
  /// fracvi.Problem(potential=<function>, gradient=..., hessian=...)): make_potential() returns
  /// it, and `potential` holds its label, "python:<module>:<name>, ..." (kPythonFunctionPrefix),
  /// which the writers record and a problem file cannot resolve (the reader says so).
  std::shared_ptr<const Potential> potential_object;
  /// [model.chain]: the built-in FPUT chain (model/chain_potential.hpp) instead of `potential`;
  /// dimension = dim, threads = the [method] threads.
  std::optional<ChainOptions> chain;
  std::vector<std::string> force;  ///< f(t) or g(x, v, t): empty or d formulas
  /// g(x, v, t) given by the caller instead of formulas (the Python module's
  /// fracvi.Problem(force=<function>, force_jacobian=...)): make_initial_value_problem() makes it
  /// the model's state force, and `force` holds its label, {"python:<module>:<name>[, ...]"}
  /// (kPythonFunctionPrefix), which a problem file cannot resolve either.
  std::shared_ptr<const StateForce> force_object;
  /// L(t, x1.., y1.., xdot1.., ydot1.., dx1.., dy1..) (dx = D^alpha_- x, dy = D^alpha_+ y); when
  /// set, mass is empty, damping zero, potential "0", force empty, convention riemann-liouville.
  std::string lagrangian;

  // [initial]
  Eigen::VectorXd position, velocity;  ///< position is empty for a [boundary] file without it
  /// The formulas in i (1-based index), d and pi the initial data were given as, or "" (given as
  /// numbers); to_toml writes them back instead of d numbers.
  std::string position_formula, velocity_formula;

  // [boundary]
  Eigen::VectorXd boundary_start, boundary_end;  ///< x(a) = y(b), x(b) = y(a); empty if absent

  // [time]
  double start = 0.0, end = 1.0;
  long long steps = 1;
  [[nodiscard]] double step() const { return (end - start) / static_cast<double>(steps); }

  // [method]
  /// a registry name, or "auto" (the default: choose_scheme() picks it for the problem)
  std::string scheme = std::string(kAutoScheme);
  double newton_tolerance = NewtonOptions{}.relative_tolerance;  // one default: core/newton_options
  int newton_max_iterations = NewtonOptions{}.max_iterations;
  /// "auto", "direct" or "fast" (the damping memory sum)
  std::string history = std::string(to_string(IntegratorOptions{}.history));
  double history_tolerance =
      IntegratorOptions{}.history_tolerance;  ///< per-weight relative accuracy of the fast history
  /// error tolerances of the adaptive schemes (dopri5)
  double abs_tolerance = IntegratorOptions{}.abs_tolerance;
  double rel_tolerance = IntegratorOptions{}.rel_tolerance;
  /// "auto", "dense", "banded" or "sparse" (Newton matrix)
  std::string linear_solver = std::string(to_string(IntegratorOptions{}.linear_solver));
  /// "pointwise" or "moments" (how the forcing enters)
  std::string load = std::string(to_string(IntegratorOptions{}.load));
  /// "taylor" or "series" (what the Lobatto schemes take out of x at t0)
  std::string split = std::string(to_string(IntegratorOptions{}.split));
  /// "richardson" or "none" (the a-posteriori error estimate of fracvi run / fracvi.integrate)
  std::string error_estimate = std::string(to_string(IntegratorOptions{}.error_estimate));
  /// > 0: choose N by doubling time.steps until the error estimate is <= tolerance; 0: off
  double tolerance = IntegratorOptions{}.tolerance;
  /// the ceiling of that doubling
  long long max_steps = static_cast<long long>(IntegratorOptions{}.max_steps);
  /// "auto", "on" or "off": the backward run of the mirror equation and its mirror error (a
  /// consistency check that costs about one more run); "auto" runs it when
  /// time.steps · model.dim ≤ kAutoMirrorWork (mirror_check_runs)
  std::string mirror = "auto";
  int threads =
      IntegratorOptions{}.threads;  ///< OpenMP threads over the degrees of freedom; 0 = all
  /// subnormal numbers flushed to zero while stepping (IntegratorOptions::flush_subnormals)
  bool flush_subnormals = IntegratorOptions{}.flush_subnormals;

  // [output]
  /// store every n-th step (IntegratorOptions::save_every) and the last; kAutoEvery ("auto", the
  /// default): chosen from time.steps by stored_every()
  long long every = 0;
  /// `fracvi run` writes a checkpoint of the whole state every n steps (0: none), from which
  /// `fracvi run --resume DIR` continues bit-for-bit (io/checkpoint.hpp)
  long long checkpoint_every = 0;
  /// the state at these times too (IntegratorOptions::output_times), ascending, in [start, end]
  std::vector<double> times;
  /// the trajectory's file: "csv" (trajectory.csv, text, 17 digits) or "npz" (trajectory.npz,
  /// NumPy's archive of the stored arrays: io/npz.hpp)
  std::string format = "csv";

  // [[events]]: zero crossings of g(t, x1..xd, v1..vd) (IntegratorOptions::events)
  struct EventSpec {
    std::string name;
    std::string g;
    std::string direction = std::string(to_string(EventDirection::kBoth));
    bool terminal = false;
    friend bool operator==(const EventSpec&, const EventSpec&) = default;
  };
  std::vector<EventSpec> events;

  // [reference]
  std::vector<std::string> reference;  ///< exact x(t), empty or d formulas in t
};

/// How a potential or a force given as Python callables is labelled in `ProblemSpec::potential`
/// and `ProblemSpec::force`.
inline constexpr std::string_view kPythonFunctionPrefix = "python:";

/// Step-DOFs (time.steps · model.dim) up to which method.mirror = "auto" runs the mirror check:
/// such runs take well under a second (bench/RESULTS.md: 0.1–1 µs per step-DOF for the midpoint
/// schemes), so the check is nearly free; above it the check would double a long run's wait, and
/// the error estimate, not the mirror, is what measures accuracy.
inline constexpr long long kAutoMirrorWork = 1'000'000;

/// ProblemSpec::every = "auto" (the default): every step while a run has at most kAutoStoredRows
/// steps; beyond, the smallest power of two that keeps the stored states within kAutoStoredRows + 1
/// (+ the last). Why: a run of 10^7 steps that stored every state kept 740 MB and wrote a 1.2 GB
/// trajectory.csv (5.7 s of a 13 s run, bench/RESULTS.md), far more than a plot or a table reads;
/// a power of two keeps every stored step on the grids of the error estimate's N/2 and N/4
/// companion runs, which compare on the stored rows.
inline constexpr long long kAutoEvery = 0;
inline constexpr long long kAutoStoredRows = 100'000;

/// The storage stride of a run of `steps` steps with output.every = `every` (kAutoEvery: the rule
/// above; any other value is returned as it is).
long long stored_every(long long every, long long steps);
inline long long stored_every(const ProblemSpec& spec) {
  return stored_every(spec.every, spec.steps);
}

/// Whether a run of `spec` runs the mirror check (method.mirror and, for "auto", kAutoMirrorWork).
bool mirror_check_runs(const ProblemSpec& spec);

/// Parses and validates a problem from TOML text. `overrides` are "section.key=value" strings
/// (the CLI's --set), applied before validation; the key must be a field of the schema
/// ("<source>: --set <key>: unknown key ...; valid in [section]: ..." otherwise), the value is
/// read as a TOML value, or as a string when it is not one (so --set model.potential=x1^2 works
/// without quotes), and then checked by the reader like a value in the file.
ProblemSpec parse_problem(std::string_view toml_text, const std::string& source,
                          std::span<const std::string> overrides = {});

/// The same schema and validation from a JSON object (used by the Python module: a dict or keyword
/// arguments become JSON). JSON integers are TOML integers, so `steps = 100` must not be 100.0.
ProblemSpec parse_problem_json(const nlohmann::json& document, const std::string& source,
                               std::span<const std::string> overrides = {});

/// Reads and parses a problem file.
ProblemSpec load_problem(const std::filesystem::path& file,
                         std::span<const std::string> overrides = {});

/// The built-in problem `fracvi run` uses without a file.
std::string_view default_problem_toml();

/// The resolved problem as JSON (written into summary.json) and as TOML (a file that
/// reproduces the run: parse_problem(to_toml(p)) equals p field by field). Both iterate the schema
/// (io/problem_schema.hpp, ProblemField::write), so every field is written; to_toml is the TOML
/// form of to_json. Matrices: a diagonal with equal entries is written as one number, another
/// diagonal as an array of d numbers, a dense matrix as d rows. Initial data given as formulas
/// is written as the formulas, a constant vector (d ≥ 2) as one number. Alternative spellings
/// (damping_order, time.step) are written as alpha and steps.
nlohmann::json to_json(const ProblemSpec& spec);
std::string to_toml(const ProblemSpec& spec);

}  // namespace fracvi
