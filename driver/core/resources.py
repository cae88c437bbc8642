"""Where the files the tool reads at run time are: the SystemVerilog (``rtl/``), the C++ harness
and test benches (``sim/``) and the TOML scenes (``scenes/``).

In a checkout they are the repository's top-level folders, and an editable install
(``pip install -e .``) runs the checkout's code, so it reads them there. A wheel carries them
inside the package: pyproject.toml maps each folder to a package directory
(``[tool.setuptools.package-dir]``: ``rtl/`` to ``driver/rtl``, ``sim/`` to ``driver/sim``,
``scenes/`` to ``driver/scenes/data``; tests/test_packaging.py checks the mapping against
``IN_PACKAGE`` and the wheel's contents), so an installed tool needs no checkout. ``data_dir`` is
the one function that finds them; nothing else builds these paths.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent        # the driver package
ROOT = PACKAGE.parent            # the directory holding it: the checkout, or site-packages
# each data folder's name in the checkout -> its directory inside the installed package
IN_PACKAGE = {"rtl": "rtl", "sim": "sim", "scenes": "scenes/data"}


def checkout() -> Path | None:
    """The root of the source checkout this package runs from (an editable install or the source
    tree itself), or None for an installed wheel."""
    return ROOT if (ROOT / "pyproject.toml").is_file() and (ROOT / "rtl").is_dir() else None


def data_dir(name: str) -> Path:
    """The folder ``name`` ("rtl", "sim" or "scenes"): the checkout's top-level folder, or in an
    installed wheel the package directory that holds it (``IN_PACKAGE``)."""
    if name not in IN_PACKAGE:
        raise KeyError(f"no data folder {name!r}; the tool's are {', '.join(IN_PACKAGE)}")
    root = checkout()
    return root / name if root is not None else PACKAGE / IN_PACKAGE[name]
