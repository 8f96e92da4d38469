#include "fracvi/integrate/integrator.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "fracvi/core/error.hpp"

namespace fracvi {

void validate(const IntegratorOptions& options) {
  validate(options.newton, "options.newton");
  if (options.history != HistoryKind::kAuto && options.history != HistoryKind::kDirect &&
      options.history != HistoryKind::kFast) {
    throw ValidationError("options.history has an unknown value");
  }
  if (!(options.history_tolerance >= kMinHistoryTolerance &&
        options.history_tolerance <= kMaxHistoryTolerance)) {
    throw ValidationError(
        "options.history_tolerance = " + format_number(options.history_tolerance) +
        " must be in [" + format_number(kMinHistoryTolerance) + ", " +
        format_number(kMaxHistoryTolerance) +
        "] (per-weight relative accuracy of the fast history)");
  }
  if (options.save_every < 1) {
    throw ValidationError("options.save_every = 0 must be >= 1 (store every n-th step)");
  }
  if (options.threads < 0) {
    throw ValidationError("options.threads = " + std::to_string(options.threads) +
                          " must be >= 0 (0 = all cores)");
  }
  if (!parse_linear_solver(to_string(options.linear_solver))) {
    throw ValidationError("options.linear_solver has an unknown value");
  }
  if (options.start != StartValue::kDiscreteLegendre &&
      options.start != StartValue::kExplicitEuler) {
    throw ValidationError("options.start has an unknown value");
  }
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

InitialValueProblem validated(InitialValueProblem problem, const Method& method,
                              const IntegratorOptions& options) {
  validate(problem);
  validate(options);
  check_applicable(problem, method, options);
  return problem;
}

// Stored rows for N steps every s steps: 0, s, 2s, …, and N.
std::size_t stored_rows(std::size_t n_steps, std::size_t every) {
  return n_steps / every + 1 + (n_steps % every != 0 ? 1 : 0);
}

}  // namespace

struct Integrator::Impl {
  InitialValueProblem problem;  // the stepper refers to it: Impl never moves (held by pointer)
  Method method;
  IntegratorOptions options;
  Eigen::Index d;
  std::size_t n_steps;
  double h;
  std::unique_ptr<Stepper> stepper;

  Solution sol;
  std::size_t k = 0;
  std::size_t saved = 0;  // rows of sol filled
  Status status = Status::kRunning;
  double e0 = 0.0;
  double energy_k = 0.0, work_k = 0.0, balance_k = 0.0;  // at step k

  std::array<char, 480> message{};
  std::chrono::steady_clock::time_point clock_start;
  bool clock_running = false;
  double run_seconds = 0.0;

  Impl(InitialValueProblem prob, Method meth, IntegratorOptions opts)
      : problem(std::move(prob)),
        method(meth),
        options(opts),
        d(problem.model.dimension()),
        n_steps(problem.steps),
        h(problem.step_size()),
        stepper(method.info().make_stepper(problem, options)) {
    const auto rows = static_cast<Eigen::Index>(stored_rows(n_steps, options.save_every));
    sol.t = Eigen::VectorXd::Constant(rows, kNaN);
    sol.step.assign(static_cast<std::size_t>(rows), 0);
    sol.x = RowMatrixXd::Constant(rows, d, kNaN);
    sol.v = RowMatrixXd::Constant(rows, d, kNaN);
    sol.energy = Eigen::VectorXd::Constant(rows, kNaN);
    sol.dissipated = Eigen::VectorXd::Constant(rows, kNaN);
    sol.balance = Eigen::VectorXd::Constant(rows, kNaN);
    sol.method = std::string(method.name());
    sol.declared_order = method.declared_order(problem.model);
    sol.save_every = options.save_every;
    sol.linear_solver = std::string(to_string(stepper->linear_solver()));
    sol.history_bytes = stepper->history_bytes();
    if (options.diagnostics) {
      e0 = energy(0);
      energy_k = e0;
      work_k = stepper->work();
      balance_k = 0.0;
    } else {
      energy_k = work_k = balance_k = kNaN;
      sol.max_balance_error = kNaN;
    }
    store();
  }

  // E_k = ½ v_kᵀ p_k + U(x_k, t_k) from the stepper's state.
  [[nodiscard]] double energy(std::size_t i) const {
    const double kinetic = 0.5 * stepper->velocity().dot(stepper->momentum());
    return problem.model.potential
               ? kinetic + problem.model.potential->value(stepper->position(), time(i))
               : kinetic + 0.0;
  }

  Eigen::Map<Eigen::VectorXd> row(RowMatrixXd& m, std::size_t i) {
    return {m.row(static_cast<Eigen::Index>(i)).data(), d};
  }
  // t_i = t0 + i h, the same expression as InitialValueProblem::time() (h is its step_size()).
  [[nodiscard]] double time(std::size_t i) const { return problem.t0 + static_cast<double>(i) * h; }

  // Copies the state at step k into the next stored row (steps 0, s, 2s, … and the last one).
  void store() {
    const auto i = static_cast<Eigen::Index>(saved);
    sol.t(i) = time(k);
    sol.step[saved] = k;
    row(sol.x, saved) = stepper->position();
    row(sol.v, saved) = stepper->velocity();
    sol.energy(i) = energy_k;
    sol.dissipated(i) = work_k;
    sol.balance(i) = balance_k;
    ++saved;
  }
  [[nodiscard]] bool stored(std::size_t step) const {
    return saved > 0 && sol.step[saved - 1] == step;
  }

