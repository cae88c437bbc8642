"""driver.power on the configurations with the q8 decode (``-q8``, COMPRESSED) and TRANSFORM
(``-xf``): the box_q8 and transform streams, which configurations run which operation, the
decode stage's label S0 at both levels, the report's comparisons and the CLI (its refusals
are in tests/test_power.py).

The default suite builds the traced RTL of baseline-unified-q8 once (cached) and measures tiny
streams on it; the TRANSFORM model and the gate netlists run under ``-m slow``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from driver import backend
from driver.core.configs import Q8_SUFFIX, XF_SUFFIX
from driver.cli import main
from driver.core.datapath import QUADBOX, TRANSFORM, transform_results
from driver.instances import transform_ray
from driver.core.wire import FLAG_DECODE_Q8, pack_requests
from driver.core.layout import Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, decode_q8, q8_count
from driver.power import activity, measure, netlist, report, stimulus

import driver.power as power

Q8 = {"EXTENDED": 0, "DISJOINT": 0, "COMPRESSED": 1, "LATENCY": 12}


def _nodes(req):
    return np.ascontiguousarray(req["qnode"]).view(Q8_NODE)[:, 0]


# ------------------------------------------------------------------------------------------------
# the streams

def test_box_q8_stream_is_the_box_stream_as_valid_q8_nodes():
    """box_q8: the box stream's rays; each node holds the first 1-4 of that request's boxes,
    encoded as the encoder does (smallest exponent per axis, every decoded box containing its
    box); the golden model answers it exactly as a plain QUADBOX on the decoded boxes, and hits
    about the share of boxes the box stream hits."""
    n = 800
    box, q8 = stimulus.requests("box", n, seed=4), stimulus.requests("box_q8", n, seed=4)
    assert (q8["opcode"] == QUADBOX).all() and (q8["flags"] == FLAG_DECODE_Q8).all()
    for f in ("origin", "dir", "inv", "extent", "kx", "shear"):
        assert np.array_equal(box[f], q8[f], equal_nan=True)
    nodes = _nodes(q8)
    count = q8_count(nodes)
    assert set(np.unique(count)) == {1, 2, 3, 4}
    assert (nodes["exp"][:, 3] == count).all() and not nodes["child"].any()
    exp = nodes["exp"][:, :3].view(np.int8).astype(np.int64)
    assert ((exp >= Q8_EXP_MIN) & (exp <= Q8_EXP_MAX)).all()
    used = np.arange(4)[None, :] < count[:, None]
    dec = decode_q8(nodes)
    assert np.isinf(dec[~used]).all()
    assert (dec[used][:, :3] <= box["box"][used][:, :3]).all()          # containment
    assert (dec[used][:, 3:] >= box["box"][used][:, 3:]).all()
    # the exponent is the smallest whose 255 steps span the node: one less would not
    lo = np.where(used[..., None], box["box"][..., :3], np.inf).min(axis=1)
    hi = np.where(used[..., None], box["box"][..., 3:], -np.inf).max(axis=1)
    span = hi.astype(np.float64) - lo
    assert (span <= 255 * np.ldexp(1.0, exp)).all()
    assert ((exp == Q8_EXP_MIN) | (span > 255 * np.ldexp(1.0, exp - 1))).all()
    assert np.array_equal(nodes["origin"], lo.astype(np.float32))
    # the decode on the golden model == a plain QUADBOX on the decoded boxes == box_q8_host
    plain = q8.copy()
    plain["flags"] = 0
    plain["box"] = dec
    host = stimulus.requests("box_q8_host", n, seed=4)
    assert host["flags"].sum() == 0 and np.array_equal(host["box"], dec)
    got = backend("golden", compressed=True).run(q8)
    want = backend("golden").run(plain)
    assert got.tobytes() == want.tobytes() == backend("golden").run(host).tobytes()
    share_q8 = got["box_hit"].sum() / used.sum()
    share_box = backend("golden").run(box)["box_hit"].mean()
    assert 0.2 < share_box < 0.8 and abs(share_q8 - share_box) < 0.1


def test_transform_stream_is_well_formed():
    """transform: TRANSFORM requests with only opcode, tag, origin, dir and matrix set; the
    golden model answers the host's transform of the same rays, bit for bit."""
    req = stimulus.requests("transform", 200, seed=2)
    assert (req["opcode"] == TRANSFORM).all() and (req["flags"] == 0).all()
    m = req["matrix"]
    assert np.isfinite(m).all() and len(np.unique(m[:, 0, 0])) == 200
    det = np.linalg.det(m[:, :, :3].astype(np.float64))
    assert (det > 0).any() and (det < 0).any()                       # rotations and mirrors
    assert not req["tri"].any() and not req["vec_a"].any()
    o, d = transform_results(backend("golden", transform=True).run(req))
    o2, d2 = transform_ray(m, req["origin"], req["dir"])
    assert np.array_equal(o, o2) and np.array_equal(d, d2)


