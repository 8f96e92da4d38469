// fracvi._fracvi: the C++ library as seen from Python. python/fracvi/__init__.py is the public
// API; this module is its thin native layer (docs/python.md).
//
// One source of truth. Problems are validated by the C++ problem-file reader (parse_problem,
// parse_problem_json, load_problem) and by the same model checks `fracvi run` applies, and bad
// input raises ProblemError (a ValueError) whose message is exactly what `fracvi run` prints after
// "fracvi run: ": checked_spec() and run_problem() go through prepare_run(), the checks the CLI
// applies (python/tests/test_problem.py compares the messages with the CLI's). Runs go
// through integrate(), summaries through make_summary(), files through write_run_output().
//
// No copies where it matters (DESIGN §4): a Solution's arrays are read-only NumPy views of its
// Eigen storage (row-major (N+1) × d), and the Python object owning the Solution is their base,
// so an array keeps the storage alive after the Solution object is gone. Results of the discrete
// operators and weights move their Eigen/std::vector buffer into the array they return.
//
// Layout conversion of sequences: the paper's operators take a d × (N+1) matrix whose column k is
// z_k (fracvi/discrete/operators.hpp). A C-contiguous NumPy array of shape (N+1, d), row k = z_k,
// has exactly that memory layout, so Python uses the NumPy-natural shape and nothing is
// transposed.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "callables.hpp"
#include "fracvi/analysis/comparison.hpp"
#include "fracvi/analysis/error_estimate.hpp"
#include "fracvi/discrete/operators.hpp"
#include "fracvi/expression/expression.hpp"
#include "fracvi/fractional/riemann_liouville.hpp"
#include "fracvi/fractional/weights.hpp"
#include "fracvi/integrate/dense_output.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/lagrangian_problem.hpp"
#include "fracvi/io/output.hpp"
#include "fracvi/io/problem_file.hpp"
#include "fracvi/io/problem_schema.hpp"
#include "fracvi/io/run.hpp"
#include "fracvi/io/sweep.hpp"
#include "fracvi/lagrangian/action.hpp"
#include "fracvi/lagrangian/bvp.hpp"
#include "fracvi/lagrangian/continuous_residual.hpp"
#include "fracvi/schemes/registry.hpp"

namespace py = pybind11;

namespace fracvi::python {

namespace {

/// Bad problem input; becomes fracvi.ProblemError, a subclass of ValueError.
class ProblemError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

std::string repr_text(py::handle h) {
  return py::repr(h).cast<std::string>();
}

// ---------------------------------------------------------------------------------------------
// JSON <-> Python. Direct conversion (no text in between), so doubles cross unchanged and Python
// ints stay JSON integers (the reader insists that time.steps is an integer).

py::object to_python(const nlohmann::json& j) {
  using Type = nlohmann::json::value_t;
  switch (j.type()) {
    case Type::boolean: return py::bool_(j.get<bool>());
    case Type::number_integer: return py::int_(j.get<std::int64_t>());
    case Type::number_unsigned: return py::int_(j.get<std::uint64_t>());
    case Type::number_float: return py::float_(j.get<double>());
    case Type::string: return py::str(j.get_ref<const std::string&>());
    case Type::array: {
      py::list list;
      for (const auto& e : j) list.append(to_python(e));
      return list;
    }
    case Type::object: {
      py::dict dict;
      for (const auto& [k, v] : j.items()) dict[py::str(k)] = to_python(v);
      return dict;
    }
    default: return py::none();  // null (JSON has no NaN: summary.json writes null)
  }
}

nlohmann::json from_python(py::handle h, const std::string& key, const std::string& source) {
  const std::string where = source + ": " + (key.empty() ? std::string("the problem") : key);
  PyObject* p = h.ptr();
  if (h.is_none()) return nullptr;  // the reader's message: "<key>: null is not a value"
  if (PyBool_Check(p)) return h.cast<bool>();
  if (PyLong_Check(p)) {
    int overflow = 0;
    const long long value = PyLong_AsLongLongAndOverflow(p, &overflow);
    if (overflow != 0) throw ProblemError(where + " = " + repr_text(h) + " does not fit 64 bits");
    return static_cast<std::int64_t>(value);
  }
  if (PyFloat_Check(p)) return PyFloat_AsDouble(p);
  if (PyUnicode_Check(p)) return h.cast<std::string>();
  if (PyDict_Check(p)) {
    nlohmann::json object = nlohmann::json::object();
    for (const auto& [k, v] : py::reinterpret_borrow<py::dict>(h)) {
      if (!PyUnicode_Check(k.ptr())) {
        throw ProblemError(where + ": key " + repr_text(k) + " is not a string");
      }
      const auto name = k.cast<std::string>();
      object[name] = from_python(v, key.empty() ? name : key + "." + name, source);
    }
    return object;
  }
  if (PyList_Check(p) || PyTuple_Check(p)) {
    nlohmann::json array = nlohmann::json::array();
    std::size_t i = 0;
    for (const auto& e : py::reinterpret_borrow<py::sequence>(h)) {
      array.push_back(from_python(e, key + "[" + std::to_string(++i) + "]", source));
    }
    return array;
  }
  // NumPy arrays and scalars (np.float64 is a float already; np.int64, np.bool_ are not).
  if (py::hasattr(h, "tolist")) return from_python(h.attr("tolist")(), key, source);
  throw ProblemError(where + " = " + repr_text(h) + ": a " +
                     py::str(py::type::handle_of(h).attr("__name__")).cast<std::string>() +
                     " cannot be used (numbers, strings, lists and dicts only)");
}

// ---------------------------------------------------------------------------------------------
// Problems.

/// Parses with `parse` and applies every check the command line applies before its first step,
/// with its messages: those of `fracvi run` (prepare_run) for a problem with [initial], which can
/// then be integrated, and those of `fracvi bvp` (prepare_bvp) for a boundary value problem
/// without [initial], which can then be solved by solve_bvp.
template <class Parse>
ProblemSpec checked_spec(Parse&& parse) {
  try {
    ProblemSpec spec = parse();
    if (spec.position.size() == 0 && spec.boundary_start.size() > 0) {
      return prepare_bvp(std::move(spec)).spec;
    }
    return prepare_run(std::move(spec)).spec;
  } catch (const ProblemFileError& e) {
    throw ProblemError(e.what());
  }
}

py::array matrix_copy(const Eigen::MatrixXd& m) {
  py::array_t<double> out({m.rows(), m.cols()});
  auto a = out.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) a(i, j) = m(i, j);
  return out;
}

py::array vector_copy(const Eigen::VectorXd& v) {
  py::array_t<double> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

/// M or R as stored: dense storage as a NumPy array, sparse storage (a number or d numbers in the
/// problem) as a scipy.sparse.csc_matrix (pybind11's Eigen::SparseMatrix caster; a copy). Never
/// expanded: a chain of 10^5 masses would need 80 GB dense.
py::object model_matrix(const ModelMatrix& m) {
  if (!m.is_sparse()) return matrix_copy(m.dense());
  try {
    py::module_::import("scipy.sparse");
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_ImportError)) throw;
    throw py::import_error(
        "this matrix is stored sparse (the problem gives it as a number or d numbers) and is "
        "returned as a scipy.sparse.csc_matrix, but scipy is not installed (Debian: "
        "python3-scipy)");
  }
  return py::cast(m.sparse());
}

py::object chain_dict(const ProblemSpec& s) {
  if (!s.chain) return py::none();
  const ChainOptions& c = *s.chain;
  py::dict d;
  d["stiffness"] = c.stiffness;
  d["cubic"] = c.cubic;
  d["quartic"] = c.quartic;
  d["onsite"] = c.onsite;
  d["boundary"] = std::string(to_string(c.boundary));
  return d;
}

// ---------------------------------------------------------------------------------------------
// Runs.

/// What a run produced, with the problem it solved (make_summary and write_run_output need it).
struct Run {
  ProblemSpec spec;
  Solution solution;
  /// The exception a Python signal handler raised during the run (KeyboardInterrupt for Ctrl-C),
  /// or None: fracvi.integrate raises it with the partial solution attached.
  py::object interrupt = py::none();
};

/// IntegratorOptions::interrupt for a run with the GIL released. Python's SIGINT handler only
/// records the signal; the handlers themselves (which raise KeyboardInterrupt) run when the
/// interpreter gets to them, which it does not during a C++ loop. So the run takes the GIL about
/// every kInterval of wall time (the clock is read every kStride calls) and runs them
/// (PyErr_CheckSignals); when one raises, its exception is kept in `slot` (which must outlive the
/// function) and the run stops. Once it has fired it keeps answering true (options.hpp).
std::function<bool()> python_interrupt(py::object& slot) {
  struct State {
    py::object* slot;
    std::chrono::steady_clock::time_point next;
    unsigned calls = 0;
    bool raised = false;
  };
  constexpr auto kInterval = std::chrono::milliseconds(100);
  constexpr unsigned kStride = 16;
  auto state = std::make_shared<State>(State{&slot, std::chrono::steady_clock::now() + kInterval});
  return [state, kInterval]() {
    if (state->raised) return true;
    if (++state->calls % kStride != 0) return false;
    const auto now = std::chrono::steady_clock::now();
    if (now < state->next) return false;
    state->next = now + kInterval;
    const py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() == 0) return false;
    PyObject *type = nullptr, *value = nullptr, *traceback = nullptr;
    PyErr_Fetch(&type, &value, &traceback);
    PyErr_NormalizeException(&type, &value, &traceback);
    if (traceback != nullptr && value != nullptr) PyException_SetTraceback(value, traceback);
    Py_XDECREF(type);
    Py_XDECREF(traceback);
    *state->slot = value != nullptr ? py::reinterpret_steal<py::object>(value) : py::none();
    state->raised = true;
    return true;
  };
}

