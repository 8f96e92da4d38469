#include "fracvi/integrate/integrator.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <limits>
#include <mutex>
#include <span>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include <boost/math/tools/toms748_solve.hpp>

#include "fracvi/core/error.hpp"
#include "fracvi/core/memory.hpp"
#include "fracvi/integrate/dense_output.hpp"
#include "fracvi/internal/background_thread.hpp"
#include "fracvi/internal/float_environment.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/solve/vector_passes.hpp"

namespace fracvi {

void validate(const IntegratorOptions& options) {
  validate(options.newton, "options.newton");
  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance)) {
    throw ValidationError("options.tolerance = " + format_number(options.tolerance) +
                          " must be >= 0 (0: off)");
  }
  if (options.max_steps < 1) throw ValidationError("options.max_steps must be >= 1");
  if (options.history != HistoryKind::kAuto && options.history != HistoryKind::kDirect &&
      options.history != HistoryKind::kFast) {
    throw ValidationError("options.history has an unknown value");
  }
  if (options.history_tolerance != kAutoHistoryTolerance &&
      !(options.history_tolerance >= kMinHistoryTolerance &&
        options.history_tolerance <= kMaxHistoryTolerance)) {
    throw ValidationError(
        "options.history_tolerance = " + format_number(options.history_tolerance) +
        " must be 0 (auto: chosen from the run) or in [" + format_number(kMinHistoryTolerance) +
        ", " + format_number(kMaxHistoryTolerance) +
        "] (per-weight relative accuracy of the fast history)");
  }
  // Tolerances of the adaptive schemes: positive, not both zero, the relative one above round-off.
  if (!(options.abs_tolerance >= 0.0 && std::isfinite(options.abs_tolerance))) {
    throw ValidationError("options.abs_tolerance = " + format_number(options.abs_tolerance) +
                          " must be >= 0 (absolute error tolerance of the adaptive schemes)");
  }
  if (!(options.rel_tolerance >= 1e-15 && options.rel_tolerance < 1.0)) {
    throw ValidationError("options.rel_tolerance = " + format_number(options.rel_tolerance) +
                          " must be in [1e-15, 1) (relative error tolerance of the adaptive "
                          "schemes)");
  }
  if (options.save_every < 1) {
    throw ValidationError("options.save_every = 0 must be >= 1 (store every n-th step)");
  }
  if (options.threads < 0) {
    throw ValidationError("options.threads = " + std::to_string(options.threads) +
                          " must be >= 0 (0 = all cores)");
  }
  if (options.row_split_from < 1) {
    throw ValidationError("options.row_split_from = " + std::to_string(options.row_split_from) +
                          " must be >= 1 (the dimension from which a step is split by rows)");
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
constexpr const char* kKinkHint =
    "the potential has kinks in x (abs, sign, min, max, floor or heaviside of a position); where "
    "its gradient jumps, the step's implicit equation can have no solution: smooth the kink, e.g. "
    "sqrt(x^2 + d^2) for abs(x) (docs/problem-file.md)";

InitialValueProblem validated(InitialValueProblem problem, const Method& method,
                              const IntegratorOptions& options) {
  validate(problem);
  validate(options);
  validate_output(options.output_times, options.events, problem.t0, problem.t_end);
  check_storage(problem, options);
  check_applicable(problem, method, options);
  return problem;
}

IntegratorOptions with_tolerance(IntegratorOptions options, double history_tolerance) {
  options.history_tolerance = history_tolerance;
  return options;
}

// Stored rows for N steps every s steps: 0, s, 2s, …, and N.
std::size_t stored_rows(std::size_t n_steps, std::size_t every) {
  return n_steps / every + 1 + (n_steps % every != 0 ? 1 : 0);
}

// The mirror check on a second thread alongside the run (IntegratorOptions::mirror_alongside).
// The backward mirror run needs only the problem, the options and x_1 (Stepper::mirror_run), not
// the rest of the trajectory: it starts as soon as the first step is done, keeps y at the stored
// steps predicted from N and output.every, and take_solution() compares them with the stored
// rows — the same numbers as a mirror run after the run, with the run and the mirror run on two
// cores instead of one after the other. The run's interrupt hook is asked on the calling thread
// only (finish()); the mirror thread sees a flag.
class AlongsideMirror {
 public:
  // `flush_subnormals`: IntegratorOptions::flush_subnormals, for the mirror run's thread.
  AlongsideMirror(const Stepper& stepper, std::vector<std::size_t> steps, Eigen::Index d,
                  bool flush_subnormals)
      : steps_(std::move(steps)),
        rows_(steps_, static_cast<Eigen::Index>(steps_.size()), d, cancel_),
        thread_([this, &stepper, flush_subnormals] { body(stepper, flush_subnormals); }) {}
  ~AlongsideMirror() {
    cancel_.store(true, std::memory_order_relaxed);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (gate_ == Gate::kClosed) gate_ = Gate::kAbandoned;
    }
    changed_.notify_all();
    thread_.join();
  }
  AlongsideMirror(const AlongsideMirror&) = delete;
  AlongsideMirror& operator=(const AlongsideMirror&) = delete;

  // x_1 is known: the mirror run starts. Called from the step loop: no allocation.
  void open() noexcept {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (gate_ == Gate::kClosed) gate_ = Gate::kOpen;
    }
    changed_.notify_all();
  }
  [[nodiscard]] bool opened() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return gate_ == Gate::kOpen;
  }
  [[nodiscard]] const std::vector<std::size_t>& steps() const noexcept { return steps_; }

  // Waits for the mirror run (asking `interrupted` every 10 ms: true cancels it) and returns the
  // mirror error of the stored rows `x` (row i at steps()[i]), or NaN when the mirror run failed
  // or was cancelled.
  [[nodiscard]] double finish(const RowMatrixXd& x, const std::function<bool()>& interrupted) {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!done_) {
      if (changed_.wait_for(lock, std::chrono::milliseconds(10)) == std::cv_status::timeout &&
          !done_ && interrupted()) {
        cancel_.store(true, std::memory_order_relaxed);
        changed_.wait(lock, [this] { return done_; });
        return kNaN;
      }
    }
    if (!succeeded_) return kNaN;
    return rows_.error(x);
  }

 private:
  enum class Gate { kClosed, kOpen, kAbandoned };

  // y at the predicted stored steps, and which rows the mirror run reached.
  class Recorded final : public MirrorRows {
   public:
    Recorded(std::span<const std::size_t> steps, Eigen::Index rows, Eigen::Index d,
             const std::atomic<bool>& cancel)
        : MirrorRows(steps),
          y_(rows, d),
          reached_(static_cast<std::size_t>(rows), 0),
          cancel_(cancel) {}
    void put(std::size_t row, const Eigen::VectorXd& y) override {
      y_.row(static_cast<Eigen::Index>(row)) = y.transpose();
      reached_[row] = 1;
    }
    bool stop() override { return cancel_.load(std::memory_order_relaxed); }
    // MirrorComparison's maximum over the rows reached, the same differences in the same order.
    [[nodiscard]] double error(const RowMatrixXd& x) const {
      MirrorComparison comparison(x, steps(), {});
      Eigen::VectorXd y(y_.cols());
      for (std::size_t i = 0; i < reached_.size(); ++i) {
        if (reached_[i] == 0) continue;
        y = y_.row(static_cast<Eigen::Index>(i)).transpose();
        comparison.put(i, y);
      }
      return comparison.error();
    }

   private:
    RowMatrixXd y_;
    std::vector<unsigned char> reached_;
    const std::atomic<bool>& cancel_;
  };

  void body(const Stepper& stepper, bool flush_subnormals) {
    internal::lower_this_thread_priority();  // the run keeps its core (background_thread.hpp)
    const internal::SubnormalsFlushed flushed(flush_subnormals);  // as the mirror run after it
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [this] { return gate_ != Gate::kClosed; });
      if (gate_ == Gate::kAbandoned) {
        done_ = true;
        return;
      }
    }
    bool succeeded =
        false;  // mirror_run reports a throwing callback as false; a thread must not throw
    try {
      succeeded = stepper.mirror_run(rows_);
    } catch (...) {
    }
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      succeeded_ = succeeded;
      done_ = true;
    }
    changed_.notify_all();
  }

  std::vector<std::size_t> steps_;
  std::atomic<bool> cancel_{false};
  Recorded rows_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  Gate gate_ = Gate::kClosed;
  bool done_ = false, succeeded_ = false;
  std::thread thread_;  // last: starts once everything above is constructed
};

}  // namespace

