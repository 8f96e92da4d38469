// The hash-consed expression DAG: simplifying constructors and symbolic differentiation.
#include "graph.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <limits>

namespace fracvi::internal {

namespace {

struct FunctionEntry {
  std::string_view name;
  Op op;
};

constexpr FunctionEntry kFunctions[] = {
    {"sin", Op::kSin},     {"cos", Op::kCos},
    {"tan", Op::kTan},     {"exp", Op::kExp},
    {"log", Op::kLog},     {"sqrt", Op::kSqrt},
    {"abs", Op::kAbs},     {"sign", Op::kSign},
    {"sinh", Op::kSinh},   {"cosh", Op::kCosh},
    {"tanh", Op::kTanh},   {"atan", Op::kAtan},
    {"floor", Op::kFloor}, {"heaviside", Op::kHeaviside},
    {"pow", Op::kPow},     {"min", Op::kMin},
    {"max", Op::kMax},     {"atan2", Op::kAtan2},
};

constexpr std::int32_t kNoVariable = std::numeric_limits<std::int32_t>::max();
constexpr NodeId kPending = -2;  // collected by derivative(), not yet differentiated

bool is_integer_valued(double v) {
  return std::isfinite(v) && std::floor(v) == v;
}

}  // namespace

std::string_view function_name(Op op) {
  for (const auto& f : kFunctions)
    if (f.op == op) return f.name;
  return "?";
}

Op function_by_name(std::string_view name) {
  for (const auto& f : kFunctions)
    if (f.name == name) return f.op;
  return Op::kConst;
}

const std::vector<std::string>& function_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const auto& f : kFunctions) v.emplace_back(f.name);
    return v;
  }();
  return names;
}

std::size_t Builder::KeyHash::operator()(const Key& k) const {
  // 64-bit mix (splitmix64 finaliser) of the packed fields.
  std::uint64_t h = k.bits ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.a)) << 32) ^
                    static_cast<std::uint32_t>(k.b) ^ (static_cast<std::uint64_t>(k.op) << 56);
  h ^= h >> 30;
  h *= 0xbf58476d1ce4e5b9ULL;
  h ^= h >> 27;
  h *= 0x94d049bb133111ebULL;
  h ^= h >> 31;
  return static_cast<std::size_t>(h);
}

Builder::Builder(const std::vector<Node>& nodes, std::size_t num_variables)
    : num_variables_(num_variables), nodes_(nodes) {
  index_.reserve(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    index_.emplace(Key{n.op, n.a, n.b, std::bit_cast<std::uint64_t>(n.value)},
                   static_cast<NodeId>(i));
  }
}

NodeId Builder::intern(Op op, NodeId a, NodeId b, double value) {
  const Key key{op, a, b, std::bit_cast<std::uint64_t>(value)};
  if (auto it = index_.find(key); it != index_.end()) return it->second;
  Node n{op, a, b, value, kNoVariable, -1};
  if (op == Op::kVar) {
    n.lo = n.hi = b;
  } else if (op != Op::kConst) {
    n.lo = node(a).lo;
    n.hi = node(a).hi;
    if (is_binary(op)) {
      n.lo = std::min(n.lo, node(b).lo);
      n.hi = std::max(n.hi, node(b).hi);
    }
  }
  const auto id = static_cast<NodeId>(nodes_.size());
  nodes_.push_back(n);
  index_.emplace(key, id);
  return id;
}

NodeId Builder::constant(double value) {
  if (value == 0.0) value = 0.0;  // one zero: -0 and +0 are the same node
  return intern(Op::kConst, kNoNode, kNoNode, value);
}

NodeId Builder::variable(std::size_t index) {
  assert(index < num_variables_);
  return intern(Op::kVar, kNoNode, static_cast<NodeId>(index));
}

// The rewrites below keep every node in a small canonical form: no Neg of a Neg, Sub, constant
// or constant multiple; negative constants and negative constant factors never appear as the
// right operand of + or -; constant factors come first in products and are merged. Reordering
// commutative operands and negating are exact in IEEE arithmetic; merging constant factors
// (c1*(c2*x) -> (c1*c2)*x) may change the last bit, which is the usual price of simplification.

