"""The RT-unit replay without evaluating the datapath again (``--replay-datapath timing``, the
default) against the replay that evaluates every request on the Verilated model (``rtl``): every
count, time and per-ray array is the same under every kind of schedule; and the "rtl" backend's
traversal steps split over several models give the responses and cycles of one model."""

from __future__ import annotations

import numpy as np
import pytest

from driver import rtunit, workloads
from driver.backends import harness
from driver.backends.harness import HarnessBackend, default_threads, model_latency
from driver.bvh4 import build
from driver.rtunit import MemoryModel, UnitCosts
from driver.rtunit.gpu import replay_frame, timing_differences, waves_of
from driver.rtunit.order import RayOrder
from driver.rtunit.plan import Schedule
from driver.scenes.scene import load_scene
from driver.tracer import trace

PARAMS = HarnessBackend().params
GPU_MEMORY = MemoryModel(cache_bytes=16384, ways=8, line_bytes=128, sector_bytes=32,
                         hit_latency=4, mshrs=16, l2_bytes=262144, l2_latency=40)


@pytest.fixture(scope="module")
def ao_waves():
    """An ambient-occlusion frame of the room: camera and any-hit rays, several wavefronts."""
    scene = load_scene("room")
    be = HarnessBackend()
    res = workloads.run(workloads.setup_for(scene), build(scene.mesh), 24, 24,
                        lambda b, o, d, **k: trace(b, o, d, backend=be, record=True, **k), "ao",
                        ao_rays=2)
    return waves_of(res.batches)


# (rays in flight, pipelines, memory, schedule, replay options)
CASES = {
    "one-kernel, node cache": (64, 1, MemoryModel(), Schedule("one-kernel"), {}),
    "wavefront, free fetches, 2 pipelines": (16, 2, None, Schedule("wavefront"), {}),
    "warps of 8 on 2 units, L1+L2+MSHRs, sectors": (
        64, 1, GPU_MEMORY, Schedule("one-kernel", warp_size=8, rt_units=2), {}),
    "shader cycles, flush between kernels": (
        32, 1, MemoryModel(), Schedule("wavefront", shader_cycles=50, flush_between=True), {}),
    "one ray in flight, turnaround 0": (1, 1, None, Schedule("wavefront"), {"turnaround": 0}),
    "affinity": (16, 1, MemoryModel(), Schedule("one-kernel"),
                 {"order": RayOrder("affinity", 64)}),
    "treelets": (16, 1, MemoryModel(), Schedule("one-kernel"),
                 {"order": RayOrder("treelet", 64)}),
    "hash order": (32, 2, MemoryModel(), Schedule("wavefront"), {"order": RayOrder("hash")}),
    "the RT unit's costs, node cache, stack 4": (
        64, 1, MemoryModel(), Schedule("wavefront"), {"unit_costs": UnitCosts(stack_depth=4)}),
    "the RT unit's costs, fixed latency, one divider, any-hit": (
        32, 1, None, Schedule("one-kernel"),
        {"unit_costs": UnitCosts(dividers=1, fixed_latency=20, any_hit=True)}),
    "the RT unit's costs, 3 pipelines, fixed latency, any-hit": (
        32, 3, None, Schedule("one-kernel"),
        {"unit_costs": UnitCosts(fixed_latency=2, any_hit=True)}),
}


def test_the_unit_costs_need_the_index_order(ao_waves):
    with pytest.raises(ValueError, match="the index ray order"):
        replay_frame(ao_waves, 16, 2, MemoryModel(), Schedule("one-kernel"),
                     unit_costs=UnitCosts(), order=RayOrder("affinity", 64))