std::vector<std::size_t> stored_steps(std::size_t steps_done, std::size_t save_every) {
  std::vector<std::size_t> steps;
  steps.reserve(stored_rows(steps_done, save_every));
  for (std::size_t k = 0; k < steps_done; k += save_every) steps.push_back(k);
  steps.push_back(steps_done);
  return steps;
}

void check_storage(const InitialValueProblem& problem, const IntegratorOptions& options) {
  if (options.save_every < 1) return;  // validate(options) names it
  // Per stored row (Solution): t, the step index, energy, dissipated, balance, and x, v.
  const double d = static_cast<double>(problem.model.dimension());
  const double row_bytes = 40.0 + 16.0 * d;
  const double rows = static_cast<double>(stored_rows(problem.steps, options.save_every));
  std::string advice;
  if (const std::size_t memory = physical_memory_bytes(); memory != 0) {
    // The smallest stride whose rows (about N/every + 2) take at most half of the memory.
    const double budget = 0.5 * static_cast<double>(memory) / row_bytes - 2.0;
    if (budget >= 1.0) {
      advice = "; store fewer states with [output] every = n (n >= " +
               format_number(std::ceil(static_cast<double>(problem.steps) / budget)) +
               " keeps it within half of the memory) or take fewer steps";
    } else {
      advice = "; even two stored states do not fit: reduce model.dim";
    }
  }
  check_fits_in_memory(rows * row_bytes,
                       "time.steps = " + std::to_string(problem.steps) +
                           " with output.every = " + std::to_string(options.save_every) +
                           ": the stored trajectory (" + format_number(rows) + " states of " +
                           format_number(d) + " positions and velocities)",
                       advice);
}

struct Integrator::Impl {
  InitialValueProblem problem;  // the stepper refers to it: Impl never moves (held by pointer)
  Method method;
  HistoryBudget budget;       // the fast history's ε (history_budget.hpp)
  IntegratorOptions options;  // as given, with history_tolerance = budget.tolerance
  Eigen::Index d;
  std::size_t n_steps;
  double h;
  std::unique_ptr<Stepper> stepper;
  // The mirror check alongside the run, or null (IntegratorOptions::mirror_alongside); declared
  // after the stepper, which its thread reads, so that it is joined first.
  std::unique_ptr<AlongsideMirror> alongside;

  Solution sol;
  std::size_t k = 0;
  std::size_t saved = 0;  // rows of sol filled
  Status status = Status::kRunning;
  double e0 = 0.0;
  double energy_k = 0.0, work_k = 0.0, balance_k = 0.0;  // at step k
  double kinetic_k = 0.0, potential_k = 0.0;             // K_k, U_k (energy_k = K_k + U_k)

