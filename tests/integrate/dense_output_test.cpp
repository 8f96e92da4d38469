// Dense output and events (docs/theory/dense_output.md).
//
// Dense output: the cubic Hermite interpolant of the grid states, evaluated during the run at
// IntegratorOptions::output_times. Its order is measured, for every scheme that applies to
// 2α = 1, as the least-squares log–log slope over 5 step sizes of the error at 9 off-grid times
// (irrational fractions of the interval: never a grid point), against
//   * the exact solution of a damped, forced oscillator (matrix exponential), and
//   * a nonlinear damped pendulum against Boost.Odeint dopri5 at 1e-13.
// Expected: x to order min(p, 4), v to order min(p, 3), p the scheme's declared order.
// Events: the first zero of a damped oscillator against its closed form (and its order), the
// direction filter against the closed-form zeros, a terminal event, the failures of g.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "../support/test_problems.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/integrate/dense_output.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "integrate_test_support.hpp"

namespace fracvi {
namespace {

// Step counts on [0, T] (T = 4 or 5): low-order schemes need finer grids to leave the
// pre-asymptotic range (fvi-gl's local order is 0.23 between N = 20 and 40), high-order ones reach
// the round-off floor on them.
const std::vector<std::size_t> kSteps = {20, 40, 80, 160, 320};
const std::vector<std::size_t> kFineSteps = {80, 160, 320, 640, 1280};
// First order (and the explicit Euler's energy growth flagged "inaccurate" up to N = 80).
const std::vector<std::size_t> kFinestSteps = {320, 640, 1280, 2560, 5120};
// Off-grid output times: T (j + φ)/9 with φ = (√5 − 1)/2 irrational, j = 0 … 8.
std::vector<double> off_grid_times(double t0, double t_end) {
  const double phi = (std::sqrt(5.0) - 1.0) / 2.0;
  std::vector<double> t;
  for (int j = 0; j < 9; ++j) t.push_back(t0 + (t_end - t0) * (j + phi) / 9.0);
  return t;
}

// The observed orders may fall short of the expected ones by this: the fit over h = T/20 …
// T/320 still carries the next term of the error expansion (measured deviations are printed).
constexpr double kOrderSlack = 0.2;

// The scheme's options for a reference-quality run (dopri5: tight tolerances, so that its grid
// data are far more accurate than the interpolant).
IntegratorOptions run_options(const SchemeInfo& info) {
  IntegratorOptions o;
  o.mirror = false;
  if (info.adaptive) o.abs_tolerance = o.rel_tolerance = 1e-13;
  return o;
}

// The pendulum M x'' + R x' + 4 sin x = 0, 2α = 1, x0 = 1.2, v0 = 0, on [0, 4].
InitialValueProblem pendulum(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.0}};
  p.model.damping = Eigen::MatrixXd{{0.3}};
  p.model.alpha = 0.5;
  p.model.potential = std::make_shared<const test::PendulumChain>(Eigen::VectorXd{{4.0}}, 0.0);
  p.x0 = Eigen::VectorXd{{1.2}};
  p.v0 = Eigen::VectorXd{{0.0}};
  p.t_end = 4.0;
  p.steps = steps;
  return p;
}

// The pendulum at `times` (all > t_0) by Boost.Odeint dopri5 at 1e-13, started at t_0.
Eigen::MatrixXd pendulum_reference(const std::vector<double>& times) {
  const InitialValueProblem p = pendulum(10);
  std::vector<double> from_start{p.t0};
  from_start.insert(from_start.end(), times.begin(), times.end());
  const Eigen::MatrixXd all = test::dopri5_reference(p.model, p.x0, p.v0, from_start, 1e-13);
  return all.bottomRows(all.rows() - 1);
}

