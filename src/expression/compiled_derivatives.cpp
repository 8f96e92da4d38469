// CompiledDerivatives: value + gradient + sparse Hessian on one tape.
#include <algorithm>
#include <numeric>
#include <unordered_set>

#include "graph.hpp"

namespace fracvi {

namespace {

std::vector<std::size_t> all_variables(const Expression& f) {
  std::vector<std::size_t> v(f.variables().size());
  std::iota(v.begin(), v.end(), std::size_t{0});
  return v;
}

}  // namespace

CompiledDerivatives::CompiledDerivatives(const Expression& f)
    : CompiledDerivatives(f, all_variables(f)) {}

CompiledDerivatives::CompiledDerivatives(const Expression& f, std::vector<std::size_t> wrt)
    : f_(f), wrt_(std::move(wrt)) {
  using internal::NodeId;
  const std::size_t n = f.variables().size(), m = wrt_.size();
  std::unordered_set<std::size_t> seen;
  for (std::size_t v : wrt_) {
    if (v >= n)
      throw std::invalid_argument("CompiledDerivatives: variable index " + std::to_string(v) +
                                  " out of range (" + std::to_string(n) + " variables)");
    if (!seen.insert(v).second)
      throw std::invalid_argument("CompiledDerivatives: variable '" + f.variables()[v] +
                                  "' listed twice");
  }

  const internal::ExpressionData& data = *f.data_;
  internal::Builder builder(data.nodes, n);
  const std::vector<NodeId> full_gradient = builder.gradient(data.root);  // one reverse sweep
  std::vector<NodeId> gradient(m);
  for (std::size_t k = 0; k < m; ++k) {
    gradient[k] = full_gradient[wrt_[k]];
    if (!builder.is_constant(gradient[k], 0.0)) gradient_pattern_.push_back(k);
  }

  // Hessian entries (k, l), k <= l, column by column: ∂g_k/∂x_l for all candidate k in one
  // forward sweep (forward-over-reverse), so subexpressions shared by several gradient entries
  // are differentiated once. g_k can depend on x_l only if x_l lies in g_k's dependence
  // interval; with the coordinates sorted by variable index that is a contiguous range, so a
  // banded (chain) Hessian has O(d) candidates, not O(d²).
  std::vector<std::size_t> by_var(m);
  std::iota(by_var.begin(), by_var.end(), std::size_t{0});
  std::sort(by_var.begin(), by_var.end(),
            [&](std::size_t x, std::size_t y) { return wrt_[x] < wrt_[y]; });
  struct Entry {
    HessianEntry at;
    NodeId id;
  };
  std::vector<std::vector<std::size_t>> rows_of(m);  // candidate rows k of column l
  for (std::size_t k : gradient_pattern_) {
    const internal::Node& g = builder.node(gradient[k]);
    if (g.lo > g.hi) continue;
    const auto lo = static_cast<std::size_t>(g.lo), hi = static_cast<std::size_t>(g.hi);
    auto it = std::lower_bound(by_var.begin(), by_var.end(), lo,
                               [&](std::size_t x, std::size_t v) { return wrt_[x] < v; });
    for (; it != by_var.end() && wrt_[*it] <= hi; ++it)
      if (*it >= k) rows_of[*it].push_back(k);
  }
  std::vector<Entry> entries;
  std::vector<NodeId> roots;
  for (std::size_t l = 0; l < m; ++l) {
    if (rows_of[l].empty()) continue;
    roots.clear();
    for (std::size_t k : rows_of[l]) roots.push_back(gradient[k]);
    const std::vector<NodeId> column = builder.derivative(roots, wrt_[l]);
    for (std::size_t i = 0; i < column.size(); ++i) {
      if (builder.is_constant(column[i], 0.0)) continue;
      entries.push_back({{rows_of[l][i], l}, column[i]});
      if (!builder.is_constant(column[i])) hessian_is_constant_ = false;
    }
  }
  // A Hessian that simplified to constants is also what a piecewise-linear U leaves: abs, sign,
  // max, floor … differentiate to piecewise constants and then to 0, although the gradient jumps.
  // Only a polynomial in wrt() (of degree ≤ 2, then) has a constant Hessian everywhere.
  if (hessian_is_constant_ && !f.polynomial_degree(wrt_)) hessian_is_constant_ = false;
  std::sort(entries.begin(), entries.end(), [](const Entry& x, const Entry& y) {
    return x.at.row != y.at.row ? x.at.row < y.at.row : x.at.col < y.at.col;
  });
  std::vector<NodeId> hessian;
  hessian.reserve(entries.size());
  for (const Entry& e : entries) {
    hessian_pattern_.push_back(e.at);
    hessian.push_back(e.id);
  }
  program_ = std::make_shared<const internal::Program>(
      internal::compile(builder.nodes(), n, data.root, gradient, hessian));
  tape_variables_ = program_->num_variables;
  workspace_ = make_workspace();
}

std::size_t CompiledDerivatives::tape_size() const {
  return program_->hessian_code.size();
}

CompiledDerivatives::Workspace CompiledDerivatives::make_workspace() const {
  Workspace ws;
  ws.slots_.assign(program_->num_slots, 0.0);
  internal::fill_constants(*program_, ws.slots_);
  ws.owner_ = program_.get();
  ws.variables_ = program_->num_variables;
  return ws;
}

void CompiledDerivatives::throw_mismatch(std::size_t values) const {
  if (values != program_->num_variables)
    throw std::invalid_argument("CompiledDerivatives: got " + std::to_string(values) +
                                " values for " + std::to_string(num_variables()) + " variables");
  throw std::invalid_argument(
      "CompiledDerivatives: the workspace was not made by this object (make_workspace())");
}

double CompiledDerivatives::evaluate(std::span<const double> values, Workspace& ws) const {
  check(values, ws);
  double* s = ws.slots_.data();
  internal::run(*program_, program_->value_code, values.data(), s);
  return s[program_->value_slot];
}

const double* CompiledDerivatives::run_gradient(std::span<const internal::Instruction> code,
                                                std::span<const double> values,
                                                std::span<double> gradient, Workspace& ws) const {
  check(values, ws);
  if (gradient.size() != gradient_size())
    throw std::invalid_argument("CompiledDerivatives: gradient has size " +
                                std::to_string(gradient.size()) + ", expected " +
                                std::to_string(gradient_size()));
  double* s = ws.slots_.data();
  internal::run(*program_, code, values.data(), s);
  for (std::size_t k = 0; k < gradient.size(); ++k) gradient[k] = s[program_->gradient_slots[k]];
  return s;
}

double CompiledDerivatives::evaluate(std::span<const double> values, std::span<double> gradient,
                                     Workspace& ws) const {
  return run_gradient(program_->gradient_code, values, gradient, ws)[program_->value_slot];
}

void CompiledDerivatives::gradient(std::span<const double> values, std::span<double> gradient,
                                   Workspace& ws) const {
  run_gradient(program_->gradient_only_code, values, gradient, ws);
}

double CompiledDerivatives::evaluate(std::span<const double> values, std::span<double> gradient,
                                     std::span<double> hessian_values, Workspace& ws) const {
  check(values, ws);
  if (gradient.size() != gradient_size() || hessian_values.size() != hessian_pattern_.size())
    throw std::invalid_argument(
        "CompiledDerivatives: gradient/Hessian sizes " + std::to_string(gradient.size()) + "/" +
        std::to_string(hessian_values.size()) + ", expected " + std::to_string(gradient_size()) +
        "/" + std::to_string(hessian_pattern_.size()));
  double* s = ws.slots_.data();
  internal::run(*program_, program_->hessian_code, values.data(), s);
  for (std::size_t k = 0; k < gradient.size(); ++k) gradient[k] = s[program_->gradient_slots[k]];
  for (std::size_t e = 0; e < hessian_values.size(); ++e)
    hessian_values[e] = s[program_->hessian_slots[e]];
  return s[program_->value_slot];
}

double CompiledDerivatives::evaluate_dense(std::span<const double> values,
                                           std::span<double> gradient,
                                           Eigen::Ref<Eigen::MatrixXd> hessian,
                                           Workspace& ws) const {
  check(values, ws);
  const auto m = static_cast<Eigen::Index>(gradient_size());
  if (gradient.size() != gradient_size() || hessian.rows() != m || hessian.cols() != m)
    throw std::invalid_argument("CompiledDerivatives: gradient/Hessian shape does not match " +
                                std::to_string(gradient_size()) + " coordinates");
  double* s = ws.slots_.data();
  internal::run(*program_, program_->hessian_code, values.data(), s);
  for (std::size_t k = 0; k < gradient.size(); ++k) gradient[k] = s[program_->gradient_slots[k]];
  hessian.setZero();
  for (std::size_t e = 0; e < hessian_pattern_.size(); ++e) {
    const auto r = static_cast<Eigen::Index>(hessian_pattern_[e].row);
    const auto c = static_cast<Eigen::Index>(hessian_pattern_[e].col);
    hessian(r, c) = hessian(c, r) = s[program_->hessian_slots[e]];
  }
  return s[program_->value_slot];
}

}  // namespace fracvi
