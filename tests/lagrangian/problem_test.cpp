// Problem files with `[model] lagrangian` and `[boundary]`: parsing, strict validation, round trip,
// and the mechanical-form detection behind `fracvi run`.
#include "fracvi/io/lagrangian_problem.hpp"

#include <gtest/gtest.h>

#include "fracvi/io/output.hpp"
#include "lagrangian_test_support.hpp"

namespace fracvi {
namespace {

const std::string kLagrangianFile = R"(
name = "lag"
[model]
dim = 2
alpha = 0.6
lagrangian = "0.5*(xdot1^2 + xdot2^2) + 0.5*(ydot1^2 + ydot2^2) - x1^2 - y2^2 - dx1*dy1"
[boundary]
start = [0.1, 0.2]
end = [0.3, -0.4]
[time]
end = 2.0
steps = 20
)";

std::string with(const std::string& from, const std::string& to) {
  std::string s = kLagrangianFile;
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

TEST(LagrangianProblemFile, ParsesAndRoundTrips) {
  const ProblemSpec p = parse_problem(kLagrangianFile, "p.toml");
  EXPECT_EQ(p.lagrangian.substr(0, 10), "0.5*(xdot1");
  EXPECT_EQ(p.convention, "riemann-liouville");
  EXPECT_EQ(p.position.size(), 0);  // no [initial]: a boundary value problem
  EXPECT_EQ(p.boundary_start, Eigen::Vector2d(0.1, 0.2));
  EXPECT_EQ(p.boundary_end, Eigen::Vector2d(0.3, -0.4));
  const ProblemSpec q = parse_problem(to_toml(p), "again.toml");
  EXPECT_EQ(q.lagrangian, p.lagrangian);
  EXPECT_EQ(q.boundary_start, p.boundary_start);
  EXPECT_EQ(q.boundary_end, p.boundary_end);
  EXPECT_EQ(q.position.size(), 0);
  const ProblemSpec j = parse_problem_json(to_json(p), "json");
  EXPECT_EQ(j.lagrangian, p.lagrangian);
  EXPECT_EQ(j.boundary_end, p.boundary_end);

  const BoundaryValueProblem bvp = make_boundary_value_problem(p);
  EXPECT_EQ(bvp.grid.steps, 20);
  EXPECT_EQ(bvp.grid.alpha, 0.6);
  const BvpSolution s = solve_bvp(bvp, make_bvp_options(p));
  EXPECT_TRUE(s.ok()) << s.message;
}

struct BadCase {
  const char* label;
  std::string text;
  std::vector<std::string> needles;  // all must appear in the message
};

TEST(LagrangianProblemFile, RejectsBadInputNamingKeyValueAndRule) {
  const std::vector<BadCase> cases{
      {"variable not in d",
       with("- dx1*dy1", "- dx1*dy3"),
       {"p.toml", "model.lagrangian", "dy3", "column"}},
      {"lagrangian with mass",
       with("alpha = 0.6", "alpha = 0.6\nmass = 1.0"),
       {"model.mass", "cannot be combined with model.lagrangian"}},
      {"lagrangian with potential",
       with("alpha = 0.6", "alpha = 0.6\npotential = \"x1\""),
       {"model.potential", "cannot be combined"}},
      {"lagrangian with caputo",
       with("alpha = 0.6", "alpha = 0.6\nconvention = \"caputo\""),
       {"model.convention", "caputo", "Riemann-Liouville"}},
      {"boundary without end", with("end = [0.3, -0.4]\n", ""), {"boundary.end", "missing"}},
      {"boundary wrong size",
       with("start = [0.1, 0.2]", "start = [0.1]"),
       {"boundary.start", "1 entries", "dim is 2"}},
      {"unknown boundary key",
       with("start = [0.1, 0.2]", "begin = [0.1, 0.2]"),
       {"boundary.begin", "unknown key"}},
      {"no boundary, no initial",
       with("[boundary]\nstart = [0.1, 0.2]\nend = [0.3, -0.4]\n", ""),
       {"initial.position", "missing"}},
  };
  for (const auto& c : cases) {
    try {
      parse_problem(c.text, "p.toml");
      ADD_FAILURE() << c.label << ": accepted";
    } catch (const ProblemFileError& e) {
      for (const auto& needle : c.needles)
        EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
            << c.label << ": '" << needle << "' not in: " << e.what();
    }
  }
}

TEST(LagrangianProblemFile, SingularVelocityHessianIsRefused) {
  // No kinetic term in ydot: the y-equations cannot be solved.
  const ProblemSpec p = parse_problem(with("0.5*(ydot1^2 + ydot2^2)", "0*ydot1"), "p.toml");
  try {
    make_boundary_value_problem(p);
    FAIL() << "accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("d2L/dydot2, is singular"), std::string::npos) << e.what();
  }
  // A position-dependent mass that vanishes at the initial data of an IVP.
  ProblemSpec q = parse_problem(with("0.5*(xdot1^2 + xdot2^2)", "0.5*x1^2*(xdot1^2 + xdot2^2)")
                                    .append("[initial]\nposition = [0.0, 0.0]\n"),
                                "p.toml");
  EXPECT_THROW(make_lagrangian_initial_value_problem(q), ValidationError);
}

TEST(MechanicalForm, RecognisesPartLagrangianAndRefusesTheRest) {
  auto form = [](Eigen::Index d, const std::string& text) {
    return mechanical_form(std::make_shared<const ExpressionLagrangian>(d, text), 0.5);
  };
  const MechanicalForm ok = form(
      2,
      "0.5*(2*xdot1^2 + 2*0.5*xdot1*xdot2 + 3*xdot2^2) + ydot1^2 - (x1^2 + cos(x2) - "
      "t*x1) - sin(y1) - (0.7*dx1*dy1 + 0.1*dx1*dy2 + 0.1*dx2*dy1 + 0.2*dx2*dy2) + 0.1*y1*ydot1");
  ASSERT_TRUE(ok.model) << ok.reason;
  EXPECT_EQ(ok.model->mass.to_dense(), (Eigen::Matrix2d() << 2.0, 0.5, 0.5, 3.0).finished());
  EXPECT_EQ(ok.model->damping.to_dense(), (Eigen::Matrix2d() << 0.7, 0.1, 0.1, 0.2).finished());
  Eigen::VectorXd g(2);
  ok.model->potential->gradient(Eigen::Vector2d(0.3, 0.4), 2.0, g);
  EXPECT_NEAR(g(0), 2 * 0.3 - 2.0, 1e-15);
  EXPECT_NEAR(g(1), -std::sin(0.4), 1e-15);

  const std::vector<std::pair<std::string, std::string>> refused{
      {"0.5*(1 + x1^2)*xdot1^2 - dx1*dy1", "dL/dxdot1 depends on x1"},
      {"0.5*xdot1^2 + 0.5*xdot1^4 - dx1*dy1", "not constant"},
      {"0.5*xdot1^2 - dx1^2*dy1", "not constant"},
      {"0.5*xdot1^2 - x1*dx1", "dL/dx1 depends on dx1"},
      {"0.5*xdot1^2 + t*xdot1", "dL/dxdot1 depends on t"},
      {"0.5*xdot1^2 + 2*xdot1", "linear in xdot1"},
      {"0.5*xdot1^2 - x1*y1", "boundary value problem"},
  };
  for (const auto& [text, needle] : refused) {
    const MechanicalForm f = form(1, text);
    EXPECT_FALSE(f.model) << text;
    EXPECT_NE(f.reason.find(needle), std::string::npos) << text << ": " << f.reason;
  }
}

TEST(MechanicalForm, RunOfTheLagrangianEqualsRunOfTheMechanicalFields) {
  const std::string mech = R"toml(
[model]
dim = 1
mass = 2.0
damping = 0.3
alpha = 0.5
potential = "1 - cos(x1)"
[initial]
position = [0.5]
velocity = [0.1]
[time]
end = 3.0
steps = 300
[method]
newton_tolerance = 1e-15
)toml";
  std::string lag = mech;
  lag.replace(lag.find("mass = 2.0\ndamping = 0.3\n"), 25, "");
  lag.replace(lag.find("potential = \"1 - cos(x1)\""), 25,
              "lagrangian = \"xdot1^2 + ydot1^2 - (1 - cos(x1)) - (1 - cos(y1)) - 0.3*dx1*dy1\"");
  const ProblemSpec a = parse_problem(mech, "mech.toml");
  const ProblemSpec b = parse_problem(lag, "lag.toml");
  const Solution sa =
      integrate(make_initial_value_problem(a), fvi_gl(), make_integrator_options(a));
  const Solution sb =
      integrate(make_lagrangian_initial_value_problem(b), fvi_gl(), make_integrator_options(b));
  ASSERT_TRUE(sa.ok() && sb.ok());
  // Same scheme; U from two different tapes of the same formula: round-off apart.
  EXPECT_LE((sa.x - sb.x).cwiseAbs().maxCoeff(), 1e-13);
  // A non-mechanical L is refused, and the message points to fracvi bvp.
  ProblemSpec c = b;
  c.lagrangian = "0.5*(1 + x1^2)*xdot1^2 + ydot1^2 - dx1*dy1";
  try {
    make_lagrangian_initial_value_problem(c);
    FAIL() << "accepted";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("fracvi bvp"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fracvi
