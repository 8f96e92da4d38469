#include "fracvi/io/output.hpp"
#include "fracvi/core/version.hpp"
#include "fracvi/io/npz.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

#include "fracvi/analysis/convergence.hpp"
#include "fracvi/integrate/dense_output.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/chain_potential.hpp"
#include "fracvi/model/expression_potential.hpp"

namespace fracvi {

std::shared_ptr<const Potential> make_potential(const ProblemSpec& spec) {
  if (spec.potential_object) return spec.potential_object;  // Python callables
  if (spec.chain) {
    ChainOptions options = *spec.chain;
    options.dimension = spec.dim;
    options.threads = spec.threads;
    return make_chain_potential(options);
  }
  return std::make_shared<const ExpressionPotential>(spec.dim, spec.potential);
}

MechanicalModel make_mechanical_model(const ProblemSpec& spec) {
  MechanicalModel m;
  m.mass = spec.mass;
  m.damping = spec.damping;
  m.alpha = spec.alpha;
  m.convention = *parse_convention(spec.convention);
  m.potential = make_potential(spec);
  if (spec.force_object) {
    m.state_force = spec.force_object;  // Python callables
  } else {
    auto forces = make_expression_forces(spec.dim, spec.force);
    m.forcing = std::move(forces.forcing);
    m.state_force = std::move(forces.state_force);
    m.forcing_formulas = std::move(forces.forcing_formulas);
  }
  return m;
}

InitialValueProblem make_initial_value_problem(const ProblemSpec& spec) {
  InitialValueProblem p;
  p.model = make_mechanical_model(spec);
  p.x0 = spec.position;
  p.v0 = spec.velocity;
  p.t0 = spec.start;
  p.t_end = spec.end;
  p.steps = static_cast<std::size_t>(spec.steps);
  return p;
}

IntegratorOptions make_integrator_options(const ProblemSpec& spec) {
  IntegratorOptions o;
  o.newton.relative_tolerance = spec.newton_tolerance;
  o.newton.max_iterations = spec.newton_max_iterations;
  o.history = *parse_history_kind(spec.history);
  o.history_tolerance = spec.history_tolerance;
  o.abs_tolerance = spec.abs_tolerance;
  o.rel_tolerance = spec.rel_tolerance;
  o.linear_solver = *parse_linear_solver(spec.linear_solver);
  o.load = *parse_forcing_load(spec.load);
  o.split = *parse_taylor_split(spec.split);
  o.error_estimate = *parse_error_estimate(spec.error_estimate);
  o.tolerance = spec.tolerance;
  o.max_steps = static_cast<std::size_t>(spec.max_steps);
  o.threads = spec.threads;
  o.flush_subnormals = spec.flush_subnormals;
  o.save_every = static_cast<std::size_t>(stored_every(spec));
  o.mirror = mirror_check_runs(spec);
  // On a second core alongside the run where it applies (integrator.hpp): a problem file's run is
  // one process's whole job, and method.threads = 1 keeps it on one core.
  o.mirror_alongside = true;
  o.output_times = spec.times;
  for (std::size_t i = 0; i < spec.events.size(); ++i) {
    const ProblemSpec::EventSpec& e = spec.events[i];
    o.events.push_back(formula_event(e.name, e.g, spec.dim, *parse_event_direction(e.direction),
                                     e.terminal, "events[" + std::to_string(i + 1) + "].g"));
  }
  return o;
}

nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

nlohmann::json json_row(const RowMatrixXd& m, Eigen::Index row) {
  nlohmann::json a = nlohmann::json::array();
  if (m.rows() == 0) return a;
  for (Eigen::Index j = 0; j < m.cols(); ++j) a.push_back(json_number(m(row, j)));
  return a;
}

void append_csv_number(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 17);
  out.append(buf, r.ptr);
}

std::filesystem::path temporary_path(const std::filesystem::path& file) {
  static std::atomic<unsigned> counter{0};
  return file.string() + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
}

void write_file_atomically(const std::filesystem::path& file,
                           const std::function<void(std::ostream&)>& write) {
  const auto tmp = temporary_path(file);
  // Nothing is left behind on failure: the temporary is removed before the error propagates.
  const auto fail = [&tmp](const std::string& what) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw OutputError(what);
  };
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) fail("cannot write " + tmp.string() + ": " + std::strerror(errno));
    try {
      write(out);
    } catch (...) {
      out.close();
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw;
    }
    if (!out.flush()) fail("error while writing " + tmp.string() + ": " + std::strerror(errno));
    out.close();
    if (out.fail()) fail("error while closing " + tmp.string() + ": " + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) fail("cannot rename " + tmp.string() + " to " + file.string() + ": " + ec.message());
}

