#include "fracvi/model/expression_potential.hpp"

#include <atomic>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

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

Expression build(Eigen::Index d, const std::string& potential,
                 const std::vector<std::string>& force) {
  const auto names = all_names(d);
  // Parse each piece on its own first, so that an error points into the text the user wrote.
  Expression::parse(potential, names);
  if (force.empty()) return Expression::parse(potential, names);
  if (static_cast<Eigen::Index>(force.size()) != d) {
    throw std::invalid_argument("force has " + std::to_string(force.size()) +
                                " components, the dimension is " + std::to_string(d));
  }
  parse_expressions(force, {"t"});
  std::string text = "(" + potential + ")";
  for (Eigen::Index i = 0; i < d; ++i) {
    text += " - (" + force[static_cast<std::size_t>(i)] + ")*x" + std::to_string(i + 1);
  }
  return Expression::parse(text, names);
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

ExpressionPotential::ExpressionPotential(Eigen::Index dimension, const std::string& potential,
                                         const std::vector<std::string>& force)
    : dimension_(dimension),
      derivatives_(build(dimension, potential, force), position_indices(dimension)),
      time_dependent_(derivatives_.expression().depends_on(static_cast<std::size_t>(dimension))),
      id_(next_id()) {}

ExpressionPotential::Scratch& ExpressionPotential::scratch(
    const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
  thread_local std::unordered_map<std::uint64_t, Scratch> per_object;
  auto [it, inserted] = per_object.try_emplace(id_);
  Scratch& s = it->second;
  if (inserted) {
    s.args.resize(static_cast<std::size_t>(dimension_) + 1);
    s.gradient.resize(static_cast<std::size_t>(dimension_));
    s.workspace = derivatives_.make_workspace();
  }
  for (Eigen::Index i = 0; i < dimension_; ++i) s.args[static_cast<std::size_t>(i)] = x[i];
  s.args.back() = t;
  return s;
}

double ExpressionPotential::value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
  Scratch& s = scratch(x, t);
  return derivatives_.evaluate(s.args, s.workspace);
}

void ExpressionPotential::gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                                   Eigen::Ref<Eigen::VectorXd> g) const {
  Scratch& s = scratch(x, t);
  derivatives_.evaluate(s.args, std::span<double>(g.data(), static_cast<std::size_t>(g.size())),
                        s.workspace);
}

void ExpressionPotential::hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                                  Eigen::Ref<Eigen::MatrixXd> H) const {
  Scratch& s = scratch(x, t);
  derivatives_.evaluate_dense(s.args, s.gradient, H, s.workspace);
}

}  // namespace fracvi