NodeId Builder::add(NodeId a, NodeId b) {
  const Node na = node(a), nb = node(b);
  if (na.op == Op::kConst && nb.op == Op::kConst) return constant(na.value + nb.value);
  if (na.op == Op::kConst) return add(b, a);  // the constant on the right from here on
  if (is_constant(a, 0.0)) return b;
  if (is_constant(b, 0.0)) return a;
  if (nb.op == Op::kNeg) return sub(a, nb.a);
  if (na.op == Op::kNeg) return sub(b, na.a);
  if (nb.op == Op::kConst && nb.value < 0) return sub(a, constant(-nb.value));
  if (nb.op == Op::kMul && node(nb.a).op == Op::kConst && node(nb.a).value < 0)
    return sub(a, mul(constant(-node(nb.a).value), nb.b));
  if (na.op == Op::kMul && node(na.a).op == Op::kConst && node(na.a).value < 0)
    return sub(b, mul(constant(-node(na.a).value), na.b));
  if (nb.op == Op::kConst && (na.op == Op::kAdd || na.op == Op::kSub) && is_constant(na.b)) {
    const double c = node(na.b).value;  // (x + c) + d -> x + (c + d), (x - c) + d -> x + (d - c)
    return add(na.a, constant(na.op == Op::kAdd ? c + nb.value : nb.value - c));
  }
  if (a == b) return mul(constant(2.0), a);
  // Constants last ("x + 1"), otherwise by id, so that a + b and b + a are one node.
  if (nb.op != Op::kConst && a > b) std::swap(a, b);
  return intern(Op::kAdd, a, b);
}

NodeId Builder::sub(NodeId a, NodeId b) {
  const Node na = node(a), nb = node(b);
  if (na.op == Op::kConst && nb.op == Op::kConst) return constant(na.value - nb.value);
  if (is_constant(b, 0.0)) return a;
  if (is_constant(a, 0.0)) return neg(b);
  if (a == b) return constant(0.0);
  if (nb.op == Op::kNeg) return add(a, nb.a);
  if (nb.op == Op::kConst && nb.value < 0) return add(a, constant(-nb.value));
  if (nb.op == Op::kConst && (na.op == Op::kAdd || na.op == Op::kSub) && is_constant(na.b)) {
    const double c = node(na.b).value;  // (x + c) - d -> x + (c - d), (x - c) - d -> x - (c + d)
    return na.op == Op::kAdd ? add(na.a, constant(c - nb.value))
                             : sub(na.a, constant(c + nb.value));
  }
  if (nb.op == Op::kMul && node(nb.a).op == Op::kConst && node(nb.a).value < 0)
    return add(a, mul(constant(-node(nb.a).value), nb.b));
  return intern(Op::kSub, a, b);
}

NodeId Builder::mul(NodeId a, NodeId b) {
  const Node na = node(a), nb = node(b);
  if (na.op == Op::kConst && nb.op == Op::kConst) return constant(na.value * nb.value);
  // 0*x = 0 even where x would be inf or NaN: the usual symbolic convention, needed so that
  // derivatives of terms not involving a variable vanish structurally.
  if (is_constant(a, 0.0) || is_constant(b, 0.0)) return constant(0.0);
  if (is_constant(a, 1.0)) return b;
  if (is_constant(b, 1.0)) return a;
  if (is_constant(a, -1.0)) return neg(b);
  if (is_constant(b, -1.0)) return neg(a);
  if (na.op == Op::kNeg && nb.op == Op::kNeg) return mul(na.a, nb.a);
  if (nb.op == Op::kConst) return mul(b, a);  // constant factor first
  if (na.op == Op::kConst) {
    const double c = na.value;
    if (nb.op == Op::kNeg) return mul(constant(-c), nb.a);
    if (nb.op == Op::kMul && node(nb.a).op == Op::kConst)
      return mul(constant(c * node(nb.a).value), nb.b);
    if (nb.op == Op::kDiv && node(nb.b).op == Op::kConst)
      return mul(constant(c / node(nb.b).value), nb.a);
    return intern(Op::kMul, a, b);
  }
  if (a == b) return pow_int(a, 2);
  if (a > b) std::swap(a, b);
  return intern(Op::kMul, a, b);
}