  Status fail(Status s, const char* what, const char* detail = nullptr) noexcept {
    status = s;
    stop_clock();
    // The last completed step is part of the trajectory so far even between stored rows.
    if (!stored(k)) store();
    const bool has_detail = detail != nullptr && detail[0] != '\0';
    std::snprintf(message.data(), message.size(),
                  "%s at step %zu (computing x_%zu at t = %.17g)%s%s", what, k + 1, k + 1,
                  time(k + 1), has_detail ? ": " : "", has_detail ? detail : "");
    return status;
  }

  void stop_clock() noexcept {
    if (clock_running) {
      run_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
      clock_running = false;
    }
  }

  Status step() noexcept {
    if (status != Status::kRunning) return status;
    if (!clock_running) {
      clock_start = std::chrono::steady_clock::now();
      clock_running = true;
    }
    const Status s = stepper->step();
    const auto iterations = static_cast<std::size_t>(stepper->last_iterations());
    sol.newton_iterations += iterations;
    sol.max_newton_iterations_per_step = std::max(sol.max_newton_iterations_per_step, iterations);
    if (s != Status::kSuccess) {
      return fail(s, stepper->failure_message(), stepper->failure_detail());
    }
    ++k;
    if (options.diagnostics) {
      // Step k is computed; if its diagnostics fail, the run ends with it as the last row.
      Status bad = Status::kSuccess;
      std::array<char, 200> detail;  // written only on failure (no per-step clearing)
      detail[0] = '\0';
      try {
        energy_k = energy(k);
        work_k = stepper->work();
        balance_k = energy_k + work_k - e0;
        if (!std::isfinite(energy_k) || !std::isfinite(work_k)) bad = Status::kNonFinite;
      } catch (const std::exception& e) {
        bad = Status::kCallbackError;
        std::snprintf(detail.data(), detail.size(), ": %s", e.what());
      } catch (...) {
        bad = Status::kCallbackError;
      }
      if (bad != Status::kSuccess) {
        status = bad;
        stop_clock();
        sol.steps_done = k;
        if (!stored(k)) store();
        std::snprintf(message.data(), message.size(), "%s at step %zu (t = %.17g)%s",
                      bad == Status::kNonFinite ? "non-finite energy or dissipated work"
                                                : "the potential threw while computing the energy",
                      k, time(k), detail.data());
        return status;
      }
      sol.max_balance_error = std::max(sol.max_balance_error, std::abs(balance_k));
    }
    sol.steps_done = k;
    if (k % options.save_every == 0 || k == n_steps) store();
    if (k == n_steps) {
      status = Status::kSuccess;
      stop_clock();
    }
    return status;
  }
};

Integrator::Integrator(InitialValueProblem problem, Method method, IntegratorOptions options)
    : impl_(std::make_unique<Impl>(validated(std::move(problem), method, options), method,
                                   options)) {}

Integrator::~Integrator() = default;
Integrator::Integrator(Integrator&&) noexcept = default;
Integrator& Integrator::operator=(Integrator&&) noexcept = default;

Status Integrator::step() noexcept {
  return impl_->step();
}
Status Integrator::status() const {
  return impl_->status;
}
std::size_t Integrator::steps_done() const {
  return impl_->k;
}
std::size_t Integrator::steps_total() const {
  return impl_->n_steps;
}
double Integrator::time() const {
  return impl_->time(impl_->k);
}

Eigen::Map<const Eigen::VectorXd> Integrator::position() const {
  return {impl_->stepper->position().data(), impl_->d};
}
Eigen::Map<const Eigen::VectorXd> Integrator::velocity() const {
  return {impl_->stepper->velocity().data(), impl_->d};
}

StepView Integrator::view() const {
  return StepView{impl_->k,        time(),        position(),      velocity(),
                  impl_->energy_k, impl_->work_k, impl_->balance_k};
}

LinearSolver Integrator::linear_solver() const {
  return impl_->stepper->linear_solver();
}

const InitialValueProblem& Integrator::problem() const {
  return impl_->problem;
}
const Method& Integrator::method() const {
  return impl_->method;
}
const IntegratorOptions& Integrator::options() const {
  return impl_->options;
}
const Solution& Integrator::solution() const {
  return impl_->sol;
}

double Integrator::mirror_error() const {
  if (impl_->status != Status::kSuccess) return kNaN;
  return impl_->stepper->mirror_error(
      impl_->sol.x, std::span<const std::size_t>(impl_->sol.step.data(), impl_->saved));
}

Solution Integrator::take_solution() {
  Impl& im = *impl_;
  im.stop_clock();
  double seconds = im.run_seconds;
  if (im.options.mirror && im.status == Status::kSuccess) {
    const auto start = std::chrono::steady_clock::now();
    im.sol.mirror_error = mirror_error();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  if (!im.stored(im.k)) im.store();  // stopped by the caller between stored rows
  Solution s = std::move(im.sol);
  s.status = im.status;
  s.steps_done = im.k;
  s.message = im.status == Status::kSuccess || im.status == Status::kRunning
                  ? std::string()
                  : std::string(im.message.data());
  if (im.status == Status::kRunning) {
    s.message = "stopped by the caller after " + std::to_string(im.k) + " of " +
                std::to_string(im.n_steps) + " steps";
  }
  const auto rows = static_cast<Eigen::Index>(im.saved);
  s.step.resize(im.saved);
  s.t.conservativeResize(rows);
  s.x.conservativeResize(rows, Eigen::NoChange);
  s.v.conservativeResize(rows, Eigen::NoChange);
  s.energy.conservativeResize(rows);
  s.dissipated.conservativeResize(rows);
  s.balance.conservativeResize(rows);
  s.wall_time_seconds = seconds;
  impl_.reset();
  return s;
}

Solution integrate(const InitialValueProblem& problem, const Method& method,
                   const IntegratorOptions& options) {
  Integrator integrator(problem, method, options);
  integrator.run();
  return integrator.take_solution();
}

}  // namespace fracvi
