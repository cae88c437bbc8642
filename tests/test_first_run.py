"""Honest first runs: a first model build reports each step with its time, progress on a
non-terminal stderr is one line per bar or phase (no ``\\r`` repaints), and every bad argument of
``render``, ``bench`` and ``knn`` fails with one line before any work."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from driver.core import progress
from driver.backends import verilate
from driver.cli import main


def test_bar_and_phase_on_a_non_terminal_write_one_line_each(capsys):
    b = progress.bar(1000, "tracing", "ray")
    for done in range(0, 1001, 50):
        b.hook(done, 1000)
    b.close()
    with progress.phase("building the BVH4", delay=0):
        pass
    with progress.phase("quick", delay=5):                  # shorter than its delay: silent
        pass
    with progress.bar(3, "BVH build", "tri", None) as off:  # None: terminal only
        off.update(3)
    assert list(progress.iterate([1, 2], "items", "item")) == [1, 2]
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("tracing: 1,000/1,000 rays in ") and lines[0].endswith(" s")
    assert lines[1].startswith("building the BVH4: done in ")
    assert lines[2].startswith("items: 2/2 items in ")


def test_render_progress_in_a_log_is_one_line_per_phase(capsys):
    from driver.render import render
    render("sphere", 8, 8, backend="golden", progress=True, tile=4)
    err = capsys.readouterr().err
    assert "\r" not in err
    bars = [ln for ln in err.splitlines() if " tiles in " in ln]
    assert len(bars) == 1 and "4/4 tiles" in bars[0]


def _fake_tools(monkeypatch, work: Path):
    """Build tools that only leave the files the next step expects; records the steps run."""
    ran = []

    def fake_run(cmd, cwd, log, what, log_path, env):
        ran.append(what)
        if "training" in what:
            (work / "obj" / "x.gcda").touch()
        if what.startswith("linking"):
            Path(cmd[cmd.index("-o") + 1]).touch()
        if what.startswith("verilating"):
            (work / "obj").mkdir(exist_ok=True)
    monkeypatch.setattr(verilate, "_run", fake_run)
    monkeypatch.setattr(verilate, "_runtime_library", lambda obj, *a: obj / "libverilated.a")
    monkeypatch.setattr(verilate, "is_gcc", lambda cxx: True)
    monkeypatch.setattr(verilate, "find_make", lambda: "make")
    return ran


@pytest.mark.parametrize("pgo", [True, False])
def test_first_build_says_each_step_with_its_time(monkeypatch, tmp_path, capsys, pgo):
    work = tmp_path / "w"
    work.mkdir()
    ran = _fake_tools(monkeypatch, work)
    verilate._build_library_in(work, "top", [], [], {}, [], "x", Path("/usr/bin/true"), "g++",
                               ["PYTHON", "-m", "train"] if pgo else None, {},
                               tmp_path / "log")
    steps = verilate.PGO_STEPS if pgo else verilate.PLAIN_STEPS
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == len(steps)
    for i, (line, name) in enumerate(zip(lines, steps), 1):
        assert line.startswith(f"  [{i}/{len(steps)}] {name}: {steps[name]}: done in ")
    assert ran[0].startswith("verilating") and (("training" in " ".join(ran)) == pgo)


def test_cached_build_announces_and_reports_the_total(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))

    def build(work: Path):
        (work / "lib.so").write_text("x")
    out = verilate.cached_build("entry", "lib.so", build, "Verilator model top", "top")
    assert out.read_text() == "x"
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("building Verilator model top (first time")
    assert err[-1].startswith("built Verilator model top in ") and str(out.parent) in err[-1]
    verilate.cached_build("entry", "lib.so", build, "Verilator model top", "top")
    assert capsys.readouterr().err == ""                     # cached: silent


def _no_work(monkeypatch):
    import driver.bench
    import driver.knn
    import driver.render

    def fail(*a, **k):
        raise AssertionError("work started before the arguments were checked")
    for mod, names in ((driver.render, ("render",)), (driver.knn, ("knn",)),
                       (driver.bench, ("bench", "bench_workload", "bench_workers"))):
        for name in names:
            monkeypatch.setattr(mod, name, fail)


@pytest.mark.parametrize("args, words", [
    (["render", "sphere", "--workload", "ao", "--ao-rays", "0"], "--ao-rays"),
    (["render", "sphere", "--spp", "0"], "--spp"),
    (["render", "sphere", "--bounces", "-1"], "--bounces"),
    (["render", "sphere", "--seed", "-1"], "--seed"),
    (["render", "sphere", "--workers", "0"], "--workers"),
    (["render", "sphere", "--tile", "0"], "--tile"),
    (["render", "sphere", "--json", "s.txt"], ".json"),
    (["bench", "--scene", "no_such_scene"], "unknown scene"),
    (["bench", "--scene", "nosuch.ply", "--workload", "ao"], "no such file"),
    (["bench", "--size", "0"], "1..8192"),
    (["bench", "--rays-in-flight", "0"], "--rays-in-flight"),
    (["bench", "--pipelines", "0"], "--pipelines"),
    (["bench", "--sweep-rays", "1,x"], "--sweep-rays"),
    (["bench", "--workload", "path", "--spp", "0"], "--spp"),
    (["bench", "--tile", "0"], "--tile"),
    (["bench", "--json", "b.txt"], ".json"),
    (["bench", "--sweep-size", "8", "--plot", "p.txt"], ".png"),
    (["knn", "nosuch.npy"], "no such file"),
    (["knn", "data.npy", "--backend", "nope"], "unknown backend"),
    (["knn", "data.npy", "-k", "0"], "-k must be"),
    (["knn", "data.npy", "--queries", "10"], "--queries must be"),
    (["knn", "data.npy", "--out", "n.txt"], "extension"),
])
def test_every_bad_argument_fails_before_any_work(error_line, in_tmp, monkeypatch, args, words):
    np.save(in_tmp / "data.npy", np.random.default_rng(0).random((10, 8), np.float32))
    _no_work(monkeypatch)
    extra = ["--backend", "golden"] if args[0] == "render" else []
    assert main([*args, *extra, "--no-progress"]) == 2
    assert words in error_line()
    assert sorted(p.name for p in in_tmp.iterdir()) == ["data.npy"]


COUNTER = """module counter #(parameter int STEP = 1) (input logic clk_i, output logic [7:0] n_o);
  always_ff @(posedge clk_i) n_o <= n_o + 8'(STEP);
