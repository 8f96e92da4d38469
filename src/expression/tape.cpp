// Compilation of DAG roots into a straight-line tape, and its interpreter.
#include <algorithm>
#include <cmath>
#include <iterator>

#include "graph.hpp"

namespace fracvi::internal {

Program compile(const std::vector<Node>& nodes, std::size_t num_variables, NodeId value,
                std::span<const NodeId> gradient, std::span<const NodeId> hessian) {
  std::vector<NodeId> roots{value};
  roots.insert(roots.end(), gradient.begin(), gradient.end());
  const std::size_t num_value_gradient = roots.size();
  roots.insert(roots.end(), hessian.begin(), hessian.end());

  const std::vector<NodeId> all = reachable(nodes, roots);
  std::vector<std::int32_t> slot(nodes.size(), -1);
  std::size_t next = num_variables;
  for (NodeId id : all) {
    const Node& n = nodes[static_cast<std::size_t>(id)];
    slot[static_cast<std::size_t>(id)] = n.op == Op::kVar ? n.b : static_cast<std::int32_t>(next++);
  }

  Program p;
  p.num_variables = num_variables;
  p.num_slots = next;
  const auto emit = [&](std::span<const NodeId> ids, std::vector<Instruction>& code) {
    for (NodeId id : ids) {
      const Node& n = nodes[static_cast<std::size_t>(id)];
      Instruction in{n.op, slot[static_cast<std::size_t>(id)], 0, 0};
      switch (n.op) {
        case Op::kConst:
        case Op::kVar: continue;
        case Op::kPowInt:
          in.a = slot[static_cast<std::size_t>(n.a)];
          in.b = n.b;
          break;
        default:
          in.a = slot[static_cast<std::size_t>(n.a)];
          if (is_binary(n.op)) in.b = slot[static_cast<std::size_t>(n.b)];
      }
      code.push_back(in);
    }
  };
  for (NodeId id : all) {
    const Node& n = nodes[static_cast<std::size_t>(id)];
    if (n.op == Op::kConst) p.constants.emplace_back(slot[static_cast<std::size_t>(id)], n.value);
  }
  emit(reachable(nodes, std::span(roots).first(1)), p.value_code);
  emit(reachable(nodes, std::span(roots).first(num_value_gradient)), p.gradient_code);
  emit(reachable(nodes, std::span(roots).subspan(1, gradient.size())), p.gradient_only_code);
  emit(all, p.hessian_code);

  const auto slot_of = [&](NodeId id) { return slot[static_cast<std::size_t>(id)]; };
  p.value_slot = slot_of(value);
  std::transform(gradient.begin(), gradient.end(), std::back_inserter(p.gradient_slots), slot_of);
  std::transform(hessian.begin(), hessian.end(), std::back_inserter(p.hessian_slots), slot_of);
  return p;
}

void fill_constants(const Program& program, std::span<double> slots) {
  for (const auto& [s, v] : program.constants) slots[static_cast<std::size_t>(s)] = v;
}

void run(const Program& program, std::span<const Instruction> code, const double* values,
         double* s) {
  // A plain loop: typical potentials have a handful of variables, too few for memmove. Values
  // already in the slots (CompiledDerivatives::Workspace::values) are not copied.
  if (values != s) {
    for (std::size_t i = 0; i < program.num_variables; ++i) s[i] = values[i];
  }
  for (const Instruction& in : code) {
    const double x = s[in.a];
    double r;
    switch (in.op) {
      case Op::kAdd: r = x + s[in.b]; break;
      case Op::kSub: r = x - s[in.b]; break;
      case Op::kMul: r = x * s[in.b]; break;
      case Op::kDiv: r = x / s[in.b]; break;
      case Op::kPow: r = std::pow(x, s[in.b]); break;
      case Op::kMin: r = nan_min(x, s[in.b]); break;
      case Op::kMax: r = nan_max(x, s[in.b]); break;
      case Op::kAtan2: r = std::atan2(x, s[in.b]); break;
      case Op::kNeg: r = -x; break;
      case Op::kPowInt: r = ipow(x, in.b); break;
      case Op::kSin: r = std::sin(x); break;
      case Op::kCos: r = std::cos(x); break;
      case Op::kTan: r = std::tan(x); break;
      case Op::kExp: r = std::exp(x); break;
      case Op::kLog: r = std::log(x); break;
      case Op::kSqrt: r = std::sqrt(x); break;
      case Op::kAbs: r = std::abs(x); break;
      case Op::kSign: r = sign(x); break;
      case Op::kSinh: r = std::sinh(x); break;
      case Op::kCosh: r = std::cosh(x); break;
      case Op::kTanh: r = std::tanh(x); break;
      case Op::kAtan: r = std::atan(x); break;
      case Op::kFloor: r = std::floor(x); break;
      case Op::kHeaviside: r = heaviside(x); break;
      default: r = std::nan(""); break;
    }
    s[in.out] = r;
  }
}

}  // namespace fracvi::internal
