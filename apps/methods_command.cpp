// `fracvi methods`: the method registry (fracvi/schemes/registry.hpp), as a table or as JSON.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi::cli {

Command add_methods_command(CLI::App& parent) {
  auto json = std::make_shared<bool>(false);
  CLI::App* app = parent.add_subcommand(
      "methods",
      "List the time-stepping schemes (the method registry): name, declared order, stages, "
      "whether it is variational, has a mirror run, an exact energy balance and a fast history, "
      "where it applies and its stability bound. Choose one with [method] scheme in a problem file "
      "or --set "
      "method.scheme=NAME.");
  app->add_flag("--json", *json, "print the registry as a JSON array (one object per scheme)");
  auto run = [json]() {
    const auto rows = scheme_table();
    if (*json) {
      nlohmann::ordered_json out = nlohmann::ordered_json::array();
      for (const SchemeRow& r : rows) {
        out.push_back({{"name", r.name},
                       {"order", r.order},
                       {"stages", r.stages},
                       {"variational", r.variational},
                       {"mirror", r.mirror},
                       {"exact_balance", r.exact_balance},
                       {"fast_history", r.fast_history},
                       {"adaptive", r.adaptive},
                       {"applies_to", r.applies_to},
                       {"stability", r.stability},
                       {"summary", r.summary},
                       {"reference", r.reference}});
      }
      std::printf("%s\n", out.dump(2).c_str());
      return kExitSuccess;
    }
    auto yes = [](bool b) { return b ? "yes" : "no"; };
    std::printf("%-12s %-18s %-6s %-11s %-6s %-13s %-12s %-15s %s\n", "scheme", "order", "stages",
                "variational", "mirror", "exact balance", "fast history", "applies to",
                "stability bound");
    for (const SchemeRow& r : rows) {
      std::printf("%-12s %-18s %-6d %-11s %-6s %-13s %-12s %-15s %s\n", r.name.c_str(),
                  r.order.c_str(), r.stages, yes(r.variational), yes(r.mirror),
                  yes(r.exact_balance), yes(r.fast_history), r.applies_to.c_str(),
                  r.stability.c_str());
    }
    std::printf("\n");
    for (const SchemeRow& r : rows) {
      std::printf("%s: %s [%s]\n", r.name.c_str(), r.summary.c_str(), r.reference.c_str());
    }
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
