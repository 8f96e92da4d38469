// Python functions as model data: see callables.hpp.
#include "callables.hpp"

#include <pybind11/numpy.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace fracvi::python {

namespace {

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(a.shape(i));
  }
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string describe(const py::handle& r) {
  std::string type = py::str(py::type::of(r).attr("__name__"));
  std::string text;  // repr on one line (an array's rows joined), at most 80 characters
  for (const char c : std::string(py::repr(r))) {
    if (c == '\n') {
      text += ' ';
    } else if (c != ' ' || text.empty() || text.back() != ' ') {
      text += c;
    }
  }
  if (text.size() > 80) text = text.substr(0, 77) + "...";
  return text + " (" + type + ")";
}

/// A fresh NumPy array holding the d entries of x (the function may keep or change it).
py::array_t<double> copy(const Eigen::Ref<const Eigen::VectorXd>& x) {
  py::array_t<double> a(x.size());
  std::copy(x.data(), x.data() + x.size(), a.mutable_data());
  return a;
}

// A C-ordered double array of r (converted if it is array-like), or the error naming the rule.
// `call` is what returned it, e.g. "model.gradient(x, t)".
py::array_t<double> as_array(const py::object& r, const std::string& call,
                             const std::string& rule) {
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(r);
  if (!a || r.is_none()) {
    throw std::runtime_error(call + " returned " + describe(r) + ": it must return " + rule);
  }
  return a;
}

/// r as a vector of shape (d,) into `out`, or the error naming the call and the rule.
void read_vector(const py::object& r, const std::string& call, const std::string& what,
                 Eigen::Ref<Eigen::VectorXd> out) {
  const std::string d = std::to_string(out.size());
  const std::string rule = what + ", an array of shape (d,) = (" + d + ",)";
  const auto a = as_array(r, call, rule);
  if (a.ndim() != 1 || a.shape(0) != out.size()) {
    throw std::runtime_error(call + " returned shape " + shape_text(a) + ": it must return " +
                             rule);
  }
  const auto v = a.unchecked<1>();
  for (Eigen::Index i = 0; i < out.size(); ++i) out(i) = v(i);
}

/// r (a d × d array or scipy.sparse matrix) into `out`, or the error naming the call and rule.
void read_matrix(py::object r, const std::string& call, const std::string& what,
                 Eigen::Ref<Eigen::MatrixXd> out) {
  if (py::hasattr(r, "toarray")) r = r.attr("toarray")();  // scipy.sparse
  const std::string d = std::to_string(out.rows());
  const std::string rule =
      what + ": a d × d array or scipy.sparse matrix, (d, d) = (" + d + ", " + d + ")";
  const auto a = as_array(r, call, rule);
  if (a.ndim() != 2 || a.shape(0) != out.rows() || a.shape(1) != out.cols()) {
    throw std::runtime_error(call + " returned shape " + shape_text(a) + ": it must return " +
                             rule);
  }
  const auto m = a.unchecked<2>();
  for (Eigen::Index i = 0; i < out.rows(); ++i) {
    for (Eigen::Index j = 0; j < out.cols(); ++j) out(i, j) = m(i, j);
  }
}

/// f() with what a Python function raised turned into the run's error: a KeyboardInterrupt or
/// SystemExit is kept in `raised` (the first) and reported as an interruption, any other
/// exception with its text and traceback. `call` names the function, e.g. "model.force(x, v, t)".
template <class F>
auto guarded(const std::string& call, py::object& raised, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_KeyboardInterrupt) || e.matches(PyExc_SystemExit)) {
      if (raised.is_none()) raised = e.value();
      throw std::runtime_error(call + " was interrupted (" +
                               py::str(e.type().attr("__name__")).cast<std::string>() + ")");
    }
    throw std::runtime_error(call + " raised an exception:\n" + exception_text(e));
  }
}

