#include "fracvi/model/expression_potential.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace fracvi {

namespace {

std::uint64_t next_id() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

std::vector<std::string> all_names(Eigen::Index d) {
  auto names = ExpressionPotential::position_names(d);
  names.push_back("t");
  return names;
}

std::vector<std::size_t> position_indices(Eigen::Index d) {
  std::vector<std::size_t> wrt(static_cast<std::size_t>(d));
  std::iota(wrt.begin(), wrt.end(), std::size_t{0});
  return wrt;
}

}  // namespace

std::vector<std::string> ExpressionPotential::position_names(Eigen::Index dimension) {
  std::vector<std::string> names;
  names.reserve(static_cast<std::size_t>(dimension));
  for (Eigen::Index i = 1; i <= dimension; ++i) names.push_back("x" + std::to_string(i));
  return names;
}

ExpressionPotential::ExpressionPotential(Eigen::Index dimension, const std::string& potential)
    : dimension_(dimension),
      derivatives_(Expression::parse(potential, all_names(dimension)), position_indices(dimension)),
      time_dependent_(derivatives_.expression().depends_on(static_cast<std::size_t>(dimension))),
      kinks_(derivatives_.expression().has_kinks_in(derivatives_.wrt())),
      id_(next_id()) {
  if (derivatives_.hessian_is_constant() && !time_dependent_ && !kinks_) set_up_affine_gradient();
}

void ExpressionPotential::set_up_affine_gradient() {
  const Eigen::Index d = dimension_;
  const auto n = static_cast<std::size_t>(d);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(d);
  Eigen::VectorXd b(d);
  gradient(zero, 0.0, b);  // the tape (affine_gradient_ is still false)
  const std::vector<HessianEntry> pattern = hessian_pattern();
  std::vector<double> values(pattern.size());
  hessian_values(zero, 0.0, values);
  if (!b.allFinite()) return;
  // K's rows, both triangles, columns ascending within a row.
  std::vector<std::vector<std::pair<Eigen::Index, double>>> rows(n);
  for (std::size_t e = 0; e < pattern.size(); ++e) {
    if (!std::isfinite(values[e])) return;
    rows[static_cast<std::size_t>(pattern[e].row)].emplace_back(pattern[e].col, values[e]);
    if (pattern[e].row != pattern[e].col)
      rows[static_cast<std::size_t>(pattern[e].col)].emplace_back(pattern[e].row, values[e]);
  }
  row_start_.assign(1, 0);
  for (auto& row : rows) {
    std::sort(row.begin(), row.end());
    for (const auto& [col, value] : row) {
      stiffness_col_.push_back(col);
      stiffness_value_.push_back(value);
    }
    row_start_.push_back(static_cast<Eigen::Index>(stiffness_col_.size()));
  }
  gradient_at_zero_.assign(b.data(), b.data() + d);
  // The check at x_i = 1 + i/d: b + Kx against the tape, to round-off of the terms' sizes. A
  // formula that passed the symbolic test but is not affine in its gradient keeps the tape.
  Eigen::VectorXd x(d), tape(d), affine(d);
  for (Eigen::Index i = 0; i < d; ++i) x(i) = 1.0 + static_cast<double>(i) / static_cast<double>(d);
  gradient(x, 0.0, tape);
  affine_gradient_ = true;
  gradient(x, 0.0, affine);
  for (Eigen::Index i = 0; i < d; ++i) {
    double size = std::abs(b(i));
    for (Eigen::Index k = row_start_[static_cast<std::size_t>(i)];
         k < row_start_[static_cast<std::size_t>(i) + 1]; ++k) {
      size += std::abs(stiffness_value_[static_cast<std::size_t>(k)]) *
              std::abs(x(stiffness_col_[static_cast<std::size_t>(k)]));
    }
    if (!(std::abs(tape(i) - affine(i)) <= 64.0 * std::numeric_limits<double>::epsilon() * size)) {
      affine_gradient_ = false;
      return;
    }
  }
}

