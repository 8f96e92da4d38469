// Interrupts and checkpoints (issue 14, item 5): IntegratorOptions::interrupt ends a run with
// Status::kInterrupted and the trajectory so far; Integrator::visit_state saves a running
// integration and restores it into a fresh Integrator that then continues bit for bit — for
// every scheme that declares SchemeInfo::checkpoints, with the direct, fast and local histories,
// stored rows every step or every n-th, on a nonlinear, forced, coupled problem (where Newton's
// predictor and every accumulator matter). The negative control alters one saved accumulator and
// shows the comparison notices.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

InitialValueProblem pendula(double alpha, std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.5, 0.3}, {0.3, 1.0}};
  p.model.damping = Eigen::MatrixXd{{0.6, -0.2}, {-0.2, 0.4}};
  p.model.alpha = alpha;
  p.model.convention = Convention::kCaputo;
  p.model.potential =
      std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{9.81, 4.0}}, 2.0);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f(0) = 0.3 * std::sin(2.0 * t);
    f(1) = 0.1;
  };
  p.x0 = Eigen::VectorXd{{1.2, -0.4}};
  p.v0 = Eigen::VectorXd{{0.5, 0.8}};
  p.t_end = 2.0;
  p.steps = steps;
  return p;
}

// Bitwise equality of two arrays of doubles (NaN and signed zeros included).
template <class A>
bool same_bits(const A& a, const A& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), static_cast<std::size_t>(a.size()) * sizeof(double)) == 0;
}

void expect_same_run(const Solution& a, const Solution& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.message, b.message);
  EXPECT_EQ(a.steps_done, b.steps_done);
  EXPECT_EQ(a.step, b.step);
  EXPECT_TRUE(same_bits(a.t, b.t));
  EXPECT_TRUE(same_bits(a.x, b.x));
  EXPECT_TRUE(same_bits(a.v, b.v));
  EXPECT_TRUE(same_bits(a.energy, b.energy));
  EXPECT_TRUE(same_bits(a.dissipated, b.dissipated));
  EXPECT_TRUE(same_bits(a.balance, b.balance));
  EXPECT_EQ(a.newton_iterations, b.newton_iterations);
  EXPECT_EQ(a.max_newton_iterations_per_step, b.max_newton_iterations_per_step);
  EXPECT_EQ(a.jacobian_factorizations, b.jacobian_factorizations);
  EXPECT_EQ(std::memcmp(&a.max_balance_error, &b.max_balance_error, sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(&a.mirror_error, &b.mirror_error, sizeof(double)), 0);
  EXPECT_EQ(a.history, b.history);
}

// The state after `k` steps of a run.
std::string state_after(const InitialValueProblem& p, const Method& method,
                        const IntegratorOptions& options, std::size_t k) {
  Integrator integrator(p, method, options);
  for (std::size_t i = 0; i < k; ++i) EXPECT_EQ(integrator.step(), Status::kRunning);
  StateWriter writer;
  integrator.visit_state(writer);
  return writer.bytes();
}

Solution resumed_from(const std::string& state, const InitialValueProblem& p, const Method& method,
                      const IntegratorOptions& options) {
  Integrator integrator(p, method, options);
  StateReader reader(state, "test state");
  integrator.visit_state(reader);
  reader.finish();
  integrator.run();
  return integrator.take_solution();
}

struct Case {
  const char* scheme;
  double alpha;
  HistoryKind history;
  std::size_t save_every;
  const char* expected_history;  // what the run used
  ForcingLoad load = ForcingLoad::kPointwise;
  bool state_force = false;  // add a van der Pol-type g(x, v, t) (Lobatto: its stage velocities)
  // kBanded: Newton keeps its Jacobian from step to step (simplified Newton; the dense path
  // forms it at every iterate), so the checkpoint must hold where it was formed.
  LinearSolver linear_solver = LinearSolver::kAuto;
};

// With 240 steps (h = 1/120) Newton takes about three corrections a step on the pendula, and
// the banded path then forms J afresh at every step; with 2400 (h = 1/1200) two, and it keeps J
// from step to step — the state a checkpoint must then carry.
constexpr std::size_t kKeptJacobianSteps = 2400;

