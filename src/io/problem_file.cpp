#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/problem_schema.hpp"

#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/registry.hpp"

#include <toml++/toml.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "fracvi/core/memory.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/lagrangian/lagrangian.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "fracvi/solve/symmetric_factor.hpp"

namespace fracvi {

namespace {

// The largest time.steps: the step index and every count stay far inside 64 bits, and a trajectory
// of more steps would not be stored anyway (the memory check of the Integrator).
constexpr long long kMaxSteps = 2'000'000'000LL;

// The schema: section → allowed keys, from the one table of io/problem_schema.hpp. "" is the top
// level; "model.chain" is a table in [model].
const std::map<std::string, std::vector<std::string>>& schema() {
  static const std::map<std::string, std::vector<std::string>> s = [] {
    std::map<std::string, std::vector<std::string>> m;
    for (const ProblemField& f : problem_schema()) m[f.section].push_back(f.key);
    return m;
  }();
  return s;
}

std::string joined(const std::vector<std::string>& names, const char* separator = ", ") {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : separator) + n;
  return out;
}

// The value as given: the shortest text that reads back as the same double (-0.2, not
// -0.20000000000000001); `digits` significant digits otherwise.
std::string format_value(double v, int digits = 0) {
  if (digits == 0) return format_number(v);
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
        std::vector<std::string> valid;
        for (const std::string& name : top)
          if (!is_schema_section(name)) valid.push_back(name);
        for (const std::string& name : schema_section_names())
          if (name.find('.') == std::string::npos) valid.push_back(name);
        fail(key, "unknown key or section" + did_you_mean(key, top) + "; valid: " + joined(valid));
      }
      if (key == "name") continue;
      if (key == "events") {
        if (!v.is_array() || !(v.as_array()->empty() || v.is_array_of_tables())) {
          fail(key,
               "must be an array of tables [[events]] (name, g, direction, terminal), not a "
               "single value or table");
        }
        const auto& a = *v.as_array();
        for (std::size_t i = 0; i < a.size(); ++i) {
          check_table_keys(*a[i].as_table(), "events", "events[" + std::to_string(i + 1) + "]");
        }
        continue;
      }
      if (!v.is_table()) fail(key, "must be a section [" + key + "], not a value");
      check_table_keys(*v.as_table(), key);
    }
  }

  // The keys of section `path` (and of its sub-tables that have a schema, e.g. [model.chain]).
  // `shown` names the table in messages (events[2] for the second [[events]]).
  void check_table_keys(const toml::table& table, const std::string& path,
                        const std::string& shown = "") const {
    const auto& s = schema();
    const auto& allowed = s.at(path);
    for (auto&& [k, v] : table) {
      const std::string sub(k.str());
      if (std::find(allowed.begin(), allowed.end(), sub) == allowed.end()) {
        fail((shown.empty() ? path : shown) + "." + sub,
             "unknown key" + did_you_mean(sub, allowed) + "; valid in [" + path +
                 "]: " + joined(allowed));
      }
      if (v.is_table() && s.count(path + "." + sub) != 0) {
        check_table_keys(*v.as_table(), path + "." + sub);
      }
    }
  }

  // `section` may be a dotted path of tables ("model.chain").
  const toml::node* find(const std::string& section, const std::string& key) const {
    const toml::table* table = &root_;
    std::size_t from = 0;
    while (!section.empty() && from <= section.size()) {
      const std::size_t dot = std::min(section.find('.', from), section.size());
      const toml::node* sub = table->get(section.substr(from, dot - from));
      if (!sub || !sub->is_table()) return nullptr;
      table = sub->as_table();
      from = dot + 1;
    }
    return table->get(key);
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
    if (!n.is_number()) fail(key, value_text(n) + "must be a number, got " + type_name(n));
    if (const auto* i = n.as_integer()) return exact_double(i->get(), key);
    const double v = n.as_floating_point()->get();
    if (!std::isfinite(v)) fail(key, "= " + format_value(v) + " must be finite");
    return v;
  }
  // An integer where a number is expected, converted only when the double holds it exactly:
  // toml++'s value<double>() is empty beyond ±2^53 (and reading it anyway gave R = 6.95e-310 for
  // damping = 1e17 written as an integer), and silently rounding would make the file say
  // something the run does not do. 10^17 is exact (= 2^17·5^17); 2^53 + 1 is not.
  double exact_double(std::int64_t value, const std::string& key) const {
    const double v = static_cast<double>(value);
    // v is within [−2^63, 2^63]; 2^63 itself is not an int64, so compare before converting back.
    const bool exact = v < 0x1p63 && static_cast<std::int64_t>(v) == value;
    if (!exact) {
      const std::string digits = std::to_string(value);
      const std::size_t sign = value < 0 ? 1 : 0;
      const std::string as_float = digits.substr(0, sign + 1) + "." + digits.substr(sign + 1) +
                                   "e" + std::to_string(digits.size() - sign - 1);
      fail(key, "= " + digits +
                    ": integers beyond 2^53 are not exactly representable as a double; write it "
                    "as a float, e.g. " +
                    as_float + " (rounded to the nearest double, " + format_value(v) + ")");
    }
    return v;
  }
  long long integer(const toml::node& n, const std::string& key) const {
    if (!n.is_integer()) fail(key, value_text(n) + "must be an integer, got " + type_name(n));
    return *n.value<long long>();
  }
  bool boolean(const toml::node& n, const std::string& key) const {
    if (!n.is_boolean()) fail(key, value_text(n) + "must be true or false, got " + type_name(n));
    return *n.value<bool>();
  }
  std::string string(const toml::node& n, const std::string& key) const {
    if (!n.is_string()) fail(key, value_text(n) + "must be a string, got " + type_name(n));
    return *n.value<std::string>();
  }
  Eigen::VectorXd vector(const toml::node& n, const std::string& key, Eigen::Index d) const {
    if (!n.is_array()) {
      fail(key, "must be an array of " + std::to_string(d) + " numbers, got " + type_name(n));
    }
    const auto& a = *n.as_array();
    if (static_cast<Eigen::Index>(a.size()) != d) {
      fail(key, "has " + std::to_string(a.size()) + " entries, model.dim is " + std::to_string(d));
    }
    Eigen::VectorXd v(d);
    for (Eigen::Index i = 0; i < d; ++i)
      v[i] = number(a[static_cast<std::size_t>(i)], key + "[" + std::to_string(i + 1) + "]");
    return v;
  }
  // Scalar (times I) or vector (diagonal), both stored sparse, or a d×d matrix (array of rows),
  // stored dense. `definite`: M (entries > 0, positive definite) or R (entries >= 0, positive
  // semidefinite). A diagonal is checked entry by entry, never expanded.
  ModelMatrix matrix(const toml::node& n, const std::string& key, Eigen::Index d,
                     bool definite) const {
    const char* rule = definite ? " must be positive (M must be positive definite)"
                                : " must not be negative (R must be positive semidefinite)";
    const auto bad = [definite](double v) { return definite ? !(v > 0.0) : v < 0.0; };
    if (n.is_number()) {
      const double v = number(n, key);
      if (bad(v)) fail(key, "= " + format_value(v) + rule);
      return ModelMatrix::identity(d, v);
    }
    if (!n.is_array()) {
      fail(key, "must be a number, an array of d numbers or a d×d array, got " + type_name(n));
    }
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
    const Eigen::VectorXd v = vector(n, key, d);
    for (Eigen::Index i = 0; i < d; ++i) {
      if (bad(v[i]))
        fail(key + "[" + std::to_string(i + 1) + "]", "= " + format_value(v[i]) + rule);
    }
    return ModelMatrix::diagonal(v);
  }

  // [initial] data: an array of d numbers, one number for every coordinate, or a formula in
  // i (1-based coordinate index), d and pi. `formula` receives the formula ("" otherwise).
  Eigen::VectorXd initial_vector(const toml::node& n, const std::string& key, Eigen::Index d,
                                 std::string& formula) const {
    formula.clear();
    if (n.is_number()) return Eigen::VectorXd::Constant(d, number(n, key));
    if (n.is_string()) {
      formula = *n.value<std::string>();
      Expression e;
      try {
        e = Expression::parse(formula, {"i", "d"});
      } catch (const ExpressionError& err) {
        fail(key, "= \"" + formula + "\": " + err.reason() + " at column " +
                      std::to_string(err.column() + 1) + " (a formula in i = 1..d, d and pi)");
      }
      Eigen::VectorXd v(d);
      const double dd = static_cast<double>(d);
      for (Eigen::Index i = 0; i < d; ++i) {
        v[i] = e({static_cast<double>(i + 1), dd});
        if (!std::isfinite(v[i])) {
          fail(key, "= \"" + formula + "\" is " + format_value(v[i]) +
                        " at i = " + std::to_string(i + 1) + " (initial data must be finite)");
        }
      }
      return v;
    }
    if (!n.is_array()) {
      fail(key, "must be an array of " + std::to_string(d) +
                    " numbers, one number or a formula in i and d (a string), got " + type_name(n));
    }
    return vector(n, key, d);
  }

  // "= <value> " for the message of a value of the wrong type (scalars and short arrays as TOML
  // writes them), "" for a table or a long array; fail() then reads "key = value must be …".
  static std::string value_text(const toml::node& n) {
    if (n.is_table()) return "";
    std::ostringstream os;
    n.visit([&os](const auto& v) { os << v; });
    const std::string text = os.str();
    if (text.size() > 60 || text.find('\n') != std::string::npos) return "";
    return "= " + text + " ";
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

// Symmetric to round-off (the rule of validate(): fracvi::roundoff_tolerance).
bool is_symmetric(const Eigen::MatrixXd& m) {
  return (m - m.transpose()).cwiseAbs().maxCoeff() <=
         roundoff_tolerance(m.rows(), m.cwiseAbs().maxCoeff());
}

// The dense-storage checks (the sparse forms are diagonals checked entry by entry by the reader).
void check_dense_mass(const Reader& r, const Eigen::MatrixXd& m) {
  if (!is_symmetric(m)) r.fail("model.mass", "is not symmetric");
  Eigen::LLT<Eigen::MatrixXd> llt(m);
  if (llt.info() != Eigen::Success) {
    const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).eigenvalues()[0];
    r.fail("model.mass", "is not symmetric positive definite (smallest eigenvalue " +
                             format_value(lmin, 6) + ")");
  }
}

