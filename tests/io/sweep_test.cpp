// Sweep documents (fracvi/io/sweep.hpp): how parameters expand into cases, and what is refused.
// The command line end to end is tests/cli/sweep_test.py.
#include "fracvi/io/sweep.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace fracvi {
namespace {

using Json = nlohmann::json;

Json base() {
  return Json::parse(R"({"name": "osc", "model": {"dim": 1, "mass": 1.0, "damping": 0.5,
      "alpha": 0.5, "convention": "caputo", "potential": "x1^2/2"}, "initial": {"position": [1.0]},
      "time": {"end": 10.0, "steps": 200}})");
}

SweepSpec sweep_of(const Json& parameters, const std::string& combine = "grid") {
  return make_sweep(
      Json{{"problem", base()}, {"sweep", {{"combine", combine}, {"parameters", parameters}}}},
      "<test>", ".");
}

TEST(Sweep, GridFirstParameterVariesSlowest) {
  const SweepSpec s = sweep_of(Json::parse(R"([["model.alpha", [0.25, 0.5]],
                                               ["model.damping", [1, 2.5, 3.0]]])"));
  ASSERT_EQ(s.cases.size(), 6u);
  EXPECT_EQ(s.cases[0].values, (std::vector<std::string>{"0.25", "1"}));
  EXPECT_EQ(s.cases[2].values, (std::vector<std::string>{"0.25", "3.0"}));
  EXPECT_EQ(s.cases[3].values, (std::vector<std::string>{"0.5", "1"}));
  EXPECT_EQ(case_overrides(s, s.cases[4]),
            (std::vector<std::string>{"model.alpha=0.5", "model.damping=2.5"}));
  for (const auto& c : s.cases) EXPECT_EQ(c.invalid, "") << c.index;
}

TEST(Sweep, ZipPairsTheValues) {
  const SweepSpec s = sweep_of(Json::parse(R"([["model.alpha", [0.25, 0.5]],
                                               ["method.scheme", ["fvi-gl", "fvi-midpoint"]]])"),
                               "zip");
  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[1].values, (std::vector<std::string>{"0.5", "\"fvi-midpoint\""}));
}

TEST(Sweep, RangesHitTheirEndPointsExactly) {
  const SweepSpec s = sweep_of(Json::parse(R"([["model.damping", {"logspace": [0.1, 3.0, 5]}],
                                               ["model.alpha", {"linspace": [0.1, 0.9, 5]}]])"),
                               "zip");
  // exp(log 0.1 + (log 3 − log 0.1)·1) is 2.9999999999999996: the end points are set, not
  // computed.
  EXPECT_EQ(s.parameters[0].values.front(), "0.1");
  EXPECT_EQ(s.parameters[0].values.back(), "3.0");
  // a + (b − a)·i/(n − 1) between them (NumPy's linspace gives the same doubles).
  EXPECT_EQ(s.parameters[1].values, (std::vector<std::string>{"0.1", "0.30000000000000004", "0.5",
                                                              "0.7000000000000001", "0.9"}));
}

TEST(Sweep, IntegerFieldsAreRounded) {
  const SweepSpec s = sweep_of(Json::parse(R"([["time.steps", {"logspace": [100, 10000, 5]}]])"));
  EXPECT_EQ(s.parameters[0].values,
            (std::vector<std::string>{"100", "316", "1000", "3162", "10000"}));
}

// Generated values beyond the 64-bit integers for an integer field are refused by value:
// std::llround of 1e30 is unspecified (it gave -9223372036854775808, refused as "must be
// positive").
TEST(Sweep, IntegerFieldsBeyondInt64AreRefused) {
  for (const char* range : {R"({"logspace": [100, 1e30, 3]})", R"({"linspace": [1, 1e19, 2]})",
                            R"({"linspace": [-1e300, 1, 2]})"}) {
    SCOPED_TRACE(range);
    try {
      sweep_of(Json::parse(std::string(R"([["time.steps", )") + range + "]]"));
      ADD_FAILURE() << "accepted";
    } catch (const SweepError& e) {
      EXPECT_NE(std::string(e.what()).find(" for the integer field time.steps is beyond the "
                                           "64-bit integers"),
                std::string::npos)
          << e.what();
    }
  }
  // 2^62 is still an integer (and then refused by the problem's own limit, per case).
  const SweepSpec s =
      sweep_of(Json::parse(R"([["time.steps", {"linspace": [100, 4.611686018427387904e18, 2]}]])"));
  EXPECT_EQ(s.parameters[0].values, (std::vector<std::string>{"100", "4611686018427387904"}));
}

