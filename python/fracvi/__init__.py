"""fracvi: fractional variational integrators for damped mechanical systems

    M x'' + R D^{2α} x + ∇U(x, t) = f(t),   x ∈ R^d,

from the discrete fractional variational principle of Jiménez & Ober-Blöbaum (the paper's
scheme `DiscEqs`). α ∈ [0, 1] is the Lagrangian order; the damping term has order 2α
(α = 1/2: viscous damping R x'; α = 3/4: Bagley–Torvik R D^{3/2} x).

Quick start (examples/python/quickstart.py)::

    import fracvi
    problem = fracvi.Problem(dim=1, mass=1.0, damping=0.5, alpha=0.75, convention="caputo",
                             potential="x1^2/2", position=[1.0], end=20.0, steps=2000)
    solution = fracvi.integrate(problem)
    solution.x[-1], solution.max_balance_error      # NumPy views of the C++ storage
    fracvi.write(solution, problem, "out")           # the files of `fracvi run`
    fracvi.plot(solution, "out")                     # its three PNG plots

Stepping by hand: fracvi.Integrator(problem, **options) with step(), state, run(until=t,
observer=f) and solution(). Files: fracvi.load(directory) reads back what `fracvi run` and
fracvi.write (CSV, or format="npz") wrote. Problem, Solution and BvpSolution pickle
(multiprocessing.Pool.map(fracvi.integrate, problems)).

Boundary value problems ([boundary], `fracvi bvp`): fracvi.solve_bvp(problem) returns the curves
x, y of the discrete fractional Euler–Lagrange equations with their residuals.

Problems use the schema of the problem files (docs/problem-file.md) and are validated by the same
C++ code as `fracvi run`: bad input raises ProblemError (a ValueError) with exactly the message the
command line prints. Numerical failure is not an exception: the Solution has a status, a message
and the trajectory up to the failure (or pass raise_on_failure=True).

Parameter studies (`fracvi sweep`): fracvi.sweep(problem, {"model.alpha": [...], ...}, jobs=2)
runs every case in-process on local threads and returns a SweepResult (NumPy columns);
fracvi.plot_sweep draws a quantity against a parameter or as a heat map over two.

Also here: Grünwald–Letnikov and convolution-quadrature weights (gl_weights, cq_weights), the
paper's discrete operators on sequences (midpoint, delta_minus, delta_plus, frac_delta_minus,
frac_delta_plus) and continuous Riemann–Liouville derivatives (rl_derivative).

Build: `cmake --preset release && cmake --build --preset release`, then
`PYTHONPATH=build/release/python /usr/bin/python3` (Debian's interpreter, which has NumPy).
"""
import json
import os
import sys
from collections import namedtuple
from collections.abc import Mapping

import numpy as np

from . import _fracvi
from . import plot as _plotting  # before `def plot` below, which rebinds the name
from . import plot_compare as _compare_figures  # idem for `def plot_compare`
from . import plot_sweep as _sweep_plotting
from .plot_sweep import SweepResult
from ._fracvi import ProblemError

__all__ = [
    "Problem", "ProblemError", "Solution", "IntegrationError", "integrate", "Integrator", "State",
    "write", "load", "plot",
    "BvpSolution", "solve_bvp", "methods", "problem_schema",
    "gl_weights", "cq_weights", "midpoint", "delta_minus", "delta_plus", "frac_delta_minus",
    "frac_delta_plus", "convolve_past", "convolve_future", "rl_derivative",
    "rl_derivative_power", "fracel_residual", "action", "compare", "plot_compare", "sweep",
    "load_sweep", "plot_sweep", "SweepResult",
]

ProblemError.__module__ = __name__
ProblemError.__doc__ = ("Bad problem input (a ValueError). The message is the one `fracvi run` "
                        "prints: '<source>: <key> = <value> <rule>'.")


class IntegrationError(RuntimeError):
    """A run that did not succeed, raised by integrate(..., raise_on_failure=True).

    str(error) is the solution's message; error.solution holds the trajectory up to the failure.
    """

    def __init__(self, solution):
        super().__init__(f"{solution.status}: {solution.message}")
        self.solution = solution

    @property
    def status(self):
        return self.solution.status


# ---------------------------------------------------------------------------------------------
# Problems