void make_read_only(py::array& a) {
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
}

/// A read-only view of `rows` × `cols` row-major doubles (cols = 0: a vector), owned by `owner`.
py::array view(py::handle owner, const double* data, Eigen::Index rows, Eigen::Index cols) {
  constexpr auto kSize = static_cast<py::ssize_t>(sizeof(double));
  py::array a;
  if (cols == 0) {
    a = py::array(py::dtype::of<double>(), {py::ssize_t{rows}}, {kSize}, data, owner);
  } else {
    a = py::array(py::dtype::of<double>(), {py::ssize_t{rows}, py::ssize_t{cols}},
                  {py::ssize_t{cols} * kSize, kSize}, data, owner);
  }
  make_read_only(a);
  return a;
}

// "" keeps the problem's [method] history.
std::optional<HistoryKind> parse_history(const std::string& name) {
  if (name.empty()) return std::nullopt;
  if (auto kind = parse_history_kind(name)) return kind;
  throw py::value_error("history = '" + name + "' must be 'auto', 'direct' or 'fast'");
}

StartValue parse_start(const std::string& name) {
  if (name == "legendre") return StartValue::kDiscreteLegendre;
  if (name == "euler") return StartValue::kExplicitEuler;
  throw py::value_error("start = '" + name + "' must be 'legendre' or 'euler'");
}

/// The run options of fracvi.integrate and fracvi.Integrator (the keywords that are not fields of
/// the problem).
struct RunOptions {
  bool diagnostics = true;
  double absolute_tolerance = 0.0;
  std::string history;  // "" keeps the problem's
  std::string start = "legendre";
  /// Events given as Python callables: (name, g, direction, terminal) tuples, after the
  /// problem's formula events.
  std::vector<py::tuple> events;
};

/// A Python callable g(t, x, v) as an Event: called with the GIL taken (the runs release it),
/// with x and v as new read-only NumPy arrays. It must return one real number: a Python
/// exception, or a result that is not one number (an array of another size, a string, None),
/// becomes an exception whose what() the Integrator puts in the run's message
/// (Status::kCallbackError); a NaN is Status::kNonFinite. Each call allocates (Python objects):
/// the step loop's no-allocation rule holds for the formula events only.
Event python_event(const py::tuple& item, std::size_t index) {
  const std::string name = item[0].cast<std::string>();
  const auto direction = parse_event_direction(item[2].cast<std::string>());
  if (!direction) {
    throw py::value_error("events[" + std::to_string(index) + "] (\"" + name +
                          "\"): direction = '" + item[2].cast<std::string>() +
                          "' must be 'both', 'rising' or 'falling' (or 0, +1, -1)");
  }
  auto function = std::make_shared<py::object>(item[1]);
  Event event;
  event.name = name;
  event.direction = *direction;
  event.terminal = item[3].cast<bool>();
  event.function = [function](double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                              const Eigen::Ref<const Eigen::VectorXd>& v) -> double {
    const py::gil_scoped_acquire gil;
    std::string problem;
    try {
      const py::object result = (*function)(t, vector_copy(x), vector_copy(v));
      const py::array values = py::array::ensure(result);
      const char kind = values ? values.dtype().kind() : 'O';
      const bool real = kind == 'f' || kind == 'i' || kind == 'u' || kind == 'b';
      if (values && values.size() == 1 && real) {
        return py::float_(values.attr("item")()).cast<double>();
      }
      const std::string shape =
          values ? py::str(values.attr("shape")).cast<std::string>() : std::string("?");
      problem = "g returned " + py::repr(result).cast<std::string>().substr(0, 60) + " (type " +
                py::str(py::type::of(result).attr("__name__")).cast<std::string>() + ", shape " +
                shape + "): it must return one real number";
    } catch (py::error_already_set& e) {
      problem = python::exception_text(e);
    }
    throw std::runtime_error(problem);
  };
  return event;
}

/// Whether the model's potential or force are Python functions (callables.hpp).
bool calls_python(const MechanicalModel& model) {
  return python::is_python(model.potential) || python::is_python(model.state_force);
}

/// prepare_run (the CLI's checks and messages) with the run options applied and validated.
/// `caller` names the Python function in messages.
PreparedRun prepare_python_run(const ProblemSpec& spec, const RunOptions& run,
                               const std::string& caller) {
  PreparedRun prepared;
  try {
    prepared = prepare_run(spec);
  } catch (const ProblemFileError& e) {
    throw ProblemError(e.what());
  }
  IntegratorOptions& options = prepared.options;
  options.diagnostics = run.diagnostics;
  options.newton.absolute_tolerance = run.absolute_tolerance;
  if (const auto kind = parse_history(run.history)) options.history = *kind;
  options.start = parse_start(run.start);
  for (std::size_t i = 0; i < run.events.size(); ++i) {
    options.events.push_back(python_event(run.events[i], options.events.size()));
  }
  // A run of a model with Python functions holds the GIL throughout (run_problem): a mirror run
  // alongside it on a second thread would wait for the GIL at its first call, and the run for it.
  if (calls_python(prepared.problem.model)) options.mirror_alongside = false;
  try {
    validate(options);
  } catch (const ValidationError& e) {
    throw py::value_error(e.what());
  }
  if (prepared.spec.checkpoint_every > 0) {
    throw ProblemError(spec.source + ": output.checkpoint_every = " +
                       std::to_string(prepared.spec.checkpoint_every) +
                       ": checkpoints are written by `fracvi run` into its output directory; " +
                       caller + " writes none (set it to 0)");
  }
  return prepared;
}

/// The KeyboardInterrupt or SystemExit one of the model's Python functions raised, or None;
/// cleared (both are taken, the potential's kept if both raised).
py::object take_raised_interrupt(const MechanicalModel& model) {
  py::object potential = python::take_raised_interrupt(model.potential);
  py::object force = python::take_raised_interrupt(model.state_force);
  return potential.is_none() ? force : potential;
}

/// A KeyboardInterrupt or SystemExit raised inside a Python model function during the run
/// (callables.hpp) becomes the run's interrupt, as a Ctrl-C between steps would: `slot` keeps the
/// first, and the failed step's status "callback-error" becomes "interrupted".
void absorb_raised_interrupt(const MechanicalModel& model, Solution& solution, py::object& slot) {
  py::object raised = take_raised_interrupt(model);
  if (raised.is_none()) return;
  if (slot.is_none()) slot = raised;
  if (solution.status == Status::kCallbackError) {
    solution.status = Status::kInterrupted;
    solution.message = "interrupted after step " + std::to_string(solution.steps_done) + " (" +
                       py::str(py::type::of(raised).attr("__name__")).cast<std::string>() +
                       " inside a model function)";
  }
}

std::unique_ptr<Run> run_problem(const ProblemSpec& spec, const RunOptions& run_options) {
  PreparedRun prepared = prepare_python_run(spec, run_options, "fracvi.integrate");
  const InitialValueProblem& problem = prepared.problem;
  IntegratorOptions& options = prepared.options;
  auto run = std::make_unique<Run>();
  run->spec = spec;
  options.interrupt = python_interrupt(run->interrupt);
  // Compiled formulas run without the GIL, so other Python threads run meanwhile (only the signal
  // handlers need it, python_interrupt). Python model functions need it at every call: the run
  // keeps it then (taking it back at each call costs more than the call, measured in
  // bench/python_functions_bench.py).
  std::optional<py::gil_scoped_release> release;
  if (!calls_python(problem.model)) release.emplace();
  if (options.tolerance > 0.0) {
    // method.tolerance: N doubled from time.steps until the error estimate meets it.
    run->solution = integrate_to_tolerance(problem, prepared.method, options);
  } else {
    run->solution = integrate(problem, prepared.method, options);
    // Accuracy, not consistency: Richardson from companion runs (analysis/error_estimate.hpp).
    estimate_error(problem, prepared.method, options, run->solution);
  }
  release.reset();
  absorb_raised_interrupt(problem.model, run->solution, run->interrupt);
  return run;
}

/// A Run from a Solution and the problem it solves, as the Python object fracvi.Solution wraps.
py::object make_run(const ProblemSpec& spec, Solution&& solution) {
  auto run = std::make_unique<Run>();
  run->spec = spec;
  run->solution = std::move(solution);
  return py::cast(std::move(run));
}

using InputArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// Copies arrays of `rows` rows (vectors, or rows × d matrices) into Eigen storage, refusing any
/// other shape with "<what>: <name> has shape (…); <why> make <rows> rows [of d values]".
struct RowsReader {
  py::ssize_t rows, d;
  std::string what, why;

  [[nodiscard]] Eigen::VectorXd vector(const InputArray& a, const char* name) const {
    check(a, name, a.ndim() == 1 && a.shape(0) == rows, false);
    return Eigen::Map<const Eigen::VectorXd>(a.data(), rows);
  }
  [[nodiscard]] RowMatrixXd matrix(const InputArray& a, const char* name) const {
    check(a, name, a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == d, true);
    return Eigen::Map<const RowMatrixXd>(a.data(), rows, d);
  }