  // Health checks (integrator.hpp): the quantities of the three rules.
  double span;                    // T = t_end − t_0
  Eigen::VectorXd m_times_x;      // workspace (set-up only)
  Eigen::VectorXd mass_weights;   // √M_ii: ‖x‖_M = ‖√diag(M) x‖ (integrator.hpp)
  double state_base = 0.0;        // ‖x_0‖_M + T‖v_0‖_M
  double energy_floor = 0.0;      // max(|E_0|, K_0 + |U_0|, S_R)
  double max_supplied = 0.0;      // max_j |P_j|
  double max_activity = 0.0;      // max_j (K_j + |U_j|)
  double energy_scale = 0.0;      // S_k
  double running_max = 0.0;       // max_{j≤k} ‖x_j‖_M
  double checkpoint_max = 0.0;    // max_{j≤J'} ‖x_j‖_M at the last power of two J'
  double growth_reference = 0.0;  // max_{j≤J} ‖x_j‖_M, J the power of two before J'
  std::size_t next_checkpoint = 1;
  bool supplied_known = false;      // P_k is available (tracked, or 0 by construction)
  bool memory_is_a_source = false;  // RL memory of x(0): rule 1 off (init_health)
  double max_abs_work = 0.0;        // max_j |W_j| (in S_k when P_j is not known)
  double tolerance_scale = 0.0;     // S̃_k
  double max_abs_balance = 0.0;     // max_j |E_j + W_j − E_0| and its step (rule 3)
  std::size_t max_balance_step = 0;

  // Dense output and events (dense_output.hpp): the state before the step, the interpolant's
  // workspace, the next output time, g of every event at the step's start, and the crossings of
  // one step (event, s), sorted by s. All sized in the constructor.
  bool dense = false;
  Eigen::VectorXd x_before, v_before, x_dense, v_dense;
  std::size_t next_output = 0;
  std::vector<double> g_before, g_after;
  std::vector<std::pair<double, std::size_t>> crossings;

  // The run's message: up to 480 characters of its own around a callback's detail.
  using MessageBuffer = std::array<char, kFailureDetailCapacity + 480>;
  MessageBuffer message{};
  std::chrono::steady_clock::time_point clock_start;
  bool clock_running = false;
  double run_seconds = 0.0;

  Impl(InitialValueProblem prob, Method meth, IntegratorOptions opts)
      : problem(std::move(prob)),
        method(meth),
        budget(history_budget(problem, method.declared_order(problem.model), opts.history_tolerance,
                              method.info().history_budget_ceiling)),
        options(with_tolerance(opts, budget.tolerance)),
        d(problem.model.dimension()),
        n_steps(problem.steps),
        h(problem.step_size()),
        stepper(method.info().make_stepper(problem, options)),
        span(problem.t_end - problem.t0),
        m_times_x(d),
        mass_weights(d) {
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
    sol.step_size = h;
    sol.linear_solver = std::string(to_string(stepper->linear_solver()));
    const HistoryReport memory = stepper->history();
    sol.history_bytes = memory.bytes;
    sol.history = std::string(memory.kind);
    sol.history_exponentials = memory.exponentials;
    sol.history_window = memory.window;
    if (sol.history == "fast") {
      sol.history_tolerance = budget.tolerance;
      sol.history_tolerance_auto = budget.automatic;
      sol.history_limited = budget.limited;
    }
    if (options.diagnostics) {
      e0 = energy(0);
      energy_k = e0;
      work_k = stepper->work();
      balance_k = 0.0;
    } else {
      energy_k = work_k = balance_k = kNaN;
      sol.max_balance_error = kNaN;
    }
    init_health();
    store();
    init_dense();
    start_alongside_mirror();
  }

  // IntegratorOptions::mirror_alongside, when it applies (integrator.hpp); otherwise, or when no
  // thread can be started, take_solution() runs the mirror check after the run.
  void start_alongside_mirror() {
    if (!options.mirror || !options.mirror_alongside || options.threads == 1 ||
        !options.events.empty() || d >= kMaxAlongsideMirrorDimension ||
        std::thread::hardware_concurrency() < 2 || !method.info().has_mirror) {
      return;
    }
    const double bytes = static_cast<double>(stored_rows(n_steps, options.save_every)) *
                         static_cast<double>(d) * sizeof(double);
    if (bytes > kMaxAlongsideMirrorBytes) return;
    try {
      alongside = std::make_unique<AlongsideMirror>(
          *stepper, stored_steps(n_steps, options.save_every), d, options.flush_subnormals);
    } catch (const std::system_error&) {
      alongside.reset();  // no thread: the mirror run after the run
    }
  }

  // Sizes the dense output's storage, evaluates every event at (t_0, x_0, v_0) and outputs the
  // requested times equal to t_0. A g that throws or is not finite there is bad input.
  void init_dense() {
    const auto outputs = static_cast<Eigen::Index>(options.output_times.size());
    sol.output_t = Eigen::VectorXd::Constant(outputs, kNaN);
    sol.output_x = RowMatrixXd::Constant(outputs, d, kNaN);
    sol.output_v = RowMatrixXd::Constant(outputs, d, kNaN);
    const std::size_t n_events = options.events.size();
    dense = outputs > 0 || n_events > 0;
    if (!dense) return;
    x_before.resize(d);
    v_before.resize(d);
    x_dense.resize(d);
    v_dense.resize(d);
    g_before.resize(n_events);
    g_after.resize(n_events);
    crossings.reserve(n_events);
    // Recording crossings appends to these; 64 crossings fit before the first reallocation.
    constexpr std::size_t kReservedCrossings = 64;
    EventLog& log = sol.events;
    for (const Event& e : options.events) log.names.push_back(e.name);
    log.event.reserve(kReservedCrossings);
    log.t.reserve(kReservedCrossings);
    log.step.reserve(kReservedCrossings);
    log.direction.reserve(kReservedCrossings);
    log.x.reserve(kReservedCrossings * static_cast<std::size_t>(d));
    log.v.reserve(kReservedCrossings * static_cast<std::size_t>(d));
    for (std::size_t i = 0; i < n_events; ++i) {
      double g = kNaN;
      try {
        g = options.events[i].function(problem.t0, stepper->position(), stepper->velocity());
      } catch (const std::exception& e) {
        throw ValidationError(event_field(i) + ": g(t_0, x_0, v_0) threw: " + e.what());
      }
      if (!std::isfinite(g)) {
        throw ValidationError(event_field(i) + ": g(t_0, x_0, v_0) = " + format_number(g) +
                              " at t_0 = " + format_number(problem.t0) +
                              ": must be a finite number");
      }
      g_before[i] = g;
    }
    output_until(0.0, false);
  }

