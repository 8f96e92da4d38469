// The problem-file schema (io/problem_schema.hpp) is the one definition of every field: the docs
// tables, the reader's accepted keys and the defaults must agree with it.
#include "fracvi/io/problem_schema.hpp"

#include <gtest/gtest.h>

#include <toml++/toml.h>
#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/run.hpp"
#include "fracvi/model/chain_potential.hpp"

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

struct DocsRow {
  std::string type, default_text, binding;
};

// (section, key) → (type, default, C++) from every key table of docs/problem-file.md
// (| key | type | default | C++ | rule |).
std::map<std::pair<std::string, std::string>, DocsRow> docs_tables() {
  std::ifstream in(std::string(FRACVI_SOURCE_DIR) + "/docs/problem-file.md");
  EXPECT_TRUE(in.good());
  std::map<std::pair<std::string, std::string>, DocsRow> rows;
  std::string line, section = "?";
  while (std::getline(in, line)) {
    if (line.rfind("#", 0) == 0) section = section_of(line);
    if (line.rfind("| `", 0) != 0 || section == "?") continue;
    std::vector<std::string> cells;
    std::stringstream ss(line.substr(1));
    std::string cell;
    while (std::getline(ss, cell, '|')) cells.push_back(trim(cell));
    EXPECT_EQ(cells.size(), 5u) << "a key table row needs 5 columns: " << line;
    if (cells.size() < 5) continue;
    rows[{section, without_backticks(cells[0])}] = {
        without_backticks(cells[1]), without_backticks(cells[2]), without_backticks(cells[3])};
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
    EXPECT_EQ(it->second.type, f.type) << "type of [" << f.section << "] " << f.key;
    EXPECT_EQ(it->second.default_text, f.default_text)
        << "default of [" << f.section << "] " << f.key;
    EXPECT_EQ(it->second.binding, f.binding) << "C++ member of [" << f.section << "] " << f.key;
    EXPECT_FALSE(f.binding.empty()) << "[" << f.section << "] " << f.key << " has no binding";
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
  // The scheme: "auto" (docs/comparison.md), which is choose_scheme() of the C++ API; here the
  // first candidate, fvi-lobatto3 (the C++ Method() default stays the paper's fvi-gl: a program
  // names its scheme).
  EXPECT_EQ(run.method, fracvi::choose_scheme(run.problem, run.options));
  EXPECT_EQ(run.method.name(), "fvi-lobatto3");
}

// ---------------------------------------------------------------------------------------------
// The writers (to_toml, to_json) iterate the schema: every field is written, and reading the
// written problem.toml back gives the same problem, field by field, for a non-default value of
// every field.

using Json = nlohmann::json;

// Every member of ProblemSpec that a problem file sets, compared exactly (a new member must be
// added here; a new field of the schema must be added to kCases below, which the test enforces).
std::vector<std::string> differences(const fracvi::ProblemSpec& a, const fracvi::ProblemSpec& b) {
  std::vector<std::string> out;
  const auto check = [&out](bool same, const char* what) {
    if (!same) out.emplace_back(what);
  };
  const auto same_matrix = [](const fracvi::ModelMatrix& x, const fracvi::ModelMatrix& y) {
    if (x.rows() != y.rows() || x.is_sparse() != y.is_sparse()) return false;
    return x.rows() == 0 || x.to_dense() == y.to_dense();
  };
  const auto same_vector = [](const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
    return x.size() == y.size() && x == y;
  };
  check(a.name == b.name, "name");
  check(a.dim == b.dim, "dim");
  check(same_matrix(a.mass, b.mass), "mass");
  check(same_matrix(a.damping, b.damping), "damping");
  check(a.alpha == b.alpha, "alpha");
  check(a.convention == b.convention, "convention");
  check(a.potential == b.potential, "potential");
  check(a.chain.has_value() == b.chain.has_value(), "chain");
  if (a.chain && b.chain) {
    check(a.chain->dimension == b.chain->dimension, "chain.dimension");
    check(a.chain->stiffness == b.chain->stiffness, "chain.stiffness");
    check(a.chain->cubic == b.chain->cubic, "chain.cubic");
    check(a.chain->quartic == b.chain->quartic, "chain.quartic");
    check(a.chain->onsite == b.chain->onsite, "chain.onsite");
    check(a.chain->boundary == b.chain->boundary, "chain.boundary");
    check(a.chain->threads == b.chain->threads, "chain.threads");
  }
  check(a.force == b.force, "force");
  check(a.lagrangian == b.lagrangian, "lagrangian");
  check(same_vector(a.position, b.position), "position");
  check(same_vector(a.velocity, b.velocity), "velocity");
  check(a.position_formula == b.position_formula, "position_formula");
  check(a.velocity_formula == b.velocity_formula, "velocity_formula");
  check(same_vector(a.boundary_start, b.boundary_start), "boundary_start");
  check(same_vector(a.boundary_end, b.boundary_end), "boundary_end");
  check(a.start == b.start, "start");
  check(a.end == b.end, "end");
  check(a.steps == b.steps, "steps");
  check(a.scheme == b.scheme, "scheme");
  check(a.newton_tolerance == b.newton_tolerance, "newton_tolerance");
  check(a.newton_max_iterations == b.newton_max_iterations, "newton_max_iterations");
  check(a.history == b.history, "history");
  check(a.history_tolerance == b.history_tolerance, "history_tolerance");
  check(a.abs_tolerance == b.abs_tolerance, "abs_tolerance");
  check(a.rel_tolerance == b.rel_tolerance, "rel_tolerance");
  check(a.linear_solver == b.linear_solver, "linear_solver");
  check(a.load == b.load, "load");
  check(a.split == b.split, "split");
  check(a.error_estimate == b.error_estimate, "error_estimate");
  check(a.mirror == b.mirror, "mirror");
  check(a.tolerance == b.tolerance, "tolerance");
  check(a.max_steps == b.max_steps, "max_steps");
  check(a.threads == b.threads, "threads");
  check(a.flush_subnormals == b.flush_subnormals, "flush_subnormals");
  check(a.every == b.every, "every");
  check(a.checkpoint_every == b.checkpoint_every, "checkpoint_every");
  check(a.times == b.times, "times");
  check(a.format == b.format, "format");
  check(a.events == b.events, "events");
  check(a.reference == b.reference, "reference");
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& e : v) s += (s.empty() ? "" : ", ") + e;
  return s;
}

