#!/usr/bin/env python3
"""Checks the layered include order of the library (include/ and src/).

Every C++ file under include/ and src/ belongs to one layer of LAYERS (a file pattern naming it,
otherwise the longest folder pattern containing it). A file may include only headers of its own
layer or of the layers below it: `#include "fracvi/..."` (and <fracvi/...>) name a file under
include/, any other quoted include is resolved relative to the including file. apps/, python/,
tests/, bench/ and examples/ sit on top of everything and are not checked.

Exit status 1 with one line per problem:
    path:line: <layer> includes <header> of higher layer <layer>
and for a file (or an included header) that no layer claims: add its folder to LAYERS.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The layers, bottom up: (name, path patterns relative to the root). A pattern ending in "/" is a
# folder, any other a single file.
LAYERS = [
    # Matrices, status codes, error types, Newton options: no fracvi includes.
    ("core", ["include/fracvi/core/", "src/core/"]),
    # Header-only utilities (OpenMP helpers) anything above core may use.
    ("internal", ["include/fracvi/internal/"]),
    # Fractional weights, Riemann-Liouville operators, exponential fits, convolution quadrature.
    ("fractional", ["include/fracvi/fractional/", "src/fractional/"]),
    # Symbolic expressions: parser, graph, tape, derivatives (src/expression/graph.hpp included).
    ("expression", ["include/fracvi/expression/", "src/expression/"]),
    # Discrete fractional operators on sequences.
    ("discrete", ["include/fracvi/discrete/", "src/discrete/"]),
    # The memory of the damping term: histories (direct, local, fast) over a convolution quadrature.
    ("memory", ["include/fracvi/memory/", "src/memory/"]),
    # Mechanical model (M, R, U, f), potentials, ModelMatrix, InitialValueProblem.
    ("model", ["include/fracvi/model/", "src/model/"]),
    # Newton's method for the implicit midpoint step and the symmetric factorisations it uses.
    ("solve", ["include/fracvi/solve/", "src/solve/"]),
    # Time-stepping schemes: options, steppers, the scheme registry, stability bounds.
    ("schemes", ["include/fracvi/schemes/", "src/schemes/"]),
    # The integrator driver (integrate(), Integrator) and its result record Solution.
    ("integrate", ["include/fracvi/integrate/", "src/integrate/"]),
    # General Lagrangians, action sums, continuous residuals, boundary value problems.
    ("lagrangian", ["include/fracvi/lagrangian/", "src/lagrangian/"]),
    # Error measures and convergence studies over Solutions.
    ("analysis", ["include/fracvi/analysis/", "src/analysis/"]),
    # Problem files, run preparation, output files, the general-Lagrangian problem front end.
    ("io", ["include/fracvi/io/", "src/io/"]),
]

SOURCE_SUFFIXES = (".hpp", ".h", ".hh", ".ipp", ".inl", ".cpp", ".cc", ".cxx")
INCLUDE = re.compile(r'^\s*#\s*include\s*(?:"([^"]+)"|<(fracvi/[^>]+)>)')


def layer_of(path):
    """(index, name) of the layer of a root-relative path, or None: a file pattern first, then
    the longest folder pattern that contains the path."""
    folder = None
    for index, (name, patterns) in enumerate(LAYERS):
        for pattern in patterns:
            if pattern == path:
                return index, name
            if pattern.endswith("/") and path.startswith(pattern):
                if folder is None or len(pattern) > folder[0]:
                    folder = (len(pattern), index, name)
    return folder[1:] if folder else None


def sources():
    for top in ("include", "src"):
        for directory, dirs, files in os.walk(os.path.join(ROOT, top)):
            dirs.sort()
            for f in sorted(files):
                if f.endswith(SOURCE_SUFFIXES):
                    yield os.path.relpath(os.path.join(directory, f), ROOT).replace(os.sep, "/")


def main():
    problems = []
    files = includes = 0
    for path in sources():
        files += 1
        own = layer_of(path)
        if own is None:
            problems.append(f"{path}:1: file is in no layer (add its folder to LAYERS in "
                            f"scripts/check-layers.py)")
            continue
        with open(os.path.join(ROOT, path), encoding="utf-8") as f:
            lines = f.read().splitlines()
        for number, line in enumerate(lines, 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            name = m.group(1) or m.group(2)
            if name.startswith("fracvi/"):
                target = "include/" + name
            else:
                target = os.path.normpath(os.path.join(os.path.dirname(path), name))
                target = target.replace(os.sep, "/")
                if not os.path.isfile(os.path.join(ROOT, target)):
                    continue  # a system or third-party header found on the include path
            includes += 1
            theirs = layer_of(target)
            if theirs is None:
                problems.append(f"{path}:{number}: {own[1]} includes {name}, which is in no layer "
                                f"(add its folder to LAYERS in scripts/check-layers.py)")
            elif theirs[0] > own[0]:
                problems.append(f"{path}:{number}: {own[1]} includes {name} of higher layer "
                                f"{theirs[1]}")
    if problems:
        print("\n".join(problems))
        print(f"check-layers: {len(problems)} problem(s) in {files} files", file=sys.stderr)
        return 1
    print(f"check-layers: {files} files, {includes} includes checked, layer order "
          f"{' < '.join(name for name, _ in LAYERS)} respected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
