"""RT-unit model (driver.rtunit): replay of recorded ray chains through P Verilated pipelines with
R rays in flight; the "rtl" traversal fast path (requests assembled in the C++ harness)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import driver
from driver import backend, prepare_rays
from driver.bvh4 import build
from driver.backends.harness import build_requests
from driver.core.wire import (pack_requests, pack_responses, ray_words, unpack_requests,
                              unpack_responses)
from driver.tracer import trace
from driver import rtunit
from support import meshes
from support.recording import RecordingBackend

LAT = driver.LATENCY


@pytest.fixture(scope="module")
def scene():
    """A small room with a crate, 300 rays from inside: box and triangle ops, varied chains."""
    rng = np.random.default_rng(5)
    tris = meshes.box_room(2)
    bvh = build(tris)
    o = rng.uniform([-1.5, -0.8, -1.0], [2.5, 1.2, 1.8], (300, 3))
    d = rng.normal(size=(300, 3))
    return bvh, o, d


@pytest.fixture(scope="module")
def wave(scene):
    bvh, o, d = scene
    return trace(bvh, o, d, backend="rtl", record=True)


def test_fast_path_matches_golden_and_generic_requests(scene, wave):
    bvh, o, d = scene
    rec_be = RecordingBackend(backend("golden"))
    gold = trace(bvh, o, d, backend=rec_be, record=True)
    assert np.array_equal(wave.t.view(np.uint32), gold.t.view(np.uint32))
    assert np.array_equal(wave.prim, gold.prim) and gold.hit.sum() > 250
    a, b = wave.record, gold.record
    for f in ("ray", "ptr", "responses"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert np.array_equal(a.extent.view(np.uint32), b.extent.view(np.uint32))
    # the harness assembles exactly the words the generic path packs
    sent = np.concatenate(rec_be.calls)
    words = build_requests(a.params, a.ray_words, a.image, a.ray, a.ptr, a.extent)
    assert np.array_equal(words, pack_requests(sent))
    assert np.array_equal(pack_requests(a.requests()), words)
    assert np.array_equal(wave.step_requests, gold.step_requests)
    assert wave.stats["ops"] == a.ops == len(sent)
    assert a.box_ops == wave.stats["box_ops"]
    # the RTL fast path counts cycles like the generic one: n + latency per step
    assert wave.stats["cycles"] == wave.stats["ops"] + LAT * len(wave.step_requests)


def test_wire_helpers_round_trip(wave):
    rsp = unpack_responses(wave.record.responses)
    assert np.array_equal(pack_responses(rsp), wave.record.responses)
    req = wave.record.requests(np.arange(50))
    # the wire words are the truth (a field such as qnode overlays the box words on the wire)
    assert np.array_equal(pack_requests(unpack_requests(pack_requests(req))), pack_requests(req))


def test_timed_trace_stats(scene):
    bvh, o, d = scene
    res = trace(bvh, o, d, backend="rtl", rays_in_flight=rtunit.DEFAULT_RAYS_IN_FLIGHT)
    s = res.stats
    json.dumps(s)
    assert s["ops"] == s["box_ops"] + s["tri_ops"] == res.record.ops
    assert s["cycles"] >= s["ops"] + s["latency_cycles"]
    assert s["utilization"] == s["ops"] / s["cycles"]
    assert s["frame_us_at_1ghz"] == s["cycles"] / 1000
    assert s["latency_cycles"] == LAT and s["pipelines"] == 1
    assert s["rays_in_flight"] == rtunit.DEFAULT_RAYS_IN_FLIGHT and s["turnaround_cycles"] == 1
    assert s["responses_verified"] is None and s["replay_datapath"] == "timing"
    assert s["wavefront_cycles"] == s["ops"] + LAT * len(res.step_requests)
    assert s["utilization"] > 0.9 and s["per_pipeline_ops"] == [s["ops"]]


def test_one_ray_in_flight_hides_no_latency(wave):
    rec = wave.record
    one = rtunit.replay(rec, 1, 1)
    assert one.cycles >= rec.ops * 11
    assert one.cycles == rec.ops * (LAT + 1)          # response at +11, next request 1 later
    assert one.starved_cycles > rec.ops * 10
    zero = rtunit.replay(rec, 1, 1, turnaround=0)
    assert zero.cycles == rec.ops * LAT + 1            # issued in the cycle of the response
    assert np.array_equal(one.responses, zero.responses)


@pytest.mark.parametrize("pipelines", [1, 2, 4])
def test_latency_and_throughput_bounds(wave, pipelines):
    rec = wave.record
    for r in (2, 8, 64, 1000):
        res = rtunit.replay(rec, r, pipelines)
        s = res.stats()
        assert res.datapath == "timing" and s["ops"] == rec.ops == sum(s["per_pipeline_ops"])
        assert s["cycles"] >= -(-rec.ops // pipelines) + LAT
        # each ray has one request in flight, 12 cycles apart: at most R requests per 12 cycles
        assert s["cycles"] >= rec.ops * (LAT + 1) / r - (LAT + 1)
        assert s["utilization"] == rec.ops / (pipelines * s["cycles"]) <= 1


def test_more_pipelines_same_hits(scene, wave):
    bvh, o, d = scene
    for p in (1, 2, 3, 8):
        res = trace(bvh, o, d, backend="rtl", rays_in_flight=16, pipelines=p)
        assert np.array_equal(res.t.view(np.uint32), wave.t.view(np.uint32))
        assert np.array_equal(res.prim, wave.prim)
        assert res.stats["replay_datapath"] == "timing" and res.stats["pipelines"] == p
        assert res.stats["hits"] == wave.stats["hits"]
        rep = rtunit.replay(res.record, 16, p)
        assert np.array_equal(rep.responses, wave.record.responses)


def test_skip_idle_is_exact(wave):
    for r, p in ((1, 1), (3, 2), (40, 4)):
        a = rtunit.replay(wave.record, r, p, skip_idle=True, datapath="rtl")
        b = rtunit.replay(wave.record, r, p, skip_idle=False, datapath="rtl")
        assert a.cycles == b.cycles and np.array_equal(a.responses, b.responses)
        assert b.model_evals == b.cycles * p             # every model, every cycle
        assert a.model_evals <= b.model_evals


def test_scheduler_exact_cycles():
    """Two rays, chains of 3 and 1 requests, on the root box node of a small BVH."""
    bvh = build(meshes.soup(12))
    rays = prepare_rays([[0, 0, -5], [0.1, 0, -5]], [[0, 0, 1], [0, 0, 1]])
    rec = rtunit.Record(ray_words(rays), bvh.image.view("<u4"),
                        np.array([0, 1, 0, 0], np.uint32), np.full(4, bvh.root, np.uint32),
                        np.full(4, np.inf, np.float32), None, driver.backends.build.rtl_params(0, 0, LAT))
    # R=2, P=1: r0 at 0, r1 at 1; r0 again at 12 and 24 -> last response at 35
    assert rtunit.replay(rec, 2, 1).cycles == 36
    assert rtunit.replay(rec, 2, 1, turnaround=0).cycles == 34
    assert rtunit.replay(rec, 2, 2).cycles == 36
    assert rtunit.replay(rec, 1, 1).cycles == 48            # 4 requests, 12 cycles each
    res = rtunit.replay(rec, 2, 2)
    assert res.per_pipeline == [3, 1] and not res.verified
    assert np.array_equal(res.responses[:, 0], [0, 1, 0, 0])          # tags = rays


def test_replay_detects_mismatch_and_bad_input(wave):
    rec = wave.record
    bad = rtunit.Record(rec.ray_words, rec.image, rec.ray, rec.ptr, rec.extent,
                        rec.responses.copy(), rec.params)
    bad.responses[7, 6] ^= 1
    with pytest.raises(rtunit.ReplayMismatch):
        rtunit.replay(bad, 8, datapath="rtl")
    assert rtunit.replay(bad, 8).verified is None      # the timing replay compares nothing
    with pytest.raises(ValueError):
        rtunit.replay(rec, 0)
    with pytest.raises(ValueError):
        rtunit.replay(rec, 4, 0)
    with pytest.raises(ValueError):
        rtunit.replay(rec, 4, turnaround=-1)
    broken = rtunit.Record(rec.ray_words, rec.image, rec.ray, rec.ptr.copy(), rec.extent,
                           None, rec.params)
    broken.ptr[3] = 0xFFFFFFF8 | 5                   # a box pointer far outside the image
    with pytest.raises(ValueError):
        rtunit.replay(broken, 8)


def test_golden_backend_with_rt_unit(scene, wave):
    bvh, o, d = scene
    res = trace(bvh, o[:50], d[:50], backend="golden", rays_in_flight=4, pipelines=2,
                datapath="rtl")            # the golden model's responses checked on the RTL
    assert res.stats["backend"] == "golden" and res.stats["responses_verified"]
    assert np.array_equal(res.prim, wave.prim[:50])


def test_empty_trace_with_rt_unit(scene):
    bvh = scene[0]
    res = trace(bvh, np.zeros((0, 3)), np.zeros((0, 3)), backend="rtl", rays_in_flight=8)
    assert res.stats["ops"] == 0 and res.stats["cycles"] == 0


def test_sweep_and_plot(wave, tmp_path):
    pts = rtunit.sweep(wave.record, (1, 4, 32), (1, 2))
    assert [(p["pipelines"], p["rays_in_flight"]) for p in pts] == [
        (1, 1), (1, 4), (1, 32), (2, 1), (2, 4), (2, 32)]
    cyc = {(p["pipelines"], p["rays_in_flight"]): p["cycles"] for p in pts}
    assert cyc[1, 1] == cyc[2, 1] > cyc[1, 4] > cyc[1, 32]
    assert cyc[2, 32] < cyc[1, 32]
    par = rtunit.sweep(wave.record, (1, 4, 32), (1, 2), workers=2)
    assert [p["cycles"] for p in par] == [p["cycles"] for p in pts]
    png = tmp_path / "sweep.png"
    rtunit.plot_sweep(pts, png, "test")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
