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

class PythonPotential final : public Potential {
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
    return guarded("potential", [&] {
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
    guarded("gradient", [&] { call_gradient(copy(x), t, g); });
  }

  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override {
    const py::gil_scoped_acquire gil;
    guarded("hessian", [&] {
      if (hessian_.is_none()) {
        difference_hessian(x, t, H);
        return;
      }
      py::object r = hessian_(copy(x), t);
      if (py::hasattr(r, "toarray")) r = r.attr("toarray")();  // scipy.sparse
      const auto a = as_array(r, "hessian", "∇²U at (x, t): a d × d array or scipy.sparse matrix");
      if (a.ndim() != 2 || a.shape(0) != dimension_ || a.shape(1) != dimension_) {
        throw std::runtime_error("model.hessian(x, t) returned shape " + shape_text(a) +
                                 ": it must return ∇²U at (x, t), of shape (d, d) = (" +
                                 std::to_string(dimension_) + ", " + std::to_string(dimension_) +
                                 ")");
      }
      const auto m = a.unchecked<2>();
      for (Eigen::Index i = 0; i < dimension_; ++i) {
        for (Eigen::Index j = 0; j < dimension_; ++j) H(i, j) = m(i, j);
      }
    });
  }

  /// The KeyboardInterrupt or SystemExit a function raised, or None; cleared. GIL held.
  py::object take_raised() const { return std::exchange(raised_, py::none()); }

 private:
  template <class F>
  auto guarded(const char* field, F&& f) const -> decltype(f()) {
    try {
      return f();
    } catch (py::error_already_set& e) {
      if (e.matches(PyExc_KeyboardInterrupt) || e.matches(PyExc_SystemExit)) {
        if (raised_.is_none()) raised_ = e.value();
        throw std::runtime_error(std::string("model.") + field + "(x, t) was interrupted (" +
                                 py::str(e.type().attr("__name__")).cast<std::string>() + ")");
      }
      throw std::runtime_error(std::string("model.") + field + "(x, t) raised an exception:\n" +
                               exception_text(e));
    }
  }

  [[nodiscard]] py::array_t<double> copy(const Eigen::Ref<const Eigen::VectorXd>& x) const {
    py::array_t<double> a(dimension_);
    std::copy(x.data(), x.data() + dimension_, a.mutable_data());
    return a;
  }

  static std::string describe(const py::handle& r) {
    std::string type = py::str(py::type::of(r).attr("__name__"));
    std::string text = py::repr(r);
    if (text.size() > 80) text = text.substr(0, 77) + "...";
    return text + " (" + type + ")";
  }

  // A C-ordered double array of r (converted if it is array-like), or the error naming the rule.
  static py::array_t<double> as_array(const py::object& r, const char* field, const char* rule) {
    auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(r);
    if (!a || r.is_none()) {
      throw std::runtime_error(std::string("model.") + field + "(x, t) returned " + describe(r) +
                               ": it must return " + rule);
    }
    return a;
  }

  void call_gradient(const py::array_t<double>& x, double t, Eigen::Ref<Eigen::VectorXd> g) const {
    const std::string rule =
        "∇U at (x, t), an array of shape (d,) = (" + std::to_string(dimension_) + ",)";
    const auto a = as_array(gradient_(x, t), "gradient", rule.c_str());
    if (a.ndim() != 1 || a.shape(0) != dimension_) {
      throw std::runtime_error("model.gradient(x, t) returned shape " + shape_text(a) +
                               ": it must return " + rule);
    }
    const auto v = a.unchecked<1>();
    for (Eigen::Index i = 0; i < dimension_; ++i) g(i) = v(i);
  }

  // Column i of ∇²U as (∇U(x + δe_i) − ∇U(x − δe_i)) / 2δ, δ = ε^{1/3} max(1, |x_i|) (the step
  // that balances truncation O(δ²) and cancellation O(ε/δ)); then symmetrised.
  void difference_hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                          Eigen::Ref<Eigen::MatrixXd> H) const {
    const double scale = std::cbrt(std::numeric_limits<double>::epsilon());
    py::array_t<double> shifted = copy(x);
    double* y = shifted.mutable_data();
    Eigen::VectorXd plus(dimension_), minus(dimension_);
    for (Eigen::Index i = 0; i < dimension_; ++i) {
      const double xi = x(i);
      const double delta = scale * std::max(1.0, std::abs(xi));
      y[i] = xi + delta;
      call_gradient(shifted, t, plus);
      y[i] = xi - delta;
      call_gradient(shifted, t, minus);
      y[i] = xi;
      H.col(i) = (plus - minus) / (2.0 * delta);
    }
    const Eigen::MatrixXd symmetric = 0.5 * (H + H.transpose());
    H = symmetric;
  }

  Eigen::Index dimension_;
  py::object value_, gradient_, hessian_;
  mutable py::object raised_ = py::none();  // written with the GIL held
};

}  // namespace

std::string exception_text(const py::error_already_set& e) {
  try {
    const py::module_ traceback = py::module_::import("traceback");
    std::string text;
    for (const auto& line : traceback.attr("format_exception_only")(e.type(), e.value())) {
      text += line.cast<std::string>();
    }
    text += "Traceback (most recent call last):\n";
    for (const auto& line : traceback.attr("format_tb")(e.trace()))
      text += line.cast<std::string>();
    while (!text.empty() && text.back() == '\n') text.pop_back();
    return text;
  } catch (const py::error_already_set&) {
    return e.what();  // pybind11's own rendering, with the frames
  }
}

std::shared_ptr<const Potential> make_python_potential(long long dimension, py::object value,
                                                       py::object gradient, py::object hessian) {
  return std::make_shared<const PythonPotential>(static_cast<Eigen::Index>(dimension),
                                                 std::move(value), std::move(gradient),
                                                 std::move(hessian));
}

bool is_python_potential(const std::shared_ptr<const Potential>& potential) {
  return dynamic_cast<const PythonPotential*>(potential.get()) != nullptr;
}

py::object take_raised_interrupt(const std::shared_ptr<const Potential>& potential) {
  const auto* python = dynamic_cast<const PythonPotential*>(potential.get());
  return python == nullptr ? py::object(py::none()) : python->take_raised();
}

}  // namespace fracvi::python