def _plain(value):
    """Mappings as dicts (the native layer takes dicts, lists, tuples, numbers, strings and
    NumPy values), scipy.sparse matrices in the problem files' forms (_sparse_as_plain)."""
    matrix = _sparse_as_plain(value)
    if matrix is not None:
        return matrix
    if isinstance(value, Mapping) and not isinstance(value, dict):
        value = dict(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _sparse_as_plain(value):
    """A scipy.sparse matrix (model.mass, model.damping) as the problem files give matrices: a
    diagonal one as its d diagonal entries (stored sparse, as Problem.mass returns it), any other
    as d rows (stored dense: the files have no other sparse form). None for anything else (scipy
    is not imported for that: a sparse matrix exists only if scipy.sparse was)."""
    sparse = sys.modules.get("scipy.sparse")
    if sparse is None or not sparse.issparse(value):
        return None
    coo = sparse.coo_matrix(value)
    off_diagonal = coo.data[coo.row != coo.col]
    if coo.shape[0] == coo.shape[1] and not np.any(off_diagonal != 0):
        return coo.diagonal().tolist()
    dense_bytes = 8.0 * coo.shape[0] * coo.shape[1]
    if dense_bytes > _MAX_DENSE_BYTES:
        raise ProblemError(
            f"a scipy.sparse matrix of shape {coo.shape} with off-diagonal entries is stored "
            f"dense ({dense_bytes / 2**30:.3g} GiB), more than the {_MAX_DENSE_BYTES / 2**30:g} "
            f"GiB fracvi expands: only a diagonal mass or damping matrix is stored sparse")
    return coo.toarray().tolist()


_MAX_DENSE_BYTES = 2.0**30  # a non-diagonal scipy.sparse matrix expanded to d rows, at most


def _assignments(overrides, where):
    """The "section.key=value" assignments of `overrides`: one string, or a list (any iterable)
    of strings; a string is never taken apart character by character."""
    if isinstance(overrides, str):
        return [overrides]
    rule = ('each is "section.key=value", as for `fracvi run --set`; give one string or a list '
            'of strings')
    if isinstance(overrides, (bytes, Mapping)) or not hasattr(overrides, "__iter__"):
        raise TypeError(f"{where}: overrides = {overrides!r} is not a string or a list of "
                        f"strings ({rule})")
    items = list(overrides)
    for i, item in enumerate(items):
        if not isinstance(item, str):
            raise TypeError(f"{where}: overrides[{i}] = {item!r} is not a string ({rule})")
    return items


def _schema():
    """The sections (top-level tables) of the problem-file schema and the section of every key
    that may be given flat, from the one schema of the C++ reader (problem_schema()): the keys of
    [model], [initial], [time], [method] and [output]. Keys of [boundary], [reference] and
    [model.chain] are given in their section (boundary=dict(start=..., end=...)): their names
    (start, end, position, boundary) are taken by the flat keys or by a section."""
    rows = _fracvi.problem_schema()
    sections = {row["key"] for row in rows if row["section"] == "" and row["type"] == "table"}
    flat = {row["key"]: row["section"] for row in rows
            if row["section"] in ("model", "initial", "time", "method", "output")}
    return sections, flat


_SECTIONS, _FLAT_KEYS = _schema()

# U and the force given as Python functions (issue 16 item 2): potential=<function> with
# gradient= and an optional hessian=, each a function of (x, t), and force=<function> with an
# optional force_jacobian=, functions of (x, v, t); x and v NumPy arrays of shape (d,). They are
# not keys of the problem files: the C++ reader gets the placeholders potential = "0" and
# force = [], and the problem records the labels "python:module:name, module:name[, ...]"
# (callables.hpp). A problem keeps them as a dict {key: function} (hessian, force_jacobian may be
# None).
_PYTHON_PREFIX = "python:"
_FUNCTION_GROUPS = {
    # first key: the problem-file field that holds the label; then (key, required, rule)
    "potential": (("potential", True, "U(x, t) -> float"),
                  ("gradient", True, "∇U(x, t) -> array of shape (d,)"),
                  ("hessian", False, "∇²U(x, t) -> (d, d) array or scipy.sparse matrix")),
    "force": (("force", True, "g(x, v, t) -> array of shape (d,)"),
              ("force_jacobian", False, "J(x, v, t) -> the pair (∂g/∂x, ∂g/∂v), (d, d) "
                                        "arrays or scipy.sparse matrices")),
}
_FUNCTION_KEYS = tuple(key for group in _FUNCTION_GROUPS.values() for key, _, _ in group)
_EXTRA_FUNCTION_KEYS = tuple(k for k in _FUNCTION_KEYS if k not in _FUNCTION_GROUPS)
_PLACEHOLDERS = {"potential": "0", "force": []}
_FUNCTIONS_RULE = ("U as Python functions: potential=U(x, t) -> float, gradient=g(x, t) -> array "
                   "of shape (d,), and optionally hessian=H(x, t) -> (d, d) array or "
                   "scipy.sparse matrix (without it, central differences of the gradient); the "
                   "force as force=g(x, v, t) -> array of shape (d,), and optionally "
                   "force_jacobian=J(x, v, t) -> (∂g/∂x, ∂g/∂v) (without it, central "
                   "differences of g)")


def _function_name(function):
    module = getattr(function, "__module__", None) or "?"
    qualname = getattr(function, "__qualname__", None) or type(function).__qualname__
    return f"{module}:{qualname}"


def _function_label(functions, group):
    """The label a problem records for the functions of `group`: "python:module:name, ..."."""
    return _PYTHON_PREFIX + ", ".join(_function_name(functions[key])
                                      for key, _, _ in _FUNCTION_GROUPS[group]
                                      if functions.get(key) is not None)


def _label_of(value):
    """The "python:..." label a field holds (a string, or for the force a list of one), or None."""
    if isinstance(value, (list, tuple)) and len(value) == 1:
        value = value[0]
    if isinstance(value, str) and value.startswith(_PYTHON_PREFIX):
        return value
    return None


def _import_functions(label, group, source):
    """The functions of `group` a "python:module:name, ..." label names, imported again."""
    import importlib
    keys = _FUNCTION_GROUPS[group]
    required = sum(1 for _, needed, _ in keys if needed)
    names = [n.strip() for n in label[len(_PYTHON_PREFIX):].split(",")]
    if not required <= len(names) <= len(keys) or not all(":" in n for n in names):
        what = ", ".join(key for key, _, _ in keys)
        raise ProblemError(f'{source}: model.{group} = "{label}" is not the label of Python '
                           f'{group} functions ("python:module:name, ...": {what}, the last '
                           f'{len(keys) - required} optional)')
    functions = {}
    for (key, _, _), name in zip(keys, names):
        module, _, qualname = name.partition(":")
        try:
            function = importlib.import_module(module)
            for part in qualname.split("."):
                function = getattr(function, part)
        except (ImportError, AttributeError) as error:
            given = ", ".join(f"{k}={k[0].upper()}" for k, _, _ in keys)
            raise ProblemError(
                f'{source}: model.{group} = "{label}" names the Python function {name}, which '
                f'cannot be imported here ({error}; a lambda, a local function or one of '
                f'__main__ cannot be): pass the functions again, functions=dict({given}) to '
                f'Problem.from_dict, Problem.from_toml or fracvi.load') from None
        functions[key] = function
    return functions


def _as_functions(functions, source):
    """functions=dict(potential=U, gradient=g, ..., force=f, ...) checked, or None."""
    if functions is None:
        return None
    if not isinstance(functions, Mapping) or set(functions) - set(_FUNCTION_KEYS):
        raise TypeError(f"{source}: functions = {functions!r} must be a dict with keys among "
                        f"{', '.join(_FUNCTION_KEYS)} ({_FUNCTIONS_RULE})")
    return dict(functions)


def _take_functions(document, source, functions=None):
    """(document for the C++ reader, functions or None): U or the force as Python functions —
    model.potential (model.force) a callable with model.gradient, ... ; the label a run from
    Python recorded (imported again); or `functions` given by the caller, which win — are taken
    out of [model] and replaced by the placeholders (potential "0", force [])."""
    model = document.get("model") if isinstance(document, Mapping) else None
    if not isinstance(model, Mapping):
        if functions:
            raise ProblemError(f"{source}: functions= given, but the problem has no [model]")
        return document, None
    model = dict(model)
    given = {key: model.pop(key) for key in _EXTRA_FUNCTION_KEYS if key in model}
    supplied = functions or {}
    taken = {}
    for group, keys in _FUNCTION_GROUPS.items():
        names = [key for key, _, _ in keys]
        value = model.get(group)
        if any(key in supplied for key in names):
            found = {key: supplied.get(key) for key in names}
        elif callable(value):
            found = {group: value, **{key: given.get(key) for key in names[1:]}}
        elif _label_of(value) is not None and not any(key in given for key in names[1:]):
            found = _import_functions(_label_of(value), group, source)
        else:
            for key in names[1:]:
                if key in given:
                    raise ProblemError(
                        f"{source}: model.{key} = {given[key]!r} goes with a Python {group} "
                        f"function ({group}=<function>); formulas have exact derivatives of "
                        f"their own")
            continue
        for key, required, rule in keys:
            function = found.get(key)
            if required and not callable(function):
                raise ProblemError(f"{source}: model.{key} = {function!r} is not a function: "
                                   f"{rule} is required ({_FUNCTIONS_RULE})")
            if not required and function is not None and not callable(function):
                raise ProblemError(f"{source}: model.{key} = {function!r} is not a function or "
                                   f"None: {rule} ({_FUNCTIONS_RULE})")
            taken[key] = function
        model[group] = _PLACEHOLDERS[group]
    if not taken:
        return document, None
    return dict(document, model=model), taken


def _with_functions(spec, functions):
    """The native problem with U and/or the force as Python functions (each checked once at the
    initial state)."""
    if not functions:
        return spec
    if "potential" in functions:
        spec = _fracvi.with_python_potential(
            spec, _function_label(functions, "potential"), functions["potential"],
            functions["gradient"], functions.get("hessian"))
    if "force" in functions:
        spec = _fracvi.with_python_force(spec, _function_label(functions, "force"),
                                         functions["force"], functions.get("force_jacobian"))
    return spec


class Problem:
    """A validated problem: the model, initial data, time grid and method of `fracvi run`.

    Three ways to make one, all with the schema of the problem files (docs/problem-file.md):

    * keywords: Problem(name="osc", model=dict(dim=1, mass=1.0, potential="x1^2/2", ...),
      initial=dict(position=[1.0]), time=dict(end=10.0, steps=1000)); any key may also be given
      flat when its name is unique, e.g. Problem(dim=1, mass=1.0, potential="x1^2/2",
      alpha=0.5, position=[1.0], end=10.0, steps=1000), or for the built-in FPUT chain
      Problem(dim=100000, mass=1.0, chain=dict(quartic=1.0), position="sin(pi*i/(d+1))", ...);
    * Problem.from_dict(d): the nested dict of a problem file (e.g. tomllib.load);
    * Problem.from_toml(path or text), Problem.default() (the built-in problem of `fracvi run`).

    overrides=["model.alpha=0.6", ...] (or one such string) are applied last, like `fracvi run
    --set`.

    U may also be Python functions of (x, t), x a NumPy array of shape (d,):
    Problem(potential=U, gradient=dU, hessian=H, ...) with U(x, t) -> float, dU(x, t) -> array
    of shape (d,), H(x, t) -> (d, d) array or scipy.sparse matrix (optional: without it, central
    differences of dU, which only slow Newton down). Each is called once here at (x(t0), t0) to
    check it. They are slower than formulas (docs/python.md, "Python functions": each call takes
    the GIL and makes NumPy arrays); an exception inside one ends a run with status
    "callback-error", its traceback in the message, and the trajectory so far. The problem
    records them as "python:module:name, ..."; to_dict, pickling and fracvi.load import them
    again by that name (a lambda or a function of __main__ cannot be: pass functions= then).

    The force may be a Python function too: Problem(force=g, force_jacobian=J, ...) with
    g(x, v, t) -> array of shape (d,), a non-conservative force like a `force` formula in x and v
    (docs/theory/forces.md), and J(x, v, t) -> (∂g/∂x, ∂g/∂v), (d, d) arrays or scipy.sparse
    matrices (optional: without it, central differences of g). Schemes without discrete
    Lagrange–d'Alembert forces refuse it, as they refuse a formula in x or v.

    Invalid input raises ProblemError (a ValueError) with the message `fracvi run` prints.
    Integers must be Python ints where the schema wants integers (time.steps = 100, not 100.0).
    """

    __slots__ = ("_spec", "_functions")

    def __init__(self, *, source="<keywords>", overrides=(), **keywords):
        document = {}
        for key in _EXTRA_FUNCTION_KEYS:  # gradient=, hessian=, force_jacobian= (functions)
            if key in keywords:
                model = keywords.setdefault("model", {})
                if isinstance(model, Mapping):
                    if key in model:
                        raise ProblemError(f"{source}: model.{key} is given twice (as {key}= "
                                           f"and in model=)")
                    keywords["model"] = dict(model, **{key: keywords.pop(key)})
        for key, value in keywords.items():
            if key in _SECTIONS:
                document.setdefault(key, {})
                if not isinstance(value, Mapping):
                    document[key] = value  # the reader says what is wrong with it
                    continue
                for k, v in value.items():
                    document[key][k] = v
        flat = {k: v for k, v in keywords.items() if k not in _SECTIONS}
        for key, value in flat.items():
            section = _FLAT_KEYS.get(key)
            if section is None:
                document[key] = value  # top level: name, or an unknown key the reader reports
                continue
            target = document.setdefault(section, {})
            if not isinstance(target, dict):
                continue
            if key in target:
                raise ProblemError(f"{source}: {section}.{key} is given twice (as {key}= and in "
                                   f"{section}=)")
            target[key] = value
        document, functions = _take_functions(document, source)
        spec = _fracvi.parse_dict(_plain(document), source, _assignments(overrides, "Problem"))
        self._spec = _with_functions(spec, functions)
        self._functions = functions

    @classmethod
    def from_dict(cls, document, *, source="<dict>", overrides=(), functions=None):
        """A problem from the nested dict of a problem file: {"name": ..., "model": {...},
        "initial": {...}, "time": {...}, "method": {...}, "output": {...}}. functions=
        dict(potential=U, gradient=g, hessian=H) gives U as Python functions, dict(force=f,
        force_jacobian=J) the force (see the class), also in place of the "python:..." labels a
        problem with such functions records."""
        document, functions = _take_functions(
            document, source, _as_functions(functions, "Problem.from_dict"))
        spec = _fracvi.parse_dict(_plain(document), source,
                                  _assignments(overrides, "Problem.from_dict"))
        return cls._wrap(spec, functions)

    @classmethod
    def from_toml(cls, toml, *, source=None, overrides=(), functions=None):
        """A problem from a TOML file (a path: str or os.PathLike) or from TOML text (a str that
        contains a newline or '='). Messages name the file, or `source` (default "<string>").
        functions= as for from_dict (a problem.toml written by a run with Python functions names
        them; they are imported again, or taken from functions=)."""
        is_path = isinstance(toml, os.PathLike) or (isinstance(toml, str) and "\n" not in toml and
                                                   "=" not in toml)
        if not is_path and not isinstance(toml, str):
            raise TypeError(f"from_toml takes a path or TOML text, not {type(toml).__name__}")
        if is_path and (source is not None or functions is not None or
                        _names_functions(toml, is_path)):
            with open(toml, encoding="utf-8") as f:
                return cls.from_toml(f.read(), source=source or os.fspath(toml),
                                     overrides=overrides, functions=functions)
        if is_path:
            return cls._wrap(_fracvi.load_toml(os.fspath(toml),
                                               _assignments(overrides, "Problem.from_toml")))
        source = source or "<string>"
        if functions is not None or _names_functions(toml, is_path):
            import tomllib
            return cls.from_dict(tomllib.loads(toml), source=source, overrides=overrides,
                                 functions=functions)
        return cls._wrap(_fracvi.parse_toml(toml, source,
                                            _assignments(overrides, "Problem.from_toml")))

    @classmethod
    def default(cls, *, overrides=()):
        """The built-in problem of `fracvi run` (a forced Duffing oscillator with Bagley–Torvik
        damping)."""
        return cls._wrap(_fracvi.parse_toml(_fracvi.default_problem_toml(), "<built-in problem>",
                                            _assignments(overrides, "Problem.default")))

    @classmethod
    def _wrap(cls, spec, functions=None):
        p = object.__new__(cls)
        p._spec = _with_functions(spec, functions)
        p._functions = functions
        return p

    def _rebuild(self, document, overrides=()):
        """Problem.from_dict(document) with this problem's source and Python functions."""
        functions = dict(self._functions or {})
        for group, keys in _FUNCTION_GROUPS.items():
            if group in functions and any(a.split("=", 1)[0].strip() == f"model.{group}"
                                          for a in overrides):
                # an override gives U (the force) as formulas instead
                for key, _, _ in keys:
                    functions.pop(key, None)
                document = dict(document, model=dict(document["model"],
                                                     **{group: _PLACEHOLDERS[group]}))
        return Problem.from_dict(document, source=self.source, overrides=overrides,
                                 functions=functions or None)

    def with_overrides(self, *overrides):
        """A copy with "section.key=value" assignments applied (like `fracvi run --set`): what
        default(overrides=...) takes — one string or a list of strings — or several strings,
        p.with_overrides("model.alpha=0.6", "time.steps=200")."""
        assignments = [a for group in overrides
                       for a in _assignments(group, "with_overrides")]
        return self._rebuild(self.to_dict(), assignments)

    def to_dict(self):
        """The fully resolved problem (every default filled in) as nested dicts: the "problem"
        entry of summary.json. Matrices in their compact form (one number for m·I, d numbers for
        a diagonal, d rows for a full matrix); initial data given as formulas stay formulas.
        Problem.from_dict(p.to_dict()) == p."""
        return self._spec.to_dict()

    def to_toml(self):
        """The resolved problem as TOML text (the problem.toml `fracvi run` writes)."""
        return self._spec.to_toml()

    def __reduce__(self):
        # Pickled as its resolved dict (validated again when unpickled); Python functions by
        # reference, as pickle does (a lambda does not pickle).
        return _unpickle_problem, (self.to_dict(), self.source, self._functions)

    def __eq__(self, other):
        return (isinstance(other, Problem) and self.to_dict() == other.to_dict() and
                self._functions == other._functions)

    __hash__ = None

    def __repr__(self):
        model = (f"lagrangian={self.lagrangian!r}" if self.lagrangian else
                 f"chain={self.chain!r}" if self.chain else f"potential={self.potential!r}")
        return (f"Problem(name={self.name!r}, dim={self.dim}, alpha={self.alpha:g}, "
                f"convention={self.convention!r}, {model}, t=[{self.start:g}, {self.end:g}], "
                f"steps={self.steps})")

    # Read-only views of the resolved fields (arrays are copies).
    source = property(lambda self: self._spec.source, doc="file name or label used in messages")
    name = property(lambda self: self._spec.name)
    dim = property(lambda self: self._spec.dim, doc="d")
    mass = property(lambda self: self._spec.mass,
                    doc="M (d × d): a NumPy array when given as d rows (dense), a "
                        "scipy.sparse.csc_matrix when given as a number or d numbers (stored "
                        "sparse, a diagonal; never expanded)")
    damping = property(lambda self: self._spec.damping, doc="R (d × d), stored like mass")
    chain = property(lambda self: self._spec.chain,
                     doc="the built-in FPUT chain of [model.chain] as a dict (stiffness, cubic, "
                         "quartic, onsite, boundary), or None (potential is a formula)")
    alpha = property(lambda self: self._spec.alpha, doc="Lagrangian order α ∈ [0, 1]")
    damping_order = property(lambda self: 2.0 * self._spec.alpha, doc="2α")
    convention = property(lambda self: self._spec.convention)
    potential = property(lambda self: self._function("potential", self._spec.potential),
                         doc="U(x1..xd, t): the formula, or the Python function U(x, t)")
    gradient = property(lambda self: self._function("gradient"),
                        doc="the Python function ∇U(x, t) of a potential given as functions, "
                            "else None (a formula's derivatives are exact and internal)")
    hessian = property(lambda self: self._function("hessian"),
                       doc="the Python function ∇²U(x, t), or None")
    force = property(lambda self: self._function("force", list(self._spec.force)),
                     doc="f(t) or g(x, v, t): [] or d formulas in t, x1..xd, v1..vd, or the "
                         "Python function g(x, v, t)")
    force_jacobian = property(lambda self: self._function("force_jacobian"),
                              doc="the Python function (∂g/∂x, ∂g/∂v)(x, v, t) of a force given "
                                  "as a function, or None")

    def _function(self, key, otherwise=None):
        if self._functions is not None and key in self._functions:
            return self._functions[key]
        return otherwise
    lagrangian = property(lambda self: self._spec.lagrangian,
                          doc="a general L(t, x, y, xdot, ydot, dx, dy), or '' (mechanical model)")
    position = property(lambda self: self._spec.position,
                        doc="x(t0) (empty for a boundary value problem without [initial])")
    velocity = property(lambda self: self._spec.velocity, doc="x'(t0)")
    boundary = property(lambda self: dict(start=self._spec.boundary_start,
                                          end=self._spec.boundary_end)
                        if len(self._spec.boundary_start) else None,
                        doc="[boundary] as dict(start=x(start), end=x(end)) (arrays), or None")
    start = property(lambda self: self._spec.start, doc="t0")
    end = property(lambda self: self._spec.end, doc="t_end")
    steps = property(lambda self: self._spec.steps, doc="N")
    step = property(lambda self: self._spec.step, doc="h = (end − start)/N")
    scheme = property(lambda self: self._spec.scheme)
    newton_tolerance = property(lambda self: self._spec.newton_tolerance)
    newton_max_iterations = property(lambda self: self._spec.newton_max_iterations)
    history = property(lambda self: self._spec.history, doc='"auto", "direct" or "fast"')
    history_tolerance = property(
        lambda self: "auto" if self._spec.history_tolerance == 0.0 else self._spec.history_tolerance,
        doc='method.history_tolerance: "auto" (chosen from the run) or the number given')
    abs_tolerance = property(lambda self: self._spec.abs_tolerance)
    rel_tolerance = property(lambda self: self._spec.rel_tolerance)
    linear_solver = property(lambda self: self._spec.linear_solver,
                             doc='method.linear_solver: "auto", "dense", "banded" or "sparse"')
    load = property(lambda self: self._spec.load,
                    doc='method.load: "pointwise" or "moments" (how the forcing enters)')
    split = property(lambda self: self._spec.split,
                     doc='method.split: "taylor" or "series" (what the Lobatto schemes take out '
                         'of x at t0)')
    error_estimate = property(lambda self: self._spec.error_estimate,
                              doc='method.error_estimate: "richardson" or "none"')
    tolerance = property(lambda self: self._spec.tolerance,
                         doc="method.tolerance: > 0 doubles N until the error estimate meets it")
    max_steps = property(lambda self: self._spec.max_steps,
                         doc="method.max_steps: the ceiling of that doubling")
    threads = property(lambda self: self._spec.threads, doc="method.threads (0: measured, one thread or all cores)")
    flush_subnormals = property(
        lambda self: self._spec.flush_subnormals,
        doc="method.flush_subnormals: numbers below 2.2e-308 flushed to zero while stepping")
    every = property(lambda self: self._spec.every,
                     doc="output.every: the solution stores every n-th state and the last; "
                         "\"auto\" (the default): every state up to 10^5 steps, beyond the "
                         "smallest power of two that keeps 10^5 + 1 (Solution.save_every is the "
                         "stride used)")
    format = property(lambda self: self._spec.format,
                      doc='output.format: "csv" (trajectory.csv) or "npz" (trajectory.npz)')


def _names_functions(toml, is_path):
    """Whether TOML text (or the file) gives model.potential as a "python:..." label."""
    if is_path:
        try:
            with open(toml, encoding="utf-8") as f:
                toml = f.read()
        except OSError:
            return False  # the native reader reports it
    import re
    return re.search(r"""(potential|force)\s*=\s*\[?\s*["']""" + _PYTHON_PREFIX,
                     toml) is not None


def _unpickle_problem(document, source, functions=None):
    return Problem.from_dict(document, source=source, functions=functions)


def _as_problem(problem):
    if isinstance(problem, Problem):
        return problem
    if isinstance(problem, Mapping):
        return Problem.from_dict(problem)
    if isinstance(problem, (str, os.PathLike)):
        return Problem.from_toml(problem)
    raise TypeError(f"expected a fracvi.Problem, a dict or a TOML path/text, not "
                    f"{type(problem).__name__}")


# ---------------------------------------------------------------------------------------------
# Solutions

def _view(name, doc):
    return property(lambda self: getattr(self._run, name), doc=doc)


class Solution:
    """The result of integrate(): grid, states, diagnostics, statistics and a status.

    t, x, v, energy, dissipated and balance are read-only NumPy arrays that view the C++ storage
    (no copy; an array keeps the storage alive). x and v have one row per stored state, row r is
    the state at t[r], the step step[r]: with the problem's output.every = n (save_every) every
    n-th step and always the last, so (steps + 1, d) for n = 1. If the run failed, they hold the
    rows computed before the failure.

    energy[k] = ½ v_kᵀ M v_k + U(x_k, t_k); dissipated[k] = W_k, the work removed by damping minus
    the work of f; balance[k] = E_k + W_k − E_0 (zero to round-off for quadratic,
    time-independent U).
    """

    __slots__ = ("_run", "problem")

    def __init__(self, run, problem):
        self._run = run
        self.problem = problem

    def __reduce__(self):
        # Pickled as summary.json's content and the arrays (multiprocessing sends solutions so).
        summary, *arrays = self._run.summary_and_columns()
        return _unpickle_solution, (self.problem, summary, *arrays)

    t = _view("t", "t_k of the stored states, shape (rows,)")
    step = _view("step", "the step index k of each stored row (int64), shape (rows,)")
    x = _view("x", "positions x_k, shape (rows, d), C-contiguous")
    v = _view("v", "velocities v_k = M⁻¹ p_k, shape (rows, d), C-contiguous")
    energy = _view("energy", "E_k (NaN with diagnostics=False)")
    dissipated = _view("dissipated", "W_k (NaN with diagnostics=False)")
    balance = _view("balance", "E_k + W_k − E_0 (NaN with diagnostics=False)")
    status = _view("status", '"success", "newton-failure", "non-finite", "callback-error", '
                   '"unstable", "inaccurate", "interrupted" or "event" (a terminal event '
                   'stopped it: not a failure) (docs/conventions.md)')
    ok = _view("ok", "status == 'success'")
    t_eval = _view("output_t", "the requested times the run reached (t_eval / output.times), "
                   "shape (n,)")
    x_eval = _view("output_x", "x at t_eval from the cubic Hermite dense output of every step "
                   "(docs/theory/dense_output.md), shape (n, d)")
    v_eval = _view("output_v", "v at t_eval, its derivative, shape (n, d)")

    @property
    def events(self):
        """The zero crossings of the events, in time order: a list of EventRecord(name, t,
        direction, step, x, v)."""
        return [EventRecord(*record) for record in self._run.events]

    @property
    def t_events(self):
        """{event name: array of its crossing times} for the events that crossed."""
        out = {}
        for record in self._run.events:
            out.setdefault(record[0], []).append(record[1])
        return {name: np.asarray(times, dtype=float) for name, times in out.items()}

    def __call__(self, t):
        """x(t) from the stored rows by the same interpolant as t_eval (integrate(dense=True)
        stores every step): t a number gives shape (d,), an array of times shape t.shape + (d,).
        Grid times give the stored state exactly. ValueError outside [t[0], t[-1]] or between
        stored rows that are not consecutive steps (output.every > 1)."""
        return self.interpolate(t)[0]

    def interpolate(self, t):
        """(x(t), v(t)) as in solution(t)."""
        times = np.asarray(t, dtype=float)
        if times.ndim == 0:
            return self._run.interpolate(float(times))
        pairs = [self._run.interpolate(float(s)) for s in times.ravel()]
        shape = times.shape + (self.dim,)
        return (np.array([p[0] for p in pairs]).reshape(shape),
                np.array([p[1] for p in pairs]).reshape(shape))
    message = _view("message", "empty on success; otherwise the step, the time and the cause")
    steps = _view("steps", "completed steps (rows 0 … steps are valid)")
    newton_iterations = _view("newton_iterations", "total over all steps")
    max_newton_iterations_per_step = _view("max_newton_iterations_per_step", "")
    jacobian_factorizations = _view(
        "jacobian_factorizations",
        "times the Newton matrix was formed and factored, the set-up's included (0: explicit)")
    mirror_error = _view("mirror_error",
                         "max_k ‖y_k − x_(N−k)‖_∞ of the backward mirror run (NaN if not run)")
    max_balance_error = _view("max_balance_error", "max_k |balance[k]| (a consistency check)")
    error_estimate = _view("error_estimate",
                           "estimated max_k ‖x_k − x(t_k)‖_∞ (Richardson from companion runs with "
                           "N/2 and N/4 steps; NaN when none: summary()['error_estimate_details'])")
    wall_time = _view("wall_time", "seconds of stepping (forward plus mirror run)")
    setup_time = _view("setup_time", "seconds of set-up before step 1 (weights, the fast "
                       "history's fit or FFT plans, factorisations); the run's whole cost is "
                       "setup_time + wall_time")
    history_tolerance = _view("history_tolerance",
                              "the fast history's per-weight accuracy ε used (NaN without a fast "
                              "history); history_tolerance_auto: chosen by the accuracy budget")
    history_tolerance_auto = _view("history_tolerance_auto",
                                   "True when the accuracy budget chose history_tolerance")
    history_limited = _view("history_limited",
                            "True when the budget asked for less than the fit's floor 1e-13: the "
                            "history may limit the accuracy")
    history = _view("history", 'the damping memory that ran: "direct", "fast", "local", "fft" '
                    'or "none" (what method.history = "auto" chose)')
    history_bytes = _view("history_bytes", "bytes kept by the damping memory")
    history_exponentials = _view("history_exponentials",
                                 "K, the fast history's exponentials (recursions per degree of "
                                 "freedom); 0 for the other memories")
    history_window = _view("history_window",
                           "n0, the fast history's window of exactly weighted recent lags; 0 for "
                           "the other memories")
    method = _view("method", 'the scheme, e.g. "fvi-gl"')
    linear_solver = _view("linear_solver",
                          'factorisation of the Newton matrix used: "dense", "banded" or "sparse"')
    save_every = _view("save_every", "the storage stride of the run (the problem's output.every)")
    declared_order = _view("declared_order", "the order the scheme is designed to reach")

    @property
    def dim(self):
        return self._run.x.shape[1]

    def summary(self):
        """The content of summary.json (status, message, final state, diagnostics, statistics,
        the resolved problem) as a dict; non-finite numbers are None as in the file."""
        return self._run.summary()

    def write(self, directory, *, plot=False, format=None):
        """Writes trajectory.csv (format="npz", or output.format = "npz": trajectory.npz),
        summary.json and problem.toml into `directory` (created if needed), as `fracvi run --out
        directory` does; with plot=True also its PNG plots. See fracvi.write; fracvi.load reads it back."""
        return write(self, self.problem, directory, plot=plot, format=format)

    def plot(self, directory=None, *, show=None):
        """See fracvi.plot."""
        return plot(self, directory, show=show)

    def __repr__(self):
        return (f"Solution(status={self.status!r}, steps={self.steps}, dim={self.dim}, "
                f"t_end={self.t[-1] if len(self.t) else float('nan'):g}, "
                f"error_estimate={self.error_estimate:.3g}, "
                f"max_balance_error={self.max_balance_error:.3g}, "
                f"mirror_error={self.mirror_error:.3g})")


def _run_options(diagnostics, newton_absolute_tolerance, history, start, events=()):
    return _fracvi.RunOptions(bool(diagnostics), float(newton_absolute_tolerance), history or "",
                              start, list(events))


_EVENT_KEYS = ("name", "g", "direction", "terminal")


def _event_direction(value, where):
    """"both", "rising", "falling", or SciPy's 0, +1, -1."""
    if isinstance(value, str):
        return value  # checked by the reader (formulas) or the module (callables)
    if isinstance(value, (int, float, np.number)) and not isinstance(value, (bool, np.bool_)):
        return "both" if value == 0 else ("rising" if value > 0 else "falling")
    raise TypeError(f"{where}.direction = {value!r} must be 'both', 'rising', 'falling' "
                    f"(or 0, +1, -1)")


def _split_events(events):
    """The events keyword as ([[events]] tables of formulas for the problem, (name, g, direction,
    terminal) tuples of Python callables for the run). An item is a formula string (its name is
    the formula), a callable g(t, x, v) (name: its __name__; SciPy's attributes .direction and
    .terminal are honoured), or a dict with the keys of [[events]] whose g is either."""
    if events is None:
        return [], []
    if callable(events) or isinstance(events, (str, Mapping)):
        events = [events]
    formulas, callables = [], []
    for i, item in enumerate(events):
        where = f"events[{i}]"
        if isinstance(item, Mapping):
            unknown = sorted(set(item) - set(_EVENT_KEYS))
            if unknown:
                raise TypeError(f"{where}: unknown key {unknown[0]!r} (valid: "
                                f"{', '.join(_EVENT_KEYS)})")
            if "g" not in item:
                raise TypeError(f"{where}: missing 'g' (a formula in t, x1..xd, v1..vd or a "
                                f"callable g(t, x, v))")
            g = item["g"]
            entry = dict(item)
        elif isinstance(item, str) or callable(item):
            g, entry = item, {"g": item}
        else:
            raise TypeError(f"{where} = {item!r} must be a formula string, a callable g(t, x, v) "
                            f"or a dict with the keys {', '.join(_EVENT_KEYS)}")
        if isinstance(g, str):
            entry.setdefault("name", g)
            if "direction" in entry:
                entry["direction"] = _event_direction(entry["direction"], where)
            formulas.append(entry)
        elif callable(g):
            name = entry.get("name", getattr(g, "__name__", f"event{i}"))
            direction = _event_direction(entry.get("direction", getattr(g, "direction", "both")),
                                         where)
            terminal = entry.get("terminal", getattr(g, "terminal", False))
            if not isinstance(terminal, (bool, np.bool_)):
                raise TypeError(f"{where}.terminal = {terminal!r} must be True or False")
            callables.append((str(name), g, direction, bool(terminal)))
        else:
            raise TypeError(f"{where}.g = {g!r} must be a formula string or a callable "
                            f"g(t, x, v)")
    return formulas, callables


def _with_output(problem, fields, t_eval, formulas, dense, function):
    """t_eval (output.times) and the formula events applied to the problem; dense checked."""
    if t_eval is not None:
        if fields.get("times") is not None:
            raise TypeError(f"{function}() got t_eval and times: they are the same (give one)")
        times = np.asarray(t_eval, dtype=float)
        if times.ndim != 1:
            raise ValueError(f"t_eval must be a 1-D sequence of times, got shape {times.shape}")
        fields = dict(fields, times=times.tolist())
    if formulas:
        document = problem.to_dict()
        document["events"] = list(document.get("events", [])) + formulas
        problem = Problem.from_dict(document, source=problem.source)
    if dense:
        every = fields.get("every", problem.every)
        if every == "auto":
            # dense=True asks for every step: "auto" (not a stride the user chose) becomes 1.
            fields = dict(fields, every=1)
        elif every != 1:
            raise ValueError(f"dense=True needs every step stored (output.every = 1): sol(t) "
                             f"interpolates between consecutive steps; output.every = {every!r} "
                             f"(t_eval= gives exact-order values at chosen times with any every)")
    return problem, fields


EventRecord = namedtuple("EventRecord", "name t direction step x v")
EventRecord.__doc__ = """A zero crossing of an event function: its name, the time t (the root of
g on the dense interpolant), direction (+1 rising, -1 falling), the step k + 1 whose interval
(t_k, t_(k+1)] holds it, and the interpolated state x, v there."""


def _with_mirror(fields, mirror):
    """The mirror keyword as the problem's method.mirror: True/False are "on"/"off", a string is
    taken as it is ("auto", "on", "off"), None keeps the problem's value."""
    if mirror is None:
        return fields
    if isinstance(mirror, bool):
        mirror = "on" if mirror else "off"
    return dict(fields, mirror=mirror)


def _unpickle_solution(problem, summary, *arrays):
    *columns, output = arrays if len(arrays) == 7 else (*arrays, None)
    return Solution(_fracvi.restore_run(problem._spec, summary, *columns, "<pickle>", output),
                    problem)


def integrate(problem, *, newton_absolute_tolerance=0.0, mirror=None, diagnostics=True,
              history=None, start="legendre", raise_on_failure=False, t_eval=None,
              events=None, dense=False, **fields):
    """Integrates `problem` (a Problem, a dict, or a TOML path/text) to its final time.

    Every key of the problem's [method] and [output] sections (problem_schema(): scheme,
    newton_tolerance (relative), newton_max_iterations, history_tolerance, abs_tolerance and rel_tolerance (the
    adaptive schemes' error tolerances), linear_solver ("auto",
    "dense", "banded", "sparse"), load ("pointwise" or "moments": the forcing at the
    quadrature points or its exact moments), split ("taylor" or "series": what the Lobatto
    schemes take out of x at t0), error_estimate ("richardson": the Solution's
    error_estimate from companion runs with N/2 and N/4 steps, about 0.75 of the cost more; or
    "none"), tolerance (> 0: N doubled from steps until error_estimate <= tolerance, up to
    max_steps; summary()["tolerance_runs"] lists the runs), threads (0: measured, one thread or all cores), flush_subnormals (True, the default: numbers below 2.2e-308 flushed to zero while stepping, x86-64), every (store every n-th state; "auto": every state up to 10^5 steps, then thinned by a power of two)) may be
    given as a keyword: it overrides the problem's value, is validated by the same reader as a
    problem file, and is recorded in summary(). An unknown keyword is a TypeError naming the valid
    ones. mirror is method.mirror (the backward run of the mirror equation and mirror_error, a
    consistency check costing about one more run: "auto" — on when steps × dim ≤ 10^6 — "on" or
    "off"; True and False mean "on" and "off"; None keeps the problem's). The rest are run
    options: newton_absolute_tolerance, diagnostics (energy, dissipated, balance
    columns), history (the memory sum's implementation: None keeps the problem's [method]
    history, else "auto", "direct" or "fast"), start ("legendre": the discrete Legendre
    transform, or "euler": first-order x_1 = x_0 + h v_0, for comparisons).

    Numerical failure (Newton not converging, non-finite values, a run found "unstable" or
    "inaccurate" by its health checks) returns a Solution with status != "success", its message
    and the trajectory so far; raise_on_failure=True raises
    IntegrationError instead (with .solution). Bad input raises ProblemError / ValueError.

    Ctrl-C (SIGINT) stops the run within about 0.1 s: the KeyboardInterrupt (or whatever the
    signal handler raised) propagates with the partial solution as its attribute .solution
    (status "interrupted", the trajectory up to the last completed step).

    Output where you want it (docs/theory/dense_output.md): t_eval (= output.times; ascending,
    within [start, end]) gives solution.t_eval, x_eval, v_eval from the cubic Hermite interpolant
    of every step's (x, v), evaluated during the run whatever `every`; dense=True keeps every step
    (needs every = 1) so that solution(t) interpolates anywhere afterwards. events: zero
    crossings of g(t, x, v), each a formula string in t, x1..xd, v1..vd (fast: the [[events]] of
    problem files), a callable g(t, x, v) -> float (slower: Python at every step), or a dict with
    name, g, direction ("both", "rising", "falling" or SciPy's 0, +1, -1) and terminal; located
    on the interpolant, listed in solution.events and t_events; a terminal one ends the run with
    status "event" (not a failure: raise_on_failure does not raise). A callable that raises, or
    returns anything but one real number, ends the run ("callback-error"; a NaN: "non-finite")
    with the exception and its traceback in the message, the steps so far kept.
    """
    formulas, callables = _split_events(events)
    problem, fields = _with_output(_as_problem(problem), fields, t_eval, formulas, dense,
                                   "integrate")
    problem = _with_fields(problem, _with_mirror(fields, mirror), "integrate",
                           _FIELD_SECTIONS, _RUN_OPTIONS)
    run = _fracvi.integrate(problem._spec,
                            _run_options(diagnostics, newton_absolute_tolerance, history, start,
                                         callables))
    solution = Solution(run, problem)
    if run.interrupt is not None:
        # Ctrl-C (or another signal whose handler raised) during the run: the run stopped at the
        # next check (about every 0.1 s) with status "interrupted"; its exception is raised here
        # with the trajectory so far attached.
        interrupt = run.interrupt
        interrupt.solution = solution
        raise interrupt
    if raise_on_failure and not solution.ok and solution.status != "event":
        raise IntegrationError(solution)
    return solution


State = namedtuple("State", "k t x v p energy dissipated balance")
State.__doc__ = """The state of an Integrator after step k: t = t_k, positions x_k, velocities v_k,
momenta p_k = M v_k (arrays, copies), and the diagnostics E_k, W_k, E_k + W_k − E_0 (NaN with
diagnostics=False)."""


class Integrator:
    """Steps a problem by hand: the C++ Integrator (fracvi/integrate/integrator.hpp) from Python.

    Integrator(problem, **options) takes what integrate() takes: a Problem, a dict or a TOML
    path/text, any key of [method] and [output] as a keyword (scheme="fvi-bdf2", every=10, ...)
    (mirror as in integrate) and the run options newton_absolute_tolerance, diagnostics, history,
    start and
    raise_on_failure. It checks the problem and sets up the whole storage at once (as integrate
    does), then

    * step() takes one step and returns the status ("running" while steps remain, "success" after
      the last one, or a failure: "newton-failure", "non-finite", "unstable", …);
    * run(until=t) takes the steps up to the last grid time t_k <= t (the grid is t_0 + k h;
      round-off of 1e-9 steps is forgiven), run(steps=n) n more (at most to the end), run() all
      that remain; observer(state) is called after every step (and at k = 0 when no step was
      taken yet). Returns the status;
    * state is the State (k, t, x, v, p, energy, dissipated, balance) now; status, k, t and
      steps (N) the rest.
    * solution() returns a Solution of the steps taken: while running the rows so far with
      status "running"; once the run has ended, the finished Solution (mirror run and error
      estimate included), the same as integrate(problem) returns, bit for bit.

    A step that fails ends the integration: the status says how (as in integrate), solution()
    has the message and the rows so far; raise_on_failure=True raises IntegrationError instead.
    An exception raised by the observer ends run() and propagates with the solution so far as its
    attribute .solution; the Integrator stays at the last completed step and can go on. Ctrl-C
    during run() stops it before the next step (within about 0.1 s) and raises KeyboardInterrupt
    with .solution (status "interrupted", the rows so far); the Integrator can go on here too.
    method.tolerance > 0 (which reruns the problem with more steps) is refused: use integrate.
    The GIL is released while it steps; another thread using the same Integrator meanwhile gets
    a RuntimeError. It does not pickle.
    """

    __slots__ = ("_native", "problem", "_raise_on_failure")

    def __init__(self, problem, *, newton_absolute_tolerance=0.0, mirror=None, diagnostics=True,
                 history=None, start="legendre", raise_on_failure=False, t_eval=None,
                 events=None, dense=False, **fields):
        formulas, callables = _split_events(events)
        problem, fields = _with_output(_as_problem(problem), fields, t_eval, formulas, dense,
                                       "Integrator")
        self.problem = _with_fields(problem, _with_mirror(fields, mirror),
                                    "Integrator", _FIELD_SECTIONS, _RUN_OPTIONS)
        self._native = _fracvi.Stepping(self.problem._spec, _run_options(
            diagnostics, newton_absolute_tolerance, history, start, callables))
        self._raise_on_failure = bool(raise_on_failure)

    status = property(lambda self: self._native.status,
                      doc='"running" while steps remain, then how the run ended')
    k = property(lambda self: self._native.steps_done, doc="steps done")
    t = property(lambda self: self._native.time, doc="t_k, the time of the current state")
    steps = property(lambda self: self._native.steps_total, doc="N, the steps of the grid")

    @property
    def state(self):
        """The State (k, t, x, v, p, energy, dissipated, balance) after the last step."""
        return State(*self._native.state())

    def step(self):
        """Takes one step (nothing once the run has ended) and returns the status."""
        status = self._native.step()
        if self._native.interrupt is not None:  # Ctrl-C inside a Python model function
            interrupt = self._native.interrupt
            interrupt.solution = self.solution()
            raise interrupt
        return self._checked(status)

    def run(self, until=None, *, steps=None, observer=None):
        """Steps to the last grid time <= until, or `steps` more steps, or to the end (neither);
        observer(state), if given, is called after every step. Returns the status."""
        target = self._target(until, steps)
        if observer is not None and not callable(observer):
            raise TypeError(f"observer = {observer!r} is not callable (a function of a State)")
        call = None if observer is None else (lambda *state: observer(State(*state)))
        try:
            status = self._native.run(target, call)
        except BaseException as error:  # raised by the observer (or Ctrl-C inside it)
            error.solution = self._partial(error)
            raise
        if self._native.interrupt is not None:
            interrupt = self._native.interrupt
            interrupt.solution = self._partial(interrupt)
            raise interrupt
        return self._checked(status)

    def solution(self):
        """A Solution of the steps taken (see the class)."""
        run = self._native.solution()
        solution = Solution(run, self.problem)
        if run.interrupt is not None:  # Ctrl-C during the error estimate's companion runs
            interrupt = run.interrupt
            interrupt.solution = solution
            raise interrupt
        return solution

    def __reduce__(self):
        raise TypeError("a fracvi.Integrator does not pickle (it holds a running C++ "
                        "integration); pickle its problem, or its solution()")

    def _partial(self, error):
        if isinstance(error, KeyboardInterrupt):
            return Solution(self._native.interrupted_solution(), self.problem)
        return self.solution()

    def _checked(self, status):
        if self._raise_on_failure and status not in ("running", "success", "event"):
            raise IntegrationError(self.solution())
        return status

    def _target(self, until, steps):
        """The step run() goes to."""
        k, total = self._native.steps_done, self._native.steps_total
        if until is not None and steps is not None:
            raise TypeError("run() takes until= or steps=, not both")
        if steps is not None:
            if isinstance(steps, (bool, np.bool_)) or not isinstance(steps, (int, np.integer)):
                raise TypeError(f"steps = {steps!r} must be an integer (the number of steps)")
            if steps < 0:
                raise ValueError(f"steps = {steps} must not be negative")
            return min(total, k + int(steps))
        if until is None:
            return total
        if isinstance(until, (bool, np.bool_)) or not isinstance(until, (int, float, np.number)):
            raise TypeError(f"until = {until!r} must be a number (a time)")
        p = self.problem
        position = (float(until) - p.start) / p.step  # in steps
        if not np.isfinite(position):
            raise ValueError(f"until = {until!r} must be a finite time")
        if position > total + 1e-9:
            raise ValueError(f"until = {until!r} is after the problem's end time time.end = "
                             f"{p.end!r}: the Integrator's grid ends there")
        if position < k - 1e-9:
            raise ValueError(f"until = {until!r} is before the current time t = {self.t!r} "
                             f"(step {k}): an Integrator only goes forward")
        return min(total, int(np.floor(position + 1e-9)))

    def __repr__(self):
        return (f"Integrator(status={self.status!r}, k={self.k}, steps={self.steps}, "
                f"t={self.t:g}, problem={self.problem.name!r})")


def compare(problem, *, steps, schemes=None, reference=None, reference_steps=0,
            reference_scheme=None, energy_steps=None, repeat=1):
    """Runs every scheme at every step count on `problem` and measures each run against one
    reference (the library behind `fracvi compare`; docs/comparison.md).

    steps: increasing step counts. schemes: registry names (default: every scheme in methods();
    one that does not apply, or a step beyond its stability bound, is a row with status
    "not applicable" and the reason in "message"). reference: the exact x(t) as d formulas in t
    (default: the problem's [reference] position); or reference_steps: a fine run with that many
    steps (a larger multiple of every step count) by reference_scheme (default: dopri5 at
    tolerances 1e-13 where it applies, else fvi-lobatto4, fvi-lobatto3, fvi-midpoint).
    energy_steps: the N of the energy track (one of steps; default the middle one). repeat: runs
    per scheme and N, the best wall time kept. Each run stores every step and runs without the
    mirror run and error estimate, so wall_seconds is the integration alone.

    Returns a dict: "table" (columns as NumPy arrays or lists: scheme, steps, declared_order,
    status, h, final_error, max_error, energy_error, dissipated_error, balance_error,
    wall_seconds, newton_iterations, message), "reference", "energy_reference" (how E_ref was
    obtained) and "energy" (t, reference_energy, reference_dissipated, and dicts "energy",
    "dissipated" of the per-scheme E_k and W_k at energy_steps). Errors are NaN for runs that did
    not succeed. Bad arguments raise ValueError; a failing reference run RuntimeError.
    """
    problem = _as_problem(problem)
    steps = [int(n) for n in steps]
    if not steps:
        raise ValueError("steps: give at least one step count")
    if any(n < 1 for n in steps):
        raise ValueError(f"steps = {steps}: step counts must be positive")
    if schemes is None:
        schemes = [m["name"] for m in methods()]
    elif isinstance(schemes, str):
        schemes = [schemes]
    if isinstance(reference, str):
        reference = [reference]
    if int(repeat) < 1:
        raise ValueError(f"repeat = {repeat}: must be at least 1")
    if energy_steps is None:
        energy_steps = steps[len(steps) // 2]
    result = _fracvi.compare(problem._spec, list(schemes), steps, list(reference or []),
                             int(reference_steps), reference_scheme or "", int(energy_steps),
                             int(repeat))
    table = result["table"]
    for key in ("scheme", "status", "message"):
        table[key] = np.array(table[key], dtype=object)
    result["problem"] = problem.to_dict()
    return result


def plot_compare(result, directory):
    """Draws work_precision.png, error_vs_steps.png and energy_tracking.png of a compare() result
    into `directory` (created if needed); returns the paths."""
    _figures = _compare_figures
    os.makedirs(directory, exist_ok=True)
    meta = {"problem": result.get("problem", {}), "reference": result["reference"],
            "energy_reference": result["energy_reference"],
            "energy_steps": result["energy"]["steps"],
            "adaptive": [m["name"] for m in methods() if m["adaptive"]]}
    paths = []
    for name, draw in (("work_precision.png", _figures.plot_work_precision),
                       ("error_vs_steps.png", _figures.plot_error_vs_steps)):
        paths.append(os.path.join(directory, name))
        draw(result["table"], meta, paths[-1])
    e = result["energy"]
    if e["steps"]:
        curves = {s: (e["energy"][s], e["dissipated"][s]) for s in e["energy"]}
        paths.append(os.path.join(directory, "energy_tracking.png"))
        _figures.plot_energy_tracking(
            (e["t"], e["reference_energy"], e["reference_dissipated"], curves), meta, paths[-1])
    return paths


def _with_fields(problem, fields, function, valid_fields, run_options):
    """`problem` with the [method]/[output] keywords `fields` applied (validated by the reader,
    like a problem file); an unknown keyword is a TypeError naming the valid ones."""
    sections = {}
    for key, value in fields.items():
        section = valid_fields.get(key)
        if section is None:
            valid = ", ".join(sorted(valid_fields)) + ", " + ", ".join(run_options)
            raise TypeError(f"{function}() got an unexpected keyword argument '{key}' "
                            f"(valid: {valid})")
        if value is not None:
            sections.setdefault(section, {})[key] = value
    if not sections:
        return problem
    document = problem.to_dict()
    for section, values in sections.items():
        document.setdefault(section, {}).update(values)
    return problem._rebuild(document)


# ---------------------------------------------------------------------------------------------
# Boundary value problems

class BvpSolution:
    """The result of solve_bvp(): the curves x and y of the restricted discrete variational
    principle (`DiscFracEL`) with x(a) = start = y(b), x(b) = end = y(a), the residuals of the
    equations, Newton's statistics and a status — what `fracvi bvp` prints and writes.

    t (N+1,), x, y, x_residual, y_residual (N+1, d) are read-only NumPy views of the C++ storage
    (the best iterate Newton found; residual rows 0 and N are zero). status is "success" when
    every equation is at most residual_tolerance in absolute value.
    """

    __slots__ = ("_run", "problem")

    def __init__(self, run, problem):
        self._run = run
        self.problem = problem

    def __reduce__(self):
        # Pickled as its fields and arrays (multiprocessing.Pool.map(fracvi.solve_bvp, ...)).
        return _unpickle_bvp_solution, (self.problem, _fracvi.bvp_state(self._run))

    t = _view("t", "t_k = start + k h, shape (N+1,)")
    x = _view("x", "x_k, shape (N+1, d), x[0] = boundary start, x[N] = boundary end")
    y = _view("y", "y_k, shape (N+1, d), y[0] = boundary end, y[N] = boundary start")
    x_residual = _view("x_residual", "the x-equations of DiscFracEL at k, shape (N+1, d)")
    y_residual = _view("y_residual", "the y-equations of DiscFracEL at k, shape (N+1, d)")
    status = _view("status", '"success", "newton-failure", "non-finite", …')
    ok = _view("ok", "status == 'success'")
    message = _view("message", "empty on success; otherwise the cause and the iteration")
    residual_norm = _view("residual_norm", "max |x_residual|, |y_residual|")
    residual_floor = _view("residual_floor",
                           "estimated rounding level of the equations (a tolerance below it "
                           "cannot be met)")
    residual_tolerance = _view("residual_tolerance", "the tolerance it was solved to")
    residual_history = _view("residual_history",
                             "max |F| before each Newton iteration, and the last (a list)")
    newton_iterations = _view("newton_iterations", "Newton iterations")
    linear_iterations = _view("linear_iterations", "GMRES iterations in total (0 for dense LU)")
    linear_solver = _view("linear_solver", 'e.g. "dense LU (n = 396)"')
    sum = _view("sum", '"extended" or "printed": the action sum whose equations were solved')
    wall_time = _view("wall_time", "seconds")

    @property
    def scheme(self):
        """The scheme whose Δ^α_± were used ([method] scheme; "auto" takes fvi-gl for a boundary
        value problem, as `fracvi bvp` does)."""
        scheme = self.problem.scheme
        return "fvi-gl" if scheme == "auto" else scheme

    @property
    def dim(self):
        return self._run.x.shape[1]

    @property
    def mirror_error(self):
        """max_k ‖y_k − x_(N−k)‖_∞ (what `fracvi bvp` prints as `mirror`)."""
        x, y = self.x, self.y
        return float(np.max(np.abs(y - x[::-1]))) if len(x) else 0.0

    def summary(self):
        """The content of the summary.json of `fracvi bvp` as a dict."""
        return self._run.summary()

    def write(self, directory):
        """Writes trajectory.csv (t, x, y, residual_x, residual_y), summary.json and
        problem.toml into `directory`, as `fracvi bvp --out directory` does. Returns it."""
        directory = os.fspath(directory)
        self._run.write(directory)
        return directory

    def __repr__(self):
        return (f"BvpSolution(status={self.status!r}, N={len(self.t) - 1}, dim={self.dim}, "
                f"residual_norm={self.residual_norm:.3g}, scheme={self.scheme!r})")


def _unpickle_bvp_solution(problem, state):
    return BvpSolution(_fracvi.restore_bvp_run(problem._spec, state), problem)


def solve_bvp(problem, *, sum="extended", solver="auto", tolerance=None, raise_on_failure=False,
              **fields):
    """Solves the variational boundary value problem of `problem` (a Problem, a dict, or a TOML
    path/text with a [boundary] section), as `fracvi bvp` does: all interior x_k, y_k of the
    restricted discrete fractional Euler–Lagrange equations (`DiscFracEL`) at once, by Newton's
    method with the exact Jacobian, for the problem's Lagrangian ([model] lagrangian, or the
    mechanical fields with the Riemann–Liouville convention).

    The fractional differences Δ^α_± are those of [method] scheme (Grünwald–Letnikov for
    "fvi-gl", BDF2 convolution quadrature for "fvi-bdf2"); a scheme without a boundary value form
    raises ProblemError. Every key of [method] and [output] may be given as a keyword, as for
    integrate() (scheme, newton_max_iterations: Newton's iteration limit, every: the stride of
    the written trajectory.csv, …). The rest are the options of `fracvi bvp`: sum ("extended":
    the paper's printed DiscFracEL, or "printed": the exact equations of the printed action sum),
    solver ("auto", "dense" or "krylov") and tolerance (converged when every equation is at most
    this in absolute value; default None: 1e-10, or the round-off floor of the equations when
    that is larger, as it is for many steps; a tolerance given is taken as given).

    Returns a BvpSolution. Numerical failure is a status (the best iterate is returned);
    raise_on_failure=True raises IntegrationError instead. Bad input raises ProblemError.
    """
    problem = _with_fields(_as_problem(problem), fields, "solve_bvp", _BVP_FIELD_SECTIONS,
                           _BVP_OPTIONS)
    run = _fracvi.solve_bvp(problem._spec, sum, solver,
                            None if tolerance is None else float(tolerance))
    solution = BvpSolution(run, problem)
    if raise_on_failure and not solution.ok:
        raise IntegrationError(solution)
    return solution


TRAJECTORY_FORMATS = ("csv", "npz")


def write(solution, problem=None, directory=None, *, plot=False, format=None):
    """Writes the files of `fracvi run` — trajectory.csv, summary.json, problem.toml — into
    `directory` (created if needed); with plot=True also its plots (fracvi.plot).

    Call as write(solution, problem, directory) or write(solution, directory); the problem
    defaults to the one the solution was computed from (it is recorded in summary.json and
    problem.toml). trajectory.csv has one line per stored row of the solution (the run already
    kept only every output.every-th state), 17 significant digits, so every number reads back
    to itself. format="npz" writes trajectory.npz instead (NumPy's uncompressed archive of the
    arrays t, step, x, v, energy, dissipated, balance as stored: smaller, and about 30 times
    faster to write and read for large systems); either way an earlier run's trajectory in the
    other format is removed, and summary.json is written last. format=None takes the problem's
    output.format ("csv" unless set); a format given here leaves the problem (and its
    problem.toml) as it is, so that load(directory).problem == problem.
    fracvi.load reads both back. Returns the directory.
    """
    if format is not None and format not in TRAJECTORY_FORMATS:
        raise ValueError(f"write: format = {format!r} must be one of "
                         f"{', '.join(map(repr, TRAJECTORY_FORMATS))}")
    if directory is None and isinstance(problem, (str, os.PathLike)):
        problem, directory = None, problem
    if directory is None:
        raise TypeError("write() needs a directory")
    problem = solution.problem if problem is None else _as_problem(problem)
    if problem.dim != solution.dim:
        raise ValueError(f"write: the problem has dimension {problem.dim}, the solution "
                         f"{solution.dim}")
    directory = os.fspath(directory)
    solution._run.write(directory, problem._spec, format or "")
    if plot:
        _plotting.plot_run(directory)
    return directory


def load(directory, *, functions=None):
    """The Solution of a run directory written by `fracvi run --out`, fracvi.write (CSV or npz)
    or a sweep's saved case (out/cases/<case>/), with its problem: problem.toml (or, without it,
    summary.json's "problem"), the statistics and status of summary.json, the rows of
    trajectory.npz or trajectory.csv.

    The loaded solution equals the one written, bit for bit (the CSV's 17 significant digits
    read back to the same doubles; the step indices, which the CSV has no column for, follow
    from summary.json's steps and save_every), with the states at output.times (times.csv: t_eval,
    x_eval, v_eval) and the event crossings (summary.json). Only the damping memory's size (not
    in the files) is not restored. A directory without summary.json (a run still going, or stopped before it
    wrote one), a trajectory that does not match the summary or the problem, or the output of
    `fracvi bvp` or `fracvi sweep` raises an error naming the file and what is wrong.

    A run whose potential or force was given as Python functions records their names: they are
    imported again, or given as functions=dict(potential=U, gradient=g, hessian=H, force=f,
    force_jacobian=J) (the keys the problem needs).
    """
    directory = os.fspath(directory)
    if not os.path.isdir(directory):
        raise FileNotFoundError(f"load: {directory} is not a directory (the --out directory of "
                                f"`fracvi run`, or one fracvi.write wrote)")
    summary_path = os.path.join(directory, "summary.json")
    if not os.path.exists(summary_path):
        sweep = os.path.exists(os.path.join(directory, "results.csv"))
        raise FileNotFoundError(
            f"load: {summary_path} does not exist: " +
            ("this is a sweep's directory; fracvi.load_sweep reads its results.csv, "
             "fracvi.load a case's directory under cases/" if sweep else
             "a run directory holds a complete run once summary.json, written last, is there"))
    summary = _plotting.load_summary(directory)
    if "residual_norm" in summary:
        raise ValueError(f"load: {directory} holds a boundary value solution (`fracvi bvp`); "
                         f"fracvi.load reads initial value runs")
    toml = os.path.join(directory, "problem.toml")
    if os.path.exists(toml):
        problem = Problem.from_toml(toml, functions=functions)
    elif isinstance(summary.get("problem"), dict):
        problem = Problem.from_dict(summary["problem"], source=f'{summary_path}: "problem"',
                                    functions=functions)
    else:
        raise FileNotFoundError(f"load: {directory} has neither problem.toml nor a \"problem\" "
                                f"in summary.json")
    arrays = _plotting.load_trajectory(directory)
    trajectory = _plotting.trajectory_file(directory)
    run = _fracvi.restore_run(problem._spec, summary,
                              *(arrays[name] for name in _plotting.ARRAYS), trajectory,
                              _read_times(directory, summary, problem.dim))
    if "step" in arrays and not np.array_equal(arrays["step"], run.step):
        raise ValueError(f"{trajectory}: step = {arrays['step'].tolist()[:8]}… differs from the "
                         f"rows summary.json's steps = {run.steps} and save_every = "
                         f"{run.save_every} make")
    return Solution(run, problem)


def _read_times(directory, summary, dim):
    """(t, x, v) of times.csv (the states at output.times), or None when the run had none."""
    if not summary.get("output_times"):
        return None
    path = os.path.join(directory, "times.csv")
    if not os.path.exists(path):
        raise FileNotFoundError(f"load: {path} does not exist, and summary.json records "
                                f"output_times = {summary['output_times']} states at "
                                f"output.times (written to times.csv)")
    table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if table.shape[1] != 1 + 2 * dim:
        raise ValueError(f"{path}: {table.shape[1]} columns; t, x1..xd, v1..vd make "
                         f"{1 + 2 * dim} for the problem's dim = {dim}")
    return table[:, 0].copy(), table[:, 1:1 + dim].copy(), table[:, 1 + dim:].copy()


def plot(solution, directory=None, *, show=None):
    """The plots of `fracvi run`: trajectory, phase portrait and energy balance, and for d > 8 a
    space-time image of x_i(t) (large systems: a few coordinates are drawn, the phase portrait
    is that of the largest excursion).

    solution: a Solution, or the directory of a finished run (trajectory.csv + summary.json).
    With a directory, writes trajectory.png, phase.png, energy.png (and spacetime.png for
    d > 8; 800 × 500 px) there and returns their paths; nothing is shown unless show=True.
    Without one, the figures are created with pyplot, shown (show=None or True; set show=False to
    only get them) and returned.
    """
    if isinstance(solution, (str, os.PathLike)):
        arrays, summary = _plotting.load(os.fspath(solution))
        arrays = {name: arrays[name] for name in _plotting.ARRAYS}
    else:
        summary = solution.summary()
        arrays = dict(t=solution.t, x=solution.x, v=solution.v, energy=solution.energy,
                      dissipated=solution.dissipated, balance=solution.balance)
    if directory is not None:
        figures = _plotting.figures(summary=summary, **arrays)
        paths = _plotting.save(figures, os.fspath(directory))
        if show:
            plot(solution, None, show=True)
        return paths
    figures = _plotting.figures(summary=summary, pyplot=True, **arrays)
    if show is None or show:
        import matplotlib.pyplot as plt
        plt.show()
    return figures


# ---------------------------------------------------------------------------------------------
# The problem-file schema and the method registry

def sweep(problem, parameters, *, jobs=1, combine="grid", save="final", out=None,
          resume=False):
    """Runs a parameter sweep (`fracvi sweep`, docs/sweep-file.md) and returns its table.

    problem: the base problem (a Problem, the dict of a problem file, or a path to one).
    parameters: {field: values} over fields of the problem schema, in the order of the grid (the
    first varies slowest): a list or array of values, or a dict {"linspace": [start, stop, n]},
    {"logspace": [start, stop, n]} (n values from start to stop evenly in log),
    {"random": "uniform" | "loguniform", "low": a, "high": b, "count": n, "seed": s} or
    {"random": "normal", "mean": m, "std": s, "count": n, "seed": s}; e.g.
    {"model.damping_order": {"linspace": [0.2, 1.8, 6]}, "model.damping": [0.1, 1.0]}.
    combine: "grid" (every combination) or "zip" (the i-th values together).
    save: "summary" (no final state columns), "final" (x1..xd, v1..vd) or "trajectory" (also each
    case's `fracvi run` files in out/cases/<case>/; needs out).
    jobs: cases run at once on threads; each case runs on one thread unless the sweep sets
    method.threads, so the numbers do not depend on jobs.
    out: a directory for results.csv (appended as cases finish) and sweep.json, as `fracvi sweep
    --out`; resume=True continues the sweep there.

    Every case is checked before any runs; a case refused then, or one that fails, is a row with
    its status and message, never an exception. A sweep that is not one (an unknown field, zipped
    lists of different lengths, ...) raises ProblemError.
    Returns a SweepResult: column name -> NumPy array in case order, and .parameters."""
    if isinstance(problem, Problem):
        if problem._functions is not None:
            what = " and ".join(g for g in _FUNCTION_GROUPS if g in problem._functions)
            raise ProblemError(f"sweep: {problem.source}: the {what} is given as Python "
                               f"functions, and a sweep's cases are read from the problem's "
                               f"dict like problem files, which cannot hold functions: give "
                               f"formulas, or loop over fracvi.integrate "
                               f"(problem.with_overrides(...), multiprocessing.Pool.map)")
        document = {"problem": problem.to_dict()}
    elif isinstance(problem, Mapping):
        document = {"problem": _plain(problem)}
    elif isinstance(problem, (str, os.PathLike)):
        document = {"base": os.fspath(problem)}
    else:
        raise TypeError(f"sweep: problem must be a fracvi.Problem, a dict or a path, not "
                        f"{type(problem).__name__}")
    if not isinstance(parameters, Mapping):
        raise TypeError("sweep: parameters must be a dict {field: values}")
    document["sweep"] = {"combine": combine, "save": save,
                         "parameters": [[k, _plain(v)] for k, v in parameters.items()]}
    if save == "trajectory" and out is None:
        raise ValueError('sweep: save="trajectory" writes files: give out=DIRECTORY')
    columns, rows = _fracvi.sweep(document, "<fracvi.sweep>", os.getcwd(), int(jobs),
                                  "" if out is None else os.fspath(out), bool(resume))
    return _sweep_plotting.table(columns, rows)


def load_sweep(path):
    """The SweepResult of a results.csv written by `fracvi sweep` (or of its directory)."""
    return _sweep_plotting.load(path)


def plot_sweep(result, quantity="energy_final", *, x=None, y=None, file=None):
    """A matplotlib Figure of `quantity` over a sweep (a SweepResult, or a results.csv path): a
    heat map over two parameters (x, y; by default the sweep's two), or the quantity against one
    parameter x. Cases that did not succeed are blank (heat map) or crosses (lines). Saved to
    `file` if given."""
    if isinstance(result, (str, os.PathLike)):
        result = load_sweep(result)
    return _sweep_plotting.plot(result, quantity, x=x, y=y, file=file)


def problem_schema():
    """Every field of a problem file (the one schema of the reader, the writers, the docs and the
    keywords of integrate() and solve_bvp()): a list of dicts with section ("" for the top
    level), key, type, default, summary and binding, the C++ member the field fills (e.g.
    "InitialValueProblem::x0" for [initial] position; "" for a section). Keywords use the keys."""
    return _fracvi.problem_schema()


# integrate()'s keywords from [method] and [output] (the "history" key is a run option there).
# Not keywords: `history` (a run option below) and `checkpoint_every` (the checkpoints of
# `fracvi run`'s output directory; integrate() writes none and refuses a problem that asks).
_NOT_KEYWORDS = ("history", "checkpoint_every")
_FIELD_SECTIONS = {row["key"]: row["section"] for row in _fracvi.problem_schema()
                   if row["section"] in ("method", "output") and row["key"] not in _NOT_KEYWORDS}
_RUN_OPTIONS = ("newton_absolute_tolerance", "diagnostics", "history", "start",
                "raise_on_failure", "t_eval", "events", "dense")
# solve_bvp()'s keywords: every key of [method] and [output] but those of the initial value
# drivers (the error estimate and its tolerance; solve_bvp's own `tolerance` is its residual's;
# flush_subnormals is the step loop's floating-point setting, not the BVP's Newton solve's).
_IVP_ONLY = ("error_estimate", "tolerance", "max_steps", "checkpoint_every", "mirror",
             "flush_subnormals", "format")  # a BVP writes trajectory.csv of x, y and the residuals
_BVP_FIELD_SECTIONS = {row["key"]: row["section"] for row in _fracvi.problem_schema()
                       if row["section"] in ("method", "output") and row["key"] not in _IVP_ONLY}
_BVP_OPTIONS = ("sum", "solver", "tolerance", "raise_on_failure")

def methods():
    """The time-stepping schemes, one dict per scheme (the registry `fracvi methods` prints):
    name, order (declared, in words), stages, variational, mirror, exact_balance, fast_history,
    adaptive (the error follows abs_tolerance/rel_tolerance, not h), applies_to, stability (the
    bound), summary, reference. Pass a name as integrate(..., scheme=NAME)."""
    return _fracvi.methods()


# ---------------------------------------------------------------------------------------------
# Weights, discrete operators, Riemann–Liouville derivatives

def gl_weights(order, n):
    """The first n Grünwald–Letnikov weights α_0..α_{n−1} of (1 − ζ)^order (`AlphaDef`):
    α_0 = 1, α_k = α_{k−1}(k − 1 − order)/k, any real order (re-anchored to Gamma ratios every
    4096 terms; relative error below about 1e-12 for any n)."""
    return _fracvi.gl_weights(float(order), _count(n))


def cq_weights(order, n, scheme="gl"):
    """The first n convolution-quadrature weights of s^order: Taylor coefficients of δ(ζ)^order
    with δ = 1 − ζ ("gl", equal to gl_weights), (1 − ζ) + (1 − ζ)²/2 ("bdf2") or
    2(1 − ζ)/(1 + ζ) ("trapezoidal"). For step h the operator is h^(−order) Σ w_m z_{k−m}."""
    return _fracvi.cq_weights(float(order), _count(n), scheme)


def _count(n):
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"n must be an integer, not {n!r}")
    return int(n)


_SEQUENCE_DOC = """

    z is a sequence z_0..z_N: an array of shape (N+1,) (scalars) or (N+1, d) (row k is z_k ∈ R^d),
    anything np.asarray accepts. The result has the same shape, row k the operator at index k;
    rows outside the paper's index range are zero (`AllSequencs`)."""


def midpoint(z):
    """S z_k = (z_k + z_{k+1})/2 for k = 0..N−1 (`MidpointRule`); row N is 0."""
    return _fracvi.midpoint(z)


def delta_minus(z, h):
    """Δ_− z_k = (z_k − z_{k−1})/h for k = 1..N (`DiscDerDef`); Δ_− z_0 := 0."""
    return _fracvi.delta_minus(z, float(h))


def delta_plus(z, h):
    """Δ_+ z_k = −(z_{k+1} − z_k)/h for k = 0..N−1 (`DiscDerDef`, note the sign); row N is 0."""
    return _fracvi.delta_plus(z, float(h))


def frac_delta_minus(z, h, alpha, quadrature="gl"):
    """Δ^α_− z_k = h^(−α) Σ_{n=0}^{k} w_n z_{k−n} for k = 0..N (`DiscFracDerDef`), with the
    weights w_n = cq_weights(alpha, N+1, quadrature): the paper's Grünwald–Letnikov α_n for
    quadrature="gl" (order 1), BDF2 ("bdf2", order 2; the Δ^α_− of the scheme fvi-bdf2) or the
    trapezoidal rule ("trapezoidal", order 2)."""
    return _fracvi.frac_delta_minus(z, float(h), float(alpha), quadrature)


def frac_delta_plus(z, h, alpha, quadrature="gl"):
    """Δ^α_+ z_k = h^(−α) Σ_{n=0}^{N−k} w_n z_{k+n} for k = 0..N (`DiscFracDerDef`), with the
    weights of frac_delta_minus (quadrature "gl", "bdf2" or "trapezoidal")."""
    return _fracvi.frac_delta_plus(z, float(h), float(alpha), quadrature)


def convolve_past(w, z):
    """Σ_{m=0}^{k} w_m z_{k−m} for k = 0..N (the causal convolution; len(w) ≥ N+1)."""
    return _fracvi.convolve_past(w, z)


def convolve_future(w, z):
    """Σ_{m=0}^{N−k} w_m z_{k+m} for k = 0..N (the anti-causal convolution; len(w) ≥ N+1)."""
    return _fracvi.convolve_future(w, z)


for _f in (midpoint, delta_minus, delta_plus, frac_delta_minus, frac_delta_plus, convolve_past,
           convolve_future):
    _f.__doc__ += _SEQUENCE_DOC


def rl_derivative(alpha, f, t, a, b, side="left", df=None, tolerance=_fracvi.default_rl_tolerance):
    """The Riemann–Liouville derivative D^α_− f(t) (side="left": memory of the past from a) or
    D^α_+ f(t) (side="right": memory of the future up to b, with the paper's sign D^1_+ f = −f')
    on [a, b], α ∈ [0, 1] (the paper's `RL`), by tanh–sinh quadrature of a form that needs f and
    its derivative f'.

    f is a formula in t (a str, e.g. "t^1.5*exp(-t)"; its derivative is then exact, from the
    expression engine) or a Python callable float -> float, in which case df (f', a callable or
    a formula) is required: fracvi does not differentiate numerically. t is a number (returns a
    float) or an array (returns an array of the same shape). Accurate to about 1e-12 relative
    for smooth f. At the terminal the value is ±inf when f(terminal) ≠ 0 and 0 < α < 1.
    """
    return _fracvi.rl_derivative(float(alpha), f, t, float(a), float(b), side, df,
                                 float(tolerance))


def rl_derivative_power(order, p, t, a, b, side="left"):
    """Closed form D^order_− (t − a)^p (side="left") or D^order_+ (b − t)^p (side="right"):
    Γ(p+1)/Γ(p+1−order) · d^(p−order), d = t − a resp. b − t; any order ≥ 0, p > −1."""
    return _fracvi.rl_derivative_power(float(order), float(p), t, float(a), float(b), side)


# ---------------------------------------------------------------------------------------------
# The continuous equations along given curves (FracEL, ActFunc)

_CURVE_DOC = """
    Curves (x, y, eta, eta_y) are a formula in t (str, d = 1), a list of d formulas (derivatives
    exact, from the expression engine), or a tuple (f, fdot, fddot) of callables t -> float
    (d = 1) or t -> sequence of d floats: fracvi does not differentiate numerically, so callables
    bring their first and second derivatives. The Lagrangian is the problem's ([model]
    lagrangian, or the mechanical L of M, R, U), of order problem.alpha, on [time.start,
    time.end]. Bad input and residuals or integrals that do not exist (docs/cli.md, `residual`
    and `action`) raise ValueError with the reason.
"""


def fracel_residual(problem, x, y, t, tolerance=1e-12):
    """Residuals of the restricted fractional Euler-Lagrange equations (`FracEL`) along the
    curves x(t), y(t) at the times t: returns (x_equation, y_equation), each of shape
    (len(t), d) (or (d,) for a scalar t), x_equation = dL/dx - d/dt dL/dxdot +
    D^alpha_-(dL/dD^alpha_+ y), y_equation = dL/dy - d/dt dL/dydot + D^alpha_+(dL/dD^alpha_- x).
    Nested tanh-sinh quadratures at relative tolerance `tolerance` (about 1e-15 on smooth
    curves; x(start), y(end) != 0 are handled in closed form where the coupling allows).
    """
    problem = _as_problem(problem)
    scalar = np.ndim(t) == 0
    points = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
    ex, ey = _fracvi.fracel_residual(problem._spec, x, y, points.tolist(), float(tolerance))
    ex, ey = np.asarray(ex), np.asarray(ey)
    return (ex[0], ey[0]) if scalar else (ex, ey)


def action(problem, x, y, eta=None, eta_y=None, *, pairing=False, tolerance=1e-12):
    """The action A = integral of L(x, y, xdot, ydot, D^alpha_- x, D^alpha_+ y) dt (`ActFunc`)
    along the curves x(t), y(t), as {"action": A}. With eta, also "variation": the first
    variation dA = d/de A[x + e eta, y + e eta_y] at e = 0 (exact derivative in e; eta_y defaults
    to eta: the restricted variation of `ConsVariations`). With pairing=True, also "pairing":
    the integral of (E_x . eta + E_y . eta_y) dt with E_x, E_y the FracEL residuals, equal to
    dA for restricted variations vanishing at the ends (Theorem `ConsFraEL`); it needs eta and
    eta' to vanish at both ends and costs one residual per quadrature node (seconds).
    """
    problem = _as_problem(problem)
    if eta is None and (eta_y is not None or pairing):
        raise ValueError("action: eta_y and pairing need eta (the variation of x)")
    return _fracvi.action(problem._spec, x, y, eta, eta_y, bool(pairing), float(tolerance))


fracel_residual.__doc__ += _CURVE_DOC
action.__doc__ += _CURVE_DOC
