// The problem-file schema (io/problem_schema.hpp) is the one definition of every field: the docs
// tables, the reader's accepted keys and the defaults must agree with it.
#include "fracvi/io/problem_schema.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"

namespace {

using fracvi::ProblemField;

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(' '), b = s.find_last_not_of(' ');
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

std::string without_backticks(std::string s) {
  std::erase(s, '`');
  return s;
}

// The section a docs heading introduces ("## `[method]`" → "method", "## Top level" → "",
// "### A general Lagrangian …" → "model"); nullopt-like "?" for headings without a key table.
std::string section_of(const std::string& heading) {
  if (heading.find("Top level") != std::string::npos) return "";
  if (heading.find("general Lagrangian") != std::string::npos) return "model";
  const auto open = heading.find("`["), close = heading.find("]`");
  if (open != std::string::npos && close != std::string::npos) {
    return heading.substr(open + 2, close - open - 2);
  }
  return "?";
}

// (section, key) → (type, default) from every key table of docs/problem-file.md.
std::map<std::pair<std::string, std::string>, std::pair<std::string, std::string>> docs_tables() {
  std::ifstream in(std::string(FRACVI_SOURCE_DIR) + "/docs/problem-file.md");
  EXPECT_TRUE(in.good());
  std::map<std::pair<std::string, std::string>, std::pair<std::string, std::string>> rows;
  std::string line, section = "?";
  while (std::getline(in, line)) {
    if (line.rfind("#", 0) == 0) section = section_of(line);
    if (line.rfind("| `", 0) != 0 || section == "?") continue;
    std::vector<std::string> cells;
    std::stringstream ss(line.substr(1));
    std::string cell;
    while (std::getline(ss, cell, '|')) cells.push_back(trim(cell));
    if (cells.size() < 4) continue;
    rows[{section, without_backticks(cells[0])}] = {without_backticks(cells[1]),
                                                    without_backticks(cells[2])};
  }
  return rows;
}

TEST(ProblemSchema, DocsTablesAreTheSchema) {
  const auto docs = docs_tables();
  std::size_t fields = 0;
  for (const ProblemField& f : fracvi::problem_schema()) {
    if (f.type == "table") continue;  // a section: its own heading, not a row
    ++fields;
    const auto it = docs.find({f.section, f.key});
    ASSERT_NE(it, docs.end()) << "docs/problem-file.md has no row for [" << f.section << "] "
                              << f.key;
    EXPECT_EQ(it->second.first, f.type) << "type of [" << f.section << "] " << f.key;
    EXPECT_EQ(it->second.second, f.default_text) << "default of [" << f.section << "] " << f.key;
  }
  EXPECT_EQ(docs.size(), fields) << "docs/problem-file.md documents a key the schema lacks";
}

// Every key of the schema is accepted by the reader, and a key next to it is refused with the
// valid ones named (the reader's key check is the schema).
TEST(ProblemSchema, ReaderAcceptsExactlyTheSchemaKeys) {
  const std::string base(fracvi::default_problem_toml());
  for (const std::string section : {"method", "output"}) {
    for (const std::string& key : fracvi::schema_keys(section)) {
      const std::string bad = section + "." + key + "x=1";
      const std::vector<std::string> overrides{bad};
      try {
        (void)fracvi::parse_problem(base, "<built-in>", overrides);
        ADD_FAILURE() << bad << " was accepted";
      } catch (const fracvi::ProblemFileError& e) {
        EXPECT_NE(std::string(e.what()).find("unknown key"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      }
    }
  }
}

// One default per field: a problem that omits [method] and [output] runs with IntegratorOptions{}
// (and NewtonOptions{}), the C++ API's defaults.
TEST(ProblemSchema, OmittedFieldsTakeTheLibraryDefaults) {
  const std::string text =
      "[model]\ndim = 1\nmass = 1.0\nalpha = 0.5\npotential = \"x1^2/2\"\n[initial]\n"
      "position = [1.0]\n[time]\nend = 1.0\nsteps = 10\n";
  const fracvi::PreparedRun run = fracvi::prepare_run(fracvi::parse_problem(text, "<test>"));
  const fracvi::IntegratorOptions defaults;
  EXPECT_EQ(run.options.newton.relative_tolerance, defaults.newton.relative_tolerance);
  EXPECT_EQ(run.options.newton.max_iterations, defaults.newton.max_iterations);
  EXPECT_EQ(run.options.history, defaults.history);
  EXPECT_EQ(run.options.history_tolerance, defaults.history_tolerance);
  EXPECT_EQ(run.options.linear_solver, defaults.linear_solver);
  EXPECT_EQ(run.options.threads, defaults.threads);
  EXPECT_EQ(run.options.save_every, defaults.save_every);
  EXPECT_EQ(run.method, fracvi::Method());
}

}  // namespace