def test_which_configuration_runs_which_operation():
    p = power.build_params
    assert stimulus.measurable(p("baseline-unified")) == [
        "box", "box_q8_host", "triangle", "triangle_no_cull"]
    assert stimulus.measurable(p("baseline-unified" + Q8_SUFFIX)) == [
        "box", "box_q8", "box_q8_host", "triangle", "triangle_no_cull"]
    assert stimulus.measurable(p("baseline-unified" + XF_SUFFIX)) == [
        "box", "box_q8_host", "triangle", "triangle_no_cull", "transform"]
    assert [stimulus.box_op(p(c), q8) for c in ("baseline-unified", "baseline-unified-q8")
            for q8 in (False, True)] == ["box", "box_q8_host", "box", "box_q8"]
    assert set(stimulus.measurable(p("extended-disjoint" + Q8_SUFFIX + XF_SUFFIX))) == \
        set(stimulus.OPS)
    assert power.params_of("baseline-unified-q8") == Q8
    assert power.params_of("baseline-unified-xf")["LATENCY"] == 11
    assert power.parse_configs("all") == list(power.configs())
    assert power.parse_configs("baseline-unified-q8-xf,baseline-unified") == [
        "baseline-unified-q8-xf", "baseline-unified"]
    with pytest.raises(ValueError, match="box_q8 needs the build parameter COMPRESSED"):
        measure(None, {"EXTENDED": 0}, ops=["box_q8"])


# ------------------------------------------------------------------------------------------------
# the decode stage's label

def test_gate_netlist_labels_the_decode_stage_s0(tmp_path):
    """Logic feeding the decode register R_dec (``g_decode.u_dec_reg``) is stage S0."""
    def _cell(t, **conn):
        return {"type": t, "connections": {k: [v] for k, v in conn.items()},
                "attributes": {"src": "x.sv:1"}}

    req = list(range(5, 5 + 32 * activity.REQ_WORDS))
    design = {"modules": {"rayflex": {
        "ports": {"clk_i": {"direction": "input", "bits": [2]},
                  "req_i": {"direction": "input", "bits": req},
                  "rsp_o": {"direction": "output", "bits": [9004]}},
        "netnames": {"g_decode.u_dec_reg.main_q": {"hide_name": 0, "bits": [9002]},
                     "g_reg[0].u_reg.main_q": {"hide_name": 0, "bits": [9004]}},
        "cells": {"dec": _cell("$_AND_", A=5, B=6, Y=9001),
                  "r_dec": _cell("$_DFF_P_", C=2, D=9001, Q=9002),
                  "s1": _cell("$_NOT_", A=9002, Y=9003),
                  "r1": _cell("$_DFF_P_", C=2, D=9003, Q=9004)}}}}
    info = netlist._write(design, tmp_path)
    net = netlist._load(tmp_path, "k", {**info, "synth_s": 0}, cached=True)
    lab = netlist.STAGE_LABELS
    assert [lab[net.stage[b]] for b in (9001, 9002, 9003, 9004)] == \
        ["S0", "registers", "S1", "registers"]


def test_signal_stage_names():
    s = activity._signal_stage
    lab = netlist.STAGE_LABELS
    assert lab[s(["TOP.rayflex.g_decode.u_s0.add_y"])] == "S0"
    assert lab[s(["TOP.rayflex.g_decode.u_dec_reg.main_q"])] == "registers"
    assert lab[s(["TOP.rayflex.u_s1.st_o"])] == "S1"


@pytest.fixture(scope="module")
def q8_signals():
    return activity.SignalModel(Q8)