endmodule
"""


def test_plain_builds_share_one_runtime_library(monkeypatch, tmp_path):
    """Two models with the same Verilator settings link one runtime library, compiled once;
    each loads."""
    import ctypes
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("RAYFLEX_PGO", "0")
    sv = tmp_path / "counter.sv"
    sv.write_text(COUNTER)
    libs = [verilate.build_library("counter", [sv], [], params={"STEP": s}) for s in (1, 2)]
    assert libs[0] != libs[1]
    for lib in libs:
        ctypes.CDLL(str(lib))
    runtimes = list((tmp_path / "cache" / "verilator").glob("libverilated-*/libverilated.a"))
    assert len(runtimes) == 1


def test_runtime_settings_name_tracing_and_the_runtime_files():
    """What keys the shared runtime library: a traced model's makefile differs from a plain one's
    in VM_TRACE and its runtime files, and both are read."""
    plain = "VM_TRACE = 0\nVM_TRACE_VCD = 0\nVM_GLOBAL_FAST += \\\n  verilated \\\n\n"
    traced = ("VM_TRACE = 1\nVM_TRACE_VCD = 1\nVM_GLOBAL_FAST += \\\n  verilated \\\n"
              "  verilated_vcd_c \\\n\n")
    found = [verilate.runtime_settings(t) for t in (plain, traced)]
    assert found[0] == [["VM_TRACE", "=", "0"], ["VM_TRACE_VCD", "=", "0"],
                        ["VM_GLOBAL_FAST", "+=", "verilated"]]
    assert found[1][2] == ["VM_GLOBAL_FAST", "+=", "verilated", "verilated_vcd_c"]
