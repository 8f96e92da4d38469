#include "fracvi/io/checkpoint.hpp"

#include <bit>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "fracvi/core/version.hpp"
#include "fracvi/io/output.hpp"

namespace fracvi {

namespace {

constexpr std::string_view kMagic = "FRACVI-CHECKPOINT 1\n";

// FNV-1a, 64 bits: enough to tell a damaged or truncated file from the one written.
std::string fnv1a64(std::string_view bytes) {
  std::uint64_t hash = 14695981039346656037ull;
  for (const char c : bytes) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 1099511628211ull;
  }
  char text[20];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

// The problem as the checkpoint compares it: the resolved TOML (problem.toml without its first,
// comment line naming the version).
std::string problem_text(const ProblemSpec& spec) {
  return to_toml(spec);
}

// "line N: `a` in the checkpoint, `b` in problem.toml" for the first line that differs.
std::string first_difference(const std::string& saved, const std::string& now) {
  std::istringstream a(saved), b(now);
  std::string la, lb;
  for (int line = 1;; ++line) {
    const bool more_a = static_cast<bool>(std::getline(a, la));
    const bool more_b = static_cast<bool>(std::getline(b, lb));
    if (!more_a && !more_b) return "";
    if (!more_a) la = "(end)";
    if (!more_b) lb = "(end)";
    if (la != lb || !more_a || !more_b) {
      return "`" + la + "` when the checkpoint was taken, `" + lb + "` now";
    }
  }
}

}  // namespace

void write_checkpoint(const std::filesystem::path& dir, const ProblemSpec& spec,
                      Integrator& integrator) {
  StateWriter writer;
  integrator.visit_state(writer);
  const std::string& state = writer.bytes();
  const nlohmann::json header = {
      {"byte_order", std::endian::native == std::endian::little ? "little" : "big"},
      {"fracvi_version", version_string()},
      {"scheme", std::string(integrator.method().name())},
      {"step", integrator.steps_done()},
      {"steps", integrator.steps_total()},
      {"state_bytes", state.size()},
      {"state_fnv1a64", fnv1a64(state)},
      {"problem", problem_text(spec)},
  };
  const OutputLock lock(dir);
  write_file_atomically(dir / "problem.toml",
                        "# written by " + version_string() + "\n" + problem_text(spec));
  write_file_atomically(dir / kCheckpointFile, [&](std::ostream& out) {
    out << kMagic << header.dump() << '\n';
    out.write(state.data(), static_cast<std::streamsize>(state.size()));
  });
}

Checkpoint read_checkpoint(const std::filesystem::path& dir) {
  Checkpoint c;
  c.file = dir / kCheckpointFile;
  const std::string where = c.file.string();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw CheckpointError(dir.string() +
                          ": not a directory (--resume takes the output directory "
                          "of a run that wrote checkpoints)");
  }
  std::ifstream in(c.file, std::ios::binary);
  if (!in) {
    throw CheckpointError(where + ": no checkpoint (the run in " + dir.string() +
                          " did not write one: set [output] checkpoint_every = n)");
  }
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto corrupt = [&where](const std::string& what) {
    return CheckpointError(where + ": corrupt checkpoint: " + what);
  };
  if (bytes.compare(0, kMagic.size(), kMagic) != 0) {
    throw corrupt("it does not start with \"FRACVI-CHECKPOINT 1\"");
  }
  const std::size_t end_of_header = bytes.find('\n', kMagic.size());
  if (end_of_header == std::string::npos) throw corrupt("no header line");
  nlohmann::json header;
  try {
    header = nlohmann::json::parse(bytes.substr(kMagic.size(), end_of_header - kMagic.size()));
    c.step = header.at("step").get<std::size_t>();
    c.scheme = header.at("scheme").get<std::string>();
    const auto size = header.at("state_bytes").get<std::size_t>();
    c.state = bytes.substr(end_of_header + 1);
    if (c.state.size() != size) {
      throw corrupt("the state has " + std::to_string(c.state.size()) + " bytes, the header says " +
                    std::to_string(size) + " (truncated?)");
    }
    if (header.at("byte_order").get<std::string>() !=
        (std::endian::native == std::endian::little ? "little" : "big")) {
      throw CheckpointError(where + ": written on a machine of the other byte order");
    }
    if (fnv1a64(c.state) != header.at("state_fnv1a64").get<std::string>()) {
      throw corrupt("the state's checksum does not match (the file was altered or damaged)");
    }
  } catch (const nlohmann::json::exception& e) {
    throw corrupt(std::string("unreadable header: ") + e.what());
  }
  const std::filesystem::path problem_file = dir / "problem.toml";
  if (!std::filesystem::exists(problem_file, ec)) {
    throw CheckpointError(problem_file.string() + ": missing (the checkpoint's problem)");
  }
  c.spec = load_problem(problem_file);
  const std::string saved = header.at("problem").get<std::string>();
  if (const std::string now = problem_text(c.spec); now != saved) {
    throw CheckpointError(problem_file.string() +
                          ": the problem changed since the checkpoint was taken (" +
                          first_difference(saved, now) +
                          "); resume refused: a resumed run must continue the same problem "
                          "(start a new run for a changed one)");
  }
  return c;
}

void restore_checkpoint(const Checkpoint& checkpoint, Integrator& integrator) {
  if (checkpoint.scheme != integrator.method().name()) {
    throw CheckpointError(checkpoint.file.string() + ": taken with method.scheme = \"" +
                          checkpoint.scheme + "\", not \"" +
                          std::string(integrator.method().name()) + "\"");
  }
  StateReader reader(checkpoint.state, "");
  try {
    integrator.visit_state(reader);
    reader.finish();
  } catch (const CheckpointError& e) {
    throw CheckpointError(checkpoint.file.string() + ": " + e.what());
  }
}

}  // namespace fracvi
