// The commands' output directories: prepared before any work, written after it (cli.hpp).
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <list>
#include <string>
#include <vector>

#include "cli.hpp"
#include "fracvi/io/output.hpp"

namespace fracvi::cli {

namespace {

// The directories this process claimed (held until it exits: the run, then its writing), and
// whether prepare_output created them.
struct Claim {
  std::filesystem::path dir;
  bool created;
  OutputLock lock;
};
std::list<Claim>& claims() {
  static std::list<Claim> held;  // a list: OutputLock is not move-assignable
  return held;
}

}  // namespace

std::filesystem::path prepare_output(const std::string& given,
                                     const std::filesystem::path& fallback) {
  const std::filesystem::path dir = given.empty() ? fallback : std::filesystem::path(given);
  try {
    std::error_code ec;
    const bool existed = std::filesystem::exists(dir, ec);
    prepare_output_directory(dir);
    claims().push_back(Claim{dir, !existed, OutputLock(dir)});
  } catch (const OutputError& e) {
    throw UsageError((given.empty() ? std::string("output directory ") : std::string("--out ")) +
                     e.what());
  }
  return dir;
}

void abandon_output(const std::filesystem::path& dir) {
  auto& held = claims();
  for (auto it = held.begin(); it != held.end(); ++it) {
    if (it->dir != dir) continue;
    const bool created = it->created;
    held.erase(it);           // releases the lock (its file is removed)
    std::error_code ignored;  // not empty, or not removable: leave it
    if (created) std::filesystem::remove(dir, ignored);
    return;
  }
}

std::filesystem::path default_output(const std::string& name, const std::string& suffix,
                                     const std::vector<std::string>& overrides) {
  std::string tail;
  // `--set name=…` names the run: the user chose the directory's name, nothing is appended.
  const bool named = std::any_of(overrides.begin(), overrides.end(),
                                 [](const std::string& o) { return o.rfind("name=", 0) == 0; });
  for (const std::string& o : named ? std::vector<std::string>{} : overrides) {
    tail += '-';
    for (const char c : o) {
      const bool plain = std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' || c == '_' ||
                         c == '=' || c == '+' || c == '-';
      tail += plain ? c : '_';
    }
  }
  constexpr std::size_t kMaxTail = 80;
  if (tail.size() > kMaxTail) {
    // FNV-1a of the overrides: short, stable across runs and machines.
    std::uint64_t hash = 14695981039346656037ull;
    for (const std::string& o : overrides) {
      for (const char c : o + '\n') {
        hash ^= static_cast<unsigned char>(c);
        hash *= 1099511628211ull;
      }
    }
    char buf[24];
    std::snprintf(buf, sizeof buf, "-set-%016llx", static_cast<unsigned long long>(hash));
    tail = buf;
  }
  return std::filesystem::path("fracvi-out") / (name + suffix + tail);
}

void report_quiet_failure(const char* command, const std::string& name, Status status,
                          const std::string& message, const std::string& where,
                          const std::filesystem::path& dir) {
  std::fprintf(stderr, "fracvi %s: %s: %s%s%s (%s; files in %s)\n", command, name.c_str(),
               to_string(status).data(), message.empty() ? "" : ": ", message.c_str(),
               where.c_str(), dir.string().c_str());
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
