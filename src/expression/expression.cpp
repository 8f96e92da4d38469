// Expression: parsing entry points, evaluation, derivatives, printing, polynomial degree.
#include <algorithm>
#include <charconv>
#include <climits>
#include <cmath>
#include <map>
#include <numbers>

#include "graph.hpp"

namespace fracvi {

namespace internal {

std::shared_ptr<const ExpressionData> make_expression_data(const Builder& builder, NodeId root,
                                                           std::string text,
                                                           std::vector<std::string> variables) {
  auto data = std::make_shared<ExpressionData>();
  data->nodes = extract(builder.nodes(), std::span(&root, 1));
  data->root = root;
  data->program = compile(data->nodes, variables.size(), root, {}, {});
  data->depends.assign(variables.size(), false);
  for (const Node& n : data->nodes)
    if (n.op == Op::kVar) data->depends[static_cast<std::size_t>(n.b)] = true;
  data->text = std::move(text);
  data->variables = std::move(variables);
  return data;
}

namespace {

// Binding strength for printing: a child is parenthesised when it binds less tightly than its
// position requires. Right operands of left-associative operators need strictly tighter
// binding, so the printed text re-parses to the same tree (a - (b - c), a/(b*c)).
constexpr int kPrecAdd = 1, kPrecMul = 2, kPrecUnary = 3, kPrecPow = 4, kPrecAtom = 5;

int precedence(const Node& n) {
  switch (n.op) {
    case Op::kConst: return n.value < 0 ? kPrecUnary : kPrecAtom;
    case Op::kAdd:
    case Op::kSub: return kPrecAdd;
    case Op::kMul:
    case Op::kDiv: return kPrecMul;
    case Op::kNeg: return kPrecUnary;
    case Op::kPow:
    case Op::kPowInt: return kPrecPow;
    default: return kPrecAtom;
  }
}

std::string format_number(double v) {
  if (v == std::numbers::pi) return "pi";
  if (v == std::numbers::e) return "e";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
  return std::string(buf, r.ptr);
}

class Printer {
 public:
  Printer(const std::vector<Node>& nodes, const std::vector<std::string>& variables)
      : nodes_(nodes), variables_(variables) {}

  void print(NodeId id, std::string& out) const {
    const Node& n = nodes_[static_cast<std::size_t>(id)];
    switch (n.op) {
      case Op::kConst: out += format_number(n.value); return;
      case Op::kVar: out += variables_[static_cast<std::size_t>(n.b)]; return;
      case Op::kAdd:
      case Op::kSub:
      case Op::kMul:
      case Op::kDiv: return left_chain(id, out);
      case Op::kPow:
        operand(n.a, kPrecAtom, out);
        out += '^';
        return operand(n.b, kPrecUnary, out);
      case Op::kNeg: out += '-'; return operand(n.a, kPrecUnary, out);
      case Op::kPowInt:
        operand(n.a, kPrecAtom, out);
        out += '^' + std::to_string(n.b);
        return;
      default:
        out += function_name(n.op);
        out += '(';
        print(n.a, out);
        if (is_binary(n.op)) {
          out += ", ";
          print(n.b, out);
        }
        out += ')';
    }
  }

 private:
  void operand(NodeId id, int min_prec, std::string& out) const {
    const bool parens = precedence(nodes_[static_cast<std::size_t>(id)]) < min_prec;
    if (parens) out += '(';
    print(id, out);
    if (parens) out += ')';
  }
  // a + b - c + ... is a left-deep tree as deep as it is long (a sum of 10^5 springs): walk
  // its left spine in a loop instead of recursing.
  void left_chain(NodeId id, std::string& out) const {
    const int prec = precedence(nodes_[static_cast<std::size_t>(id)]);
    std::vector<NodeId> spine;
    NodeId cur = id;
    for (;;) {
      const Node& n = nodes_[static_cast<std::size_t>(cur)];
      const bool infix =
          n.op == Op::kAdd || n.op == Op::kSub || n.op == Op::kMul || n.op == Op::kDiv;
      if (!infix || precedence(n) != prec) break;
      spine.push_back(cur);
      cur = n.a;
    }
    operand(cur, prec, out);
    for (auto it = spine.rbegin(); it != spine.rend(); ++it) {
      const Node& n = nodes_[static_cast<std::size_t>(*it)];
      out += n.op == Op::kAdd ? " + " : n.op == Op::kSub ? " - " : n.op == Op::kMul ? "*" : "/";
      operand(n.b, prec + 1, out);
    }
  }

