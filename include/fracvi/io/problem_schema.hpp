// The problem-file schema, written once (DESIGN §4.1, "one schema"): every section and key of a
// problem file with its type, its default and a one-line summary. It drives the reader's check of
// unknown keys (with the nearest valid name suggested), Python's fracvi.problem_schema() and the
// keyword arguments of fracvi.integrate() for [method] and [output], and the docs: the key, type
// and default columns of every table in docs/problem-file.md are checked against it by
// tests/io/problem_schema_test.cpp. The defaults of [method] and [output] are not literals here:
// they are printed from ProblemSpec{}, whose defaults come from IntegratorOptions{} and
// NewtonOptions{}, so that there is one default per field everywhere.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace fracvi {

struct ProblemField {
  std::string section;  ///< "" (top level), "model", "model.chain", "initial", …
  std::string key;
  std::string type;          ///< as in the docs, e.g. "number", "array of d strings"
  std::string default_text;  ///< as in the docs, e.g. "required", "1e-12", "\"auto\""
  std::string summary;       ///< one line
};

/// Every field, in the order of docs/problem-file.md.
const std::vector<ProblemField>& problem_schema();

/// The keys of one section (a sub-table such as "model.chain" is a key of its parent too).
std::vector<std::string> schema_keys(std::string_view section);

/// True if `section` is a section or sub-table of the schema.
bool is_schema_section(std::string_view section);

}  // namespace fracvi