  [[nodiscard]] std::string event_field(std::size_t i) const {
    return "events[" + std::to_string(i) + "] (\"" + options.events[i].name + "\")";
  }

  // Fills the requested output times t ≤ t_k + s_end h of the step [t_k, t_{k+1}] (k = this->k
  // − 1 after a step; at k = 0 before any, with s_end = 0: the times equal to t_0).
  void output_until(double s_end, bool stepped) noexcept {
    const std::size_t k0 = stepped ? k - 1 : k;
    const double ta = time(k0);
    // Up to t_{k+1} itself (the last time may be t_end, a rounding away from t_N), or to the
    // terminal crossing.
    const bool last = stepped && k == n_steps;
    const double t_step_end = last ? std::max(problem.t_end, time(k)) : time(k);
    const double t_limit = s_end == 1.0 && stepped ? t_step_end : ta + s_end * h;
    while (next_output < options.output_times.size()) {
      const double t = options.output_times[next_output];
      if (t > t_limit) break;
      const auto r = static_cast<Eigen::Index>(next_output);
      Eigen::Map<Eigen::VectorXd> x(sol.output_x.row(r).data(), d),
          v(sol.output_v.row(r).data(), d);
      if (!stepped) {
        x = stepper->position();
        v = stepper->velocity();
      } else {
        // At or past the step's end (the last time may be t_end, a rounding away from t_N): the
        // grid state itself.
        const double s = t >= time(k) ? 1.0 : std::clamp((t - ta) / h, 0.0, 1.0);
        hermite_interpolate(s, h, x_before, v_before, stepper->position(), stepper->velocity(), x,
                            v);
      }
      sol.output_t[r] = t;
      ++next_output;
    }
  }

  // g of event i on the interpolant of the step just taken at s ∈ [0, 1].
  double g_dense(std::size_t i, double s) {
    hermite_interpolate(s, h, x_before, v_before, stepper->position(), stepper->velocity(), x_dense,
                        v_dense);
    return options.events[i].function(time_in_step(s), x_dense, v_dense);
  }
  // t_{k−1} + s h in the step just taken, t_k itself at s = 1.
  [[nodiscard]] double time_in_step(double s) const {
    return s == 1.0 ? time(k) : time(k - 1) + s * h;
  }

  // After step k: evaluates the events at t_k, locates the crossings in [t_{k−1}, t_k] on the
  // interpolant (TOMS 748 to full precision in s), records them in time order up to the first
  // terminal one, and outputs the requested times up to there. Returns kEvent (message written)
  // for a terminal crossing, kCallbackError / kNonFinite (message written) when a g throws or is
  // not finite, kSuccess otherwise.
  Status dense_step() noexcept {
    double s_end = 1.0;
    std::size_t terminal = options.events.size();
    std::size_t i = 0;
    double s_bad = 1.0;
    try {
      crossings.clear();
      for (i = 0; i < options.events.size(); ++i) {
        s_bad = 1.0;
        const double g =
            options.events[i].function(time(k), stepper->position(), stepper->velocity());
        if (!std::isfinite(g)) return bad_event(i, g, 1.0);
        g_after[i] = g;
        const double ga = g_before[i];
        const bool rising = ga < 0.0 && g >= 0.0, falling = ga > 0.0 && g <= 0.0;
        const EventDirection dir = options.events[i].direction;
        if (!((rising && dir != EventDirection::kFalling) ||
              (falling && dir != EventDirection::kRising))) {
          continue;
        }
        double s = 1.0;
        if (g != 0.0) {
          // Bracketed by construction (ga and g of opposite signs); the root of the interpolant
          // to a few ulps of s: its error is then the interpolant's (dense_output.md).
          auto f = [&](double sigma) {
            s_bad = sigma;
            const double value = g_dense(i, sigma);
            if (!std::isfinite(value)) throw NonFiniteEvent{value};
            return value;
          };
          boost::uintmax_t iterations = 100;
          const auto bracket = boost::math::tools::toms748_solve(
              f, 0.0, 1.0, ga, g, boost::math::tools::eps_tolerance<double>(), iterations);
          s = 0.5 * (bracket.first + bracket.second);
        }
        crossings.emplace_back(s, i);
      }
    } catch (const NonFiniteEvent& e) {
      return bad_event(i, e.value, s_bad);
    } catch (const std::exception& e) {
      return event_threw(i, e.what(), s_bad);
    } catch (...) {
      return event_threw(i, "an exception that is not a std::exception", s_bad);
    }
    std::sort(crossings.begin(), crossings.end());
    EventLog& log = sol.events;
    for (const auto& [s, e] : crossings) {
      if (terminal < options.events.size()) break;  // after the terminal crossing
      hermite_interpolate(s, h, x_before, v_before, stepper->position(), stepper->velocity(),
                          x_dense, v_dense);
      log.event.push_back(e);
      log.t.push_back(time_in_step(s));
      log.step.push_back(k);
      log.direction.push_back(g_after[e] > g_before[e] ? 1 : -1);
      log.x.insert(log.x.end(), x_dense.data(), x_dense.data() + d);
      log.v.insert(log.v.end(), v_dense.data(), v_dense.data() + d);
      if (options.events[e].terminal) {
        terminal = e;
        s_end = s;
      }
    }
    std::swap(g_before, g_after);
    output_until(s_end, true);
    if (terminal == options.events.size()) return Status::kSuccess;
    std::snprintf(message.data(), message.size(),
                  "stopped by the terminal event \"%s\" at t = %.17g (in step %zu); the steps up "
                  "to there are kept",
                  options.events[terminal].name.c_str(), sol.events.t.back(), k);
    return Status::kEvent;
  }

