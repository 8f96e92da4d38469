#include "fracvi/io/sweep.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>
#include <utility>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_schema.hpp"
#include "fracvi/io/run.hpp"

namespace fracvi {

namespace {

using Json = nlohmann::json;

// --- TOML → JSON (the sweep file and a base problem file become one JSON document) -------------

Json to_json_value(const toml::node& node);

Json to_json_table(const toml::table& table) {
  Json out = Json::object();
  for (const auto& [k, v] : table) out[std::string(k.str())] = to_json_value(v);
  return out;
}

Json to_json_value(const toml::node& node) {
  if (const auto* t = node.as_table()) return to_json_table(*t);
  if (const auto* a = node.as_array()) {
    Json out = Json::array();
    for (const auto& v : *a) out.push_back(to_json_value(v));
    return out;
  }
  if (const auto* v = node.as_integer()) return Json(static_cast<std::int64_t>(v->get()));
  if (const auto* v = node.as_floating_point()) return Json(v->get());
  if (const auto* v = node.as_string()) return Json(v->get());
  if (const auto* v = node.as_boolean()) return Json(v->get());
  // Dates and times: no problem field takes one; the reader then names the key and the type.
  return Json("a TOML date or time");
}

toml::table parse_toml_file(const std::filesystem::path& file, const std::string& what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SweepError(file.string() + ": cannot open the " + what);
  std::stringstream text;
  text << in.rdbuf();
  try {
    return toml::parse(text.str(), file.string());
  } catch (const toml::parse_error& e) {
    throw SweepError(file.string() + ":" + std::to_string(e.source().begin.line) + ":" +
                     std::to_string(e.source().begin.column) +
                     ": not valid TOML: " + std::string(e.description()));
  }
}

// --- values as TOML text (what apply_override reads back) --------------------------------------

std::string number_text(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  // The shortest text that reads back as the same double (0.2, not 0.20000000000000001).
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  // A float stays a float ("2" would be read as an integer).
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string toml_text(const Json& v, const std::string& where) {
  if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
  if (v.is_number()) return number_text(v.get<double>());
  if (v.is_string()) return quoted(v.get<std::string>());
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < v.size(); ++i) {
      out += (i ? ", " : "") + toml_text(v[i], where);
    }
    return out + "]";
  }
  throw SweepError(where + ": a value must be a number, a string, a boolean or an array, got " +
                   std::string(v.type_name()));
}

// --- the parameter forms ----------------------------------------------------------------------

const std::vector<std::string> kForms = {"values", "linspace", "logspace", "random"};
const std::vector<std::string> kRandomKeys = {"random", "count", "seed", "low",
                                              "high",   "mean",  "std"};

bool is_form(const Json& v) {
  if (!v.is_object()) return false;
  return std::any_of(kForms.begin(), kForms.end(),
                     [&v](const std::string& f) { return v.contains(f); });
}

double number_of(const Json& v, const std::string& where) {
  if (!v.is_number()) {
    throw SweepError(where + " = " + v.dump() + " must be a number");
  }
  return v.get<double>();
}

// The most cases a sweep may have (and so values a parameter may take): far beyond what runs in
// a day, small enough that the case list itself is never the problem.
constexpr std::size_t kMaxCases = 10'000'000;

long long count_of(const Json& v, const std::string& where) {
  if (!v.is_number_integer() || v.get<long long>() < 1 ||
      v.get<long long>() > static_cast<long long>(kMaxCases)) {
    throw SweepError(where + " = " + v.dump() + " must be an integer count from 1 to " +
                     std::to_string(kMaxCases));
  }
  return v.get<long long>();
}

// splitmix64 (Steele, Lea & Flood 2014): a generator fully specified here, so that a seed gives
// the same draws with every compiler and standard library (std::*_distribution do not).
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  /// Uniform in (0, 1]: 53 random bits.
  double uniform() { return (static_cast<double>(next() >> 11) + 1.0) * 0x1.0p-53; }
};

