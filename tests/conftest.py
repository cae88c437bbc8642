"""Shared fixtures. The helpers (testbench, scoreboard, request streams, the paper's cases, the
scalar reference, meshes, the FP-unit model) are the package ``tests/support``, importable as
``support`` because pyproject.toml's pytest settings put tests/ on the path (``pythonpath``)."""

import os
from pathlib import Path

import pytest

from driver.core.configs import CONFIGS as CONFIG_NAMES, parse_config
from support.prebuild import SUITE_DEPTH, SUITE_RAYS

# The suite builds the RTL harness without profile-guided optimisation: a PGO build compiles the
# model twice and runs a training workload, which for five configurations would double the suite's
# cold-cache time. The default (PGO) build is what `rayflex` uses; tests/test_pgo.py builds and
# checks it explicitly, and every PGO build checks its own final library against golden.
os.environ.setdefault("RAYFLEX_PGO", "0")

# The parts of the suite a contributor runs on their own (`pytest -m rtl`, `-m "bvh or rtunit"`),
# beside `slow`: each marker is given to whole test modules, from this one table. The markers are
# declared (with what they mean) in pyproject.toml; tests/test_code_shape.py checks that every name
# here is a test module and every marker a declared one.
MODULE_MARKERS = {
    "rtl": ("test_rtl", "test_rtl_extended", "test_rtl_lint", "test_fp_units", "test_fp_div",
            "test_q8_decode_unit", "test_q8_datapath", "test_no_cull", "test_transform",
            "test_pgo", "test_faults", "test_layout", "test_knn", "test_export",
            "test_replay_timing", "test_fused", "test_shared"),
    "golden": ("test_golden", "test_golden_directed", "test_extended_golden", "test_prepare_rays"),
    "bvh": ("test_bvh4", "test_q8_image", "test_geometry_corpus", "test_instances",
            "test_traversal"),
    "rtunit": ("test_rtunit", "test_gpu", "test_gpu_pin", "test_memory", "test_rayorder",
               "test_replay_timing", "test_rtunit_rtl", "test_rtunit_modules",
               "test_rtunit_pipelines"),
    "scenes": ("test_scene", "test_lumibench_scenes", "test_camera_options"),
    "frame": ("test_render", "test_workloads", "test_tiles", "test_default_tiling",
              "test_double_sided", "test_lumibench_shaders", "test_check", "test_adjudicate"),
    "timing": ("test_area", "test_power", "test_power_ops"),
    "docs": ("test_docs", "test_statistics_doc", "test_readme_questions", "test_api",
             "test_layers", "test_code_shape"),
    "cli": ("test_cli", "test_first_run", "test_camera_options", "test_bench", "test_sweep",
            "test_suite", "test_design"),
}


# The Verilator builds each test module needs (tests/support/prebuild.py names them: a
# configuration name for the "rtl" harness, "pgo:", "pyverilator:", "signals:", "rtunit:" and
# "tb:" for the others): the suite builds those of the collected tests before the first test, on every
# core, the harnesses without profile guidance (RAYFLEX_PGO=0 above). A build missing here is
# made by the first test that needs it; one listed but not needed costs its time.
PREBUILD = Path(__file__).parent / "support" / "prebuild.py"
_B = "baseline-unified"
_UNIT = f"rtunit:{_B}:{SUITE_RAYS}:{SUITE_DEPTH}"      # the RT unit the suite's unit tests share
RTL_BUILDS = {
    "test_rtl": (_B, _B + "@10", _B + "@14", "pyverilator:" + _B),
    "test_rtl_extended": tuple(CONFIG_NAMES),
    "test_no_cull": tuple(CONFIG_NAMES),
    "test_q8_datapath": (_B, _B + "-q8", "extended-disjoint-q8", f"pyverilator:{_B}-q8"),
    "test_transform": (_B, _B + "-xf", "extended-disjoint-q8-xf", f"pyverilator:{_B}-xf"),
    "test_knn": ("extended-unified",),
    "test_instances": (_B, _B + "-q8", _B + "-xf"),
    "test_q8_image": (_B, _B + "-q8"),
    "test_sweep": (_B, "baseline-disjoint", "signals:" + _B, "signals:baseline-disjoint",
                   _UNIT),
    "test_fused": (_B + "-fused", "extended-disjoint-fused"),
    "test_shared": ("extended-disjoint-q8-shared",),
    "test_pgo": ("pgo:" + _B,),
    "test_power": ("signals:" + _B, f"signals:{_B}-q8"),
    "test_power_ops": (f"signals:{_B}-q8",),
    "test_gpu": (_B, "signals:" + _B),
    "test_bench": (_B, "pyverilator:" + _B, _UNIT),
    "test_rtunit_rtl": (_B, _B + "-q8", _B + "-q8-xf", _UNIT,
                        f"rtunit:{_B}-q8-xf:{SUITE_RAYS}:4",
                        f"rtunit:{_B}-q8-xf:{SUITE_RAYS}:4:1:cull"),
    "test_rtunit_modules": ("tb:rtu_units",),
    "test_rtunit_pipelines": (_B, _UNIT, _UNIT + ":2"),
    "test_unit_energy": (_B, f"rtunit:{_B}:4:8", f"activity:{_B}:4:8", f"signals-all:{_B}"),
    "test_unit_gates": (f"rtunit:{_B}:4:8",),
    "test_readme_questions": (_B, _B + "-xf", _UNIT, "signals:" + _B,
                              "signals:baseline-disjoint"),
    **{m: (_B,) for m in ("test_rtunit", "test_gpu_pin", "test_memory",
                          "test_rayorder", "test_replay_timing", "test_traversal",
                          "test_workloads", "test_cli", "test_export",
                          "test_double_sided", "test_tiles", "test_api")},
    "test_statistics_doc": (_B, f"activity:{_B}:4:8", f"signals-all:{_B}"),
    "test_suite": (_B, _UNIT),
}


