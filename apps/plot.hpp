// Drawing the PNG plots of a run with matplotlib (python/fracvi/plot.py under Debian's python3).
#pragma once

#include <filesystem>
#include <string>

namespace fracvi::cli {

/// Draws trajectory.png, phase.png and energy.png (and spacetime.png for d > 8) into `dir`.
/// Returns "" on success, otherwise a one-line note saying why there are no plots (the data files
/// are written regardless).
std::string draw_plots(const std::filesystem::path& dir, bool quiet);

/// Removes the plots draw_plots() writes (python/fracvi/plot.py FILES), so that `run --no-plot`
/// does not leave an earlier run's pictures beside new data.
void remove_plots(const std::filesystem::path& dir);
/// Draws convergence.png (log-log error against h) from convergence.csv in `dir`; "" or a note.
std::string draw_convergence_plot(const std::filesystem::path& dir);
/// Draws work_precision.png, error_vs_steps.png and energy_tracking.png from compare.csv,
/// energy.csv and compare.json in `dir` (python/fracvi/plot_compare.py); "" or a note.
std::string draw_compare_plots(const std::filesystem::path& dir);

}  // namespace fracvi::cli
