#include "fracvi/io/problem_file.hpp"

#include <toml++/toml.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "fracvi/expression/expression.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/model/expression_potential.hpp"

namespace fracvi {

namespace {

// The schema: section → allowed keys. "" is the top level.
const std::map<std::string, std::vector<std::string>>& schema() {
  static const std::map<std::string, std::vector<std::string>> s{
      {"", {"name", "model", "initial", "boundary", "time", "method", "output", "reference"}},
      {"model",
       {"dim", "mass", "damping", "alpha", "damping_order", "convention", "potential", "force",
        "lagrangian"}},
      {"initial", {"position", "velocity"}},
      {"boundary", {"start", "end"}},
      {"time", {"start", "end", "steps", "step"}},
      {"method",
       {"scheme", "newton_tolerance", "newton_max_iterations", "history", "history_tolerance"}},
      {"output", {"every"}},
      {"reference", {"position"}},
  };
  return s;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string suggestion(std::string_view wrong, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, wrong.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(wrong, c);
    if (d < best_d) best_d = d, best = c;
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

std::string format_value(double v, int digits = 17) {
  std::ostringstream os;
  os.precision(digits);
  os << v;
  return os.str();
}

// Reads and checks one problem; `fail` builds the one-line messages.
class Reader {
 public:
  Reader(const toml::table& root, std::string source) : root_(root), source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    // "key = value is ..." and "key and other ..." read on; everything else is "key: rule".
    const bool continues = what.rfind("= ", 0) == 0 || what.rfind("and ", 0) == 0;
    throw ProblemFileError(source_ + ": " + key + (continues ? " " : ": ") + what);
  }

  void check_unknown_keys() const {
    const auto& s = schema();
    for (auto&& [k, v] : root_) {
      const std::string key(k.str());
      const auto& top = s.at("");
      if (std::find(top.begin(), top.end(), key) == top.end()) {
        fail(key, "unknown key or section" + suggestion(key, top) +
                      "; valid: name, [model], [initial], [boundary], [time], [method], [output], "
                      "[reference]");
      }
      if (key == "name") continue;
      if (!v.is_table()) fail(key, "must be a section [" + key + "], not a value");
      const auto& allowed = s.at(key);
      for (auto&& [k2, v2] : *v.as_table()) {
        const std::string sub(k2.str());
        if (std::find(allowed.begin(), allowed.end(), sub) == allowed.end()) {
          std::string valid;
          for (const auto& a : allowed) valid += (valid.empty() ? "" : ", ") + a;
          fail(key + "." + sub,
               "unknown key" + suggestion(sub, allowed) + "; valid in [" + key + "]: " + valid);
        }
      }
    }
  }

  const toml::node* find(const std::string& section, const std::string& key) const {
    if (section.empty()) return root_.get(key);
    const toml::node* sec = root_.get(section);
    return sec && sec->is_table() ? sec->as_table()->get(key) : nullptr;
  }
  static std::string path(const std::string& section, const std::string& key) {
    return section.empty() ? key : section + "." + key;
  }
  const toml::node& required(const std::string& section, const std::string& key,
                             const std::string& what) const {
    const toml::node* n = find(section, key);
    if (!n) fail(path(section, key), "missing (" + what + ")");
    return *n;
  }

  double number(const toml::node& n, const std::string& key) const {
    if (!n.is_number()) fail(key, "must be a number, got " + type_name(n));
    const double v = *n.value<double>();
    if (!std::isfinite(v)) fail(key, "= " + format_value(v) + " must be finite");
    return v;
  }
  long long integer(const toml::node& n, const std::string& key) const {
    if (!n.is_integer()) fail(key, "must be an integer, got " + type_name(n));
    return *n.value<long long>();
  }
  std::string string(const toml::node& n, const std::string& key) const {
    if (!n.is_string()) fail(key, "must be a string, got " + type_name(n));
    return *n.value<std::string>();
  }
  Eigen::VectorXd vector(const toml::node& n, const std::string& key, Eigen::Index d) const {
    if (!n.is_array()) fail(key, "must be an array of " + std::to_string(d) + " numbers");
    const auto& a = *n.as_array();
    if (static_cast<Eigen::Index>(a.size()) != d) {
      fail(key, "has " + std::to_string(a.size()) + " entries, model.dim is " + std::to_string(d));
    }
    Eigen::VectorXd v(d);
    for (Eigen::Index i = 0; i < d; ++i)
      v[i] = number(a[static_cast<std::size_t>(i)], key + "[" + std::to_string(i + 1) + "]");
    return v;
  }
  // Scalar (times I), vector (diagonal) or d×d matrix (array of rows).
  Eigen::MatrixXd matrix(const toml::node& n, const std::string& key, Eigen::Index d) const {
    if (n.is_number()) return number(n, key) * Eigen::MatrixXd::Identity(d, d);
    if (!n.is_array()) fail(key, "must be a number, an array of d numbers or a d×d array");
    const auto& a = *n.as_array();
    if (!a.empty() && a[0].is_array()) {
      if (static_cast<Eigen::Index>(a.size()) != d) {
        fail(key, "has " + std::to_string(a.size()) + " rows, model.dim is " + std::to_string(d));
      }
      Eigen::MatrixXd m(d, d);
      for (Eigen::Index i = 0; i < d; ++i) {
        m.row(i) =
            vector(a[static_cast<std::size_t>(i)], key + "[" + std::to_string(i + 1) + "]", d)
                .transpose();
      }
      return m;
    }
    return vector(n, key, d).asDiagonal();
  }

  static std::string type_name(const toml::node& n) {
    switch (n.type()) {
      case toml::node_type::string: return "a string";
      case toml::node_type::integer: return "an integer";
      case toml::node_type::floating_point: return "a number";
      case toml::node_type::boolean: return "a boolean";
      case toml::node_type::array: return "an array";
      case toml::node_type::table: return "a table";
      default: return "a date/time";
    }
  }

 private:
  const toml::table& root_;
  std::string source_;
};

void check_expression(const Reader& r, const std::string& key, const std::string& text,
                      const std::vector<std::string>& variables) {
  try {
    Expression::parse(text, variables);
  } catch (const ExpressionError& e) {
    r.fail(key, "\"" + text + "\": " + e.reason() + " at column " + std::to_string(e.column() + 1));
  }
}

// Symmetric to round-off, relative to the largest entry.
bool is_symmetric(const Eigen::MatrixXd& m) {
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  return (m - m.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * scale;
}

void apply_override(toml::table& root, const std::string& assignment, const std::string& source) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ProblemFileError(source + ": --set '" + assignment +
                           "' must have the form section.key=value");
  }
  const std::string path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  // The value as TOML if it is one, else as a plain string.
  toml::table parsed;
  bool is_toml = true;
  try {
    parsed = toml::parse("v = " + text);
  } catch (const toml::parse_error&) {
    is_toml = false;
  }
  const auto dot = path.find('.');
  toml::table* target = &root;
  std::string key = path;
  if (dot != std::string::npos) {
    const std::string section = path.substr(0, dot);
    key = path.substr(dot + 1);
    if (!root.contains(section)) root.insert(section, toml::table{});
    target = root.get_as<toml::table>(section);
    if (!target) {
      throw ProblemFileError(source + ": --set " + path + ": '" + section + "' is not a section");
    }
  }
  if (is_toml) {
    target->insert_or_assign(key, *parsed.get("v"));
  } else {
    target->insert_or_assign(key, text);
  }
}

ProblemSpec read(const toml::table& root, const std::string& source) {
  Reader r(root, source);
  r.check_unknown_keys();
  ProblemSpec p;
  p.source = source;
  if (const auto* n = r.find("", "name")) p.name = r.string(*n, "name");
  if (p.name.empty() || p.name.find_first_of("/\\") != std::string::npos || p.name == "." ||
      p.name == "..") {
    r.fail("name", "= \"" + p.name + "\" must be a non-empty name without slashes");
  }

  // [model]
  const long long dim = r.integer(r.required("model", "dim", "the dimension d"), "model.dim");
  if (dim < 1) r.fail("model.dim", "= " + std::to_string(dim) + " must be at least 1");
  p.dim = static_cast<Eigen::Index>(dim);
  // A general Lagrangian replaces the mechanical fields (mass, damping, potential, force).
  const auto* lagrangian = r.find("model", "lagrangian");
  if (lagrangian) {
    p.lagrangian = r.string(*lagrangian, "model.lagrangian");
    for (const char* key : {"mass", "damping", "potential", "force"}) {
      if (r.find("model", key)) {
        r.fail(std::string("model.") + key,
               "cannot be combined with model.lagrangian (the Lagrangian already holds the "
               "kinetic energy, the potential and the memory coupling; give one or the other)");
      }
    }
    check_expression(r, "model.lagrangian", p.lagrangian,
                     ExpressionLagrangian::variable_names(p.dim));
  } else {
    p.mass = r.matrix(r.required("model", "mass", "the mass matrix M"), "model.mass", p.dim);
    if (!is_symmetric(p.mass)) r.fail("model.mass", "is not symmetric");
    Eigen::LLT<Eigen::MatrixXd> llt(p.mass);
    if (llt.info() != Eigen::Success) {
      const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(p.mass).eigenvalues()[0];
      r.fail("model.mass", "is not symmetric positive definite (smallest eigenvalue " +
                               format_value(lmin, 6) + ")");
    }
  }
  p.damping = Eigen::MatrixXd::Zero(p.dim, p.dim);
  if (const auto* n = r.find("model", "damping")) p.damping = r.matrix(*n, "model.damping", p.dim);
  if (!is_symmetric(p.damping)) r.fail("model.damping", "is not symmetric");
  {
    const double lmin =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(p.damping).eigenvalues().minCoeff();
    const double scale = std::max(1.0, p.damping.cwiseAbs().maxCoeff());
    if (lmin < -1e-12 * scale) {
      r.fail("model.damping",
             "is not positive semidefinite (smallest eigenvalue " + format_value(lmin, 6) + ")");
    }
  }
  const auto* alpha = r.find("model", "alpha");
  const auto* order = r.find("model", "damping_order");
  if (alpha && order) {
    r.fail("model.alpha",
           "and model.damping_order are both given; give one (damping_order = 2*alpha)");
  }
  if (!alpha && !order) {
    r.fail("model.alpha",
           "missing (the Lagrangian order in [0, 1]; or give model.damping_order "
           "= 2*alpha in [0, 2])");
  }
  if (alpha) {
    p.alpha = r.number(*alpha, "model.alpha");
    if (p.alpha < 0.0 || p.alpha > 1.0) {
      r.fail("model.alpha", "= " + format_value(p.alpha) +
                                " is outside [0, 1] (alpha is the Lagrangian order; the damping "
                                "order is 2*alpha)");
    }
  } else {
    const double beta = r.number(*order, "model.damping_order");
    if (beta < 0.0 || beta > 2.0) {
      r.fail("model.damping_order",
             "= " + format_value(beta) + " is outside [0, 2] (damping_order = 2*alpha)");
    }
    p.alpha = beta / 2.0;
  }
  if (const auto* n = r.find("model", "convention")) {
    p.convention = r.string(*n, "model.convention");
    if (p.convention != "caputo" && p.convention != "riemann-liouville") {
      r.fail("model.convention", "= \"" + p.convention +
                                     "\" must be \"caputo\" or \"riemann-liouville\"" +
                                     suggestion(p.convention, {"caputo", "riemann-liouville"}));
    }
  } else if (!(p.damping.isZero(0.0) || p.alpha == 0.5)) {
    r.fail("model.convention",
           "missing: fractional damping needs an explicit memory convention, \"caputo\" (memory "
           "of x - x(0) - t v(0)) or \"riemann-liouville\" (the paper's)");
  }
  if (lagrangian) {
    if (r.find("model", "convention") && p.convention != "riemann-liouville") {
      r.fail("model.convention",
             "= \"" + p.convention +
                 "\" is not available with model.lagrangian: a general Lagrangian is a function "
                 "of the paper's Riemann-Liouville derivatives dx = D^alpha_- x, dy = D^alpha_+ y "
                 "(give \"riemann-liouville\" or leave the key out)");
    }
    p.convention = "riemann-liouville";
  }
  auto names = ExpressionPotential::position_names(p.dim);
  names.push_back("t");
  if (!lagrangian) {
    p.potential = r.string(r.required("model", "potential", "U as a formula in x1..xd and t"),
                           "model.potential");
    check_expression(r, "model.potential", p.potential, names);
  }
  if (const auto* n = r.find("model", "force")) {
    if (!n->is_array()) r.fail("model.force", "must be an array of d formulas in t");
    const auto& a = *n->as_array();
    if (!a.empty() && static_cast<Eigen::Index>(a.size()) != p.dim) {  // [] means no force
      r.fail("model.force", "has " + std::to_string(a.size()) + " components, model.dim is " +
                                std::to_string(p.dim));
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string key = "model.force[" + std::to_string(i + 1) + "]";
      p.force.push_back(r.string(a[i], key));
      check_expression(r, key, p.force.back(), {"t"});
    }
  }

  // [initial] (optional when the file poses a boundary value problem)
  const bool has_boundary = r.find("", "boundary") != nullptr;
  if (!has_boundary || r.find("initial", "position") != nullptr)
    p.position = r.vector(r.required("initial", "position", "x(0)"), "initial.position", p.dim);
  p.velocity = Eigen::VectorXd::Zero(p.dim);
  if (const auto* n = r.find("initial", "velocity"))
    p.velocity = r.vector(*n, "initial.velocity", p.dim);
  if (p.convention == "riemann-liouville" && 2.0 * p.alpha > 1.0 && !p.position.isZero(0.0) &&
      !p.damping.isZero(0.0)) {
    r.fail("model.convention",
           "\"riemann-liouville\" with damping order 2*alpha = " + format_value(2.0 * p.alpha) +
               " > 1 and initial.position != 0 is ill-posed: the Riemann-Liouville damping "
               "force of the constant x(0) behaves like t^(-2 alpha) and is not integrable; use "
               "convention = \"caputo\" (memory of x - x(0) - t v(0)) or start at x(0) = 0");
  }

  // [boundary]: x(a) = start = y(b), x(b) = end = y(a) (`fracvi bvp`)
  if (has_boundary) {
    p.boundary_start =
        r.vector(r.required("boundary", "start", "x(a) = y(b)"), "boundary.start", p.dim);
    p.boundary_end = r.vector(r.required("boundary", "end", "x(b) = y(a)"), "boundary.end", p.dim);
  }

  // [time]
  if (const auto* n = r.find("time", "start")) p.start = r.number(*n, "time.start");
  p.end = r.number(r.required("time", "end", "the final time"), "time.end");
  if (!(p.end > p.start)) {
    r.fail("time.end", "= " + format_value(p.end) +
                           " must be greater than time.start = " + format_value(p.start));
  }
  const auto* steps = r.find("time", "steps");
  const auto* step = r.find("time", "step");
  if (steps && step) r.fail("time.steps", "and time.step are both given; give exactly one");
  if (!steps && !step) r.fail("time.steps", "missing: give time.steps (N) or time.step (h)");
  if (steps) {
    p.steps = r.integer(*steps, "time.steps");
    if (p.steps < 1) r.fail("time.steps", "= " + std::to_string(p.steps) + " must be positive");
  } else {
    const double h = r.number(*step, "time.step");
    if (!(h > 0.0)) r.fail("time.step", "= " + format_value(h) + " must be positive");
    const double n = (p.end - p.start) / h;
    const double rounded = std::round(n);
    if (rounded < 1.0 || std::abs(n - rounded) > 1e-9 * rounded) {
      r.fail("time.step", "= " + format_value(h) + " does not divide [" + format_value(p.start) +
                              ", " + format_value(p.end) + "] into a whole number of steps");
    }
    p.steps = static_cast<long long>(rounded);
  }
  if (p.steps > 2'000'000'000LL)
    r.fail("time.steps", "= " + std::to_string(p.steps) + " is too large");

  // [method]
  if (const auto* n = r.find("method", "scheme")) {
    p.scheme = r.string(*n, "method.scheme");
    if (p.scheme != "fvi-gl") {
      r.fail("method.scheme", "= \"" + p.scheme + "\" is not a known scheme (available: fvi-gl)" +
                                  suggestion(p.scheme, {"fvi-gl"}));
    }
  }
  if (const auto* n = r.find("method", "newton_tolerance")) {
    p.newton_tolerance = r.number(*n, "method.newton_tolerance");
    if (!(p.newton_tolerance > 0.0)) {
      r.fail("method.newton_tolerance",
             "= " + format_value(p.newton_tolerance) + " must be positive");
    }
  }
  if (const auto* n = r.find("method", "newton_max_iterations")) {
    const long long it = r.integer(*n, "method.newton_max_iterations");
    if (it < 1 || it > 10000) {
      r.fail("method.newton_max_iterations", "= " + std::to_string(it) + " must be in [1, 10000]");
    }
    p.newton_max_iterations = static_cast<int>(it);
  }
  if (const auto* n = r.find("method", "history")) {
    p.history = r.string(*n, "method.history");
    if (p.history != "auto" && p.history != "direct" && p.history != "fast") {
      r.fail("method.history", "= \"" + p.history + "\" must be \"auto\", \"direct\" or \"fast\"" +
                                   suggestion(p.history, {"auto", "direct", "fast"}));
    }
  }
  if (const auto* n = r.find("method", "history_tolerance")) {
    p.history_tolerance = r.number(*n, "method.history_tolerance");
    if (!(p.history_tolerance >= 1e-13 && p.history_tolerance <= 1e-3)) {
      r.fail("method.history_tolerance", "= " + format_value(p.history_tolerance) +
                                             " must be in [1e-13, 1e-3] (per-weight relative "
                                             "accuracy of the fast history)");
    }
  }
  // [output]
  if (const auto* n = r.find("output", "every")) {
    p.every = r.integer(*n, "output.every");
    if (p.every < 1) r.fail("output.every", "= " + std::to_string(p.every) + " must be at least 1");
  }
  // [reference]
  if (const auto* n = r.find("reference", "position")) {
    if (!n->is_array()) r.fail("reference.position", "must be an array of d formulas in t");
    const auto& a = *n->as_array();
    if (static_cast<Eigen::Index>(a.size()) != p.dim) {
      r.fail("reference.position", "has " + std::to_string(a.size()) +
                                       " components, model.dim is " + std::to_string(p.dim));
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string key = "reference.position[" + std::to_string(i + 1) + "]";
      p.reference.push_back(r.string(a[i], key));
      check_expression(r, key, p.reference.back(), {"t"});
    }
  }
  return p;
}

}  // namespace

ProblemSpec parse_problem(std::string_view toml_text, const std::string& source,
                          std::span<const std::string> overrides) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    throw ProblemFileError(source + ":" + std::to_string(e.source().begin.line) + ":" +
                           std::to_string(e.source().begin.column) +
                           ": not valid TOML: " + std::string(e.description()));
  }
  for (const auto& o : overrides) apply_override(root, o, source);
  return read(root, source);
}

