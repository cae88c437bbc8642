"""The RT unit in RTL with several datapath pipelines (``PIPELINES``, ``--pipelines`` with
``--backend rtunit``; rtl/rf_rtu_pipes.sv): every ray's hit, primitive, t bits and op counts
identical to the Python traversal on the "rtl" datapath with two pipelines, closest and any-hit;
fewer cycles than one pipeline on a frame that keeps the datapath busy, each pipeline taking
requests; the replay with the unit's costs counting the same cycles; lint; bad pipeline counts
refused in one line before any build; docs/rtunit_rtl.md's measured table."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from driver.backends import BackendError, backend
from driver.backends.build import rtl_params
from driver.backends.rtunit import RtUnitBackend, lint_unit, unit_params
from driver.bvh.instances import build_two_level
from driver.cli import main
from driver.tracer import as_bvh, trace
from support.corpus import rays as corpus_rays
from support.meshes import box_room, instance_rays, small_instances, soup
from support.prebuild import SUITE_DEPTH, SUITE_RAYS

RAYS, DEPTH = SUITE_RAYS, SUITE_DEPTH    # the suite's unit (tests/support/prebuild.py), and :2
FAST = 2                    # fixed memory latency: the datapath, not the memory, decides


@pytest.fixture(scope="module")
def scene():
    tris = soup(200, 1)
    o, d = corpus_rays(tris, 256, 3)            # 16 x 16 rays aimed at the soup
    return as_bvh(tris), o, d


@pytest.fixture(scope="module")
def units():
    return {p: RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEPTH, mem_latency=FAST,
                             pipelines=p) for p in (1, 2)}


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_two_pipelines_match_the_traversal(scene, units, any_hit):
    bvh, o, d = scene
    ref = trace(bvh, o, d, backend="rtl", any_hit=any_hit)
    got = trace(bvh, o, d, backend=units[2], any_hit=any_hit)
    assert ref.hit.sum() > 20
    assert got.hit.tolist() == ref.hit.tolist()
    assert got.prim.tolist() == ref.prim.tolist()
    assert got.t.view(np.uint32).tolist() == ref.t.view(np.uint32).tolist()
    assert got.box_ops.tolist() == ref.box_ops.tolist()
    assert got.tri_ops.tolist() == ref.tri_ops.tolist()
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0
    assert unit["pipelines"] == 2 and len(unit["pipeline_requests"]) == 2
    assert sum(unit["pipeline_requests"]) == int(ref.box_ops.sum() + ref.tri_ops.sum())
    assert min(unit["pipeline_requests"]) > 0            # both pipelines took requests
    assert unit["utilization"] == pytest.approx(
        sum(unit["pipeline_requests"]) / (2 * unit["cycles"]))
    # the replay with the unit's costs on the same two pipelines counts the unit's cycles
    assert unit["replay_cycles_ratio"] == 1.0


def test_two_pipelines_take_fewer_cycles_on_a_busy_datapath(scene, units):
    bvh, o, d = scene
    one, two = (trace(bvh, o, d, backend=units[p]).stats["unit_rtl"] for p in (1, 2))
    assert one["pipeline_requests"] == [sum(two["pipeline_requests"])]   # the same requests
    assert one["utilization"] > 0.5                   # one pipeline is kept busy
    assert two["cycles"] < 0.95 * one["cycles"]
    assert one["replay_cycles_ratio"] == 1.0 and two["replay_cycles_ratio"] == 1.0


@pytest.mark.slow    # its own build (rtunit:baseline-unified-q8-xf:8:4:2), not in the suite's
@pytest.mark.parametrize("frame", ["instanced", "q8"])
def test_two_pipelines_on_instanced_and_q8_frames(frame):
    """Two pipelines with the q8 decode stage and TRANSFORM (a small stack: it spills): an
    instanced frame (a two-level q8 image, rays entering their BLAS through TRANSFORM, whose
    responses share the ray-setup port) and a q8 frame with pair leaves, every ray equal to the
    "rtl" traversal, both pipelines used, and the replay with the unit's costs on the same two
    pipelines counting the unit's cycles."""
    unit = RtUnitBackend(rays_in_flight=8, stack_depth=4, mem_latency=FAST, compressed=True,
                         transform=True, pipelines=2)
    if frame == "instanced":
        bvh = build_two_level(small_instances(), "q8")
        o, d = instance_rays()
        ref = trace(bvh, o, d, backend=backend("rtl", compressed=True, transform=True),
                    transform="datapath")
    else:
        tris = np.concatenate([box_room(4), soup(100, 4)])  # quads (pair leaves) and triangles
        o, d = corpus_rays(tris, 256, 5)
        bvh = as_bvh(tris, "q8")
        ref = trace(bvh, o, d, backend=backend("rtl", compressed=True))
    got = trace(bvh, o, d, backend=unit)
    assert ref.hit.sum() > 20
    fields = ["hit", "prim", "box_ops", "tri_ops"]
    if frame == "instanced":
        fields += ["instance", "transform_ops"]
    for field in fields:
        assert getattr(got, field).tolist() == getattr(ref, field).tolist(), field
    assert got.t.view(np.uint32).tolist() == ref.t.view(np.uint32).tolist()
    assert got.stats["ops"] == ref.stats["ops"]
    u = got.stats["unit_rtl"]
    assert u["traversal_mismatches"] == 0 and u["stack_overflows"] > 0
    requests = sum(int(getattr(got, f).sum()) for f in fields[2:] if "ops" in f)
    assert sum(u["pipeline_requests"]) == requests and min(u["pipeline_requests"]) > 0
    if frame == "instanced":
        assert (got.transform_ops > 1).sum() >= 20 and u["setup_busy_cycles"] > 0
    assert u["replay_cycles"] == u["cycles"]


