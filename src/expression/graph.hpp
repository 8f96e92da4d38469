// Internals of the expression engine: the hash-consed DAG, its simplifying builder, symbolic
// differentiation, and the straight-line tape. Not installed; include only from src/expression.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "fracvi/expression/expression.hpp"

namespace fracvi::internal {

enum class Op : std::uint8_t {
  kConst,  // value
  kVar,    // b = variable index
  kAdd,    // binary ops: a, b
  kSub,
  kMul,
  kDiv,
  kPow,  // a^b, general (exp/log rule)
  kMin,  // min(a, b), max(a, b), atan2(a, b): binary functions called by name
  kMax,
  kAtan2,
  kNeg,     // unary ops: a
  kPowInt,  // a^n with n = b, a small integer
  kSin,
  kCos,
  kTan,
  kExp,
  kLog,
  kSqrt,
  kAbs,
  kSign,
  kSinh,
  kCosh,
  kTanh,
  kAtan,
  kFloor,
  kHeaviside,
};

inline bool is_binary(Op op) {
  return op >= Op::kAdd && op <= Op::kAtan2;
}
inline bool is_unary(Op op) {
  return op >= Op::kNeg;
}
/// The unary functions callable by name (everything after kPowInt).
inline bool is_named_function(Op op) {
  return op > Op::kPowInt;
}

using NodeId = std::int32_t;
inline constexpr NodeId kNoNode = -1;

struct Node {
  Op op = Op::kConst;
  NodeId a = kNoNode;
  NodeId b = kNoNode;
  double value = 0.0;
  // The smallest and largest variable index the node depends on (lo > hi: none). An interval,
  // not a set: it prunes differentiation cheaply and exactly for banded structures such as
  // chains, and conservatively otherwise.
  std::int32_t lo = 0;
  std::int32_t hi = -1;
};

/// Exponents up to this size are kPowInt (exact repeated multiplication, n·x^(n−1) derivative
/// valid for negative x); larger integers fall back to std::pow.
inline constexpr std::int64_t kMaxIntExponent = 1 << 20;

std::string_view function_name(Op op);
/// kSin..kHeaviside for a built-in unary function name, kPow, kMin, kMax or kAtan2 for a binary
/// one ("pow", "min", "max", "atan2"), kConst if unknown.
Op function_by_name(std::string_view name);
/// Names of all functions, for error messages.
const std::vector<std::string>& function_names();

/// x^n by repeated squaring for |n| <= 16 (error a few ulps), std::pow beyond.
inline double ipow(double x, std::int32_t n) {
  switch (n) {  // the exponents of typical potentials, without the loop
    case 2: return x * x;
    case 3: return x * x * x;
    case 4: {
      const double x2 = x * x;
      return x2 * x2;
    }
    case -1: return 1.0 / x;
    case -2: return 1.0 / (x * x);
    default: break;
  }
  if (n > 16 || n < -16) return std::pow(x, static_cast<double>(n));
  unsigned m = static_cast<unsigned>(n < 0 ? -n : n);
  double r = 1.0, base = x;
  while (m != 0) {
    if (m & 1U) r *= base;
    base *= base;
    m >>= 1U;
  }
  return n < 0 ? 1.0 / r : r;
}

/// sign(±0) = ±0 and sign(NaN) = NaN, so that abs' = sign does not invent a value at the kink.
inline double sign(double x) {
  return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : x);
}

/// The unit step: 0 for x < 0, 1/2 at ±0 (the mean of the two sides), 1 for x > 0, NaN for NaN.
inline double heaviside(double x) {
  return x > 0.0 ? 1.0 : (x < 0.0 ? 0.0 : (x == 0.0 ? 0.5 : x));
}

/// min and max that keep a NaN (std::min would drop one in its second argument), so that a NaN
/// reaches the integrator's non-finite check.
inline double nan_min(double a, double b) {
  return std::isnan(b) ? b : (b < a ? b : a);
}
inline double nan_max(double a, double b) {
  return std::isnan(b) ? b : (b > a ? b : a);
}

inline double apply_unary(Op op, double x, std::int32_t n) {
  switch (op) {
    case Op::kNeg: return -x;
    case Op::kPowInt: return ipow(x, n);
    case Op::kSin: return std::sin(x);
    case Op::kCos: return std::cos(x);
    case Op::kTan: return std::tan(x);
    case Op::kExp: return std::exp(x);
    case Op::kLog: return std::log(x);
    case Op::kSqrt: return std::sqrt(x);
    case Op::kAbs: return std::abs(x);
    case Op::kSign: return sign(x);
    case Op::kSinh: return std::sinh(x);
    case Op::kCosh: return std::cosh(x);
    case Op::kTanh: return std::tanh(x);
    case Op::kAtan: return std::atan(x);
    case Op::kFloor: return std::floor(x);
    case Op::kHeaviside: return heaviside(x);
    default: return std::nan("");
  }
}

inline double apply_binary(Op op, double x, double y) {
  switch (op) {
    case Op::kAdd: return x + y;
    case Op::kSub: return x - y;
    case Op::kMul: return x * y;
    case Op::kDiv: return x / y;
    case Op::kPow: return std::pow(x, y);
    case Op::kMin: return nan_min(x, y);
    case Op::kMax: return nan_max(x, y);
    case Op::kAtan2: return std::atan2(x, y);
    default: return std::nan("");
  }
}

