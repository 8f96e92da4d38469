// `fracvi plot DIR`: redraw the PNG plots of a run (or of a convergence study) from its files.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli.hpp"
#include "plot.hpp"

namespace fracvi::cli {

Command add_plot_command(CLI::App& parent) {
  auto dir = std::make_shared<std::string>();
  CLI::App* app = parent.add_subcommand(
      "plot",
      "Redraw the plots of an output directory: trajectory.png, phase.png and energy.png (and "
      "spacetime.png for d > 8) from trajectory.csv (or trajectory.npz: output.format = \"npz\") "
      "and "
      "summary.json (fracvi run), or "
      "convergence.png from convergence.csv "
      "(fracvi convergence). Uses matplotlib through Debian's /usr/bin/python3.");
  app->add_option("directory", *dir, "output directory of fracvi run or fracvi convergence")
      ->required();
  auto run = [dir]() {
    const std::filesystem::path d(*dir);
    const bool is_run = (std::filesystem::exists(d / "trajectory.csv") ||
                         std::filesystem::exists(d / "trajectory.npz")) &&
                        std::filesystem::exists(d / "summary.json");
    const bool is_study = std::filesystem::exists(d / "convergence.csv") &&
                          std::filesystem::exists(d / "convergence.json");
    if (!is_run && !is_study) {
      throw UsageError(
          "directory = '" + *dir +
          "' holds neither trajectory.csv (or .npz) + summary.json nor convergence.csv + "
          "convergence.json");
    }
    const std::string note = is_run ? draw_plots(d, false) : draw_convergence_plot(d);
    if (!note.empty()) {
      std::fprintf(stderr, "fracvi plot: %s\n", note.c_str());
      return kExitNumericalFailure;
    }
    const char* run_plots = std::filesystem::exists(d / "spacetime.png")
                                ? "{trajectory,phase,energy,spacetime}.png"
                                : "{trajectory,phase,energy}.png";
    std::printf("%s\n", is_run ? (d / run_plots).string().c_str()
                               : (d / "convergence.png").string().c_str());
    return kExitSuccess;
  };
  return {app, run};
}

}  // namespace fracvi::cli