// Every optional field at its default (so each case below changes exactly what it names).
Json base_problem() {
  return Json::parse(R"({
    "name": "base",
    "model": {"dim": 2, "mass": 1.0, "alpha": 0.5, "potential": "x1^2/2 + x2^2/2"},
    "initial": {"position": [1.0, 0.0]},
    "time": {"end": 1.0, "steps": 10}
  })");
}

struct Case {
  std::string field;    ///< "section.key" of the schema field the case sets
  std::string written;  ///< the key that must appear in problem.toml ("" = field)
  std::function<void(Json&)> edit;
};

// At least one non-default value per field (values with long binary expansions, so that a writer
// that rounds is caught).
const std::vector<Case>& cases() {
  static const std::vector<Case> all = {
      {"name", "", [](Json& j) { j["name"] = "renamed"; }},
      {"model.dim", "",
       [](Json& j) {
         j["model"]["dim"] = 3;
         j["initial"]["position"] = {1.0, 0.0, 0.1};
       }},
      {"model.mass", "",
       [](Json& j) {
         j["model"]["mass"] = {{2.0, 0.3}, {0.3, 1.0 / 3.0}};
       }},
      {"model.mass", "",
       [](Json& j) {
         j["model"]["mass"] = {0.7, 1.0 / 3.0};
       }},
      {"model.mass", "", [](Json& j) { j["model"]["mass"] = 0.1; }},
      {"model.damping", "",
       [](Json& j) {
         j["model"]["damping"] = {0.1, 0.2};
       }},
      {"model.damping", "",
       [](Json& j) {
         j["model"]["damping"] = {{0.2, 0.1}, {0.1, 0.3}};
       }},
      {"model.alpha", "",
       [](Json& j) {
         j["model"]["alpha"] = 0.7;
         j["model"]["damping"] = 0.2;
         j["model"]["convention"] = "caputo";
       }},
      {"model.damping_order", "model.alpha",
       [](Json& j) {
         j["model"].erase("alpha");
         j["model"]["damping_order"] = 1.3;
       }},
      {"model.convention", "", [](Json& j) { j["model"]["convention"] = "riemann-liouville"; }},
      {"model.potential", "", [](Json& j) { j["model"]["potential"] = "x1^4/4 + cos(x2)"; }},
      {"model.chain", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = Json::object();
       }},
      {"model.chain.stiffness", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = {{"stiffness", 2.1}};
       }},
      {"model.chain.cubic", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = {{"cubic", 0.3}};
       }},
      {"model.chain.quartic", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = {{"quartic", 1.1}};
       }},
      {"model.chain.onsite", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = {{"onsite", 0.1}};
       }},
      {"model.chain.boundary", "",
       [](Json& j) {
         j["model"].erase("potential");
         j["model"]["chain"] = {{"boundary", "free"}};
       }},
      {"model.force", "",
       [](Json& j) {
         j["model"]["force"] = {"0.1*sin(t)", "0"};
       }},
      // A non-conservative force g(x, v, t): the same key, formulas in x and v too.
      {"model.force", "",
       [](Json& j) {
         j["model"]["force"] = {"0.3*(1 - x1^2)*v1", "-0.1*x2*v2 + 0.2*cos(t)"};
       }},
      {"model.lagrangian", "",
       [](Json& j) {
         j["model"].erase("mass");
         j["model"].erase("potential");
         j["model"]["lagrangian"] = "xdot1^2/2 + xdot2^2/2 - x1^2/2 - 0.3*dx1*dy1";
       }},
      {"initial.position", "",
       [](Json& j) {
         j["initial"]["position"] = {0.1, -1.0 / 3.0};
       }},
      {"initial.position", "", [](Json& j) { j["initial"]["position"] = "0.1*i"; }},
      {"initial.position", "", [](Json& j) { j["initial"]["position"] = 0.3; }},
      {"initial.velocity", "",
       [](Json& j) {
         j["initial"]["velocity"] = {0.2, 1.0 / 7.0};
       }},
      {"initial.velocity", "", [](Json& j) { j["initial"]["velocity"] = "sin(i)"; }},
      {"boundary.start", "",
       [](Json& j) {
         j["boundary"] = {{"start", {0.3, -0.2}}, {"end", {0.0, 0.0}}};
       }},
      {"boundary.end", "",  // a boundary value problem without [initial]
       [](Json& j) {
         j.erase("initial");
         j["boundary"] = {{"start", {0.0, 0.0}}, {"end", {-0.4, 0.1}}};
       }},
      {"time.start", "", [](Json& j) { j["time"]["start"] = -0.1; }},
      {"time.end", "", [](Json& j) { j["time"]["end"] = 2.7; }},
      {"time.steps", "", [](Json& j) { j["time"]["steps"] = 37; }},
      {"time.step", "time.steps",
       [](Json& j) {
         j["time"].erase("steps");
         j["time"]["step"] = 0.125;
       }},
      {"method.scheme", "", [](Json& j) { j["method"]["scheme"] = "fvi-bdf2"; }},
      {"method.newton_tolerance", "", [](Json& j) { j["method"]["newton_tolerance"] = 3e-11; }},
      {"method.newton_max_iterations", "",
       [](Json& j) { j["method"]["newton_max_iterations"] = 7; }},
      {"method.history", "", [](Json& j) { j["method"]["history"] = "fast"; }},
      {"method.history_tolerance", "", [](Json& j) { j["method"]["history_tolerance"] = 3e-9; }},
      {"method.abs_tolerance", "", [](Json& j) { j["method"]["abs_tolerance"] = 2e-7; }},
      {"method.rel_tolerance", "", [](Json& j) { j["method"]["rel_tolerance"] = 3e-6; }},
      {"method.linear_solver", "", [](Json& j) { j["method"]["linear_solver"] = "dense"; }},
      {"method.load", "", [](Json& j) { j["method"]["load"] = "moments"; }},
      {"method.split", "", [](Json& j) { j["method"]["split"] = "series"; }},
      {"method.error_estimate", "", [](Json& j) { j["method"]["error_estimate"] = "none"; }},
      {"method.mirror", "", [](Json& j) { j["method"]["mirror"] = "off"; }},
      {"method.tolerance", "", [](Json& j) { j["method"]["tolerance"] = 1e-5; }},
      {"method.max_steps", "", [](Json& j) { j["method"]["max_steps"] = 123456; }},
      {"method.threads", "", [](Json& j) { j["method"]["threads"] = 3; }},
      {"method.flush_subnormals", "", [](Json& j) { j["method"]["flush_subnormals"] = false; }},
      {"output.every", "", [](Json& j) { j["output"]["every"] = 5; }},
      {"output.checkpoint_every", "", [](Json& j) { j["output"]["checkpoint_every"] = 250; }},
      {"output.format", "", [](Json& j) { j["output"]["format"] = "npz"; }},
      {"output.times", "",
       [](Json& j) {
         j["output"]["times"] = {0.1, 1.0 / 3.0, 1.0};
       }},
      {"events", "",
       [](Json& j) {
         j["events"] = Json::array({{{"name", "a"}, {"g", "x1"}}, {{"name", "b"}, {"g", "v2"}}});
       }},
      {"events.name", "events",
       [](Json& j) {
         j["events"] = Json::array({{{"name", "zero crossing"}, {"g", "x1"}}});
       }},
      {"events.g", "events",
       [](Json& j) {
         j["events"] = Json::array({{{"name", "g"}, {"g", "x1 - 0.5*sin(t) + v2/3"}}});
       }},
      {"events.direction", "events",
       [](Json& j) {
         j["events"] = Json::array({{{"name", "up"}, {"g", "x1"}, {"direction", "rising"}}});
       }},
      {"events.terminal", "events",
       [](Json& j) {
         j["events"] = Json::array({{{"name", "stop"}, {"g", "x1"}, {"terminal", true}}});
       }},
      {"reference.position", "",
       [](Json& j) {
         j["reference"]["position"] = {"cos(t)", "0"};
       }},
  };
  return all;
}