 private:
  void check(const InputArray& a, const char* name, bool fits, bool matrix) const {
    if (fits) return;
    std::string shape = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) {
      shape += (i ? ", " : "") + std::to_string(a.shape(i));
    }
    shape += a.ndim() == 1 ? ",)" : ")";
    throw py::value_error(
        what + ": " + name + " has shape " + shape + "; " + why + " make " + std::to_string(rows) +
        " stored rows" +
        (matrix ? " of the problem's dim = " + std::to_string(d) + " values" : std::string()));
  }
};

/// A Run from what summary.json and the trajectory hold (fracvi.load, and unpickling): the
/// summary's fields (and event crossings) through read_summary, the step indices from steps and
/// save_every (stored_steps), the arrays checked against them and against the problem's
/// dimension; `output` None or the states at output.times (t, x, v: times.csv), as many as the
/// summary's output_times. `what` names the source in messages.
py::object restore_run(const ProblemSpec& spec, py::handle summary, const InputArray& t,
                       const InputArray& x, const InputArray& v, const InputArray& energy,
                       const InputArray& dissipated, const InputArray& balance,
                       const std::string& what, const py::object& output) {
  Solution s;
  const nlohmann::json json = from_python(summary, "", what);
  try {
    read_summary(json, s, what);
  } catch (const OutputError& e) {
    throw py::value_error(e.what());
  }
  if (s.events.x.size() != s.events.size() * static_cast<std::size_t>(spec.dim) ||
      s.events.v.size() != s.events.x.size()) {
    throw py::value_error(what +
                          ": \"events\" has crossings whose position or velocity do not "
                          "have the problem's dim = " +
                          std::to_string(spec.dim) + " values");
  }
  const auto output_times =
      json.contains("output_times") && json["output_times"].is_number_integer()
          ? std::max<py::ssize_t>(0, json["output_times"].get<py::ssize_t>())
          : py::ssize_t{0};
  if (!output.is_none() && output_times > 0) {
    const auto arrays = output.cast<py::tuple>();
    const RowsReader read_output{output_times, spec.dim, what,
                                 "the summary's output_times = " + std::to_string(output_times)};
    s.output_t = read_output.vector(arrays[0].cast<InputArray>(), "output t");
    s.output_x = read_output.matrix(arrays[1].cast<InputArray>(), "output x");
    s.output_v = read_output.matrix(arrays[2].cast<InputArray>(), "output v");
  } else {
    s.output_x.resize(0, spec.dim);
    s.output_v.resize(0, spec.dim);
  }
  s.step = stored_steps(s.steps_done, s.save_every);
  const RowsReader read{static_cast<py::ssize_t>(s.step.size()), spec.dim, what,
                        "the summary's steps = " + std::to_string(s.steps_done) +
                            " with save_every = " + std::to_string(s.save_every)};
  s.t = read.vector(t, "t");
  s.x = read.matrix(x, "x");
  s.v = read.matrix(v, "v");
  s.energy = read.vector(energy, "energy");
  s.dissipated = read.vector(dissipated, "dissipated");
  s.balance = read.vector(balance, "balance");
  return make_run(spec, std::move(s));
}

// ---------------------------------------------------------------------------------------------
// Stepping by hand (fracvi.Integrator).

/// A C++ Integrator driven from Python, with the problem it solves. It has no interrupt hook of
/// its own: run() looks at Python's signal handlers between steps (python_interrupt), so Ctrl-C
/// ends the call, not the integration, which run() or step() continue.
class Stepping {
 public:
  Stepping(const ProblemSpec& spec, const RunOptions& run_options)
      : prepared_(prepare_python_run(spec, run_options, "fracvi.Integrator")) {
    if (prepared_.options.tolerance > 0.0) {
      throw ProblemError(spec.source + ": method.tolerance = " +
                         repr_text(py::float_(prepared_.options.tolerance)) +
                         ": it doubles time.steps and reruns the problem until the error "
                         "estimate meets it, and an Integrator steps one grid (set it to 0, or "
                         "use fracvi.integrate)");
    }
    prepared_.spec = spec;
    try {
      integrator_ =
          std::make_unique<Integrator>(prepared_.problem, prepared_.method, prepared_.options);
    } catch (const ValidationError& e) {
      throw ProblemError(e.what());
    }
    momentum_.resize(prepared_.problem.model.dimension());
  }

  [[nodiscard]] std::string status() const { return std::string(to_string(integrator_->status())); }
  [[nodiscard]] std::size_t steps_done() const { return integrator_->steps_done(); }
  [[nodiscard]] std::size_t steps_total() const { return integrator_->steps_total(); }
  [[nodiscard]] double time() const { return integrator_->time(); }
  [[nodiscard]] const py::object& interrupt() const { return interrupt_; }

  /// (k, t, x, v, p, energy, dissipated, balance) now; the arrays are copies, p = M v.
  py::tuple state() {
    Unlocked::refuse_while(stepping_);
    const StepView view = integrator_->view();
    prepared_.problem.model.mass.multiply(view.v, momentum_);
    return py::make_tuple(view.k, view.t, vector_copy(view.x), vector_copy(view.v),
                          vector_copy(momentum_), view.energy, view.dissipated, view.balance);
  }

  std::string step() {
    interrupt_ = py::none();
    {
      // The GIL released: compiled formulas need none, Python model functions take it back.
      const Unlocked unlocked(stepping_);
      integrator_->step();
    }
    return raised_status();
  }

  /// Steps until step `target` (at most) is done or the run ends. observer(k, t, x, v, p, energy,
  /// dissipated, balance), if not None, is called for the current state when no step has been
  /// taken yet, then after every completed step; what it raises propagates (the integration stays
  /// at the last completed step). A signal handler that raises (Ctrl-C) stops the loop before the
  /// next step, its exception kept in interrupt().
  std::string run(std::size_t target, const py::object& observer) {
    interrupt_ = py::none();
    const auto interrupted = python_interrupt(interrupt_);
    Integrator& integ = *integrator_;
    const auto going = [&] {
      return integ.status() == Status::kRunning && integ.steps_done() < target;
    };
    if (observer.is_none()) {
      {
        const Unlocked unlocked(stepping_);
        while (going() && !interrupted()) integ.step();
      }
      return raised_status();
    }
    if (integ.steps_done() == 0) observer(*state());
    while (going() && !interrupted()) {
      const std::size_t before = integ.steps_done();
      Status s;
      {
        const Unlocked unlocked(stepping_);
        s = integ.step();
      }
      const bool stepped = integ.steps_done() != before;
      if (stepped && (s == Status::kRunning || s == Status::kSuccess || s == Status::kInaccurate)) {
        observer(*state());
      }
    }
    return raised_status();
  }