/// Column i of the Jacobian of f at y as (f(y + δe_i) − f(y − δe_i)) / 2δ,
/// δ = ε^{1/3} max(1, |y_i|) (the step that balances truncation O(δ²) and cancellation O(ε/δ)).
/// `shifted` holds y on entry and on return; f(shifted, out) evaluates f at it.
template <class F>
void difference_jacobian(py::array_t<double>& shifted, F&& f, Eigen::Ref<Eigen::MatrixXd> J) {
  const double scale = std::cbrt(std::numeric_limits<double>::epsilon());
  double* y = shifted.mutable_data();
  Eigen::VectorXd plus(J.rows()), minus(J.rows());
  for (Eigen::Index i = 0; i < J.cols(); ++i) {
    const double yi = y[i];
    const double delta = scale * std::max(1.0, std::abs(yi));
    y[i] = yi + delta;
    f(plus);
    y[i] = yi - delta;
    f(minus);
    y[i] = yi;
    J.col(i) = (plus - minus) / (2.0 * delta);
  }
}

class PythonPotential final : public Potential, public PythonFunctions {
 public:
  PythonPotential(Eigen::Index dimension, py::object value, py::object gradient, py::object hessian)
      : dimension_(dimension),
        value_(std::move(value)),
        gradient_(std::move(gradient)),
        hessian_(std::move(hessian)) {}

  // The functions are released with the GIL held: the last copy of a ProblemSpec may go away in
  // a thread that does not hold it (the runs release it).
  ~PythonPotential() override {
    if (Py_IsInitialized() == 0) return;
    const py::gil_scoped_acquire gil;
    value_ = py::object();
    gradient_ = py::object();
    hessian_ = py::object();
    raised_ = py::object();
  }
  PythonPotential(const PythonPotential&) = delete;
  PythonPotential& operator=(const PythonPotential&) = delete;

  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }

  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    const py::gil_scoped_acquire gil;
    return guarded("model.potential(x, t)", raised_, [&] {
      const py::object r = value_(copy(x), t);
      try {
        return r.cast<double>();
      } catch (const py::cast_error&) {
        throw std::runtime_error("model.potential(x, t) returned " + describe(r) +
                                 ": it must return a number, U at (x, t)");
      }
    });
  }

  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    const py::gil_scoped_acquire gil;
    guarded("model.gradient(x, t)", raised_, [&] { call_gradient(copy(x), t, g); });
  }

  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    const py::gil_scoped_acquire gil;
    guarded("model.hessian(x, t)", raised_, [&] {
      if (!hessian_.is_none()) {
        read_matrix(hessian_(copy(x), t), "model.hessian(x, t)", "∇²U at (x, t)", H);
        return;
      }
      // Central differences of ∇U, then symmetrised.
      py::array_t<double> shifted = copy(x);
      difference_jacobian(
          shifted, [&](Eigen::VectorXd& g) { call_gradient(shifted, t, g); }, H);
      const Eigen::MatrixXd symmetric = 0.5 * (H + H.transpose());
      H = symmetric;
    });
  }

 private:
  void call_gradient(const py::array_t<double>& x, double t, Eigen::Ref<Eigen::VectorXd> g) const {
    read_vector(gradient_(x, t), "model.gradient(x, t)", "∇U at (x, t)", g);
  }

  Eigen::Index dimension_;
  py::object value_, gradient_, hessian_;
};

class PythonForce final : public StateForce, public PythonFunctions {
 public:
  PythonForce(Eigen::Index dimension, py::object force, py::object jacobian)
      : dimension_(dimension), force_(std::move(force)), jacobian_(std::move(jacobian)) {}