namespace {

toml::array to_toml_array(const nlohmann::json& a, const std::string& source,
                          const std::string& key);

// JSON → TOML, so that one reader validates both.
toml::table to_toml_table(const nlohmann::json& object, const std::string& source,
                          const std::string& prefix) {
  toml::table t;
  for (const auto& [k, v] : object.items()) {
    const std::string key = prefix.empty() ? k : prefix + "." + k;
    if (v.is_object()) {
      t.insert(k, to_toml_table(v, source, key));
    } else if (v.is_array()) {
      t.insert(k, to_toml_array(v, source, key));
    } else if (v.is_string()) {
      t.insert(k, v.get<std::string>());
    } else if (v.is_boolean()) {
      t.insert(k, v.get<bool>());
    } else if (v.is_number_integer()) {
      t.insert(k, v.get<int64_t>());
    } else if (v.is_number()) {
      t.insert(k, v.get<double>());
    } else {
      throw ProblemFileError(source + ": " + key + ": null is not a value");
    }
  }
  return t;
}

toml::array to_toml_array(const nlohmann::json& a, const std::string& source,
                          const std::string& key) {
  toml::array out;
  for (const auto& v : a) {
    if (v.is_array()) {
      out.push_back(to_toml_array(v, source, key));
    } else if (v.is_string()) {
      out.push_back(v.get<std::string>());
    } else if (v.is_number_integer()) {
      out.push_back(v.get<int64_t>());
    } else if (v.is_number()) {
      out.push_back(v.get<double>());
    } else if (v.is_boolean()) {
      out.push_back(v.get<bool>());
    } else {
      throw ProblemFileError(source + ": " + key + ": arrays hold numbers, strings or arrays");
    }
  }
  return out;
}

}  // namespace