void write_file_atomically(const std::filesystem::path& file, const std::string& content) {
  write_file_atomically(file, [&content](std::ostream& out) { out << content; });
}

namespace {
// The claims of this process: lock file → (descriptor, nesting depth).
std::mutex lock_mutex;
std::map<std::string, std::pair<int, int>> held_locks;

// The pid in a temporary's name: `<file>.tmp.<pid>.<n>` (write_file_atomically) or
// `.fracvi-write-test-<pid>` (prepare_output_directory's probe); 0 for any other name.
pid_t temporary_owner(const std::string& name) {
  // The value of a string of decimal digits, −1 for anything else.
  const auto number = [](std::string_view text) -> long long {
    long long value = -1;
    const auto r = std::from_chars(text.data(), text.data() + text.size(), value);
    return !text.empty() && r.ec == std::errc() && r.ptr == text.data() + text.size() ? value : -1;
  };
  const auto owner = [](long long pid) {
    return pid > 0 && pid <= std::numeric_limits<pid_t>::max() ? static_cast<pid_t>(pid) : 0;
  };
  constexpr std::string_view kProbe = ".fracvi-write-test-", kTemporary = ".tmp.";
  const std::string_view text(name);
  if (text.starts_with(kProbe)) return owner(number(text.substr(kProbe.size())));
  const std::size_t at = text.rfind(kTemporary);
  if (at == std::string_view::npos || at == 0) return 0;
  const std::string_view tail = text.substr(at + kTemporary.size());  // <pid>.<n>
  const std::size_t dot = tail.find('.');
  if (dot == std::string_view::npos || number(tail.substr(dot + 1)) < 0) return 0;
  return owner(number(tail.substr(0, dot)));
}

// A run killed while writing (SIGKILL, power loss) leaves its temporary: removed by the next run
// that claims the directory, if the process that wrote it is gone. Holding the directory's lock,
// no other fracvi run writes into it; the pid test keeps the temporaries of a live process (one
// writing without the lock) — a pid reused since by an unrelated process only keeps a dead
// temporary a while longer. Best effort: what cannot be listed or removed is left.
void remove_stale_temporaries(const std::filesystem::path& dir) {
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const pid_t pid = temporary_owner(it->path().filename().string());
    if (pid == 0 || pid == ::getpid()) continue;
    if (::kill(pid, 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to ask)
    std::error_code ignored;
    if (it->is_regular_file(ignored)) std::filesystem::remove(it->path(), ignored);
  }
}
}  // namespace

OutputLock::OutputLock(const std::filesystem::path& dir) {
  const std::string path = (dir / ".fracvi.lock").string();
  const std::lock_guard<std::mutex> guard(lock_mutex);
  if (auto it = held_locks.find(path); it != held_locks.end()) {
    ++it->second.second;
    key_ = path;
    return;
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    throw OutputError(dir.string() +
                      ": cannot create the lock file .fracvi.lock: " + std::strerror(errno));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    char owner[32] = {};
    const ssize_t n = ::pread(fd, owner, sizeof owner - 1, 0);
    ::close(fd);
    if (error == EWOULDBLOCK) {
      const std::string pid = n > 0 ? std::string(owner, static_cast<std::size_t>(n)) : "?";
      throw OutputError(dir.string() + ": in use by another fracvi run (pid " +
                        pid.substr(0, pid.find('\n')) +
                        "); give each concurrent run its own --out directory");
    }
    throw OutputError(dir.string() + ": cannot lock .fracvi.lock: " + std::strerror(error));
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    // The pid is only for the message of a competing run; the lock itself holds.
  }
  held_locks.emplace(path, std::make_pair(fd, 1));
  key_ = path;
  remove_stale_temporaries(dir);
}

OutputLock::~OutputLock() {
  if (key_.empty()) return;
  const std::lock_guard<std::mutex> guard(lock_mutex);
  auto it = held_locks.find(key_);
  if (it == held_locks.end() || --it->second.second > 0) return;
  // Unlinked while still locked: a process that opened the old file finds it locked and refuses;
  // one that opens after this creates a fresh file and may claim it (this run is done).
  ::unlink(key_.c_str());
  ::close(it->second.first);
  held_locks.erase(it);
}

