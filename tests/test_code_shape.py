"""The code's shape, kept: no function in driver/ longer than 80 lines (90 for a numba kernel,
whose loops cannot call helpers as cheaply) or with more than 12 parameters; the suite's marker
table names real test modules and declared markers; no test asserts a constant."""

import ast
from pathlib import Path

import conftest

ROOT = Path(__file__).resolve().parent.parent
MAX_LINES, MAX_LINES_NUMBA, MAX_PARAMS = 80, 90, 12
# numba kernels take their arrays one by one (a kernel is compiled for its arguments' types)
NUMBA_PARAMS_EXEMPT = True
# functions being split elsewhere; each entry must still exist
PENDING = {"driver/scenes/objfile.py::_scan"}


def _numba(f: ast.FunctionDef) -> bool:
    return any(k in ast.unparse(d) for d in f.decorator_list for k in ("njit", "jit", "numba"))


def _params(f: ast.FunctionDef) -> int:
    a = f.args
    names = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    n = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    return n - (bool(names) and names[0].arg in ("self", "cls"))


def _functions():
    for path in sorted((ROOT / "driver").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.walk(ast.parse(path.read_text(), rel)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield f"{rel}::{node.name}", node


def test_no_function_is_too_long_or_takes_too_many_parameters():
    over, seen = [], set()
    for name, f in _functions():
        seen.add(name)
        if name in PENDING:
            continue
        lines, numba = f.end_lineno - f.lineno + 1, _numba(f)
        if lines > (MAX_LINES_NUMBA if numba else MAX_LINES):
            over.append(f"{name}:{f.lineno}: {lines} lines")
        if _params(f) > MAX_PARAMS and not (numba and NUMBA_PARAMS_EXEMPT):
            over.append(f"{name}:{f.lineno}: {_params(f)} parameters")
    assert not over, "split these (or pass a dataclass):\n" + "\n".join(over)
    assert PENDING <= seen


def test_the_limits_catch_a_long_function_and_a_wide_one():
    long_f = ast.parse("def f():\n" + "    x = 1\n" * MAX_LINES).body[0]
    wide = ast.parse(f"def g(self, {', '.join(f'a{i}' for i in range(MAX_PARAMS + 1))}): pass")
    assert long_f.end_lineno - long_f.lineno + 1 > MAX_LINES
    assert _params(wide.body[0]) == MAX_PARAMS + 1


def test_marker_table_names_test_modules_and_declared_markers(pytestconfig):
    declared = {m.split(":")[0] for m in pytestconfig.getini("markers")}
    modules = {p.stem for p in (ROOT / "tests").glob("test_*.py")}
    assert set(conftest.MODULE_MARKERS) <= declared
    for table in (conftest.MODULE_MARKERS, conftest.RTL_BUILDS):
        named = {m for ms in table.values() for m in ms} if table is conftest.MODULE_MARKERS \
            else set(table)
        assert named <= modules, sorted(named - modules)
    for builds in conftest.RTL_BUILDS.values():
        for name in builds:
            assert conftest.rtl_build_params(name)["LATENCY"] >= 11


def _constant_asserts(path: Path) -> list[str]:
    """``assert X`` where X is a literal, a name the module imports, or a comparison of
    literals: an assert that cannot fail."""
    tree = ast.parse(path.read_text())
    imported = {a.asname or a.name.split(".")[0] for n in tree.body
                if isinstance(n, (ast.Import, ast.ImportFrom)) for a in n.names}
    out = []
    for n in ast.walk(tree):
        if not isinstance(n, ast.Assert):
            continue
        x = n.test
        if (isinstance(x, ast.Constant) or (isinstance(x, ast.Name) and x.id in imported)
                or (isinstance(x, ast.Compare) and all(isinstance(c, ast.Constant)
                                                       for c in (x.left, *x.comparators)))):
            out.append(f"{path.name}:{n.lineno}: {ast.unparse(n)}")
    return out


def test_no_assert_of_a_constant(tmp_path):
    bad = tmp_path / "t.py"
    bad.write_text("from x import NO_CHILD\nassert NO_CHILD\nassert 1 == 1\nassert y\n")
    assert len(_constant_asserts(bad)) == 2
    found = [line for p in sorted((ROOT / "tests").rglob("*.py")) for line in _constant_asserts(p)]
    assert not found, found