// For every scheme that applies: the dense output's errors at `times` against `exact` (times ×
// 2d: x then v), fitted; EXPECTs the orders min(p, 4) and min(p, 3).
void check_dense_orders(const std::function<InitialValueProblem(std::size_t)>& problem,
                        const std::vector<double>& times, const Eigen::MatrixXd& exact,
                        const char* label) {
  const Eigen::Index d = exact.cols() / 2;
  const double x_scale = exact.leftCols(d).cwiseAbs().maxCoeff();
  const double v_scale = exact.rightCols(d).cwiseAbs().maxCoeff();
  for (const SchemeInfo* info : registered_schemes()) {
    const Method method(*info);
    IntegratorOptions options = run_options(*info);
    options.output_times = times;
    std::vector<double> hs, ex, ev;
    int order = 0;
    bool applies = true;
    const int declared = method.declared_order(problem(kSteps[0]).model);
    const auto& steps = declared == 1 ? kFinestSteps : (declared == 2 ? kFineSteps : kSteps);
    for (const std::size_t n : steps) {
      InitialValueProblem p = problem(n);
      try {
        check_applicable(p, method, options);
      } catch (const ValidationError&) {
        applies = false;
        break;
      }
      const Solution sol = integrate(p, method, options);
      ASSERT_TRUE(sol.ok()) << info->name << " N = " << n << ": " << sol.message;
      ASSERT_EQ(sol.output_t.size(), static_cast<Eigen::Index>(times.size()));
      order = sol.declared_order;
      hs.push_back((p.t_end - p.t0) / static_cast<double>(n));
      ex.push_back((sol.output_x - exact.leftCols(d)).cwiseAbs().maxCoeff());
      ev.push_back((sol.output_v - exact.rightCols(d)).cwiseAbs().maxCoeff());
    }
    if (!applies) {
      std::printf("  %-16s does not apply (skipped)\n", std::string(info->name).c_str());
      continue;
    }
    const test::OrderFit fx = test::fit_order(hs, ex, {.floor = test::round_off_floor(x_scale)});
    const test::OrderFit fv = test::fit_order(hs, ev, {.floor = test::round_off_floor(v_scale)});
    const int px = std::min(order, 4), pv = std::min(order, 3);
    std::printf(
        "  %s %-16s declared %d: dense x order %.3f (expected %d), v order %.3f "
        "(expected %d); errors at the finest N: x %.2e, v %.2e\n",
        label, std::string(info->name).c_str(), order, fx.slope, px, fv.slope, pv, ex.back(),
        ev.back());
    const std::string name = std::string(label) + " " + std::string(info->name);
    EXPECT_TRUE(fx.valid) << fx.table(name + " x");
    EXPECT_GE(fx.slope, px - kOrderSlack) << fx.table(name + " x");
    EXPECT_TRUE(fv.valid) << fv.table(name + " v");
    EXPECT_GE(fv.slope, pv - kOrderSlack) << fv.table(name + " v");
  }
}

TEST(DenseOutput, OrderOnTheForcedViscousOscillator) {
  const test::ViscousOscillator s;
  const auto times = off_grid_times(0.0, s.t_end);
  const Eigen::MatrixXd exact =
      test::damped_oscillator_exact(s.M, s.R, s.K, s.fhat, s.omega, s.x0, s.v0, times);
  check_dense_orders([&](std::size_t n) { return s.problem(n); }, times, exact, "oscillator");
}

TEST(DenseOutput, OrderOnTheNonlinearPendulum) {
  const InitialValueProblem p = pendulum(10);
  const auto times = off_grid_times(p.t0, p.t_end);
  check_dense_orders(pendulum, times, pendulum_reference(times), "pendulum");
}

// Negative control of the order claim: linear interpolation of the same (fvi-lobatto3, order 4)
// grid states is only second order at the same times.
TEST(DenseOutput, LinearInterpolationOfTheSameStatesIsSecondOrder) {
  const InitialValueProblem p0 = pendulum(10);
  const auto times = off_grid_times(p0.t0, p0.t_end);
  const Eigen::MatrixXd exact = pendulum_reference(times);
  const Method method = *parse_method("fvi-lobatto3");
  std::vector<double> hs, hermite, linear;
  for (const std::size_t n : kSteps) {
    IntegratorOptions o = run_options(method.info());
    o.output_times = times;
    const Solution sol = integrate(pendulum(n), method, o);
    ASSERT_TRUE(sol.ok()) << sol.message;
    const double h = 4.0 / static_cast<double>(n);
    double lin = 0.0;
    for (std::size_t j = 0; j < times.size(); ++j) {
      const auto k = static_cast<Eigen::Index>(std::floor(times[j] / h));
      const double s = (times[j] - sol.t[k]) / h;
      lin = std::max(lin, std::abs((1 - s) * sol.x(k, 0) + s * sol.x(k + 1, 0) -
                                   exact(static_cast<Eigen::Index>(j), 0)));
    }
    hs.push_back(h);
    hermite.push_back((sol.output_x.col(0) - exact.col(0)).cwiseAbs().maxCoeff());
    linear.push_back(lin);
  }
  const test::OrderFit fh = test::fit_order(hs, hermite), fl = test::fit_order(hs, linear);
  EXPECT_GE(fh.slope, 4.0 - kOrderSlack) << fh.table("hermite");
  EXPECT_NEAR(fl.slope, 2.0, kOrderSlack) << fl.table("linear");
}

