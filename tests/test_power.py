"""driver.power (issue 15): toggle counting, steady-state energy per operation, the liberty
reader, the gate-level netlist writer, the report and the CLI.

The default suite builds the traced RTL of the baseline configuration (one ~30 s Verilator
build, cached) and measures small streams at level ``signals``; synthesis and the gate-level
model (minutes) run only under ``-m slow``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from driver import FLAG_NO_CULL, backend
from driver.cli import main
from driver.power import activity, gatesim, liberty, measure, netlist, report, stimulus
from driver.core.wire import pack_requests

BASE = {"EXTENDED": 0, "DISJOINT": 0, "LATENCY": 11}


@pytest.fixture(scope="module")
def signals():
    return activity.SignalModel(BASE)


# ------------------------------------------------------------------------------------------------
# toggle counting

VCD = """$timescale 1ps $end
$scope module TOP $end
 $var wire 1 ! clk_i $end
 $var wire 4 " req_i [3:0] $end
 $scope module rayflex $end
  $var wire 4 " req_i [3:0] $end
  $var wire 4 # data [3:0] $end
  $var wire 1 $ flag $end
 $upscope $end
$upscope $end
$enddefinitions $end
#0
$dumpvars
0!
b0000 "
b0000 #
x$
$end
#1
1!
b1010 "
b11 #
1$
#2
0!
b0101 "
b1111 #
0$
#3
b1 #
"""


def test_vcd_counter_on_a_hand_made_vcd(signals, tmp_path):
    """Bit toggles per identifier after its first value; x counts as 0; short vectors are
    zero-extended on the left."""
    vcd, cnt = tmp_path / "a.vcd", tmp_path / "a.cnt"
    vcd.write_text(VCD)
    assert signals.lib.pw_vcd_count(str(vcd).encode(), str(cnt).encode()) == 4
    got = dict((c, int(n)) for c, n in (ln.rsplit(" ", 1) for ln in cnt.read_text().splitlines()))
    # clk 0->1->0: 2; req 0000->1010->0101: 2 + 4; data 0000->0011->1111->0001: 2 + 2 + 3;
    # flag x->1->0: 1 + 1
    assert got == {"!": 2, '"': 6, "#": 7, "$": 2}


def test_vcd_header_aliases_and_testbench_inputs(signals, tmp_path):
    """One net per identifier (aliases share it); nets that are testbench inputs weigh 0."""
    vcd = tmp_path / "h.vcd"
    vcd.write_text(VCD)
    m = activity.SignalModel.__new__(activity.SignalModel)
    m._header(vcd)
    assert m.codes == {"!": 0, '"': 1, "#": 2, "$": 3}
    assert m.names[1] == ["TOP.req_i", "TOP.rayflex.req_i"]
    assert list(m.weight) == [0, 0, 1, 1]


# ------------------------------------------------------------------------------------------------
# steady state

def test_streams_are_valid_requests():
    """Every operation's stream runs on the golden model; box streams hit about half the boxes."""
    for op in stimulus.measurable({"EXTENDED": 1}):
        req = stimulus.requests(op, 64, seed=3)
        rsp = backend("golden", extended=True).run(req)
        assert len(rsp) == 64 and (req["opcode"] == stimulus.OPS[op][0]).all()
    hits = backend("golden").run(stimulus.requests("box", 400))["box_hit"].mean()
    assert 0.2 < hits < 0.8
    tri, nc = stimulus.requests("triangle", 400), stimulus.requests("triangle_no_cull", 400)
    assert (nc["flags"] == FLAG_NO_CULL).all() and np.array_equal(tri["tri"], nc["tri"])
    hit = backend("golden").run(tri)["tri_hit"].astype(bool)
    hit_nc = backend("golden").run(nc)["tri_hit"].astype(bool)
    assert (hit <= hit_nc).all() and hit_nc.sum() > hit.sum()     # the back faces hit too