void prepare_output_directory(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(dir, ec);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw OutputError(dir.string() + ": exists and is not a directory");
  }
  fs::create_directories(dir, ec);
  if (ec) throw OutputError(dir.string() + ": cannot create the directory: " + ec.message());
  // Writable? Create, write and remove a probe file (a unique name: runs may share the directory).
  const fs::path probe = dir / (".fracvi-write-test-" + std::to_string(::getpid()));
  bool written = false;
  int error = 0;
  {
    std::ofstream out(probe, std::ios::binary | std::ios::trunc);
    written = out && (out << "fracvi\n") && out.flush();
    if (!written) error = errno;
  }
  fs::remove(probe, ec);
  if (!written) {
    throw OutputError(dir.string() + ": cannot write into the directory: " +
                      std::strerror(error != 0 ? error : EIO));
  }
}

// The doubling of method.tolerance (empty array without one).
nlohmann::json tolerance_runs_json(const Solution& s) {
  nlohmann::json runs = nlohmann::json::array();
  for (const ToleranceRun& r : s.tolerance_runs) {
    runs.push_back({{"steps", r.steps},
                    {"error_estimate", json_number(r.error_estimate)},
                    {"wall_seconds", r.wall_seconds},
                    {"status", r.status}});
  }
  return runs;
}

// The crossings of the run's events (Solution::events) for summary.json.
nlohmann::json events_json(const Solution& s) {
  nlohmann::json a = nlohmann::json::array();
  const EventLog& log = s.events;
  const auto d = static_cast<std::size_t>(s.x.cols());
  for (std::size_t i = 0; i < log.size(); ++i) {
    nlohmann::json x = nlohmann::json::array(), v = nlohmann::json::array();
    for (std::size_t j = 0; j < d; ++j) {
      x.push_back(json_number(log.x[i * d + j]));
      v.push_back(json_number(log.v[i * d + j]));
    }
    a.push_back({{"name", log.names[log.event[i]]},
                 {"t", json_number(log.t[i])},
                 {"direction", log.direction[i] > 0 ? "rising" : "falling"},
                 {"step", log.step[i]},
                 {"position", x},
                 {"velocity", v}});
  }
  return a;
}

nlohmann::json make_summary(const ProblemSpec& spec, const Solution& s) {
  const Eigen::Index last = s.t.size() - 1;  // the last stored row: step s.steps_done
  nlohmann::json reference_error;            // null without a [reference]
  if (!spec.reference.empty())
    reference_error = json_number(max_error(s, parse_reference(spec.reference)));
  return {
      {"fracvi_version", version_string()},
      {"status", s.ok() ? "success" : std::string(to_string(s.status))},
      {"message", s.message},
      {"steps", s.steps_done},
      {"steps_requested", spec.steps},
      {"final_time", s.t.size() ? json_number(s.t[last]) : nlohmann::json()},
      {"final_position", json_row(s.x, last)},
      {"final_velocity", json_row(s.v, last)},
      {"final_energy", s.energy.size() ? json_number(s.energy[last]) : nlohmann::json()},
      {"mirror_error", json_number(s.mirror_error)},
      {"reference_error", reference_error},
      {"error_estimate", json_number(s.error_estimate.value)},
      {"error_estimate_details",
       {{"method", s.error_estimate.method},
        {"order", json_number(s.error_estimate.order)},
        {"observed_order", json_number(s.error_estimate.observed_order)},
        {"nodes", s.error_estimate.nodes},
        {"note", s.error_estimate.note},
        {"wall_seconds", s.error_estimate.wall_seconds},
        {"concurrent", s.error_estimate.concurrent}}},
      {"tolerance_runs", tolerance_runs_json(s)},
      {"max_balance_error", json_number(s.max_balance_error)},
      {"newton_iterations", s.newton_iterations},
      {"max_newton_iterations_per_step", s.max_newton_iterations_per_step},
      {"jacobian_factorizations", s.jacobian_factorizations},
      {"linear_solver", s.linear_solver},
      {"history", s.history},
      {"history_bytes", s.history_bytes},
      {"history_exponentials", s.history_exponentials},
      {"history_window", s.history_window},
      {"history_tolerance", json_number(s.history_tolerance)},
      {"history_tolerance_mode",
       std::isfinite(s.history_tolerance) ? (s.history_tolerance_auto ? "auto" : "user") : ""},
      {"history_limited", s.history_limited},
      {"history_threads",
       {{"team", s.history_threads.team},
        {"measured", s.history_threads.measured},
        {"pushes", s.history_threads.pushes},
        {"team_pushes", s.history_threads.team_pushes},
        {"decisions", s.history_threads.decisions},
        {"team_won", s.history_threads.team_won},
        {"team_dropped", s.history_threads.team_dropped},
        {"whole_steps", s.history_threads.whole_steps}}},
      {"save_every", s.save_every},
      {"output_times", s.output_t.size()},
      {"events", events_json(s)},
      {"wall_seconds", s.setup_seconds + s.wall_time_seconds},
      {"setup_wall_seconds", s.setup_seconds},
      {"stepping_wall_seconds", s.wall_time_seconds},
      {"method", s.method},
      {"declared_order", s.declared_order},
      {"problem", to_json(spec)},
  };
}