@pytest.mark.parametrize("case", sorted(CASES))
def test_timing_replay_equals_the_evaluated_replay(ao_waves, case):
    r, p, memory, schedule, opts = CASES[case]
    rtl = replay_frame(ao_waves, r, p, memory, schedule, width=24, datapath="rtl", **opts)
    timed = replay_frame(ao_waves, r, p, memory, schedule, width=24, datapath="timing", **opts)
    assert rtl.verified and rtl.datapath == "rtl"
    assert timed.datapath == "timing" and timed.verified is None
    assert timed.counters["model_evals"] == 0 < rtl.counters["model_evals"]
    assert timing_differences(rtl, timed) == []
    assert rtl.summary() | {"sim_wall_s": 0, "replay_datapath": "", "responses_verified": 0} \
        == timed.summary() | {"sim_wall_s": 0, "replay_datapath": "", "responses_verified": 0}
    # the functional run's responses; word 0, the tag, names the row of each wave's own ray
    # table there and of the frame's combined table in the replay
    assert np.array_equal(timed.responses[:, 1:], rtl.responses[:, 1:])


def test_timing_differences_names_what_differs(ao_waves):
    a = replay_frame(ao_waves, 64, 1, None, Schedule("one-kernel"), width=24)
    b = replay_frame(ao_waves, 32, 1, None, Schedule("one-kernel"), width=24)
    diff = timing_differences(a, b)
    assert "cycles" in diff and "ray_times" in diff
    assert "datapath" not in diff and "model_evals" not in diff


def test_the_replay_api_and_its_default(ao_waves):
    rec = ao_waves[0].record
    assert rtunit.replay(rec, 16).verified is None                    # timing: nothing compared
    assert rtunit.replay(rec, 16, datapath="rtl").verified is True
    assert rtunit.replay(rec, 16).cycles == rtunit.replay(rec, 16, datapath="rtl").cycles
    with pytest.raises(ValueError, match="replay datapath 'gates'"):
        rtunit.replay(rec, 16, datapath="gates")


def test_the_model_latency_is_measured_on_the_model():
    assert model_latency(PARAMS) == PARAMS["LATENCY"] == 11


@pytest.fixture(scope="module")
def steps():
    """The traversal steps of a bunny frame: (ray table, image, ray, ptr, extent) per call."""
    calls = []

    class Spy(HarnessBackend):
        def run_nodes(self, *a):
            calls.append(a)
            return super().run_nodes(*a)

    scene = load_scene("bunny")
    from driver.scenes.camera import primary_rays
    o, d = primary_rays(scene.camera, 48, 48)
    trace(build(scene.mesh), o, d, backend=Spy(threads=1))
    return calls


@pytest.mark.parametrize("threads", [2, 3, 7])
def test_split_steps_equal_one_model(steps, threads):
    one, many = HarnessBackend(threads=1), HarnessBackend(threads=threads)
    split = 0
    for a in steps:
        assert np.array_equal(one.run_nodes(*a), many.run_nodes(*a))
        split += min(threads, len(a[2]) // harness.SPLIT_MIN_REQUESTS) > 1
    assert split >= 3                   # the frame has steps big enough to split
    assert many.cycles == one.cycles and many.requests == one.requests


def test_patterns_are_never_split(steps):
    a = max(steps, key=lambda s: len(s[2]))
    one = HarnessBackend(threads=1, gaps=0.2, stalls=0.1)
    many = HarnessBackend(threads=4, gaps=0.2, stalls=0.1)
    assert np.array_equal(one.run_nodes(*a), many.run_nodes(*a))
    assert many.cycles == one.cycles > len(a[2]) + 11      # the gaps and stalls cost cycles
    assert many._more == []


def test_threads_from_the_environment(monkeypatch):
    monkeypatch.setenv("RAYFLEX_THREADS", "3")
    assert default_threads() == 3 and HarnessBackend().threads == 3
    monkeypatch.setenv("RAYFLEX_THREADS", "0")
    with pytest.raises(ValueError, match="RAYFLEX_THREADS='0'"):
        default_threads()
    monkeypatch.delenv("RAYFLEX_THREADS")
    assert default_threads() >= 1
    with pytest.raises(ValueError, match="threads must be >= 1"):
        HarnessBackend(threads=0)