def test_energy_is_proportional_to_work(signals):
    """2x the operations in the steady-state window -> 2x the toggles (within 5 %)."""
    words = pack_requests(stimulus.requests("triangle", 300, seed=1))
    c1, t1 = signals.run(words[:100])
    c2, t2 = signals.run(words[:200])
    c3, t3 = signals.run(words[:300])
    assert (c2 - c1, c3 - c1) == (100, 200)
    one = (t2 - t1) @ signals.weight
    two = (t3 - t1) @ signals.weight
    assert one > 1000
    assert two / one == pytest.approx(2, rel=0.05)


def test_idle_pipeline_does_not_toggle(signals):
    """Registers load only on a handshake: a drained pipeline with its inputs held is silent."""
    words = pack_requests(stimulus.requests("box", 20))
    cycles, t = signals.run(words, idle=50, only_idle=True)
    assert cycles == 50
    assert t @ signals.weight == 0


def test_measure_is_deterministic_and_complete(signals):
    a = measure(signals, BASE, n=20, seed=5)
    b = measure(signals, BASE, n=20, seed=5)
    assert a == b
    assert set(a) == {"box", "box_q8_host", "triangle", "triangle_no_cull", "idle_per_cycle"}
    for op in ("box", "box_q8_host", "triangle", "triangle_no_cull"):
        r = a[op]
        assert r["energy_per_op"] > 0 and r["cycles_per_op"] == 1.0
        assert sum(r["stages"].values()) == pytest.approx(1, abs=1e-3)
        assert r["stages"]["S1"] > 0 and r["stages"]["registers"] > 0
    assert a["idle_per_cycle"]["energy"] == 0
    c = measure(signals, BASE, n=20, seed=6)
    assert c["box"]["energy_per_op"] != a["box"]["energy_per_op"]


# ------------------------------------------------------------------------------------------------
# report

def _fake(e):
    return {op: {"energy_per_op": v} for op, v in e.items()} | {"idle_per_cycle": {"energy": 0}}


def test_ratios_and_per_ray():
    cfgs = {"baseline-unified": _fake({"box": 10, "triangle": 8}),
            "baseline-disjoint": _fake({"box": 10.2, "triangle": 8}),
            "extended-unified": _fake({"box": 12, "triangle": 9, "euclidean": 20, "cosine": 20}),
            "extended-disjoint": _fake({"box": 12, "triangle": 9, "euclidean": 18,
                                        "cosine": 21})}
    r = report.ratios(cfgs)
    assert r["extended_vs_baseline"]["unified"] == {"box": 0.2, "triangle": 0.125}
    assert r["disjoint_vs_unified"]["baseline"]["box"] == pytest.approx(0.02)
    assert r["disjoint_vs_unified"]["extended"]["euclidean"] == pytest.approx(-0.1)
    assert r["triangle_vs_box"]["baseline-unified"] == 0.8
    mix = report.mix_of({"rays": 10, "box_ops": 50, "tri_ops": 8,
                         "by_type": {"primary": {"rays": 4, "box_ops": 20, "tri_ops": 4},
                                     "shadow": {"rays": 6, "box_ops": 30, "tri_ops": 4}}})
    pr = report.per_ray(mix, cfgs)
    assert set(pr) == {"primary", "shadow"}
    assert pr["primary"]["configs"]["baseline-unified"]["energy_per_ray"] == (200 + 32) / 4
    assert pr["shadow"]["configs"]["extended-unified"]["energy_per_frame"] == 30 * 12 + 4 * 9
    assert report.mix_of({"rays": 3, "box_ops": 7, "tri_ops": 1}) == \
        {"primary": {"box_ops": 7, "tri_ops": 1, "rays": 3}}