std::vector<double> random_draws(const Json& spec, const std::string& where) {
  for (const auto& [k, v] : spec.items()) {
    if (std::find(kRandomKeys.begin(), kRandomKeys.end(), k) == kRandomKeys.end()) {
      throw SweepError(where + "." + k + ": unknown key of a random draw" +
                       did_you_mean(k, kRandomKeys) +
                       "; valid: random, count, seed, low, high (uniform, loguniform), mean, "
                       "std (normal)");
    }
  }
  if (!spec["random"].is_string()) {
    throw SweepError(where + ".random must be \"uniform\", \"loguniform\" or \"normal\"");
  }
  const std::string kind = spec["random"].get<std::string>();
  const auto need = [&](const char* key) {
    if (!spec.contains(key)) {
      throw SweepError(where + ": random = \"" + kind + "\" needs " + key);
    }
    return number_of(spec[key], where + "." + key);
  };
  const auto refuse = [&](std::initializer_list<const char*> keys) {
    for (const char* key : keys) {
      if (spec.contains(key)) {
        throw SweepError(where + "." + key + " does not apply to random = \"" + kind + "\"");
      }
    }
  };
  if (!spec.contains("count")) throw SweepError(where + ": a random draw needs count");
  if (!spec.contains("seed")) {
    throw SweepError(where +
                     ": a random draw needs seed (an integer: the same seed, the same "
                     "draws)");
  }
  const long long count = count_of(spec["count"], where + ".count");
  if (!spec["seed"].is_number_integer()) {
    throw SweepError(where + ".seed = " + spec["seed"].dump() + " must be an integer");
  }
  SplitMix64 rng{static_cast<std::uint64_t>(spec["seed"].get<std::int64_t>())};
  std::vector<double> out;
  out.reserve(static_cast<std::size_t>(count));
  if (kind == "uniform" || kind == "loguniform") {
    refuse({"mean", "std"});
    const double low = need("low"), high = need("high");
    if (!(low < high)) {
      throw SweepError(where + ": low = " + number_text(low) +
                       " must be below high = " + number_text(high));
    }
    if (kind == "loguniform" && !(low > 0.0)) {
      throw SweepError(where + ": loguniform needs low > 0, got " + number_text(low));
    }
    for (long long i = 0; i < count; ++i) {
      const double u = rng.uniform();
      out.push_back(kind == "uniform"
                        ? low + (high - low) * u
                        : std::exp(std::log(low) + (std::log(high) - std::log(low)) * u));
    }
  } else if (kind == "normal") {
    refuse({"low", "high"});
    const double mean = need("mean"), sd = need("std");
    if (!(sd >= 0.0)) throw SweepError(where + ".std must be >= 0, got " + number_text(sd));
    for (long long i = 0; i < count; ++i) {
      // Box–Muller, one draw per pair of uniforms (u1 in (0, 1], so the log is finite).
      const double u1 = rng.uniform(), u2 = rng.uniform();
      out.push_back(mean + sd * std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2));
    }
  } else {
    throw SweepError(where + ".random = \"" + kind +
                     "\" is not one of uniform, loguniform, normal" +
                     did_you_mean(kind, {"uniform", "loguniform", "normal"}));
  }
  return out;
}