  struct NonFiniteEvent {
    double value;
  };

  Status bad_event(std::size_t i, double g, double s) noexcept {
    std::snprintf(message.data(), message.size(),
                  "events[%zu] (\"%s\"): g = %.6g at t = %.17g (step %zu): an event function must "
                  "return a finite number",
                  i, options.events[i].name.c_str(), g, time_in_step(s), k);
    return Status::kNonFinite;
  }
  Status event_threw(std::size_t i, const char* what, double s) noexcept {
    std::snprintf(message.data(), message.size(),
                  "events[%zu] (\"%s\") threw in step %zu (t = %.17g): %s", i,
                  options.events[i].name.c_str(), k, time_in_step(s), what);
    return Status::kCallbackError;
  }

  // E_k = ½ v_kᵀ p_k + U(x_k, t_k) from the stepper's state; sets kinetic_k and potential_k.
  [[nodiscard]] double energy(std::size_t i) {
    const Eigen::VectorXd &v = stepper->velocity(), &p = stepper->momentum();
    // v·p as the step's momentum pass summed it, when it did (Stepper::step_sums: the same bits).
    const Stepper::StepSums& sums = stepper->step_sums();
    kinetic_k = 0.5 * (sums.step == i && sums.has_velocity_momentum ? sums.velocity_momentum
                                                                    : internal::step_dot(v, p));
    potential_k = problem.model.potential
                      ? problem.model.potential->value(stepper->position(), time(i))
                      : 0.0;
    return kinetic_k + potential_k;
  }

  // ‖x‖_M = √(xᵀMx), the state norm of the growth rule (units √mass · length, like T√(2S)).
  // The state norm of the growth rule, weighted by the diagonal of M (units √mass · length, like
  // T√(2S)): O(d) per step, where the full xᵀMx would cost a dense matrix-vector product (as much
  // as the step itself for a dense M). Exact for a diagonal M; within the conditioning of M
  // otherwise, which the factor 10^8 of the rule absorbs.
  [[nodiscard]] double mass_norm(const Eigen::VectorXd& x) const {
    // From kVectorPassesFrom on one cloned pass (Eigen's product and norm: ≈ 2.9 instructions per
    // element, d = 1000); smaller systems keep Eigen's sum. A threshold check only: its last
    // bits never reach a trajectory.
    if (x.size() >= internal::kVectorPassesFrom) {
      return std::sqrt(internal::weighted_squares_pass(mass_weights.data(), x.data(), x.size()));
    }
    return (mass_weights.array() * x.array()).matrix().norm();
  }

  void init_health() {
    mass_weights = Stepper::health_weights(problem.model.mass);
    const double x0 = mass_norm(problem.x0);
    state_base = x0 + span * mass_norm(problem.v0);
    running_max = checkpoint_max = x0;
    // S_R: the energy the damping memory of the initial state can hand back (integrator.hpp).
    double memory_energy = 0.0;
    if (!problem.model.is_undamped()) {
      problem.model.damping.multiply(problem.x0, m_times_x);
      double q = problem.x0.dot(m_times_x);
      problem.model.damping.multiply(problem.v0, m_times_x);
      q += span * span * problem.v0.dot(m_times_x);
      memory_energy = std::abs(q) * std::pow(span, -2.0 * problem.model.alpha);
    }
    energy_floor = memory_energy;
    const bool time_dependent_u =
        problem.model.potential && problem.model.potential->is_time_dependent();
    supplied_known = std::isfinite(stepper->supplied_work()) ||
                     (!problem.model.forcing && !problem.model.state_force && !time_dependent_u);
    // Riemann–Liouville with x(0) ≠ 0 and 0 < 2α < 1: the memory of the constant x(0) is a force
    // R x(0) t^{−2α}/Γ(1−2α) that acts like an external one and legitimately puts energy in (its
    // integrable singularity at t = 0 delivers a kick of order R x(0) h^{1−2α}), so the damping's
    // work is no evidence of instability there and rule 1 is off.
    const double beta = 2.0 * problem.model.alpha;
    memory_is_a_source = problem.model.convention == Convention::kRiemannLiouville && beta > 0.0 &&
                         beta < 1.0 && !problem.x0.isZero(0.0) && !problem.model.is_undamped();
    if (options.diagnostics) {
      energy_floor = std::max({energy_floor, std::abs(e0), kinetic_k + std::abs(potential_k)});
      max_activity = kinetic_k + std::abs(potential_k);
    }
    energy_scale = energy_floor;
  }