def test_cli_signals_end_to_end(tmp_path, capsys):
    """One configuration at level signals with a workload: JSON, table and plot."""
    out, png = tmp_path / "p.json", tmp_path / "p.png"
    assert main(["power", "--config", "baseline-unified", "--ops", "20", "--scene", "sphere",
                 "--size", "8", "--json", str(out), "--plot", str(png)]) == 0
    rep = json.loads(out.read_text())
    assert rep["level"] == "signals" and rep["unit"] == "bit toggles"
    cfg = rep["configs"]["baseline-unified"]
    assert cfg["box"]["energy_per_op"] > 0 and cfg["box"]["toggles_per_op"] > 0
    assert cfg["triangle_no_cull"]["energy_per_op"] > 0 and cfg["idle_per_cycle"]["energy"] == 0
    assert rep["paper"]["extended_vs_baseline"] == {"box": 0.18, "triangle": 0.20}
    pr = rep["per_ray"]["primary"]
    assert pr["rays"] == 64 and pr["configs"]["baseline-unified"]["energy_per_ray"] > 0
    assert rep["provenance"]["design_point"]["config"] == ["baseline-unified"]
    assert png.stat().st_size > 1000
    assert "| baseline-unified |" in capsys.readouterr().out


def test_energy_per_ray_of_every_ray_type(tmp_path):
    """A path workload: energy per ray for the primary, shadow and every bounce ray type, in each
    configuration measured, from the frame's own op mix."""
    out = tmp_path / "p.json"
    cfgs = ("baseline-unified", "baseline-unified-q8")      # models other tests build too
    assert main(["power", "--config", ",".join(cfgs), "--ops", "10",
                 "--scene", "cornell", "--workload", "path", "--bounces", "2", "--size", "8",
                 "--json", str(out), "--no-progress"]) == 0
    rep = json.loads(out.read_text())
    pr = rep["per_ray"]
    assert set(pr) == {"primary", "shadow", "bounce1", "bounce2"}
    for kind, row in pr.items():
        assert set(row["configs"]) == set(cfgs)
        for cfg, e in row["configs"].items():
            box = rep["configs"][cfg]["box"]["energy_per_op"]
            tri = rep["configs"][cfg]["triangle"]["energy_per_op"]
            assert e["energy_per_ray"] == pytest.approx(
                row["box_ops_per_ray"] * box + row["tri_ops_per_ray"] * tri)


