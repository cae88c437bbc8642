"""Shared fixtures. The helpers (testbench, scoreboard, request streams, the paper's cases, the
scalar reference, meshes, the FP-unit model) are the package ``tests/support``, importable as
``support`` because pyproject.toml's pytest settings put tests/ on the path (``pythonpath``)."""

import os
from pathlib import Path

import pytest

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
    "rtl": ("test_rtl", "test_rtl_extended", "test_rtl_lint", "test_fp_units", "test_q8_decode_unit",
            "test_q8_datapath", "test_no_cull", "test_transform", "test_pgo", "test_faults",
            "test_layout", "test_knn", "test_export", "test_replay_timing"),
    "golden": ("test_golden", "test_golden_directed", "test_extended_golden", "test_prepare_rays"),
    "bvh": ("test_bvh4", "test_q8_image", "test_geometry_corpus", "test_instances",
            "test_traversal"),
    "rtunit": ("test_rtunit", "test_gpu", "test_gpu_pin", "test_memory", "test_rayorder",
               "test_replay_timing"),
    "timing": ("test_area", "test_power", "test_power_ops"),
    "docs": ("test_docs", "test_statistics_doc", "test_readme_questions", "test_api",
             "test_layers", "test_code_shape"),
    "cli": ("test_cli", "test_first_run", "test_camera_options", "test_bench", "test_sweep",
            "test_suite", "test_design"),
}


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