// The values of one parameter as TOML text. An integer field (time.steps, model.dim, …) takes
// generated numbers rounded to the nearest integer (logspace over time.steps is the usual case).
std::vector<std::string> parameter_values(const std::string& path, const Json& spec,
                                          const std::string& where) {
  const auto dot = path.rfind('.');
  const ProblemField* field = dot == std::string::npos
                                  ? find_field("", path)
                                  : find_field(path.substr(0, dot), path.substr(dot + 1));
  const bool integer = field && field->type == "integer";
  std::vector<std::string> out;
  const auto generated = [&](const std::vector<double>& numbers) {
    for (const double x : numbers) {
      if (integer) {
        if (!std::isfinite(x)) throw SweepError(where + ": " + number_text(x) + " for " + path);
        // llround beyond the 64-bit integers is unspecified (1e30 became -2^63, "must be
        // positive"): refused with the value instead.
        if (!(std::abs(x) < 0x1p63)) {
          throw SweepError(where + ": " + number_text(x) + " for the integer field " + path +
                           " is beyond the 64-bit integers");
        }
        out.push_back(std::to_string(std::llround(x)));
      } else {
        out.push_back(number_text(x));
      }
    }
  };
  if (spec.is_array()) {
    if (spec.empty()) throw SweepError(where + " = []: a parameter needs at least one value");
    for (std::size_t i = 0; i < spec.size(); ++i) {
      out.push_back(toml_text(spec[i], where + "[" + std::to_string(i + 1) + "]"));
    }
    return out;
  }
  if (!spec.is_object()) {
    throw SweepError(where + " = " + spec.dump() +
                     ": a parameter is a list of values or a table with one of values, "
                     "linspace, logspace, random");
  }
  std::vector<std::string> forms;
  for (const auto& f : kForms) {
    if (spec.contains(f)) forms.push_back(f);
  }
  if (forms.empty()) {
    throw SweepError(where + " = " + spec.dump() +
                     ": a parameter table needs one of values, linspace, logspace, random");
  }
  if (forms.size() > 1) {
    throw SweepError(where + ": give one of values, linspace, logspace, random, not both " +
                     forms[0] + " and " + forms[1]);
  }
  const std::string form = forms[0];
  if (form == "random") {
    generated(random_draws(spec, where));
    return out;
  }
  for (const auto& [k, v] : spec.items()) {
    if (k != form) {
      throw SweepError(
          where + "." + k + ": unknown key beside " + form +
          (form == "values" ? std::string() : " (write " + form + " = [start, stop, count])"));
    }
  }
  if (form == "values") return parameter_values(path, spec["values"], where + ".values");
  const Json& range = spec[form];
  const std::string at = where + "." + form;
  if (!range.is_array() || range.size() != 3) {
    throw SweepError(at + " = " + range.dump() + " must be [start, stop, count]");
  }
  const double a = number_of(range[0], at + "[1]"), b = number_of(range[1], at + "[2]");
  const long long n = count_of(range[2], at + "[3]");
  if (form == "logspace" && !(a > 0.0 && b > 0.0)) {
    throw SweepError(at + " = " + range.dump() +
                     ": logspace spaces values evenly in log between start and stop, both must be "
                     "> 0");
  }
  std::vector<double> numbers;
  for (long long i = 0; i < n; ++i) {
    const double s = n == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(n - 1);
    // The end points exactly as written (no a + (b − a)·1 round-off at the last one).
    double x = form == "linspace" ? a + (b - a) * s
                                  : std::exp(std::log(a) + (std::log(b) - std::log(a)) * s);
    if (i == 0) x = a;
    if (i == n - 1 && n > 1) x = b;
    numbers.push_back(x);
  }
  generated(numbers);
  return out;
}

// Flattens {"model": {"alpha": [..]}} and {"model.alpha": [..]} alike into ("model.alpha", [..]).
void flatten(const std::string& prefix, const Json& object,
             std::vector<std::pair<std::string, Json>>& out) {
  for (const auto& [k, v] : object.items()) {
    const std::string path = prefix.empty() ? k : prefix + "." + k;
    if (v.is_object() && !is_form(v)) {
      flatten(path, v, out);
    } else {
      out.emplace_back(path, v);
    }
  }
}

std::uint64_t fnv1a(std::uint64_t hash, std::string_view text) {
  for (const char c : text) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 1099511628211ull;
  }
  return hash;
}

// One CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180).
void append_csv_field(std::string& line, const std::string& field) {
  if (field.find_first_of(",\"\n\r") == std::string::npos) {
    line += field;
    return;
  }
  line += '"';
  for (const char c : field) {
    if (c == '"') line += '"';
    line += (c == '\n' || c == '\r') ? ' ' : c;
  }
  line += '"';
}

// A parameter value as the table shows it: a string without its quotes, anything else as TOML.
std::string display_value(const std::string& toml_value) {
  if (toml_value.size() >= 2 && toml_value.front() == '"') {
    return Json::parse(toml_value).get<std::string>();  // TOML basic strings are JSON strings here
  }
  return toml_value;
}

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