NodeId Builder::div(NodeId a, NodeId b) {
  const Node na = node(a), nb = node(b);
  if (na.op == Op::kConst && nb.op == Op::kConst) return constant(na.value / nb.value);
  if (is_constant(a, 0.0)) return constant(0.0);
  if (is_constant(b, 1.0)) return a;
  if (is_constant(b, -1.0)) return neg(a);
  if (a == b) return constant(1.0);
  if (na.op == Op::kNeg && nb.op == Op::kNeg) return div(na.a, nb.a);
  if (nb.op == Op::kConst && na.op == Op::kMul && node(na.a).op == Op::kConst)
    return mul(constant(node(na.a).value / nb.value), na.b);  // (4*x^3)/4 -> x^3
  if (na.op == Op::kMul && nb.op == Op::kMul && node(na.a).op == Op::kConst &&
      node(nb.a).op == Op::kConst)  // (2*x)/(2*sqrt(u)) -> x/sqrt(u), as in sqrt(u)'
    return mul(constant(node(na.a).value / node(nb.a).value), div(na.b, nb.b));
  return intern(Op::kDiv, a, b);
}

NodeId Builder::pow(NodeId a, NodeId b) {
  const Node na = node(a), nb = node(b);
  if (na.op == Op::kConst && nb.op == Op::kConst) return constant(std::pow(na.value, nb.value));
  if (nb.op == Op::kConst) {
    const double e = nb.value;
    if (is_integer_valued(e) && std::abs(e) <= static_cast<double>(kMaxIntExponent))
      return pow_int(a, static_cast<std::int64_t>(e));
    if (e == 0.5) return function(Op::kSqrt, a);  // same value except at -0 and -inf
  }
  if (is_constant(a, 1.0)) return constant(1.0);
  return intern(Op::kPow, a, b);
}

NodeId Builder::pow_int(NodeId a, std::int64_t n) {
  if (n == 0) return constant(1.0);
  if (n == 1) return a;
  if (n > kMaxIntExponent || n < -kMaxIntExponent) return pow(a, constant(static_cast<double>(n)));
  const auto n32 = static_cast<std::int32_t>(n);
  if (is_constant(a)) return constant(ipow(node(a).value, n32));
  return intern(Op::kPowInt, a, n32);
}

NodeId Builder::neg(NodeId a) {
  const Node na = node(a);
  if (na.op == Op::kConst) return constant(-na.value);
  if (na.op == Op::kNeg) return na.a;
  if (na.op == Op::kSub) return sub(na.b, na.a);
  if (na.op == Op::kMul && node(na.a).op == Op::kConst)
    return mul(constant(-node(na.a).value), na.b);
  return intern(Op::kNeg, a, kNoNode);
}

NodeId Builder::function(Op op, NodeId a) {
  const Node na = node(a);
  if (na.op == Op::kConst) return constant(apply_unary(op, na.value, 0));
  if (op == Op::kAbs && (na.op == Op::kNeg || na.op == Op::kAbs)) return function(op, na.a);
  if (op == Op::kSign && na.op == Op::kSign) return a;
  return intern(op, a, kNoNode);
}

NodeId Builder::function(Op op, NodeId a, NodeId b) {
  if (is_constant(a) && is_constant(b)) {
    return constant(apply_binary(op, node(a).value, node(b).value));
  }
  if ((op == Op::kMin || op == Op::kMax) && a == b) return a;
  return intern(op, a, b);
}