class CheckpointResume : public ::testing::TestWithParam<Case> {};

TEST_P(CheckpointResume, ContinuesBitForBit) {
  const Case c = GetParam();
  InitialValueProblem p =
      pendula(c.alpha, c.linear_solver == LinearSolver::kBanded ? kKeptJacobianSteps : 240);
  if (c.state_force) {
    p.model.state_force = std::make_shared<const ExpressionForce>(
        2, std::vector<std::string>{"0.5*(1 - x1^2)*v1", "-0.2*x1*v2"});
  }
  const Method method = *parse_method(c.scheme);
  IntegratorOptions options;
  options.history = c.history;
  options.save_every = c.save_every;
  options.load = c.load;
  options.linear_solver = c.linear_solver;
  const Solution reference = integrate(p, method, options);
  ASSERT_EQ(reference.status, Status::kSuccess) << reference.message;
  EXPECT_EQ(reference.history, c.expected_history);
  // k = 1 (the start step's predictor and impulse), a k between stored rows, and the last step
  // before the end.
  for (const std::size_t k : {std::size_t{1}, std::size_t{97}, p.steps - 1}) {
    SCOPED_TRACE("checkpoint after step " + std::to_string(k));
    expect_same_run(resumed_from(state_after(p, method, options, k), p, method, options),
                    reference);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Schemes, CheckpointResume,
    ::testing::Values(
        Case{"fvi-gl", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"fvi-gl", 0.75, HistoryKind::kFast, 1, "fast"},
        Case{"fvi-gl", 0.75, HistoryKind::kFast, 7, "fast"},
        Case{"fvi-gl", 0.5, HistoryKind::kAuto, 1, "none"},  // Lemma 5.3
        Case{"fvi-gl", 1.0, HistoryKind::kAuto, 3, "local"},
        Case{"fvi-bdf2", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"fvi-bdf2", 0.75, HistoryKind::kFast, 5, "fast"},
        Case{"fvi-midpoint", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"fvi-midpoint", 0.75, HistoryKind::kFast, 3, "fast"},
        Case{"fvi-midpoint", 0.5, HistoryKind::kAuto, 1, "local"},
        // Block histories; nonlinear U: simplified Newton's kept stage matrix.
        Case{"fvi-lobatto3", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"fvi-lobatto3", 0.75, HistoryKind::kFast, 3, "fast"},
        Case{"fvi-lobatto3", 0.25, HistoryKind::kFast, 1, "fast", ForcingLoad::kMoments},
        Case{"fvi-lobatto2", 0.25, HistoryKind::kDirect, 1, "direct"},
        Case{"fvi-lobatto2", 0.5, HistoryKind::kAuto, 1, "fast"},  // local blocks
        Case{"fvi-lobatto4", 0.75, HistoryKind::kFast, 1, "fast"},
        Case{"fvi-lobatto4", 0.4, HistoryKind::kDirect, 4, "direct", ForcingLoad::kMoments},
        // A non-conservative force g(x, v, t): the Lobatto stage matrix is formed again at the
        // saved stages and stage velocities.
        Case{"fvi-gl", 0.75, HistoryKind::kFast, 1, "fast", ForcingLoad::kPointwise, true},
        Case{"fvi-midpoint", 0.75, HistoryKind::kDirect, 3, "direct", ForcingLoad::kPointwise,
             true},
        Case{"fvi-lobatto3", 0.75, HistoryKind::kFast, 1, "fast", ForcingLoad::kPointwise, true},
        Case{"fvi-lobatto2", 0.5, HistoryKind::kAuto, 1, "fast", ForcingLoad::kPointwise, true},
        // Baselines.
        Case{"euler-explicit", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"euler-explicit", 0.25, HistoryKind::kFast, 3, "fast"},
        Case{"euler-implicit", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"euler-implicit", 0.25, HistoryKind::kFast, 1, "fast"},
        Case{"lda-midpoint", 0.75, HistoryKind::kDirect, 1, "direct"},
        Case{"lda-midpoint", 0.75, HistoryKind::kFast, 2, "fast", ForcingLoad::kMoments},
        Case{"conformal-strang", 0.5, HistoryKind::kAuto, 1, "none"},
        // Newton's Jacobian kept across steps (banded backend, nonlinear U).
        Case{"fvi-gl", 0.75, HistoryKind::kFast, 1, "fast", ForcingLoad::kPointwise, false,
             LinearSolver::kBanded},
        Case{"fvi-midpoint", 0.75, HistoryKind::kDirect, 3, "direct", ForcingLoad::kPointwise,
             false, LinearSolver::kBanded},
        Case{"euler-implicit", 0.25, HistoryKind::kFast, 1, "fast", ForcingLoad::kPointwise, false,
             LinearSolver::kBanded},
        Case{"lda-midpoint", 0.75, HistoryKind::kFast, 2, "fast", ForcingLoad::kMoments, false,
             LinearSolver::kBanded}),
    [](const auto& param_info) {
      std::string name = std::string(param_info.param.scheme) + "_" +
                         std::string(to_string(param_info.param.history)) + "_alpha" +
                         std::to_string(static_cast<int>(param_info.param.alpha * 100)) + "_every" +
                         std::to_string(param_info.param.save_every) +
                         (param_info.param.load == ForcingLoad::kMoments ? "_moments" : "") +
                         (param_info.param.state_force ? "_state_force" : "") +
                         (param_info.param.linear_solver == LinearSolver::kBanded ? "_banded" : "");
      for (char& ch : name)
        if (ch == '-') ch = '_';
      return name;
    });

// Negative control: the comparison above would notice a state that is not the whole state. The
// fast history's recursions Y_j, altered in one bit of one entry, change the resumed trajectory.
TEST(CheckpointResume, AnAlteredAccumulatorChangesTheRun) {
  const InitialValueProblem p = pendula(0.75, 240);
  IntegratorOptions options;
  options.history = HistoryKind::kFast;
  const Solution reference = integrate(p, fvi_gl(), options);
  std::string state = state_after(p, fvi_gl(), options, 97);
  const std::string name = "fast.recursions";
  const std::size_t at = state.find(name);
  ASSERT_NE(at, std::string::npos);
  // Record layout (state_archive.cpp): name, type byte, u64 length, payload.
  const std::size_t payload = at + name.size() + 1 + sizeof(std::uint64_t);
  state[payload + sizeof(double) - 2] ^= 0x01;  // a low mantissa bit of Y_0 (first DOF)
  const Solution altered = resumed_from(state, p, fvi_gl(), options);
  EXPECT_FALSE(same_bits(altered.x, reference.x));
  // Unchanged, it is identical (the same call path).
  expect_same_run(resumed_from(state_after(p, fvi_gl(), options, 97), p, fvi_gl(), options),
                  reference);
}

// Negative control for Newton's kept Jacobian: restored as "not carried" (the flag's byte
// altered), the resumed run forms J at its own first iterate instead of keeping the saved one, and
// its iterates differ in the last bits — the record is part of the state.
TEST(CheckpointResume, AForgottenKeptJacobianChangesTheRun) {
  const InitialValueProblem p = pendula(0.75, kKeptJacobianSteps);
  IntegratorOptions options;
  options.history = HistoryKind::kFast;
  options.linear_solver = LinearSolver::kBanded;
  const Solution reference = integrate(p, fvi_gl(), options);
  ASSERT_EQ(reference.status, Status::kSuccess) << reference.message;
  std::string state = state_after(p, fvi_gl(), options, 97);
  const std::string name = "cq_midpoint.newton.carry";
  const std::size_t at = state.find(name);  // the first: ".carry_wait" comes after it
  ASSERT_NE(at, std::string::npos);
  // Record layout (state_archive.cpp): name, type byte, u64 length, payload (a u64 count, 0 or 1,
  // little-endian on x86-64).
  const std::size_t payload = at + name.size() + 1 + sizeof(std::uint64_t);
  ASSERT_EQ(state[payload], 1);
  state[payload] = 0;
  const Solution altered = resumed_from(state, p, fvi_gl(), options);
  ASSERT_EQ(altered.status, Status::kSuccess) << altered.message;
  EXPECT_FALSE(same_bits(altered.x, reference.x));
}

TEST(CheckpointResume, EverySchemeWithoutCheckpointsRefusesAndTheOthersSave) {
  for (const SchemeInfo* info : registered_schemes()) {
    SCOPED_TRACE(std::string(info->name));
    InitialValueProblem p = pendula(0.5, 240);
    p.model.mass = Eigen::MatrixXd::Identity(2, 2);  // every scheme applies (2α = 1, M = I)
    p.model.damping = Eigen::MatrixXd{{0.6, 0.0}, {0.0, 0.4}};
    Integrator integrator(p, Method(*info));
    ASSERT_EQ(integrator.step(), Status::kRunning);
    StateWriter writer;
    if (info->checkpoints) {
      EXPECT_NO_THROW(integrator.visit_state(writer));
    } else {
      EXPECT_THROW(integrator.visit_state(writer), CheckpointError);
    }
  }
}

// method.scheme = "auto" with checkpoints (fracvi run's [output] checkpoint_every) admits only
// schemes that can write them: every candidate can, so the choice is the one without checkpoints.
TEST(CheckpointResume, AutoWithCheckpointsKeepsItsChoice) {
  const auto checkpointable = [](const SchemeInfo& info) { return info.checkpoints; };
  InitialValueProblem p = pendula(0.75, 240);
  EXPECT_EQ(choose_scheme(p, {}, checkpointable).name(), "fvi-lobatto3");
  EXPECT_EQ(choose_scheme(p, {}, checkpointable), choose_scheme(p));
  p.model.alpha = 1.0;  // 2α = 2: outside the Lobatto and midpoint schemes
  EXPECT_EQ(choose_scheme(p, {}, checkpointable), choose_scheme(p));
}

TEST(CheckpointResume, AStateOfAnotherRunIsRefused) {
  const InitialValueProblem p = pendula(0.75, 240);
  IntegratorOptions direct;
  direct.history = HistoryKind::kDirect;
  IntegratorOptions fast;
  fast.history = HistoryKind::kFast;
  const std::string state = state_after(p, fvi_gl(), direct, 50);
  // Another step count, another history, another scheme: the records say which.
  InitialValueProblem longer = p;
  longer.steps = 480;
  EXPECT_THROW(resumed_from(state, longer, fvi_gl(), direct), CheckpointError);
  EXPECT_THROW(resumed_from(state, p, fvi_gl(), fast), CheckpointError);
  EXPECT_THROW(resumed_from(state, p, fvi_bdf2(), direct), CheckpointError);
  // Truncated, and with bytes left over.
  EXPECT_THROW(resumed_from(state.substr(0, state.size() - 3), p, fvi_gl(), direct),
               CheckpointError);
  EXPECT_THROW(resumed_from(state + "x", p, fvi_gl(), direct), CheckpointError);
  try {
    resumed_from(state, longer, fvi_gl(), direct);
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("integrator.steps"), std::string::npos) << e.what();
  }
  // Only a running integration has a state to continue.
  Integrator finished(p, fvi_gl(), direct);
  finished.run();
  StateWriter writer;
  EXPECT_THROW(finished.visit_state(writer), CheckpointError);
}