std::string path_of(const ProblemField& f) {
  return f.section.empty() ? f.key : f.section + "." + f.key;
}

TEST(ProblemWriters, EveryFieldHasARoundTripCase) {
  std::set<std::string> covered;
  for (const Case& c : cases()) covered.insert(c.field);
  for (const ProblemField& f : fracvi::problem_schema()) {
    if (f.type == "table") continue;  // a section: its keys are the fields
    EXPECT_EQ(covered.count(path_of(f)), 1u)
        << path_of(f) << " has no case in the round-trip test: add a non-default value";
    covered.erase(path_of(f));
  }
  EXPECT_TRUE(covered.empty()) << "cases for fields the schema lacks: " << *covered.begin();
}

TEST(ProblemWriters, ProblemTomlWritesEveryFieldAndReadsBackIdentically) {
  const fracvi::ProblemSpec base = fracvi::parse_problem_json(base_problem(), "<base>");
  // The base problem itself round-trips.
  EXPECT_EQ(joined(differences(fracvi::parse_problem(fracvi::to_toml(base), "<rt>"), base)), "");
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.field);
    Json document = base_problem();
    c.edit(document);
    const fracvi::ProblemSpec spec = fracvi::parse_problem_json(document, "<case>");
    // The case sets a value the base does not have (else the round trip below proves nothing).
    EXPECT_FALSE(differences(spec, base).empty()) << "the case changes nothing";

    const std::string text = fracvi::to_toml(spec);
    const toml::table written = toml::parse(text);
    const std::string key = c.written.empty() ? c.field : c.written;
    EXPECT_TRUE(written.at_path(key)) << key << " is not in the written problem.toml:\n" << text;

    const fracvi::ProblemSpec back = fracvi::parse_problem(text, "problem.toml");
    EXPECT_EQ(joined(differences(back, spec)), "") << "differ after the round trip:\n" << text;
    // The JSON form (summary.json, Python's to_dict) is the same document and reads back too.
    const Json json = fracvi::to_json(spec);
    EXPECT_EQ(joined(differences(fracvi::parse_problem_json(json, "summary.json"), spec)), "");
  }
}