  const std::vector<Node>& nodes_;
  const std::vector<std::string>& variables_;
};

constexpr long long kNotPolynomial = -1;

std::optional<int> degree_in(const ExpressionData& d, const std::vector<bool>& in_set) {
  const std::size_t n = d.nodes.size();
  std::vector<long long> deg(n, 0);
  std::vector<char> dep(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Node& node = d.nodes[i];
    const auto ua = static_cast<std::size_t>(node.a), ub = static_cast<std::size_t>(node.b);
    if (node.op == Op::kConst) continue;
    if (node.op == Op::kVar) {
      dep[i] = in_set[ub] ? 1 : 0;
      deg[i] = dep[i];
      continue;
    }
    dep[i] = static_cast<char>(dep[ua] || (is_binary(node.op) && dep[ub]));
    if (!dep[i]) continue;  // a coefficient: degree 0
    const long long da = deg[ua], db = is_binary(node.op) ? deg[ub] : 0;
    const bool both = da != kNotPolynomial && db != kNotPolynomial;
    long long r = kNotPolynomial;
    switch (node.op) {
      case Op::kAdd:
      case Op::kSub: r = both ? std::max(da, db) : kNotPolynomial; break;
      case Op::kMul: r = both ? da + db : kNotPolynomial; break;
      case Op::kNeg: r = da; break;
      case Op::kDiv: r = dep[ub] ? kNotPolynomial : da; break;
      case Op::kPowInt:
        r = (node.b >= 0 && da != kNotPolynomial) ? da * node.b : kNotPolynomial;
        break;
      default: break;  // transcendental or general power of something that varies
    }
    deg[i] = r == kNotPolynomial ? r : std::min<long long>(r, INT_MAX);
  }
  const long long root = deg[static_cast<std::size_t>(d.root)];
  if (root == kNotPolynomial) return std::nullopt;
  return static_cast<int>(root);
}

// power_laws(): every node as a finite sum Σ c_j u^{γ_j} in u = v − origin (a map γ → c, zero
// terms dropped), children before parents; nullopt for a node that is not one. Products and
// integer powers of sums are expanded, up to kMaxPowerLaws terms (beyond: nullopt).
using PowerSum = std::map<double, double>;
constexpr std::size_t kMaxPowerLaws = 64;

// Exponents that differ from an integer by round-off (t^(1/3)^3) are that integer, so that equal
// powers meet in one term.
double snap_exponent(double gamma) {
  const double whole = std::round(gamma);
  return std::abs(gamma - whole) < 1e-12 ? whole : gamma;
}

void add_term(PowerSum& sum, double gamma, double c) {
  const double key = snap_exponent(gamma);
  const double total = (sum[key] += c);
  if (total == 0.0) sum.erase(key);
}

std::optional<PowerSum> product(const PowerSum& a, const PowerSum& b) {
  if (a.size() * b.size() > kMaxPowerLaws * kMaxPowerLaws) return std::nullopt;
  PowerSum out;
  for (const auto& [ga, ca] : a)
    for (const auto& [gb, cb] : b) add_term(out, ga + gb, ca * cb);
  if (out.size() > kMaxPowerLaws) return std::nullopt;
  return out;
}

// (c u^γ)^p for one term: c^p u^{γp}; a negative c only for integer p (no complex values), 0^p
// only for p > 0.
std::optional<PowerSum> term_power(const PowerSum& a, double p) {
  if (a.empty()) return p > 0.0 ? std::optional<PowerSum>(PowerSum{}) : std::nullopt;
  if (a.size() != 1) return std::nullopt;
  const auto [gamma, c] = *a.begin();
  if (c < 0.0 && p != std::round(p)) return std::nullopt;
  PowerSum out;
  add_term(out, gamma * p, std::pow(c, p));
  return out;
}

std::optional<PowerSum> integer_power(const PowerSum& a, std::int32_t n) {
  if (a.size() <= 1 || n < 0) return term_power(a, n);
  PowerSum out{{0.0, 1.0}};
  for (std::int32_t i = 0; i < n; ++i) {
    auto next = product(out, a);
    if (!next) return std::nullopt;
    out = std::move(*next);
  }
  return out;
}

std::optional<PowerSum> power_sum_of(const ExpressionData& d, std::size_t var, double origin) {
  std::vector<std::optional<PowerSum>> sums(d.nodes.size());
  for (std::size_t i = 0; i < d.nodes.size(); ++i) {
    const Node& node = d.nodes[i];
    auto operand = [&](NodeId id) -> const std::optional<PowerSum>& {
      return sums[static_cast<std::size_t>(id)];
    };
    std::optional<PowerSum>& out = sums[i];
    if (node.op == Op::kConst) {
      out.emplace();
      add_term(*out, 0.0, node.value);
      continue;
    }
    if (node.op == Op::kVar) {
      if (static_cast<std::size_t>(node.b) != var) continue;  // another variable: not in v alone
      out.emplace();
      add_term(*out, 1.0, 1.0);
      add_term(*out, 0.0, origin);  // v = u + origin
      continue;
    }
    if (!operand(node.a) || (is_binary(node.op) && !operand(node.b))) continue;
    const PowerSum& a = *operand(node.a);
    switch (node.op) {
      case Op::kAdd:
      case Op::kSub: {
        out = a;
        const double sign = node.op == Op::kAdd ? 1.0 : -1.0;
        for (const auto& [gamma, c] : *operand(node.b)) add_term(*out, gamma, sign * c);
        if (out->size() > kMaxPowerLaws) out.reset();
        break;
      }
      case Op::kNeg:
        out = a;
        for (auto& term : *out) term.second = -term.second;
        break;
      case Op::kMul: out = product(a, *operand(node.b)); break;
      case Op::kDiv: {
        // By one term c u^γ only: multiplication by (c u^γ)^{−1}.
        const PowerSum& b = *operand(node.b);
        if (b.size() != 1) break;
        if (auto inverse = term_power(b, -1.0)) out = product(a, *inverse);
        break;
      }
      case Op::kPowInt: out = integer_power(a, node.b); break;
      case Op::kSqrt: out = term_power(a, 0.5); break;
      case Op::kPow: {
        const Node& exponent = d.nodes[static_cast<std::size_t>(node.b)];
        if (exponent.op == Op::kConst) out = term_power(a, exponent.value);
        break;
      }
      default: break;  // a transcendental function of u, or of a sum of powers
    }
  }
  return sums[static_cast<std::size_t>(d.root)];
}

}  // namespace
}  // namespace internal

using internal::ExpressionData;

Expression::Expression() {
  internal::Builder builder(0);
  data_ = internal::make_expression_data(builder, builder.constant(0.0), "0", {});
}

Expression::Expression(std::shared_ptr<const ExpressionData> data) : data_(std::move(data)) {}

Expression Expression::parse(std::string_view text, std::vector<std::string> variables) {
  internal::validate_variable_names(variables);
  internal::Builder builder(variables.size());
  const internal::NodeId root = internal::parse(text, variables, builder);
  return Expression(
      internal::make_expression_data(builder, root, std::string(text), std::move(variables)));
}

double Expression::operator()(std::span<const double> values) const {
  if (values.size() != data_->variables.size())
    throw std::invalid_argument("Expression: got " + std::to_string(values.size()) +
                                " values for " + std::to_string(data_->variables.size()) +
                                " variables");
  // One buffer per thread, grown to the largest expression seen: no allocation after warm-up.
  thread_local std::vector<double> scratch;
  const internal::Program& p = data_->program;
  if (scratch.size() < p.num_slots) scratch.resize(p.num_slots);
  internal::fill_constants(p, scratch);
  internal::run(p, p.value_code, values.data(), scratch.data());
  return scratch[static_cast<std::size_t>(p.value_slot)];
}

Expression Expression::derivative(std::size_t var) const {
  if (var >= data_->variables.size())
    throw std::invalid_argument("Expression::derivative: variable index " + std::to_string(var) +
                                " out of range (" + std::to_string(data_->variables.size()) +
                                " variables)");
  internal::Builder builder(data_->nodes, data_->variables.size());
  const internal::NodeId d = builder.derivative(data_->root, var);
  return Expression(internal::make_expression_data(builder, d, "", data_->variables));
}

Expression Expression::derivative(std::string_view variable) const {
  const auto index = variable_index(variable);
  if (!index)
    throw std::invalid_argument("Expression::derivative: '" + std::string(variable) +
                                "' is not a variable");
  return derivative(*index);
}

std::string Expression::to_string() const {
  std::string out;
  internal::Printer(data_->nodes, data_->variables).print(data_->root, out);
  return out;
}

const std::string& Expression::text() const {
  return data_->text;
}

const std::vector<std::string>& Expression::variables() const {
  return data_->variables;
}

std::optional<std::size_t> Expression::variable_index(std::string_view name) const {
  const auto& v = data_->variables;
  const auto it = std::find(v.begin(), v.end(), name);
  if (it == v.end()) return std::nullopt;
  return static_cast<std::size_t>(it - v.begin());
}

bool Expression::depends_on(std::size_t var) const {
  return var < data_->depends.size() && data_->depends[var];
}

bool Expression::is_constant() const {
  return data_->nodes[static_cast<std::size_t>(data_->root)].op == internal::Op::kConst;
}

std::optional<int> Expression::polynomial_degree() const {
  return internal::degree_in(*data_, std::vector<bool>(data_->variables.size(), true));
}

namespace {

// The variables `vars` as a mask over all of the expression's variables; `who` names the caller
// in the error for an index out of range.
std::vector<bool> variable_set(const ExpressionData& d, std::span<const std::size_t> vars,
                               const char* who) {
  std::vector<bool> in_set(d.variables.size(), false);
  for (std::size_t v : vars) {
    if (v >= in_set.size())
      throw std::invalid_argument(std::string("Expression::") + who + ": variable index " +
                                  std::to_string(v) + " out of range");
    in_set[v] = true;
  }
  return in_set;
}

}  // namespace

std::optional<int> Expression::polynomial_degree(std::span<const std::size_t> vars) const {
  return internal::degree_in(*data_, variable_set(*data_, vars, "polynomial_degree"));
}

bool Expression::has_kinks_in(std::span<const std::size_t> vars) const {
  using internal::Op;
  const internal::ExpressionData& d = *data_;
  const std::vector<bool> in_set = variable_set(d, vars, "has_kinks_in");
  std::vector<char> dep(d.nodes.size(), 0);
  for (std::size_t i = 0; i < d.nodes.size(); ++i) {
    const internal::Node& node = d.nodes[i];
    if (node.op == Op::kConst) continue;
    const auto ua = static_cast<std::size_t>(node.a), ub = static_cast<std::size_t>(node.b);
    if (node.op == Op::kVar) {
      dep[i] = static_cast<char>(in_set[ub]);
      continue;
    }
    dep[i] = static_cast<char>(dep[ua] || (internal::is_binary(node.op) && dep[ub]));
    const bool kinked = node.op == Op::kAbs || node.op == Op::kSign || node.op == Op::kMin ||
                        node.op == Op::kMax || node.op == Op::kFloor || node.op == Op::kHeaviside;
    if (kinked && dep[i]) return true;
  }
  return false;
}

bool Expression::is_polynomial_of_degree_at_most(int degree) const {
  const auto d = polynomial_degree();
  return d && *d <= degree;
}

std::optional<std::vector<PowerLaw>> Expression::power_laws(std::size_t var, double origin) const {
  if (var >= data_->variables.size())
    throw std::invalid_argument("Expression::power_laws: variable index " + std::to_string(var) +
                                " out of range");
  const auto sum = internal::power_sum_of(*data_, var, origin);
  if (!sum) return std::nullopt;
  std::vector<PowerLaw> laws;
  for (const auto& [gamma, c] : *sum) {
    if (!std::isfinite(gamma) || !std::isfinite(c)) return std::nullopt;
    laws.push_back({gamma, c});
  }
  return laws;
}

std::size_t Expression::node_count() const {
  return data_->nodes.size();
}

std::vector<Expression> parse_expressions(std::span<const std::string> texts,
                                          const std::vector<std::string>& variables) {
  std::vector<Expression> out;
  out.reserve(texts.size());
  for (std::size_t i = 0; i < texts.size(); ++i) {
    try {
      out.push_back(Expression::parse(texts[i], variables));
    } catch (const ExpressionError& e) {
      throw ExpressionError("component " + std::to_string(i + 1) + " of " +
                                std::to_string(texts.size()) + ": " + e.reason(),
                            e.expression(), e.column());
    }
  }
  return out;
}

}  // namespace fracvi
