// What a run leaves behind, read back (fracvi/io/output.hpp): read_summary is the inverse of
// make_summary for the solution's own fields, stored_steps gives the rows the Integrator stores,
// the .npy files of trajectory.npz have NEP 1's layout. Python's fracvi.load end to end, and
// NumPy reading the CLI's trajectory.npz, is python/tests/test_save_load.py.
#include "fracvi/io/output.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "fracvi/analysis/error_estimate.hpp"
#include "fracvi/io/npz.hpp"
#include "fracvi/io/run.hpp"

namespace fracvi {
namespace {

Solution run_of(const std::string& override_text = "time.steps=300") {
  const std::vector<std::string> overrides{"time.end=3.0", "time.steps=300", override_text};
  const PreparedRun r = prepare_run(parse_problem(default_problem_toml(), "<test>", overrides));
  if (r.options.tolerance > 0.0) return integrate_to_tolerance(r.problem, r.method, r.options);
  Solution s = integrate(r.problem, r.method, r.options);
  estimate_error(r.problem, r.method, r.options, s);
  return s;
}

void expect_same_fields(const Solution& a, const Solution& b) {
  const auto same = [](double x, double y) { return x == y || (std::isnan(x) && std::isnan(y)); };
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.message, b.message);
  EXPECT_EQ(a.steps_done, b.steps_done);
  EXPECT_EQ(a.newton_iterations, b.newton_iterations);
  EXPECT_EQ(a.max_newton_iterations_per_step, b.max_newton_iterations_per_step);
  EXPECT_EQ(a.jacobian_factorizations, b.jacobian_factorizations);
  EXPECT_EQ(a.save_every, b.save_every);
  EXPECT_EQ(a.linear_solver, b.linear_solver);
  EXPECT_EQ(a.history, b.history);
  EXPECT_EQ(a.history_threads.team, b.history_threads.team);
  EXPECT_EQ(a.history_threads.measured, b.history_threads.measured);
  EXPECT_EQ(a.history_threads.pushes, b.history_threads.pushes);
  EXPECT_EQ(a.history_threads.team_pushes, b.history_threads.team_pushes);
  EXPECT_EQ(a.history_threads.decisions, b.history_threads.decisions);
  EXPECT_EQ(a.history_threads.team_won, b.history_threads.team_won);
  EXPECT_EQ(a.history_threads.team_dropped, b.history_threads.team_dropped);
  EXPECT_EQ(a.method, b.method);
  EXPECT_EQ(a.declared_order, b.declared_order);
  EXPECT_TRUE(same(a.mirror_error, b.mirror_error));
  EXPECT_TRUE(same(a.max_balance_error, b.max_balance_error));
  EXPECT_EQ(a.wall_time_seconds, b.wall_time_seconds);
  EXPECT_TRUE(same(a.error_estimate.value, b.error_estimate.value));
  EXPECT_TRUE(same(a.error_estimate.order, b.error_estimate.order));
  EXPECT_TRUE(same(a.error_estimate.observed_order, b.error_estimate.observed_order));
  EXPECT_EQ(a.error_estimate.nodes, b.error_estimate.nodes);
  EXPECT_EQ(a.error_estimate.method, b.error_estimate.method);
  EXPECT_EQ(a.error_estimate.note, b.error_estimate.note);
  EXPECT_EQ(a.error_estimate.wall_seconds, b.error_estimate.wall_seconds);
  ASSERT_EQ(a.tolerance_runs.size(), b.tolerance_runs.size());
  for (std::size_t i = 0; i < a.tolerance_runs.size(); ++i) {
    EXPECT_EQ(a.tolerance_runs[i].steps, b.tolerance_runs[i].steps);
    EXPECT_TRUE(same(a.tolerance_runs[i].error_estimate, b.tolerance_runs[i].error_estimate));
    EXPECT_EQ(a.tolerance_runs[i].status, b.tolerance_runs[i].status);
  }
}

TEST(Output, ReadSummaryIsTheInverseOfMakeSummary) {
  const ProblemSpec spec = parse_problem(default_problem_toml(), "<test>");
  for (const char* extra :
       {"time.steps=300", "method.newton_max_iterations=1", "method.tolerance=1e-5"}) {
    Solution s = run_of(extra);
    // Through the text of summary.json, as fracvi.load reads it.
    const auto text = make_summary(spec, s).dump(2);
    Solution back;
    read_summary(nlohmann::json::parse(text), back, "summary.json");
    expect_same_fields(back, s);
    // The thread use of a large run's fast history (this small run's is one thread throughout).
    EXPECT_EQ(s.history_threads.team, 1);
    s.history_threads = {2, true, 600, 569, 3, 2, 1};
    read_summary(make_summary(spec, s), back, "summary.json");
    expect_same_fields(back, s);
    EXPECT_EQ(stored_steps(back.steps_done, back.save_every), s.step) << extra;
    EXPECT_EQ(s.tolerance_runs.empty(), std::string(extra) != "method.tolerance=1e-5");
  }
}

TEST(Output, StoredStepsAreTheIntegratorsRows) {
  EXPECT_EQ(stored_steps(0, 1), (std::vector<std::size_t>{0}));
  EXPECT_EQ(stored_steps(7, 3), (std::vector<std::size_t>{0, 3, 6, 7}));
  EXPECT_EQ(stored_steps(9, 3), (std::vector<std::size_t>{0, 3, 6, 9}));
  EXPECT_EQ(stored_steps(2, 5), (std::vector<std::size_t>{0, 2}));
}

TEST(Output, ReadSummaryNamesTheField) {
  const ProblemSpec spec = parse_problem(default_problem_toml(), "<test>");
  nlohmann::json j = make_summary(spec, run_of());
  Solution s;
  j["steps"] = -3;
  EXPECT_THROW(
      {
        try {
          read_summary(j, s, "dir/summary.json");
        } catch (const OutputError& e) {
          EXPECT_STREQ(e.what(),
                       "dir/summary.json: \"steps\" = -3 is not a count (an integer >= 0)");
          throw;
        }
      },
      OutputError);
  j["steps"] = 3;
  j["history_threads"]["team"] = 0;
  EXPECT_THROW(
      {
        try {
          read_summary(j, s, "dir/summary.json");
        } catch (const OutputError& e) {
          EXPECT_STREQ(e.what(), "dir/summary.json: \"team\" = 0 is not in [1, 4096]");
          throw;
        }
      },
      OutputError);
  j["history_threads"]["team"] = 1;
  j["history_threads"]["measured"] = 1;
  EXPECT_THROW(read_summary(j, s, "s"), OutputError) << "measured is true/false";
  j["history_threads"]["measured"] = false;
  j["error_estimate_details"].erase("note");
  EXPECT_THROW(read_summary(j, s, "s"), OutputError);
  EXPECT_EQ(parse_status("unstable"), Status::kUnstable);
  EXPECT_EQ(parse_status("fine"), std::nullopt);
}

TEST(Npz, NpyFilesHaveTheLayoutOfNep1) {
  const double matrix[6] = {1.0, -2.5, 3.0, 0.0, -0.0, 1e300};
  const std::int64_t steps[3] = {0, 7, 1LL << 40};
  struct Case {
    NpyArray array;
    std::string header;
    std::size_t bytes;
  };
  const std::vector<Case> cases{
      {{"x", {3, 2}, matrix}, "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 2), }", 48},
      {{"t", {6}, matrix}, "{'descr': '<f8', 'fortran_order': False, 'shape': (6,), }", 48},
      {{"step", {3}, nullptr, steps},
       "{'descr': '<i8', 'fortran_order': False, 'shape': (3,), }",
       24},
      {{"empty", {0, 4}, matrix}, "{'descr': '<f8', 'fortran_order': False, 'shape': (0, 4), }", 0},
  };
  for (const Case& c : cases) {
    const std::string file = npy_file(c.array);
    ASSERT_EQ(file.substr(0, 8), std::string("\x93NUMPY\x01\x00", 8));
    const std::size_t length =
        static_cast<unsigned char>(file[8]) + 256U * static_cast<unsigned char>(file[9]);
    ASSERT_EQ((10 + length) % 64, 0U) << c.header;  // the data 64-byte aligned
    const std::string header = file.substr(10, length);
    EXPECT_EQ(header.substr(0, c.header.size()), c.header);
    EXPECT_EQ(header.back(), '\n');
    EXPECT_EQ(header.find_first_not_of(' ', c.header.size()), length - 1);  // spaces, then '\n'
    ASSERT_EQ(file.size(), 10 + length + c.bytes);
    const void* data = c.array.doubles ? static_cast<const void*>(c.array.doubles)
                                       : static_cast<const void*>(c.array.integers);
    EXPECT_EQ(std::memcmp(file.data() + 10 + length, data, c.bytes), 0);
  }
}

TEST(Npz, AnUnwritableFileIsAnOutputErrorAndLeavesNothing) {
  const double t[2] = {0.0, 1.0};
  const std::vector<NpyArray> arrays{{"t", {2}, t}};
  const auto dir =
      std::filesystem::temp_directory_path() / ("fracvi-npz-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  EXPECT_THROW(write_npz(dir / "missing" / "trajectory.npz", arrays), OutputError);
  std::filesystem::create_directories(dir);
  write_npz(dir / "trajectory.npz", arrays);
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1U);  // no temporary left
  std::ifstream in(dir / "trajectory.npz", std::ios::binary);
  std::string zip((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(zip.substr(0, 4), std::string("PK\x03\x04", 4));  // a ZIP local file header
  EXPECT_NE(zip.find("t.npy"), std::string::npos);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fracvi