TEST(CheckpointResume, ABlockHistoryOfAnotherKindOrSchemeIsRefused) {
  const InitialValueProblem p = pendula(0.75, 240);
  IntegratorOptions direct;
  direct.history = HistoryKind::kDirect;
  IntegratorOptions fast;
  fast.history = HistoryKind::kFast;
  const Method lobatto3 = *parse_method("fvi-lobatto3");
  const std::string state = state_after(p, lobatto3, direct, 50);
  EXPECT_THROW(resumed_from(state, p, lobatto3, fast), CheckpointError);
  EXPECT_THROW(resumed_from(state, p, *parse_method("fvi-lobatto2"), direct), CheckpointError);
  EXPECT_THROW(resumed_from(state, p, *parse_method("fvi-lobatto4"), direct), CheckpointError);
  try {
    resumed_from(state, p, lobatto3, fast);
  } catch (const CheckpointError& e) {
    EXPECT_NE(std::string(e.what()).find("block_direct"), std::string::npos) << e.what();
  }
}

TEST(Interrupt, StopsBeforeTheNextStepAndKeepsTheTrajectory) {
  const InitialValueProblem p = pendula(0.75, 240);
  IntegratorOptions options;
  options.save_every = 10;
  const Solution whole = integrate(p, fvi_gl(), options);
  std::size_t polls = 0;
  options.interrupt = [&polls] { return ++polls > 37; };  // asked before step 38
  std::vector<std::size_t> observed;
  Integrator integrator(p, fvi_gl(), options);
  EXPECT_EQ(integrator.run([&](const StepView& v) { observed.push_back(v.k); }),
            Status::kInterrupted);
  EXPECT_EQ(integrator.steps_done(), 37u);
  EXPECT_EQ(observed.back(), 37u);  // the observer saw every completed step, no extra one
  EXPECT_EQ(observed.size(), 38u);
  EXPECT_EQ(integrator.step(), Status::kInterrupted);  // stays stopped
  const Solution s = integrator.take_solution();
  EXPECT_EQ(s.status, Status::kInterrupted);
  EXPECT_EQ(to_string(s.status), "interrupted");
  EXPECT_EQ(s.steps_done, 37u);
  EXPECT_NE(s.message.find("interrupted after step 37 of 240"), std::string::npos) << s.message;
  // Rows 0, 10, 20, 30 and the last completed step 37, equal to the uninterrupted run's.
  EXPECT_EQ(s.step, (std::vector<std::size_t>{0, 10, 20, 30, 37}));
  for (Eigen::Index i = 0; i < 4; ++i) EXPECT_EQ(s.x.row(i), whole.x.row(i));
  EXPECT_TRUE(s.x.allFinite());
  EXPECT_TRUE(std::isnan(s.mirror_error));  // no mirror run for a run that did not finish
}