// The writers write the fields the schema's write functions give, and nothing else: every key of
// the written document is a schema field.
TEST(ProblemWriters, WrittenKeysAreSchemaFields) {
  for (const Case& c : cases()) {
    Json document = base_problem();
    c.edit(document);
    const Json json = fracvi::to_json(fracvi::parse_problem_json(document, "<case>"));
    for (const auto& [section, table] : json.items()) {
      if (!table.is_object()) {
        EXPECT_NE(fracvi::find_field("", section), nullptr) << section;
        if (table.is_array()) {  // [[events]]: the keys of each table
          for (const auto& element : table) {
            if (!element.is_object()) continue;
            for (const auto& [key, unused] : element.items())
              EXPECT_NE(fracvi::find_field(section, key), nullptr) << section << "." << key;
          }
        }
        continue;
      }
      for (const auto& [key, value] : table.items()) {
        EXPECT_NE(fracvi::find_field(section, key), nullptr) << section << "." << key;
        if (value.is_object()) {
          for (const auto& [sub, unused] : value.items())
            EXPECT_NE(fracvi::find_field(section + "." + key, sub), nullptr) << sub;
        }
      }
    }
  }
}

// --set goes through the schema: an unknown key names --set, the key and the valid keys; a value
// of the wrong type names the field, the value and the rule.
TEST(ProblemWriters, SetOverridesAreCheckedAgainstTheSchema) {
  const std::string base(fracvi::default_problem_toml());
  const auto message = [&base](const std::string& assignment) {
    const std::vector<std::string> overrides{assignment};
    try {
      (void)fracvi::parse_problem(base, "<built-in>", overrides);
    } catch (const fracvi::ProblemFileError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(
      message("method.newton_tolerence=1e-9"),
      "<built-in>: --set method.newton_tolerence: unknown key (did you mean 'newton_tolerance'?); "
      "valid in [method]: scheme, newton_tolerance, newton_max_iterations, history, "
      "history_tolerance, abs_tolerance, rel_tolerance, linear_solver, load, split, "
      "error_estimate, mirror, tolerance, max_steps, threads, flush_subnormals");
  EXPECT_EQ(message("output.every.n=1"),
            "<built-in>: --set output.every.n: unknown section [output.every]; valid sections: "
            "[model], [model.chain], [initial], [boundary], [time], [method], [output], "
            "[reference], [events]");
  EXPECT_NE(message("nme=x").find("--set nme: unknown key (did you mean 'name'?); valid at the "
                                  "top level: name, model"),
            std::string::npos)
      << message("nme=x");
  EXPECT_EQ(message("time.steps=many"),
            "<built-in>: time.steps = 'many' must be an integer, got a string");
  EXPECT_EQ(message("method.threads=1.5"),
            "<built-in>: method.threads = 1.5 must be an integer, got a number");
  EXPECT_EQ(message("method.scheme=[1]"),
            "<built-in>: method.scheme = [ 1 ] must be a string, got an array");
  // A key of a sub-table is a field (the built-in problem then has potential and chain: the
  // reader's rule, not the schema's).
  EXPECT_EQ(message("model.chain.quartic=2"),
            "<built-in>: model.potential and model.chain are both given; give one (model.chain is "
            "the built-in FPUT chain potential, model.potential a formula)");
}

}  // namespace