void check_dense_damping(const Reader& r, const Eigen::MatrixXd& m) {
  if (!is_symmetric(m)) r.fail("model.damping", "is not symmetric");
  const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).eigenvalues().minCoeff();
  if (lmin < -roundoff_tolerance(m.rows(), m.cwiseAbs().maxCoeff())) {
    r.fail("model.damping",
           "is not positive semidefinite (smallest eigenvalue " + format_value(lmin, 6) + ")");
  }
}

// [model.chain]: the built-in FPUT chain with d = model.dim masses.
ChainOptions read_chain(const Reader& r, const toml::node& node, Eigen::Index d) {
  if (!node.is_table()) {
    r.fail("model.chain",
           "must be a table [model.chain] (keys stiffness, cubic, quartic, onsite, "
           "boundary), got " +
               Reader::type_name(node));
  }
  ChainOptions c;
  c.dimension = d;
  if (const auto* n = r.find("model.chain", "stiffness"))
    c.stiffness = r.number(*n, "model.chain.stiffness");
  if (const auto* n = r.find("model.chain", "cubic")) c.cubic = r.number(*n, "model.chain.cubic");
  if (const auto* n = r.find("model.chain", "quartic"))
    c.quartic = r.number(*n, "model.chain.quartic");
  if (const auto* n = r.find("model.chain", "onsite"))
    c.onsite = r.number(*n, "model.chain.onsite");
  if (const auto* n = r.find("model.chain", "boundary")) {
    const std::string b = r.string(*n, "model.chain.boundary");
    const auto parsed = parse_chain_boundary(b);
    if (!parsed) {
      r.fail("model.chain.boundary", "= \"" + b + "\" is not one of fixed, free, periodic" +
                                         did_you_mean(b, {"fixed", "free", "periodic"}));
    }
    c.boundary = *parsed;
  }
  const Eigen::Index minimum = c.boundary == ChainBoundary::kPeriodic ? 3
                               : c.boundary == ChainBoundary::kFree   ? 2
                                                                      : 1;
  if (d < minimum) {
    r.fail("model.dim", "= " + std::to_string(d) + " is too small for model.chain.boundary = \"" +
                            std::string(to_string(c.boundary)) + "\": it needs at least " +
                            std::to_string(minimum) + " masses");
  }
  return c;
}

