"""The RT unit's recorded stimulus (``RtUnitBackend.trace_unit(record=True)``) and its replay on
the unit's generic-gate netlist (``driver.power.unit_gates``, docs/rtunit_rtl.md#energy): the
recording holds every clock cycle of the run, its results are the run's, recording changes
nothing the unit computes, and the netlist driven by the recorded inputs shows the recorded
outputs cycle by cycle in every lane."""

from __future__ import annotations

import numpy as np
import pytest

from driver.backends.rtunit import RtUnitBackend, record_layout, unit_ports
from driver.core.datapath import prepare_rays
from driver.tracer import as_bvh
from support.corpus import rays as corpus_rays
from support.meshes import soup

RAYS, DEPTH = 4, 8          # the unit the suite builds (tests/conftest.py: rtunit:...:4:8)


@pytest.fixture(scope="module")
def unit():
    return RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEPTH, mem_latency=20, compare=False)


@pytest.fixture(scope="module")
def scene():
    tris = soup(200, 1)
    o, d = corpus_rays(tris, 64, 3)
    return as_bvh(tris), prepare_rays(o, d)


def _value(stim, port, cycle):
    return int.from_bytes(stim.outputs[port][cycle].tobytes(), "little")


def test_the_recording_is_every_cycle_of_the_run(unit, scene):
    bvh, rays = scene
    any_hit = np.arange(len(rays)) % 3 == 0
    plain = unit.trace_unit(bvh, rays, any_hit=any_hit)
    rec = unit.trace_unit(bvh, rays, any_hit=any_hit, record=True)
    assert plain.stimulus is None
    stim = rec.stimulus
    # recording clocks every cycle (none skipped) and changes nothing the unit computes
    assert rec.stats["skipped_cycles"] == 0 and stim.cycles == rec.stats["cycles_simulated"]
    assert rec.stats["cycles"] == plain.stats["cycles"]
    for f in ("prim", "t", "hit", "box_ops", "tri_ops", "overflows", "refills"):
        assert np.array_equal(getattr(rec, f), getattr(plain, f)), f
    # every port but the clock, in the RTL's order, inputs then outputs
    ports = [n for n, _ in unit_ports() if n != "clk_i"]
    assert [n for n, _, _ in record_layout(unit._unit)] == \
        [n for n, d in unit_ports() if d == "input" and n != "clk_i"] + \
        [n for n, d in unit_ports() if d == "output"]
    assert set(stim.inputs) | set(stim.outputs) == set(ports)
    # the results on the recorded result port are the run's, each ray once
    taken = [c for c in range(stim.cycles) if _value(stim, "res_valid_o", c)
             and int.from_bytes(stim.inputs["res_ready_i"][c].tobytes(), "little")]
    assert len(taken) == len(rays)
    ids = [_value(stim, "res_id_o", c) for c in taken]
    assert sorted(ids) == list(range(len(rays)))
    for c, i in zip(taken, ids):
        assert _value(stim, "res_hit_o", c) == rec.hit[i]
        assert _value(stim, "res_t_o", c) == rec.t[i:i + 1].view(np.uint32)[0]
        assert _value(stim, "res_box_ops_o", c) == rec.box_ops[i]
    # rays enter on the recorded ray port in order, with their any-hit flags
    entered = [c for c in range(stim.cycles)
               if stim.inputs["ray_valid_i"][c, 0] and _value(stim, "ray_ready_o", c)]
    assert len(entered) == len(rays)
    assert [int(stim.inputs["ray_any_hit_i"][c, 0]) for c in entered] == any_hit.tolist()


@pytest.mark.slow
def test_the_netlist_replays_the_recorded_runs(unit, scene):
    """The unit's gate netlist (synthesized: minutes) driven by four recorded runs, one lane
    each, shows every recorded output every cycle; a corrupted response is seen."""
    from driver.power import unit_gates
    bvh, rays = scene
    net = unit_gates.unit_netlist(unit.unit_params)
    runs = [unit.trace_unit(bvh, rays[k::4], any_hit=k == 3, record=True).stimulus
            for k in range(4)]
    rep = unit_gates.replay(net, runs)
    assert rep.mismatches == 0, rep.first_mismatch
    assert rep.cycles.tolist() == [s.cycles for s in runs]
    assert rep.toggles.sum() > 0
    # a response's data changed in one lane: the netlist's outputs leave the recording's there
    bad = runs[1]
    c = int(np.flatnonzero(bad.inputs["mem_rsp_valid_i"][:, 0])[0])
    bad.inputs["mem_rsp_data_i"][c] ^= 0xFF
    rep = unit_gates.replay(net, runs)
    assert rep.mismatches > 0 and rep.first_mismatch[0] == 1