SweepSpec make_sweep(const Json& document, const std::string& source,
                     const std::filesystem::path& directory) {
  if (!document.is_object()) throw SweepError(source + ": a sweep must be a table");
  SweepSpec s;
  s.source = source;
  for (const auto& [k, v] : document.items()) {
    if (k != "base" && k != "problem" && k != "sweep") {
      throw SweepError(source + ": " + k + ": unknown key" +
                       did_you_mean(k, {"base", "problem", "sweep"}) +
                       "; a sweep file has base (a problem file) or [problem] (inline), and "
                       "[sweep]");
    }
  }
  if (document.contains("base") == document.contains("problem")) {
    throw SweepError(source +
                     ": give the base problem once: base = \"problem.toml\" or an "
                     "inline [problem] table");
  }
  if (document.contains("base")) {
    if (!document["base"].is_string()) throw SweepError(source + ": base must be a file name");
    std::filesystem::path base = document["base"].get<std::string>();
    if (base.is_relative()) base = directory / base;
    s.base_source = base.string();
    try {
      s.base = to_json_table(parse_toml_file(base, "base problem"));
    } catch (const SweepError& e) {
      throw SweepError(source + ": base = \"" + document["base"].get<std::string>() +
                       "\": " + e.what());
    }
  } else {
    if (!document["problem"].is_object()) throw SweepError(source + ": [problem] must be a table");
    s.base = document["problem"];
    s.base_source = source + " [problem]";
  }
  if (!document.contains("sweep") || !document["sweep"].is_object()) {
    throw SweepError(source + ": [sweep] with its parameters is missing");
  }
  const Json& sweep = document["sweep"];
  for (const auto& [k, v] : sweep.items()) {
    if (k == "combine") {
      const std::string c = v.is_string() ? v.get<std::string>() : v.dump();
      if (c != "grid" && c != "zip") {
        throw SweepError(source + ": sweep.combine = \"" + c + "\" is not one of grid, zip" +
                         did_you_mean(c, {"grid", "zip"}));
      }
      s.combine = c == "grid" ? SweepCombine::kGrid : SweepCombine::kZip;
    } else if (k == "save") {
      const std::string c = v.is_string() ? v.get<std::string>() : v.dump();
      if (c == "summary") {
        s.save = SweepSave::kSummary;
      } else if (c == "final") {
        s.save = SweepSave::kFinal;
      } else if (c == "trajectory") {
        s.save = SweepSave::kTrajectory;
      } else {
        throw SweepError(source + ": sweep.save = \"" + c +
                         "\" is not one of summary, final, trajectory" +
                         did_you_mean(c, {"summary", "final", "trajectory"}));
      }
    } else if (k != "parameters") {
      throw SweepError(source + ": sweep." + k + ": unknown key" +
                       did_you_mean(k, {"combine", "save", "parameters"}) +
                       "; valid in [sweep]: combine, save, parameters");
    }
  }
  if (!sweep.contains("parameters")) {
    throw SweepError(source +
                     ": [sweep.parameters] is missing: name at least one field to sweep, "
                     "e.g. model.alpha = [0.3, 0.5]");
  }
  // [path, values] pairs (their order is the grid's); an object is taken in key order.
  std::vector<std::pair<std::string, Json>> pairs;
  const Json& given = sweep["parameters"];
  if (given.is_object()) {
    flatten("", given, pairs);
  } else if (given.is_array()) {
    for (const auto& p : given) {
      if (!p.is_array() || p.size() != 2 || !p[0].is_string()) {
        throw SweepError(source + ": sweep.parameters must be pairs [path, values]");
      }
      pairs.emplace_back(p[0].get<std::string>(), p[1]);
    }
  } else {
    throw SweepError(source + ": sweep.parameters must be a table");
  }
  if (pairs.empty()) throw SweepError(source + ": [sweep.parameters] names no parameter");
  const auto too_many = [&source] {
    return SweepError(source + ": the parameters combine into more than " +
                      std::to_string(kMaxCases) + " cases, the limit of a sweep (split it)");
  };
  // A grid past the limit is refused before any values are made (three parameters of 10^7
  // values took 2 GB and 6 s to be refused at the end): the counts the forms declare.
  std::size_t grid_size = 1;
  for (const auto& [path, spec] : pairs) {
    if (s.combine != SweepCombine::kGrid) break;
    std::size_t n = 0;
    if (spec.is_array()) {
      n = spec.size();
    } else if (spec.is_object()) {
      for (const char* form : {"linspace", "logspace"}) {
        if (spec.contains(form) && spec[form].is_array() && spec[form].size() == 3 &&
            spec[form][2].is_number_integer() && spec[form][2].get<long long>() > 0) {
          n = spec[form][2].get<std::size_t>();
        }
      }
      if (spec.contains("count") && spec["count"].is_number_integer() &&
          spec["count"].get<long long>() > 0) {
        n = spec["count"].get<std::size_t>();
      }
      if (spec.contains("values") && spec["values"].is_array()) n = spec["values"].size();
    }
    grid_size = n == 0 ? grid_size : grid_size > kMaxCases / n ? kMaxCases + 1 : grid_size * n;
    if (grid_size > kMaxCases) throw too_many();
  }
  for (const auto& [path, spec] : pairs) {
    const std::string where = source + ": sweep.parameters." + path;
    if (const std::string unknown = unknown_field_message(path); !unknown.empty()) {
      throw SweepError(source + ": sweep.parameters." + unknown);
    }
    for (const auto& p : s.parameters) {
      if (p.path == path) throw SweepError(where + " is given twice");
    }
    s.parameters.push_back({path, parameter_values(path, spec, where)});
    if (path == "method.threads") s.threads_given = true;
  }
  // A swept alternative spelling replaces the base problem's other one (the reader refuses both):
  // sweeping model.damping_order over a base with model.alpha sweeps the damping order.
  for (const auto& [spelling, other] :
       {std::pair{"model.damping_order", "model.alpha"},
        std::pair{"model.alpha", "model.damping_order"}, std::pair{"time.step", "time.steps"},
        std::pair{"time.steps", "time.step"}}) {
    const std::string_view name = spelling;  // structured bindings cannot be captured (clang 14)
    const bool swept = std::any_of(s.parameters.begin(), s.parameters.end(),
                                   [&](const SweepParameter& p) { return p.path == name; });
    const std::string section = std::string(other).substr(0, std::string(other).find('.'));
    const std::string key = std::string(other).substr(section.size() + 1);
    if (swept && s.base.contains(section) && s.base[section].is_object()) {
      s.base[section].erase(key);
    }
  }
  // method.threads = 0 is the default ("all cores"), also what a resolved problem (Python's
  // Problem.to_dict) writes: not a choice of the user's.
  if (s.base.contains("method") && s.base["method"].is_object() &&
      s.base["method"].contains("threads") && s.base["method"]["threads"] != 0) {
    s.threads_given = true;
  }

  // The cases: a grid (the first parameter varies slowest, as nested loops in the given order)
  // or the parameters zipped (all of one length).
  std::size_t total = 1;
  if (s.combine == SweepCombine::kZip) {
    total = s.parameters[0].values.size();
    for (const auto& p : s.parameters) {
      if (p.values.size() != total) {
        throw SweepError(source + ": combine = \"zip\" needs parameters of one length: " +
                         s.parameters[0].path + " has " + std::to_string(total) + " values, " +
                         p.path + " " + std::to_string(p.values.size()));
      }
    }
  } else {
    for (const auto& p : s.parameters) {
      // Saturated at the limit: three parameters of 10^7 values must not wrap around.
      total = total > (kMaxCases + 1) / p.values.size() ? kMaxCases + 1 : total * p.values.size();
    }
  }
  if (total > kMaxCases) {
    throw too_many();
  }
  s.fingerprint = fnv1a(14695981039346656037ull, s.base.dump());
  for (std::size_t i = 0; i < total; ++i) {
    SweepCase c;
    c.index = i;
    std::size_t rest = i;
    for (std::size_t j = s.parameters.size(); j-- > 0;) {
      const auto& values = s.parameters[j].values;
      const std::size_t pick = s.combine == SweepCombine::kZip ? i : rest % values.size();
      if (s.combine == SweepCombine::kGrid) rest /= values.size();
      c.values.insert(c.values.begin(), values[pick]);
    }
    for (const auto& v : c.values) s.fingerprint = fnv1a(s.fingerprint, v + '\n');
    // Up front: the reader's and prepare_run's checks, the same a `fracvi run` makes before
    // step 1. The message names the case by its parameters.
    try {
      const ProblemSpec spec =
          parse_problem_json(s.base, s.base_source + case_label(s, c), case_overrides(s, c));
      c.dim = spec.dim;
      prepare_run(spec);
    } catch (const ProblemFileError& e) {
      c.invalid = e.what();
      c.dim = 0;
    }
    s.cases.push_back(std::move(c));
  }
  return s;
}

