// Cost of one step of the paper's scheme against two classical steps on the same nonlinear
// problem (a chain of d coupled pendula, M tridiagonal but stored dense, R = 0.1 M, forced):
//
//   BM_FviStep/d/diag   one Integrator::step() of fvi-gl, α = 1/2 (Lemma 5.3; includes the
//                       velocity; diag = 1 adds energy and dissipated-work bookkeeping)
//   BM_MidpointStep     implicit midpoint with the damping at the midpoint, solved by the very
//                       same Newton (internal::MidpointNewton with A = M + (h/2)R)
//   BM_VerletStep       explicit Störmer–Verlet (velocity form), damping explicit, M⁻¹ by a
//                       prefactored Cholesky
//   BM_FractionalRun    a whole α = 0.75 run (DirectHistory) as N grows: O(N²)
//
// Ratios are what matters (STYLE.md: absolute times on a shared VM are noise); run with
// --benchmark_repetitions=5 --benchmark_report_aggregates_only=true for stable medians.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>

#include "fracvi/integrate/integrator.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/solve/midpoint_newton.hpp"

namespace {

using fracvi::Potential;

// Σ g (1 − cos x_i) + ½ k Σ (x_{i+1} − x_i)², allocation-free.
class PendulumChain final : public Potential {
 public:
  PendulumChain(Eigen::Index d, double g, double k) : d_(d), g_(g), k_(k) {}
  [[nodiscard]] Eigen::Index dimension() const override { return d_; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double) const override {
    double u = 0.0;
    for (Eigen::Index i = 0; i < d_; ++i) u += g_ * (1.0 - std::cos(x(i)));
    for (Eigen::Index i = 0; i + 1 < d_; ++i) u += 0.5 * k_ * (x(i + 1) - x(i)) * (x(i + 1) - x(i));
    return u;
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    for (Eigen::Index i = 0; i < d_; ++i) g(i) = g_ * std::sin(x(i));
    for (Eigen::Index i = 0; i + 1 < d_; ++i) {
      const double s = k_ * (x(i + 1) - x(i));
      g(i + 1) += s;
      g(i) -= s;
    }
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    H.setZero();
    for (Eigen::Index i = 0; i < d_; ++i) H(i, i) = g_ * std::cos(x(i));
    for (Eigen::Index i = 0; i + 1 < d_; ++i) {
      H(i, i) += k_;
      H(i + 1, i + 1) += k_;
      H(i, i + 1) -= k_;
      H(i + 1, i) -= k_;
    }
  }
  [[nodiscard]] bool is_time_dependent() const override { return false; }

 private:
  Eigen::Index d_;
  double g_, k_;
};

constexpr double kH = 1e-3;

fracvi::InitialValueProblem chain_problem(Eigen::Index d, double alpha, std::size_t steps) {
  fracvi::InitialValueProblem p;
  Eigen::MatrixXd mass = Eigen::MatrixXd::Identity(d, d);
  if (d > 1) {
    mass.diagonal(1).setConstant(0.2);
    mass.diagonal(-1).setConstant(0.2);
  }
  p.model.mass = mass;
  p.model.damping = 0.1 * mass;
  p.model.alpha = alpha;
  p.model.potential = std::make_shared<const PendulumChain>(d, 9.81, 3.0);
  p.model.forcing = [](double t, Eigen::Ref<Eigen::VectorXd> f) {
    f.setZero();
    f(0) = 0.3 * std::sin(2.0 * t);
  };
  p.x0 = Eigen::VectorXd::LinSpaced(d, -1.0, 1.0);
  p.v0 = Eigen::VectorXd::Constant(d, 0.1);
  p.t0 = 0.0;
  p.steps = steps;
  p.t_end = kH * static_cast<double>(steps);
  return p;
}

fracvi::IntegratorOptions no_mirror() {
  fracvi::IntegratorOptions o;
  o.mirror = false;
  return o;
}

// range(0) = d, range(1) = 1 with per-step energy diagnostics, 0 without.
void BM_FviStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const std::size_t n = d == 1 ? 200000 : 2000;
  const fracvi::InitialValueProblem p = chain_problem(d, 0.5, n);
  fracvi::IntegratorOptions opts = no_mirror();
  opts.diagnostics = state.range(1) != 0;
  auto integ = std::make_unique<fracvi::Integrator>(p, fracvi::fvi_gl(), opts);
  std::size_t newton = 0, steps = 0;
  for (auto _ : state) {
    if (integ->step() != fracvi::Status::kRunning) {
      state.PauseTiming();
      newton += integ->solution().newton_iterations;
      steps += integ->steps_done();
      integ = std::make_unique<fracvi::Integrator>(p, fracvi::fvi_gl(), opts);
      state.ResumeTiming();
    }
  }
  newton += integ->solution().newton_iterations;
  steps += integ->steps_done();
  state.counters["newton_per_step"] = static_cast<double>(newton) / static_cast<double>(steps);
}

