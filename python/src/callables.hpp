// Python functions as model data (issue 16 item 2): U(x, t), ∇U and ∇²U given as Python
// callables, for fracvi.Problem(potential=<function>, gradient=<function>, hessian=<function>).
//
// The runs release the GIL (module.cpp); every call here takes it back, hands the function a fresh
// NumPy copy of x (the function may keep it) and the float t, and checks what comes back. What
// goes wrong inside a function becomes a std::runtime_error whose what() names the function, the
// rule and, for a Python exception, its type, message and traceback: the step that called it ends
// the run with Status::kCallbackError and the rows so far (schemes/stepper.hpp). A
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

/// Whether `potential` is one make_python_potential made.
bool is_python_potential(const std::shared_ptr<const Potential>& potential);

/// After a run, with the GIL held again: the KeyboardInterrupt or SystemExit a potential function
/// raised during it (the step then ended the run with Status::kCallbackError), or None; cleared.
/// The caller raises it like a Ctrl-C between steps.
py::object take_raised_interrupt(const std::shared_ptr<const Potential>& potential);

}  // namespace fracvi::python
