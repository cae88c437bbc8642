"""The wheel carries everything the tool reads at run time.

Builds the wheel of this checkout into a temporary directory (``pip wheel``, about 10 s) and
checks its contents against the source tree: every file of the package (Python) and of the
top-level folders it reads at run time (``rtl/``: RTL, source list, lint waivers; ``sim/``: C++
harness; ``scenes/``: TOML scenes), each where ``driver.core.resources.data_dir`` finds it in an
installed wheel; the files the RTL build names, the license files and the console script.
Installing the wheel and rendering from outside the checkout is ``.ci/run``'s last step (it
builds a Verilated model, minutes on a cold cache).
"""

from __future__ import annotations

import configparser
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

from driver.backends import build
from driver.core import resources

try:
    import tomllib
except ModuleNotFoundError:                                 # Python 3.10
    from pip._vendor import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> zipfile.ZipFile:
    """The wheel of a clean copy of what the build reads (pyproject.toml, the files it names and
    the package): a stale ``build/`` directory in the checkout cannot leak into it, and the
    checkout is left untouched."""
    src = tmp_path_factory.mktemp("src")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    files = {"pyproject.toml", project["readme"], *project["license-files"], *_tracked("driver"),
             *(f for d in resources.IN_PACKAGE for f in _tracked(d))}
    for rel in files:
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / rel, src / rel)
    out = tmp_path_factory.mktemp("dist")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out),
                        str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = out.glob("rayflex_driver-*.whl")
    with zipfile.ZipFile(whl) as z:
        yield z


def _names(wheel) -> set[str]:
    return set(wheel.namelist())


def _tracked(where: str) -> set[str]:
    """The files under ``where`` that git tracks (and the working tree has), or, outside a git
    checkout, every file there except caches and build products."""
    r = subprocess.run(["git", "-C", str(ROOT), "ls-files", "--", where], capture_output=True,
                       text=True)
    if r.returncode == 0 and r.stdout.strip():
        return {ln for ln in r.stdout.splitlines() if (ROOT / ln).is_file()}
    skip = {"__pycache__", "build", ".venv", ".git", ".pytest_cache"}
    return {p.relative_to(ROOT).as_posix() for p in (ROOT / where).rglob("*")
            if p.is_file() and not skip & set(p.relative_to(ROOT).parts)
            and ".egg-info" not in p.as_posix()}


def _in_package(rel: str) -> str:
    """The wheel's name of a source-tree file: a file of a top-level data folder (``rtl/``,
    ``sim/``, ``scenes/``) inside the package, where ``data_dir`` finds it installed."""
    top, _, rest = rel.partition("/")
    if top in resources.IN_PACKAGE:
        return f"driver/{resources.IN_PACKAGE[top]}/{rest}"
    return rel


def test_wheel_holds_exactly_the_files_of_the_package(wheel):
    tracked = {_in_package(f) for f in
               _tracked("driver") | {f for d in resources.IN_PACKAGE for f in _tracked(d)}}
    assert any(f.endswith(".sv") for f in tracked) and any(f.endswith(".toml") for f in tracked)
    in_wheel = {n for n in _names(wheel) if n.startswith("driver/")}
    assert in_wheel == tracked, (f"missing: {sorted(tracked - in_wheel)}; "
                                 f"not in the source tree: {sorted(in_wheel - tracked)}")


def test_wheel_holds_what_the_rtl_build_reads(wheel):
    names = _names(wheel)
    needed = [build.SOURCE_LIST, build.RTL_DIR / build.LINT_WAIVERS,
              *(build.RTL_DIR / f for f in build.source_names()),
              *(build.SIM_DIR / f for f in build.HARNESS_SOURCES + build.HARNESS_HEADERS)]
    for path in needed:
        rel = _in_package(path.relative_to(ROOT).as_posix())
        assert rel in names, f"{rel} (read by the RTL build) is not in the wheel"
        assert wheel.read(rel) == path.read_bytes()


def test_wheel_holds_the_scenes_and_the_generated_header_code(wheel):
    from driver.scenes import scene
    names = _names(wheel)
    scenes = sorted(scene.SCENES_DIR.glob("*.toml"))
    assert scenes
    for s in scenes:
        assert f"driver/scenes/data/{s.name}" in names
    assert "driver/core/layout.py" in names          # generates the harness's rf_layout.h
    assert not any(n.startswith(("tests/", "tools/", "bench/", "docs/", "images/")) for n in names)