  // The rules 1 and 2 of integrator.hpp at step k (diagnostics already computed), and the
  // running quantities of rule 3 (applied by balance_rule_tripped()). Returns kUnstable (message
  // written) or kSuccess.
  Status check_health() noexcept {
    if (options.diagnostics) {
      max_activity = std::max(max_activity, kinetic_k + std::abs(potential_k));
      double damping_work = kNaN;
      if (supplied_known && !memory_is_a_source) {
        const double supplied =
            std::isfinite(stepper->supplied_work()) ? stepper->supplied_work() : 0.0;
        max_supplied = std::max(max_supplied, std::abs(supplied));
        damping_work = work_k + supplied;
      }
      max_abs_work = std::max(max_abs_work, std::abs(work_k));
      // Without P_k (rule 1 off) the work W_k, which contains it, stands in for it.
      const double unknown_supply = std::isfinite(damping_work) ? 0.0 : max_abs_work;
      // Not the damping's own work: a scheme past its bound can book a growing positive one
      // (measured for fvi-lobatto2/3/4 forced 3 % past it) and would hide its own blow-up.
      energy_scale = std::max({energy_floor, max_supplied, unknown_supply});
      tolerance_scale = std::max(energy_scale, kActivityFraction * max_activity);
      if (std::abs(balance_k) > max_abs_balance) {
        max_abs_balance = std::abs(balance_k);
        max_balance_step = k;
      }
      // Rule 1: the damping put energy in.
      if (damping_work < -kUnstableDampingFactor * tolerance_scale) {
        std::snprintf(message.data(), message.size(),
                      "unstable at step %zu (t = %.17g): the damping put energy in: its work "
                      "W_k + (work of f) = %.6g is below -%g x the energy scale %.6g (an explicit "
                      "damping memory past its stability bound, or a step too large)",
                      k, time(k), damping_work, kUnstableDampingFactor, tolerance_scale);
        return Status::kUnstable;
      }
    }
    // Rule 2: the state grew by orders of magnitude.
    // ‖x_k‖_M as the step's position pass summed it, when it did (the same bits as mass_norm).
    const Stepper::StepSums& sums = stepper->step_sums();
    const double x_norm = sums.step == k && sums.has_mass_squares ? std::sqrt(sums.mass_squares)
                                                                  : mass_norm(stepper->position());
    double base = std::max(state_base, growth_reference);
    if (options.diagnostics) base = std::max(base, span * std::sqrt(2.0 * energy_scale));
    if (base > 0.0 && x_norm > kUnstableGrowthFactor * base) {
      std::snprintf(message.data(), message.size(),
                    "unstable at step %zu (t = %.17g): the state grew by orders of magnitude: "
                    "|x_k|_M = %.6g exceeds %g x its scale %.6g (the largest of |x_0|_M + "
                    "T|v_0|_M, T sqrt(2 x energy scale) and |x_j|_M earlier in the run)",
                    k, time(k), x_norm, kUnstableGrowthFactor, base);
      return Status::kUnstable;
    }
    running_max = std::max(running_max, x_norm);
    if (k == next_checkpoint) {
      growth_reference = checkpoint_max;
      checkpoint_max = running_max;
      next_checkpoint *= 2;
    }
    return Status::kSuccess;
  }

  // Rule 3, over the run so far: max_j |E_j + W_j − E_0| > kInaccurateBalanceFraction · S̃_k. The
  // scale of the whole run, not of step j: a run starting from rest has tiny energies in its
  // first steps, where the balance error of an O(h^p) scheme is relatively large but absolutely
  // negligible (measured 1.7e-11 against an energy of 1.7e-11 at step 1 of a power-law problem).
  [[nodiscard]] bool balance_rule_tripped() const {
    return options.diagnostics && max_abs_balance > kInaccurateBalanceFraction * tolerance_scale;
  }
  void write_inaccurate_message(MessageBuffer& out) const noexcept {
    std::snprintf(out.data(), out.size(),
                  "inaccurate: the energy balance error |E_k + W_k - E_0| reached %.6g at step %zu "
                  "(t = %.17g), more than %g x the energy scale %.6g of the run (the steps do not "
                  "resolve the motion: take more steps)",
                  max_abs_balance, max_balance_step, time(max_balance_step),
                  kInaccurateBalanceFraction, tolerance_scale);
  }

  Eigen::Map<Eigen::VectorXd> row(RowMatrixXd& m, std::size_t i) const {
    return {m.row(static_cast<Eigen::Index>(i)).data(), d};
  }
  // t_i = t0 + i h, the same expression as InitialValueProblem::time() (h is its step_size()).
  [[nodiscard]] double time(std::size_t i) const { return problem.t0 + static_cast<double>(i) * h; }

