#!/usr/bin/env python3
"""The house's figures (issues 28 and 45): how the library is laid out, and the gate.

    scripts/house-figures.py [--check] [SRC]      # default: src

Prints, one `name: value` per line (each place indented below its figure):
- functions over the line limit (counted from `fn` to its closing brace, tests included);
- files over the line limit;
- library functions returning `Result<_, String>` (outside `src/cli/` and test modules);
- cycles in the import graph: between the rooms (top-level modules, `crate::room`
  references), and between the sibling modules of one room (`super::sibling`,
  `crate::room::sibling`, `self::child` paths);
- references that run against the floors docs/design.md §9 lists (a room using a room on
  its own floor or above), and rooms that list does not name;
- the largest files.

With `--check` it exits 1 when a figure passes its limit in `scripts/house-limits.toml`,
naming each place (`make lint` runs it so). Text heuristics, not a parser: good enough to
hold the figures from one commit to the next.
"""

import collections
import os
import re
import sys
import tomllib

ARGS = [a for a in sys.argv[1:] if not a.startswith("--")]
CHECK = "--check" in sys.argv[1:]
SRC = ARGS[0] if ARGS else "src"
ROOT = os.path.dirname(os.path.abspath(SRC))
HERE = os.path.dirname(os.path.abspath(__file__))
LIMITS = tomllib.load(open(os.path.join(HERE, "house-limits.toml"), "rb"))


def rust_files():
    for root, _, names in os.walk(SRC):
        for n in sorted(names):
            if n.endswith(".rs"):
                yield os.path.join(root, n)


FILES = sorted(rust_files())
TEXT = {f: open(f, encoding="utf-8").read() for f in FILES}


def code_lines(f):
    """The file's lines with `//` comments blanked (doc comments name paths too)."""
    return [("" if line.strip().startswith("//") else line) for line in TEXT[f].split("\n")]


# Functions: a `fn` line, to the first line after it that closes a brace at its indent.
FN = re.compile(r'^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(unsafe\s+)?(extern "C"\s+)?fn\s+(\w+)')
fn_limit = LIMITS["max_function_lines"]
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
        if j - i + 1 > fn_limit:
            long_fns.append((j - i + 1, f, i + 1, m.group(7)))

sizes = sorted(((TEXT[f].count("\n"), f) for f in FILES), reverse=True)
long_files = [(n, f) for n, f in sizes if n > LIMITS["max_file_lines"]]

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
    for m in STRING_RESULT.finditer(t):
        string_fns.append((f, t.count("\n", 0, m.start()) + 1, m.group(1)))


def module_of(f):
    """`src/simulate/run.rs` -> ("simulate", "run"); `src/simulate/mod.rs` -> ("simulate",)."""
    rel = os.path.relpath(f, SRC)[:-3].split(os.sep)
    if rel[-1] == "mod":
        rel = rel[:-1]
    return tuple(rel)


MODULES = {module_of(f): f for f in FILES}


def strongly_connected(graph, nodes):
    """Tarjan's strongly connected components of more than one node: the cycles."""
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

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return cycles


# The rooms: top-level modules (files or folders) other than the entry points and the CLI.
rooms = set()
for n in os.listdir(SRC):
    name = n[:-3] if n.endswith(".rs") else n
    if name not in ("main", "lib", "cli"):
        rooms.add(name)
room_graph = collections.defaultdict(set)
# Where each room-to-room reference first appears, for the messages.
room_where = {}
for f in FILES:
    room = module_of(f)[0]
    if room not in rooms:
        continue
    for i, line in enumerate(code_lines(f)):
        for target in re.findall(r"crate::(\w+)", line):
            if target != room and target in rooms:
                room_graph[room].add(target)
                room_where.setdefault((room, target), f"{f}:{i + 1}")
room_cycles = strongly_connected(room_graph, rooms)


def paths_in(line):
    """The module paths a line names, with `a::{b::c, d}` groups expanded (one level)."""
    out = []
    for m in re.finditer(r"\b((?:crate|super|self)(?:::\w+)*)::\{([^{}]*)\}", line):
        for part in m.group(2).split(","):
            part = part.strip()
            if part and part != "self":
                out.append(m.group(1) + "::" + part)
            elif part == "self":
                out.append(m.group(1))
    out += re.findall(r"\b((?:crate|super|self)(?:::\w+)+)", line)
    return out


def resolve(module, path):
    """The module `path` (as written in `module`) names, or None: the longest prefix of the
    path that is a module of this crate."""
    parts = path.split("::")
    if parts[0] == "crate":
        base, rest = (), parts[1:]
    else:
        base = list(module)
        rest = parts
        # `super` in `a/b.rs` (module a::b) is `a`; in `a/mod.rs` (module a) it is the root.
        while rest and rest[0] == "super":
            base = base[:-1]
            rest = rest[1:]
        if rest and rest[0] == "self":
            rest = rest[1:]
        base = tuple(base)
    best = None
    cur = base
    for p in rest:
        cur = cur + (p,)
        if cur in MODULES:
            best = cur
        else:
            break
    return best


