#include "fracvi/io/problem_schema.hpp"

#include <algorithm>

#include "fracvi/core/error.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

namespace {

std::string quoted(const std::string& s) {
  return "\"" + s + "\"";
}

std::vector<ProblemField> make_schema() {
  const ProblemSpec d;  // the defaults (from IntegratorOptions{}, NewtonOptions{}, Method{})
  const std::string same = "same forms";
  return {
      {"", "name", "string", quoted(d.name), "names the default output directory"},
      {"", "model", "table", "required", "the model"},
      {"", "initial", "table", "required unless [boundary]", "initial data"},
      {"", "boundary", "table", "-", "boundary data (fracvi bvp)"},
      {"", "time", "table", "required", "the grid"},
      {"", "method", "table", "-", "the scheme and its solver"},
      {"", "output", "table", "-", "what is stored"},
      {"", "reference", "table", "-", "an exact solution to compare with"},
      {"model", "dim", "integer", "required", "d >= 1"},
      {"model", "mass", "number, array of d numbers, or d×d array", "required", "M, SPD"},
      {"model", "damping", same, "0", "R, symmetric PSD"},
      {"model", "alpha", "number", "required (or damping_order)", "the Lagrangian order α"},
      {"model", "damping_order", "number", "—", "2α, instead of alpha"},
      {"model", "convention", "string", "required unless R = 0 or α = 1/2",
       "caputo or riemann-liouville"},
      {"model", "potential", "string", "required unless [model.chain]", "U(x, t)"},
      {"model", "chain", "table [model.chain]", "—", "the built-in FPUT chain as U"},
      {"model", "force", "array of d strings", "none", "f(t)"},
      {"model.chain", "stiffness", "number", "1", "linear spring constant"},
      {"model.chain", "cubic", "number", "0", "α-FPUT coefficient"},
      {"model.chain", "quartic", "number", "0", "β-FPUT coefficient"},
      {"model.chain", "onsite", "number", "0", "on-site stiffness"},
      {"model.chain", "boundary", "string", quoted("fixed"), "fixed, free or periodic"},
      {"model", "lagrangian", "string", "—", "a general L instead of the mechanical fields"},
      {"initial", "position", "array of d numbers, a number, or a formula (string)",
       "required (unless [boundary] is given)", "x(start)"},
      {"initial", "velocity", same, "zeros", "x'(start)"},
      {"boundary", "start", "array of d numbers", "required with [boundary]", "x(start)"},
      {"boundary", "end", "array of d numbers", "required with [boundary]", "x(end)"},
      {"time", "start", "number", format_number(d.start), "t_0"},
      {"time", "end", "number", "required", "t_N > t_0"},
      {"time", "steps", "integer", "one of steps/step", "N"},
      {"time", "step", "number", "", "h"},
      {"method", "scheme", "string", quoted(d.scheme), "a name from the method registry"},
      {"method", "newton_tolerance", "number", format_number(d.newton_tolerance),
       "relative Newton tolerance"},
      {"method", "newton_max_iterations", "integer", std::to_string(d.newton_max_iterations),
       "Newton iterations per step"},
      {"method", "history", "string", quoted(d.history), "auto, direct or fast"},
      {"method", "history_tolerance", "number", format_number(d.history_tolerance),
       "fast-history accuracy"},
      {"method", "linear_solver", "string", quoted(d.linear_solver),
       "auto, dense, banded or sparse"},
      {"method", "threads", "integer", std::to_string(d.threads), "OpenMP threads; 0 = all"},
      {"output", "every", "integer", std::to_string(d.every), "store every n-th state"},
      {"reference", "position", "array of d strings", "—", "exact x(t), one formula per component"},
  };
}

}  // namespace

const std::vector<ProblemField>& problem_schema() {
  static const std::vector<ProblemField> schema = make_schema();
  return schema;
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

}  // namespace fracvi
