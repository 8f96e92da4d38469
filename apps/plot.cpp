#include "plot.hpp"

#include <cstdlib>
#include <filesystem>
#include <string>

namespace fracvi::cli {

namespace {

// The plotting script: next to the installed binary (../share/fracvi/plot.py) or in the source
// tree this binary was built from.
std::filesystem::path plot_script() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto installed = exe.parent_path().parent_path() / "share" / "fracvi" / "plot.py";
    if (std::filesystem::exists(installed)) return installed;
  }
  return std::filesystem::path(FRACVI_SOURCE_DIR) / "python" / "fracvi" / "plot.py";
}

std::string quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

std::string draw_plots(const std::filesystem::path& dir, bool quiet) {
  // Debian's interpreter: the first python3 on PATH may be another one without matplotlib.
  const std::string python = "/usr/bin/python3";
  const auto script = plot_script();
  if (!std::filesystem::exists(python)) return "not drawn: /usr/bin/python3 is not installed";
  if (!std::filesystem::exists(script)) return "not drawn: " + script.string() + " is missing";
  const std::string cmd = quoted(python) + " " + quoted(script.string()) + " " +
                          quoted(dir.string()) + " >/dev/null 2>" +
                          quoted((dir / "plot.log").string());
  const int rc = std::system(cmd.c_str());
  if (rc != 0) {
    (void)quiet;
    return "not drawn: matplotlib failed (python3-matplotlib installed?), see " +
           (dir / "plot.log").string();
  }
  std::filesystem::remove(dir / "plot.log");
  return "";
}

}  // namespace fracvi::cli
