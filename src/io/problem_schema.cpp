#include "fracvi/io/problem_schema.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <optional>

#include "fracvi/core/error.hpp"
#include "fracvi/core/newton_options.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/lagrangian/bvp.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/registry.hpp"

// "Type::member" for the binding column, through the member pointer: renaming the member is a
// compile error here instead of a stale name in the docs.
#define FRACVI_BINDING(Type, member) \
  (static_cast<void>(&Type::member), std::string(#Type "::" #member))

namespace fracvi {

namespace {

std::string in_quotes(std::string_view s) {
  return "\"" + std::string(s) + "\"";
}

using Json = nlohmann::json;

// --- how a resolved problem writes its fields (the compact forms of a problem file) ----------

bool is_constant(const Eigen::VectorXd& v) {
  return v.size() > 0 && (v.array() == v[0]).all();
}

Json vector_json(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

// A diagonal (sparse storage) with equal entries is one number, another diagonal d numbers; dense
// storage (or a non-diagonal sparse matrix, which a problem file cannot produce) is d rows.
Json matrix_json(const ModelMatrix& m) {
  if (m.is_sparse() && m.is_diagonal()) {
    const Eigen::VectorXd diagonal = m.sparse().diagonal();
    return is_constant(diagonal) ? Json(diagonal[0]) : vector_json(diagonal);
  }
  const Eigen::MatrixXd dense = m.to_dense();
  Json rows = Json::array();
  for (Eigen::Index i = 0; i < dense.rows(); ++i) rows.push_back(vector_json(dense.row(i)));
  return rows;
}

// Initial data: the formula it was given as, one number for a constant vector (d ≥ 2), else d
// numbers.
Json initial_json(const Eigen::VectorXd& v, const std::string& formula) {
  if (!formula.empty()) return formula;
  if (v.size() >= 2 && is_constant(v)) return v[0];
  return vector_json(v);
}

Json strings_json(const std::vector<std::string>& strings) {
  if (strings.empty()) return nullptr;
  return strings;
}

bool mechanical(const ProblemSpec& p) {
  return p.lagrangian.empty();
}

// A [model.chain] key: written when the problem has the chain.
template <class Get>
Json chain_value(const ProblemSpec& p, Get get) {
  return p.chain && mechanical(p) ? Json(get(*p.chain)) : Json();
}

std::vector<ProblemField> make_schema() {
  const ProblemSpec d;  // the defaults (from IntegratorOptions{}, NewtonOptions{}, Method{})
  const ChainOptions chain;
  const std::string same = "same forms";
  using P = const ProblemSpec&;
  return {
      {"", "name", "string", in_quotes(d.name), "names the default output directory",
       FRACVI_BINDING(ProblemSpec, name), [](P p) { return Json(p.name); }},
      {"", "model", "table", "required", "the model", "", nullptr},
      {"", "initial", "table", "required unless [boundary]", "initial data", "", nullptr},
      {"", "boundary", "table", "-", "boundary data (fracvi bvp)", "", nullptr},
      {"", "time", "table", "required", "the grid", "", nullptr},
      {"", "method", "table", "-", "the scheme and its solver", "", nullptr},
      {"", "output", "table", "-", "what is stored", "", nullptr},
      {"", "reference", "table", "-", "an exact solution to compare with", "", nullptr},
      {"", "events", "array of tables", "-", "zero crossings of g(t, x, v) to locate: [[events]]",
       FRACVI_BINDING(IntegratorOptions, events),
       [](P p) {
         if (p.events.empty()) return Json();
         Json a = Json::array();
         for (const ProblemSpec::EventSpec& e : p.events) {
           a.push_back({{"name", e.name},
                        {"g", e.g},
                        {"direction", e.direction},
                        {"terminal", e.terminal}});
         }
         return a;
       }},
      {"model", "dim", "integer", "required", "d >= 1", FRACVI_BINDING(MechanicalModel, dimension),
       [](P p) { return Json(static_cast<std::int64_t>(p.dim)); }},
      {"model", "mass", "number, array of d numbers, or d×d array", "required", "M, SPD",
       FRACVI_BINDING(MechanicalModel, mass),
       [](P p) { return mechanical(p) ? matrix_json(p.mass) : Json(); }},
      {"model", "damping", same, "0", "R, symmetric PSD", FRACVI_BINDING(MechanicalModel, damping),
       [](P p) { return mechanical(p) ? matrix_json(p.damping) : Json(); }},
      {"model", "alpha", "number", "required (or damping_order)", "the Lagrangian order α",
       FRACVI_BINDING(MechanicalModel, alpha), [](P p) { return Json(p.alpha); }},
      // Written as alpha (the reader refuses both).
      {"model", "damping_order", "number", "—", "2α, instead of alpha",
       FRACVI_BINDING(MechanicalModel, alpha), nullptr},
      {"model", "convention", "string", "required unless R = 0 or α = 1/2",
       "caputo or riemann-liouville", FRACVI_BINDING(MechanicalModel, convention),
       [](P p) { return Json(p.convention); }},
      {"model", "potential", "string", "required unless [model.chain]", "U(x, t)",
       FRACVI_BINDING(MechanicalModel, potential),
       [](P p) { return mechanical(p) && !p.chain ? Json(p.potential) : Json(); }},
      // A table: its keys are the [model.chain] rows below.
      {"model", "chain", "table [model.chain]", "—", "the built-in FPUT chain as U",
       FRACVI_BINDING(MechanicalModel, potential), nullptr},
      {"model", "force", "array of d strings", "none", "f(t), or g(x, v, t) in x1..xd, v1..vd",
       FRACVI_BINDING(MechanicalModel, forcing),
       [](P p) { return mechanical(p) ? strings_json(p.force) : Json(); }},
      {"model.chain", "stiffness", "number", format_number(chain.stiffness),
       "linear spring constant", FRACVI_BINDING(ChainOptions, stiffness),
       [](P p) { return chain_value(p, [](const ChainOptions& c) { return c.stiffness; }); }},
      {"model.chain", "cubic", "number", format_number(chain.cubic), "α-FPUT coefficient",
       FRACVI_BINDING(ChainOptions, cubic),
       [](P p) { return chain_value(p, [](const ChainOptions& c) { return c.cubic; }); }},
      {"model.chain", "quartic", "number", format_number(chain.quartic), "β-FPUT coefficient",
       FRACVI_BINDING(ChainOptions, quartic),
       [](P p) { return chain_value(p, [](const ChainOptions& c) { return c.quartic; }); }},
      {"model.chain", "onsite", "number", format_number(chain.onsite), "on-site stiffness",
       FRACVI_BINDING(ChainOptions, onsite),
       [](P p) { return chain_value(p, [](const ChainOptions& c) { return c.onsite; }); }},
      {"model.chain", "boundary", "string", in_quotes(to_string(chain.boundary)),
       "fixed, free or periodic", FRACVI_BINDING(ChainOptions, boundary),
       [](P p) {
         return chain_value(
             p, [](const ChainOptions& c) { return std::string(to_string(c.boundary)); });
       }},
      {"model", "lagrangian", "string", "—", "a general L instead of the mechanical fields",
       FRACVI_BINDING(BoundaryValueProblem, lagrangian),
       [](P p) { return mechanical(p) ? Json() : Json(p.lagrangian); }},
      {"initial", "position", "array of d numbers, a number, or a formula (string)",
       "required (unless [boundary] is given)", "x(start)", FRACVI_BINDING(InitialValueProblem, x0),
       [](P p) {
         return p.position.size() > 0 ? initial_json(p.position, p.position_formula) : Json();
       }},
      // Without a position (a [boundary] problem), zero velocity is not written.
      {"initial", "velocity", same, "zeros", "x'(start)", FRACVI_BINDING(InitialValueProblem, v0),
       [](P p) {
         return p.position.size() > 0 || !p.velocity.isZero(0.0)
                    ? initial_json(p.velocity, p.velocity_formula)
                    : Json();
       }},
      {"boundary", "start", "array of d numbers", "required with [boundary]", "x(start)",
       FRACVI_BINDING(BoundaryValueProblem, x_start),
       [](P p) { return p.boundary_start.size() > 0 ? vector_json(p.boundary_start) : Json(); }},
      {"boundary", "end", "array of d numbers", "required with [boundary]", "x(end)",
       FRACVI_BINDING(BoundaryValueProblem, x_end),
       [](P p) { return p.boundary_end.size() > 0 ? vector_json(p.boundary_end) : Json(); }},
      {"time", "start", "number", format_number(d.start), "t_0",
       FRACVI_BINDING(InitialValueProblem, t0), [](P p) { return Json(p.start); }},
      {"time", "end", "number", "required", "t_N > t_0", FRACVI_BINDING(InitialValueProblem, t_end),
       [](P p) { return Json(p.end); }},
      {"time", "steps", "integer", "one of steps/step", "N",
       FRACVI_BINDING(InitialValueProblem, steps),
       [](P p) { return Json(static_cast<std::int64_t>(p.steps)); }},
      // Written as steps (the reader refuses both).
      {"time", "step", "number", "", "h", FRACVI_BINDING(InitialValueProblem, steps), nullptr},
      {"method", "scheme", "string", in_quotes(d.scheme),
       "a name from the method registry, or \"auto\": the first of fvi-lobatto3, "
       "fvi-midpoint, fvi-bdf2, fvi-gl that applies and is stable at the step",
       FRACVI_BINDING(Method, name), [](P p) { return Json(p.scheme); }},
      {"method", "newton_tolerance", "number", format_number(d.newton_tolerance),
       "relative Newton tolerance", FRACVI_BINDING(NewtonOptions, relative_tolerance),
       [](P p) { return Json(p.newton_tolerance); }},
      {"method", "newton_max_iterations", "integer", std::to_string(d.newton_max_iterations),
       "Newton iterations per step", FRACVI_BINDING(NewtonOptions, max_iterations),
       [](P p) { return Json(static_cast<std::int64_t>(p.newton_max_iterations)); }},
      {"method", "history", "string", in_quotes(d.history), "auto, direct or fast",
       FRACVI_BINDING(IntegratorOptions, history), [](P p) { return Json(p.history); }},
      {"method", "history_tolerance", "number or string", in_quotes("auto"),
       "\"auto\" (chosen from the run: the accuracy budget, docs/theory/fast_history.md) or "
       "1e-13 ... 1e-3: per-weight relative accuracy of the fast history",
       FRACVI_BINDING(IntegratorOptions, history_tolerance),
       [](P p) {
         return p.history_tolerance == kAutoHistoryTolerance ? Json("auto")
                                                             : Json(p.history_tolerance);
       }},
      {"method", "abs_tolerance", "number", format_number(d.abs_tolerance),
       "absolute error tolerance of the adaptive schemes (dopri5)",
       FRACVI_BINDING(IntegratorOptions, abs_tolerance), [](P p) { return Json(p.abs_tolerance); }},
      {"method", "rel_tolerance", "number", format_number(d.rel_tolerance),
       "relative error tolerance of the adaptive schemes (dopri5)",
       FRACVI_BINDING(IntegratorOptions, rel_tolerance), [](P p) { return Json(p.rel_tolerance); }},
      {"method", "linear_solver", "string", in_quotes(d.linear_solver),
       "auto, dense, banded or sparse", FRACVI_BINDING(IntegratorOptions, linear_solver),
       [](P p) { return Json(p.linear_solver); }},
      {"method", "load", "string", in_quotes(d.load),
       "how the forcing enters: pointwise or moments", FRACVI_BINDING(IntegratorOptions, load),
       [](P p) { return Json(p.load); }},
      {"method", "split", "string", in_quotes(d.split),
       "what the Lobatto schemes take out of x at t0: taylor (x0 + t v0, from the memory) or "
       "series (also the solution's fractional Taylor terms; linear problems whose force is a sum "
       "of "
       "power laws in t - t0)",
       FRACVI_BINDING(IntegratorOptions, split), [](P p) { return Json(p.split); }},
      {"method", "error_estimate", "string", in_quotes(d.error_estimate),
       "a-posteriori error estimate: richardson (runs with N/2, N/4 steps) or none",
       FRACVI_BINDING(IntegratorOptions, error_estimate),
       [](P p) { return Json(p.error_estimate); }},
      {"method", "mirror", "string", in_quotes(d.mirror),
       "the mirror check (backward run of DiscEqs' second line): auto (on when time.steps x "
       "model.dim <= 10^6), on or off",
       FRACVI_BINDING(IntegratorOptions, mirror), [](P p) { return Json(p.mirror); }},
      {"method", "tolerance", "number", "0 (off)",
       "> 0: double time.steps until the error estimate is <= tolerance",
       FRACVI_BINDING(IntegratorOptions, tolerance),
       [](P p) { return p.tolerance > 0.0 ? Json(p.tolerance) : Json(); }},
      {"method", "max_steps", "integer", std::to_string(d.max_steps),
       "ceiling of the doubling of method.tolerance", FRACVI_BINDING(IntegratorOptions, max_steps),
       [](P p) { return Json(static_cast<std::int64_t>(p.max_steps)); }},
      {"method", "threads", "integer", std::to_string(d.threads), "OpenMP threads; 0 = all",
       FRACVI_BINDING(IntegratorOptions, threads),
       [](P p) { return Json(static_cast<std::int64_t>(p.threads)); }},
      {"method", "flush_subnormals", "boolean", d.flush_subnormals ? "true" : "false",
       "flush numbers below 2.2e-308 to zero while stepping (x86-64: 2.4-2.9x faster where a run "
       "has them); false keeps gradual underflow",
       FRACVI_BINDING(IntegratorOptions, flush_subnormals),
       [](P p) { return Json(p.flush_subnormals); }},
      {"output", "every", "integer or string", in_quotes("auto"),
       "store every n-th state and the last; \"auto\": every state up to 10^5 steps, beyond the "
       "smallest power of two that keeps 10^5 + 1",
       FRACVI_BINDING(IntegratorOptions, save_every),
       [](P p) {
         return p.every == kAutoEvery ? Json("auto") : Json(static_cast<std::int64_t>(p.every));
       }},
      {"output", "checkpoint_every", "integer", std::to_string(d.checkpoint_every),
       "fracvi run: write a checkpoint every n steps (0: none)",
       FRACVI_BINDING(ProblemSpec, checkpoint_every),
       [](P p) { return Json(static_cast<std::int64_t>(p.checkpoint_every)); }},
      {"output", "format", "string", in_quotes(d.format),
       "the trajectory's file: csv (trajectory.csv) or npz (trajectory.npz, NumPy's archive)",
       FRACVI_BINDING(ProblemSpec, format), [](P p) { return Json(p.format); }},
      {"output", "times", "array of numbers", "[] (none)",
       "also the state at these times (ascending, in [start, end]; dense output)",
       FRACVI_BINDING(IntegratorOptions, output_times),
       [](P p) { return p.times.empty() ? Json() : Json(p.times); }},
      {"reference", "position", "array of d strings", "—", "exact x(t), one formula per component",
       FRACVI_BINDING(ProblemSpec, reference), [](P p) { return strings_json(p.reference); }},
      // The keys of each [[events]] table: written by the top-level "events" field above.
      {"events", "name", "string", "required", "names the event in records and files",
       FRACVI_BINDING(Event, name), nullptr},
      {"events", "g", "string", "required",
       "g(t, x1..xd, v1..vd), a formula: its zero crossings are the events",
       FRACVI_BINDING(Event, function), nullptr},
      {"events", "direction", "string", "\"both\"", "which crossings: rising, falling or both",
       FRACVI_BINDING(Event, direction), nullptr},
      {"events", "terminal", "boolean", "false", "stop the run at the first crossing",
       FRACVI_BINDING(Event, terminal), nullptr},
  };
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

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

}  // namespace

const std::vector<ProblemField>& problem_schema() {
  static const std::vector<ProblemField> schema = make_schema();
  return schema;
}

const ProblemField* find_field(std::string_view section, std::string_view key) {
  for (const ProblemField& f : problem_schema())
    if (f.section == section && f.key == key) return &f;
  return nullptr;
}

std::vector<std::string> schema_keys(std::string_view section) {
  std::vector<std::string> keys;
  for (const ProblemField& f : problem_schema())
    if (f.section == section) keys.push_back(f.key);
  return keys;
}

bool is_schema_section(std::string_view section) {
  return std::any_of(problem_schema().begin(), problem_schema().end(),
                     [&](const ProblemField& f) { return f.section == section; });
}

std::vector<std::string> schema_section_names() {
  std::vector<std::string> names;
  for (const ProblemField& f : problem_schema()) {
    if (f.section.empty()) continue;
    const std::string name = "[" + f.section + "]";
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  }
  return names;
}

std::string did_you_mean(std::string_view wrong, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, wrong.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(wrong, c);
    if (d < best_d) best_d = d, best = c;
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

std::string unknown_field_message(std::string_view path) {
  const auto dot = path.rfind('.');
  const std::string section(dot == std::string_view::npos ? "" : path.substr(0, dot));
  const std::string key(dot == std::string_view::npos ? path : path.substr(dot + 1));
  if (!is_schema_section(section)) {
    std::vector<std::string> sections;
    for (const ProblemField& f : problem_schema())
      if (f.type == "table" || f.type.rfind("table ", 0) == 0)
        sections.push_back(f.section.empty() ? f.key : f.section + "." + f.key);
    return std::string(path) + ": unknown section [" + section + "]" +
           did_you_mean(section, sections) + "; valid sections: " + joined(schema_section_names());
  }
  if (find_field(section, key) != nullptr) return "";
  const std::vector<std::string> keys = schema_keys(section);
  return std::string(path) + ": unknown key" + did_you_mean(key, keys) + "; valid " +
         (section.empty() ? std::string("at the top level") : "in [" + section + "]") + ": " +
         joined(keys);
}

}  // namespace fracvi

#undef FRACVI_BINDING