  /// The solution so far (Integrator::snapshot) as a Run. Once the integration has ended, the
  /// finished solution, made once: with the mirror run (if enabled and the run succeeded) and the
  /// error estimate, as fracvi.integrate returns it.
  py::object solution() {
    if (integrator_->status() == Status::kRunning) {
      return make_run(prepared_.spec, integrator_->snapshot());
    }
    if (!finished_.is_none()) return finished_;
    Solution s = integrator_->snapshot();
    py::object estimate_interrupt = py::none();
    {
      const Unlocked unlocked(stepping_);
      if (prepared_.options.mirror && s.status == Status::kSuccess) {
        const auto start = std::chrono::steady_clock::now();
        s.mirror_error = integrator_->mirror_error();
        s.wall_time_seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
      IntegratorOptions options = prepared_.options;
      options.interrupt = python_interrupt(estimate_interrupt);
      estimate_error(prepared_.problem, prepared_.method, options, s);
    }
    py::object run = make_run(prepared_.spec, std::move(s));
    if (!estimate_interrupt.is_none()) {
      run.cast<Run&>().interrupt = estimate_interrupt;  // not cached: asked again, estimated again
      return run;
    }
    finished_ = run;
    return finished_;
  }

  /// The solution so far with the status "interrupted": what a KeyboardInterrupt during run()
  /// carries. The Integrator itself goes on.
  py::object interrupted_solution() {
    Solution s = integrator_->snapshot();
    if (s.status == Status::kRunning) {
      s.status = Status::kInterrupted;
      s.message = "interrupted after step " + std::to_string(s.steps_done) + " of " +
                  std::to_string(integrator_->steps_total()) +
                  " (t = " + repr_text(py::float_(integrator_->time())) +
                  "); the Integrator can go on (run() or step())";
    }
    return make_run(prepared_.spec, std::move(s));
  }

 private:
  /// The GIL released while the Integrator steps (or finishes), so that other Python threads
  /// run meanwhile; one of them that uses this Integrator then gets a RuntimeError instead of a
  /// data race. The observer runs with the GIL held and the flag down: it may use it.
  class Unlocked {
   public:
    explicit Unlocked(bool& stepping) : stepping_(stepping) {
      refuse_while(stepping_);
      stepping_ = true;
      release_.emplace();
    }
    ~Unlocked() {
      release_.reset();  // the GIL first: the flag is only read and written with it held
      stepping_ = false;
    }
    Unlocked(const Unlocked&) = delete;
    Unlocked& operator=(const Unlocked&) = delete;
    static void refuse_while(bool stepping) {
      if (stepping) {
        throw std::runtime_error(
            "this fracvi.Integrator is stepping in another thread; use one Integrator per "
            "thread");
      }
    }

   private:
    bool& stepping_;
    std::optional<py::gil_scoped_release> release_;
  };

  /// status(), after keeping in interrupt() what a Python model function raised to interrupt
  /// (KeyboardInterrupt, SystemExit): the step that called it ended the run ("callback-error").
  std::string raised_status() {
    py::object raised = take_raised_interrupt(prepared_.problem.model);
    if (!raised.is_none() && interrupt_.is_none()) interrupt_ = raised;
    return status();
  }

  PreparedRun prepared_;
  std::unique_ptr<Integrator> integrator_;
  bool stepping_ = false;
  Eigen::VectorXd momentum_;
  py::object interrupt_ = py::none();  // what a signal handler raised during run()
  py::object finished_ = py::none();   // the Run of the ended integration, once made
};

// ---------------------------------------------------------------------------------------------
// Boundary value problems (`fracvi bvp`).

/// What solve_bvp produced, with the problem it solved (make_bvp_summary, write_bvp_output).
struct BvpRun {
  ProblemSpec spec;
  BvpSolution solution;
};

/// `fracvi bvp` from Python: prepare_bvp (the CLI's checks and messages: no [boundary], a scheme
/// without a boundary value form, …) and the CLI's --sum, --solver and --tolerance.
std::unique_ptr<BvpRun> run_bvp(const ProblemSpec& spec, const std::string& sum,
                                const std::string& solver, std::optional<double> tolerance) {
  PreparedBvp prepared;
  try {
    prepared = prepare_bvp(spec);
  } catch (const ProblemFileError& e) {
    throw ProblemError(e.what());
  }
  if (sum == "extended") {
    prepared.problem.sum = ActionSum::kExtended;
  } else if (sum == "printed") {
    prepared.problem.sum = ActionSum::kPrinted;
  } else {
    throw py::value_error("sum = '" + sum + "' must be 'extended' or 'printed'");
  }
  if (solver == "auto") {
    prepared.options.linear_solver = BvpLinearSolver::kAuto;
  } else if (solver == "dense") {
    prepared.options.linear_solver = BvpLinearSolver::kDense;
  } else if (solver == "krylov") {
    prepared.options.linear_solver = BvpLinearSolver::kKrylov;
  } else {
    throw py::value_error("solver = '" + solver + "' must be 'auto', 'dense' or 'krylov'");
  }
  // None: the default, which rises to the round-off floor (BvpOptions::above_round_off); a
  // tolerance given is taken as given.
  if (tolerance) {
    if (!(*tolerance > 0.0) || !std::isfinite(*tolerance)) {
      throw py::value_error("tolerance = " + repr_text(py::float_(*tolerance)) +
                            " must be a positive number");
    }
    prepared.options.residual_tolerance = *tolerance;
    prepared.options.above_round_off = false;
  }
  auto run = std::make_unique<BvpRun>();
  run->spec = spec;
  // The Lagrangian is a compiled formula: no Python runs during Newton's iterations.
  py::gil_scoped_release release;
  run->solution = solve_bvp(prepared.problem, prepared.options);
  return run;
}

/// What a pickled BvpSolution keeps: its fields and arrays (bvp_state), and the BvpRun again.
py::tuple bvp_state(py::object self) {
  const BvpSolution& s = self.cast<const BvpRun&>().solution;
  return py::make_tuple(std::string(to_string(s.status)), s.message, s.residual_norm,
                        s.residual_floor, s.residual_tolerance, s.residual_history,
                        s.newton_iterations, s.linear_iterations, s.linear_solver, s.sum,
                        s.wall_time_seconds, view(self, s.t.data(), s.t.size(), 0),
                        view(self, s.x.data(), s.x.rows(), s.x.cols()),
                        view(self, s.y.data(), s.y.rows(), s.y.cols()),
                        view(self, s.x_residual.data(), s.x_residual.rows(), s.x_residual.cols()),
                        view(self, s.y_residual.data(), s.y_residual.rows(), s.y_residual.cols()));
}

std::unique_ptr<BvpRun> restore_bvp_run(const ProblemSpec& spec, const py::tuple& state) {
  if (state.size() != 16) {
    throw py::value_error("<pickle>: a BvpSolution's state has 16 items, not " +
                          std::to_string(state.size()));
  }
  auto run = std::make_unique<BvpRun>();
  run->spec = spec;
  BvpSolution& s = run->solution;
  const auto status = state[0].cast<std::string>();
  const auto parsed = parse_status(status);
  if (!parsed) throw py::value_error("<pickle>: status = '" + status + "' is not a status");
  s.status = *parsed;
  s.message = state[1].cast<std::string>();
  s.residual_norm = state[2].cast<double>();
  s.residual_floor = state[3].cast<double>();
  s.residual_tolerance = state[4].cast<double>();
  s.residual_history = state[5].cast<std::vector<double>>();
  s.newton_iterations = state[6].cast<int>();
  s.linear_iterations = state[7].cast<std::size_t>();
  s.linear_solver = state[8].cast<std::string>();
  s.sum = state[9].cast<std::string>();
  s.wall_time_seconds = state[10].cast<double>();
  const auto t = state[11].cast<InputArray>();
  const RowsReader read{t.ndim() == 1 ? t.shape(0) : 0, spec.dim, "<pickle>", "the grid's t"};
  s.t = read.vector(t, "t");
  s.x = read.matrix(state[12].cast<InputArray>(), "x");
  s.y = read.matrix(state[13].cast<InputArray>(), "y");
  s.x_residual = read.matrix(state[14].cast<InputArray>(), "x_residual");
  s.y_residual = read.matrix(state[15].cast<InputArray>(), "y_residual");
  return run;
}

// ---------------------------------------------------------------------------------------------
// Arrays owned by C++ buffers.

template <class Buffer>
py::array adopt(std::unique_ptr<Buffer> buffer, std::vector<py::ssize_t> shape,
                std::vector<py::ssize_t> strides) {
  const double* data = buffer->data();
  py::capsule owner(buffer.get(), [](void* p) { delete static_cast<Buffer*>(p); });
  buffer.release();  // the capsule owns it now
  return py::array(py::dtype::of<double>(), std::move(shape), std::move(strides), data, owner);
}

constexpr py::ssize_t kDoubleSize = static_cast<py::ssize_t>(sizeof(double));

py::array adopt_vector(std::vector<double>&& v) {
  const auto n = static_cast<py::ssize_t>(v.size());
  return adopt(std::make_unique<std::vector<double>>(std::move(v)), {n}, {kDoubleSize});
}

// ---------------------------------------------------------------------------------------------
// Sequences (operators.hpp).

Sequence to_sequence(const InputArray& z, const char* op) {
  if (z.ndim() == 1) return Eigen::Map<const Eigen::MatrixXd>(z.data(), 1, z.shape(0));
  if (z.ndim() == 2) return Eigen::Map<const Eigen::MatrixXd>(z.data(), z.shape(1), z.shape(0));
  throw py::value_error(std::string(op) + ": z has " + std::to_string(z.ndim()) +
                        " dimensions; a sequence z_0..z_N is an array of shape (N+1,) or "
                        "(N+1, d) whose row k is z_k");
}

/// The d × (N+1) result as an (N+1, d) array (or (N+1,) if the input was one-dimensional).
py::array from_sequence(Sequence&& s, const InputArray& like) {
  const py::ssize_t d = s.rows();
  const py::ssize_t n1 = s.cols();
  auto buffer = std::make_unique<Sequence>(std::move(s));
  if (like.ndim() == 1) return adopt(std::move(buffer), {n1}, {kDoubleSize});
  return adopt(std::move(buffer), {n1, d}, {d * kDoubleSize, kDoubleSize});
}

/// The generating function δ(ζ) of a convolution quadrature by name (fracvi weights --scheme).
CqScheme parse_quadrature(const std::string& name, const char* op) {
  if (const auto q = parse_cq_scheme(name)) return *q;
  throw py::value_error(std::string(op) + ": quadrature = '" + name +
                        "' is not a known convolution quadrature (choose gl, bdf2 or "
                        "trapezoidal)");
}

void require_step(double h) {
  if (!(h > 0.0) || !std::isfinite(h)) {
    throw py::value_error("h = " + repr_text(py::float_(h)) + " must be a positive finite step");
  }
}

// ---------------------------------------------------------------------------------------------
// Riemann–Liouville derivatives.

Side parse_side(const std::string& side) {
  if (side == "left") return Side::kLeft;
  if (side == "right") return Side::kRight;
  throw py::value_error("side = '" + side + "' must be 'left' or 'right'");
}

Expression parse_function_of_t(const std::string& name, const std::string& text) {
  try {
    return Expression::parse(text, {"t"});
  } catch (const ExpressionError& e) {
    // The wording of `fracvi derivative --f`.
    throw py::value_error(name + " = \"" + text + "\": " + e.reason() + " at column " +
                          std::to_string(e.column() + 1) + " (a formula in t)");
  }
}

RealFunction expression_function(Expression e) {
  return [e = std::move(e)](double t) { return e({t}); };
}

/// A Python callable as a RealFunction. Called with the GIL held (rl_derivative runs on this
/// thread); a Python exception propagates through the quadrature as error_already_set.
RealFunction callable_function(py::handle f, const std::string& name) {
  if (!PyCallable_Check(f.ptr())) {
    throw py::type_error(name + " must be a callable or a formula in t (a string), not " +
                         repr_text(f));
  }
  auto fn = py::reinterpret_borrow<py::object>(f);
  return [fn](double t) { return fn(t).cast<double>(); };
}

std::pair<RealFunction, RealFunction> function_and_derivative(py::handle f, py::handle df) {
  RealFunction fv, dfv;
  if (py::isinstance<py::str>(f)) {
    const Expression e = parse_function_of_t("f", f.cast<std::string>());
    fv = expression_function(e);
    if (df.is_none()) dfv = expression_function(e.derivative(0));  // exact, symbolic
  } else {
    fv = callable_function(f, "f");
    if (df.is_none()) {
      throw py::value_error(
          "rl_derivative: f is a Python callable, so df (its derivative f') is required: fracvi "
          "never differentiates numerically. Pass df=<callable>, or give f as a formula in t, "
          "e.g. \"t^1.5*exp(-t)\", whose derivative is then exact");
    }
  }
  if (!df.is_none()) {
    dfv = py::isinstance<py::str>(df)
              ? expression_function(parse_function_of_t("df", df.cast<std::string>()))
              : callable_function(df, "df");
  }
  return {std::move(fv), std::move(dfv)};
}

/// Applies value(t) to a scalar (returns a float) or elementwise to an array (same shape).
template <class Value>
py::object map_points(py::handle t, Value&& value) {
  auto points = InputArray::ensure(t);
  if (!points)
    throw py::type_error("t must be a number or an array of numbers, not " + repr_text(t));
  if (points.ndim() == 0) return py::float_(value(*points.data()));
  std::vector<py::ssize_t> shape(points.shape(), points.shape() + points.ndim());
  py::array_t<double> out(shape);
  const double* in = points.data();
  double* o = out.mutable_data();
  for (py::ssize_t i = 0; i < points.size(); ++i) o[i] = value(in[i]);
  return out;
}

// A curve x(t) ∈ R^d for `FracEL` and the action: a formula in t (str, d = 1), a list of d
// formulas (derivatives exact, from the expression engine), or a tuple of three callables
// (x, x', x''), each t -> float (d = 1) or a sequence of d floats: fracvi never differentiates
// numerically, so callables bring their derivatives.
Curve python_curve(py::handle c, Eigen::Index d, const std::string& name) {
  auto wrong_dimension = [&](std::size_t n) {
    return py::value_error(name + " has " + std::to_string(n) +
                           " components, the problem's dim is " + std::to_string(d));
  };
  if (py::isinstance<py::str>(c)) {
    if (d != 1) throw wrong_dimension(1);
    return make_expression_curve({parse_function_of_t(name, c.cast<std::string>()).text()});
  }
  if (!py::isinstance<py::sequence>(c)) {
    throw py::type_error(name +
                         " must be a formula in t (str), a list of d formulas or a tuple "
                         "(x, xdot, xddot) of callables, not " +
                         repr_text(c));
  }
  const auto items = c.cast<py::sequence>();
  bool all_text = items.size() > 0;
  for (auto item : items) all_text = all_text && py::isinstance<py::str>(item);
  if (all_text) {
    if (static_cast<Eigen::Index>(items.size()) != d) throw wrong_dimension(items.size());
    std::vector<std::string> formulas;
    for (auto item : items) {
      formulas.push_back(parse_function_of_t(name, item.cast<std::string>()).text());
    }
    return make_expression_curve(formulas);
  }
  if (items.size() != 3) {
    throw py::value_error(name +
                          " given as callables must be a tuple (x, xdot, xddot) of three "
                          "(fracvi does not differentiate numerically), not " +
                          std::to_string(items.size()) + " items");
  }
  std::vector<py::object> parts;
  for (auto item : items) {
    if (!PyCallable_Check(item.ptr())) {
      throw py::type_error(name + ": every item of (x, xdot, xddot) must be callable, not " +
                           repr_text(item));
    }
    parts.push_back(py::reinterpret_borrow<py::object>(item));
  }
  Curve curve;
  curve.dimension = d;
  curve.evaluate = [parts, d, name](double t, int order, Eigen::Ref<Eigen::MatrixXd> out) {
    for (int k = 0; k <= order; ++k) {
      const py::object v = parts[static_cast<std::size_t>(k)](t);
      if (d == 1 && !py::isinstance<py::sequence>(v)) {
        out(0, k) = v.cast<double>();
        continue;
      }
      const auto values = v.cast<std::vector<double>>();
      if (static_cast<Eigen::Index>(values.size()) != d) {
        throw py::value_error(name + ": the callable for derivative " + std::to_string(k) +
                              " returned " + std::to_string(values.size()) +
                              " values, the problem's dim is " + std::to_string(d));
      }
      for (Eigen::Index i = 0; i < d; ++i) out(i, k) = values[static_cast<std::size_t>(i)];
    }
  };
  return curve;
}

/// `calls` (the Python model functions of `spec`, `f`) once at the initial state `where`: what
/// goes wrong is a ProblemError naming the field and the rule, a Ctrl-C inside them is raised.
template <class ModelFunction, class Calls>
void check_at_initial_state(const ProblemSpec& spec, const std::shared_ptr<const ModelFunction>& f,
                            const char* where, Calls&& calls) {
  if (spec.position.size() != spec.dim) return;  // a boundary value problem without [initial]
  try {
    calls();
  } catch (const std::runtime_error& e) {
    py::object raised = python::take_raised_interrupt(f);
    if (!raised.is_none()) {  // Ctrl-C inside the function: raise it, not a ProblemError
      PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(raised.ptr())), raised.ptr());
      throw py::error_already_set();
    }
    throw ProblemError(spec.source + ": at the initial state (" + where + " = " +
                       repr_text(py::float_(spec.start)) + "): " + e.what());
  }
}

