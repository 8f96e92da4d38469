// Problem files: schema, defaults, matrix forms, overrides, and every bad-input rule.
#include "fracvi/io/problem_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "fracvi/io/output.hpp"
#include "fracvi/io/run.hpp"

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
  EXPECT_EQ(p.mass.to_dense(), Eigen::MatrixXd::Identity(2, 2));
  EXPECT_EQ(p.damping.to_dense(), Eigen::Vector2d(0.1, 0.2).asDiagonal().toDenseMatrix());
  EXPECT_EQ(p.velocity, Eigen::Vector2d::Zero());
  EXPECT_EQ(p.start, 0.0);
  EXPECT_EQ(p.steps, 20);
  EXPECT_DOUBLE_EQ(p.step(), 0.1);
  EXPECT_EQ(p.scheme, "auto");
  EXPECT_EQ(p.newton_tolerance, 1e-12);
  EXPECT_EQ(p.every, fracvi::kAutoEvery);
  EXPECT_EQ(make_integrator_options(p).save_every, 1u);  // 20 steps: every state
  const ProblemSpec full = parse(with("mass = 1.0", "mass = [[2, 0.5], [0.5, 1]]"));
  EXPECT_EQ(full.mass(0, 1), 0.5);
  EXPECT_EQ(full.mass(0, 0), 2.0);
  EXPECT_FALSE(full.mass.is_sparse());
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
  // An override of one spelling replaces the other (it is one field), both ways.
  const std::string caputo = with("alpha = 0.5", "alpha = 0.5\nconvention = \"caputo\"");
  EXPECT_EQ(parse(caputo, {"model.damping_order=1.5"}).alpha, 0.75);
  EXPECT_EQ(parse(with("alpha = 0.5", "damping_order = 1.5\nconvention = \"caputo\""),
                  {"model.alpha=0.3"})
                .alpha,
            0.3);
  EXPECT_EQ(parse(caputo, {"model.damping_order=1.5", "model.alpha=0.2"}).alpha, 0.2);  // last wins
}

TEST(ProblemFile, StepMustDivideTheInterval) {
  EXPECT_EQ(parse(with("steps = 20", "step = 0.1")).steps, 20);
  EXPECT_NE(error_of(with("steps = 20", "step = 0.3")).find("time.step"), std::string::npos);
  EXPECT_NE(error_of(with("steps = 20", "steps = 20\nstep = 0.1")).find("both"), std::string::npos);
  EXPECT_NE(error_of(with("steps = 20", "")).find("time.steps"), std::string::npos);
}

// Integers where a number is expected are read exactly: toml++'s value<double>() is empty beyond
// ±2^53, and dereferencing it ran `damping = 100000000000000000` as R = 6.95e-310 and let
// `damping = -9007199254740993` pass the sign check. Exactly representable integers (10^17 =
// 2^17·5^17, 2^60) are converted; the others (2^53 + 1) are refused naming the key, the value and
// the rule. The same through --set (and Python's keywords, python/tests/test_problem.py).
TEST(ProblemFile, IntegersAreReadExactlyOrRefused) {
  EXPECT_EQ(parse(with("damping = [0.1, 0.2]", "damping = 100000000000000000")).damping.coeff(0, 0),
            1e17);
  EXPECT_EQ(parse(with("mass = 1.0", "mass = 1152921504606846976")).mass.coeff(1, 1),
            std::ldexp(1.0, 60));
  EXPECT_EQ(parse(kBase, {"model.damping=100000000000000000"}).damping.coeff(1, 1), 1e17);
  EXPECT_EQ(parse(kBase, {"time.end=9007199254740992"}).end, std::ldexp(1.0, 53));  // 2^53 exact
  EXPECT_EQ(parse(kBase, {"time.start=-3", "time.end=7"}).start, -3.0);
  // 2^53 + 1 and the largest int64 are not doubles.
  const std::string negative =
      error_of(with("damping = [0.1, 0.2]", "damping = -9007199254740993"));
  EXPECT_NE(negative.find("p.toml: model.damping = -9007199254740993: integers beyond 2^53 are not "
                          "exactly representable"),
            std::string::npos)
      << negative;
  EXPECT_NE(negative.find("write it as a float, e.g. -9.007199254740993e15"), std::string::npos)
      << negative;
  const std::string entry =
      error_of(with("damping = [0.1, 0.2]", "damping = [0.1, 9007199254740993]"));
  EXPECT_NE(entry.find("model.damping[2] = 9007199254740993: integers beyond 2^53"),
            std::string::npos)
      << entry;
  const std::string largest = error_of(kBase, {"time.end=9223372036854775807"});
  EXPECT_NE(largest.find("time.end = 9223372036854775807: integers beyond 2^53"), std::string::npos)
      << largest;
  // JSON (the C++ API and Python dicts): integers above INT64_MAX are refused, not wrapped.
  nlohmann::json j = to_json(parse(kBase));
  j["model"]["damping"] = std::uint64_t{18446744073709551615ULL};
  try {
    parse_problem_json(j, "dict");
    ADD_FAILURE() << "2^64 - 1 accepted";
  } catch (const ProblemFileError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "dict: model.damping = 18446744073709551615 does not fit a 64-bit integer"),
              std::string::npos)
        << e.what();
  }
  j["model"]["damping"] = std::uint64_t{100000000000000000ULL};  // unsigned but exact: 1e17
  EXPECT_EQ(parse_problem_json(j, "dict").damping.coeff(0, 0), 1e17);
  // The float form the message suggests is accepted (rounded to the nearest double).
  EXPECT_EQ(
      parse(with("damping = [0.1, 0.2]", "damping = 9.007199254740993e15")).damping.coeff(0, 0),
      9007199254740992.0);
}