void apply_override(toml::table& root, const std::string& assignment, const std::string& source) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ProblemFileError(source + ": --set '" + assignment +
                           "' must have the form section.key=value");
  }
  const std::string path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  // The key through the schema before anything is changed, so that a typo names --set.
  if (const std::string unknown = unknown_field_message(path); !unknown.empty()) {
    throw ProblemFileError(source + ": --set " + unknown);
  }
  // The value as TOML if it is one, else as a plain string.
  toml::table parsed;
  bool is_toml = true;
  try {
    parsed = toml::parse("v = " + text);
  } catch (const toml::parse_error&) {
    is_toml = false;
  }
  // section.key, or section.table.key ([model.chain]): every part before the last is a table.
  toml::table* target = &root;
  std::string key = path;
  for (auto dot = key.find('.'); dot != std::string::npos; dot = key.find('.')) {
    const std::string section = key.substr(0, dot);
    key = key.substr(dot + 1);
    if (!target->contains(section)) target->insert(section, toml::table{});
    target = target->get_as<toml::table>(section);
    if (!target) {
      throw ProblemFileError(source + ": --set " + path + ": '" + section + "' is not a section");
    }
  }
  if (is_toml) {
    target->insert_or_assign(key, *parsed.get("v"));
  } else {
    target->insert_or_assign(key, text);
  }
  // model.alpha and model.damping_order are one field in two spellings (damping_order = 2α): an
  // override of one replaces the other, as it replaces its own earlier value.
  if (path == "model.alpha") target->erase("damping_order");
  if (path == "model.damping_order") target->erase("alpha");
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
  // Every run stores at least two states (x and v, 16 bytes per coordinate each), besides the
  // vectors of the problem: refuse a dimension that cannot fit before allocating any of them.
  const double state_bytes = 32.0 * static_cast<double>(dim);
  if (const std::size_t memory = physical_memory_bytes();
      memory != 0 && state_bytes > static_cast<double>(memory)) {
    r.fail("model.dim", "= " + std::to_string(dim) +
                            ": the first and last state alone (x and v) need " +
                            format_bytes(state_bytes) + ", more than this machine's memory (" +
                            format_bytes(static_cast<double>(memory)) + ")");
  }
  p.dim = static_cast<Eigen::Index>(dim);
  // f(t) first: it needs only d, and a mismatch must be found before the d-sized work below (the
  // potential's d variable names, the matrices: 27 s for d = 10^7 when it came last).
  if (const auto* n = r.find("model", "force")) {
    if (!n->is_array()) {
      r.fail("model.force", "must be an array of d formulas in t, x1..xd and v1..vd");
    }
    const auto& a = *n->as_array();
    if (const auto* label = a.empty() ? nullptr : a[0].as_string();
        label != nullptr && label->get().starts_with(kPythonFunctionPrefix)) {
      // What a run from Python with force=<function> records (ProblemSpec::force_object).
      r.fail("model.force",
             "= [\"" + label->get() +
                 "\"] names Python functions, which a problem file cannot call: give the force "
                 "as d formulas in t, x1..xd and v1..vd, or read this problem from Python "
                 "(fracvi.load and fracvi.Problem.from_dict import the functions again when they "
                 "are importable)");
    }
    if (!a.empty() && static_cast<Eigen::Index>(a.size()) != p.dim) {  // [] means no force
      r.fail("model.force", "has " + std::to_string(a.size()) + " components, model.dim is " +
                                std::to_string(p.dim));
    }
    // Formulas in t alone are f(t); any mention of x or v makes the force g(x, v, t)
    // (make_expression_forces). The names x1..xd, v1..vd are built only when a formula is not in t
    // alone, so a large model with f(t) pays nothing for them.
    std::vector<std::string> state_names;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string key = "model.force[" + std::to_string(i + 1) + "]";
      p.force.push_back(r.string(a[i], key));
      try {
        Expression::parse(p.force.back(), {"t"});
      } catch (const ExpressionError&) {
        if (state_names.empty()) state_names = ExpressionForce::variable_names(p.dim);
        check_expression(r, key, p.force.back(), state_names);
      }
    }
  }
  // A general Lagrangian replaces the mechanical fields (mass, damping, potential, force).
  const auto* lagrangian = r.find("model", "lagrangian");
  if (lagrangian) {
    p.lagrangian = r.string(*lagrangian, "model.lagrangian");
    for (const char* key : {"mass", "damping", "potential", "chain", "force"}) {
      if (r.find("model", key)) {
        r.fail(std::string("model.") + key,
               "cannot be combined with model.lagrangian (the Lagrangian already holds the "
               "kinetic energy, the potential and the memory coupling; give one or the other)");
      }
    }
    check_expression(r, "model.lagrangian", p.lagrangian,
                     ExpressionLagrangian::variable_names(p.dim));
  } else {
    p.mass = r.matrix(r.required("model", "mass", "the mass matrix M"), "model.mass", p.dim,
                      /*definite=*/true);
    if (!p.mass.is_sparse()) check_dense_mass(r, p.mass.dense());
  }
  p.damping = ModelMatrix::zero(p.dim);
  if (const auto* n = r.find("model", "damping")) {
    p.damping = r.matrix(*n, "model.damping", p.dim, /*definite=*/false);
    if (!p.damping.is_sparse()) check_dense_damping(r, p.damping.dense());
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
  if (p.alpha > 0.0 && p.alpha < kMinPositiveAlpha) {
    r.fail(alpha ? "model.alpha" : "model.damping_order",
           "= " + format_value(alpha ? p.alpha : 2.0 * p.alpha) + " is positive but below " +
               format_value(alpha ? kMinPositiveAlpha : 2.0 * kMinPositiveAlpha) +
               ": so small an order differs from 0 (D^0 x = x) by less than 1e-10 relative, and "
               "its memory weights approach the subnormal range; use 0");
  }
  if (const auto* n = r.find("model", "convention")) {
    p.convention = r.string(*n, "model.convention");
    if (p.convention != "caputo" && p.convention != "riemann-liouville") {
      r.fail("model.convention", "= \"" + p.convention +
                                     "\" must be \"caputo\" or \"riemann-liouville\"" +
                                     did_you_mean(p.convention, {"caputo", "riemann-liouville"}));
    }
  } else if (!(p.damping.is_zero() || p.alpha == 0.5)) {
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
  if (const auto* chain = r.find("model", "chain"); chain && !lagrangian) {
    p.chain = read_chain(r, *chain, p.dim);
    if (r.find("model", "potential")) {
      r.fail("model.potential",
             "and model.chain are both given; give one (model.chain is the built-in FPUT chain "
             "potential, model.potential a formula)");
    }
  } else if (!lagrangian) {
    p.potential = r.string(
        r.required("model", "potential", "U as a formula in x1..xd and t, or a [model.chain]"),
        "model.potential");
    if (p.potential.starts_with(kPythonFunctionPrefix)) {
      // What a run from Python with potential=<function> records (ProblemSpec::potential_object).
      r.fail("model.potential",
             "= \"" + p.potential +
                 "\" names Python functions, which a problem file cannot call: give U as a "
                 "formula in x1..xd and t, or read this problem from Python (fracvi.load and "
                 "fracvi.Problem.from_dict import the functions again when they are importable)");
    }
    check_expression(r, "model.potential", p.potential, names);
  }

  // [initial] (optional when the file poses a boundary value problem)
  const bool has_boundary = r.find("", "boundary") != nullptr;
  if (!has_boundary || r.find("initial", "position") != nullptr) {
    p.position = r.initial_vector(r.required("initial", "position", "x(0)"), "initial.position",
                                  p.dim, p.position_formula);
  }
  p.velocity = Eigen::VectorXd::Zero(p.dim);
  if (const auto* n = r.find("initial", "velocity"))
    p.velocity = r.initial_vector(*n, "initial.velocity", p.dim, p.velocity_formula);
  if (p.convention == "riemann-liouville" && 2.0 * p.alpha > 1.0 && !p.position.isZero(0.0) &&
      !p.damping.is_zero()) {
    r.fail("model.convention",
           "\"riemann-liouville\" with damping order 2*alpha = " + format_value(2.0 * p.alpha) +
               " > 1 and initial.position != 0 is ill-posed: " +
               riemann_liouville_obstruction(2.0 * p.alpha) +
               "; use convention = \"caputo\" (memory of x - x(0) - t v(0)) or start at x(0) = 0");
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
    // Before the conversion to an integer: a tiny step (1e-300) gives a count beyond long long,
    // whose conversion is undefined behaviour.
    if (!(n <= static_cast<double>(kMaxSteps))) {
      r.fail("time.step", "= " + format_value(h) + " divides [" + format_value(p.start) + ", " +
                              format_value(p.end) + "] into " + format_value(n, 3) +
                              " steps, more than the limit of " + std::to_string(kMaxSteps));
    }
    const double rounded = std::round(n);
    if (rounded < 1.0 || std::abs(n - rounded) > 1e-9 * rounded) {
      r.fail("time.step", "= " + format_value(h) + " does not divide [" + format_value(p.start) +
                              ", " + format_value(p.end) + "] into a whole number of steps");
    }
    p.steps = static_cast<long long>(rounded);
  }
  if (p.steps > kMaxSteps) {
    r.fail("time.steps", "= " + std::to_string(p.steps) + " is more than the limit of " +
                             std::to_string(kMaxSteps));
  }

  // [method]
  if (const auto* n = r.find("method", "scheme")) {
    p.scheme = r.string(*n, "method.scheme");
    if (p.scheme != kAutoScheme && find_scheme(p.scheme) == nullptr) {
      std::vector<std::string> known;
      for (const SchemeInfo* info : registered_schemes()) known.emplace_back(info->name);
      known.emplace_back(kAutoScheme);
      r.fail("method.scheme", "= \"" + p.scheme + "\" is not a known scheme (available: auto, " +
                                  scheme_names() + ")" + did_you_mean(p.scheme, known));
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
                                   did_you_mean(p.history, {"auto", "direct", "fast"}));
    }
  }
  if (const auto* n = r.find("method", "history_tolerance")) {
    // "auto" (the default): the accuracy budget chooses ε from the run (history_budget.hpp).
    if (n->is_string()) {
      const std::string value = r.string(*n, "method.history_tolerance");
      if (value != "auto") {
        r.fail("method.history_tolerance",
               "= \"" + value + "\" must be \"auto\" or a number in [1e-13, 1e-3]");
      }
      p.history_tolerance = kAutoHistoryTolerance;
    } else {
      p.history_tolerance = r.number(*n, "method.history_tolerance");
      if (!(p.history_tolerance >= kMinHistoryTolerance &&
            p.history_tolerance <= kMaxHistoryTolerance)) {
        r.fail("method.history_tolerance", "= " + format_value(p.history_tolerance) +
                                               " must be \"auto\" or in [1e-13, 1e-3] "
                                               "(per-weight relative accuracy of the fast "
                                               "history)");
      }
    }
  }
  // The adaptive schemes' tolerances (IntegratorOptions::abs_tolerance, rel_tolerance).
  if (const auto* n = r.find("method", "abs_tolerance")) {
    p.abs_tolerance = r.number(*n, "method.abs_tolerance");
    if (!(p.abs_tolerance >= 0.0 && p.abs_tolerance < 1e300)) {
      r.fail("method.abs_tolerance", "= " + format_value(p.abs_tolerance) +
                                         " must be >= 0 (absolute error tolerance of the "
                                         "adaptive schemes)");
    }
  }
  if (const auto* n = r.find("method", "rel_tolerance")) {
    p.rel_tolerance = r.number(*n, "method.rel_tolerance");
    if (!(p.rel_tolerance >= 1e-15 && p.rel_tolerance < 1.0)) {
      r.fail("method.rel_tolerance", "= " + format_value(p.rel_tolerance) +
                                         " must be in [1e-15, 1) (relative error tolerance of "
                                         "the adaptive schemes)");
    }
  }
  if (const auto* n = r.find("method", "linear_solver")) {
    p.linear_solver = r.string(*n, "method.linear_solver");
    if (!parse_linear_solver(p.linear_solver)) {
      const std::vector<std::string> solvers{"auto", "dense", "banded", "sparse"};
      r.fail("method.linear_solver", "= \"" + p.linear_solver + "\" is not one of " +
                                         joined(solvers) + did_you_mean(p.linear_solver, solvers));
    }
  }
  if (const auto* n = r.find("method", "load")) {
    p.load = r.string(*n, "method.load");
    if (!parse_forcing_load(p.load)) {
      const std::vector<std::string> loads{"pointwise", "moments"};
      r.fail("method.load",
             "= \"" + p.load + "\" is not one of " + joined(loads) + did_you_mean(p.load, loads));
    }
  }
  if (const auto* n = r.find("method", "split")) {
    p.split = r.string(*n, "method.split");
    if (!parse_taylor_split(p.split)) {
      const std::vector<std::string> splits{"taylor", "series"};
      r.fail("method.split", "= \"" + p.split + "\" is not one of " + joined(splits) +
                                 did_you_mean(p.split, splits));
    }
  }
  if (const auto* n = r.find("method", "error_estimate")) {
    p.error_estimate = r.string(*n, "method.error_estimate");
    if (!parse_error_estimate(p.error_estimate)) {
      const std::vector<std::string> kinds{"richardson", "none"};
      r.fail("method.error_estimate", "= \"" + p.error_estimate + "\" is not one of " +
                                          joined(kinds) + did_you_mean(p.error_estimate, kinds));
    }
  }
  if (const auto* n = r.find("method", "mirror")) {
    p.mirror = r.string(*n, "method.mirror");
    const std::vector<std::string> choices{"auto", "on", "off"};
    if (std::find(choices.begin(), choices.end(), p.mirror) == choices.end()) {
      r.fail("method.mirror", "= \"" + p.mirror + "\" is not one of " + joined(choices) +
                                  did_you_mean(p.mirror, choices));
    }
  }
  if (const auto* n = r.find("method", "tolerance")) {
    p.tolerance = r.number(*n, "method.tolerance");
    if (!(p.tolerance > 0.0) || !std::isfinite(p.tolerance)) {
      r.fail("method.tolerance", "= " + format_number(p.tolerance) +
                                     " must be a positive number (the error estimate to reach; "
                                     "leave it out for a run with time.steps)");
    }
  }
  if (const auto* n = r.find("method", "max_steps")) {
    p.max_steps = r.integer(*n, "method.max_steps");
    if (p.max_steps < 1 || p.max_steps > kMaxSteps) {
      r.fail("method.max_steps", "= " + std::to_string(p.max_steps) + " must be in [1, " +
                                     std::to_string(kMaxSteps) + "]");
    }
  }
  if (p.tolerance > 0.0 && p.error_estimate == "none") {
    r.fail("method.tolerance", "needs an error estimate, but method.error_estimate = \"none\"");
  }
  if (const auto* n = r.find("method", "threads")) {
    const long long threads = r.integer(*n, "method.threads");
    if (threads < 0 || threads > 4096) {
      r.fail("method.threads", "= " + std::to_string(threads) +
                                   " must be in [0, 4096] (0: measured, one thread or all cores)");
    }
    p.threads = static_cast<int>(threads);
  }
  if (p.chain) p.chain->threads = p.threads;
  if (const auto* n = r.find("method", "flush_subnormals")) {
    p.flush_subnormals = r.boolean(*n, "method.flush_subnormals");
  }
  // [output]
  if (const auto* n = r.find("output", "every")) {
    // "auto" (the default): from time.steps (stored_every, problem_file.hpp).
    if (n->is_string()) {
      const std::string value = r.string(*n, "output.every");
      if (value != "auto") {
        r.fail("output.every", "= \"" + value + "\" must be \"auto\" or an integer >= 1");
      }
      p.every = kAutoEvery;
    } else {
      p.every = r.integer(*n, "output.every");
      if (p.every < 1) {
        r.fail("output.every",
               "= " + std::to_string(p.every) + " must be at least 1 (or \"auto\")");
      }
    }
  }
  if (const auto* n = r.find("output", "checkpoint_every")) {
    p.checkpoint_every = r.integer(*n, "output.checkpoint_every");
    if (p.checkpoint_every < 0) {
      r.fail("output.checkpoint_every", "= " + std::to_string(p.checkpoint_every) +
                                            " must be >= 0 (steps between checkpoints; 0: none)");
    }
    if (p.checkpoint_every > 0 && p.tolerance > 0.0) {
      r.fail("output.checkpoint_every",
             "= " + std::to_string(p.checkpoint_every) +
                 " cannot be combined with method.tolerance (that runs several step counts; "
                 "checkpoint one run with a fixed time.steps)");
    }
  }
  if (const auto* n = r.find("output", "format")) {
    p.format = r.string(*n, "output.format");
    const std::vector<std::string> choices{"csv", "npz"};
    if (std::find(choices.begin(), choices.end(), p.format) == choices.end()) {
      r.fail("output.format", "= \"" + p.format + "\" is not one of " + joined(choices) +
                                  did_you_mean(p.format, choices));
    }
  }
  if (const auto* n = r.find("output", "times")) {
    if (!n->is_array())
      r.fail("output.times", "must be an array of times, got " + Reader::type_name(*n));
    const auto& a = *n->as_array();
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string key = "output.times[" + std::to_string(i + 1) + "]";
      const double t = r.number(a[i], key);
      if (!(t >= p.start && t <= p.end)) {
        r.fail(key, "= " + format_value(t) + " must be within [time.start, time.end] = [" +
                        format_value(p.start) + ", " + format_value(p.end) + "]");
      }
      if (!p.times.empty() && t < p.times.back()) {
        r.fail(key, "= " + format_value(t) + " is smaller than the time before it (" +
                        format_value(p.times.back()) + "): the times must be ascending");
      }
      p.times.push_back(t);
    }
  }
  // [[events]]
  if (const auto* n = root.get("events")) {
    std::vector<std::string> variables{"t"};
    for (Eigen::Index i = 1; i <= p.dim; ++i) variables.push_back("x" + std::to_string(i));
    for (Eigen::Index i = 1; i <= p.dim; ++i) variables.push_back("v" + std::to_string(i));
    const auto& a = *n->as_array();  // an array of tables (check_unknown_keys)
    for (std::size_t i = 0; i < a.size(); ++i) {
      const auto& table = *a[i].as_table();
      const std::string at = "events[" + std::to_string(i + 1) + "]";
      ProblemSpec::EventSpec e;
      const toml::node* name = table.get("name");
      if (!name) r.fail(at + ".name", "missing (the event's name)");
      e.name = r.string(*name, at + ".name");
      if (e.name.empty()) r.fail(at + ".name", "is empty: each event needs a name");
      for (const auto& earlier : p.events) {
        if (earlier.name == e.name) {
          r.fail(at + ".name", "= \"" + e.name +
                                   "\" is the name of an earlier event: names "
                                   "must be distinct");
        }
      }
      const toml::node* g = table.get("g");
      if (!g) r.fail(at + ".g", "missing (a formula in t, x1..xd, v1..vd whose zeros are sought)");
      e.g = r.string(*g, at + ".g");
      check_expression(r, at + ".g", e.g, variables);
      if (const toml::node* dir = table.get("direction")) {
        e.direction = r.string(*dir, at + ".direction");
        if (!parse_event_direction(e.direction)) {
          r.fail(at + ".direction",
                 "= \"" + e.direction + "\" is not one of both, rising, falling");
        }
      }
      if (const toml::node* terminal = table.get("terminal")) {
        e.terminal = r.boolean(*terminal, at + ".terminal");
      }
      p.events.push_back(std::move(e));
    }
  }
  if (p.checkpoint_every > 0 && (!p.times.empty() || !p.events.empty())) {
    r.fail("output.checkpoint_every",
           "= " + std::to_string(p.checkpoint_every) +
               " cannot be combined with output.times or [[events]] (their progress is not part "
               "of a checkpoint)");
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

// A JSON integer as TOML's 64-bit signed integer: nlohmann keeps integers above INT64_MAX as
// unsigned, and get<int64_t>() would wrap them to negative numbers (18446744073709551615 → −1).
std::int64_t json_integer(const nlohmann::json& v, const std::string& source,
                          const std::string& key) {
  if (v.is_number_unsigned() && v.get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX)) {
    throw ProblemFileError(source + ": " + key + " = " + std::to_string(v.get<std::uint64_t>()) +
                           " does not fit a 64-bit integer; write it as a float, e.g. " +
                           format_value(v.get<double>()));
  }
  return v.get<std::int64_t>();
}

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
      t.insert(k, json_integer(v, source, key));
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
      out.push_back(json_integer(v, source, key));
    } else if (v.is_number()) {
      out.push_back(v.get<double>());
    } else if (v.is_boolean()) {
      out.push_back(v.get<bool>());
    } else if (v.is_object()) {  // [[events]]
      out.push_back(to_toml_table(v, source, key));
    } else {
      throw ProblemFileError(source + ": " + key +
                             ": arrays hold numbers, strings, arrays or tables");
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
  // Read at most kMaxProblemFileBytes + 1: a device or pipe without end (/dev/zero) must not be
  // read forever, and no problem file is near the limit (the largest example is a few kB; a dense
  // 1000 × 1000 matrix written out is about 20 MB).
  constexpr std::size_t kMaxProblemFileBytes = 64u << 20;
  std::string text;
  std::array<char, 1 << 16> chunk{};
  while (in && text.size() <= kMaxProblemFileBytes) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw ProblemFileError(file.string() + ": cannot read the problem file");
  if (text.size() > kMaxProblemFileBytes) {
    throw ProblemFileError(file.string() + ": is larger than " +
                           std::to_string(kMaxProblemFileBytes >> 20) +
                           " MiB, the limit for a problem file (a large model belongs in "
                           "[model.chain] or the C++ or Python API, not in the text)");
  }
  return parse_problem(text, file.string(), overrides);
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
# "auto": fvi-lobatto3 here (docs/comparison.md, "The default scheme"); "fvi-gl" is the paper's.
scheme = "auto"
newton_tolerance = 1e-12
newton_max_iterations = 50
history = "auto"

[output]
every = 1
)toml";
}