# Builds only a module's `slow` tests use (the configurations between the two that bound the
# others, e.g. the q8 decode on baseline-disjoint): made before the first test when a slow test
# of the module is collected (`pytest -m slow`), never for the default suite.
SLOW_BUILDS = {
    "test_q8_datapath": ("baseline-disjoint-q8", "extended-unified-q8"),
    "test_fused": ("extended-unified-fused",),
    "test_shared": ("extended-unified-shared",),
}


def builds_for(item) -> tuple[str, ...]:
    """The Verilator builds the collected test ``item`` needs (``RTL_BUILDS``, ``SLOW_BUILDS``)."""
    module = Path(str(item.fspath)).stem
    slow = SLOW_BUILDS.get(module, ()) if item.get_closest_marker("slow") else ()
    return (*RTL_BUILDS.get(module, ()), *slow)


def pytest_collection_finish(session):
    """Build the harness configurations the collected tests need (``builds_for``), as many at
    once as there are cores, each in its own process, with a line per build on the terminal."""
    if session.config.option.collectonly or not session.items:
        return
    names = sorted({n for item in session.items for n in builds_for(item)},
                   key=lambda n: (":" not in n, n))    # the longer, non-harness builds first
    if names:
        _prebuild(names, session.config.pluginmanager.get_plugin("terminalreporter"))


def _prebuild(names: list[str], term) -> None:
    import signal
    import subprocess
    import sys
    import time
    say = term.write_line if term is not None else (lambda line: None)
    jobs = max(1, min(len(names), os.cpu_count() or 1))
    say(f"RTL builds for these tests: {len(names)} configuration(s), {jobs} at a time")
    waiting, running, done, t0 = list(names), {}, 0, time.monotonic()
    shown = t0
    try:
        while waiting or running:
            while waiting and len(running) < jobs:
                name = waiting.pop(0)
                running[name] = (time.monotonic(), subprocess.Popen(
                    [sys.executable, str(PREBUILD), name],
                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                    start_new_session=True))
            for name, (start, proc) in list(running.items()):
                if proc.poll() is None:
                    continue
                del running[name]
                done += 1
                err = proc.stderr.read().strip().splitlines()
                what = ("built or found" if proc.returncode == 0 else
                        f"FAILED ({err[-1] if err else proc.returncode}; its tests will say why)")
                say(f"  [{done}/{len(names)}] {name}: {what} in "
                    f"{time.monotonic() - start:.0f} s")
            if running and time.monotonic() - shown >= 30:      # a line every 30 s meanwhile
                shown = time.monotonic()
                say(f"  building {', '.join(running)} ({shown - t0:.0f} s so far)")
            time.sleep(0.2)
    finally:
        for _, proc in running.values():              # Ctrl-C: stop the builds still running
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait()
    say(f"RTL builds ready in {time.monotonic() - t0:.0f} s")


def pytest_collection_modifyitems(config, items):
    by_module = {}
    for marker, modules in MODULE_MARKERS.items():
        for module in modules:
            by_module.setdefault(module, []).append(marker)
    for item in items:
        for marker in by_module.get(Path(str(item.fspath)).stem, ()):
            item.add_marker(marker)


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """Run the test in its own empty directory (the CLI writes its outputs to the working
    directory); returns that directory."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture
def error_line(capsys):
    """``error_line()`` reads what the CLI wrote to stderr, asserts it is exactly one
    ``rayflex: error: ...`` line without a traceback, and returns it."""
    def read() -> str:
        err = capsys.readouterr().err.strip()
        assert err.startswith("rayflex: error: ") and "\n" not in err and "Traceback" not in err
        return err
    return read
