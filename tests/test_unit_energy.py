"""The whole RT unit's energy from its switching activity (``rayflex power --backend rtunit``,
docs/rtunit_rtl.md#energy): the traced unit's nets mapped to the area table's module rows, its
counts non-zero in every module a frame uses and adding up, an idle unit and an empty batch at
zero, more rays more energy, the same hits as the untraced unit, the datapath's row against the
datapath alone, and the command's one-line refusals before any build."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from driver.backends import toggles
from driver.backends.rtunit import (MAX_RAYS, MAX_STACK_DEPTH, UNIT_CONTROL, UNIT_INSTANCES,
                                    UNIT_ROWS, RtUnitBackend, net_rows)
from driver.core.layout import NODE_BYTES
from driver.cli import main
from driver.core.datapath import prepare_rays
from driver.design import DesignPoint
from driver.power import unit
from driver.tracer import as_bvh, trace
from support.corpus import rays as corpus_rays
from support.meshes import soup

RAYS, DEPTH = 4, 8          # the test builds (tests/conftest.py: activity:...:4:8)
# the rows a box32 frame without instances switches (the ray setups are built with TRANSFORM)
USED = [r for r in UNIT_ROWS if r != "ray setups"]


@pytest.fixture(scope="module")
def traced():
    return RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEPTH, mem_latency=20, compare=False,
                         activity=True)


@pytest.fixture(scope="module")
def scene():
    tris = soup(200, 1)
    o, d = corpus_rays(tris, 64, 3)
    return as_bvh(tris), o, d


def _row(name):
    return UNIT_ROWS.index(name)


def test_nets_belong_to_the_module_that_drives_them():
    names = [
        ["TOP.rf_rtunit.u_sched.dp_req_o", "TOP.rf_rtunit.dp_req",
         "TOP.rf_rtunit.u_datapath.req_i"],                       # scheduler drives it
        ["TOP.rf_rtunit.u_datapath.u_s2.prod", "TOP.rf_rtunit.u_datapath.u_s2.u_mul.p_o"],
        ["TOP.rf_rtunit.u_stack.pop_i"],                          # an expression of the top
        ["TOP.rf_rtunit.pop_slot", "TOP.rf_rtunit.u_stack.pop_slot_i",
         "TOP.rf_rtunit.u_fetch.in_slot_i"],                      # a register of the top
        ["TOP.ray_i", "TOP.rf_rtunit.ray_i", "TOP.rf_rtunit.u_rays.load_ray_i"],   # harness
        ["TOP.res_id_o", "TOP.rf_rtunit.res_id_o", "TOP.rf_rtunit.u_rays.id_c_o"],
        ["TOP.rf_rtunit.g_xf.u_setup.g_setup[0].u_setup.inv_q"],
        ["TOP.rf_rtunit.u_fetch.node_q[3]"],                      # an array element
    ]
    rows, weight = net_rows(names)
    assert [UNIT_ROWS[r] for r in rows] == ["scheduler", "datapath", "control", "control",
                                            "control", "ray buffer", "ray setups", "fetch"]
    assert weight.tolist() == [1, 1, 1, 1, 0, 1, 1, 1]
    # every instance of the top has its row, and the top's own logic one more
    assert UNIT_ROWS == tuple(n for n, _ in UNIT_INSTANCES.values()) + (UNIT_CONTROL[0],)


def test_every_storage_bit_is_traced(traced):
    traced.idle_activity(1)
    names = {n.split(".", 2)[-1] for ns in traced.net_names for n in ns}
    # every stack RAM entry, node buffer entry and ray record of the slots
    assert {f"u_stack.ram_q[{s}][{e}]" for s in range(RAYS) for e in range(DEPTH)} <= names
    assert {f"u_fetch.node_q[{s}]" for s in range(RAYS)} <= names
    assert {f"u_rays.ray_q[{s}]" for s in range(RAYS)} <= names
    # Verilator leaves out a variable wider than --trace-max-width bits, an array counting all
    # its elements' bits: the limit covers the biggest unit's stack RAM and node buffer
    assert toggles.TRACE_MAX_WIDTH >= MAX_RAYS * MAX_STACK_DEPTH * 32
    assert toggles.TRACE_MAX_WIDTH >= MAX_RAYS * max(NODE_BYTES.values()) * 8


def test_idle_unit_and_empty_batch_switch_nothing(traced, scene):
    idle = traced.idle_activity(200)
    assert idle["cycles"] == 200 and idle["nets"] > 1000
    assert set(idle["toggles"]) == set(UNIT_ROWS)
    # registers load only on a handshake: nothing switches without a ray (the clock is not a net
    # here, as at the datapath's level signals)
    assert sum(idle["toggles"].values()) == 0
    bvh, o, d = scene
    empty = traced.trace_unit(bvh, prepare_rays(o[:0], d[:0]))
    assert sum(empty.activity["toggles"].values()) == 0


def test_activity_in_every_module_adds_up_and_grows_with_rays(traced, scene):
    bvh, o, d = scene
    few = traced.trace_unit(bvh, prepare_rays(o[:8], d[:8])).activity
    many = traced.trace_unit(bvh, prepare_rays(o, d)).activity
    for act in (few, many):
        # a module dropped from the table would leave its row at zero (its nets in control)
        assert all(act["toggles"][r] > 0 for r in USED), act["toggles"]
        assert act["toggles"]["ray setups"] == 0
    assert all(many["toggles"][r] > few["toggles"][r] for r in ("datapath", "ray buffer",
                                                                "stack", "fetch"))
    assert sum(many["toggles"].values()) > 4 * sum(few["toggles"].values())
    assert many["cycles"] > few["cycles"] > 0


def test_tracing_changes_nothing_the_unit_computes(traced, scene):
    bvh, o, d = scene
    plain = RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEPTH, mem_latency=20, compare=False)
    for any_hit in (False, True):
        a = trace(bvh, o, d, backend=plain, any_hit=any_hit)
        b = trace(bvh, o, d, backend=traced, any_hit=any_hit)
        assert b.hit.tolist() == a.hit.tolist() and b.prim.tolist() == a.prim.tolist()
        assert b.t.view(np.uint32).tolist() == a.t.view(np.uint32).tolist()
        assert b.box_ops.tolist() == a.box_ops.tolist()
        assert b.stats["unit_rtl"]["cycles"] == a.stats["unit_rtl"]["cycles"]
        assert "activity" not in a.stats["unit_rtl"]
        act = b.stats["unit_rtl"]["activity"]
        assert act["cycles"] >= b.stats["unit_rtl"]["cycles"]


def test_report_per_ray_type_and_the_datapath_check():
    point = DesignPoint(scene="sphere", workload="shadow", size=6, rays_in_flight=RAYS,
                        stack_depth=DEPTH)
    rep = unit.measure_unit(point, n=20)
    assert set(rep["per_ray"]) == {"primary", "shadow"}
    frame = rep["frame"]
    assert frame["rays"] == sum(r["rays"] for r in rep["per_ray"].values())
    for row in [*rep["per_ray"].values(), frame]:
        mods = row["modules"]
        assert sum(m["energy_per_ray"] for m in mods.values()) * row["rays"] == \
            pytest.approx(row["energy"])
        assert sum(m["share"] for m in mods.values()) == pytest.approx(1.0)
        assert row["energy_per_ray"] > 0
        # the datapath in the unit against the datapath alone: energy per op x the batch's ops
        assert 0.7 < row["datapath_check"]["ratio"] < 1.3
    assert frame["energy"] == pytest.approx(sum(r["energy"] for r in rep["per_ray"].values()))
    assert rep["idle_per_cycle"]["energy"] == 0
    assert "| datapath |" in unit.markdown(rep)


def test_command_writes_the_report(tmp_path, capsys):
    out = tmp_path / "u.json"
    assert main(["power", "--backend", "rtunit", "--scene", "sphere", "--size", "4",
                 "--rays-in-flight", str(RAYS), "--stack-depth", str(DEPTH), "--ops", "10",
                 "--no-progress", "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["backend"] == "rtunit" and rep["unit_params"]["RAYS"] == RAYS
    assert rep["per_ray"]["primary"]["rays"] == 16
    assert "energy per ray" in capsys.readouterr().out.lower()


@pytest.mark.parametrize("argv,message", [
    (["--level", "gates"], "level signals"),
    (["--config", "all"], "one configuration"),
    (["--config", "baseline-unified,baseline-disjoint"], "one configuration"),
    (["--op", "box"], "--op"),
    (["--rays-in-flight", "300"], "--rays-in-flight"),
    (["--bvh-format", "q8g"], "q8g"),
    (["--ops", "0"], "--ops"),
    (["--pipelines", "2"], "--pipelines"),
])
def test_command_refuses_in_one_line(argv, message, capsys, tmp_path):
    out = tmp_path / "u.json"
    assert main(["power", "--backend", "rtunit", "--scene", "sphere", "--size", "4",
                 "--json", str(out), *argv]) != 0
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_the_page_quotes_its_measurements():
    """docs/rtunit_rtl.md#energy's table is that of the figures' JSON (tools/figures.py
    unit_energy_*): every energy per ray of every ray type and module."""
    root = Path(__file__).resolve().parent.parent
    page = (root / "docs" / "rtunit_rtl.md").read_text()
    table = page[page.index("## Energy"):page.index("## What it models")]
    rows = {line.split("|")[1].strip().strip("*"): line for line in table.splitlines()
            if line.startswith("| ")}
    for stem in ("bunny64", "cornell_ao32", "bunny_floor_path32"):
        rep = json.loads((root / "docs" / f"unit_energy_{stem}.json").read_text())
        for kind, row in rep["per_ray"].items():
            assert f"**{row['energy_per_ray']:,.0f}**" in rows["total per ray"]
            for m in USED:
                assert f" {row['modules'][m]['energy_per_ray']:,.0f} (" in rows[m], (stem, m)