TEST(Sweep, RandomDrawsAreFixedBySeed) {
  const Json spec = Json::parse(R"([["model.damping",
      {"random": "uniform", "low": 1.0, "high": 2.0, "count": 3, "seed": 42}]])");
  const SweepSpec a = sweep_of(spec), b = sweep_of(spec);
  EXPECT_EQ(a.parameters[0].values, b.parameters[0].values);
  for (const auto& v : a.parameters[0].values) {
    EXPECT_GE(std::stod(v), 1.0);
    EXPECT_LE(std::stod(v), 2.0);
  }
  // splitmix64 is written out in sweep.cpp: a change of generator changes every study's draws.
  // The value from an independent Python splitmix64 (Steele, Lea & Flood's constants), seed 42.
  EXPECT_EQ(a.parameters[0].values[0], "1.7415648787718234");
  Json other = spec;
  other[0][1]["seed"] = 43;
  EXPECT_NE(sweep_of(other).parameters[0].values, a.parameters[0].values);
}

TEST(Sweep, InvalidCasesAreNamedAndKept) {
  const SweepSpec s = sweep_of(Json::parse(R"([["model.alpha", [0.5, 1.5]]])"));
  ASSERT_EQ(s.cases.size(), 2u);
  EXPECT_EQ(s.cases[0].invalid, "");
  EXPECT_NE(s.cases[1].invalid.find("(case 1: model.alpha=1.5)"), std::string::npos)
      << s.cases[1].invalid;
  EXPECT_NE(s.cases[1].invalid.find("outside [0, 1]"), std::string::npos);
}

TEST(Sweep, AlternativeSpellingReplacesTheBaseOne) {
  const SweepSpec s = sweep_of(Json::parse(R"([["model.damping_order", [0.4, 1.5]]])"));
  for (const auto& c : s.cases) EXPECT_EQ(c.invalid, "") << c.invalid;
  EXPECT_FALSE(s.base["model"].contains("alpha"));
}

TEST(Sweep, FingerprintFollowsTheCases) {
  const SweepSpec a = sweep_of(Json::parse(R"([["model.alpha", [0.25, 0.5]]])"));
  const SweepSpec b = sweep_of(Json::parse(R"([["model.alpha", [0.25, 0.5]]])"));
  const SweepSpec c = sweep_of(Json::parse(R"([["model.alpha", [0.25, 0.75]]])"));
  EXPECT_EQ(a.fingerprint, b.fingerprint);
  EXPECT_NE(a.fingerprint, c.fingerprint);
}

TEST(Sweep, RefusedDocumentsNameTheKey) {
  const auto message = [](const Json& parameters, const std::string& combine = "grid") {
    try {
      sweep_of(parameters, combine);
    } catch (const SweepError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(Json::parse(R"([["model.alpah", [0.3]]])")).find("did you mean 'alpha'"),
            std::string::npos);
  EXPECT_NE(message(Json::parse(R"([["model.alpha", []]])")).find("at least one value"),
            std::string::npos);
  EXPECT_NE(message(Json::parse(R"([["model.alpha", {"linspace": [0.1, 0.9]}]])"))
                .find("[start, stop, count]"),
            std::string::npos);
  EXPECT_NE(
      message(Json::parse(R"([["model.alpha", [0.3, 0.4]], ["model.damping", [1.0]]])"), "zip")
          .find("one length"),
      std::string::npos);
  EXPECT_NE(message(Json::parse(R"([["model.alpha", {"random": "gauss", "count": 2, "seed": 1}]])"))
                .find("not one of uniform, loguniform, normal"),
            std::string::npos);
}

TEST(Sweep, TooManyCasesAreRefusedBeforeValuesAreMade) {
  // 10^21 cases: refused from the declared counts (making 10^7 values first took seconds and GB).
  const Json range = Json::parse(R"({"linspace": [0.1, 0.9, 10000000]})");
  try {
    sweep_of(
        Json::array({Json::array({"model.alpha", range}), Json::array({"model.damping", range}),
                     Json::array({"model.mass", range})}));
    FAIL() << "accepted";
  } catch (const SweepError& e) {
    EXPECT_NE(std::string(e.what()).find("more than 10000000 cases"), std::string::npos);
  }
}

TEST(Sweep, CsvLinesSplitWithQuotes) {
  EXPECT_EQ(split_csv_line(R"(1,"a, ""b""",,x)"),
            (std::vector<std::string>{"1", "a, \"b\"", "", "x"}));
}

}  // namespace
}  // namespace fracvi