SweepSpec load_sweep(const std::filesystem::path& file) {
  const toml::table root = parse_toml_file(file, "sweep file");
  Json document = to_json_table(root);
  // The parameters in the order they are written (toml++ tables iterate in key order).
  if (const auto* parameters = root.at_path("sweep.parameters").as_table()) {
    struct Entry {
      toml::source_position at;
      std::string path;
      Json value;
    };
    std::vector<Entry> entries;
    const std::function<void(const std::string&, const toml::table&)> walk =
        [&](const std::string& prefix, const toml::table& t) {
          for (const auto& [k, v] : t) {
            const std::string path =
                prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
            const Json value = to_json_value(v);
            if (v.is_table() && !is_form(value)) {
              walk(path, *v.as_table());
            } else {
              entries.push_back({k.source().begin, path, value});
            }
          }
        };
    walk("", *parameters);
    std::stable_sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
      return a.at.line != b.at.line ? a.at.line < b.at.line : a.at.column < b.at.column;
    });
    Json pairs = Json::array();
    for (const auto& e : entries) pairs.push_back(Json::array({e.path, e.value}));
    document["sweep"]["parameters"] = pairs;
  }
  return make_sweep(document, file.string(), file.parent_path());
}

std::vector<std::string> case_overrides(const SweepSpec& sweep, const SweepCase& c) {
  std::vector<std::string> out;
  for (std::size_t j = 0; j < sweep.parameters.size(); ++j) {
    out.push_back(sweep.parameters[j].path + "=" + c.values[j]);
  }
  return out;
}