ProblemSpec parse_problem_json(const nlohmann::json& document, const std::string& source,
                               std::span<const std::string> overrides) {
  if (!document.is_object()) throw ProblemFileError(source + ": a problem must be an object");
  toml::table root = to_toml_table(document, source, "");
  for (const auto& o : overrides) apply_override(root, o, source);
  return read(root, source);
}

ProblemSpec load_problem(const std::filesystem::path& file,
                         std::span<const std::string> overrides) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ProblemFileError(file.string() + ": cannot open the problem file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_problem(text.str(), file.string(), overrides);
}

std::string_view default_problem_toml() {
  return R"toml(# The built-in problem of `fracvi run`: a forced Duffing oscillator in a double well with
# Bagley–Torvik damping (damping order 2*alpha = 3/2, Caputo). Started on the outer slope of the
# right well, it crosses between the wells while the memory damping drains energy, then settles
# into forced oscillations.
name = "fractional-duffing"

[model]
dim = 1
mass = 1.0
damping = 0.25
alpha = 0.75
convention = "caputo"
potential = "x1^4/4 - x1^2/2"
force = ["0.3*cos(1.2*t)"]

[initial]
position = [1.5]
velocity = [0.0]

[time]
start = 0.0
end = 60.0
steps = 6000

[method]
scheme = "fvi-gl"
newton_tolerance = 1e-12
newton_max_iterations = 50
history = "auto"

[output]
every = 1
)toml";
}

