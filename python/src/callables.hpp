// Python functions as model data (issue 16 item 2): U(x, t), ∇U and ∇²U, and the force
// g(x, v, t) with its Jacobians, given as Python callables, for fracvi.Problem(
// potential=<function>, gradient=<function>, hessian=<function>, force=<function>,
// force_jacobian=<function>).
//
// The runs release the GIL (module.cpp); every call here takes it back, hands the function a fresh
// NumPy copy of x (and v; the function may keep them) and the float t, and checks what comes back.
// What goes wrong inside a function becomes a std::runtime_error whose what() names the function,
// the rule and, for a Python exception, its type, message and traceback: the step that called it
// ends the run with Status::kCallbackError and the rows so far (schemes/stepper.hpp). A
// KeyboardInterrupt (or SystemExit) raised inside a function is also kept, and raised after the
// run with the partial solution, as Ctrl-C during a formula run is (take_raised_interrupt).
//
// Cost: each call allocates Python objects and takes the GIL, so the step loop is allocation-free
// only with formula potentials; bench/python_callables_bench.py measures the cost per step.
#pragma once

#include <pybind11/pybind11.h>

#include <memory>
#include <string>

#include "fracvi/model/potential.hpp"
#include "fracvi/model/state_force.hpp"

namespace fracvi::python {

namespace py = pybind11;

/// A Python exception as Python prints it, its "Type: message" line first and then the traceback
/// (most recent call last), for a run's message: the step's message buffer
/// (Stepper::failure_detail, 4 KB) then cuts deep tracebacks, not the message. Needs the GIL.
std::string exception_text(const py::error_already_set& e);

/// U, ∇U (required) and ∇²U (optional: None) as Python functions of (x, t). Without a Hessian
/// function ∇²U is the central difference of the gradient, column by column with the step
/// ε^{1/3}·max(1, |x_i|) (2d gradient calls; it only enters Newton's Jacobian, so the converged
/// iterate still solves the exact discrete equations, Newton may just take another iteration).
std::shared_ptr<const Potential> make_python_potential(long long dimension, py::object value,
                                                       py::object gradient, py::object hessian);

/// g(x, v, t) (required) and its Jacobians (optional: None) as Python functions: force(x, v, t)
/// returns an array of shape (d,), force_jacobian(x, v, t) the pair (∂g/∂x, ∂g/∂v) of d × d
/// arrays or scipy.sparse matrices, row i the gradient of g_i. Without it the Jacobians are
/// central differences of g (4d calls, the step as for the Hessian above); they only enter
/// Newton's matrix, so the discrete equations are still solved exactly.
std::shared_ptr<const StateForce> make_python_force(long long dimension, py::object force,
                                                    py::object jacobian);

/// What the Python model functions share: the KeyboardInterrupt or SystemExit one of them raised
/// during a run (the step then ended the run with Status::kCallbackError).
class PythonFunctions {
 public:
  virtual ~PythonFunctions() = default;
  /// That exception, or None; cleared. Needs the GIL.
  [[nodiscard]] py::object take_raised() const;

 protected:
  PythonFunctions() = default;
  mutable py::object raised_ = py::none();  // written with the GIL held
};

/// Whether `f` (a Potential or a StateForce) is one of the Python functions above.
template <class ModelFunction>
bool is_python(const std::shared_ptr<const ModelFunction>& f) {
  return dynamic_cast<const PythonFunctions*>(f.get()) != nullptr;
}

/// After a run, with the GIL held again: the KeyboardInterrupt or SystemExit the Python function
/// `f` raised during it, or None; cleared. The caller raises it like a Ctrl-C between steps.
template <class ModelFunction>
py::object take_raised_interrupt(const std::shared_ptr<const ModelFunction>& f) {
  const auto* python = dynamic_cast<const PythonFunctions*>(f.get());
  return python == nullptr ? py::object(py::none()) : python->take_raised();
}

}  // namespace fracvi::python
