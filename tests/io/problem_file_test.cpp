// Problem files: schema, defaults, matrix forms, overrides, and every bad-input rule.
#include "fracvi/io/problem_file.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace fracvi {
namespace {

const std::string kBase = R"toml(
name = "test"
[model]
dim = 2
mass = 1.0
damping = [0.1, 0.2]
alpha = 0.5
potential = "x1^2/2 + x2^2/2"
[initial]
position = [1.0, 0.0]
[time]
end = 2.0
steps = 20
)toml";

ProblemSpec parse(const std::string& text, std::vector<std::string> overrides = {}) {
  return parse_problem(text, "p.toml", overrides);
}

// The error message of parsing `text` with `overrides`, or "" if it parsed.
std::string error_of(const std::string& text, std::vector<std::string> overrides = {}) {
  try {
    parse(text, overrides);
  } catch (const ProblemFileError& e) {
    return e.what();
  }
  return "";
}

std::string with(const std::string& from, const std::string& to) {
  std::string s = kBase;
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

TEST(ProblemFile, DefaultsAndMatrixForms) {
  const ProblemSpec p = parse(kBase);
  EXPECT_EQ(p.name, "test");
  EXPECT_EQ(p.dim, 2);
  EXPECT_EQ(p.mass, Eigen::MatrixXd::Identity(2, 2));
  EXPECT_EQ(p.damping, Eigen::Vector2d(0.1, 0.2).asDiagonal().toDenseMatrix());
  EXPECT_EQ(p.velocity, Eigen::Vector2d::Zero());
  EXPECT_EQ(p.start, 0.0);
  EXPECT_EQ(p.steps, 20);
  EXPECT_DOUBLE_EQ(p.step(), 0.1);
  EXPECT_EQ(p.scheme, "fvi-gl");
  EXPECT_EQ(p.newton_tolerance, 1e-12);
  EXPECT_EQ(p.every, 1);
  const ProblemSpec full = parse(with("mass = 1.0", "mass = [[2, 0.5], [0.5, 1]]"));
  EXPECT_EQ(full.mass(0, 1), 0.5);
  EXPECT_EQ(full.mass(0, 0), 2.0);
}

TEST(ProblemFile, BuiltInProblemIsValid) {
  const ProblemSpec p = parse_problem(default_problem_toml(), "<built-in>");
  EXPECT_EQ(p.alpha, 0.75);
  EXPECT_EQ(p.convention, "caputo");
  EXPECT_EQ(p.force.size(), 1u);
}

TEST(ProblemFile, DampingOrderIsTwiceAlpha) {
  const ProblemSpec p = parse(with("alpha = 0.5", "damping_order = 1.5\nconvention = \"caputo\""));
  EXPECT_EQ(p.alpha, 0.75);
  EXPECT_NE(error_of(with("alpha = 0.5", "alpha = 0.5\ndamping_order = 1.0")).find("both"),
            std::string::npos);
}

TEST(ProblemFile, StepMustDivideTheInterval) {
  EXPECT_EQ(parse(with("steps = 20", "step = 0.1")).steps, 20);
  EXPECT_NE(error_of(with("steps = 20", "step = 0.3")).find("time.step"), std::string::npos);
  EXPECT_NE(error_of(with("steps = 20", "steps = 20\nstep = 0.1")).find("both"), std::string::npos);
  EXPECT_NE(error_of(with("steps = 20", "")).find("time.steps"), std::string::npos);
}

TEST(ProblemFile, OverridesApplyBeforeValidation) {
  const ProblemSpec p =
      parse(kBase, {"model.alpha=0.25", "model.convention=caputo", "model.potential=x1^4 + x2^2",
                    "time.steps=40", "name=other"});
  EXPECT_EQ(p.alpha, 0.25);
  EXPECT_EQ(p.potential, "x1^4 + x2^2");  // not valid TOML: taken as a string
  EXPECT_EQ(p.steps, 40);
  EXPECT_EQ(p.name, "other");
  EXPECT_NE(error_of(kBase, {"model.alpha=3"}).find("model.alpha = 3 is outside [0, 1]"),
            std::string::npos);
  EXPECT_NE(error_of(kBase, {"alpha"}).find("section.key=value"), std::string::npos);
  EXPECT_NE(error_of(kBase, {"model.alpah=0.3"}).find("did you mean 'alpha'"), std::string::npos);
}

TEST(ProblemFile, TomlRoundTripReproducesTheSpec) {
  const ProblemSpec p = parse(with("mass = 1.0", "mass = [[2, 0.5], [0.5, 1]]"));
  const ProblemSpec q = parse_problem(to_toml(p), "round-trip");
  EXPECT_EQ(q.mass, p.mass);
  EXPECT_EQ(q.damping, p.damping);
  EXPECT_EQ(q.alpha, p.alpha);
  EXPECT_EQ(q.potential, p.potential);
  EXPECT_EQ(q.position, p.position);
  EXPECT_EQ(q.steps, p.steps);
  EXPECT_EQ(to_json(q), to_json(p));
}

struct BadCase {
  const char* what;
  std::string text;
  std::vector<std::string> needles;  // all must appear in the message
};

TEST(ProblemFile, EveryBadInputNamesTheFileTheKeyAndTheRule) {
  const std::vector<BadCase> cases{
      {"unknown key",
       with("damping =", "dampng ="),
       {"p.toml", "model.dampng", "did you mean 'damping'"}},
      {"unknown section", kBase + "[solver]\nx = 1\n", {"p.toml", "solver", "unknown"}},
      {"wrong type",
       with("alpha = 0.5", "alpha = \"half\""),
       {"model.alpha", "must be a number", "a string"}},
      {"missing field",
       with("potential = \"x1^2/2 + x2^2/2\"", ""),
       {"model.potential", "missing"}},
      {"missing dim", with("dim = 2", ""), {"model.dim", "missing"}},
      {"position size",
       with("position = [1.0, 0.0]", "position = [1.0]"),
       {"initial.position", "1 entries", "dim is 2"}},
      {"mass rows", with("mass = 1.0", "mass = [[1, 0]]"), {"model.mass", "1 rows"}},
      {"mass not SPD",
       with("mass = 1.0", "mass = [[1, 2], [2, 1]]"),
       {"model.mass", "positive definite", "-1"}},
      {"mass not symmetric",
       with("mass = 1.0", "mass = [[1, 0.1], [0, 1]]"),
       {"model.mass", "symmetric"}},
      {"damping not PSD",
       with("damping = [0.1, 0.2]", "damping = [0.1, -0.2]"),
       {"model.damping", "semidefinite"}},
      {"alpha range",
       with("alpha = 0.5", "alpha = 1.5"),
       {"model.alpha = 1.5", "[0, 1]", "2*alpha"}},
      {"steps", with("steps = 20", "steps = 0"), {"time.steps = 0", "positive"}},
      {"steps type", with("steps = 20", "steps = 2.5"), {"time.steps", "integer"}},
      {"end", with("end = 2.0", "end = -1.0"), {"time.end", "greater than time.start"}},
      {"malformed potential",
       with("x1^2/2 + x2^2/2", "x1^2/2 + x3"),
       {"model.potential", "x3", "column 10"}},
      {"syntax", with("x1^2/2 + x2^2/2", "x1^2/2 +* x2"), {"model.potential", "column"}},
      {"force size",
       with("potential =", "force = [\"sin(t)\"]\npotential ="),
       {"model.force", "1 components"}},
      {"force variable",
       with("potential =", "force = [\"x1\", \"0\"]\npotential ="),
       {"model.force[1]", "x1"}},
      {"convention",
       with("alpha = 0.5", "alpha = 0.5\nconvention = \"caputto\""),
       {"model.convention", "did you mean 'caputo'"}},
      {"fractional needs convention",
       with("alpha = 0.5", "alpha = 0.7"),
       {"model.convention", "missing"}},
      {"ill-posed RL",
       with("alpha = 0.5", "alpha = 0.75\nconvention = \"riemann-liouville\""),
       {"model.convention", "ill-posed", "caputo"}},
      {"scheme", kBase + "[method]\nscheme = \"fvi-bdf9\"\n", {"method.scheme", "fvi-gl"}},
      {"newton tolerance",
       kBase + "[method]\nnewton_tolerance = 0\n",
       {"method.newton_tolerance", "positive"}},
      {"output every", kBase + "[output]\nevery = 0\n", {"output.every", "at least 1"}},
      {"not TOML", "name = \n", {"p.toml:1", "not valid TOML"}},
  };
  for (const auto& c : cases) {
    const std::string msg = error_of(c.text);
    ASSERT_FALSE(msg.empty()) << c.what << ": parsed without error";
    EXPECT_EQ(msg.find('\n'), std::string::npos) << c.what << ": not one line: " << msg;
    for (const auto& needle : c.needles)
      EXPECT_NE(msg.find(needle), std::string::npos)
          << c.what << ": '" << needle << "' not in: " << msg;
  }
}

}  // namespace
}  // namespace fracvi

namespace fracvi {
namespace {

TEST(ProblemFile, JsonGoesThroughTheSameValidation) {
  const ProblemSpec from_toml = parse(kBase);
  const ProblemSpec from_json = parse_problem_json(to_json(from_toml), "dict");
  EXPECT_EQ(to_json(from_json), to_json(from_toml));
  nlohmann::json bad = to_json(from_toml);
  bad["model"]["dampng"] = 0.1;
  try {
    parse_problem_json(bad, "dict");
    FAIL() << "unknown key accepted";
  } catch (const ProblemFileError& e) {
    EXPECT_NE(std::string(e.what()).find("dict: model.dampng: unknown key"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace fracvi