ExpressionPotential::Scratch& ExpressionPotential::scratch(
    const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
  // The last object's scratch, so that a run's calls (one potential, several per step) skip the
  // hash lookup (≈ 4 % of a d = 1 step, perf). A map keeps the addresses of its elements when it
  // grows, and ids are never reused.
  thread_local std::uint64_t last_id = 0;
  thread_local Scratch* last = nullptr;
  if (last == nullptr || last_id != id_) {
    // Declared here, not above: a thread_local with a constructor costs a call to its guard on
    // every pass over its declaration, the plain pointers above only a load.
    thread_local std::unordered_map<std::uint64_t, Scratch> per_object;
    auto [it, inserted] = per_object.try_emplace(id_);
    Scratch& fresh = it->second;
    if (inserted) {
      fresh.gradient.resize(static_cast<std::size_t>(dimension_));
      fresh.workspace = derivatives_.make_workspace();
    }
    last_id = id_;
    last = &fresh;
  }
  Scratch& s = *last;
  const std::span<double> args = s.workspace.values();
  for (Eigen::Index i = 0; i < dimension_; ++i) args[static_cast<std::size_t>(i)] = x[i];
  args.back() = t;
  return s;
}

double ExpressionPotential::value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
  Scratch& s = scratch(x, t);
  return derivatives_.evaluate(s.workspace.values(), s.workspace);
}

void ExpressionPotential::gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                                   Eigen::Ref<Eigen::VectorXd> g) const {
  if (affine_gradient_) {  // b_i + Σ_k K_ik x_k, columns ascending
    for (Eigen::Index i = 0; i < dimension_; ++i) {
      double sum = gradient_at_zero_[static_cast<std::size_t>(i)];
      for (Eigen::Index k = row_start_[static_cast<std::size_t>(i)];
           k < row_start_[static_cast<std::size_t>(i) + 1]; ++k) {
        sum += stiffness_value_[static_cast<std::size_t>(k)] *
               x[stiffness_col_[static_cast<std::size_t>(k)]];
      }
      g[i] = sum;
    }
    return;
  }
  Scratch& s = scratch(x, t);
  derivatives_.gradient(s.workspace.values(),
                        std::span<double>(g.data(), static_cast<std::size_t>(g.size())),
                        s.workspace);
}

void ExpressionPotential::hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                                  Eigen::Ref<Eigen::MatrixXd> H) const {
  Scratch& s = scratch(x, t);
  derivatives_.evaluate_dense(s.workspace.values(), s.gradient, H, s.workspace);
}

std::vector<Potential::HessianEntry> ExpressionPotential::hessian_pattern() const {
  std::vector<HessianEntry> pattern;
  pattern.reserve(derivatives_.hessian_pattern().size());
  for (const auto& e : derivatives_.hessian_pattern()) {
    pattern.push_back({static_cast<Eigen::Index>(e.row), static_cast<Eigen::Index>(e.col)});
  }
  return pattern;
}

void ExpressionPotential::hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                                         std::span<double> values) const {
  Scratch& s = scratch(x, t);
  derivatives_.evaluate(s.workspace.values(), s.gradient, values, s.workspace);
}

namespace {

Forcing forcing_of(std::vector<Expression> formulas) {
  auto components = std::make_shared<const std::vector<Expression>>(std::move(formulas));
  return [components](double t, Eigen::Ref<Eigen::VectorXd> out) {
    const double args[] = {t};
    for (std::size_t i = 0; i < components->size(); ++i)
      out[static_cast<Eigen::Index>(i)] = (*components)[i](args);
  };
}

}  // namespace

Forcing make_expression_forcing(const std::vector<std::string>& force) {
  if (force.empty()) return {};
  return forcing_of(parse_expressions(force, {"t"}));
}

