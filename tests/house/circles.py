#!/usr/bin/env python3
"""No circle among a folder's C files (docs/core-internals.md, "Files").

A file and the header of its own name are one unit (stream.c and stream.h);
a header without a .c of its name (grid.h, context.h, the *_template.h
kernels) is a unit of its own.  Unit A depends on unit B when a file of A
includes a header of B ("name.h", found in the folder) or calls, inside a
function body, a function that B's .c file defines (not static).  The dependencies must form no
circle: in a circle two files each need the other, so neither can be read,
tested or replaced alone.  The core keeps its types in headers of their own
and each file's functions for the others in the header of its name, so that
a file's includes say which files it calls.

The reading is textual (comments and strings dropped; a definition is a
non-static function whose body's brace opens a line, as clang-format lays
them out): a circle it reports names the files and the functions that tie
them, to be checked in the code.

usage: circles.py FOLDER [FOLDER ...]    exit 1 if any folder has a circle
"""
import os
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
STRING = re.compile(r'"(?:\\.|[^"\\\n])*"' + r"|'(?:\\.|[^'\\\n])*'")
DEFINITION = re.compile(r"^(?!static\b|typedef\b|struct\b|enum\b|union\b|#)[A-Za-z_][\w \t\*]*?\b"
                        r"([A-Za-z_]\w*)\s*\(([^;{}]*?)\)\s*\n\{", re.M | re.S)
CALL = re.compile(r"\b([A-Za-z_]\w*)\s*\(")


def strip(text):
    return STRING.sub('""', COMMENT.sub(" ", text))


def calls(text):
    """The names called inside braces (function bodies, not prototypes)."""
    out, depth, at = [], 0, 0
    for m in re.finditer(r"[{}]", text):
        if depth > 0:
            out += CALL.findall(text, at, m.start())
        depth += 1 if m.group() == "{" else -1
        depth = max(depth, 0)
        at = m.end()
    return out


def graph(folder):
    files = sorted(f for f in os.listdir(folder) if f.endswith((".c", ".h", ".inc")))
    stems = {os.path.splitext(f)[0] for f in files if f.endswith(".c")}
    unit = {f: (os.path.splitext(f)[0] if os.path.splitext(f)[0] in stems else f) for f in files}
    raw, code = {}, {}
    for f in files:
        with open(os.path.join(folder, f), encoding="utf-8", errors="replace") as fh:
            raw[f] = fh.read()
        code[f] = strip(raw[f])
    defined = {}  # function -> unit of the .c that defines it
    for f in files:
        if f.endswith(".c"):
            for m in DEFINITION.finditer(code[f]):
                defined.setdefault(m.group(1), unit[f])
    deps = {u: {} for u in unit.values()}
    for f in files:
        a = unit[f]
        for inc in INCLUDE.findall(raw[f]):
            b = unit.get(os.path.basename(inc))
            if b and b != a:
                deps[a].setdefault(b, set()).add("#include " + os.path.basename(inc))
        for name in calls(code[f]):
            b = defined.get(name)
            if b and b != a:
                deps[a].setdefault(b, set()).add(name + "()")
    return deps


def circles(deps):
    """Tarjan's strongly connected components of more than one unit."""
    index, low, on, stack, out = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(deps[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(deps):
        if v not in index:
            visit(v)
    return out


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    bad = 0
    for folder in sys.argv[1:]:
        deps = graph(folder)
        found = circles(deps)
        for comp in found:
            bad += 1
            print(f"{folder}: a circle of {len(comp)} units: {', '.join(comp)}")
            for a in comp:
                for b in sorted(deps[a]):
                    if b in comp:
                        print(f"  {a} -> {b}: {', '.join(sorted(deps[a][b])[:6])}")
        print(f"{folder}: {len(deps)} units, {sum(len(d) for d in deps.values())} dependencies, "
              f"{len(found)} circles")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