namespace {
nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(row);
  }
  return rows;
}
nlohmann::json vector_json(const Eigen::VectorXd& v) {
  nlohmann::json a = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}
toml::array matrix_toml(const Eigen::MatrixXd& m) {
  toml::array rows;
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    toml::array row;
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(row);
  }
  return rows;
}
toml::array vector_toml(const Eigen::VectorXd& v) {
  toml::array a;
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}
}  // namespace

nlohmann::json to_json(const ProblemSpec& p) {
  nlohmann::json force = nlohmann::json::array();
  for (const auto& f : p.force) force.push_back(f);
  nlohmann::json j = {
      {"name", p.name},
      {"model",
       {{"dim", p.dim},
        {"mass", matrix_json(p.mass)},
        {"damping", matrix_json(p.damping)},
        {"alpha", p.alpha},
        {"convention", p.convention},
        {"potential", p.potential},
        {"force", force}}},
      {"initial", {{"position", vector_json(p.position)}, {"velocity", vector_json(p.velocity)}}},
      {"time", {{"start", p.start}, {"end", p.end}, {"steps", p.steps}}},
      {"method",
       {{"scheme", p.scheme},
        {"newton_tolerance", p.newton_tolerance},
        {"newton_max_iterations", p.newton_max_iterations},
        {"history", p.history},
        {"history_tolerance", p.history_tolerance}}},
      {"output", {{"every", p.every}}},
  };
  if (!p.reference.empty()) j["reference"] = {{"position", p.reference}};
  if (!p.lagrangian.empty()) {
    j["model"] = {{"dim", p.dim},
                  {"lagrangian", p.lagrangian},
                  {"alpha", p.alpha},
                  {"convention", p.convention}};
  }
  if (p.position.size() == 0) j.erase("initial");
  if (p.boundary_start.size() > 0) {
    j["boundary"] = {{"start", vector_json(p.boundary_start)},
                     {"end", vector_json(p.boundary_end)}};
  }
  return j;
}