// A signal during the mirror check (the backward run after the last step) stops it at its next
// step: the run is interrupted, with the whole trajectory and no mirror error.
TEST(Interrupt, DuringTheMirrorCheckStopsItAndKeepsTheTrajectory) {
  for (const char* scheme : {"fvi-gl", "fvi-midpoint", "fvi-lobatto3"}) {
    SCOPED_TRACE(scheme);
    const Method method = *parse_method(scheme);
    const InitialValueProblem p = pendula(0.75, 240);
    IntegratorOptions options;
    const Solution whole = integrate(p, method, options);
    ASSERT_EQ(whole.status, Status::kSuccess) << whole.message;
    ASSERT_TRUE(std::isfinite(whole.mirror_error));
    // The forward run asks before each of its 240 steps; the mirror run before each of its own:
    // the hook says stop at its 50th question there (and keeps saying it).
    std::size_t polls = 0;
    options.interrupt = [&polls, &p] { return ++polls >= p.steps + 50; };
    const Solution s = integrate(p, method, options);
    EXPECT_EQ(polls, p.steps + 51);  // and once more by the Integrator, to tell why it ended
    EXPECT_EQ(s.status, Status::kInterrupted);
    EXPECT_NE(s.message.find("interrupted during the mirror check, after all 240 steps"),
              std::string::npos)
        << s.message;
    EXPECT_EQ(s.steps_done, p.steps);
    EXPECT_TRUE(std::isnan(s.mirror_error));
    EXPECT_TRUE(same_bits(s.x, whole.x));
    EXPECT_TRUE(same_bits(s.v, whole.v));
  }
}

TEST(Interrupt, BeforeTheFirstStepKeepsTheInitialState) {
  const InitialValueProblem p = pendula(0.75, 240);
  IntegratorOptions options;
  options.interrupt = [] { return true; };
  const Solution s = integrate(p, fvi_gl(), options);
  EXPECT_EQ(s.status, Status::kInterrupted);
  EXPECT_EQ(s.steps_done, 0u);
  ASSERT_EQ(s.x.rows(), 1);
  EXPECT_EQ(s.x.row(0).transpose(), p.x0);
}

}  // namespace
}  // namespace fracvi