/// `spec` with U given as Python functions (callables.hpp) in place of its formula, labelled
/// `label` (kPythonFunctionPrefix...). The functions are called once at (x(t0), t0), so that a
/// function that fails or returns the wrong shape is reported now, naming the field and the rule,
/// and not at the first step.
ProblemSpec with_python_potential(const ProblemSpec& spec, const std::string& label,
                                  py::object value, py::object gradient, py::object hessian) {
  if (spec.chain || !spec.lagrangian.empty()) {
    throw ProblemError(spec.source + ": potential=<function> and " +
                       (spec.chain ? "model.chain" : "model.lagrangian") +
                       " are both given; give one (the function replaces the potential formula)");
  }
  ProblemSpec s = spec;
  s.potential = label;
  s.potential_object = python::make_python_potential(s.dim, std::move(value), std::move(gradient),
                                                     std::move(hessian));
  check_at_initial_state(s, s.potential_object, "x(t0), t0", [&] {
    const Potential& u = *s.potential_object;
    Eigen::VectorXd g(s.dim);
    Eigen::MatrixXd h(s.dim, s.dim);
    (void)u.value(s.position, s.start);
    u.gradient(s.position, s.start, g);
    u.hessian(s.position, s.start, h);
  });
  return s;
}

/// `spec` with the force given as a Python function g(x, v, t) (callables.hpp) in place of its
/// formulas, labelled {label}; checked once at (x(t0), v(t0), t0) as with_python_potential does.
ProblemSpec with_python_force(const ProblemSpec& spec, const std::string& label, py::object force,
                              py::object jacobian) {
  if (!spec.lagrangian.empty()) {
    throw ProblemError(spec.source +
                       ": force=<function> and model.lagrangian are both given: a general "
                       "Lagrangian has no non-conservative force (g(x, v, t) has no Lagrangian)");
  }
  ProblemSpec s = spec;
  s.force = {label};
  s.force_object = python::make_python_force(s.dim, std::move(force), std::move(jacobian));
  check_at_initial_state(s, s.force_object, "x(t0), v(t0), t0", [&] {
    Eigen::VectorXd g(s.dim);
    Eigen::MatrixXd dx(s.dim, s.dim), dv(s.dim, s.dim);
    s.force_object->jacobians(s.position, s.velocity, s.start, g, dx, dv);
  });
  return s;
}

}  // namespace

