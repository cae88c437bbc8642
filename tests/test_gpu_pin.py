"""The RT-unit replay with warps, one-kernel frames and a memory hierarchy, pinned to the replay
before them: with ``--frame wavefront --flush-between --warp-size 1 --rt-units 1 --l2-kib 0``
and the default memory, every RT-unit statistic of the pinned frames equals the one recorded
before (tests/data/rtunit_pin.json, tests/data/rtunit_pin_orders.json); and the monotone
properties of docs/rtunit.md on real frames."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from driver import rtunit, workloads
from driver.backends import backend
from driver.design import DesignPoint
from driver.rtunit.gpu import replay_frame, waves_of
from driver.rtunit.plan import Schedule, Wave
from driver.scenes.scene import load_scene
from driver.tracer import trace

DATA = Path(__file__).resolve().parent / "data"
# not compared: wall times, and how the replay ran its pipelines (the pins came from replays
# that evaluated the model; these run as the pipelines' timing, the default)
WALL = {"sim_wall_s", "sim_cycles_per_s", "full_cycles", "responses_verified", "replay_datapath",
        "model_evals"}
PIN = Schedule("wavefront", warp_size=1, warps_per_unit=0, shader_cycles=0, flush_between=True,
               rt_units=1)


def frame(point: DesignPoint):
    scene = point.scene_of(load_scene(point.scene))
    rtl = backend("rtl", **point.backend_options())
    return workloads.run(workloads.setup_for(scene), point.build(scene), point.size, point.size,
                         lambda b, o, d, **k: trace(b, o, d, backend=rtl, record=True, **k),
                         point.workload, **point.workload_options())


def differences(got, want, path="") -> list[str]:
    """Where ``got`` differs from ``want`` (every key of ``want``, wall times left out)."""
    if isinstance(want, dict):
        out = []
        for k, v in want.items():
            if k in WALL:
                continue
            if k not in got:
                out.append(f"{path}/{k} missing")
            else:
                out += differences(got[k], v, f"{path}/{k}")
        return out
    if isinstance(want, list):
        if len(got) != len(want):
            return [f"{path}: {len(got)} entries, pinned {len(want)}"]
        return [d for i, (a, b) in enumerate(zip(got, want)) for d in differences(a, b,
                                                                                  f"{path}[{i}]")]
    if isinstance(want, float):
        return [] if got == pytest.approx(want, rel=1e-12, abs=1e-12) else [f"{path}: {got} != "
                                                                            f"{want}"]
    return [] if got == want else [f"{path}: {got} != {want}"]


PINNED = json.loads((DATA / "rtunit_pin.json").read_text())


@pytest.fixture(scope="module", params=sorted(PINNED))
def pinned(request):
    name = request.param
    want = PINNED[name]
    return name, want, frame(DesignPoint(**want["design_point"]))


def test_every_statistic_of_the_pinned_frames(pinned):
    name, want, res = pinned
    point = DesignPoint(**want["design_point"])
    waves = waves_of(res.batches)
    bad = []
    for key, memory in (("rtunit", None), ("rtunit_memory", point.memory())):
        fr = replay_frame(waves, point.rays_in_flight, point.pipelines, memory, PIN, width=128)
        assert fr.datapath == "timing"
        for kind, t in want["by_type"].items():
            bad += differences(fr.type_summary(kind), t[key], f"{name}/{kind}/{key}")
        total = fr.summary()
        assert total["cycles"] == sum(t[key]["cycles"] for t in want["by_type"].values())
        assert total["frame_schedule"] == "wavefront" and total["kernels"] == len(res.batches)
    # and each batch replayed alone (driver.rtunit.replay), statistic for statistic
    for kind, t in want["by_type"].items():
        recs = [b.result.record for b in res.batches if b.kind == kind]
        got = [rtunit.replay(r, point.rays_in_flight, point.pipelines, memory=m).stats()
               for r in recs for m in (None, point.memory())]
        bad += differences(got, t["replays"], f"{name}/{kind}/replays")
    assert not bad, "\n".join(bad[:20])


def test_every_ray_order_pinned():
    want = json.loads((DATA / "rtunit_pin_orders.json").read_text())
    point = DesignPoint(scene="bunny_floor", workload="path", size=32, spp=2, bounces=2)
    res = frame(point)
    windows = {"hash": 1024, "twopoint": 256, "affinity": 256, "hash-affinity": 256,
               "treelet": 256}
    bad = []
    for policy, runs in want.items():
        got = [rtunit.replay(b.result.record, 64, 1, memory=point.memory(), ray_order=policy,
                             ray_window=windows[policy]).stats() for b in res.batches]
        bad += differences(got, runs, policy)
    assert not bad, "\n".join(bad[:20])


# ------------------------------------------------------------------------------ monotone

@pytest.fixture(scope="module")
def path_frame():
    return frame(DesignPoint(scene="bunny_floor", workload="path", size=24, spp=2, bounces=2))


def test_more_rt_units_never_add_frame_cycles_with_free_memory(path_frame):
    waves = waves_of(path_frame.batches)
    for warp in (1, 8):
        last = None
        for units in (1, 2, 3, 4, 6, 8, 16):
            fr = replay_frame(waves, 32, 1, None, Schedule("one-kernel", warp_size=warp,
                                                           rt_units=units), width=24,
                              datapath="rtl")
            assert fr.verified
            if last is not None:
                assert fr.cycles <= last, (warp, units)
            last = fr.cycles


def test_warps_of_one_thread_are_the_per_ray_pool(path_frame):
    """Warp size 1 with the ray pool as the only limit (resident warps enough to keep it full,
    here every one) is the per-ray pool of the same size, cycle for cycle, with the memory and
    without; in a one-kernel frame of one ray type and in a wavefront frame."""
    prim = [b for b in path_frame.batches if b.kind == "primary"]
    rec = prim[0].result.record
    n = rec.rays
    for r in (1, 4, 64):
        for memory in (None, rtunit.MemoryModel()):
            pool = rtunit.replay(rec, r, 1, memory=memory)
            for warps in (0, r + 1, 4 * r, n):
                fr = replay_frame([Wave(rec, "primary", np.arange(n), np.zeros(n, np.int64))],
                                  r, 1, memory, Schedule("one-kernel", warp_size=1,
                                                         warps_per_unit=warps), width=24)
                assert (fr.cycles, fr.counters["starved_cycles"]) == (pool.cycles,
                                                                      pool.starved_cycles)
                assert np.array_equal(fr.responses[:, 1:], pool.responses[:, 1:])