  // Released with the GIL held, as PythonPotential's.
  ~PythonForce() override {
    if (Py_IsInitialized() == 0) return;
    const py::gil_scoped_acquire gil;
    force_ = py::object();
    jacobian_ = py::object();
    raised_ = py::object();
  }
  PythonForce(const PythonForce&) = delete;
  PythonForce& operator=(const PythonForce&) = delete;

  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }

  void value(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::VectorXd>& v,
             double t, Eigen::Ref<Eigen::VectorXd> out) const override {
    const py::gil_scoped_acquire gil;
    guarded(kCall, raised_, [&] { call_force(copy(x), copy(v), t, out); });
  }

  void jacobians(const Eigen::Ref<const Eigen::VectorXd>& x,
                 const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                 Eigen::Ref<Eigen::VectorXd> out, Eigen::Ref<Eigen::MatrixXd> dx,
                 Eigen::Ref<Eigen::MatrixXd> dv) const override {
    const py::gil_scoped_acquire gil;
    py::array_t<double> xs = copy(x), vs = copy(v);
    guarded(kCall, raised_, [&] { call_force(xs, vs, t, out); });
    if (jacobian_.is_none()) {  // central differences of g in x, then in v
      guarded(kCall, raised_, [&] {
        difference_jacobian(
            xs, [&](Eigen::VectorXd& g) { call_force(xs, vs, t, g); }, dx);
        difference_jacobian(
            vs, [&](Eigen::VectorXd& g) { call_force(xs, vs, t, g); }, dv);
      });
      return;
    }
    guarded(kJacobianCall, raised_, [&] {
      const py::object r = jacobian_(xs, vs, t);
      const char* rule = "the pair (∂g/∂x, ∂g/∂v) at (x, v, t), a tuple of two d × d arrays";
      // A tuple or list: a (2, d, d) or 2 × 2 array is not taken apart by rows.
      if (!(py::isinstance<py::tuple>(r) || py::isinstance<py::list>(r)) || py::len(r) != 2) {
        throw std::runtime_error(std::string(kJacobianCall) + " returned " + describe(r) +
                                 ": it must return " + rule);
      }
      const auto pair = r.cast<py::sequence>();
      read_matrix(pair[0], kJacobianCall, "∂g/∂x at (x, v, t), its first entry", dx);
      read_matrix(pair[1], kJacobianCall, "∂g/∂v at (x, v, t), its second entry", dv);
    });
  }

 private:
  static constexpr const char* kCall = "model.force(x, v, t)";
  static constexpr const char* kJacobianCall = "model.force_jacobian(x, v, t)";

  void call_force(const py::array_t<double>& x, const py::array_t<double>& v, double t,
                  Eigen::Ref<Eigen::VectorXd> out) const {
    read_vector(force_(x, v, t), kCall, "g at (x, v, t)", out);
  }

  Eigen::Index dimension_;
  py::object force_, jacobian_;
};

}  // namespace

std::string exception_text(const py::error_already_set& e) {
  try {
    const py::module_ traceback = py::module_::import("traceback");
    std::string text;
    for (const auto& line : traceback.attr("format_exception_only")(e.type(), e.value())) {
      text += line.cast<std::string>();
    }
    // No traceback when the call itself failed (a function of the wrong signature: TypeError).
    if (e.trace()) {
      text += "Traceback (most recent call last):\n";
      for (const auto& line : traceback.attr("format_tb")(e.trace()))
        text += line.cast<std::string>();
    }
    while (!text.empty() && text.back() == '\n') text.pop_back();
    return text;
  } catch (const std::exception&) {  // error_already_set, cast_error
    return e.what();                 // pybind11's own rendering, with the frames
  }
}

std::shared_ptr<const Potential> make_python_potential(long long dimension, py::object value,
                                                       py::object gradient, py::object hessian) {
  return std::make_shared<const PythonPotential>(static_cast<Eigen::Index>(dimension),
                                                 std::move(value), std::move(gradient),
                                                 std::move(hessian));
}

std::shared_ptr<const StateForce> make_python_force(long long dimension, py::object force,
                                                    py::object jacobian) {
  return std::make_shared<const PythonForce>(static_cast<Eigen::Index>(dimension), std::move(force),
                                             std::move(jacobian));
}

py::object PythonFunctions::take_raised() const {
  return std::exchange(raised_, py::none());
}

}  // namespace fracvi::python