std::string case_label(const SweepSpec& sweep, const SweepCase& c) {
  std::string s = " (case " + std::to_string(c.index) + ":";
  for (std::size_t j = 0; j < sweep.parameters.size(); ++j) {
    s += (j ? ", " : " ") + sweep.parameters[j].path + "=" + c.values[j];
  }
  return s + ")";
}

namespace {

Eigen::Index max_dim(const SweepSpec& sweep) {
  Eigen::Index d = 0;
  for (const auto& c : sweep.cases) d = std::max(d, c.dim);
  return d;
}

}  // namespace

std::vector<std::string> sweep_columns(const SweepSpec& sweep) {
  std::vector<std::string> columns{"case"};
  for (const auto& p : sweep.parameters) columns.push_back(p.path);
  for (const char* c : {"status", "message", "steps_done", "final_time"}) columns.emplace_back(c);
  if (sweep.save != SweepSave::kSummary) {
    const Eigen::Index d = max_dim(sweep);
    for (Eigen::Index i = 1; i <= d; ++i) columns.push_back("x" + std::to_string(i));
    for (Eigen::Index i = 1; i <= d; ++i) columns.push_back("v" + std::to_string(i));
  }
  for (const char* c : {"energy_initial", "energy_final", "dissipated", "max_balance_error",
                        "mirror_error", "error_estimate", "error_order", "newton_iterations",
                        "max_newton_iterations_per_step", "wall_seconds"}) {
    columns.emplace_back(c);
  }
  return columns;
}