namespace {

// A field of a summary.json being read back; `what` names the file in messages.
struct SummaryReader {
  const nlohmann::json& j;
  std::string what;

  [[noreturn]] void fail(const std::string& key, const std::string& rule) const {
    throw OutputError(what + ": \"" + key + "\" " + rule);
  }
  const nlohmann::json& at(const nlohmann::json& object, const std::string& key) const {
    if (!object.is_object() || !object.contains(key)) fail(key, "is missing");
    return object[key];
  }
  // A number; null is NaN (json_number writes non-finite numbers as null).
  double number(const nlohmann::json& object, const std::string& key) const {
    const auto& v = at(object, key);
    if (v.is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!v.is_number()) fail(key, "= " + v.dump() + " is not a number");
    return v.get<double>();
  }
  std::size_t count(const nlohmann::json& object, const std::string& key) const {
    const auto& v = at(object, key);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0)) {
      fail(key, "= " + v.dump() + " is not a count (an integer >= 0)");
    }
    return v.get<std::size_t>();
  }
  bool flag(const nlohmann::json& object, const std::string& key) const {
    const auto& v = at(object, key);
    if (!v.is_boolean()) fail(key, "= " + v.dump() + " is not true/false");
    return v.get<bool>();
  }
  std::string text(const nlohmann::json& object, const std::string& key) const {
    const auto& v = at(object, key);
    if (!v.is_string()) fail(key, "= " + v.dump() + " is not a string");
    return v.get<std::string>();
  }
  Status status(const nlohmann::json& object, const std::string& key) const {
    const std::string name = text(object, key);
    const auto s = parse_status(name);
    if (!s) fail(key, "= \"" + name + "\" is not a status of a run");
    return *s;
  }
};

}  // namespace