# Sibling modules within a room: an edge a -> b where a's file names a path into b (or
# below it) and a, b share a parent module. Edges to the parent are the re-exports a
# `mod.rs` gathers, not a dependency, so they are not counted.
module_graph = collections.defaultdict(set)
module_where = {}
for f in FILES:
    me = module_of(f)
    if me[0] not in rooms or len(me) < 2:
        continue
    for i, line in enumerate(code_lines(f)):
        for p in paths_in(line):
            target = resolve(me, p)
            if target is None or len(target) < len(me):
                continue
            # The sibling of `me` that the target lies in.
            sib = target[: len(me)]
            if sib[:-1] == me[:-1] and sib != me:
                module_graph[me].add(sib)
                module_where.setdefault((me, sib), f"{f}:{i + 1}")
module_cycles = strongly_connected(module_graph, [m for m in MODULES if m and m[0] in rooms])


def edges_of(cycle, graph, where, name):
    members = set(cycle)
    return [
        f"{name(a)} -> {name(b)} ({where[(a, b)]})"
        for a in sorted(cycle)
        for b in sorted(graph[a])
        if b in members
    ]


# The floors of docs/design.md §9: the first code block after its heading, one floor a
# line, the rooms before two spaces.
layers = {}
design = os.path.join(ROOT, "docs", "design.md")
if os.path.exists(design):
    text = open(design, encoding="utf-8").read()
    k = text.find("\n## 9. Rooms")
    if k >= 0:
        block = text[k:].split("```")[1].strip().split("\n")
        for i, line in enumerate(block):
            for name in re.split(r",\s*", line.split("  ")[0].strip()):
                layers[name] = i
against = sorted(
    (a, b)
    for a in room_graph
    for b in room_graph[a]
    if a in layers and b in layers and layers[b] >= layers[a]
)
unlisted = sorted(r for r in rooms if r not in layers)

dotted = "::".join
print(f"rust_files: {len(FILES)}")
print(f"lines: {sum(n for n, _ in sizes)}")
print(f"functions_over_{fn_limit}_lines: {len(long_fns)}")
for n, f, line, name in sorted(long_fns, reverse=True):
    print(f"  {f}:{line} {name}: {n} lines")
print(f"files_over_{LIMITS['max_file_lines']}_lines: {len(long_files)}")
for n, f in long_files:
    print(f"  {f}: {n} lines")
print(f"library_fns_returning_string_errors: {len(string_fns)}")
for f, line, name in string_fns:
    print(f"  {f}:{line} {name}")
print(f"import_cycles: {len(room_cycles) + len(module_cycles)}")
for c in room_cycles:
    print("  rooms " + " <-> ".join(c))
    for e in edges_of(c, room_graph, room_where, str):
        print("    " + e)
for c in module_cycles:
    print("  modules " + " <-> ".join(dotted(m) for m in c))
    for e in edges_of(c, module_graph, module_where, dotted):
        print("    " + e)
print(f"references_against_the_floors: {len(against)}")
for a, b in against:
    print(f"  {a} -> {b} ({room_where[(a, b)]})")
print(f"rooms_missing_from_the_floors: {len(unlisted)}")
for r in unlisted:
    print(f"  {r}")
print("largest_files:")
for n, f in sizes[:8]:
    print(f"  {n} {f}")

if CHECK:
    failures = []
    checks = [
        ("max_function_lines", len(long_fns), f"function(s) over {fn_limit} lines"),
        ("max_file_lines", len(long_files), f"file(s) over {LIMITS['max_file_lines']} lines"),
        ("max_string_errors", len(string_fns), "library function(s) returning Result<_, String>"),
        ("max_import_cycles", len(room_cycles) + len(module_cycles), "import cycle(s)"),
        (
            "max_references_against_the_floors",
            len(against),
            "reference(s) against the floors of docs/design.md §9",
        ),
        (
            "max_rooms_missing_from_the_floors",
            len(unlisted),
            "room(s) missing from docs/design.md §9",
        ),
    ]
    if not layers:
        failures.append("docs/design.md has no '## 9. Rooms' section with the floors")
    for key, value, what in checks:
        # Line limits bound each item; the others bound a count.
        limit = 0 if key in ("max_function_lines", "max_file_lines") else LIMITS[key]
        if value > limit:
            failures.append(f"{value} {what} (limit {limit}, scripts/house-limits.toml `{key}`)")
    if failures:
        print("\nhouse gate: FAILED", file=sys.stderr)
        for msg in failures:
            print(f"  {msg}", file=sys.stderr)
        print("  (the places are listed above; raise a limit only in a commit that says why)", file=sys.stderr)
        sys.exit(1)
    print("house gate: passed")