NodeId Builder::derivative_rule(NodeId id, NodeId da, NodeId db, std::int32_t var) {
  const Node n = node(id);
  const NodeId a = n.a, b = n.b;
  switch (n.op) {
    case Op::kConst: return constant(0.0);
    case Op::kVar: return constant(b == var ? 1.0 : 0.0);
    case Op::kAdd: return add(da, db);
    case Op::kSub: return sub(da, db);
    case Op::kNeg: return neg(da);
    case Op::kMul: return add(mul(da, b), mul(a, db));
    case Op::kDiv:
      // (a/b)' = (a' − (a/b)·b')/b reuses the quotient node itself.
      if (is_constant(db, 0.0)) return div(da, b);
      return div(sub(da, mul(id, db)), b);
    case Op::kPowInt:  // n·a^(n−1)·a', valid for negative a
      return mul(mul(constant(static_cast<double>(b)), pow_int(a, std::int64_t{b} - 1)), da);
    case Op::kPow:
      if (is_constant(db, 0.0))  // exponent independent of var: b·a^(b−1)·a'
        return mul(mul(b, pow(a, sub(b, constant(1.0)))), da);
      if (is_constant(da, 0.0))  // base independent of var: a^b·log(a)·b'
        return mul(mul(id, function(Op::kLog, a)), db);
      return mul(id, add(mul(db, function(Op::kLog, a)), div(mul(b, da), a)));
    case Op::kSin: return mul(function(Op::kCos, a), da);
    case Op::kCos: return neg(mul(function(Op::kSin, a), da));
    case Op::kTan: return mul(add(constant(1.0), pow_int(id, 2)), da);
    case Op::kExp: return mul(id, da);
    case Op::kLog: return div(da, a);
    case Op::kSqrt: return div(da, mul(constant(2.0), id));
    case Op::kAbs: return mul(function(Op::kSign, a), da);
    case Op::kSign: return constant(0.0);  // piecewise constant
    case Op::kSinh: return mul(function(Op::kCosh, a), da);
    case Op::kCosh: return mul(function(Op::kSinh, a), da);
    case Op::kTanh: return mul(sub(constant(1.0), pow_int(id, 2)), da);
    case Op::kAtan: return div(da, add(constant(1.0), pow_int(a, 2)));
    case Op::kFloor:
    case Op::kHeaviside: return constant(0.0);  // piecewise constant; the jumps are not seen
    case Op::kMin:
    case Op::kMax: {
      // The derivative of the selected argument, and at a tie (a = b) the mean of the two:
      // min' = (a' + b')/2 − sign(a − b)(a' − b')/2, max' with + (linear in da, db).
      const NodeId mean = mul(constant(0.5), add(da, db));
      const NodeId half_gap = mul(mul(constant(0.5), function(Op::kSign, sub(a, b))), sub(da, db));
      return n.op == Op::kMin ? sub(mean, half_gap) : add(mean, half_gap);
    }
    case Op::kAtan2:  // atan2(a, b), the angle of (b, a): (b a' − a b')/(a² + b²)
      return div(sub(mul(b, da), mul(a, db)), add(pow_int(a, 2), pow_int(b, 2)));
  }
  return constant(std::nan(""));
}

NodeId Builder::derivative(NodeId f, std::size_t var) {
  return derivative(std::span(&f, 1), var)[0];
}

std::vector<NodeId> Builder::derivative(std::span<const NodeId> roots, std::size_t var) {
  const auto v = static_cast<std::int32_t>(var);
  const auto relevant = [&](NodeId id) { return node(id).lo <= v && v <= node(id).hi; };
  if (memo_.size() < nodes_.size()) memo_.resize(nodes_.size(), kNoNode);

  // Collect the nodes that may depend on var; nodes not collected have derivative 0.
  std::vector<NodeId> order, stack;
  for (NodeId r : roots) {
    if (relevant(r) && memo_[static_cast<std::size_t>(r)] == kNoNode) {
      memo_[static_cast<std::size_t>(r)] = kPending;
      stack.push_back(r);
    }
  }
  while (!stack.empty()) {
    const NodeId id = stack.back();
    stack.pop_back();
    order.push_back(id);
    const Node& n = node(id);
    if (n.op == Op::kVar || n.op == Op::kConst) continue;
    for (NodeId c : {n.a, is_binary(n.op) ? n.b : kNoNode}) {
      if (c == kNoNode || !relevant(c)) continue;
      NodeId& m = memo_[static_cast<std::size_t>(c)];
      if (m == kNoNode) {
        m = kPending;
        stack.push_back(c);
      }
    }
  }
  // Ids are topological (children are created before parents).
  std::sort(order.begin(), order.end());
  const NodeId zero = constant(0.0);
  const auto d = [&](NodeId c) {
    if (c == kNoNode || static_cast<std::size_t>(c) >= memo_.size()) return zero;
    const NodeId m = memo_[static_cast<std::size_t>(c)];
    return m >= 0 ? m : zero;
  };
  for (NodeId id : order) {
    const Node n = node(id);
    const bool has_operands = n.op != Op::kVar && n.op != Op::kConst;
    const NodeId da = has_operands ? d(n.a) : zero;
    const NodeId db = is_binary(n.op) ? d(n.b) : zero;
    const NodeId result = derivative_rule(id, da, db, v);
    memo_[static_cast<std::size_t>(id)] = result;
  }
  std::vector<NodeId> result;
  result.reserve(roots.size());
  for (NodeId r : roots) result.push_back(d(r));
  for (NodeId id : order) memo_[static_cast<std::size_t>(id)] = kNoNode;
  return result;
}