/// Creates nodes with hash-consing and local simplification (constant folding, neutral and
/// absorbing elements, sign normalisation, merging of constant factors). Every constructor
/// returns the id of an existing equal node when there is one, so equal subexpressions are
/// one node and the tape computes them once.
class Builder {
 public:
  explicit Builder(std::size_t num_variables) : num_variables_(num_variables) {}
  /// Continues from an existing (e.g. extracted) graph; ids are preserved.
  Builder(const std::vector<Node>& nodes, std::size_t num_variables);

  NodeId constant(double value);
  NodeId variable(std::size_t index);
  NodeId add(NodeId a, NodeId b);
  NodeId sub(NodeId a, NodeId b);
  NodeId mul(NodeId a, NodeId b);
  NodeId div(NodeId a, NodeId b);
  NodeId pow(NodeId a, NodeId b);
  NodeId pow_int(NodeId a, std::int64_t n);
  NodeId neg(NodeId a);
  /// A named unary function (kSin..kHeaviside).
  NodeId function(Op op, NodeId a);
  /// A named binary function: kMin, kMax or kAtan2 (pow is pow()).
  NodeId function(Op op, NodeId a, NodeId b);

  /// ∂f/∂x_var by forward accumulation, built iteratively (no recursion, so deep sums are
  /// fine) over the nodes whose dependence interval contains var.
  NodeId derivative(NodeId f, std::size_t var);
  /// The same for several roots in one sweep: shared subexpressions are differentiated once.
  std::vector<NodeId> derivative(std::span<const NodeId> roots, std::size_t var);
  /// ∂f/∂x_v for every variable v by one reverse (adjoint) sweep, O(size of f) rather than
  /// O(size × variables): a sum of d springs would otherwise cost O(d²).
  std::vector<NodeId> gradient(NodeId f);

  const Node& node(NodeId id) const { return nodes_[static_cast<std::size_t>(id)]; }
  const std::vector<Node>& nodes() const { return nodes_; }
  bool is_constant(NodeId id) const { return node(id).op == Op::kConst; }
  bool is_constant(NodeId id, double v) const { return is_constant(id) && node(id).value == v; }

 private:
  struct Key {
    Op op;
    NodeId a, b;
    std::uint64_t bits;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const;
  };
  NodeId intern(Op op, NodeId a, NodeId b, double value = 0.0);
  // The forward rule: (∂id/∂a)·da + (∂id/∂b)·db. It is linear in (da, db) and treats them
  // as opaque nodes, so the reverse sweep reuses it with (adjoint, 0) and (0, adjoint).
  NodeId derivative_rule(NodeId id, NodeId da, NodeId db, std::int32_t var);

  std::size_t num_variables_;
  std::vector<Node> nodes_;
  std::unordered_map<Key, NodeId, KeyHash> index_;
  std::vector<NodeId> memo_;  // per-node scratch of derivative(), all kNoNode between calls
};

/// The nodes reachable from `roots`, renumbered in the same (topological) order; `roots` is
/// rewritten to the new ids.
std::vector<Node> extract(const std::vector<Node>& nodes, std::span<NodeId> roots);

/// Children-before-parents list of the nodes reachable from `roots`, ascending ids.
std::vector<NodeId> reachable(const std::vector<Node>& nodes, std::span<const NodeId> roots);

// ---------------------------------------------------------------------------------------------
// The tape: every node has a slot in a flat array of doubles (the Workspace). Slots 0..n-1 hold
// the variables (copied in bulk, no instructions), constants are stored once when the workspace
// is made, and every other node is one instruction, in topological order. Value,
// value+gradient and value+gradient+Hessian have their own instruction lists over the same
// slots, so asking for less costs less.

struct Instruction {
  Op op;
  std::int32_t out;
  std::int32_t a;  // slot of operand a
  std::int32_t b;  // slot of operand b; for kPowInt the exponent
};

struct Program {
  std::size_t num_variables = 0;
  std::size_t num_slots = 0;
  std::vector<std::pair<std::int32_t, double>> constants;
  // gradient_only_code: the gradient without the value's own instructions (a potential's force).
  std::vector<Instruction> value_code, gradient_code, gradient_only_code, hessian_code;
  std::int32_t value_slot = 0;
  std::vector<std::int32_t> gradient_slots;  // one per gradient coordinate (a zero slot if zero)
  std::vector<std::int32_t> hessian_slots;   // one per hessian_pattern() entry
};

Program compile(const std::vector<Node>& nodes, std::size_t num_variables, NodeId value,
                std::span<const NodeId> gradient, std::span<const NodeId> hessian);

void fill_constants(const Program& program, std::span<double> slots);
/// Copies the variables into their slots (unless `values` are the slots) and runs `code`.
void run(const Program& program, std::span<const Instruction> code, const double* values,
         double* slots);

// ---------------------------------------------------------------------------------------------

struct ExpressionData {
  std::string text;
  std::vector<std::string> variables;
  std::vector<Node> nodes;  // compact: exactly the nodes reachable from root
  NodeId root = 0;
  Program program;  // value only
  std::vector<bool> depends;
};

/// Packs a root of a builder into ExpressionData (extracts, compiles the value tape).
std::shared_ptr<const ExpressionData> make_expression_data(const Builder& builder, NodeId root,
                                                           std::string text,
                                                           std::vector<std::string> variables);

/// Parses `text` into `builder`; throws ExpressionError.
NodeId parse(std::string_view text, const std::vector<std::string>& variables, Builder& builder);

/// Throws std::invalid_argument unless the names are distinct identifiers that shadow nothing.
void validate_variable_names(const std::vector<std::string>& variables);

}  // namespace fracvi::internal