// The writers iterate the schema (io/problem_schema.hpp): every field that a resolved problem
// writes is written, and to_toml is the TOML form of the same document, so the two cannot drift.
nlohmann::json to_json(const ProblemSpec& p) {
  nlohmann::json document = nlohmann::json::object();
  for (const ProblemField& field : problem_schema()) {
    if (field.write == nullptr) continue;
    nlohmann::json value = field.write(p);
    if (value.is_null()) continue;
    nlohmann::json* table = &document;
    for (std::size_t from = 0; !field.section.empty() && from <= field.section.size();) {
      const std::size_t dot = std::min(field.section.find('.', from), field.section.size());
      table = &(*table)[field.section.substr(from, dot - from)];
      from = dot + 1;
    }
    (*table)[field.key] = std::move(value);
  }
  return document;
}

std::string to_toml(const ProblemSpec& p) {
  std::ostringstream os;
  os << to_toml_table(to_json(p), p.source, "") << '\n';
  return os.str();
}

long long stored_every(long long every, long long steps) {
  if (every != kAutoEvery) return every;
  long long stride = 1;
  // ceil(steps / stride) ≤ kAutoStoredRows; steps ≤ 2·10^9 (checked), so no overflow.
  while ((steps + stride - 1) / stride > kAutoStoredRows) stride *= 2;
  return stride;
}

bool mirror_check_runs(const ProblemSpec& spec) {
  if (spec.mirror != "auto") return spec.mirror == "on";
  // The product of two checked integers (time.steps, model.dim), in floating point: no overflow.
  return static_cast<double>(spec.steps) * static_cast<double>(spec.dim) <=
         static_cast<double>(kAutoMirrorWork);
}

}  // namespace fracvi