// Times on the grid give the grid states bit for bit, and every > 1 changes nothing: the
// interpolant uses every step's full-precision state.
TEST(DenseOutput, GridTimesAreExactAndStrideIndependent) {
  const test::ViscousOscillator s;
  const std::size_t n = 60;
  InitialValueProblem p = s.problem(n);
  std::vector<double> times;
  for (const int k : {0, 7, 13, 30, 59, 60}) times.push_back(p.t0 + k * p.step_size());
  for (double t : off_grid_times(p.t0, p.t_end)) times.push_back(t);
  std::sort(times.begin(), times.end());
  for (const char* scheme : {"fvi-gl", "fvi-midpoint", "fvi-lobatto3"}) {
    IntegratorOptions one;
    one.output_times = times;
    const Method method = *parse_method(scheme);
    const Solution a = integrate(p, method, one);
    IntegratorOptions seven = one;
    seven.save_every = 7;
    const Solution b = integrate(p, method, seven);
    ASSERT_TRUE(a.ok() && b.ok()) << a.message << b.message;
    EXPECT_EQ(a.output_x, b.output_x) << scheme;
    EXPECT_EQ(a.output_v, b.output_v) << scheme;
    EXPECT_EQ(a.output_t, b.output_t) << scheme;
    for (std::size_t j = 0; j < times.size(); ++j) {
      const auto r = static_cast<Eigen::Index>(j);
      for (Eigen::Index k = 0; k < a.t.size(); ++k) {
        if (a.t[k] == times[j]) {
          EXPECT_EQ(a.output_x.row(r), a.x.row(k)) << scheme << " t = " << times[j];
          EXPECT_EQ(a.output_v.row(r), a.v.row(k)) << scheme << " t = " << times[j];
        }
      }
      // sol(t) from the stored rows (every = 1) is the same interpolant, bit for bit.
      Eigen::VectorXd x(2), v(2);
      interpolate(a, times[j], x, v);
      EXPECT_EQ(x.transpose(), a.output_x.row(r)) << scheme << " t = " << times[j];
      EXPECT_EQ(v.transpose(), a.output_v.row(r)) << scheme << " t = " << times[j];
    }
    // With every = 7 sol(t) between two stored rows that are not consecutive steps is refused.
    Eigen::VectorXd x(2), v(2);
    EXPECT_THROW(interpolate(b, 0.5 * (b.t[1] + b.t[2]), x, v), ValidationError);
    EXPECT_THROW(interpolate(a, -0.1, x, v), ValidationError);
  }
}

