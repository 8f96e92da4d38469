#include "plot.hpp"

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace fracvi::cli {

namespace {

// A plotting script: next to the installed binary (../share/fracvi/<name>) or in the source tree
// this binary was built from.
std::filesystem::path plot_script(const std::string& name) {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto installed = exe.parent_path().parent_path() / "share" / "fracvi" / name;
    if (std::filesystem::exists(installed)) return installed;
  }
  return std::filesystem::path(FRACVI_SOURCE_DIR) / "python" / "fracvi" / name;
}

std::string shell_quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// plot.py's exit status for a malformed trajectory.csv or summary.json (MALFORMED_EXIT there).
constexpr int kMalformedInput = 3;

// Runs the script `name` on `dir`; "" on success, else a one-line note (the log is kept in dir).
std::string run_plot_script(const std::string& name, const std::filesystem::path& dir) {
  // Debian's interpreter: the first python3 on PATH may be another one without matplotlib.
  const std::string python = "/usr/bin/python3";
  const auto script = plot_script(name);
  if (!std::filesystem::exists(python)) return "not drawn: /usr/bin/python3 is not installed";
  if (!std::filesystem::exists(script)) return "not drawn: " + script.string() + " is missing";
  const auto log = dir / "plot.log";
  const std::string cmd = shell_quoted(python) + " " + shell_quoted(script.string()) + " " +
                          shell_quoted(dir.string()) + " >/dev/null 2>" +
                          shell_quoted(log.string());
  const int status = std::system(cmd.c_str());
  if (status != 0) {
    // The script's exit status 3 (plot.py MALFORMED_EXIT): the input files are malformed, and
    // its one line names the file, the line and what is wrong — not matplotlib's fault.
    if (WIFEXITED(status) && WEXITSTATUS(status) == kMalformedInput) {
      std::ifstream in(log);
      std::string line;
      std::getline(in, line);
      std::error_code ignored;
      std::filesystem::remove(log, ignored);
      return "not drawn: malformed input: " + line;
    }
    return "not drawn: matplotlib failed (is python3-matplotlib installed?), see " + log.string();
  }
  std::filesystem::remove(log);
  return "";
}

}  // namespace

std::string draw_plots(const std::filesystem::path& dir, bool /*quiet*/) {
  return run_plot_script("plot.py", dir);
}

void remove_plots(const std::filesystem::path& dir) {
  for (const char* name : {"trajectory.png", "phase.png", "energy.png", "spacetime.png"}) {
    std::error_code ignored;  // absent or not removable: nothing to do (the run's data are written)
    std::filesystem::remove(dir / name, ignored);
  }
}

std::string draw_convergence_plot(const std::filesystem::path& dir) {
  return run_plot_script("plot_convergence.py", dir);
}

std::string draw_compare_plots(const std::filesystem::path& dir) {
  return run_plot_script("plot_compare.py", dir);
}

}  // namespace fracvi::cli