def test_box_q8_on_the_q8_model(q8_signals):
    """On baseline-unified-q8 at level signals: one op per cycle at 12 stages; box_q8 spends a
    share in S0, and more than box does there (the idle decode stage)."""
    r = measure(q8_signals, Q8, n=12, seed=1, ops=["box", "box_q8"])
    assert set(r) == {"box", "box_q8", "idle_per_cycle"}
    for op in ("box", "box_q8"):
        assert r[op]["cycles_per_op"] == 1.0 and r[op]["energy_per_op"] > 0
        assert sum(r[op]["stages"].values()) == pytest.approx(1, abs=1e-3)
    assert r["box_q8"]["stages"]["S0"] > 0.05 > r["box"]["stages"]["S0"]
    assert r["idle_per_cycle"]["energy"] == 0


@pytest.mark.slow
def test_transform_on_the_xf_model():
    p = power.params_of("baseline-unified-xf")
    r = measure(activity.SignalModel(p), p, n=12, seed=1, ops=["transform"])
    assert r["transform"]["cycles_per_op"] == 1.0 and r["transform"]["energy_per_op"] > 0
    assert r["transform"]["stages"]["S2"] > 0.05 and r["transform"]["stages"]["S0"] == 0


# ------------------------------------------------------------------------------------------------
# the report

def _fake(e, stages=None):
    return {op: {"energy_per_op": v, **({"stages": stages[op]} if stages and op in stages
                                          else {})} for op, v in e.items()} \
        | {"idle_per_cycle": {"energy": 0}}


def test_report_decode_and_transform_comparisons():
    cfgs = {"baseline-unified": _fake({"box": 100, "box_q8_host": 90, "triangle": 80}),
            "baseline-unified-q8": _fake({"box": 104, "box_q8": 108, "box_q8_host": 96,
                                          "triangle": 81},
                                         {"box_q8": {"S0": 0.25, "S1": 0.75},
                                          "box": {"S0": 0.01, "S1": 0.99}}),
            "baseline-unified-xf": _fake({"box": 102, "triangle": 82, "transform": 51})}
    r = report.ratios(cfgs)
    q = r["q8_decode"]["baseline-unified-q8"]
    assert q["base"] == "baseline-unified"
    assert q["box_q8_vs_host"] == 0.125
    assert q["box_q8_vs_base_host"] == 0.2 and q["box_vs_base_box"] == 0.04
    assert q["decode_share"] == 0.25 and q["decode_energy"] == 27.0
    x = r["transform_op"]["baseline-unified-xf"]
    assert x["transform_vs_box"] == 0.5 - 1 and x["box_vs_base_box"] == 0.02
    assert x["triangle_vs_base_triangle"] == pytest.approx(0.025)
    assert list(r["q8_decode"]) == ["baseline-unified-q8"] and list(r["transform_op"]) == [
        "baseline-unified-xf"]
    mix = {"primary": {"rays": 2, "box_ops": 10, "tri_ops": 2}}
    pr = report.per_ray(mix, cfgs, q8_image=True)["primary"]["configs"]
    assert pr["baseline-unified-q8"] == {"energy_per_ray": (10 * 108 + 2 * 81) / 2,
                                         "energy_per_frame": 10 * 108 + 2 * 81,
                                         "box_op": "box_q8"}
    assert pr["baseline-unified"]["box_op"] == "box_q8_host"   # the host decodes the node
    assert "baseline-unified-xf" not in pr                      # box_q8_host not measured
    assert report.per_ray(mix, cfgs)["primary"]["configs"]["baseline-unified-q8"][
        "box_op"] == "box"
    assert report.stage_columns([{"S0": 0.0, "S1": 1.0}, {"S1": 0.5, "S2": 0.5}]) == ["S1", "S2"]


# ------------------------------------------------------------------------------------------------
# the command line

def test_cli_q8_configuration_end_to_end(tmp_path, capsys):
    """--config with a -q8 configuration and --op: the JSON, the decode comparison rows and the
    S0 column of the stage table."""
    out = tmp_path / "p.json"
    assert main(["power", "--config", "baseline-unified-q8", "--op", "box,box_q8,box_q8_host",
                 "--ops", "10", "--scene", "sphere", "--size", "4", "--bvh-format", "q8", "--json",
                 str(out), "--no-progress"]) == 0
    rep = json.loads(out.read_text())
    cfg = rep["configs"]["baseline-unified-q8"]
    assert set(cfg) >= {"box", "box_q8"} and "triangle" not in cfg and cfg["latency"] == 12
    assert rep["ratios"]["q8_decode"]["baseline-unified-q8"]["decode_share"] > 0
    assert rep["per_ray"] == {} or all(
        "baseline-unified-q8" not in row["configs"] for row in rep["per_ray"].values())
    text = capsys.readouterr().out
    assert "| box_q8 vs box_q8_host (baseline-unified-q8) |" in text and "| S0 |" in text


