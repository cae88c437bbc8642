"""Shared fixtures. The helpers (testbench, scoreboard, request streams, the paper's cases, the
scalar reference, meshes, the FP-unit model) are the package ``tests/support``, importable as
``support`` because pyproject.toml's pytest settings put tests/ on the path (``pythonpath``)."""

import os

import pytest

# The suite builds the RTL harness without profile-guided optimisation: a PGO build compiles the
# model twice and runs a training workload, which for five configurations would double the suite's
# cold-cache time. The default (PGO) build is what `rayflex` uses; tests/test_pgo.py builds and
# checks it explicitly, and every PGO build checks its own final library against golden.
os.environ.setdefault("RAYFLEX_PGO", "0")


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