  // Copies the state at step k into row r of `target` (allocated).
  void store_row(Solution& target, std::size_t r) const {
    const auto i = static_cast<Eigen::Index>(r);
    target.t(i) = time(k);
    target.step[r] = k;
    row(target.x, r) = stepper->position();
    row(target.v, r) = stepper->velocity();
    target.energy(i) = energy_k;
    target.dissipated(i) = work_k;
    target.balance(i) = balance_k;
  }
  // Copies the state at step k into the next stored row (steps 0, s, 2s, … and the last one).
  void store() {
    store_row(sol, saved);
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

  // options.interrupt asked to stop before step k + 1: the run ends at step k, which becomes the
  // last row (as for a failure).
  Status interrupt() noexcept {
    status = Status::kInterrupted;
    stop_clock();
    if (!stored(k)) store();
    std::snprintf(message.data(), message.size(),
                  "interrupted after step %zu of %zu (t = %.17g); the trajectory up to there is "
                  "kept",
                  k, n_steps, time(k));
    return status;
  }

  [[nodiscard]] bool interrupt_requested() const noexcept {
    if (!options.interrupt) return false;
    try {
      return options.interrupt();
    } catch (...) {
      return true;  // a hook that cannot answer is taken as a request to stop
    }
  }

  // The whole running state (Integrator::visit_state). The rows before `saved` are the steps
  // 0, s, 2s, … ≤ k of a running integration (failure and last-step rows end a run), so their
  // step indices are implied and only their values are stored.
  void visit_state(StateArchive& archive) {
    if (status != Status::kRunning) {
      throw CheckpointError(std::string("a checkpoint needs a running integration; this one is ") +
                            std::string(to_string(status)));
    }
    if (dense) {
      throw CheckpointError(
          "a run with output times or events cannot save its state (their "
          "progress is not part of a checkpoint)");
    }
    if (!method.info().checkpoints) {
      throw CheckpointError("method.scheme = \"" + std::string(method.name()) +
                            "\" cannot save its state (no checkpoints)");
    }
    // The scheme in the record's name: steppers shared by schemes (fvi-gl, fvi-bdf2) have the
    // same records, and the state of one must not continue the other.
    std::size_t scheme_record = 1;
    archive.count("integrator.scheme=" + std::string(method.name()), scheme_record);
    archive.expect("integrator.dimension", static_cast<std::size_t>(d));
    archive.expect("integrator.steps", n_steps);
    archive.expect("integrator.save_every", options.save_every);
    archive.count("integrator.k", k);
    archive.count("integrator.saved", saved);
    const std::size_t rows = sol.step.size();
    if (k >= n_steps || saved != k / options.save_every + 1 || saved > rows) {
      throw CheckpointError("checkpoint records 'integrator.k' = " + std::to_string(k) +
                            " and 'integrator.saved' = " + std::to_string(saved) +
                            " do not describe a running integration of " + std::to_string(n_steps) +
                            " steps (corrupt)");
    }
    for (std::size_t i = 0; i < saved; ++i) sol.step[i] = i * options.save_every;
    const auto values = [&](std::string_view name, double* data, Eigen::Index width) {
      archive.doubles(name, std::span<double>(data, saved * static_cast<std::size_t>(width)));
    };
    values("rows.t", sol.t.data(), 1);
    values("rows.x", sol.x.data(), d);  // row-major: the first rows are contiguous
    values("rows.v", sol.v.data(), d);
    values("rows.energy", sol.energy.data(), 1);
    values("rows.dissipated", sol.dissipated.data(), 1);
    values("rows.balance", sol.balance.data(), 1);
    sol.steps_done = k;
    archive.count("stats.newton_iterations", sol.newton_iterations);
    archive.count("stats.max_newton_iterations_per_step", sol.max_newton_iterations_per_step);
    archive.number("stats.max_balance_error", sol.max_balance_error);
    archive.number("stats.run_seconds", run_seconds);
    for (auto [name, value] : {std::pair<const char*, double*>{"health.e0", &e0},
                               {"health.energy", &energy_k},
                               {"health.work", &work_k},
                               {"health.balance", &balance_k},
                               {"health.kinetic", &kinetic_k},
                               {"health.potential", &potential_k},
                               {"health.max_supplied", &max_supplied},
                               {"health.max_activity", &max_activity},
                               {"health.energy_scale", &energy_scale},
                               {"health.running_max", &running_max},
                               {"health.checkpoint_max", &checkpoint_max},
                               {"health.growth_reference", &growth_reference},
                               {"health.max_abs_work", &max_abs_work},
                               {"health.tolerance_scale", &tolerance_scale},
                               {"health.max_abs_balance", &max_abs_balance}}) {
      archive.number(name, *value);
    }
    archive.count("health.next_checkpoint", next_checkpoint);
    archive.count("health.max_balance_step", max_balance_step);
    stepper->visit_state(archive);
    if (archive.loading() && alongside) {
      // A mirror run that started from this Integrator's own x_1 is no use for the restored run.
      if (alongside->opened()) {
        alongside.reset();
      } else if (k >= 1) {
        alongside->open();
      }
    }
  }

  [[nodiscard]] Solution result(Solution s, std::size_t rows) const;

  Status step() noexcept {
    if (status != Status::kRunning) return status;
    if (interrupt_requested()) return interrupt();
    if (!clock_running) {
      clock_start = std::chrono::steady_clock::now();
      clock_running = true;
    }
    if (dense) {
      x_before = stepper->position();
      v_before = stepper->velocity();
    }
    const Status s = stepper->step();
    const auto iterations = static_cast<std::size_t>(stepper->last_iterations());
    sol.newton_iterations += iterations;
    sol.max_newton_iterations_per_step = std::max(sol.max_newton_iterations_per_step, iterations);
    if (s != Status::kSuccess) {
      // A Newton failure on a potential with kinks: most likely a step whose midpoint is at one,
      // where the implicit equation has no solution (docs/problem-file.md) — say so.
      const char* detail = stepper->failure_detail();
      if (s == Status::kNewtonFailure && detail[0] == '\0' && problem.model.potential &&
          problem.model.potential->has_kinks()) {
        detail = kKinkHint;
      }
      return fail(s, stepper->failure_message(), detail);
    }
    ++k;
    if (k == 1 && alongside) alongside->open();  // x_1 is known: the mirror run can start
    if (options.diagnostics) {
      // Step k is computed; if its diagnostics fail, the run ends with it as the last row.
      Status bad = Status::kSuccess;
      std::array<char, kFailureDetailCapacity> detail;  // written only on failure
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
    if (check_health() == Status::kUnstable) {
      status = Status::kUnstable;
      stop_clock();
      store();  // the step that tripped the rule is the last row
      return status;
    }
    if (dense) {
      if (const Status e = dense_step(); e != Status::kSuccess) {
        status = e;
        stop_clock();
        store();  // the step in which the event was found (or g failed) is the last row
        return status;
      }
    }
    if (k % options.save_every == 0 || k == n_steps) store();
    if (k == n_steps) {
      status = balance_rule_tripped() ? Status::kInaccurate : Status::kSuccess;
      if (status == Status::kInaccurate) write_inaccurate_message(message);
      stop_clock();
    }
    return status;
  }
};

Integrator::Integrator(InitialValueProblem problem, Method method, IntegratorOptions options) {
  const auto start = std::chrono::steady_clock::now();
  impl_ = std::make_unique<Impl>(validated(std::move(problem), method, options), method, options);
  impl_->sol.setup_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

Integrator::~Integrator() = default;
Integrator::Integrator(Integrator&&) noexcept = default;
Integrator& Integrator::operator=(Integrator&&) noexcept = default;

Status Integrator::step() noexcept {
  const internal::SubnormalsFlushed flushed(impl_->options.flush_subnormals);
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

void Integrator::visit_state(StateArchive& archive) {
  impl_->visit_state(archive);
}

double Integrator::mirror_error() const {
  if (impl_->status != Status::kSuccess) return kNaN;
  // The same floating-point environment as the run alongside (AlongsideMirror::body) and the run.
  const internal::SubnormalsFlushed flushed(impl_->options.flush_subnormals);
  return impl_->stepper->mirror_error(
      impl_->sol.x, std::span<const std::size_t>(impl_->sol.step.data(), impl_->saved),
      impl_->options.interrupt);
}

// `s` holding `rows` rows (the stored ones and, when the run stopped between them, the state at
// step k) as the run's result now: status, steps done, message, and the rows not reached dropped.
Solution Integrator::Impl::result(Solution s, std::size_t rows) const {
  s.status = status;
  s.steps_done = k;
  s.jacobian_factorizations = stepper->jacobian_factorizations();
  s.history_threads = stepper->history().threads;
  s.message = status == Status::kSuccess || status == Status::kRunning
                  ? std::string()
                  : std::string(message.data());
  // A run that failed or was stopped while rule 3 held says so too: a failure may be its
  // consequence.
  const bool unresolved = balance_rule_tripped() && status != Status::kInaccurate;
  if (unresolved && status != Status::kRunning) {
    s.message += " (before that, the energy balance error had reached " +
                 format_number(max_abs_balance) + " at step " + std::to_string(max_balance_step) +
                 ", more than " + format_number(kInaccurateBalanceFraction) +
                 " x the energy scale " + format_number(tolerance_scale) + ")";
  }
  if (status == Status::kRunning && unresolved) {
    MessageBuffer inaccurate{};
    write_inaccurate_message(inaccurate);
    s.message = std::string(inaccurate.data()) + "; ";
  }
  if (status == Status::kRunning) {
    s.message += "stopped by the caller after " + std::to_string(k) + " of " +
                 std::to_string(n_steps) + " steps";
  }
  const auto n = static_cast<Eigen::Index>(rows);
  s.step.resize(rows);
  s.t.conservativeResize(n);
  s.x.conservativeResize(n, Eigen::NoChange);
  s.v.conservativeResize(n, Eigen::NoChange);
  s.energy.conservativeResize(n);
  s.dissipated.conservativeResize(n);
  s.balance.conservativeResize(n);
  const auto outputs = static_cast<Eigen::Index>(next_output);
  s.output_t.conservativeResize(outputs);
  s.output_x.conservativeResize(outputs, Eigen::NoChange);
  s.output_v.conservativeResize(outputs, Eigen::NoChange);
  return s;
}

Solution Integrator::take_solution() {
  Impl& im = *impl_;
  im.stop_clock();
  double seconds = im.run_seconds;
  if (im.options.mirror && im.status == Status::kSuccess) {
    const auto start = std::chrono::steady_clock::now();
    const std::vector<std::size_t>* predicted = im.alongside ? &im.alongside->steps() : nullptr;
    if (predicted != nullptr && im.alongside->opened() && predicted->size() == im.saved &&
        std::equal(predicted->begin(), predicted->end(), im.sol.step.begin())) {
      im.sol.mirror_error =
          im.alongside->finish(im.sol.x, [&im] { return im.interrupt_requested(); });
      im.sol.mirror_alongside = true;
    } else {
      im.alongside.reset();  // not the rows it predicted (never expected): after the run instead
      im.sol.mirror_error = mirror_error();
    }
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // A signal during the mirror check (the mirror runs poll the hook, which keeps answering true
    // once it has, options.hpp) stops it: the trajectory is complete, the check was not made.
    if (!std::isfinite(im.sol.mirror_error) && im.interrupt_requested()) {
      im.status = Status::kInterrupted;
      std::snprintf(im.message.data(), im.message.size(),
                    "interrupted during the mirror check, after all %zu steps (t = %.17g); the "
                    "trajectory is complete, the mirror error was not computed",
                    im.k, im.time(im.k));
    }
  }
  if (!im.stored(im.k)) im.store();  // stopped by the caller between stored rows
  Solution s = im.result(std::move(im.sol), im.saved);
  s.wall_time_seconds = seconds;
  impl_.reset();
  return s;
}

Solution Integrator::snapshot() const {
  const Impl& im = *impl_;
  Solution s = im.sol;  // every row is allocated, the one for the state at step k too
  std::size_t rows = im.saved;
  if (!im.stored(im.k)) im.store_row(s, rows++);
  s = im.result(std::move(s), rows);
  s.wall_time_seconds = im.run_seconds;
  if (im.clock_running) {
    s.wall_time_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - im.clock_start).count();
  }
  return s;
}

Solution integrate(const InitialValueProblem& problem, const Method& method,
                   const IntegratorOptions& options) {
  Integrator integrator(problem, method, options);
  integrator.run();
  return integrator.take_solution();
}

}  // namespace fracvi