std::string run_sweep_case(const SweepSpec& sweep, const SweepCase& c,
                           const SweepCaseOptions& options) {
  const auto started = now_seconds();
  Solution solution;
  std::string status, message;
  if (!c.invalid.empty()) {
    status = "invalid";
    message = c.invalid;
  } else {
    try {
      ProblemSpec spec = parse_problem_json(sweep.base, sweep.base_source + case_label(sweep, c),
                                            case_overrides(sweep, c));
      if (options.single_thread && !sweep.threads_given) spec.threads = 1;
      const PreparedRun prepared = prepare_run(std::move(spec));
      solution = solve_prepared(prepared);
      status = solution.ok() ? "success" : std::string(to_string(solution.status));
      message = solution.message;
      if (sweep.save == SweepSave::kTrajectory && !options.out.empty()) {
        write_run_output(options.out / "cases" / std::to_string(c.index), prepared.spec, solution);
      }
    } catch (const std::exception& e) {
      status = "error";
      message = e.what();
    }
  }
  const double wall = now_seconds() - started;

  std::string line;
  line += std::to_string(c.index);
  for (const auto& v : c.values) line += ',', append_csv_field(line, display_value(v));
  line += ',', append_csv_field(line, status);
  line += ',', append_csv_field(line, message);
  const Eigen::Index rows = solution.t.size();
  const Eigen::Index last = rows - 1;
  const auto number = [&line](double v) { line += ',', append_csv_number(line, v); };
  const auto empty = [&line] { line += ','; };
  const auto at_end = [&](const Eigen::VectorXd& v) {
    if (rows > 0) {
      number(v[last]);
    } else {
      empty();
    }
  };
  line += ',' + std::to_string(solution.steps_done);
  at_end(solution.t);
  if (sweep.save != SweepSave::kSummary) {
    const Eigen::Index d = max_dim(sweep);
    for (const RowMatrixXd* m : {&solution.x, &solution.v}) {
      for (Eigen::Index i = 0; i < d; ++i) {
        if (rows > 0 && i < m->cols()) {
          number((*m)(last, i));
        } else {
          empty();  // no state (invalid, error) or a smaller model.dim than another case's
        }
      }
    }
  }
  if (rows > 0) {
    number(solution.energy[0]);
  } else {
    empty();
  }
  at_end(solution.energy);
  at_end(solution.dissipated);
  if (rows > 0) {
    number(solution.max_balance_error);
    number(solution.mirror_error);
    number(solution.error_estimate.value);
    number(solution.error_estimate.order);
  } else {
    for (int i = 0; i < 4; ++i) empty();
  }
  line += ',' + std::to_string(solution.newton_iterations);
  line += ',' + std::to_string(solution.max_newton_iterations_per_step);
  number(wall);
  return line + '\n';
}

std::size_t run_sweep_local(const SweepSpec& sweep, const std::vector<std::size_t>& cases, int jobs,
                            const SweepCaseOptions& options,
                            const std::function<void(std::size_t, const std::string&)>& on_row,
                            const std::atomic<bool>* stop) {
  std::atomic<std::size_t> next{0}, ran{0};
  std::mutex mutex;
  std::exception_ptr failure;
  const auto worker = [&] {
    for (;;) {
      if (stop && stop->load()) return;
      const std::size_t k = next++;
      if (k >= cases.size()) return;
      const std::string row = run_sweep_case(sweep, sweep.cases[cases[k]], options);
      const std::lock_guard<std::mutex> lock(mutex);
      ++ran;
      try {
        on_row(cases[k], row);
      } catch (...) {  // the table could not be written: stop everyone, report once
        if (!failure) failure = std::current_exception();
        next = cases.size();
      }
    }
  };
  const auto n = static_cast<std::size_t>(std::max(jobs, 1));
  std::vector<std::thread> threads;
  for (std::size_t i = 1; i < std::min(n, cases.size()); ++i) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  return ran;
}

