// What a run leaves behind, read back (fracvi/io/output.hpp): read_summary is the inverse of
// make_summary for the solution's own fields, stored_steps gives the rows the Integrator stores.
// Python's fracvi.load end to end is python/tests/test_save_load.py.
#include "fracvi/io/output.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "fracvi/analysis/error_estimate.hpp"
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
  EXPECT_EQ(a.save_every, b.save_every);
  EXPECT_EQ(a.linear_solver, b.linear_solver);
  EXPECT_EQ(a.history, b.history);
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
    const Solution s = run_of(extra);
    // Through the text of summary.json, as fracvi.load reads it.
    const auto text = make_summary(spec, s).dump(2);
    Solution back;
    read_summary(nlohmann::json::parse(text), back, "summary.json");
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
  j["error_estimate_details"].erase("note");
  EXPECT_THROW(read_summary(j, s, "s"), OutputError);
  EXPECT_EQ(parse_status("unstable"), Status::kUnstable);
  EXPECT_EQ(parse_status("fine"), std::nullopt);
}

}  // namespace
}  // namespace fracvi
