// Problem files: the TOML description of a mechanical problem for `fracvi run`.
//
//   name = "damped-pendulum"
//   [model]    dim, mass, damping, alpha | damping_order, convention, potential, force
//              or dim, lagrangian, alpha (a general L(t, x, y, xdot, ydot, dx, dy); no mass,
//              damping, potential or force then, and the Riemann-Liouville convention)
//   [initial]  position, velocity   (optional when [boundary] is given)
//   [boundary] start, end           (x(a) = y(b), x(b) = y(a): the BVP of `fracvi bvp`)
//   [time]     start, end, steps | step
//   [method]   scheme, newton_tolerance, newton_max_iterations, history, history_tolerance
//   [output]   every
//   [reference] position   (optional exact solution: d formulas in t)
//
// Parsing validates everything before a single step is taken: unknown sections and keys are
// errors (with the nearest valid name suggested), and every message names the file, the key, the
// value and the rule. docs/problem-file.md is the reference for every key.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace fracvi {

/// Bad problem input. what() is one line: "<source>: <key> ...: <rule>".
class ProblemFileError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A fully resolved, validated problem: every default filled in, matrices expanded.
struct ProblemSpec {
  std::string source = "<built-in>";  ///< file name, for messages
  std::string name = "problem";

  // [model]
  Eigen::Index dim = 1;
  Eigen::MatrixXd mass;               ///< M, symmetric positive definite
  Eigen::MatrixXd damping;            ///< R, symmetric positive semidefinite
  double alpha = 0.5;                 ///< Lagrangian order; the damping order is 2α
  std::string convention = "caputo";  ///< "caputo" or "riemann-liouville"
  std::string potential = "0";        ///< U(x1..xd, t)
  std::vector<std::string> force;     ///< f(t), empty or d formulas
  /// L(t, x1.., y1.., xdot1.., ydot1.., dx1.., dy1..) (dx = D^alpha_- x, dy = D^alpha_+ y); when
  /// set, mass is empty, damping zero, potential "0", force empty, convention riemann-liouville.
  std::string lagrangian;

  // [initial]
  Eigen::VectorXd position, velocity;  ///< position is empty for a [boundary] file without it

  // [boundary]
  Eigen::VectorXd boundary_start, boundary_end;  ///< x(a) = y(b), x(b) = y(a); empty if absent

  // [time]
  double start = 0.0, end = 1.0;
  long long steps = 1;
  [[nodiscard]] double step() const { return (end - start) / static_cast<double>(steps); }

  // [method]
  std::string scheme = "fvi-gl";
  double newton_tolerance = 1e-12;
  int newton_max_iterations = 50;
  std::string history = "auto";      ///< "auto", "direct" or "fast" (the damping memory sum)
  double history_tolerance = 1e-10;  ///< per-weight relative accuracy of the fast history

  // [output]
  long long every = 1;

  // [reference]
  std::vector<std::string> reference;  ///< exact x(t), empty or d formulas in t
};

/// Parses and validates a problem from TOML text. `overrides` are "section.key=value" strings
/// (the CLI's --set), applied before validation; value is read as a TOML value, or as a string
/// when it is not one (so --set model.potential=x1^2 works without quotes).
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
/// reproduces the run).
nlohmann::json to_json(const ProblemSpec& spec);
std::string to_toml(const ProblemSpec& spec);

}  // namespace fracvi
