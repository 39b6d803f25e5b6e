#!/usr/bin/env python3
"""Module-level import graph of a Rust crate's sources and its cycles (non-test code only).

Usage: scripts/import_cycles.py [SRC_DIR]   (default: sitl/src)
       STRICT=1 scripts/import_cycles.py      (every file its own node, a folder's mod.rs too)

Nodes: one per file-level module; a folder's `mod.rs` and the files beside it in that same folder are
one node (the folder), since a parent and its children are one unit of code. A file `x.rs` whose
children live in `x/` stays its own node, and so does each child. The roots `lib.rs` and `main.rs`
are nodes of their own (`main.rs` is the binary: its `crate::` is the binary's, `sitl::` is the
library's).

Edges: every path in code that names a module of the crate: `use crate::a::b`, `use super::x`,
`use self::x`, inline `crate::a::f()`, `super::super::T`, and in the binary `sitl::a`. Comments,
string literals and test code (a `#[cfg(test)]` module and everything after it in its file, files
named `tests.rs`, and modules declared under `#[cfg(test)]`) are left out. `mod x;` declarations are
not imports. Prints the edges between nodes and every cycle (strongly connected components of more
than one node); exits 1 when there is one.
"""

import os
import re
import sys

SRC = sys.argv[1] if len(sys.argv) > 1 else "sitl/src"


def strip(text):
    """Code without comments and string literals (kept as empty strings)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i)
            i = n if j < 0 else j + 2
        elif c == "r" and re.match(r'r#*"', text[i:]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            close = '"' + m.group(1)
            j = text.find(close, i + len(m.group(0)))
            out.append('""')
            i = n if j < 0 else j + len(close)
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""')
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:]):
            m = re.match(r"'(\\.|[^\\'])'", text[i:])
            out.append("' '")
            i += len(m.group(0))
        else:
            out.append(c)
            i += 1
    return "".join(out)


def non_test(code):
    """The code before the first `#[cfg(test)]` that opens a module (tests come last in this project)."""
    m = re.search(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s*)?mod\s+\w+\s*\{", code)
    return code[: m.start()] if m else code


# Module path (tuple) of every file, per crate root.
files = {}
for dirpath, _, names in os.walk(SRC):
    for name in names:
        if name.endswith(".rs"):
            files[os.path.relpath(os.path.join(dirpath, name), SRC)] = None


def module_of(rel):
    parts = rel[:-3].split("/")
    if parts[-1] == "mod":
        parts = parts[:-1]
    if parts in (["lib"], ["main"]):
        return ()
    return tuple(parts)


def crate_of(rel):
    """'bin' for main.rs and the modules it declares (cli/), else 'lib'."""
    return "bin" if rel == "main.rs" or rel.startswith("cli/") else "lib"


def node_of(rel):
    d, name = os.path.split(rel)
    if rel in ("lib.rs", "main.rs"):
        return rel
    if os.environ.get("STRICT") is None and os.path.exists(os.path.join(SRC, d, "mod.rs")) and d:
        return d + "/"
    return rel


# Test-only files: named tests.rs, or declared under #[cfg(test)].
test_only = set()
for rel in files:
    if os.path.basename(rel) == "tests.rs":
        test_only.add(rel)
for rel in files:
    code = strip(open(os.path.join(SRC, rel)).read())
    for m in re.finditer(r"#\[cfg\(test\)\]\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;", code):
        base = os.path.dirname(rel) if rel.endswith("mod.rs") or rel in ("lib.rs", "main.rs") else rel[:-3]
        for cand in (os.path.join(base, m.group(1) + ".rs"), os.path.join(base, m.group(1), "mod.rs")):
            if cand in files:
                test_only.add(cand)

modules = {}  # (crate, module path) -> file
for rel in files:
    modules[(crate_of(rel), module_of(rel))] = rel


def resolve(crate, path):
    """The file of the longest prefix of `path` that is a module of `crate`."""
    for k in range(len(path), -1, -1):
        f = modules.get((crate, tuple(path[:k])))
        if f:
            return f
    return None


def expand(tree):
    """`a::{b, c::{d, e}}` -> [[a, b], [a, c, d], [a, c, e]] (self, *, `as` handled)."""
    tree = re.sub(r"\s+", "", tree)

    def split_top(s):
        parts, depth, cur = [], 0, ""
        for ch in s:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            if ch == "," and depth == 0:
                parts.append(cur)
                cur = ""
            else:
                cur += ch
        if cur:
            parts.append(cur)
        return parts

    def go(s):
        i = s.find("{")
        if i < 0:
            s = s.split("as")[0] if re.search(r"\bas\b", s) else s
            return [[p for p in s.split("::") if p and p not in ("*", "self")]]
        prefix = [p for p in s[:i].split("::") if p]
        inner = s[i + 1 : s.rfind("}")]
        out = []
        for part in split_top(inner):
            for tail in go(part):
                out.append(prefix + tail)
        return out or [prefix]

    return go(tree)


edges = {}  # (from node, to node) -> example
for rel in sorted(files):
    if rel in test_only:
        continue
    crate = crate_of(rel)
    here = list(module_of(rel))
    code = non_test(strip(open(os.path.join(SRC, rel)).read()))
    paths = []
    for m in re.finditer(r"\buse\s+([^;]+);", code):
        paths.extend(expand(m.group(1)))
    for m in re.finditer(r"(?<![\w:])((?:crate|super|self|sitl)(?:::\w+)+)", code):
        paths.append(m.group(1).split("::"))
    for m in re.finditer(r"(?<![\w:])(\w+(?:::\w+)+)", code):
        paths.append(m.group(1).split("::"))
    for p in paths:
        if not p:
            continue
        target_crate, base = crate, None
        if p[0] == "crate":
            base, rest = [], p[1:]
        elif p[0] == "sitl" and crate == "bin":
            target_crate, base, rest = "lib", [], p[1:]
        elif p[0] in ("super", "self"):
            base = list(here)
            # A file's own module is `here`; super of a module file x.rs or x/mod.rs is its parent.
            rest = list(p)
            while rest and rest[0] in ("super", "self"):
                if rest[0] == "super":
                    base = base[:-1]
                rest = rest[1:]
        elif (crate, tuple(here + [p[0]])) in modules:
            base, rest = list(here), list(p)  # a path relative to this module: a child's name first
        else:
            continue
        target = resolve(target_crate, base + rest)
        if target is None or target in test_only:
            continue
        a, b = node_of(rel), node_of(target)
        if a != b:
            edges.setdefault((a, b), f"{rel}: {'::'.join(p)}")

nodes = sorted({n for e in edges for n in e})
graph = {n: sorted({b for (a, b) in edges if a == n}) for n in nodes}

# Tarjan's strongly connected components.
index, low, stack, on, sccs = {}, {}, [], set(), []
counter = [0]


def visit(v):
    index[v] = low[v] = counter[0]
    counter[0] += 1
    stack.append(v)
    on.add(v)
    for w in graph[v]:
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
        sccs.append(comp)


sys.setrecursionlimit(10000)
for v in nodes:
    if v not in index:
        visit(v)

print(f"{len(nodes)} nodes, {len(edges)} edges (non-test code of {SRC})")
for (a, b), why in sorted(edges.items()):
    print(f"  {a} -> {b}    ({why})")
cycles = [sorted(c) for c in sccs if len(c) > 1]
if cycles:
    for c in cycles:
        print("CYCLE:", " <-> ".join(c))
        for (a, b), why in sorted(edges.items()):
            if a in c and b in c:
                print(f"    {a} -> {b}    ({why})")
    sys.exit(1)
print("no cycles")