// Implicit midpoint: x_{k+1} = x_k + Δ, v_{k+1} = 2Δ/h − v_k, with
// (M + (h/2)R) Δ + (h²/2) [∇U(x_k + Δ/2) − f(t_{k+½})] = h M v_k. Trajectory stored like the
// Integrator does (row-major, preallocated).
void BM_MidpointStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const std::size_t n = d == 1 ? 200000 : 2000;
  const fracvi::InitialValueProblem p = chain_problem(d, 0.5, n);
  const fracvi::ModelMatrix A = linear_combination(p.model.mass, 0.5 * kH, p.model.damping);
  fracvi::internal::MidpointNewton newton(A, kH, p.model.potential.get(), fracvi::NewtonOptions{});
  fracvi::RowMatrixXd xs(static_cast<Eigen::Index>(n + 1), d),
      vs(static_cast<Eigen::Index>(n + 1), d);
  Eigen::VectorXd c(d), delta(d), f(d);
  std::size_t k = 0, iterations = 0, steps = 0;
  xs.row(0) = p.x0.transpose();
  vs.row(0) = p.v0.transpose();
  delta = kH * p.v0;
  for (auto _ : state) {
    if (k == n) {
      k = 0;
      delta = kH * p.v0;
    }
    const Eigen::Map<const Eigen::VectorXd> x(xs.row(static_cast<Eigen::Index>(k)).data(), d);
    const Eigen::Map<const Eigen::VectorXd> v(vs.row(static_cast<Eigen::Index>(k)).data(), d);
    const double t_half = p.t0 + (static_cast<double>(k) + 0.5) * kH;
    p.model.forcing(t_half, f);
    p.model.mass.multiply(v, c);
    c *= kH;
    const auto report = newton.solve(x, t_half, c, &f, delta);
    iterations += static_cast<std::size_t>(report.iterations);
    ++steps;
    Eigen::Map<Eigen::VectorXd>(xs.row(static_cast<Eigen::Index>(k + 1)).data(), d) = x + delta;
    Eigen::Map<Eigen::VectorXd>(vs.row(static_cast<Eigen::Index>(k + 1)).data(), d) =
        (2.0 / kH) * delta - v;
    ++k;
    benchmark::DoNotOptimize(xs.data());
  }
  state.counters["newton_per_step"] = static_cast<double>(iterations) / static_cast<double>(steps);
}

// Velocity Verlet with explicit damping: a(x, v) = M⁻¹(f − ∇U(x) − R v).
void BM_VerletStep(benchmark::State& state) {
  const auto d = static_cast<Eigen::Index>(state.range(0));
  const std::size_t n = d == 1 ? 200000 : 2000;
  const fracvi::InitialValueProblem p = chain_problem(d, 0.5, n);
  const Eigen::LLT<Eigen::MatrixXd> llt(p.model.mass.dense());
  const Eigen::MatrixXd& damping = p.model.damping.dense();
  fracvi::RowMatrixXd xs(static_cast<Eigen::Index>(n + 1), d),
      vs(static_cast<Eigen::Index>(n + 1), d);
  Eigen::VectorXd g(d), f(d), force(d), acc(d), v_half(d);
  std::size_t k = 0;
  xs.row(0) = p.x0.transpose();
  vs.row(0) = p.v0.transpose();
  auto acceleration = [&](const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v, double t) {
    p.model.potential->gradient(x, t, g);
    p.model.forcing(t, f);
    force = f - g;
    force.noalias() -= damping * v;
    acc = llt.solve(force);
  };
  acceleration(p.x0, p.v0, p.t0);
  for (auto _ : state) {
    if (k == n) {
      k = 0;
      acceleration(p.x0, p.v0, p.t0);
    }
    const Eigen::Map<const Eigen::VectorXd> x(xs.row(static_cast<Eigen::Index>(k)).data(), d);
    const Eigen::Map<const Eigen::VectorXd> v(vs.row(static_cast<Eigen::Index>(k)).data(), d);
    Eigen::Map<Eigen::VectorXd> x1(xs.row(static_cast<Eigen::Index>(k + 1)).data(), d);
    Eigen::Map<Eigen::VectorXd> v1(vs.row(static_cast<Eigen::Index>(k + 1)).data(), d);
    v_half = v + (0.5 * kH) * acc;
    x1 = x + kH * v_half;
    acceleration(x1, v_half, p.t0 + static_cast<double>(k + 1) * kH);
    v1 = v_half + (0.5 * kH) * acc;
    ++k;
    benchmark::DoNotOptimize(xs.data());
  }
}

// A whole general-α run (direct history): the memory sum makes the cost O(N²·d).
void BM_FractionalRun(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const fracvi::InitialValueProblem p = chain_problem(1, 0.75, n);
  for (auto _ : state) {
    fracvi::Integrator integ(p, fracvi::fvi_gl(), no_mirror());
    benchmark::DoNotOptimize(integ.run());
  }
  state.SetComplexityN(static_cast<benchmark::IterationCount>(n));
}

BENCHMARK(BM_FviStep)->Args({1, 1})->Args({1, 0})->Args({100, 1})->Args({100, 0});
BENCHMARK(BM_MidpointStep)->Arg(1)->Arg(100);
BENCHMARK(BM_VerletStep)->Arg(1)->Arg(100);
BENCHMARK(BM_FractionalRun)
    ->RangeMultiplier(2)
    ->Range(1000, 16000)
    ->Unit(benchmark::kMillisecond)
    ->Complexity(benchmark::oNSquared);

}  // namespace

BENCHMARK_MAIN();
