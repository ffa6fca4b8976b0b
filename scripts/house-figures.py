#!/usr/bin/env python3
"""The house's figures (issue 28): how the library is laid out.

    scripts/house-figures.py [SRC]      # default: src

Prints, one `name: value` per line (details indented below):
- functions over 150 lines (counted from `fn` to its closing brace, tests included);
- files over 700 lines;
- library functions returning `Result<_, String>` (outside `src/cli/` and test modules);
- cycles in the import graph of the top-level rooms (`crate::room` references), and
  references that run against the layers ARCHITECTURE.md lists (a room using its own layer
  or one below it);
- the largest rooms by lines.

Text heuristics, not a parser: good enough to track the figures from one commit to the next.
"""

import collections
import os
import re
import sys

SRC = sys.argv[1] if len(sys.argv) > 1 else "src"


def rust_files():
    for root, _, names in os.walk(SRC):
        for n in sorted(names):
            if n.endswith(".rs"):
                yield os.path.join(root, n)


FILES = sorted(rust_files())
TEXT = {f: open(f, encoding="utf-8").read() for f in FILES}

# Functions: a `fn` line, to the first line after it that closes a brace at its indent.
FN = re.compile(r'^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(unsafe\s+)?(extern "C"\s+)?fn\s+(\w+)')
long_fns = []
for f in FILES:
    lines = TEXT[f].split("\n")
    for i, line in enumerate(lines):
        m = FN.match(line)
        if not m or line.rstrip().endswith(";"):
            continue
        indent = m.group(1)
        j = i + 1
        while j < len(lines) and not (
            lines[j].startswith(indent + "}") and len(lines[j]) - len(lines[j].lstrip()) == len(indent)
        ):
            j += 1
        if j - i + 1 > 150:
            long_fns.append((j - i + 1, f, m.group(7)))

sizes = sorted(((TEXT[f].count("\n"), f) for f in FILES), reverse=True)
long_files = [(n, f) for n, f in sizes if n > 700]

# `-> Result<..., String>` in library code, before any `#[cfg(test)]`.
STRING_RESULT = re.compile(
    r"\bfn (\w+)[^;{]*?->\s*(Option<)?Result<[^{;]*,\s*String>\s*>?\s*(where[^{]*)?\{", re.S
)
string_fns = []
for f in FILES:
    if f.startswith(os.path.join(SRC, "cli") + os.sep):
        continue
    t = TEXT[f]
    k = t.find("#[cfg(test)]")
    if k >= 0:
        t = t[:k]
    string_fns += [(f, m.group(1)) for m in STRING_RESULT.finditer(t)]

# The rooms: top-level modules (files or folders) other than the entry points and the CLI.
rooms = set()
for n in os.listdir(SRC):
    name = n[:-3] if n.endswith(".rs") else n
    if name not in ("main", "lib", "cli"):
        rooms.add(name)
graph = collections.defaultdict(set)
for f in FILES:
    rel = os.path.relpath(f, SRC).split(os.sep)
    room = rel[0][:-3] if rel[0].endswith(".rs") else rel[0]
    if room not in rooms:
        continue
    for line in TEXT[f].split("\n"):
        if line.strip().startswith("//"):
            continue
        for target in re.findall(r"crate::(\w+)", line):
            if target != room and target in rooms:
                graph[room].add(target)

# Strongly connected components (Tarjan): a component of more than one room is a cycle.
index, low, stack, on, cycles, counter = {}, {}, [], set(), [], [0]


def visit(v):
    index[v] = low[v] = counter[0]
    counter[0] += 1
    stack.append(v)
    on.add(v)
    for w in sorted(graph[v]):
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
            cycles.append(sorted(comp))


for r in sorted(rooms):
    if r not in index:
        visit(r)

# The layers of ARCHITECTURE.md's first code block: one line each, rooms before two spaces.
layers = {}
arch = os.path.join(os.path.dirname(os.path.abspath(SRC)), "ARCHITECTURE.md")
if os.path.exists(arch):
    block = open(arch, encoding="utf-8").read().split("```")[1].strip().split("\n")
    for i, line in enumerate(block):
        for name in re.split(r",\s*", line.split("  ")[0].strip()):
            layers[name] = i
against = sorted(
    (a, b) for a in graph for b in graph[a] if a in layers and b in layers and layers[b] >= layers[a]
)
unlisted = sorted(r for r in rooms if layers and r not in layers)

print(f"rust_files: {len(FILES)}")
print(f"lines: {sum(n for n, _ in sizes)}")
print(f"functions_over_150_lines: {len(long_fns)}")
for n, f, name in sorted(long_fns, reverse=True):
    print(f"  {n} {f} {name}")
print(f"files_over_700_lines: {len(long_files)}")
for n, f in long_files:
    print(f"  {n} {f}")
print(f"library_fns_returning_string_errors: {len(string_fns)}")
for f, name in string_fns:
    print(f"  {f} {name}")
print(f"import_cycles: {len(cycles)}")
for c in cycles:
    print("  " + " <-> ".join(c))
if layers:
    print(f"references_against_the_layers: {len(against)}")
    for a, b in against:
        print(f"  {a} -> {b}")
    print(f"rooms_missing_from_the_layers: {len(unlisted)}")
    for r in unlisted:
        print(f"  {r}")
print("largest_files:")
for n, f in sizes[:8]:
    print(f"  {n} {f}")