std::vector<NodeId> Builder::gradient(NodeId f) {
  const NodeId zero = constant(0.0);
  std::vector<NodeId> grad(num_variables_, zero);
  const std::vector<NodeId> order = reachable(nodes_, std::span(&f, 1));
  std::vector<NodeId> adjoint(nodes_.size(), kNoNode);  // kNoNode: zero so far
  adjoint[static_cast<std::size_t>(f)] = constant(1.0);
  const auto accumulate = [&](NodeId child, NodeId contribution) {
    if (node(child).lo > node(child).hi || is_constant(contribution, 0.0)) return;
    NodeId& adj = adjoint[static_cast<std::size_t>(child)];
    adj = adj == kNoNode ? contribution : add(adj, contribution);
  };
  // Descending ids: every parent is done before its children.
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    const NodeId id = *it;
    const NodeId adj = adjoint[static_cast<std::size_t>(id)];
    const Node n = node(id);
    if (adj == kNoNode) continue;
    if (n.op == Op::kVar) {
      grad[static_cast<std::size_t>(n.b)] = adj;
      continue;
    }
    if (n.op == Op::kConst) continue;
    accumulate(n.a, derivative_rule(id, adj, zero, -1));
    if (is_binary(n.op)) accumulate(n.b, derivative_rule(id, zero, adj, -1));
  }
  return grad;
}

std::vector<NodeId> reachable(const std::vector<Node>& nodes, std::span<const NodeId> roots) {
  std::vector<char> seen(nodes.size(), 0);
  std::vector<NodeId> stack(roots.begin(), roots.end()), out;
  for (NodeId r : roots) seen[static_cast<std::size_t>(r)] = 1;
  while (!stack.empty()) {
    const NodeId id = stack.back();
    stack.pop_back();
    out.push_back(id);
    const Node& n = nodes[static_cast<std::size_t>(id)];
    if (n.op == Op::kVar || n.op == Op::kConst) continue;
    for (NodeId c : {n.a, is_binary(n.op) ? n.b : kNoNode}) {
      if (c != kNoNode && !seen[static_cast<std::size_t>(c)]) {
        seen[static_cast<std::size_t>(c)] = 1;
        stack.push_back(c);
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Node> extract(const std::vector<Node>& nodes, std::span<NodeId> roots) {
  const std::vector<NodeId> keep = reachable(nodes, roots);
  std::vector<NodeId> new_id(nodes.size(), kNoNode);
  std::vector<Node> out;
  out.reserve(keep.size());
  for (NodeId id : keep) {
    Node n = nodes[static_cast<std::size_t>(id)];
    if (n.op != Op::kVar && n.op != Op::kConst) {
      n.a = new_id[static_cast<std::size_t>(n.a)];
      if (is_binary(n.op)) n.b = new_id[static_cast<std::size_t>(n.b)];
    }
    new_id[static_cast<std::size_t>(id)] = static_cast<NodeId>(out.size());
    out.push_back(n);
  }
  for (NodeId& r : roots) r = new_id[static_cast<std::size_t>(r)];
  return out;
}

}  // namespace fracvi::internal