// Inputs whose conversion to an integer would overflow — undefined behaviour, which the asan
// preset's -fsanitize=float-cast-overflow traps (scripts/sanitize.sh) — are refused by value before
// any conversion: step counts beyond the limit (a tiny or subnormal time.step, a span of 1e19 or
// one that overflows to inf, steps near 2^63), integer fields given as floats, and dimensions
// whose storage alone exceeds any memory.
TEST(ProblemFile, CountsThatWouldOverflowAreRefusedBeforeConversion) {
  const std::string by_step = with("steps = 20", "step = 1");
  const auto expect_refused = [](const std::string& message, const std::string& needle) {
    EXPECT_NE(message.find(needle), std::string::npos) << message;
  };
  expect_refused(error_of(with("steps = 20", "step = 1e-300")),
                 "p.toml: time.step = 1e-300 divides [0, 2] into 2e+300 steps, more than the limit "
                 "of 2000000000");
  expect_refused(error_of(with("steps = 20", "step = 5e-324")),
                 "time.step = 5e-324 divides [0, 2] into inf steps");
  expect_refused(error_of(by_step, {"time.end=1e19"}), "into 1e+19 steps, more than the limit");
  expect_refused(error_of(by_step, {"time.start=-1e308", "time.end=1e308"}),
                 "into inf steps, more than the limit");
  expect_refused(error_of(kBase, {"time.steps=9223372036854775807"}),
                 "time.steps = 9223372036854775807 is more than the limit of 2000000000");
  expect_refused(error_of(kBase, {"time.steps=-9223372036854775808"}),
                 "time.steps = -9223372036854775808 must be positive");
  for (const char* field : {"model.dim", "time.steps", "output.every", "output.checkpoint_every",
                            "method.max_steps", "method.threads"}) {
    expect_refused(error_of(kBase, {std::string(field) + "=1e19"}),
                   std::string(field) + " = 1e+19 must be an integer, got a number");
  }
  // The storage of 10^12 and 2^62 degrees of freedom is refused with the number, before any
  // vector is allocated; a span that overflows, by prepare_run (every check before step 1).
  const auto prepare_error = [](std::vector<std::string> overrides) {
    try {
      prepare_run(parse(kBase, std::move(overrides)));
    } catch (const ProblemFileError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  expect_refused(prepare_error({"model.dim=1000000000000"}),
                 "model.dim = 1000000000000: the first and last state alone (x and v) need 32 TB");
  expect_refused(prepare_error({"model.dim=4611686018427387904"}),
                 "model.dim = 4611686018427387904: the first and last state alone");
  expect_refused(prepare_error({"time.start=-1e308", "time.end=1e308"}),
                 "time.end - time.start = inf");
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
  EXPECT_EQ(q.mass.to_dense(), p.mass.to_dense());
  EXPECT_FALSE(q.mass.is_sparse());
  EXPECT_EQ(q.damping.to_dense(), p.damping.to_dense());
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
      {"Python functions in a file",
       with("potential = \"x1^2/2 + x2^2/2\"", "potential = \"python:m:U, m:dU\""),
       {"p.toml", "model.potential = \"python:m:U, m:dU\"", "names Python functions",
        "which a problem file cannot call", "fracvi.load"}},
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
      // x1…xd, v1…vd and t are the force's variables (a non-conservative force g(x, v, t)); a
      // position or velocity beyond d, or another name, is refused with the known names.
      {"force position beyond d",
       with("potential =", "force = [\"x5\", \"0\"]\npotential ="),
       {"model.force[1]", "x5", "x1, x2, v1, v2, t", "column 1"}},
      {"force unknown name",
       with("potential =", "force = [\"0\", \"-0.1*w1\"]\npotential ="),
       {"model.force[2]", "'w1'", "x1, x2, v1, v2, t", "column 6"}},
      {"force velocity beyond d",
       with("potential =", "force = [\"v3*t\", \"0\"]\npotential ="),
       {"model.force[1]", "v3"}},
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

namespace fracvi {
namespace {

// A chain of the built-in FPUT potential with formula initial data.
const std::string kChain = R"toml(
name = "chain"
[model]
dim = 5
mass = 1.0
damping = 0.1
alpha = 0.5
[model.chain]
quartic = 1.0
[initial]
position = "0.1*sin(pi*i/(d+1))"
[time]
end = 1.0
steps = 10
)toml";

std::string chain_with(const std::string& from, const std::string& to) {
  std::string s = kChain;
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

void expect_error(const std::string& text, const std::vector<std::string>& needles,
                  std::vector<std::string> overrides = {}) {
  const std::string msg = error_of(text, std::move(overrides));
  ASSERT_FALSE(msg.empty()) << "parsed without error: " << text;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  for (const auto& needle : needles)
    EXPECT_NE(msg.find(needle), std::string::npos) << "'" << needle << "' not in: " << msg;
}

TEST(ProblemFile, ScalarAndVectorMatricesAreStoredSparse) {
  const ProblemSpec p = parse(kBase);  // mass = 1.0, damping = [0.1, 0.2]
  ASSERT_TRUE(p.mass.is_sparse());
  ASSERT_TRUE(p.damping.is_sparse());
  EXPECT_EQ(p.mass.stored_entries(), 2);
  EXPECT_EQ(p.damping.coeff(1, 1), 0.2);
  EXPECT_EQ(p.damping.coeff(0, 1), 0.0);
  // No damping: a sparse zero with no entries.
  const ProblemSpec undamped = parse(with("damping = [0.1, 0.2]\n", ""));
  EXPECT_TRUE(undamped.damping.is_sparse());
  EXPECT_TRUE(undamped.damping.is_zero());
  EXPECT_EQ(undamped.damping.rows(), 2);

  // d = 10^5: a dense M would be 80 GB; the scalar and the vector stay O(d).
  std::string damping = "[";
  for (int i = 0; i < 100000; ++i) damping += i == 0 ? "0.01" : ", 0.01";
  damping += "]";
  const ProblemSpec big =
      parse(chain_with("damping = 0.1", "damping = " + damping), {"model.dim=100000"});
  EXPECT_EQ(big.dim, 100000);
  ASSERT_TRUE(big.mass.is_sparse());
  ASSERT_TRUE(big.damping.is_sparse());
  EXPECT_EQ(big.mass.stored_entries(), 100000);
  EXPECT_EQ(big.damping.coeff(99999, 99999), 0.01);
  // Written back compactly: a constant diagonal is one number, the formula stays a formula.
  const std::string toml = to_toml(big);
  EXPECT_LT(toml.size(), 2000u) << toml.substr(0, 300);
  EXPECT_NE(toml.find("mass = 1.0"), std::string::npos) << toml;
  EXPECT_NE(toml.find("damping = 0.01"), std::string::npos) << toml;
  EXPECT_NE(toml.find("position = '0.1*sin(pi*i/(d+1))'"), std::string::npos) << toml;
  EXPECT_NE(toml.find("velocity = 0.0"), std::string::npos) << toml;
}

TEST(ProblemFile, DiagonalEntriesAreCheckedOneByOne) {
  expect_error(with("mass = 1.0", "mass = -1.0"),
               {"p.toml: model.mass = -1 must be positive", "positive definite"});
  expect_error(with("mass = 1.0", "mass = [1.0, 0.0]"),
               {"model.mass[2] = 0 must be positive", "positive definite"});
  expect_error(with("damping = [0.1, 0.2]", "damping = [0.1, -0.2]"),
               {"model.damping[2] = -0.2 must not be negative", "semidefinite"});
  expect_error(with("damping = [0.1, 0.2]", "damping = -0.5"),
               {"model.damping = -0.5 must not be negative"});
  // Dense storage keeps the eigenvalue messages.
  expect_error(with("damping = [0.1, 0.2]", "damping = [[0.1, 0.3], [0.3, 0.1]]"),
               {"model.damping: is not positive semidefinite (smallest eigenvalue -0.2)"});
}

TEST(ProblemFile, ChainTableWithDefaults) {
  const ProblemSpec p = parse(kChain);
  ASSERT_TRUE(p.chain.has_value());
  EXPECT_EQ(p.chain->dimension, 5);
  EXPECT_EQ(p.chain->stiffness, 1.0);
  EXPECT_EQ(p.chain->cubic, 0.0);
  EXPECT_EQ(p.chain->quartic, 1.0);
  EXPECT_EQ(p.chain->onsite, 0.0);
  EXPECT_EQ(p.chain->boundary, ChainBoundary::kFixed);
  EXPECT_EQ(p.chain->threads, 0);
  EXPECT_FALSE(parse(kBase).chain.has_value());

  const ProblemSpec q = parse(chain_with("quartic = 1.0", R"(stiffness = 2.0
cubic = 0.5
quartic = 0.25
onsite = 0.1
boundary = "periodic")"),
                              {"method.threads=2"});
  EXPECT_EQ(q.chain->stiffness, 2.0);
  EXPECT_EQ(q.chain->cubic, 0.5);
  EXPECT_EQ(q.chain->quartic, 0.25);
  EXPECT_EQ(q.chain->onsite, 0.1);
  EXPECT_EQ(q.chain->boundary, ChainBoundary::kPeriodic);
  EXPECT_EQ(q.chain->threads, 2);
  // --set reaches into the table, and creates it.
  EXPECT_EQ(parse(kChain, {"model.chain.boundary=free"}).chain->boundary, ChainBoundary::kFree);
  const ProblemSpec set =
      parse(with("potential = \"x1^2/2 + x2^2/2\"\n", ""), {"model.chain.stiffness=3"});
  ASSERT_TRUE(set.chain.has_value());
  EXPECT_EQ(set.chain->stiffness, 3.0);

  // prepare_run builds the chain potential; the options follow [method] and [output].
  const PreparedRun run = prepare_run(parse(kChain, {"output.every=4", "method.threads=1"}));
  const auto* chain = dynamic_cast<const ChainPotential*>(run.problem.model.potential.get());
  ASSERT_NE(chain, nullptr);
  EXPECT_EQ(chain->options().quartic, 1.0);
  EXPECT_EQ(chain->options().threads, 1);
  EXPECT_EQ(run.options.save_every, 4u);
  EXPECT_EQ(run.options.threads, 1);
  EXPECT_EQ(run.options.linear_solver, LinearSolver::kAuto);
}

TEST(ProblemFile, ChainErrorsNameTheKeyTheValueAndTheRule) {
  expect_error(chain_with("quartic = 1.0", "quartc = 1.0"),
               {"p.toml: model.chain.quartc: unknown key (did you mean 'quartic'?)",
                "valid in [model.chain]: stiffness, cubic, quartic, onsite, boundary"});
  expect_error(chain_with("quartic = 1.0", "boundary = \"circular\""),
               {"model.chain.boundary = \"circular\" is not one of fixed, free, periodic"});
  expect_error(chain_with("quartic = 1.0", "boundary = \"fixd\""), {"did you mean 'fixed'?"});
  expect_error(chain_with("quartic = 1.0", "stiffness = \"stiff\""),
               {"model.chain.stiffness", "must be a number", "a string"});
  expect_error(chain_with("alpha = 0.5", "alpha = 0.5\npotential = \"x1^2\""),
               {"model.potential and model.chain are both given"});
  expect_error(chain_with("quartic = 1.0", "boundary = \"periodic\""),
               {"model.dim = 2 is too small for model.chain.boundary = \"periodic\"", "3"},
               {"model.dim=2"});
  expect_error(chain_with("quartic = 1.0", "boundary = \"free\""),
               {"model.dim = 1", "\"free\"", "at least 2"}, {"model.dim=1"});
  expect_error(kBase, {"model.chain", "must be a table"}, {"model.chain=1"});
  expect_error(chain_with("mass = 1.0\ndamping = 0.1\n", "lagrangian = \"xdot1^2/2\"\n"),
               {"model.chain", "cannot be combined with model.lagrangian"});
  expect_error(with("potential = \"x1^2/2 + x2^2/2\"\n", ""),
               {"model.potential: missing", "[model.chain]"});
}

TEST(ProblemFile, InitialDataAsNumbersAndFormulas) {
  const ProblemSpec p = parse(chain_with("[time]", "velocity = -0.5\n[time]"));
  ASSERT_EQ(p.position.size(), 5);
  for (int i : {1, 3, 5})
    EXPECT_DOUBLE_EQ(p.position[i - 1], 0.1 * std::sin(std::numbers::pi * i / 6.0)) << i;
  EXPECT_EQ(p.position_formula, "0.1*sin(pi*i/(d+1))");
  EXPECT_EQ(p.velocity, Eigen::VectorXd::Constant(5, -0.5));
  EXPECT_TRUE(p.velocity_formula.empty());
  const ProblemSpec q = parse(with("position = [1.0, 0.0]", "position = 2"));
  EXPECT_EQ(q.position, Eigen::Vector2d(2.0, 2.0));
  EXPECT_EQ(parse(with("position = [1.0, 0.0]", "position = \"i*d\"")).position,
            Eigen::Vector2d(2.0, 4.0));
  // Arrays as before.
  EXPECT_EQ(parse(kBase).position, Eigen::Vector2d(1.0, 0.0));

  expect_error(
      chain_with("position = \"0.1*sin(pi*i/(d+1))\"", "position = \"sin(pi*j)\""),
      {"initial.position = \"sin(pi*j)\": unknown variable 'j'", "at column 8", "formula in i"});
  expect_error(chain_with("position = \"0.1*sin(pi*i/(d+1))\"", "position = \"1 +* i\""),
               {"initial.position = \"1 +* i\"", "column 4"});
  expect_error(chain_with("position = \"0.1*sin(pi*i/(d+1))\"", "position = \"1/(i-2)\""),
               {"initial.position = \"1/(i-2)\" is inf at i = 2", "finite"});
  expect_error(chain_with("[time]", "velocity = [1.0]\n[time]"),
               {"initial.velocity", "1 entries", "dim is 5"});
  expect_error(chain_with("[time]", "velocity = true\n[time]"),
               {"initial.velocity", "one number or a formula", "a boolean"});
}

TEST(ProblemFile, LinearSolverAndThreads) {
  const ProblemSpec p = parse(kBase);
  EXPECT_EQ(p.linear_solver, "auto");
  EXPECT_EQ(p.threads, 0);
  for (const char* name : {"auto", "dense", "banded", "sparse"}) {
    const ProblemSpec q = parse(kBase + "[method]\nlinear_solver = \"" + name + "\"\n");
    EXPECT_EQ(q.linear_solver, name);
    EXPECT_EQ(to_string(make_integrator_options(q).linear_solver), name);
  }
  EXPECT_EQ(parse(kBase + "[method]\nthreads = 3\n").threads, 3);
  EXPECT_EQ(make_integrator_options(parse(kBase, {"method.threads=2"})).threads, 2);
  EXPECT_EQ(make_integrator_options(parse(kBase, {"output.every=7"})).save_every, 7u);
  // "auto": every state up to 10^5 steps, then the smallest power of two keeping ≤ 10^5 + 1 rows
  // (+ the last).
  EXPECT_EQ(make_integrator_options(parse(kBase, {"output.every=\"auto\""})).save_every, 1u);
  for (const auto& [steps, stride] :
       std::vector<std::pair<long long, long long>>{{100'000, 1},
                                                    {100'001, 2},
                                                    {200'000, 2},
                                                    {200'001, 4},
                                                    {10'000'000, 128},
                                                    {2'000'000'000, 32768}}) {
    EXPECT_EQ(fracvi::stored_every(fracvi::kAutoEvery, steps), stride) << steps;
    EXPECT_LE((steps + stride - 1) / stride, fracvi::kAutoStoredRows) << steps;
    if (stride > 1) {  // the smallest such power: half of it would store too many
      EXPECT_GT((steps + stride / 2 - 1) / (stride / 2), fracvi::kAutoStoredRows) << steps;
    }
  }
  EXPECT_EQ(fracvi::stored_every(3, 10'000'000), 3);
  EXPECT_EQ(make_integrator_options(parse(kBase, {"time.steps=10000000"})).save_every, 128u);
  expect_error(kBase + "[output]\nevery = \"often\"\n",
               {"output.every = \"often\" must be \"auto\" or an integer >= 1"});

  expect_error(kBase + "[method]\nlinear_solver = \"bandd\"\n",
               {"method.linear_solver = \"bandd\" is not one of auto, dense, banded, sparse",
                "did you mean 'banded'?"});
  expect_error(kBase + "[method]\nlinear_solver = 1\n",
               {"method.linear_solver", "must be a string"});
  expect_error(kBase + "[method]\nthreads = -1\n",
               {"method.threads = -1 must be in [0, 4096]", "all cores"});
  expect_error(kBase + "[method]\nthreads = 1.5\n", {"method.threads", "must be an integer"});
  expect_error(kBase + "[method]\nthread = 1\n", {"method.thread", "did you mean 'threads'?"});
}

// method.mirror: "auto" runs the mirror check up to kAutoMirrorWork step-DOFs (kBase: d = 2).
TEST(ProblemFile, MirrorCheckAutoOnOff) {
  EXPECT_EQ(parse(kBase).mirror, "auto");
  EXPECT_TRUE(make_integrator_options(parse(kBase)).mirror);
  const std::string at_limit = "time.steps=" + std::to_string(kAutoMirrorWork / 2);
  const std::string past_limit = "time.steps=" + std::to_string(kAutoMirrorWork / 2 + 1);
  EXPECT_TRUE(make_integrator_options(parse(kBase, {at_limit})).mirror);
  EXPECT_FALSE(make_integrator_options(parse(kBase, {past_limit})).mirror);
  EXPECT_TRUE(make_integrator_options(parse(kBase, {past_limit, "method.mirror=on"})).mirror);
  EXPECT_FALSE(make_integrator_options(parse(kBase, {"method.mirror=off"})).mirror);
  const ProblemSpec off = parse(kBase + "[method]\nmirror = \"off\"\n");
  EXPECT_EQ(parse_problem(to_toml(off), "round-trip").mirror, "off");
  expect_error(kBase + "[method]\nmirror = \"offf\"\n",
               {"method.mirror = \"offf\" is not one of auto, on, off", "did you mean 'off'?"});
  expect_error(kBase + "[method]\nmirror = true\n", {"method.mirror", "must be a string"});
}

// method.history_tolerance: "auto" (the default, the accuracy budget) or a number used exactly.
TEST(ProblemFile, HistoryToleranceAutoOrNumber) {
  EXPECT_EQ(parse(kBase).history_tolerance, kAutoHistoryTolerance);
  EXPECT_EQ(make_integrator_options(parse(kBase)).history_tolerance, kAutoHistoryTolerance);
  const ProblemSpec given = parse(kBase + "[method]\nhistory_tolerance = 3e-12\n");
  EXPECT_EQ(make_integrator_options(given).history_tolerance, 3e-12);
  EXPECT_EQ(parse(kBase, {"method.history_tolerance=auto"}).history_tolerance,
            kAutoHistoryTolerance);
  const ProblemSpec automatic = parse(kBase + "[method]\nhistory_tolerance = \"auto\"\n");
  EXPECT_EQ(automatic.history_tolerance, kAutoHistoryTolerance);
  EXPECT_EQ(parse_problem(to_toml(automatic), "round-trip").history_tolerance,
            kAutoHistoryTolerance);
  EXPECT_EQ(parse_problem(to_toml(given), "round-trip").history_tolerance, 3e-12);
  expect_error(kBase + "[method]\nhistory_tolerance = \"tight\"\n",
               {"method.history_tolerance", "must be \"auto\" or a number"});
  expect_error(kBase + "[method]\nhistory_tolerance = 1e-15\n",
               {"method.history_tolerance", "must be \"auto\" or in [1e-13, 1e-3]"});
  expect_error(kBase + "[method]\nhistory_tolerance = 0\n",
               {"method.history_tolerance", "must be \"auto\" or in [1e-13, 1e-3]"});
}

// method.flush_subnormals: true (the default) or false, passed to the integrator, kept by the
// round trip; anything but a boolean is refused with the key.
TEST(ProblemFile, FlushSubnormalsIsABoolean) {
  EXPECT_TRUE(parse(kBase).flush_subnormals);
  EXPECT_TRUE(make_integrator_options(parse(kBase)).flush_subnormals);
  const ProblemSpec kept = parse(kBase, {"method.flush_subnormals=false"});
  EXPECT_FALSE(kept.flush_subnormals);
  EXPECT_FALSE(make_integrator_options(kept).flush_subnormals);
  EXPECT_FALSE(parse_problem(to_toml(kept), "round-trip").flush_subnormals);
  EXPECT_EQ(to_json(kept)["method"]["flush_subnormals"], false);
  expect_error(kBase + "[method]\nflush_subnormals = 1\n",
               {"method.flush_subnormals", "must be true or false, got an integer"});
  expect_error(kBase + "[method]\nflush_subnormals = \"yes\"\n",
               {"method.flush_subnormals", "must be true or false"});
}

TEST(ProblemFile, RoundTripOfTheNewKeys) {
  const std::string text = chain_with("[time]", "velocity = \"0.01*i\"\n[time]") +
                           "[method]\nlinear_solver = \"sparse\"\nthreads = 1\n[output]\nevery = "
                           "5\n";
  const ProblemSpec p =
      parse(text, {"model.damping=[0.1, 0.2, 0.3, 0.4, 0.5]", "model.chain.onsite=0.5"});
  const ProblemSpec q = parse_problem(to_toml(p), "round-trip");
  EXPECT_EQ(to_json(q), to_json(p));
  EXPECT_EQ(to_toml(q), to_toml(p));
  ASSERT_TRUE(q.chain.has_value());
  EXPECT_EQ(q.chain->onsite, 0.5);
  EXPECT_EQ(q.chain->quartic, 1.0);
  EXPECT_EQ(q.position, p.position);
  EXPECT_EQ(q.velocity, p.velocity);
  EXPECT_EQ(q.velocity_formula, "0.01*i");
  EXPECT_TRUE(q.damping.is_sparse());
  EXPECT_EQ(q.damping.to_dense(), p.damping.to_dense());
  EXPECT_EQ(q.linear_solver, "sparse");
  EXPECT_EQ(q.threads, 1);
  EXPECT_EQ(q.every, 5);
  const nlohmann::json j = to_json(p);
  EXPECT_EQ(j["model"]["mass"], 1.0);
  EXPECT_EQ(j["model"]["damping"], nlohmann::json({0.1, 0.2, 0.3, 0.4, 0.5}));
  EXPECT_EQ(j["model"]["chain"]["boundary"], "fixed");
  EXPECT_FALSE(j["model"].contains("potential"));
  EXPECT_EQ(j["initial"]["position"], "0.1*sin(pi*i/(d+1))");
  // The JSON form goes through the same reader.
  EXPECT_EQ(to_json(parse_problem_json(j, "dict")), j);
  // Arrays of a dense matrix stay dense.
  const ProblemSpec dense = parse(with("mass = 1.0", "mass = [[2, 0], [0, 1]]"));
  EXPECT_FALSE(parse_problem(to_toml(dense), "rt").mass.is_sparse());
}

}  // namespace
}  // namespace fracvi
