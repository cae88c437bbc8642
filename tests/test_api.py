"""The Python API (docs/api.md): its example runs and prints what the page says, its reference is
the docstrings, every name ``driver`` exports has one, and ``import driver`` stays light."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "api.md"
HEAVY = ("trimesh", "numba", "scipy", "embreex", "dask", "distributed", "matplotlib", "sklearn",
         "pyverilator")


def _tool():
    spec = importlib.util.spec_from_file_location("api_doc", ROOT / "tools" / "api_doc.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _example() -> tuple[str, str]:
    """(the example's code, the output the page says it prints)."""
    text = PAGE.read_text().split("## An example", 1)[1]
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    shown = re.search(r"```text\n(.*?)```", text, re.S).group(1)
    return code, shown


def test_the_example_prints_what_the_page_says(tmp_path):
    code, shown = _example()
    script = tmp_path / "example.py"
    script.write_text(code)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=900, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout == shown


def test_the_reference_is_the_docstrings():
    tool = _tool()
    assert tool.split(PAGE.read_text())[1] == tool.reference(), \
        "docs/api.md's reference differs from the docstrings: run python tools/api_doc.py"


def test_every_exported_name_is_documented():
    import driver
    assert sorted(driver.__all__) == sorted(set(driver.__all__))
    names = re.findall(r"^### `driver\.(\w+)`$", PAGE.read_text(), re.M)
    assert [n for n in names if n in driver.__all__] == list(driver.__all__)
    for name in driver.__all__:
        obj = getattr(driver, name)
        if callable(obj) and not hasattr(obj, "names"):
            assert (obj.__doc__ or "").strip(), f"driver.{name} has no docstring"
    assert set(driver.__all__) <= set(dir(driver))
    with pytest.raises(AttributeError):
        driver.no_such_name                                  # noqa: B018


def test_import_driver_loads_no_heavy_package_until_a_scene_is_loaded():
    probe = ("import sys, driver\n"
             f"heavy = {HEAVY!r}\n"
             "print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)))\n"
             "driver.load_scene('sphere')\n"
             "print('trimesh' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         timeout=300, check=True).stdout.split("\n")
    assert out[:2] == ["[]", "True"]


def test_the_index_links_the_api_page():
    assert "(api.md)" in (ROOT / "docs" / "index.md").read_text()