std::vector<std::string> split_csv_line(std::string_view line) {
  std::vector<std::string> fields(1);
  bool in_quotes = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (in_quotes) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        in_quotes = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      in_quotes = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

SweepTable::SweepTable(const std::filesystem::path& dir, const SweepSpec& sweep, bool resume)
    : dir_(dir) {
  const std::vector<std::string> columns = sweep_columns(sweep);
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (i) header_ += ',';
    append_csv_field(header_, columns[i]);
  }
  header_ += '\n';
  char fingerprint[20];
  std::snprintf(fingerprint, sizeof fingerprint, "%016llx",
                static_cast<unsigned long long>(sweep.fingerprint));
  const auto results = dir_ / "results.csv";
  const auto manifest = dir_ / "sweep.json";
  prepare_output_directory(dir_);
  lock_.emplace(dir_);  // before reading the table: nobody else appends to it meanwhile
  if (std::filesystem::exists(results)) {
    if (!resume) {
      throw SweepError(dir_.string() +
                       ": holds the results.csv of a sweep; continue it with --resume, or choose "
                       "another --out (nothing is overwritten)");
    }
    std::ifstream in(manifest);
    Json m;
    try {
      m = Json::parse(in);
    } catch (const Json::exception&) {
      throw SweepError(manifest.string() + ": missing or unreadable; --resume needs it");
    }
    if (m.value("fingerprint", std::string()) != fingerprint) {
      throw SweepError(dir_.string() +
                       ": its results.csv is from a different sweep (another base problem or other "
                       "parameters); --resume continues the same sweep only");
    }
    // Same cases but other columns (sweep.save changed): the rows there would not fit the table.
    if (m.value("columns", Json::array()) != Json(columns)) {
      throw SweepError(dir_.string() +
                       ": its results.csv has other columns (was sweep.save changed?); --resume "
                       "continues the same sweep only");
    }
    std::ifstream rows(results);
    std::string line;
    bool first = true;
    while (std::getline(rows, line)) {
      if (first) {
        first = false;
        continue;
      }
      // A row counts when it is whole: the right number of fields and a case of this sweep.
      const auto fields = split_csv_line(line);
      if (fields.size() != columns.size() || rows.eof()) continue;  // torn (no newline) or foreign
      char* end = nullptr;
      const unsigned long long index = std::strtoull(fields[0].c_str(), &end, 10);
      if (end == fields[0].c_str() || *end != '\0' || index >= sweep.cases.size()) continue;
      if (!done_.insert(index).second) continue;
      rows_.emplace_back(index, line + '\n');
    }
  }
  write_file_atomically(manifest, Json{{"fingerprint", fingerprint},
                                       {"source", sweep.source},
                                       {"base", sweep.base_source},
                                       {"cases", sweep.cases.size()},
                                       {"columns", columns}}
                                          .dump(1) +
                                      "\n");
  // The table as it stands (header and whole rows), then rows are appended to it.
  std::string text = header_;
  for (const auto& r : rows_) text += r.second;
  write_file_atomically(results, text);
  fd_ = ::open(results.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd_ < 0) throw OutputError(results.string() + ": " + std::strerror(errno));
  last_sync_ = now_seconds();
}

SweepTable::~SweepTable() {
  if (fd_ >= 0) ::close(fd_);
}

void SweepTable::append(std::size_t index, const std::string& row) {
  const std::lock_guard<std::mutex> lock(mutex_);
  // One write(2) on an O_APPEND descriptor: the row lands whole or (a crash of the machine, not of
  // the process) torn at the end, where the resume drops it.
  std::size_t written = 0;
  while (written < row.size()) {
    const ssize_t n = ::write(fd_, row.data() + written, row.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw OutputError(file().string() + ": " + std::strerror(errno));
    written += static_cast<std::size_t>(n);
  }
  // To the disk at most once a second: a sweep of thousands of millisecond cases must not wait
  // for the disk after each one; a killed process loses nothing either way (the kernel has it).
  if (const double now = now_seconds(); now - last_sync_ > 1.0) {
    ::fdatasync(fd_);
    last_sync_ = now;
  }
  done_.insert(index);
  rows_.emplace_back(index, row);
}

void SweepTable::finish() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::sort(rows_.begin(), rows_.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::string text = header_;
  for (const auto& r : rows_) text += r.second;
  write_file_atomically(file(), text);
  ::close(fd_);
  fd_ = ::open(file().c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
}

}  // namespace fracvi
