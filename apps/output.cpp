// The commands' output directories: prepared before any work, written after it (cli.hpp).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <string>

#include "cli.hpp"
#include "fracvi/io/output.hpp"

namespace fracvi::cli {

std::filesystem::path prepare_output(const std::string& given,
                                     const std::filesystem::path& fallback) {
  const std::filesystem::path dir = given.empty() ? fallback : std::filesystem::path(given);
  try {
    prepare_output_directory(dir);
  } catch (const OutputError& e) {
    throw UsageError((given.empty() ? std::string("output directory ") : std::string("--out ")) +
                     e.what());
  }
  return dir;
}

bool write_results(const char* command, const std::filesystem::path& dir,
                   const std::function<void()>& write) {
  try {
    write();
    return true;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fracvi %s: the results could not be written to %s: %s\n", command,
                 dir.string().c_str(), e.what());
    return false;
  }
}

}  // namespace fracvi::cli
