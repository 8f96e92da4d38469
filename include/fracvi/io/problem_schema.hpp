// The problem-file schema, written once (DESIGN §4.1, "one schema"): every section and key of a
// problem file with its type, its default, a one-line summary, the C++ member it fills and how a
// resolved problem writes it. It drives
//  * the reader's check of unknown keys (with the nearest valid name suggested), for files, JSON
//    and `--set section.key=value` (check_override_key);
//  * the writers: to_json (summary.json, Python's Problem.to_dict) and to_toml (the resolved
//    problem.toml) iterate this table, so a field cannot be left out of them;
//  * Python's fracvi.problem_schema() and the keywords of fracvi.integrate() / solve_bvp();
//  * the docs: the key, type, default and C++ columns of every table in docs/problem-file.md are
//    checked against it by tests/io/problem_schema_test.cpp.
// The defaults of [method], [output] and [model.chain] are not literals here: they are printed
// from ProblemSpec{} and ChainOptions{}, whose defaults come from IntegratorOptions{} and
// NewtonOptions{}, so that there is one default per field everywhere.
//
// File keys and C++ names differ on purpose: the library API uses the paper's notation (x0, v0,
// t0, save_every, relative_tolerance), the files the user's vocabulary (position, velocity,
// start, every, newton_tolerance). The `binding` column is the dictionary between the two.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace fracvi {

struct ProblemSpec;

struct ProblemField {
  std::string section;  ///< "" (top level), "model", "model.chain", "initial", …
  std::string key;
  std::string type;          ///< as in the docs, e.g. "number", "array of d numbers"; "table" for
                             ///< a section
  std::string default_text;  ///< as in the docs, e.g. "required", "1e-12", "\"auto\""
  std::string summary;       ///< one line
  /// The one C++ member the field fills, e.g. "InitialValueProblem::x0" (a library type where
  /// the value reaches one, ProblemSpec otherwise); "" for a section. Spelled through the member
  /// pointer in problem_schema.cpp, so a renamed member does not compile until this is updated.
  std::string binding;
  /// The field's value in a resolved problem as the writers write it (JSON: integers stay
  /// integers), or null when the problem does not write it: an alternative spelling (damping_order
  /// and time.step are written as alpha and steps), a field that does not apply (potential with
  /// [model.chain] or [model] lagrangian) or absent optional data. Null for sections.
  nlohmann::json (*write)(const ProblemSpec&) = nullptr;
};

/// Every field, in the order of docs/problem-file.md.
const std::vector<ProblemField>& problem_schema();

/// The field [section] key, or null.
const ProblemField* find_field(std::string_view section, std::string_view key);

/// The keys of one section (a sub-table such as "model.chain" is a key of its parent too).
std::vector<std::string> schema_keys(std::string_view section);

/// True if `section` is a section or sub-table of the schema.
bool is_schema_section(std::string_view section);

/// The sections of the schema as they are named in messages: "[model]", "[model.chain]", ….
std::vector<std::string> schema_section_names();

/// "" if `path` ("section.key", "section.table.key" or a top-level "key") names a field of the
/// schema, else the one-line reason naming the path, the nearest valid name and the valid ones
/// (for `--set`; the reader's own check of files says the same).
std::string unknown_field_message(std::string_view path);

/// The suggestion " (did you mean 'x'?)" for the candidate nearest to `wrong`, or "".
std::string did_you_mean(std::string_view wrong, const std::vector<std::string>& candidates);

}  // namespace fracvi