void bind(py::module_& m) {
  m.doc() = "Native layer of the fracvi package (use the fracvi module, not this one).";
  py::register_exception<ProblemError>(m, "ProblemError", PyExc_ValueError);

  // --- problems ----------------------------------------------------------------------------
  py::class_<ProblemSpec>(m, "Spec", "A validated problem (C++ fracvi::ProblemSpec).")
      .def_readonly("source", &ProblemSpec::source)
      .def_readonly("name", &ProblemSpec::name)
      .def_property_readonly("dim", [](const ProblemSpec& s) { return s.dim; })
      .def_property_readonly("mass", [](const ProblemSpec& s) { return model_matrix(s.mass); })
      .def_property_readonly("damping",
                             [](const ProblemSpec& s) { return model_matrix(s.damping); })
      .def_property_readonly("chain", &chain_dict)
      .def_readonly("alpha", &ProblemSpec::alpha)
      .def_readonly("convention", &ProblemSpec::convention)
      .def_readonly("potential", &ProblemSpec::potential)
      .def_readonly("force", &ProblemSpec::force)
      .def_readonly("format", &ProblemSpec::format)
      .def_readonly("lagrangian", &ProblemSpec::lagrangian)
      .def_property_readonly("position",
                             [](const ProblemSpec& s) { return vector_copy(s.position); })
      .def_property_readonly("velocity",
                             [](const ProblemSpec& s) { return vector_copy(s.velocity); })
      .def_property_readonly("boundary_start",
                             [](const ProblemSpec& s) { return vector_copy(s.boundary_start); })
      .def_property_readonly("boundary_end",
                             [](const ProblemSpec& s) { return vector_copy(s.boundary_end); })
      .def_readonly("start", &ProblemSpec::start)
      .def_readonly("end", &ProblemSpec::end)
      .def_readonly("steps", &ProblemSpec::steps)
      .def_property_readonly("step", &ProblemSpec::step)
      .def_readonly("scheme", &ProblemSpec::scheme)
      .def_readonly("newton_tolerance", &ProblemSpec::newton_tolerance)
      .def_readonly("newton_max_iterations", &ProblemSpec::newton_max_iterations)
      .def_readonly("history", &ProblemSpec::history)
      .def_readonly("history_tolerance", &ProblemSpec::history_tolerance)
      .def_readonly("abs_tolerance", &ProblemSpec::abs_tolerance)
      .def_readonly("rel_tolerance", &ProblemSpec::rel_tolerance)
      .def_readonly("linear_solver", &ProblemSpec::linear_solver)
      .def_readonly("load", &ProblemSpec::load)
      .def_readonly("split", &ProblemSpec::split)
      .def_readonly("error_estimate", &ProblemSpec::error_estimate)
      .def_readonly("tolerance", &ProblemSpec::tolerance)
      .def_readonly("max_steps", &ProblemSpec::max_steps)
      .def_readonly("threads", &ProblemSpec::threads)
      .def_readonly("flush_subnormals", &ProblemSpec::flush_subnormals)
      .def_property_readonly("every",
                             [](const ProblemSpec& s) -> py::object {
                               if (s.every == kAutoEvery) return py::str("auto");
                               return py::int_(s.every);
                             })
      .def("to_dict", [](const ProblemSpec& s) { return to_python(to_json(s)); })
      .def("to_toml", [](const ProblemSpec& s) { return to_toml(s); });

  m.def(
      "parse_toml",
      [](const std::string& text, const std::string& source,
         const std::vector<std::string>& overrides) {
        return checked_spec([&] { return parse_problem(text, source, overrides); });
      },
      py::arg("text"), py::arg("source"), py::arg("overrides"));
  m.def(
      "load_toml",
      [](const std::string& path, const std::vector<std::string>& overrides) {
        return checked_spec([&] { return load_problem(path, overrides); });
      },
      py::arg("path"), py::arg("overrides"));
  m.def(
      "parse_dict",
      [](py::handle document, const std::string& source,
         const std::vector<std::string>& overrides) {
        const nlohmann::json json = from_python(document, "", source);
        return checked_spec([&] { return parse_problem_json(json, source, overrides); });
      },
      py::arg("document"), py::arg("source"), py::arg("overrides"));
  m.def("default_problem_toml", [] { return std::string(default_problem_toml()); });
  m.def("with_python_potential", &with_python_potential, py::arg("spec"), py::arg("label"),
        py::arg("value"), py::arg("gradient"), py::arg("hessian"));
  m.def("with_python_force", &with_python_force, py::arg("spec"), py::arg("label"),
        py::arg("force"), py::arg("jacobian"));

  // --- solutions ---------------------------------------------------------------------------
  py::class_<Run>(m, "Run", "A Solution and the problem it solves (C++ fracvi::Solution).")
      .def_readonly("interrupt", &Run::interrupt,
                    "the exception a signal handler raised during the run (KeyboardInterrupt), "
                    "or None")
      .def_property_readonly("t",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.t.data(), s.t.size(), 0);
                             })
      .def_property_readonly("x",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.x.data(), s.x.rows(), s.x.cols());
                             })
      .def_property_readonly("v",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.v.data(), s.v.rows(), s.v.cols());
                             })
      .def_property_readonly("energy",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.energy.data(), s.energy.size(), 0);
                             })
      .def_property_readonly("dissipated",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.dissipated.data(), s.dissipated.size(), 0);
                             })
      .def_property_readonly("balance",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.balance.data(), s.balance.size(), 0);
                             })
      .def_property_readonly(
          "step",
          [](const Run& r) {
            const auto& steps = r.solution.step;
            py::array_t<std::int64_t> out(static_cast<py::ssize_t>(steps.size()));
            std::copy(steps.begin(), steps.end(), out.mutable_data());
            return out;
          })
      .def_property_readonly("save_every", [](const Run& r) { return r.solution.save_every; })
      .def_property_readonly("linear_solver", [](const Run& r) { return r.solution.linear_solver; })
      .def_property_readonly("status",
                             [](const Run& r) { return std::string(to_string(r.solution.status)); })
      .def_property_readonly("ok", [](const Run& r) { return r.solution.ok(); })
      .def_property_readonly("message", [](const Run& r) { return r.solution.message; })
      .def_property_readonly("steps", [](const Run& r) { return r.solution.steps_done; })
      .def_property_readonly("newton_iterations",
                             [](const Run& r) { return r.solution.newton_iterations; })
      .def_property_readonly("max_newton_iterations_per_step",
                             [](const Run& r) { return r.solution.max_newton_iterations_per_step; })
      .def_property_readonly("jacobian_factorizations",
                             [](const Run& r) { return r.solution.jacobian_factorizations; })
      .def_property_readonly("mirror_error", [](const Run& r) { return r.solution.mirror_error; })
      .def_property_readonly("error_estimate",
                             [](const Run& r) { return r.solution.error_estimate.value; })
      .def_property_readonly("max_balance_error",
                             [](const Run& r) { return r.solution.max_balance_error; })
      .def_property_readonly("wall_time", [](const Run& r) { return r.solution.wall_time_seconds; })
      .def_property_readonly("setup_time", [](const Run& r) { return r.solution.setup_seconds; })
      .def_property_readonly("history_tolerance",
                             [](const Run& r) { return r.solution.history_tolerance; })
      .def_property_readonly("history_tolerance_auto",
                             [](const Run& r) { return r.solution.history_tolerance_auto; })
      .def_property_readonly("history_limited",
                             [](const Run& r) { return r.solution.history_limited; })
      .def_property_readonly("history", [](const Run& r) { return r.solution.history; })
      .def_property_readonly("history_bytes", [](const Run& r) { return r.solution.history_bytes; })
      .def_property_readonly("history_exponentials",
                             [](const Run& r) { return r.solution.history_exponentials; })
      .def_property_readonly("history_window",
                             [](const Run& r) { return r.solution.history_window; })
      .def_property_readonly("method", [](const Run& r) { return r.solution.method; })
      .def_property_readonly("declared_order",
                             [](const Run& r) { return r.solution.declared_order; })
      .def_property_readonly("spec", [](const Run& r) { return r.spec; })
      .def_property_readonly("output_t",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.output_t.data(), s.output_t.size(), 0);
                             })
      .def_property_readonly("output_x",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.output_x.data(), s.output_x.rows(),
                                           s.output_x.cols());
                             })
      .def_property_readonly("output_v",
                             [](py::object self) {
                               const auto& s = self.cast<const Run&>().solution;
                               return view(self, s.output_v.data(), s.output_v.rows(),
                                           s.output_v.cols());
                             })
      .def_property_readonly(
          "events",
          [](const Run& r) {
            // (name, t, direction (+1/-1), step, x, v) per crossing, in time order; copies.
            const EventLog& log = r.solution.events;
            const Eigen::Index d = r.solution.x.cols();
            py::list out;
            for (std::size_t i = 0; i < log.size(); ++i) {
              const auto at = static_cast<Eigen::Index>(i) * d;
              out.append(py::make_tuple(
                  log.names[log.event[i]], log.t[i], log.direction[i], log.step[i],
                  vector_copy(Eigen::Map<const Eigen::VectorXd>(log.x.data() + at, d)),
                  vector_copy(Eigen::Map<const Eigen::VectorXd>(log.v.data() + at, d))));
            }
            return out;
          })
      .def(
          "interpolate",
          [](const Run& r, double t) {
            const Eigen::Index d = r.solution.x.cols();
            Eigen::VectorXd x(d), v(d);
            try {
              interpolate(r.solution, t, x, v);
            } catch (const ValidationError& e) {
              throw py::value_error(e.what());
            }
            return py::make_tuple(vector_copy(x), vector_copy(v));
          },
          py::arg("t"))
      .def(
          "summary",
          [](const Run& r, const ProblemSpec* spec) {
            return to_python(make_summary(spec ? *spec : r.spec, r.solution));
          },
          py::arg("spec") = nullptr)
      .def("summary_and_columns",
           [](py::object self) {
             // What pickling keeps (restore_run makes the Run again): summary.json's content and
             // the columns of trajectory.csv, as views (pickle copies them).
             const Run& r = self.cast<const Run&>();
             const Solution& s = r.solution;
             return py::make_tuple(
                 to_python(make_summary(r.spec, s)), view(self, s.t.data(), s.t.size(), 0),
                 view(self, s.x.data(), s.x.rows(), s.x.cols()),
                 view(self, s.v.data(), s.v.rows(), s.v.cols()),
                 view(self, s.energy.data(), s.energy.size(), 0),
                 view(self, s.dissipated.data(), s.dissipated.size(), 0),
                 view(self, s.balance.data(), s.balance.size(), 0),
                 py::make_tuple(
                     view(self, s.output_t.data(), s.output_t.size(), 0),
                     view(self, s.output_x.data(), s.output_x.rows(), s.output_x.cols()),
                     view(self, s.output_v.data(), s.output_v.rows(), s.output_v.cols())));
           })
      .def(
          "write",
          [](const Run& r, const std::string& directory, const ProblemSpec* spec,
             const std::string& format) {
            write_run_output(directory, spec ? *spec : r.spec, r.solution, format);
          },
          py::arg("directory"), py::arg("spec") = nullptr, py::arg("format") = "");

  // fracvi.sweep: the cases of `fracvi sweep` on local threads; returns (columns, rows) of
  // results.csv in case order, each row its fields as text (the Python side makes NumPy columns).
  m.def(
      "sweep",
      [](py::handle document, const std::string& source, const std::string& directory, int jobs,
         const std::string& out, bool resume) {
        const nlohmann::json json = from_python(document, "", source);
        SweepSpec sweep;
        try {
          sweep = make_sweep(json, source, directory);
        } catch (const SweepError& e) {
          throw ProblemError(e.what());
        }
        std::vector<std::pair<std::size_t, std::string>> rows;
        {
          py::gil_scoped_release release;
          SweepCaseOptions options;
          options.single_thread = true;
          std::unique_ptr<SweepTable> table;
          std::vector<std::size_t> pending;
          if (!out.empty()) {
            options.out = out;
            try {
              table = std::make_unique<SweepTable>(out, sweep, resume);
            } catch (const SweepError& e) {
              throw ProblemError(e.what());
            }
          }
          for (const auto& c : sweep.cases) {
            if (!table || !table->done().contains(c.index)) pending.push_back(c.index);
          }
          run_sweep_local(sweep, pending, jobs, options,
                          [&](std::size_t index, const std::string& row) {
                            if (table) {
                              table->append(index, row);
                            } else {
                              rows.emplace_back(index, row);
                            }
                          });
          if (table) {
            table->finish();
            rows = table->rows();
          }
          std::sort(rows.begin(), rows.end());
        }
        py::list out_rows;
        for (const auto& [index, row] : rows) {
          out_rows.append(split_csv_line(std::string_view(row).substr(0, row.size() - 1)));
        }
        return py::make_tuple(sweep_columns(sweep), out_rows);
      },
      py::arg("document"), py::arg("source"), py::arg("directory"), py::arg("jobs"), py::arg("out"),
      py::arg("resume"));

  py::class_<RunOptions>(m, "RunOptions", "The run options of integrate() and Integrator.")
      .def(py::init([](bool diagnostics, double absolute_tolerance, const std::string& history,
                       const std::string& start, const std::vector<py::tuple>& events) {
             return RunOptions{diagnostics, absolute_tolerance, history, start, events};
           }),
           py::arg("diagnostics"), py::arg("absolute_tolerance"), py::arg("history"),
           py::arg("start"), py::arg("events") = std::vector<py::tuple>{});

  m.def("integrate", &run_problem, py::arg("spec"), py::arg("options"));
  m.def("restore_run", &restore_run, py::arg("spec"), py::arg("summary"), py::arg("t"),
        py::arg("x"), py::arg("v"), py::arg("energy"), py::arg("dissipated"), py::arg("balance"),
        py::arg("what"), py::arg("output") = py::none());

  py::class_<Stepping>(m, "Stepping", "A C++ Integrator stepped from Python (fracvi.Integrator).")
      .def(py::init<const ProblemSpec&, const RunOptions&>(), py::arg("spec"), py::arg("options"))
      .def_property_readonly("status", &Stepping::status)
      .def_property_readonly("steps_done", &Stepping::steps_done)
      .def_property_readonly("steps_total", &Stepping::steps_total)
      .def_property_readonly("time", &Stepping::time)
      .def_property_readonly("interrupt", &Stepping::interrupt)
      .def("state", &Stepping::state)
      .def("step", &Stepping::step)
      .def("run", &Stepping::run, py::arg("target"), py::arg("observer"))
      .def("solution", &Stepping::solution)
      .def("interrupted_solution", &Stepping::interrupted_solution);

  // --- boundary value problems ---------------------------------------------------------------
  py::class_<BvpRun>(m, "BvpRun",
                     "A BvpSolution and the problem it solves (C++ fracvi::BvpSolution).")
      .def_property_readonly("t",
                             [](py::object self) {
                               const auto& s = self.cast<const BvpRun&>().solution;
                               return view(self, s.t.data(), s.t.size(), 0);
                             })
      .def_property_readonly("x",
                             [](py::object self) {
                               const auto& s = self.cast<const BvpRun&>().solution;
                               return view(self, s.x.data(), s.x.rows(), s.x.cols());
                             })
      .def_property_readonly("y",
                             [](py::object self) {
                               const auto& s = self.cast<const BvpRun&>().solution;
                               return view(self, s.y.data(), s.y.rows(), s.y.cols());
                             })
      .def_property_readonly("x_residual",
                             [](py::object self) {
                               const auto& s = self.cast<const BvpRun&>().solution;
                               return view(self, s.x_residual.data(), s.x_residual.rows(),
                                           s.x_residual.cols());
                             })
      .def_property_readonly("y_residual",
                             [](py::object self) {
                               const auto& s = self.cast<const BvpRun&>().solution;
                               return view(self, s.y_residual.data(), s.y_residual.rows(),
                                           s.y_residual.cols());
                             })
      .def_property_readonly(
          "status", [](const BvpRun& r) { return std::string(to_string(r.solution.status)); })
      .def_property_readonly("ok", [](const BvpRun& r) { return r.solution.ok(); })
      .def_property_readonly("message", [](const BvpRun& r) { return r.solution.message; })
      .def_property_readonly("residual_norm",
                             [](const BvpRun& r) { return r.solution.residual_norm; })
      .def_property_readonly("residual_floor",
                             [](const BvpRun& r) { return r.solution.residual_floor; })
      .def_property_readonly("residual_tolerance",
                             [](const BvpRun& r) { return r.solution.residual_tolerance; })
      .def_property_readonly("residual_history",
                             [](const BvpRun& r) { return r.solution.residual_history; })
      .def_property_readonly("newton_iterations",
                             [](const BvpRun& r) { return r.solution.newton_iterations; })
      .def_property_readonly("linear_iterations",
                             [](const BvpRun& r) { return r.solution.linear_iterations; })
      .def_property_readonly("linear_solver",
                             [](const BvpRun& r) { return r.solution.linear_solver; })
      .def_property_readonly("sum", [](const BvpRun& r) { return r.solution.sum; })
      .def_property_readonly("wall_time",
                             [](const BvpRun& r) { return r.solution.wall_time_seconds; })
      .def_property_readonly("spec", [](const BvpRun& r) { return r.spec; })
      .def("summary",
           [](const BvpRun& r) { return to_python(make_bvp_summary(r.spec, r.solution)); })
      .def(
          "write",
          [](const BvpRun& r, const std::string& directory) {
            write_bvp_output(directory, r.spec, r.solution);
          },
          py::arg("directory"));

  // --- the comparison of schemes (fracvi/analysis/comparison.hpp, `fracvi compare`) -----------
  m.def(
      "compare",
      [](const ProblemSpec& spec, const std::vector<std::string>& schemes,
         const std::vector<std::size_t>& steps, const std::vector<std::string>& exact,
         std::size_t reference_steps, const std::string& reference_scheme, std::size_t energy_steps,
         int repeat) {
        ComparisonSetup setup;
        setup.schemes = schemes;
        setup.steps = steps;
        setup.exact = exact;
        setup.reference_steps = reference_steps;
        setup.reference_scheme = reference_scheme;
        setup.options.energy_steps = energy_steps;
        setup.options.repeat = repeat;
        Comparison c;
        {
          py::gil_scoped_release release;
          c = compare_schemes(spec, setup);
        }
        const std::size_t n = c.rows.size();
        py::dict table;
        py::list scheme, status, message;
        py::array_t<std::int64_t> nsteps(static_cast<py::ssize_t>(n)), order(nsteps.size()),
            newton(nsteps.size());
        std::vector<py::array_t<double>> reals;
        const char* real_names[] = {"h",
                                    "final_error",
                                    "max_error",
                                    "energy_error",
                                    "dissipated_error",
                                    "balance_error",
                                    "wall_seconds"};
        for (std::size_t j = 0; j < std::size(real_names); ++j) reals.emplace_back(nsteps.size());
        for (std::size_t i = 0; i < n; ++i) {
          const ComparisonRow& r = c.rows[i];
          scheme.append(r.scheme);
          status.append(r.status);
          message.append(r.message);
          nsteps.mutable_at(i) = static_cast<std::int64_t>(r.steps);
          order.mutable_at(i) = r.declared_order;
          newton.mutable_at(i) = static_cast<std::int64_t>(r.newton_iterations);
          const double values[] = {r.h,
                                   r.final_error,
                                   r.max_error,
                                   r.energy_error,
                                   r.dissipated_error,
                                   r.balance_error,
                                   r.wall_seconds};
          for (std::size_t j = 0; j < std::size(values); ++j) reals[j].mutable_at(i) = values[j];
        }
        table["scheme"] = scheme;
        table["steps"] = nsteps;
        table["declared_order"] = order;
        table["status"] = status;
        for (std::size_t j = 0; j < std::size(real_names); ++j) table[real_names[j]] = reals[j];
        table["newton_iterations"] = newton;
        table["message"] = message;
        py::dict energy;
        const EnergyTrack& e = c.energy;
        energy["steps"] = e.steps;
        energy["t"] = e.t;
        energy["reference_energy"] = e.reference_energy;
        energy["reference_dissipated"] = e.reference_dissipated;
        py::dict energies, dissipated;
        for (std::size_t j = 0; j < e.schemes.size(); ++j) {
          energies[py::str(e.schemes[j])] = e.energy[j];
          dissipated[py::str(e.schemes[j])] = e.dissipated[j];
        }
        energy["energy"] = energies;
        energy["dissipated"] = dissipated;
        py::dict out;
        out["table"] = table;
        out["reference"] = c.reference;
        out["energy_reference"] = c.energy_reference;
        out["energy"] = energy;
        return out;
      },
      py::arg("spec"), py::arg("schemes"), py::arg("steps"), py::arg("exact"),
      py::arg("reference_steps"), py::arg("reference_scheme"), py::arg("energy_steps"),
      py::arg("repeat"));

  m.def("solve_bvp", &run_bvp, py::arg("spec"), py::arg("sum"), py::arg("solver"),
        py::arg("tolerance"));
  m.def("bvp_state", &bvp_state, py::arg("run"));
  m.def("restore_bvp_run", &restore_bvp_run, py::arg("spec"), py::arg("state"));

  // --- weights -----------------------------------------------------------------------------
  m.def(
      "gl_weights",
      [](double order, std::int64_t n) {
        if (n < 0) throw py::value_error("n = " + std::to_string(n) + " must not be negative");
        return adopt_vector(gl_weights(order, static_cast<std::size_t>(n)));
      },
      py::arg("order"), py::arg("n"));
  m.def(
      "cq_weights",
      [](double order, std::int64_t n, const std::string& scheme) {
        const auto s = parse_cq_scheme(scheme);
        if (!s) {
          throw py::value_error("scheme = '" + scheme +
                                "' is not a known scheme (choose gl, bdf2 or trapezoidal)");
        }
        if (n < 0) throw py::value_error("n = " + std::to_string(n) + " must not be negative");
        return adopt_vector(cq_weights(*s, order, static_cast<std::size_t>(n)));
      },
      py::arg("order"), py::arg("n"), py::arg("scheme"));

  // --- the problem-file schema (io/problem_schema.hpp) ------------------------------------------
  m.def("problem_schema", []() {
    py::list out;
    for (const ProblemField& f : problem_schema()) {
      py::dict row;
      row["section"] = f.section;
      row["key"] = f.key;
      row["type"] = f.type;
      row["default"] = f.default_text;
      row["summary"] = f.summary;
      row["binding"] = f.binding;
      out.append(row);
    }
    return out;
  });

  // --- the method registry ---------------------------------------------------------------------
  m.def("methods", []() {
    py::list out;
    for (const SchemeRow& r : scheme_table()) {
      py::dict row;
      row["name"] = r.name;
      row["order"] = r.order;
      row["stages"] = r.stages;
      row["variational"] = r.variational;
      row["mirror"] = r.mirror;
      row["exact_balance"] = r.exact_balance;
      row["fast_history"] = r.fast_history;
      row["adaptive"] = r.adaptive;
      row["applies_to"] = r.applies_to;
      row["stability"] = r.stability;
      row["summary"] = r.summary;
      row["reference"] = r.reference;
      out.append(row);
    }
    return out;
  });

  // --- discrete operators (AllSequencs) ----------------------------------------------------
  m.def(
      "midpoint",
      [](const InputArray& z) { return from_sequence(midpoint(to_sequence(z, "midpoint")), z); },
      py::arg("z"));
  m.def(
      "delta_minus",
      [](const InputArray& z, double h) {
        require_step(h);
        return from_sequence(delta_minus(to_sequence(z, "delta_minus"), h), z);
      },
      py::arg("z"), py::arg("h"));
  m.def(
      "delta_plus",
      [](const InputArray& z, double h) {
        require_step(h);
        return from_sequence(delta_plus(to_sequence(z, "delta_plus"), h), z);
      },
      py::arg("z"), py::arg("h"));
  m.def(
      "frac_delta_minus",
      [](const InputArray& z, double h, double alpha, const std::string& quadrature) {
        require_step(h);
        return from_sequence(frac_delta_minus(to_sequence(z, "frac_delta_minus"), h, alpha,
                                              parse_quadrature(quadrature, "frac_delta_minus")),
                             z);
      },
      py::arg("z"), py::arg("h"), py::arg("alpha"), py::arg("quadrature"));
  m.def(
      "frac_delta_plus",
      [](const InputArray& z, double h, double alpha, const std::string& quadrature) {
        require_step(h);
        return from_sequence(frac_delta_plus(to_sequence(z, "frac_delta_plus"), h, alpha,
                                             parse_quadrature(quadrature, "frac_delta_plus")),
                             z);
      },
      py::arg("z"), py::arg("h"), py::arg("alpha"), py::arg("quadrature"));
  m.def(
      "convolve_past",
      [](const InputArray& w, const InputArray& z) {
        if (w.ndim() != 1) throw py::value_error("convolve_past: w must be one-dimensional");
        return from_sequence(convolve_past({w.data(), static_cast<std::size_t>(w.size())},
                                           to_sequence(z, "convolve_past")),
                             z);
      },
      py::arg("w"), py::arg("z"));
  m.def(
      "convolve_future",
      [](const InputArray& w, const InputArray& z) {
        if (w.ndim() != 1) throw py::value_error("convolve_future: w must be one-dimensional");
        return from_sequence(convolve_future({w.data(), static_cast<std::size_t>(w.size())},
                                             to_sequence(z, "convolve_future")),
                             z);
      },
      py::arg("w"), py::arg("z"));

  // --- continuous Riemann–Liouville derivatives (RL) ---------------------------------------
  m.def(
      "rl_derivative",
      [](double alpha, py::handle f, py::handle t, double a, double b, const std::string& side,
         py::handle df, double tolerance) {
        const Side s = parse_side(side);
        const auto functions = function_and_derivative(f, df);
        return map_points(t, [&](double point) {
          return rl_derivative(alpha, s, functions.first, functions.second, a, b, point, tolerance);
        });
      },
      py::arg("alpha"), py::arg("f"), py::arg("t"), py::arg("a"), py::arg("b"), py::arg("side"),
      py::arg("df"), py::arg("tolerance"));
  m.def(
      "rl_derivative_power",
      [](double order, double p, py::handle t, double a, double b, const std::string& side) {
        const Side s = parse_side(side);
        return map_points(
            t, [&](double point) { return rl_derivative_power(order, s, p, a, b, point); });
      },
      py::arg("order"), py::arg("p"), py::arg("t"), py::arg("a"), py::arg("b"), py::arg("side"));
  m.attr("default_rl_tolerance") = kRlDefaultTolerance;

  // --- FracEL and the action along given curves (issue 13) ----------------------------------
  m.def(
      "fracel_residual",
      [](const ProblemSpec& spec, py::handle x, py::handle y, const std::vector<double>& t,
         double tolerance) {
        const auto lagrangian = make_lagrangian(spec);
        const Curve xc = python_curve(x, spec.dim, "x"), yc = python_curve(y, spec.dim, "y");
        ContinuousResidualOptions options;
        options.tolerance = tolerance;
        Eigen::MatrixXd ex(static_cast<Eigen::Index>(t.size()), spec.dim), ey = ex;
        for (std::size_t k = 0; k < t.size(); ++k) {
          const ContinuousElResidual r = fractional_el_residual(
              *lagrangian, spec.alpha, xc, yc, spec.start, spec.end, t[k], options);
          ex.row(static_cast<Eigen::Index>(k)) = r.x_equation.transpose();
          ey.row(static_cast<Eigen::Index>(k)) = r.y_equation.transpose();
        }
        return py::make_tuple(ex, ey);
      },
      py::arg("spec"), py::arg("x"), py::arg("y"), py::arg("t"), py::arg("tolerance"));
  m.def(
      "action",
      [](const ProblemSpec& spec, py::handle x, py::handle y, py::handle eta, py::handle eta_y,
         bool pairing, double tolerance) {
        const auto lagrangian = make_lagrangian(spec);
        const Curve xc = python_curve(x, spec.dim, "x"), yc = python_curve(y, spec.dim, "y");
        ContinuousResidualOptions options;
        options.tolerance = tolerance;
        py::dict out;
        out["action"] = action(*lagrangian, spec.alpha, xc, yc, spec.start, spec.end, options);
        if (eta.is_none()) return out;
        const Curve dx = python_curve(eta, spec.dim, "eta");
        const Curve dy = eta_y.is_none() ? dx : python_curve(eta_y, spec.dim, "eta_y");
        out["variation"] = action_variation(*lagrangian, spec.alpha, xc, yc, dx, dy, spec.start,
                                            spec.end, options);
        if (pairing) {
          out["pairing"] = fracel_pairing(*lagrangian, spec.alpha, xc, yc, dx, dy, spec.start,
                                          spec.end, options);
        }
        return out;
      },
      py::arg("spec"), py::arg("x"), py::arg("y"), py::arg("eta"), py::arg("eta_y"),
      py::arg("pairing"), py::arg("tolerance"));
}

}  // namespace fracvi::python

PYBIND11_MODULE(_fracvi, m) {
  fracvi::python::bind(m);
}
