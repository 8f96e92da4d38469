#include "fracvi/schemes/registry.hpp"

#include <array>
#include <cmath>
#include <string>

#include "fracvi/core/error.hpp"
#include "scheme_rows.hpp"

namespace fracvi {

namespace {

// One line per scheme.
constexpr std::array<const SchemeInfo*, 12> kSchemes{
    &internal::kFviGl,           &internal::kFviBdf2,       &internal::kFviMidpoint,
    &internal::kFviLobatto2,     &internal::kFviLobatto3,   &internal::kFviLobatto4,
    &internal::kEulerExplicit,   &internal::kEulerImplicit, &internal::kLdaMidpoint,
    &internal::kConformalStrang, &internal::kDopri5,        &internal::kPiTrapezoid,
};

}  // namespace

std::optional<ForcingLoad> parse_forcing_load(std::string_view name) {
  if (name == "pointwise") return ForcingLoad::kPointwise;
  if (name == "moments") return ForcingLoad::kMoments;
  return std::nullopt;
}

std::string_view to_string(ForcingLoad load) {
  return load == ForcingLoad::kMoments ? "moments" : "pointwise";
}

std::optional<TaylorSplit> parse_taylor_split(std::string_view name) {
  if (name == "taylor") return TaylorSplit::kTaylor;
  if (name == "series") return TaylorSplit::kSeries;
  return std::nullopt;
}

std::string_view to_string(TaylorSplit split) {
  return split == TaylorSplit::kSeries ? "series" : "taylor";
}

std::optional<ErrorEstimateKind> parse_error_estimate(std::string_view name) {
  if (name == "richardson") return ErrorEstimateKind::kRichardson;
  if (name == "none") return ErrorEstimateKind::kNone;
  return std::nullopt;
}

std::string_view to_string(ErrorEstimateKind kind) {
  return kind == ErrorEstimateKind::kRichardson ? "richardson" : "none";
}

std::span<const SchemeInfo* const> registered_schemes() {
  return kSchemes;
}

const SchemeInfo* find_scheme(std::string_view name) {
  for (const SchemeInfo* info : kSchemes)
    if (info->name == name) return info;
  return nullptr;
}

std::string scheme_names() {
  std::string names;
  for (const SchemeInfo* info : kSchemes) {
    if (!names.empty()) names += ", ";
    names += info->name;
  }
  return names;
}

std::vector<SchemeRow> scheme_table() {
  std::vector<SchemeRow> rows;
  for (const SchemeInfo* info : kSchemes) {
    rows.push_back({std::string(info->name), std::string(info->order_rule),
                    std::string(info->applies_to), std::string(info->stability_rule),
                    std::string(info->summary), std::string(info->reference), info->stages,
                    info->variational, info->has_mirror, info->exact_balance, info->fast_history,
                    info->adaptive});
  }
  return rows;
}

Method::Method() : info_(&internal::kFviGl) {}

Method fvi_gl() {
  return Method(internal::kFviGl);
}
Method fvi_bdf2() {
  return Method(internal::kFviBdf2);
}

std::optional<Method> parse_method(std::string_view name) {
  if (const SchemeInfo* info = find_scheme(name)) return Method(*info);
  return std::nullopt;
}

std::string scheme_names_with(bool SchemeInfo::*property) {
  std::string names;
  for (const SchemeInfo* info : kSchemes) {
    if (!(info->*property)) continue;
    if (!names.empty()) names += ", ";
    names += info->name;
  }
  return names;
}

std::string boundary_value_scheme_names() {
  std::string names;
  for (const SchemeInfo* info : kSchemes) {
    if (!info->variational_quadrature) continue;
    if (!names.empty()) names += ", ";
    names += info->name;
  }
  return names;
}

CqScheme boundary_value_quadrature(const SchemeInfo& info) {
  if (info.variational_quadrature) return *info.variational_quadrature;
  throw ValidationError(
      "method.scheme = \"" + std::string(info.name) +
      "\" has no boundary value form (schemes with one: " + boundary_value_scheme_names() + ")");
}

void check_applicable(const InitialValueProblem& problem, const Method& method,
                      const IntegratorOptions& options) {
  const SchemeInfo& info = method.info();
  if (const std::string rule = info.applicability(problem); !rule.empty()) {
    throw ValidationError("method.scheme = \"" + std::string(info.name) +
                          "\" does not apply to this problem: " + rule);
  }
  if (problem.model.state_force && !info.no_state_force.empty()) {
    std::string with;
    for (const SchemeInfo* scheme : registered_schemes()) {
      if (!scheme->no_state_force.empty()) continue;
      with += (with.empty() ? "" : ", ") + std::string(scheme->name);
    }
    throw ValidationError("method.scheme = \"" + std::string(info.name) +
                          "\" does not take a force g(x, v, t) (model.force mentions x or v): " +
                          std::string(info.no_state_force) + " (schemes that do: " + with + ")");
  }
  if (options.history == HistoryKind::kFast && !info.fast_history && !problem.model.is_undamped()) {
    throw ValidationError("method.history = \"fast\" is not available for method.scheme = \"" +
                          std::string(info.name) +
                          "\" (no fast memory for its weights): use \"auto\" (the direct sum for "
                          "this scheme) or \"direct\"");
  }
  if (options.start == StartValue::kExplicitEuler && !info.explicit_euler_start) {
    throw ValidationError(
        "start = \"euler\" (x_1 = x_0 + h v_0) is not available for "
        "method.scheme = \"" +
        std::string(info.name) +
        "\" (schemes with it: " + scheme_names_with(&SchemeInfo::explicit_euler_start) +
        "); its own start keeps its order: use \"legendre\"");
  }
  if (options.load == ForcingLoad::kMoments && !info.forcing_moments) {
    const std::string with = scheme_names_with(&SchemeInfo::forcing_moments);
    throw ValidationError("method.load = \"moments\" is not available for method.scheme = \"" +
                          std::string(info.name) + "\" (schemes with it: " + with +
                          "); use \"pointwise\"");
  }
  if (options.split == TaylorSplit::kSeries && !info.series_split) {
    const std::string with = scheme_names_with(&SchemeInfo::series_split);
    throw ValidationError("method.split = \"series\" is not available for method.scheme = \"" +
                          std::string(info.name) + "\" (schemes with it: " + with +
                          "); use \"taylor\"");
  }
  const StabilityBound bound = info.stability(problem);
  if (bound.stable) return;
  std::string advice;
  if (bound.largest_step > 0.0 && std::isfinite(bound.largest_step)) {
    const double span = problem.t_end - problem.t0;
    const double steps = std::floor(span / bound.largest_step) + 1.0;
    advice = "; the largest stable step is h < " + format_number(bound.largest_step) +
             ", i.e. time.steps >= " + format_number(steps);
  } else {
    advice = "; no step size is stable for this problem (use another scheme)";
  }
  throw ValidationError("time.steps = " + std::to_string(problem.steps) + " (h = " +
                        format_number(problem.step_size()) + ") is beyond the stability bound of " +
                        std::string(info.name) + ": " + bound.rule + advice);
}

std::string_view auto_scheme_rule() {
  return "the first of fvi-lobatto3, fvi-midpoint, fvi-bdf2, fvi-gl that applies to the problem "
         "and is stable at its step (docs/comparison.md)";
}

Method choose_scheme(const InitialValueProblem& problem, const IntegratorOptions& options,
                     const std::function<bool(const SchemeInfo&)>& admissible) {
  const SchemeInfo* const candidates[] = {&internal::kFviLobatto3, &internal::kFviMidpoint,
                                          &internal::kFviBdf2, &internal::kFviGl};
  for (std::size_t i = 0; i < std::size(candidates); ++i) {
    // fvi-gl, the last resort, is tried whatever `admissible` says: its refusal names the rule.
    if (admissible && i + 1 < std::size(candidates) && !admissible(*candidates[i])) continue;
    const Method method(*candidates[i]);
    try {
      check_applicable(problem, method, options);
      return method;
    } catch (const ValidationError&) {
      if (i + 1 == std::size(candidates)) throw;  // none applies: the paper's scheme's reason
    }
  }
  return Method();  // unreachable
}

}  // namespace fracvi
