// A Method names a time-stepping scheme and declares its order (DESIGN §4). Today there is one:
// the paper's fractional variational integrator with Grünwald–Letnikov memory ("fvi-gl",
// `DiscEqs`). Later schemes (BDF2-CQ, Lobatto RKCQ, baselines) become new enumerators.
#pragma once

#include <optional>
#include <string_view>

#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {

enum class Scheme {
  kFviGl,  ///< `DiscEqs`: midpoint discrete Lagrangian + GL damping sum (Lemma 5.3 for α = 1/2)
};

struct Method {
  Scheme scheme = Scheme::kFviGl;

  /// "fvi-gl".
  [[nodiscard]] std::string_view name() const;

  /// The order the scheme is designed to reach on smooth solutions of `model`:
  /// 2 when R = 0 (the conservative midpoint variational integrator), otherwise 1 (the GL
  /// damping sum — and for α = 1/2 the backward difference of Lemma 5.3 — is first order).
  /// Measured orders are in tests/integrate/ and docs/theory/start_step.md.
  [[nodiscard]] int declared_order(const MechanicalModel& model) const;
};

/// The paper's scheme.
inline Method fvi_gl() {
  return Method{};
}

/// "fvi-gl" → Method; anything else → nullopt.
std::optional<Method> parse_method(std::string_view name);

}  // namespace fracvi
