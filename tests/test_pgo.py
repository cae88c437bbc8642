"""Profile-guided build of the "rtl" harness: the training workload checks what it runs, a failed
training fails the build, and RAYFLEX_PGO switches it off."""

import sys
from pathlib import Path

import numpy as np
import pytest

from driver import pgo
from driver.backends import build, harness
from driver.backends import BackendError
from driver.rtunit import ReplayMismatch
from driver.backends.verilate import BuildError, build_library
from support.fpu import FPU_HARNESS, FPU_TB_SOURCES

BASELINE = {"EXTENDED": 0, "DISJOINT": 0, "LATENCY": 11}


def test_training_workload_runs_every_path():
    counts = pgo.train(BASELINE)
    assert counts["traversal"] > 50_000          # both scenes' requests, wavefront and replay
    assert counts["run"] == pgo.RUN_SLICE
    assert counts["knn"] == 0                    # no vector opcodes on a baseline build


@pytest.mark.parametrize("method, error, what", [
    ("run_nodes", ReplayMismatch, "differ from the functional run"),   # the replay's own check
    ("run", pgo.TrainingMismatch, "run"),
])
def test_training_catches_a_wrong_library(monkeypatch, method, error, what):
    """A library that returns one wrong response bit must not become a cached build."""
    real = getattr(harness.HarnessBackend, method)

    def corrupt(self, *args):
        out = real(self, *args)
        if method == "run":
            out["tag"][len(out) // 2] ^= 1
        else:
            out[len(out) // 2, 1] ^= 1
        return out

    monkeypatch.setattr(harness.HarnessBackend, method, corrupt)
    with pytest.raises(error, match=what):
        pgo.train(BASELINE)


def test_failed_training_is_a_build_error(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))
    with pytest.raises(BuildError, match="profile-guided optimisation training") as e:
        build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS,
                      train=[sys.executable, "-c", "import sys; sys.exit(3)"])
    assert "\n" not in str(e.value)
    cached = [p for p in tmp_path.glob("verilator/fpu_tb_top-*/*.so")
              if p.parent.suffix != ".failed"]
    assert not cached


@pytest.mark.slow                      # an instrumented build of its own (~50 s)
def test_training_that_runs_nothing_is_a_build_error(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))
    with pytest.raises(BuildError, match="wrote no profile"):
        build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS,
                      train=[sys.executable, "-c", "pass"])


@pytest.mark.parametrize("value, enabled", [(None, True), ("1", True), ("0", False),
                                            ("off", False), ("yes", True)])
def test_rayflex_pgo_switch(monkeypatch, value, enabled):
    if value is None:
        monkeypatch.delenv("RAYFLEX_PGO", raising=False)
    else:
        monkeypatch.setenv("RAYFLEX_PGO", value)
    assert build.pgo_enabled() is enabled


def test_rayflex_pgo_bad_value(monkeypatch):
    monkeypatch.setenv("RAYFLEX_PGO", "maybe")
    with pytest.raises(BackendError, match="RAYFLEX_PGO"):
        build.pgo_enabled()


def test_profile_guided_library_is_bit_exact(monkeypatch):
    """The default (profile-guided) "rtl" build, the one `rayflex` uses (the rest of the suite
    builds without PGO), against golden on requests of a scene the training did not see (the
    soup of random triangles), the directed cases and random corner-case requests."""
    from driver.scenes.camera import frame, primary_rays
    from driver.backends.golden import GoldenBackend
    from driver.scenes.scene import builtin
    from driver.tracer import trace
    from support.cases import all_requests
    from support.streams import mixed_stream
    monkeypatch.setenv("RAYFLEX_PGO", "1")
    monkeypatch.setattr(harness, "_LIBS", {})              # load the PGO build in this test only
    mesh = builtin("soup")
    o, d = primary_rays(frame(mesh.vertices), 24, 24)
    req = np.concatenate([trace(mesh, o, d, backend="golden", record=True).record.requests(),
                          all_requests(), mixed_stream(3, 12_000, 8_000)])
    be = harness.HarnessBackend()
    log = (Path(be._lib._name).parent / "build.log").read_text()
    assert log.count("-m driver.pgo") == 2                # trained, then the final build checked
    assert log.count("PGO workload") == 2 and log.count("results = golden") == 2
    assert be.run(req).tobytes() == GoldenBackend().run(req).tobytes()


def test_compiler_other_than_gcc_builds_without_profile(tmp_path, monkeypatch):
    """clang keeps its profiles in another format: the build then runs no training (this
    command would fail) and gives a working library."""
    from driver.backends import verilate
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))
    monkeypatch.setattr(verilate, "is_gcc", lambda cxx: False)
    lib = build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS,
                        train=[sys.executable, "-c", "import sys; sys.exit(3)"])
    assert lib.is_file() and "-fprofile" not in (lib.parent / "build.log").read_text()


def test_is_gcc():
    import shutil
    from driver.backends.verilate import is_gcc
    assert is_gcc("/nonexistent/c++") is False
    found = [(cxx, gcc) for cxx, gcc in (("g++", True), ("clang++", False)) if shutil.which(cxx)]
    assert found, "neither g++ nor clang++ on PATH (the RTL backends need one)"
    for cxx, gcc in found:
        assert is_gcc(cxx) is gcc, cxx
