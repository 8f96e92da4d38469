// Published numbers of the higher-order FVIs, reproduced digit for digit (issue: "Reproduce the
// published numbers"; the tables are in docs/verification.md).
//
// fvi-midpoint: x'' + 0.25 x' + x = 0, x(0) = 1, x'(0) = 0.5 on [0, 16], h = 16/N, error = max over
// the grid nodes of |x_k − x(t_k)| against the closed form
//   x(t) = e^{−t/8} (cos ωt + (0.5 + 1/8)/ω sin ωt),  ω = √(1 − 1/64);
// published (Hariz, Jiménez, Ober-Blöbaum; the RKCQ paper's public data): 2.5317e-1 at N = 16 and
// 1.7690e-5 at N = 2048, order 2. The comparison is of the five printed digits.
//
// fvi-lobatto2/3/4 (arXiv 2510.11082 and its public data, github.com/khaledharizb/RKCQ, files
// errors/q_err_{2,3,4}stage.dat; docs/theory/fvi_lobatto.md §7):
//  * q'' + 0.25 q' + 0.5 q = 0, q(0) = (0.8, −0.5), q'(0) = (0.4, 0) on [0, 30], h = 30/N, max over
//    nodes and components against the closed form: s = 2: 3.7828e-2 (N = 32), 2.2871e-3 (128);
//    s = 3: 3.0588e-4, 1.1582e-6; s = 4: 3.8855e-7, 9.6690e-11. The last one is 9.6696e-11 here and
//    in the independent Python prototype (tools/prototypes/fvi_lobatto.py): 5.4e-15 apart, which
//    the published run's Newton stopping rule (nlsolve ftol = 1e-14 per step) explains; it is
//    checked to 1e-14 absolute instead of five digits.
//  * Bagley–Torvik q'' + D^{1/2} q + q = t³ + 6t + 16/(5√π) t^{5/2}, zero data, exact t³ on [0, 1],
//    pointwise forcing at the stages (the published setting): s = 2: 4.8039e-2 (N = 4), 1.1227e-5
//    (N = 256); s = 4: 5.04e-7 at N = 4 (the value of a clean implementation; the public
//    notebooks for s = 3, 4 add a padding term to the history, fvi_lobatto.md §7.2).
//
// pi-trapezoid (Garrappa's MT_FDE_PI2_IM, Garrappa 2018, the multi-term example): y'' + 0.5
// D^{3/2} y + y = 0 (Caputo), y(0) = 1, y'(0) = 0 on [0, 20], error |y_N − y(20)| with the
// published exact y(20) = −0.061964539893443569, itself checked against the Laplace inversion of
// tests/support (independent); published: about 5.8e-4 at h = 1/8 … 8.6e-9 at h = 1/2048, order
// 2.00 (two digits).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "../support/linear_oscillator_reference.hpp"
#include "../support/order_fit.hpp"
#include "../support/test_problems.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {
namespace {

std::string five_digits(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4e", value);
  return buf;
}

double midpoint_oscillator_error(std::size_t steps) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Constant(1, 1, 0.25);
  p.model.alpha = 0.5;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  p.x0 = Eigen::VectorXd::Constant(1, 1.0);
  p.v0 = Eigen::VectorXd::Constant(1, 0.5);
  p.t_end = 16.0;
  p.steps = steps;
  IntegratorOptions options;
  options.mirror = false;
  const Solution sol = integrate(p, *parse_method("fvi-midpoint"), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  const double omega = std::sqrt(1.0 - 1.0 / 64.0);
  double err = 0.0;
  for (Eigen::Index k = 0; k < sol.x.rows(); ++k) {
    const double t = sol.t(k);
    const double exact =
        std::exp(-t / 8.0) * (std::cos(omega * t) + (0.5 + 0.125) / omega * std::sin(omega * t));
    err = std::max(err, std::abs(sol.x(k, 0) - exact));
  }
  return err;
}

TEST(PublishedNumbers, MidpointFviDampedOscillator) {
  const double coarse = midpoint_oscillator_error(16);
  const double fine = midpoint_oscillator_error(2048);
  std::printf("  fvi-midpoint: %s (published 2.5317e-01) at N = 16, %s (1.7690e-05) at N = 2048\n",
              five_digits(coarse).c_str(), five_digits(fine).c_str());
  EXPECT_EQ(five_digits(coarse), "2.5317e-01");
  EXPECT_EQ(five_digits(fine), "1.7690e-05");
  // Order 2 between them: log(coarse/fine)/log(128).
  EXPECT_NEAR(std::log(coarse / fine) / std::log(128.0), 2.0, 0.05);
}

// x'' + 0.25x' + 0.5x = 0 per component: x = e^{−t/8}(x0 cos ωt + (v0 + x0/8)/ω sin ωt).
double lobatto_oscillator_error(const char* scheme, std::size_t steps) {
  const InitialValueProblem p = test::published_oscillator_2d(steps);
  IntegratorOptions options;
  options.mirror = false;
  const Solution sol = integrate(p, *parse_method(scheme), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  const double omega = std::sqrt(0.5 - 1.0 / 64.0);
  double err = 0.0;
  for (Eigen::Index k = 0; k < sol.x.rows(); ++k) {
    const double t = sol.t(k);
    for (Eigen::Index i = 0; i < 2; ++i) {
      const double exact =
          std::exp(-t / 8.0) *
          (p.x0(i) * std::cos(omega * t) + (p.v0(i) + p.x0(i) / 8.0) / omega * std::sin(omega * t));
      err = std::max(err, std::abs(sol.x(k, i) - exact));
    }
  }
  return err;
}

TEST(PublishedNumbers, LobattoFviDampedOscillator2D) {
  struct Row {
    const char* scheme;
    const char* coarse;
    const char* fine;
    double order;
  };
  for (const Row& row : {Row{"fvi-lobatto2", "3.7828e-02", "2.2871e-03", 2.0},
                         Row{"fvi-lobatto3", "3.0588e-04", "1.1582e-06", 4.0},
                         Row{"fvi-lobatto4", "3.8855e-07", "9.6690e-11", 6.0}}) {
    const double coarse = lobatto_oscillator_error(row.scheme, 32);
    const double fine = lobatto_oscillator_error(row.scheme, 128);
    std::printf("  %s: %.10e (published %s) at h = 0.9375, %.10e (%s) at h = 0.234375\n",
                row.scheme, coarse, row.coarse, fine, row.fine);
    EXPECT_EQ(five_digits(coarse), row.coarse) << row.scheme;
    if (std::string(row.scheme) == "fvi-lobatto4") {
      EXPECT_NEAR(fine, 9.6690e-11, 1e-14) << row.scheme;
    } else {
      EXPECT_EQ(five_digits(fine), row.fine) << row.scheme;
    }
    EXPECT_NEAR(std::log(coarse / fine) / std::log(4.0), row.order, 0.1) << row.scheme;
  }
}

// The forcing's quadrature caps the published orders (fvi_lobatto.md §7.3): with
// method.load = "moments" (exact Galerkin moments of f, tanh–sinh on the first interval) the two
// Bagley–Torvik problems reach, measured here and in the independent prototype: t³ with D^{1/2}:
// s = 3 order 4 (3.45 pointwise), s = 4 4.5 (3.5); t^{5/2} with D^{3/2}: s = 2 1.94 (1.57),
// s = 3 and 4 order 3 (1.5). What is left (4.5, 3) is the RKCQ on the non-smooth solution near
// t_0, not the forcing.
struct BagleyTorvik {
  double alpha;
  double (*force)(double);
  double (*exact)(double);
};

double bagley_torvik_load_error(const BagleyTorvik& bt, const char* scheme, std::size_t steps,
                                ForcingLoad load) {
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Identity(1, 1);
  p.model.alpha = bt.alpha;
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  const auto force = bt.force;
  p.model.forcing = [force](double t, Eigen::Ref<Eigen::VectorXd> out) { out(0) = force(t); };
  p.x0 = Eigen::VectorXd::Zero(1);
  p.v0 = Eigen::VectorXd::Zero(1);
  p.t_end = 1.0;
  p.steps = steps;
  IntegratorOptions options;
  options.mirror = false;
  options.load = load;
  const Solution sol = integrate(p, *parse_method(scheme), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  double err = 0.0;
  for (Eigen::Index k = 0; k < sol.x.rows(); ++k)
    err = std::max(err, std::abs(sol.x(k, 0) - bt.exact(sol.t(k))));
  return err;
}

// The published Bagley–Torvik problem with D^{1/2}, exact q = t³ (pointwise forcing).
const BagleyTorvik kCubic{0.25,
                          [](double t) {
                            return t * t * t + 6.0 * t +
                                   16.0 / (5.0 * std::sqrt(M_PI)) * std::pow(t, 2.5);
                          },
                          [](double t) { return t * t * t; }};

double bagley_torvik_error(const char* scheme, std::size_t steps) {
  return bagley_torvik_load_error(kCubic, scheme, steps, ForcingLoad::kPointwise);
}

TEST(PublishedNumbers, LobattoFviBagleyTorvik) {
  const double s2_coarse = bagley_torvik_error("fvi-lobatto2", 4);
  const double s2_fine = bagley_torvik_error("fvi-lobatto2", 256);
  const double s4_coarse = bagley_torvik_error("fvi-lobatto4", 4);
  std::printf(
      "  fvi-lobatto2: %.10e (published 4.8039e-02) at N = 4, %.10e (1.1227e-05) at "
      "N = 256; fvi-lobatto4: %.10e (5.04e-07) at N = 4\n",
      s2_coarse, s2_fine, s4_coarse);
  EXPECT_EQ(five_digits(s2_coarse), "4.8039e-02");
  EXPECT_EQ(five_digits(s2_fine), "1.1227e-05");
  char s4[32];
  std::snprintf(s4, sizeof s4, "%.2e", s4_coarse);
  EXPECT_STREQ(s4, "5.04e-07");
}

TEST(PublishedNumbers, MomentLoadLiftsTheForcingCap) {
  const BagleyTorvik root{0.75,
                          [](double t) {
                            return 3.75 * std::sqrt(t) + 15.0 * std::sqrt(M_PI) / 8.0 * t +
                                   std::pow(t, 2.5);
                          },
                          [](double t) { return std::pow(t, 2.5); }};
  struct Row {
    const BagleyTorvik* problem;
    const char* label;
    const char* scheme;
    double pointwise_below;  // the cap: the pointwise order stays below this
    double moments_at_least;
    std::vector<std::size_t> steps = {16, 32, 64, 128};
  };
  for (const Row& row :
       {Row{&kCubic, "D^1/2, t^3", "fvi-lobatto3", 3.6, 3.9},
        // s = 4 reaches the round-off floor from N = 64: coarser steps, local
        // orders 4.34, 4.46 → 4.5.
        Row{&kCubic, "D^1/2, t^3", "fvi-lobatto4", 3.6, 4.3, {8, 16, 32, 64}},
        Row{&root, "D^3/2, t^5/2", "fvi-lobatto2", 1.7, 1.85},
        Row{&root, "D^3/2, t^5/2", "fvi-lobatto3", 1.6, 2.9},
        Row{&root, "D^3/2, t^5/2", "fvi-lobatto4", 1.6, 2.9},
        // The midpoint schemes' cell average of f: the second-order schemes
        // saturated at 1.5–1.7 only through the forcing's midpoint value.
        Row{&root, "D^3/2, t^5/2", "fvi-bdf2", 1.8, 1.95, {64, 128, 256, 512}},
        Row{&root, "D^3/2, t^5/2", "fvi-midpoint", 1.6, 1.95, {64, 128, 256, 512}}}) {
    std::vector<double> hs, pointwise, moments;
    for (const std::size_t n : row.steps) {
      hs.push_back(1.0 / static_cast<double>(n));
      pointwise.push_back(
          bagley_torvik_load_error(*row.problem, row.scheme, n, ForcingLoad::kPointwise));
      moments.push_back(
          bagley_torvik_load_error(*row.problem, row.scheme, n, ForcingLoad::kMoments));
    }
    const test::OrderFit fp = test::fit_order(hs, pointwise, {.floor = test::round_off_floor(1.0)});
    const test::OrderFit fm = test::fit_order(hs, moments, {.floor = test::round_off_floor(1.0)});
    std::printf(
        "  %s, %s: order %.3f pointwise (error %.3e at the finest N), %.3f with moments (%.3e)\n",
        row.label, row.scheme, fp.slope, pointwise.back(), fm.slope, moments.back());
    EXPECT_TRUE(fp.valid && fm.valid) << fp.table() << fm.table();
    EXPECT_LT(fp.slope, row.pointwise_below) << fp.table(row.scheme);
    EXPECT_GE(fm.slope, row.moments_at_least) << fm.table(row.scheme);
  }
}

TEST(PublishedNumbers, MomentLoadIsRefusedForSchemesWithoutIt) {
  // A row without it (the baselines but lda-midpoint) is refused before step 1 with the rule and
  // the schemes that have it.
  InitialValueProblem p;
  p.model.mass = Eigen::MatrixXd::Identity(1, 1);
  p.model.damping = Eigen::MatrixXd::Zero(1, 1);
  p.model.potential = make_quadratic_potential(Eigen::MatrixXd::Identity(1, 1));
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> out) { out(0) = std::sqrt(t); };
  p.x0 = Eigen::VectorXd::Zero(1);
  p.v0 = Eigen::VectorXd::Zero(1);
  IntegratorOptions options;
  options.load = ForcingLoad::kMoments;
  SchemeInfo without = fvi_gl().info();
  without.forcing_moments = false;
  try {
    check_applicable(p, Method(without), options);
    ADD_FAILURE() << "a scheme without forcing moments accepted method.load = moments";
  } catch (const ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("method.load = \"moments\" is not available"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("fvi-lobatto3"), std::string::npos) << e.what();
  }
  // Every registered row: accepted where the row declares the moments, refused otherwise.
  for (const SchemeInfo* info : registered_schemes()) {
    if (info->forcing_moments) {
      EXPECT_NO_THROW(check_applicable(p, Method(*info), options)) << info->name;
    } else {
      EXPECT_THROW(check_applicable(p, Method(*info), options), ValidationError) << info->name;
    }
  }
}

// pi-trapezoid on Garrappa's multi-term example (file comment).
constexpr double kGarrappaExact = test::kCaputoOscillatorExact;

double garrappa_error(std::size_t steps_per_unit) {
  const InitialValueProblem p = test::caputo_oscillator(20 * steps_per_unit);
  IntegratorOptions options;
  options.mirror = false;
  options.diagnostics = false;
  options.save_every = p.steps;
  const Solution sol = integrate(p, *parse_method("pi-trapezoid"), options);
  EXPECT_TRUE(sol.ok()) << sol.message;
  return std::abs(sol.x(sol.x.rows() - 1, 0) - kGarrappaExact);
}

std::string two_digits(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1e", value);
  return buf;
}

TEST(PublishedNumbers, ProductTrapezoidMultiTermGarrappa) {
  // The published exact value against the independent Laplace inversion (validated to ~1e-14).
  const test::LaplaceInversion inversion(
      test::LinearOscillator::scalar(1.0, 0.5, 1.0, 1.5, 1.0, 0.0));
  const double laplace = inversion(20.0)[0];
  std::printf("  y(20): published %.17g, Laplace inversion %.17g\n", kGarrappaExact, laplace);
  EXPECT_NEAR(laplace, kGarrappaExact, 1e-12);

  std::vector<double> hs, errors;
  for (std::size_t n = 8; n <= 2048; n *= 2) {
    hs.push_back(1.0 / static_cast<double>(n));
    errors.push_back(garrappa_error(n));
  }
  const test::OrderFit fit = test::fit_order(hs, errors, {.floor = test::round_off_floor(1.0)});
  std::printf("%s", fit.table("pi-trapezoid, Garrappa's example, |y_N - y(20)|").c_str());
  EXPECT_EQ(two_digits(errors.front()), "5.8e-04");
  EXPECT_EQ(two_digits(errors.back()), "8.6e-09");
  EXPECT_TRUE(fit.valid);
  EXPECT_NEAR(fit.slope, 2.0, 0.05);
}

}  // namespace
}  // namespace fracvi
