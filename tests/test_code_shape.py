"""The code's shape, kept: no function in driver/ longer than 80 lines (90 for a numba kernel,
whose loops cannot call helpers as cheaply) or with more than 12 parameters (a kernel takes
related arrays as one tuple); the suite's marker
table names real test modules and declared markers; no test asserts a constant."""

import ast
import re
from pathlib import Path

import conftest
from support import prebuild

ROOT = Path(__file__).resolve().parent.parent
MAX_LINES, MAX_LINES_NUMBA, MAX_PARAMS = 80, 90, 12


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
    over = []
    for name, f in _functions():
        lines, numba = f.end_lineno - f.lineno + 1, _numba(f)
        if lines > (MAX_LINES_NUMBA if numba else MAX_LINES):
            over.append(f"{name}:{f.lineno}: {lines} lines")
        if _params(f) > MAX_PARAMS:
            over.append(f"{name}:{f.lineno}: {_params(f)} parameters")
    assert not over, "split these (or pass a dataclass):\n" + "\n".join(over)


def test_the_limits_catch_a_long_function_and_a_wide_one():
    long_f = ast.parse("def f():\n" + "    x = 1\n" * MAX_LINES).body[0]
    wide = ast.parse(f"def g(self, {', '.join(f'a{i}' for i in range(MAX_PARAMS + 1))}): pass")
    assert long_f.end_lineno - long_f.lineno + 1 > MAX_LINES
    assert _params(wide.body[0]) == MAX_PARAMS + 1


def test_marker_table_names_test_modules_and_declared_markers(pytestconfig):
    declared = {m.split(":")[0] for m in pytestconfig.getini("markers")}
    modules = {p.stem for p in (ROOT / "tests").glob("test_*.py")}
    assert set(conftest.MODULE_MARKERS) <= declared
    for table in (conftest.MODULE_MARKERS, conftest.RTL_BUILDS, conftest.SLOW_BUILDS):
        named = {m for ms in table.values() for m in ms} if table is conftest.MODULE_MARKERS \
            else set(table)
        assert named <= modules, sorted(named - modules)
    for builds in (*conftest.RTL_BUILDS.values(), *conftest.SLOW_BUILDS.values()):
        for spec in builds:                  # every spec names a kind and a configuration
            kind, config, extra = prebuild.split(spec)
            if kind == "tb":                 # a testbench (split checked its name)
                continue
            assert prebuild.harness_params(config)["LATENCY"] >= 10
            assert all(int(n) > 0 for n in extra[:3])      # rays, depth, pipelines
            assert extra[3:] in ([], ["cull"])              # the culling stack


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


# Path-like words in the tree that name no file on purpose: the installed package's folders
# (driver.core.resources), name patterns and the made-up paths of tests.
NOT_FILES = {"driver/rtl", "driver/sim", "driver/scenes/data", "scenes/data", "scenes/NAME.toml",
             "scenes/soup.toml", "rtl/pyverilator", "driver/x.py", "driver/x", "images/5.png",
             "images/compressed_path64_F.json"}
# dotted names that are no module on purpose: the wheel's data packages (pyproject.toml) and the
# API test's unknown name
NOT_MODULES = {"driver.rtl", "driver.sim", "driver.scenes.data", "driver.no_such_name"}
_PATH = re.compile(r"(?<![\w./~-])((?:driver|tools|tests|docs|rtl|sim|scenes|bench|images|\.ci)"
                   r"/[\w./-]*\w)")
_MODULE = re.compile(r"(?<![\w./-])(driver(?:\.\w+)+)")
_TEXT = {".py", ".md", ".sv", ".cpp", ".h", ".txt", ".toml", ".cff", ".vlt"}


def _is_module(dotted: str) -> bool:
    """``dotted`` is a module of the package, or a name its longest module prefix defines."""
    import importlib
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:k])
        if base.with_suffix(".py").is_file() or (base / "__init__.py").is_file():
            return k == len(parts) or hasattr(importlib.import_module(".".join(parts[:k])),
                                              parts[k])
    return False


def _stale_references(path: Path, rel: str) -> list[str]:
    out = []
    for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        for m in _PATH.finditer(line):
            ref = m.group(1).rstrip(".")
            if (ref.endswith("_") or ref in NOT_FILES or any(c in ref for c in "*{<")
                    or (ROOT / ref).exists()):
                continue
            out.append(f"{rel}:{n}: {ref}")
        out += [f"{rel}:{n}: {m.group(1)}" for m in _MODULE.finditer(line)
                if m.group(1) not in NOT_MODULES and not _is_module(m.group(1))]
    return out


def test_every_file_and_module_the_tree_names_exists():
    """A path (``driver/core/layout.py``, ``tools/figures.py``) or module (``driver.rtunit.gpu``)
    named in a comment, docstring, doc or source list is one of the repository's."""
    stale = []
    for folder in ("driver", "rtl", "sim", "tests", "docs", "tools", "bench", "scenes"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix in _TEXT and path.is_file() and "data" not in path.parts[-2:-1]:
                stale += _stale_references(path, path.relative_to(ROOT).as_posix())
    for name in ("README.md", "pyproject.toml", "CITATION.cff", "THIRD_PARTY_NOTICES.md"):
        stale += _stale_references(ROOT / name, name)
    assert not stale, "references to files or modules that do not exist:\n" + "\n".join(stale)


def test_stale_reference_check_catches_one(tmp_path):
    f = tmp_path / "x.py"
    f.write_text("# the layout (driver" + "/layout.py, driver" + ".layout), tools/figures.py\n")
    assert len(_stale_references(f, "x.py")) == 2