void read_summary(const nlohmann::json& summary, Solution& s, const std::string& what) {
  const SummaryReader r{summary, what};
  if (!summary.is_object()) throw OutputError(what + ": not a JSON object");
  s.status = r.status(summary, "status");
  s.message = r.text(summary, "message");
  s.steps_done = r.count(summary, "steps");
  s.mirror_error = r.number(summary, "mirror_error");
  s.error_estimate.value = r.number(summary, "error_estimate");
  const auto& details = r.at(summary, "error_estimate_details");
  s.error_estimate.method = r.text(details, "method");
  s.error_estimate.order = r.number(details, "order");
  s.error_estimate.observed_order = r.number(details, "observed_order");
  s.error_estimate.nodes = r.count(details, "nodes");
  s.error_estimate.note = r.text(details, "note");
  s.error_estimate.wall_seconds = r.number(details, "wall_seconds");
  // Absent in summaries written before the companions could run alongside the run.
  s.error_estimate.concurrent = details.contains("concurrent") &&
                                details.at("concurrent").is_boolean() &&
                                details.at("concurrent").get<bool>();
  s.tolerance_runs.clear();
  const auto& runs = r.at(summary, "tolerance_runs");
  if (!runs.is_array()) r.fail("tolerance_runs", "is not an array");
  for (const auto& run : runs) {
    s.tolerance_runs.push_back({r.count(run, "steps"), r.number(run, "error_estimate"),
                                r.number(run, "wall_seconds"), r.text(run, "status")});
  }
  s.max_balance_error = r.number(summary, "max_balance_error");
  s.newton_iterations = r.count(summary, "newton_iterations");
  s.max_newton_iterations_per_step = r.count(summary, "max_newton_iterations_per_step");
  // Written before factorisations were counted: 0, as for an explicit scheme.
  s.jacobian_factorizations =
      summary.contains("jacobian_factorizations") ? r.count(summary, "jacobian_factorizations") : 0;
  s.linear_solver = r.text(summary, "linear_solver");
  s.history = r.text(summary, "history");
  if (summary.contains("history_exponentials")) {
    s.history_bytes = r.count(summary, "history_bytes");
    s.history_exponentials = r.count(summary, "history_exponentials");
    s.history_window = r.count(summary, "history_window");
  }  // else written before K and n0 were recorded (issue 17): 0 as for no fast history
  if (summary.contains("history_tolerance")) {
    s.history_tolerance = r.number(summary, "history_tolerance");
    s.history_tolerance_auto = r.text(summary, "history_tolerance_mode") == "auto";
    s.history_limited = r.flag(summary, "history_limited");
  } else {  // written before the accuracy budget (issue 17): ε was not recorded
    s.history_tolerance = std::numeric_limits<double>::quiet_NaN();
    s.history_tolerance_auto = s.history_limited = false;
  }
  s.history_threads = HistoryThreads{};
  if (summary.contains("history_threads")) {  // absent in summaries written before it (issue 17)
    const auto& t = r.at(summary, "history_threads");
    const std::size_t team = r.count(t, "team");
    if (team < 1 || team > 4096)
      r.fail("team", "= " + std::to_string(team) + " is not in [1, 4096]");
    s.history_threads = {static_cast<int>(team), r.flag(t, "measured"), r.count(t, "pushes"),
                         r.count(t, "team_pushes"), r.count(t, "decisions"), r.count(t, "team_won"),
                         r.count(t, "team_dropped"),
                         // absent in summaries written before the step split by rows
                         t.contains("whole_steps") && r.flag(t, "whole_steps")};
  }
  s.save_every = r.count(summary, "save_every");
  if (s.save_every < 1) r.fail("save_every", "= 0 is not a storage stride (at least 1)");
  if (summary.contains("stepping_wall_seconds")) {
    s.wall_time_seconds = r.number(summary, "stepping_wall_seconds");
    s.setup_seconds = r.number(summary, "setup_wall_seconds");
  } else {  // written before set-up and stepping were reported apart: all of it was stepping
    s.wall_time_seconds = r.number(summary, "wall_seconds");
    s.setup_seconds = 0.0;
  }
  s.events = EventLog{};
  if (summary.contains("events")) {  // absent in summaries written before events (issue 16)
    const auto& crossings = r.at(summary, "events");
    if (!crossings.is_array()) r.fail("events", "is not an array");
    for (const auto& c : crossings) {
      const std::string name = r.text(c, "name");
      const auto known = std::find(s.events.names.begin(), s.events.names.end(), name);
      s.events.event.push_back(static_cast<std::size_t>(known - s.events.names.begin()));
      if (known == s.events.names.end()) s.events.names.push_back(name);
      s.events.t.push_back(r.number(c, "t"));
      s.events.step.push_back(r.count(c, "step"));
      const std::string direction = r.text(c, "direction");
      if (direction != "rising" && direction != "falling")
        r.fail("events", "direction = \"" + direction + "\" is not rising or falling");
      s.events.direction.push_back(direction == "rising" ? 1 : -1);
      for (const char* key : {"position", "velocity"}) {
        const auto& state = r.at(c, key);
        if (!state.is_array()) r.fail(std::string("events ") + key, "is not an array");
        auto& out = std::string_view(key) == "position" ? s.events.x : s.events.v;
        for (const auto& value : state) {
          if (!value.is_null() && !value.is_number())
            r.fail(std::string("events ") + key, "holds " + value.dump() + ", not a number");
          out.push_back(value.is_null() ? std::numeric_limits<double>::quiet_NaN()
                                        : value.get<double>());
        }
      }
    }
  }
  s.method = r.text(summary, "method");
  const auto& order = r.at(summary, "declared_order");
  if (!order.is_number_integer())
    r.fail("declared_order", "= " + order.dump() + " is not an integer");
  s.declared_order = order.get<int>();
}

void write_trajectory_npz(const std::filesystem::path& file, const Solution& s) {
  const auto rows = static_cast<std::size_t>(s.t.size());
  const auto d = static_cast<std::size_t>(s.x.cols());
  const std::vector<std::int64_t> step(s.step.begin(), s.step.end());
  const std::vector<NpyArray> arrays{
      {"t", {rows}, s.t.data()},
      {"step", {step.size()}, nullptr, step.data()},
      {"x", {rows, d}, s.x.data()},
      {"v", {rows, d}, s.v.data()},
      {"energy", {rows}, s.energy.data()},
      {"dissipated", {rows}, s.dissipated.data()},
      {"balance", {rows}, s.balance.data()},
  };
  write_npz(file, arrays);
}

