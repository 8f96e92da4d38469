// Shared by `fracvi residual` and `fracvi action`: the problem's Lagrangian and curves given as
// formulas on the command line.
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi::cli {

namespace {

// Splits "f1, f2" at the commas that are not inside parentheses (pow(a, b) stays whole).
std::vector<std::string> split_formulas(const std::string& text) {
  std::vector<std::string> parts(1);
  int depth = 0;
  for (char c : text) {
    if (c == '(') ++depth;
    if (c == ')') --depth;
    if (c == ',' && depth == 0) {
      parts.emplace_back();
    } else {
      parts.back() += c;
    }
  }
  return parts;
}

}  // namespace

Curve parse_curve(const std::string& flag, const std::string& text, Eigen::Index d) {
  const auto formulas = split_formulas(text);
  if (static_cast<Eigen::Index>(formulas.size()) != d) {
    throw UsageError(flag + " = \"" + text + "\" has " + std::to_string(formulas.size()) +
                     " components, model.dim is " + std::to_string(d) +
                     " (give d formulas in t separated by commas)");
  }
  try {
    return make_expression_curve(formulas);
  } catch (const ExpressionError& e) {
    throw UsageError(flag + " = \"" + text + "\": " + e.reason() + " at column " +
                     std::to_string(e.column() + 1) + " (formulas in t)");
  }
}

LagrangianProblem load_lagrangian_problem(const std::string& file,
                                          const std::vector<std::string>& overrides) {
  LagrangianProblem out;
  try {
    out.spec = load_problem(file, overrides);
    out.lagrangian = make_lagrangian(out.spec);
  } catch (const ProblemFileError& e) {
    throw UsageError(e.what());
  } catch (const ExpressionError& e) {
    throw UsageError(out.spec.source + ": " + e.reason() + " at column " +
                     std::to_string(e.column() + 1));
  } catch (const ValidationError& e) {
    throw UsageError(out.spec.source + ": " + e.what());
  }
  return out;
}

}  // namespace fracvi::cli