@pytest.mark.parametrize("argv, words", [
    (["--config", "nope"], "unknown value"),
    (["--ops", "0"], "--ops"),
    (["--workload", "bunny:x"], "--workload"),
    (["--scene", "no_such_scene"], "unknown scene"),
    (["--size", "0"], "--size"),
    (["--rays-in-flight", "8"], "--backend rtunit measures the whole unit"),
    (["--level", "gates", "--latency", "12"], "--latency"),
    (["--json", "/nonexistent-dir/p.json"], "directory"),
    (["--stimulus-seed", "-1"], "--stimulus-seed"),
    # an operation or a latency a configuration cannot run (-q8, -xf configurations)
    (["--op", "box_q8"], "--op box_q8: configuration baseline-unified cannot run it"),
    (["--op", "transform", "--config", "baseline-unified-q8"], "a -xf configuration"),
    (["--op", "euclidean", "--config", "baseline-unified-xf"], "extended"),
    (["--op", "nope"], "unknown operation"),
    (["--op", ","], "at least one"),
    (["--config", "baseline-unified-xq"], "unknown value"),
    (["--config", "baseline-unified-q8", "--latency", "10"], "at least 11"),
    (["--config", "baseline-unified-q8", "--level", "gates", "--latency", "13"],
     "baseline-unified-q8 has 12 stages"),
])
def test_cli_bad_input_fails_before_any_measurement(argv, words, capsys, monkeypatch):
    import driver.power as power
    monkeypatch.setattr(power, "run_level", lambda *a, **k: pytest.fail("measured"))
    monkeypatch.setattr(report, "frame_mix", lambda *a, **k: pytest.fail("traced"))
    assert main(["power", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error:") and words in err[0], err


def test_liberty_level_without_the_file_exits_2(tmp_path, capsys):
    assert main(["power", "--level", "liberty", "--liberty", str(tmp_path / "none.lib")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rayflex: error: --level liberty")
    bad = tmp_path / "bad.lib"
    bad.write_text("library (x) { cell (A) {")
    assert main(["power", "--level", "liberty", "--liberty", str(bad)]) == 2   # before synthesis
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "end of file" in err[0]


def test_power_says_what_it_will_build(monkeypatch, capsys):
    import driver.power as power
    monkeypatch.setattr(power.run, "uncached_models", lambda models: [f"signals {m[1]}"
                                                                      for m in models[:1]])
    monkeypatch.setattr(power, "run_level", lambda *a, **k: (_ for _ in ()).throw(
        KeyboardInterrupt()))
    monkeypatch.setattr(report, "frame_mix", lambda *a, **k: {})
    assert main(["power", "--config", "all"]) == 130
    err = capsys.readouterr().err
    assert "power: 1 of 4 models to build first" in err


def test_a_model_build_reports_before_the_progress_bar_is_drawn(monkeypatch):
    """power's bar and a first build's lines once shared one stderr line: the bar was drawn,
    then the model built under it. The model is made first now."""
    import driver.power as power
    from driver.power import run as power_run
    events = []

    class Model:
        def __init__(self, params):
            events.append("model")

    class Bar:
        def __init__(self, per_cfg):
            events.append("bar")

        def step(self, cfg, op):
            pass

        def close(self):
            events.append("closed")
    monkeypatch.setattr(activity, "SignalModel", Model)
    monkeypatch.setattr(power_run, "_Bar", Bar)
    monkeypatch.setattr(power_run, "measure", lambda *a, **k: {})
    power_run.run_level("signals", ["baseline-unified", "baseline-disjoint"], progress=True)
    assert events == ["model", "bar", "closed"] * 2


# ------------------------------------------------------------------------------------------------
# liberty reader

LIB = r"""
/* a tiny library */
library (tiny) {
  voltage_unit : "1V";
  capacitive_load_unit (1,pf);
  leakage_power_unit : "1nW";
  nom_voltage : 2.0;
  power_lut_template (e2x2) {
    variable_1 : total_output_net_capacitance;
    variable_2 : input_transition_time;
    index_1 ("0.0, 1.0");
    index_2 ("0.0, 2.0");
  }
  power_lut_template (e_slew_first) {
    variable_1 : input_transition_time;
    variable_2 : total_output_net_capacitance;
    index_1 ("0.0, 2.0");
    index_2 ("0.0, 1.0");
  }
  lu_table_template (t2x2) {
    variable_1 : total_output_net_capacitance;
    variable_2 : input_net_transition;
    index_1 ("0.0, 1.0");
    index_2 ("0.0, 2.0");
  }
  cell (AND2) {
    area : 4;
    cell_leakage_power : 3.0;
    pin (A) { direction : input; capacitance : 0.01; }
    pin (B) { direction : input; capacitance : 0.03; }
    pin (Y) {
      direction : output;
      function : "(A B)";
      timing () {
        related_pin : "A";
        rise_transition (t2x2) { values ("0.1, 0.1", "0.1, 0.1"); }
        fall_transition (t2x2) { values ("0.1, 0.1", "0.1, 0.1"); }
      }
      internal_power () {
        related_pin : "A";
        rise_power (e2x2) { values ( \
          "1.0, 2.0", \
          "3.0, 4.0"); }
        fall_power (e_slew_first) { values ("1.0, 3.0", "2.0, 4.0"); }
      }
    }
  }
  cell (NAND2) {
    area : 2;
    cell_leakage_power : 1.0;
    pin (A) { direction : input; capacitance : 0.02; }
    pin (B) { direction : input; capacitance : 0.02; }
    pin (Y) { direction : output; function : "!(A&B)";
      internal_power () { rise_power (e2x2) { values ("0, 0", "0, 0"); }
                          fall_power (e2x2) { values ("0, 0", "0, 0"); } } }
  }
  cell (INV) {
    area : 1;
    cell_leakage_power : 0.5;
    pin (A) { direction : input; capacitance : 0.02; }
    pin (Y) { direction : output; function : "A'";
      internal_power () { rise_power (e2x2) { values ("0.5, 0.5", "0.5, 0.5"); }
                          fall_power (e2x2) { values ("0.5, 0.5", "0.5, 0.5"); } } }
  }
  cell (XOR2) {
    area : 6;
    cell_leakage_power : 1.5;
    pin (A) { direction : input; capacitance : 0.01; }
    pin (B) { direction : input; capacitance : 0.01; }
    pin (Y) { direction : output; function : "(A^B)";
      internal_power () { rise_power (e2x2) { values ("0.3, 0.3", "0.3, 0.3"); }
                          fall_power (e2x2) { values ("0.3, 0.3", "0.3, 0.3"); } } }
  }
  cell (MUX2) {
    area : 5;
    cell_leakage_power : 2.0;
    pin (A) { direction : input; capacitance : 0.01; }
    pin (B) { direction : input; capacitance : 0.01; }
    pin (S) { direction : input; capacitance : 0.01; }
    pin (Y) { direction : output; function : "(S B) + (!S A)";
      internal_power () { rise_power (e2x2) { values ("0.25, 0.25", "0.25, 0.25"); }
                          fall_power (e2x2) { values ("0.25, 0.25", "0.25, 0.25"); } } }
  }
  cell (DFF) {
    area : 8;
    cell_leakage_power : 10.0;
    ff (IQ, IQN) { next_state : "D"; clocked_on : "CLK"; }
    pin (CLK) { direction : input; capacitance : 0.02; clock : true;
      internal_power () { rise_power (p1) { index_1 ("0.0, 1.0"); values ("0.2, 0.4"); }
                          fall_power (p1) { index_1 ("0.0, 1.0"); values ("0.2, 0.4"); } } }
    pin (D) { direction : input; capacitance : 0.01; }
    pin (Q) { direction : output; function : "IQ";
      internal_power () { rise_power (e2x2) { values ("1, 1", "1, 1"); }
                          fall_power (e2x2) { values ("1, 1", "1, 1"); } } }
  }
}
"""


@pytest.fixture
def tiny(tmp_path):
    p = tmp_path / "tiny.lib"
    p.write_text(LIB)
    return liberty.load(p)


def test_liberty_tables_and_interpolation(tiny):
    assert (tiny.name, tiny.voltage, tiny.cap_unit_pf, tiny.energy_unit_pj) == \
        ("tiny", 2.0, 1.0, 1.0)
    and2 = tiny.cells["AND2"]
    assert and2.inputs == {"A": 0.01, "B": 0.03} and and2.leakage == 3.0
    rise, fall = and2.energy[0]
    # bilinear: at (load 0.5, slew 1.0) the mean of the four corners
    assert float(rise(0.5, 1.0)) == pytest.approx(2.5)
    assert float(rise(1.0, 2.0)) == 4.0 and float(rise(0.0, 0.0)) == 1.0
    # linear extrapolation beyond the table (load 2.0 -> 5.0 at slew 0)
    assert float(rise(2.0, 0.0)) == pytest.approx(5.0)
    # a template with the slew first is transposed: the same table as rise
    assert float(fall(0.5, 1.0)) == pytest.approx(2.5) and float(fall(1.0, 0.0)) == 3.0
    clk = tiny.cells["DFF"].clock_energy[0][0]
    assert float(clk(0, 0.5)) == pytest.approx(0.3)


def test_liberty_mapping_and_net_energies(tiny):
    names = lambda g: [c.name for c in liberty.map_gate(tiny, g)]  # noqa: E731
    assert names("$_AND_") == ["AND2"] and names("$_NAND_") == ["NAND2"]
    assert names("$_NOT_") == ["INV"] and names("$_DFF_P_") == ["DFF"]
    assert names("$_MUX_") == ["MUX2"] and names("$_DFFE_PP_") == ["DFF", "MUX2"]
    with pytest.raises(ValueError, match="no cell implements"):
        liberty.map_gate(tiny, "$_NOR_")
    # nets: 0 driven by AND (drives 2 AND pins and 1 INV pin), 1 by INV (drives nothing)
    types = ["$_AND_", "$_NOT_"]
    driver = np.array([0, 1, -1])
    sinks = np.array([[2, 1], [0, 0], [0, 0]])
    in0 = np.array([2, 0, -1])
    info = liberty.net_energies(tiny, types, driver, sinks, in0)
    load0 = 2 * 0.02 + 1 * 0.02                     # mean AND2 pin 0.02 pF, INV 0.02 pF
    # AND2 at load 0.06 pF; its input (net 2) has no driver: the library's smallest slew, 0
    # rise = fall = 1 + (3 - 1) * load (bilinear at slew 0); plus 0.5 C V^2
    r = 1.0 + (3.0 - 1.0) * load0
    assert info["energy_per_toggle"][0] == pytest.approx(r + 0.5 * load0 * 4.0, rel=1e-6)
    assert info["energy_per_toggle"][1] == pytest.approx(0.5)        # INV, no load
    assert info["energy_per_toggle"][2] == 0
    assert info["leakage_mW"] == pytest.approx((3.0 + 0.5) * 1e-6)
    assert info["leakage_per_cycle_pj"] == pytest.approx(3.5e-9 * 1e-9 * 1e12)
    assert info["clock_per_cycle_pj"] == 0


def test_liberty_errors(tmp_path):
    p = tmp_path / "bad.lib"
    p.write_text("cell (X) { }")
    with pytest.raises(ValueError, match="no library"):
        liberty.load(p)
    p.write_text("library (x) { cell (A) {")
    with pytest.raises(ValueError, match="end of file"):
        liberty.load(p)
    with pytest.raises(OSError):
        liberty.load(tmp_path / "missing.lib")
    assert liberty.find(str(tmp_path / "missing.lib"))[0] is None


# ------------------------------------------------------------------------------------------------
# gate-level netlist

def _cell(t, **conn):
    return {"type": t, "connections": {k: [v] for k, v in conn.items()},
            "attributes": {"src": "x.sv:1"}}


def _design():
    """A one-stage pipeline with the datapath's ports, as Yosys JSON: out_valid <= in_valid;
    rsp[0] <= req[0] & req[1] and rsp[1] <= req[2] ^ req[3] on a handshake; rsp[2] = ~rsp[0]."""
    req = list(range(5, 5 + 32 * activity.REQ_WORDS))
    ready = req[-1] + 1
    return {"modules": {"rayflex": {
        "ports": {"clk_i": {"direction": "input", "bits": [2]},
                  "rst_ni": {"direction": "input", "bits": [3]},
                  "in_valid_i": {"direction": "input", "bits": [4]},
                  "in_ready_o": {"direction": "output", "bits": ["1"]},
                  "req_i": {"direction": "input", "bits": req},
                  "out_valid_o": {"direction": "output", "bits": [9000]},
                  "out_ready_i": {"direction": "input", "bits": [ready]},
                  "rsp_o": {"direction": "output", "bits": [9002, 9004, 9005, "0"]}},
        "netnames": {"g_reg[0].u_reg.main_q": {"hide_name": 0, "bits": [9002, 9004]},
                     "g_reg[0].u_reg.main_valid_q": {"hide_name": 0, "bits": [9000]}},
        "cells": {"v": _cell("$_DFF_PN0_", C=2, D=4, R=3, Q=9000),
                  "and": _cell("$_AND_", A=5, B=6, Y=9001),
                  "ff0": _cell("$_DFFE_PP_", C=2, D=9001, E=4, Q=9002),
                  "xor": _cell("$_XOR_", A=7, B=8, Y=9003),
                  "ff1": _cell("$_DFFE_PP_", C=2, D=9003, E=4, Q=9004),
                  "not": _cell("$_NOT_", A=9002, Y=9005)}}}}


@pytest.fixture
def tiny_net(tmp_path):
    info = netlist._write(_design(), tmp_path)
    return netlist._load(tmp_path, "k", {**info, "synth_s": 0}, cached=True), info


def test_netlist_arrays(tiny_net):
    net, info = tiny_net
    lab = netlist.STAGE_LABELS
    assert info["cells"] == {"$_AND_": 1, "$_DFFE_PP_": 2, "$_DFF_PN0_": 1, "$_NOT_": 1,
                             "$_XOR_": 1}
    assert info["levels"] == 1 and net.levels == 1
    assert list(net.fanout[[5, 9001, 9002, 9005]]) == [1, 1, 2, 1]   # rsp_o ports count
    assert net.fanout[2] == 0                                        # clock pins do not
    assert lab[net.stage[9001]] == "S1"        # the AND feeds register g_reg[0] (R1): stage S1
    assert lab[net.stage[9002]] == "registers"
    t = net.cell_types
    assert net.sinks[9001, t.index("$_DFFE_PP_")] == 1 and net.in0[9001] == 5
    assert list(net.ports["rsp_o"]) == [9002, 9004, 9005, 0]


def test_gate_simulator_logic(tiny_net):
    net, _ = tiny_net
    sim = gatesim.GateSim(net)
    rng = np.random.default_rng(0)
    bits = rng.integers(0, 2, (gatesim.LANES, 32 * activity.REQ_WORDS))
    sim.set_input("rst_ni", np.ones((gatesim.LANES, 1)))
    sim.set_input("in_valid_i", np.ones((gatesim.LANES, 1)))
    sim.set_input("req_i", bits)
    sim.settle()
    sim.clock()
    sim.settle()
    rsp = sim.output("rsp_o")
    assert (rsp[:, 0] == (bits[:, 0] & bits[:, 1])).all()
    assert (rsp[:, 1] == (bits[:, 2] ^ bits[:, 3])).all()
    assert (rsp[:, 2] == 1 - rsp[:, 0]).all() and not rsp[:, 3].any()
    assert sim.output("out_valid_o").all() and sim.output("in_ready_o").all()


def test_gate_model_steady_state_and_idle(tiny_net):
    """Toggles of the second half of each stream, exactly; idle cycles toggle nothing."""
    net, _ = tiny_net
    m = activity.GateModel(net)
    rng = np.random.default_rng(1)
    streams = [rng.integers(0, 16, (12, activity.REQ_WORDS), dtype=np.uint32)
               for _ in range(40)]                   # more than one pass of 32 pairs
    ops, cycles, t = m.pair(streams)
    assert (ops, cycles) == (40 * 6, 40 * 6)
    want_and = want_xor = 0
    for w in streams:
        a, x = w[5:, 0] & 1 & (w[5:, 0] >> 1), (w[5:, 0] >> 2 & 1) ^ (w[5:, 0] >> 3 & 1)
        want_and += np.count_nonzero(np.diff(a))
        want_xor += np.count_nonzero(np.diff(x))
    assert t[9001] == want_and and t[9002] == want_and and t[9005] == want_and
    assert t[9003] == want_xor and t[9004] == want_xor
    assert t[9000] == 0                               # valid stays high in both runs' windows
    c, ti = m.idle(streams[0], 20)
    assert c == 20 * gatesim.LANES and ti.sum() == 0


def test_liberty_level_on_the_gate_model(tiny_net, tiny):
    """The gate model's toggles priced in pJ; clock pins and leakage come on top per cycle."""
    net, _ = tiny_net
    priced = liberty.Priced(activity.GateModel(net), liberty.net_energies(
        tiny, net.cell_types, net.driver, net.sinks, net.in0))
    gates = measure(activity.GateModel(net), BASE, n=8, idle_cycles=10)
    r = measure(priced, BASE, n=8, idle_cycles=10)
    assert r["box"]["unit"] == "pJ" and r["box"]["energy_per_op"] > 0
    assert r["box"]["toggles_per_op"] == gates["box"]["toggles_per_op"]
    # 3 flip-flops (clock pin 0.2 pJ each at slew 0) and the leakage of every cell (nW) over
    # 1 ns: AND2 3 + 2 x (DFF 10 + MUX2 2) + DFF 10 (no cell with a clear: the plain one)
    # + INV 0.5 + XOR2 1.5 = 39 nW
    assert priced.per_cycle == pytest.approx(3 * 0.2 + 39e-9 * 1e-9 * 1e12, rel=1e-9)
    assert r["box"]["energy_per_op_total"] == pytest.approx(
        r["box"]["energy_per_op"] + priced.per_cycle)
    assert r["idle_per_cycle"]["energy"] == 0
    assert r["idle_per_cycle"]["energy_total"] == pytest.approx(priced.per_cycle)


def test_configurations_measured_side_by_side_in_processes(tiny_net, monkeypatch):
    """With two cores the configurations are measured in child processes, with the numbers a
    single process gives; an error in a child reaches the caller."""
    import driver.power.run as power
    net, _ = tiny_net
    nets = {"baseline-unified": net, "baseline-disjoint": net}
    monkeypatch.setattr(power.os, "cpu_count", lambda: 1)
    alone = power._measure_nets("gates", nets, n=8, seed=3, liberty_path=None)
    monkeypatch.setattr(power.os, "cpu_count", lambda: 2)

    def not_here(*a, **k):
        raise AssertionError("measured in the parent process")

    monkeypatch.setattr(power, "_measure_net", not_here)   # spawned children are unaffected
    side = power._measure_nets("gates", nets, n=8, seed=3, liberty_path=None,
                               progress=print)
    for r in (alone, side):
        for v in r.values():
            v.pop("seconds")
    assert side == alone and side["baseline-unified"]["box"]["toggles_per_op"] > 0
    with pytest.raises(OSError, match="cannot read liberty file /nonexistent.lib"):
        power._measure_nets("liberty", nets, n=8, seed=3, liberty_path="/nonexistent.lib")


class _DiesInChild:
    """A netlist whose unpickling ends the process at once, as the OOM killer would."""

    cells = {"$_AND_": 1}

    def __reduce__(self):
        import os
        return os._exit, (3,)


def test_a_dead_measurement_process_is_a_one_line_error(monkeypatch):
    import driver.power.run as power
    monkeypatch.setattr(power.os, "cpu_count", lambda: 2)

    net = _DiesInChild()
    with pytest.raises(OSError, match="measurement process died"):
        power._measure_nets("gates", {"baseline-unified": net, "baseline-disjoint": net},
                            n=8, seed=0, liberty_path=None)


@pytest.mark.slow
def test_gates_level_baseline(tmp_path):
    """Synthesis (minutes, cached), the gate-level model, and its toggles vs the RTL's."""
    out = tmp_path / "g.json"
    assert main(["power", "--level", "gates", "--config", "baseline-unified", "--ops", "100",
                 "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    cfg = rep["configs"]["baseline-unified"]
    assert cfg["box"]["energy_per_op"] > cfg["box"]["toggles_per_op"] > 0
    assert cfg["idle_per_cycle"]["energy"] == 0


def test_cold_syntheses_run_side_by_side_longest_first(monkeypatch):
    import threading
    import time

    import driver.power.run as power
    est = {"baseline-unified": 1, "baseline-disjoint": 2, "extended-unified": 3,
           "extended-disjoint": 9}
    by_params = {tuple(power.params_of(c)[k] for k in ("EXTENDED", "DISJOINT")): c for c in est}
    lock, active, started, peak = threading.Lock(), [0], [], [0]

    def fake(params, progress=None):
        cfg = by_params[(params["EXTENDED"], params["DISJOINT"])]
        with lock:
            started.append(cfg)
            active[0] += 1
            peak[0] = max(peak[0], active[0])
        time.sleep(0.2)
        with lock:
            active[0] -= 1
        if cfg == "baseline-disjoint" and fail:
            raise OSError("Yosys failed: test")
        return cfg

    monkeypatch.setattr(netlist, "synthesize", fake)
    monkeypatch.setattr(netlist, "estimate", lambda p: est[by_params[(p["EXTENDED"],
                                                                       p["DISJOINT"])]])
    monkeypatch.setattr(power.os, "cpu_count", lambda: 2)
    fail = False
    got = power._netlists(list(est))
    assert got == {c: c for c in est}                 # each configuration its own netlist
    assert peak[0] == 2 and started[0] == "extended-disjoint"
    fail = True
    with pytest.raises(OSError, match="Yosys failed"):
        power._netlists(list(est))