std::string to_toml(const ProblemSpec& p) {
  toml::array force;
  for (const auto& f : p.force) force.push_back(f);
  toml::table model{{"dim", static_cast<int64_t>(p.dim)}, {"mass", matrix_toml(p.mass)},
                    {"damping", matrix_toml(p.damping)},  {"alpha", p.alpha},
                    {"convention", p.convention},         {"potential", p.potential}};
  if (!p.force.empty()) model.insert("force", force);
  toml::table root{
      {"name", p.name},
      {"model", model},
      {"initial",
       toml::table{{"position", vector_toml(p.position)}, {"velocity", vector_toml(p.velocity)}}},
      {"time",
       toml::table{{"start", p.start}, {"end", p.end}, {"steps", static_cast<int64_t>(p.steps)}}},
      {"method",
       toml::table{{"scheme", p.scheme},
                   {"newton_tolerance", p.newton_tolerance},
                   {"newton_max_iterations", static_cast<int64_t>(p.newton_max_iterations)},
                   {"history", p.history},
                   {"history_tolerance", p.history_tolerance}}},
      {"output", toml::table{{"every", static_cast<int64_t>(p.every)}}},
  };
  if (!p.reference.empty()) {
    toml::array ref;
    for (const auto& e : p.reference) ref.push_back(e);
    root.insert("reference", toml::table{{"position", ref}});
  }
  if (!p.lagrangian.empty()) {
    root.insert_or_assign("model", toml::table{{"dim", static_cast<int64_t>(p.dim)},
                                               {"lagrangian", p.lagrangian},
                                               {"alpha", p.alpha},
                                               {"convention", p.convention}});
  }
  if (p.position.size() == 0) root.erase("initial");
  if (p.boundary_start.size() > 0) {
    root.insert("boundary", toml::table{{"start", vector_toml(p.boundary_start)},
                                        {"end", vector_toml(p.boundary_end)}});
  }
  std::ostringstream os;
  os << root << '\n';
  return os.str();
}

}  // namespace fracvi