TEST(DenseOutput, BadOutputTimesAreRefused) {
  const test::ViscousOscillator s;
  const auto message = [&](std::vector<double> times) {
    IntegratorOptions o;
    o.output_times = std::move(times);
    try {
      Integrator integ(s.problem(10), fvi_gl(), o);
    } catch (const ValidationError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message({1.0, 6.0}),
            "output.times[1] = 6 must be within [time.start, time.end] = [0, 5]");
  EXPECT_EQ(message({2.0, 1.0}),
            "output.times[1] = 1 is smaller than output.times[0] = 2: the times must be "
            "ascending");
  EXPECT_NE(message({std::nan("")}).find("output.times[0] = nan"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Events on x'' + 2ζω x' + ω² x = 0, x(0) = 1, v(0) = 0 (M = 1, R = 2ζω, 2α = 1):
// x(t) = e^{−ζωt}(cos ω_d t + (ζω/ω_d) sin ω_d t), ω_d = ω√(1 − ζ²). Its zeros are
// t_j = (jπ − atan(ω_d/(ζω)))/ω_d, j = 1, 2, …, falling for odd j, rising for even j.
constexpr double kOmega = 2.0, kZeta = 0.1, kSpan = 10.0;
const double kOmegaD = kOmega * std::sqrt(1.0 - kZeta * kZeta);
double zero_time(int j) {
  return (j * std::numbers::pi - std::atan(kOmegaD / (kZeta * kOmega))) / kOmegaD;
}

InitialValueProblem damped_oscillator(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd{{1.0}};
  p.model.damping = Eigen::MatrixXd{{2.0 * kZeta * kOmega}};
  p.model.alpha = 0.5;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd{{kOmega * kOmega}});
  p.x0 = Eigen::VectorXd{{1.0}};
  p.v0 = Eigen::VectorXd{{0.0}};
  p.t_end = kSpan;
  p.steps = steps;
  return p;
}

Event zero_of_x(EventDirection direction, bool terminal, std::string name = "zero") {
  return formula_event(std::move(name), "x1", 1, direction, terminal, "events[0].g");
}

TEST(Events, FirstZeroLocatedToTheSchemesAccuracy) {
  for (const char* scheme : {"fvi-midpoint", "fvi-lobatto3"}) {
    const Method method = *parse_method(scheme);
    std::vector<double> hs, errors;
    for (const std::size_t n : {50, 100, 200, 400, 800}) {
      IntegratorOptions o;
      o.mirror = false;
      o.events = {zero_of_x(EventDirection::kFalling, true)};
      const Solution sol = integrate(damped_oscillator(n), method, o);
      ASSERT_EQ(sol.status, Status::kEvent) << sol.message;
      ASSERT_EQ(sol.events.size(), 1u);
      // g vanishes at the located time on the interpolant (to its rounding: ‖x‖ ≤ 1).
      EXPECT_LE(std::abs(sol.events.x[0]), 8 * test::kEps) << scheme;
      hs.push_back(kSpan / static_cast<double>(n));
      errors.push_back(std::abs(sol.events.t[0] - zero_time(1)));
    }
    const test::OrderFit fit = test::fit_order(hs, errors, {.floor = test::round_off_floor(1.0)});
    const int expected = std::string(scheme) == "fvi-midpoint" ? 2 : 4;
    std::printf("  %s: first zero at t = %.15f, error %.2e at N = 800, order %.3f\n", scheme,
                zero_time(1), errors.back(), fit.slope);
    EXPECT_GE(fit.slope, expected - kOrderSlack) << fit.table(scheme);
  }
}

TEST(Events, DirectionFilterAndNonTerminalRecords) {
  const std::size_t n = 400;
  IntegratorOptions o;
  o.mirror = false;
  o.events = {zero_of_x(EventDirection::kBoth, false, "both"),
              zero_of_x(EventDirection::kRising, false, "rising"),
              zero_of_x(EventDirection::kFalling, false, "falling")};
  const Solution sol = integrate(damped_oscillator(n), *parse_method("fvi-lobatto3"), o);
  ASSERT_TRUE(sol.ok()) << sol.message;
  std::vector<int> zeros;  // j with t_j in (0, T]
  for (int j = 1; zero_time(j) <= kSpan; ++j) zeros.push_back(j);
  std::vector<std::size_t> count(3, 0);
  double previous = 0.0;
  for (std::size_t i = 0; i < sol.events.size(); ++i) {
    const std::size_t e = sol.events.event[i];
    EXPECT_GE(sol.events.t[i], previous);  // in time order
    previous = sol.events.t[i];
    // Which zero: the nearest closed-form one, rising for even j.
    const int j =
        static_cast<int>(std::lround(sol.events.t[i] * kOmegaD / std::numbers::pi +
                                     std::atan(kOmegaD / (kZeta * kOmega)) / std::numbers::pi));
    EXPECT_NEAR(sol.events.t[i], zero_time(j), 1e-6);
    EXPECT_EQ(sol.events.direction[i], j % 2 == 0 ? 1 : -1);
    if (e == 1) {
      EXPECT_EQ(j % 2, 0);
    }
    if (e == 2) {
      EXPECT_EQ(j % 2, 1);
    }
    ++count[e];
  }
  const auto rising = static_cast<std::size_t>(
      std::count_if(zeros.begin(), zeros.end(), [](int j) { return j % 2 == 0; }));
  EXPECT_EQ(count[0], zeros.size());
  EXPECT_EQ(count[1], rising);
  EXPECT_EQ(count[2], zeros.size() - rising);
  EXPECT_EQ(sol.events.names, (std::vector<std::string>{"both", "rising", "falling"}));
}

TEST(Events, TerminalEventStopsTheRunAndKeepsEverything) {
  const std::size_t n = 400;
  const double h = kSpan / static_cast<double>(n);
  IntegratorOptions o;
  o.save_every = 10;
  o.output_times = {0.1, zero_time(1) - 0.05, zero_time(2) - 0.01, zero_time(2) + 0.01, 9.0};
  o.events = {zero_of_x(EventDirection::kFalling, false, "down"),
              zero_of_x(EventDirection::kRising, true, "up")};
  const Solution sol = integrate(damped_oscillator(n), *parse_method("fvi-lobatto3"), o);
  ASSERT_EQ(sol.status, Status::kEvent);
  EXPECT_EQ(to_string(sol.status), "event");
  ASSERT_EQ(sol.events.size(), 2u);
  EXPECT_EQ(sol.events.names[sol.events.event[1]], "up");
  const double t_stop = sol.events.t[1];
  EXPECT_NEAR(t_stop, zero_time(2), 1e-6);
  // The last row is the step in which the event was found.
  const std::size_t k = sol.events.step[1];
  EXPECT_EQ(sol.steps_done, k);
  EXPECT_EQ(sol.step.back(), k);
  EXPECT_GE(sol.t[sol.t.size() - 1], t_stop);
  EXPECT_LT(sol.t[sol.t.size() - 1] - h, t_stop);
  // The output times up to the event, not after it.
  EXPECT_EQ(sol.output_t.size(), 3);
  EXPECT_NE(sol.message.find("terminal event \"up\""), std::string::npos) << sol.message;
  EXPECT_TRUE(std::isnan(sol.mirror_error));
}

TEST(Events, FailuresOfGEndTheRunWithTheTrajectory) {
  const auto run = [](EventFunction g) {
    IntegratorOptions o;
    o.events = {Event{"probe", std::move(g), EventDirection::kBoth, false}};
    return integrate(damped_oscillator(100), fvi_gl(), o);
  };
  const Solution nan =
      run([](double t, const auto&, const auto&) { return t > 1.0 ? std::nan("") : 1.0; });
  EXPECT_EQ(nan.status, Status::kNonFinite);
  EXPECT_NE(nan.message.find("events[0] (\"probe\"): g = nan"), std::string::npos) << nan.message;
  EXPECT_NE(nan.message.find("must return a finite number"), std::string::npos) << nan.message;
  EXPECT_EQ(nan.steps_done, 11u);  // t_11 = 1.1 is the first grid time past 1
  EXPECT_EQ(nan.x.rows(), 12);

  const Solution threw = run([](double t, const auto&, const auto&) -> double {
    if (t > 2.0) throw std::runtime_error("sensor offline");
    return 1.0;
  });
  EXPECT_EQ(threw.status, Status::kCallbackError);
  EXPECT_NE(threw.message.find("events[0] (\"probe\") threw in step 21"), std::string::npos)
      << threw.message;
  EXPECT_NE(threw.message.find("sensor offline"), std::string::npos) << threw.message;

  // NaN at t_0 is bad input, found before step 1.
  IntegratorOptions o;
  o.events = {Event{"probe", [](double, const auto&, const auto&) { return std::nan(""); }}};
  EXPECT_THROW(
      {
        try {
          Integrator integ(damped_oscillator(10), fvi_gl(), o);
        } catch (const ValidationError& e) {
          EXPECT_EQ(std::string(e.what()),
                    "events[0] (\"probe\"): g(t_0, x_0, v_0) = nan at t_0 = 0: must be a finite "
                    "number");
          throw;
        }
      },
      ValidationError);
}

TEST(Events, BadDefinitionsAreRefused) {
  EXPECT_THROW(
      {
        try {
          formula_event("impact", "x1 + y", 1, EventDirection::kBoth, false, "events[0].g");
        } catch (const ValidationError& e) {
          const std::string what = e.what();
          EXPECT_NE(what.find("events[0].g = \"x1 + y\""), std::string::npos) << what;
          EXPECT_NE(what.find("unknown variable 'y'"), std::string::npos) << what;
          throw;
        }
      },
      ValidationError);
  IntegratorOptions o;
  o.events = {zero_of_x(EventDirection::kBoth, false, "a"),
              zero_of_x(EventDirection::kBoth, false, "a")};
  EXPECT_THROW(Integrator(damped_oscillator(10), fvi_gl(), o), ValidationError);
  o.events = {zero_of_x(EventDirection::kBoth, false, "")};
  EXPECT_THROW(Integrator(damped_oscillator(10), fvi_gl(), o), ValidationError);
}

}  // namespace
}  // namespace fracvi