def test_power_help_names_the_extra_configurations(capsys):
    with pytest.raises(SystemExit):
        main(["power", "--help"])
    text = "".join(capsys.readouterr().out.split())        # argparse wraps at hyphens
    assert "baseline-unified,baseline-unified-q8,baseline-unified-xf" in text
    assert "all:thefourbaseconfigurations" in text and "box_q8needsa-q8configuration" in text


# ------------------------------------------------------------------------------------------------
# rayflex sweep's energy per ray

def test_sweep_energy_of_a_q8_configuration(monkeypatch):
    """A -q8 configuration tracing a q8 image is measured with box_q8 and its box ops are priced
    as box_q8; without the decode as box_q8_host; on a box32 image as box."""
    from driver import sweep
    from driver.design import DesignPoint
    asked = {}

    def fake_run_level(level, cfgs, latency=None, ops=None, **k):
        asked[(cfgs[0], level)] = (latency, tuple(ops))
        e = {"box": 10.0, "triangle": 8.0, "box_q8": 12.0, "box_q8_host": 9.0}
        return {"configs": {cfgs[0]: {op: {"energy_per_op": e[op]} for op in ops}
                            | {"latency": latency, "idle_per_cycle": {"energy": 0}}}}

    monkeypatch.setattr(power, "run_level", fake_run_level)
    monkeypatch.setattr(power, "netlist_cached", lambda cfg: False)
    points = [DesignPoint(config="baseline-unified-q8", bvh_format="q8"),
              DesignPoint(config="baseline-unified", bvh_format="q8"),
              DesignPoint(config="baseline-unified", bvh_format="box32")]
    tables = sweep.energy_tables(points, progress=False)
    assert asked == {("baseline-unified-q8", "signals"): (12, ("box", "triangle", "box_q8")),
                     ("baseline-unified", "signals"): (11, ("box", "triangle", "box_q8_host"))}
    t = tables[sweep.energy_key("baseline-unified-q8", 12)]["signals"]
    assert t == {"box": 10.0, "triangle": 8.0, "box_q8": 12.0, "unit": "bit toggles"}
    counts = {"rays": 2, "box_ops": 10, "tri_ops": 4}
    assert sweep.energy_per_ray(counts, t, sweep._box_op(points[0])) == (10 * 12 + 4 * 8) / 2
    assert sweep.energy_per_ray(counts, t) == (10 * 10 + 4 * 8) / 2
    assert [sweep._box_op(p) for p in points] == ["box_q8", "box_q8_host", "box"]


@pytest.mark.slow
def test_gates_level_of_the_decode_and_transform(tmp_path):
    """Synthesis of baseline-unified-q8 and -xf (minutes each, cached), then box_q8 vs
    box_q8_host and transform at the gate level: the decode stage's logic is labelled S0 and
    costs energy only when it decodes."""
    out = tmp_path / "g.json"
    assert main(["power", "--level", "gates", "--config", "baseline-unified-q8,baseline-unified-xf",
                 "--op", "box_q8_host,triangle", "--ops", "20", "--json", str(out),
                 "--no-progress"]) == 0
    rep = json.loads(out.read_text())
    q8 = rep["configs"]["baseline-unified-q8"]
    assert q8["latency"] == 12 and q8["box_q8_host"]["cycles_per_op"] == 1.0
    assert 0 < q8["box_q8_host"]["stages"]["S0"] < 0.05
    assert rep["configs"]["baseline-unified-xf"]["box_q8_host"]["stages"]["S0"] == 0
    p = power.params_of("baseline-unified-q8")
    net = netlist.synthesize(power.build_params("baseline-unified-q8"))
    r = measure(activity.GateModel(net), p, n=20, ops=["box_q8", "box_q8_host"])
    assert r["box_q8"]["stages"]["S0"] > 0.1
    assert r["box_q8"]["energy_per_op"] > r["box_q8_host"]["energy_per_op"]
    xf = power.params_of("baseline-unified-xf")
    net = netlist.synthesize(power.build_params("baseline-unified-xf"))
    r = measure(activity.GateModel(net), xf, n=20, ops=["transform"])
    assert r["transform"]["energy_per_op"] > 0 and r["transform"]["stages"]["S2"] > 0.2