def test_pipelines_lint_clean():
    for p in (2, 4):
        assert lint_unit(unit_params(rtl_params(False, False), 4, 4, pipelines=p)) == ""
    assert lint_unit(unit_params(rtl_params(False, False, compressed=True, transform=True), 4,
                                 4, pipelines=3)) == ""


def test_bad_pipeline_counts_are_refused_before_any_build(in_tmp, error_line):
    for bad in (0, 5, True, 1.5):
        with pytest.raises(BackendError, match="--pipelines"):
            RtUnitBackend(rays_in_flight=RAYS, pipelines=bad)
    assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--pipelines",
                 "5"]) != 0
    assert "--pipelines 5" in error_line()
    assert main(["render", "bunny", "--size", "8", "--rtunit", "--unit-costs", "rtl",
                 "--pipelines", "5"]) != 0
    assert "--unit-costs rtl" in error_line()


def test_the_rt_unit_page_quotes_its_pipeline_runs():
    """docs/rtunit_rtl.md's table of the unit with 1, 2 and 4 pipelines is
    tools/unit_pipelines.py's table of docs/rtunit_pipelines.json, and that JSON holds what the
    page says of it: every ray equal to the traversal, the replay within 0.2 %, the bunny's
    fixed-latency frame at the pop port's ceiling with two pipelines."""
    root = Path(__file__).resolve().parent.parent
    spec = importlib.util.spec_from_file_location("unit_pipelines",
                                                  root / "tools" / "unit_pipelines.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    rows = json.loads((root / "docs" / "rtunit_pipelines.json").read_text())["runs"]
    assert {(r["frame"], r["pipelines"]) for r in rows} == {
        (f, p) for f in tool.FRAMES for p in (1, 2, 4)}
    assert tool.table(rows) in (root / "docs" / "rtunit_rtl.md").read_text()
    for r in rows:
        assert r["mismatches"] == 0 and abs(r["ratio"] - 1) < 0.002
        assert len(r["pipeline_utilization"]) == r["pipelines"]
    pops = {r["pipelines"]: r for r in rows if r["frame"] == "bunny-64-fixed"}
    assert pops[2]["cycles"] - (pops[2]["ops"] + pops[2]["rays"]) < 10 and \
        pops[4]["cycles"] == pops[2]["cycles"]
