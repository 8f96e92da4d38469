#!/usr/bin/env python3
"""Checks that every fenced code block in README.md and docs/ comes from a file CI builds or runs.

A block must be preceded by a marker line naming its source:
    <!-- snippet: examples/cpp/custom_potential.cpp#potential -->   (between "[snippet: potential]"
                                                                      and "[/snippet]" lines)
    <!-- snippet: examples/damped_pendulum.toml -->                  (the whole file)
and its text must equal that source exactly. Sources must live under examples/ (problem files,
C++ and Python examples and tour.sh are all run by ctest). The README's quick start is marked
<!-- quickstart -->; its test command must be the one .ci/run executes.
Exit status 1 with one line per problem.
"""
import glob
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MARKER = re.compile(r"<!--\s*snippet:\s*([^#\s]+)(?:#(\S+))?\s*-->")


def snippet(path, name):
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        lines = f.read().splitlines()
    if name is None:
        return lines
    start = [i for i, line in enumerate(lines) if f"[snippet: {name}]" in line]
    if len(start) != 1:
        raise KeyError(f"{path}: snippet '{name}' found {len(start)} times")
    out = []
    for line in lines[start[0] + 1:]:
        if "[/snippet]" in line:
            return out
        out.append(line)
    raise KeyError(f"{path}: snippet '{name}' is not closed")


def dedent(lines):
    indent = min((len(l) - len(l.lstrip()) for l in lines if l.strip()), default=0)
    return [l[indent:] for l in lines]


def check(md):
    problems = []
    with open(md, encoding="utf-8") as f:
        lines = f.read().splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].startswith("```"):
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        block = lines[i + 1:j]
        prev = next((lines[k] for k in range(i - 1, -1, -1) if lines[k].strip()), "")
        where = f"{os.path.relpath(md, ROOT)}:{i + 1}"
        m = MARKER.search(prev)
        if "<!-- quickstart -->" in prev:
            with open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8") as f:
                ci = [l for l in f.read().splitlines() if l and not l.startswith(("#", "set ", "cd "))]
            if not ci or ci[-1] not in block:
                problems.append(f"{where}: quick-start test command differs from .ci/run")
        elif not m:
            problems.append(f"{where}: code block without a '<!-- snippet: FILE#NAME -->' marker")
        elif not m.group(1).startswith("examples/"):
            problems.append(f"{where}: snippet source {m.group(1)} is not under examples/")
        else:
            try:
                expected = dedent(snippet(m.group(1), m.group(2)))
                if dedent(block) != expected:
                    problems.append(f"{where}: block differs from {m.group(1)}#{m.group(2)}")
            except (OSError, KeyError) as e:
                problems.append(f"{where}: {e}")
        i = j + 1
    return problems


def main():
    files = [os.path.join(ROOT, "README.md")] + sorted(
        glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True))
    problems = [p for md in files for p in check(md)]
    for p in problems:
        print(p, file=sys.stderr)
    print(f"check-docs: {len(files)} files, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