void write_run_output(const std::filesystem::path& dir, const ProblemSpec& spec, const Solution& s,
                      std::string_view format) {
  prepare_output_directory(dir);
  const OutputLock lock(dir);
  // summary.json goes last and an earlier one first: a directory with a summary.json holds one
  // complete run, whatever was interrupted.
  std::error_code ec;
  std::filesystem::remove(dir / "summary.json", ec);
  const bool npz = (format.empty() ? std::string_view(spec.format) : format) == "npz";
  std::filesystem::remove(dir / (npz ? "trajectory.csv" : "trajectory.npz"), ec);
  if (npz) {
    write_trajectory_npz(dir / "trajectory.npz", s);
  } else {
    write_trajectory_csv(dir / "trajectory.csv", s);
  }
  std::filesystem::remove(dir / "times.csv", ec);
  std::filesystem::remove(dir / "events.csv", ec);
  if (!spec.times.empty()) write_times_csv(dir / "times.csv", s);
  if (!spec.events.empty()) write_events_csv(dir / "events.csv", s);
  write_file_atomically(dir / "problem.toml",
                        "# written by " + version_string() + "\n" + to_toml(spec));
  write_file_atomically(dir / "summary.json", make_summary(spec, s).dump(2) + "\n");
}

namespace {

// "t,x1,…,xd,v1,…,vd\n" after `first` (a comma-terminated prefix of columns, or "").
std::string state_header(const std::string& first, Eigen::Index d) {
  std::string line = first + "t";
  for (Eigen::Index i = 1; i <= d; ++i) line += ",x" + std::to_string(i);
  for (Eigen::Index i = 1; i <= d; ++i) line += ",v" + std::to_string(i);
  return line + "\n";
}

void append_state(std::string& line, double t, const double* x, const double* v, Eigen::Index d) {
  append_csv_number(line, t);
  for (Eigen::Index i = 0; i < d; ++i) line += ',', append_csv_number(line, x[i]);
  for (Eigen::Index i = 0; i < d; ++i) line += ',', append_csv_number(line, v[i]);
  line += '\n';
}

}  // namespace

void write_times_csv(const std::filesystem::path& file, const Solution& s) {
  const Eigen::Index d = s.x.cols();
  write_file_atomically(file, [&s, d](std::ostream& out) {
    std::string line = state_header("", d);
    for (Eigen::Index r = 0; r < s.output_t.size(); ++r) {
      append_state(line, s.output_t[r], s.output_x.row(r).data(), s.output_v.row(r).data(), d);
    }
    out << line;
  });
}

void write_events_csv(const std::filesystem::path& file, const Solution& s) {
  const Eigen::Index d = s.x.cols();
  write_file_atomically(file, [&s, d](std::ostream& out) {
    std::string line = state_header("event,direction,step,", d);
    const EventLog& log = s.events;
    const auto stride = static_cast<std::size_t>(d);
    for (std::size_t i = 0; i < log.size(); ++i) {
      line += log.names[log.event[i]] + (log.direction[i] > 0 ? ",rising," : ",falling,") +
              std::to_string(log.step[i]) + ",";
      append_state(line, log.t[i], log.x.data() + i * stride, log.v.data() + i * stride, d);
    }
    out << line;
  });
}

void write_trajectory_csv(const std::filesystem::path& file, const Solution& s) {
  const Eigen::Index d = s.x.cols();
  // Streamed row by row through one reused buffer: the CSV text is about three times the size of
  // the stored trajectory and is never held in memory as a whole.
  write_file_atomically(file, [&s, d](std::ostream& out) {
    std::string line = "t";
    for (Eigen::Index i = 1; i <= d; ++i) line += ",x" + std::to_string(i);
    for (Eigen::Index i = 1; i <= d; ++i) line += ",v" + std::to_string(i);
    line += ",energy,dissipated,balance\n";
    out << line;
    // Every stored row: the integrator already kept only every save_every-th state.
    for (Eigen::Index k = 0; k < s.t.size(); ++k) {
      line.clear();
      append_csv_number(line, s.t[k]);
      for (Eigen::Index i = 0; i < d; ++i) line += ',', append_csv_number(line, s.x(k, i));
      for (Eigen::Index i = 0; i < d; ++i) line += ',', append_csv_number(line, s.v(k, i));
      line += ',', append_csv_number(line, s.energy[k]);
      line += ',', append_csv_number(line, s.dissipated[k]);
      line += ',', append_csv_number(line, s.balance[k]);
      line += '\n';
      out << line;
    }
  });
}

}  // namespace fracvi