std::vector<std::string> ExpressionForce::variable_names(Eigen::Index dimension) {
  std::vector<std::string> names = ExpressionPotential::position_names(dimension);
  for (Eigen::Index i = 1; i <= dimension; ++i) names.push_back("v" + std::to_string(i));
  names.push_back("t");
  return names;
}

ExpressionForce::ExpressionForce(Eigen::Index dimension, const std::vector<std::string>& force)
    : dimension_(dimension), id_(next_id()) {
  if (static_cast<Eigen::Index>(force.size()) != dimension) {
    throw std::invalid_argument("force has " + std::to_string(force.size()) +
                                " components, the model's dimension is " +
                                std::to_string(dimension));
  }
  // Gradients with respect to x1..xd, v1..vd (not t): row i of ∂g/∂x and ∂g/∂v.
  const std::vector<std::size_t> wrt = position_indices(2 * dimension);
  for (const Expression& e : parse_expressions(force, variable_names(dimension)))
    components_.emplace_back(e, wrt);
  // The constructing thread's workspace now, so that the step loop (usually on this thread) does
  // not allocate it on its first evaluation.
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(dimension);
  scratch(zero, zero, 0.0);
}

ExpressionForce::Scratch& ExpressionForce::scratch(const Eigen::Ref<const Eigen::VectorXd>& x,
                                                   const Eigen::Ref<const Eigen::VectorXd>& v,
                                                   double t) const {
  thread_local std::unordered_map<std::uint64_t, Scratch> per_object;
  auto [it, inserted] = per_object.try_emplace(id_);
  Scratch& s = it->second;
  const auto d = static_cast<std::size_t>(dimension_);
  if (inserted) {
    s.args.resize(2 * d + 1);
    s.gradient.resize(2 * d);
    for (const CompiledDerivatives& c : components_) s.workspaces.push_back(c.make_workspace());
  }
  for (std::size_t i = 0; i < d; ++i) {
    s.args[i] = x[static_cast<Eigen::Index>(i)];
    s.args[d + i] = v[static_cast<Eigen::Index>(i)];
  }
  s.args.back() = t;
  return s;
}

void ExpressionForce::value(const Eigen::Ref<const Eigen::VectorXd>& x,
                            const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                            Eigen::Ref<Eigen::VectorXd> out) const {
  Scratch& s = scratch(x, v, t);
  for (std::size_t i = 0; i < components_.size(); ++i)
    out[static_cast<Eigen::Index>(i)] = components_[i].evaluate(s.args, s.workspaces[i]);
}

void ExpressionForce::jacobians(const Eigen::Ref<const Eigen::VectorXd>& x,
                                const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                                Eigen::Ref<Eigen::VectorXd> out, Eigen::Ref<Eigen::MatrixXd> dx,
                                Eigen::Ref<Eigen::MatrixXd> dv) const {
  Scratch& s = scratch(x, v, t);
  for (std::size_t i = 0; i < components_.size(); ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    out[row] = components_[i].evaluate(s.args, s.gradient, s.workspaces[i]);
    for (Eigen::Index j = 0; j < dimension_; ++j) {
      dx(row, j) = s.gradient[static_cast<std::size_t>(j)];
      dv(row, j) = s.gradient[static_cast<std::size_t>(dimension_ + j)];
    }
  }
}

ExpressionForces make_expression_forces(Eigen::Index dimension,
                                        const std::vector<std::string>& force) {
  if (force.empty()) return {};
  // Formulas in t alone (they parse with t as the only variable) keep the f(t) path to the bit.
  bool in_t_alone = true;
  for (const std::string& text : force) {
    try {
      Expression::parse(text, {"t"});
    } catch (const ExpressionError&) {
      in_t_alone = false;
      break;
    }
  }
  if (in_t_alone) {
    std::vector<Expression> formulas = parse_expressions(force, {"t"});
    return {forcing_of(formulas), nullptr, std::move(formulas)};
  }
  return {{}, std::make_shared<const ExpressionForce>(dimension, force), {}};
}

}  // namespace fracvi