def test_the_design_card_s_top_level_folders():
    """rtl/ (the SystemVerilog), sim/ (the C++ harness and test benches) and scenes/ (the scene
    files) at the repository's top level, and none of their files left inside the package."""
    assert (ROOT / "rtl" / "sources.txt").is_file() and list((ROOT / "rtl").glob("*.sv"))
    assert list((ROOT / "sim").glob("*.cpp")) and list((ROOT / "sim").glob("*.h"))
    assert list((ROOT / "scenes").glob("*.toml"))
    assert {name: resources.data_dir(name) for name in resources.IN_PACKAGE} == \
        {name: ROOT / name for name in resources.IN_PACKAGE}
    left = [f for f in _tracked("driver") if not f.endswith(".py")]
    assert not left, f"data files inside the package's source: {left}"


def test_pyproject_maps_the_folders_and_lists_every_package():
    """pyproject.toml's package list is the source tree's Python packages plus the mapped data
    folders, each mapped from the folder ``resources.IN_PACKAGE`` names."""
    st = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapped = {"driver." + inside.replace("/", "."): top
              for top, inside in resources.IN_PACKAGE.items()}
    assert st["package-dir"] == mapped
    assert {k: v for k, v in st["package-data"].items()} == {k: ["*"] for k in mapped}
    python = {Path(f).parent.as_posix().replace("/", ".") for f in _tracked("driver")
              if f.endswith("/__init__.py")}
    assert sorted(st["packages"]) == sorted(python | set(mapped))


def test_installed_wheel_finds_its_folders_inside_the_package(wheel, tmp_path):
    """Unpacked outside the checkout, the package's ``data_dir`` names its own directories, and
    they hold the checkout's files."""
    site = tmp_path / "site"
    wheel.extractall(site)
    code = ("import json, driver; from driver.core.resources import checkout, data_dir; "
            "print(json.dumps([driver.__file__, str(checkout()), "
            "{n: str(data_dir(n)) for n in ('rtl', 'sim', 'scenes')}]))")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                       env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr[-2000:]
    init, root, dirs = json.loads(r.stdout)
    assert Path(init) == site / "driver" / "__init__.py" and root == "None"
    for name, inside in resources.IN_PACKAGE.items():
        d = Path(dirs[name])
        assert d == site / "driver" / inside
        assert sorted(p.name for p in d.iterdir()) == \
            sorted(Path(f).name for f in _tracked(name))


def test_wheel_metadata_license_and_script(wheel):
    names = _names(wheel)
    info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA"))
    meta = wheel.read(f"{info}/METADATA").decode()
    assert "License-Expression: MIT" in meta
    for f in ("LICENSE", "THIRD_PARTY_NOTICES.md"):
        assert wheel.read(f"{info}/licenses/{f}") == (ROOT / f).read_bytes()
    ep = configparser.ConfigParser()
    ep.read_string(wheel.read(f"{info}/entry_points.txt").decode())
    assert ep["console_scripts"]["rayflex"] == "driver.cli:main"


def test_license_and_citation_files():
    lic = (ROOT / "LICENSE").read_text()
    assert lic.startswith("MIT License") and "RayFlex driver contributors" in lic
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["license"] == "MIT"
    (paper,) = cff["references"]
    assert paper["title"].startswith("RayFlex: An Open-Source RTL Implementation")
    assert [a["family-names"] for a in paper["authors"]] == ["Shen", "Barnes", "Nallathambi",
                                                             "Rogers"]
    assert paper["identifiers"][0]["value"] == "arXiv:2409.06000"


def test_ci_runs_the_readme_commands_and_the_wheel():
    readme = (ROOT / "README.md").read_text().splitlines()
    ci = (ROOT / ".ci" / "run").read_text()
    commands = [readme[i + 1] for i, ln in enumerate(readme) if ln.startswith(("# 1.", "# 2."))]
    assert len(commands) == 2
    for c in commands:
        assert c in ci.splitlines(), f"README command not run verbatim by .ci/run: {c}"
    assert "pip wheel" in ci and "--backend rtl" in ci.split("pip wheel", 1)[1]
