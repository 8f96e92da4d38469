#include "fracvi/integrate/method.hpp"

namespace fracvi {

std::string_view Method::name() const {
  switch (scheme) {
    case Scheme::kFviGl: return "fvi-gl";
  }
  return "unknown";
}

int Method::declared_order(const MechanicalModel& model) const {
  switch (scheme) {
    case Scheme::kFviGl: return model.is_undamped() ? 2 : 1;
  }
  return 0;
}

std::optional<Method> parse_method(std::string_view name) {
  if (name == "fvi-gl") return Method{Scheme::kFviGl};
  return std::nullopt;
}

}  // namespace fracvi
