"""The RT unit in RTL (rtl/rf_rtunit.sv, ``--backend rtunit``): every ray's hit, primitive, t bits
and box/triangle op counts identical to the Python traversal on the "rtl" datapath, at a stack
depth that never overflows and at one that spills; instanced scenes (two-level images) entered
through the datapath's TRANSFORM, instance and transform ops included; a one-ray frame's cycles
counted by hand; the distance-culled stack (``--cull-stack``, CULL) against the Python traversal's
``cull``, culled counts per ray included, at a stack depth that spills; its package constants
against driver/core/layout.py; lint; bad input refused in one line before any work; a corrupt image that gets past the host's check stopped by the harness,
the unit or the cycle budget."""

from __future__ import annotations

import re

import numpy as np
import pytest

from driver.backends import BackendError, backend
from driver.backends.build import RTL_DIR, rtl_params
from driver.backends.rtunit import RtUnitBackend, check_image, lint_unit, unit_params
from driver.bvh.instances import build_two_level
from driver.check import check, failed
from driver.backends.rtunit import div_cycles as driver_div_cycles
from driver.cli import main
from driver.core import layout, wire
from driver.core.datapath import prepare_rays
from driver.core.wire import FLAG_NO_CULL
from driver.instances import Instances
from driver.rtunit import MemoryModel, UnitCosts
from driver.tracer import as_bvh, trace
from driver.tracing.issue import issuer
from driver.traversal import traverse
from support.corpus import rays as corpus_rays
from support.meshes import box_room, instance_rays, reuse_glb, small_instances, soup
from support.prebuild import SUITE_DEPTH, SUITE_RAYS

# the suite's unit (tests/support/prebuild.py), and one with stacks of 4, the q8 decode and TRANSFORM
# (and that one with the culling stack)
RAYS, DEEP, SHALLOW = SUITE_RAYS, SUITE_DEPTH, 4


@pytest.fixture(scope="module")
def scene():
    tris = soup(200, 1)
    o, d = corpus_rays(tris, 256, 3)            # 16 x 16 rays aimed at the soup
    return as_bvh(tris), o, d


@pytest.fixture(scope="module")
def culling():
    """``shallow`` with the distance-culled stack (CULL): the suite's one culling build."""
    return RtUnitBackend(rays_in_flight=RAYS, stack_depth=SHALLOW, mem_latency=20,
                         compressed=True, transform=True, cull=True)


@pytest.fixture(scope="module")
def deep():
    return RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEEP, mem_latency=20)


@pytest.fixture(scope="module")
def shallow():
    """A small stack, the datapath's q8 decode stage and its TRANSFORM (it reads box32 and
    one-level images too)."""
    return RtUnitBackend(rays_in_flight=RAYS, stack_depth=SHALLOW, mem_latency=20,
                         compressed=True, transform=True)


def _rtl_xf():
    """The "rtl" datapath with the q8 decode and TRANSFORM (``shallow``'s), the reference."""
    return backend("rtl", compressed=True, transform=True)


def _same(ref, got, ops=True):
    assert got.hit.tolist() == ref.hit.tolist()
    assert got.prim.tolist() == ref.prim.tolist()
    assert got.t.view(np.uint32).tolist() == ref.t.view(np.uint32).tolist()
    if ops:
        assert got.box_ops.tolist() == ref.box_ops.tolist()
        assert got.tri_ops.tolist() == ref.tri_ops.tolist()


@pytest.mark.parametrize("any_hit,double_sided", [(False, False), (True, False), (False, True),
                                                  (True, True)],
                         ids=["closest", "any-hit", "closest-no-cull", "any-hit-no-cull"])
def test_unit_matches_the_traversal_on_the_rtl_datapath(scene, deep, any_hit, double_sided):
    bvh, o, d = scene
    ref = trace(bvh, o, d, backend="rtl", any_hit=any_hit, double_sided=double_sided)
    got = trace(bvh, o, d, backend=deep, any_hit=any_hit, double_sided=double_sided)
    assert ref.hit.sum() > 20
    _same(ref, got)
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["stack_overflows"] == 0
    assert 0 < unit["max_stack_depth"] <= DEEP
    # the replay with the unit's costs, on its fixed-latency memory, within 3 % of the unit;
    # the default replay has no fixed-latency memory
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03
    assert unit["replay_default_cycles"] is None
    assert got.stats["ops"] == ref.stats["ops"] and unit["cycles"] == got.stats["cycles"] > 0


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_a_small_stack_spills_and_keeps_every_hit_and_op(scene, deep, shallow, any_hit):
    bvh, o, d = scene
    ref = trace(bvh, o, d, backend=deep, any_hit=any_hit)
    got = trace(bvh, o, d, backend=shallow, any_hit=any_hit)
    _same(ref, got)
    unit = got.stats["unit_rtl"]
    assert unit["stack_overflows"] > 0 and unit["max_stack_depth"] == SHALLOW
    assert 0 < unit["stack_refills"] <= unit["stack_overflows"]
    if not any_hit:             # every spilled entry is read back unless the ray ends early
        assert unit["stack_refills"] == unit["stack_overflows"]
    assert unit["cycles"] > ref.stats["unit_rtl"]["cycles"]
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03      # the spills and refills charged


def test_the_replay_is_compared_behind_the_memory_hierarchy(scene):
    bvh, o, d = scene
    memory = MemoryModel(cache_bytes=4096, latency_cycles=50)
    be = RtUnitBackend(rays_in_flight=RAYS, stack_depth=DEEP, memory=memory.config())
    got = trace(bvh, o, d, backend=be)
    unit = got.stats["unit_rtl"]
    assert unit["memory"] == "hierarchy" and unit["traversal_mismatches"] == 0
    replayed = trace(bvh, o, d, backend="rtl", rays_in_flight=RAYS, memory=memory)
    assert unit["replay_default_cycles"] == replayed.stats["cycles"] > 0
    assert unit["replay_default_cycles_ratio"] == unit["replay_default_cycles"] / unit["cycles"]
    costs = UnitCosts(stack_depth=DEEP)
    charged = trace(bvh, o, d, backend="rtl", rays_in_flight=RAYS, memory=memory,
                    unit_costs=costs)
    assert unit["replay_cycles"] == charged.stats["cycles"] > replayed.stats["cycles"]
    assert unit["replay_cycles_ratio"] == unit["replay_cycles"] / unit["cycles"]
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_q8_images_with_the_decode_stage(shallow, any_hit):
    tris = np.concatenate([box_room(4), soup(100, 4)])  # quads (pair leaves) and loose triangles
    o, d = corpus_rays(tris, 256, 5)
    bvh = as_bvh(tris, "q8")
    assert bvh.stats["pair_ratio"] > 0.5                # pair leaves with two triangles
    ref = trace(bvh, o, d, backend=backend("rtl", compressed=True), any_hit=any_hit)
    got = trace(bvh, o, d, backend=shallow, any_hit=any_hit)
    assert ref.hit.sum() > 20
    _same(ref, got)
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["stack_overflows"] > 0
    # a pair's second triangle is read from the leaf the ray fetched for its first
    assert unit["mem_requests"] < got.stats["ops"]


@pytest.mark.parametrize("fmt", ["box32", "q8"])
@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_instances_enter_their_blas_through_the_transform(shallow, fmt, any_hit):
    inst = small_instances()
    bvh = build_two_level(inst, fmt)
    o, d = instance_rays()
    ref = trace(bvh, o, d, backend=_rtl_xf(), transform="datapath", any_hit=any_hit)
    got = trace(bvh, o, d, backend=shallow, any_hit=any_hit)
    assert ref.hit.sum() > 50 and set(ref.instance[ref.hit]) == set(range(5))
    _same(ref, got)
    assert got.instance.tolist() == ref.instance.tolist()
    assert got.transform_ops.tolist() == ref.transform_ops.tolist()
    # rays that enter several instances (fewer when the first hit ends the ray)
    assert (got.transform_ops > 1).sum() >= (3 if any_hit else 20)
    assert got.stats["transform_ops"] == ref.stats["transform_ops"]
    assert got.stats["ops"] == ref.stats["ops"]
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["stack_overflows"] > 0
    assert unit["setups"] == 2 and unit["setup_busy_cycles"] > 0
    # the replay with the unit's costs charges the return marker's pop and the ray setup
    assert unit["replay_cycles"] == unit["cycles"]
    if not any_hit:
        emb = check(inst.flatten(), o, d, got.t, got.prim)
        assert not failed(emb) and emb["hit_mismatch"] == 0


def _with_a_skipped_instance(n: int):
    """The small instanced scene with a sixth instance scaled by 1e-20 at (0, 5, 0), and n
    instance rays after two whose transformed ray overflows float32 in it: (bvh, o, d)."""
    base = small_instances()
    tiny = np.hstack([np.diag([1e-20] * 3), [[0.0], [5.0], [0.0]]])
    inst = Instances(base.meshes, np.append(base.mesh, 0),
                     np.concatenate([base.object_to_world, tiny[None]]))
    o, d = instance_rays(n)
    o = np.concatenate([[[0, 5, -2e-20], [0, 5, -2e-20]], o]).astype(np.float32)
    d = np.concatenate([[[0, 0, 1e19], [0, -1e19, 1e18]], d]).astype(np.float32)
    return build_two_level(inst), o, d


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_an_instance_whose_transformed_ray_overflows_is_skipped(shallow, any_hit):
    # a sixth instance scaled by 1e-20 at (0, 5, 0): its world_to_object (1e20) takes these
    # rays' long directions past the float32 range, so they skip it; the second then hits
    # instance 2
    bvh, o, d = _with_a_skipped_instance(32)
    ref = trace(bvh, o, d, backend=_rtl_xf(), transform="datapath", any_hit=any_hit)
    got = trace(bvh, o, d, backend=shallow, any_hit=any_hit)
    assert ref.transform_ops[:2].tolist() == [1, 2] and ref.instance[:2].tolist() == [-1, 2]
    _same(ref, got)
    assert got.instance.tolist() == ref.instance.tolist()
    assert got.transform_ops.tolist() == ref.transform_ops.tolist()
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["replay_cycles"] == unit["cycles"]


def test_instances_keep_no_cull_in_object_space(shallow):
    # rays from inside the instances: only back faces lie ahead, hit with NO_CULL alone
    rng = np.random.default_rng(1)
    o = np.column_stack([rng.integers(0, 5, 64) * 0.8 - 1.6, np.zeros(64), np.zeros(64)])
    o, d = o.astype(np.float32), rng.normal(size=(64, 3)).astype(np.float32)
    bvh = build_two_level(small_instances(), "q8")
    ref = trace(bvh, o, d, backend=_rtl_xf(), transform="datapath", double_sided=True)
    got = trace(bvh, o, d, backend=shallow, double_sided=True)
    culled = trace(bvh, o, d, backend=shallow)
    assert ref.hit.all() and culled.hit.sum() < len(o) // 2
    _same(ref, got)
    assert got.instance.tolist() == ref.instance.tolist()
    assert got.stats["unit_rtl"]["traversal_mismatches"] == 0


def test_instances_need_the_transform(deep):
    bvh = build_two_level(small_instances())
    o, d = instance_rays(8)
    for be in (deep, backend("rtunit", rays_in_flight=RAYS)):
        with pytest.raises(ValueError, match="give --transform datapath"):
            trace(bvh, o, d, backend=be)
    with pytest.raises(ValueError, match="TRANSFORM"):
        check_image(bvh, compressed=True)


def test_one_ray_frame_cycles_by_hand(deep):
    # one triangle: a root box node with one child, the triangle node; the ray hits it (NO_CULL)
    bvh, rays = _one_triangle()
    res = deep.trace_unit(bvh, rays)
    ref = trace(bvh, [[0.2, 0.2, 0]], [[0, 0, 1]], backend="rtl", double_sided=True)
    assert res.hit[0] and res.prim[0] == 0 and res.t.view(np.uint32)[0] == ref.t.view(np.uint32)[0]
    mem, dp, div = deep.mem_latency, deep.latency, div_cycles()
    # cycle 0 the ray is taken; per node: pop (1), fetch request registered (1), memory (mem),
    # issue (1), datapath (dp), response (the box's push / the triangle's hit to the divider);
    # then the divider (DIV_CYCLES), the empty stack's pop (1), the result register (1), taken (1)
    per_node = 1 + 1 + mem + 1 + dp
    assert res.stats["cycles"] == 1 + 2 * per_node + div + 1 + 1 + 1
    # while the ray waits for a node, the harness counts the cycles without clocking the unit:
    # from the cycle after the request's handshake to the cycle before the response
    assert res.stats["skipped_cycles"] == 2 * (mem - 2)
    # busy from the cycle after its handshake to the cycle its result is taken (at once)
    assert res.stats["divider_busy_cycles"] == div
    assert (res.box_ops[0], res.tri_ops[0]) == (1, 1)
    # the replay with the unit's costs counts the same cycles; an any-hit ray ends at its hit,
    # without the last pop
    for any_hit, cycles in ((False, 1 + 2 * per_node + div + 3), (True, 1 + 2 * per_node + div + 2)):
        got = trace(bvh, [[0.2, 0.2, 0]], [[0, 0, 1]], backend=deep, double_sided=True,
                    any_hit=any_hit)
        assert got.stats["unit_rtl"]["cycles"] == got.stats["unit_rtl"]["replay_cycles"] == cycles


def div_cycles() -> int:
    """rf_fp_div_pkg::DIV_CYCLES: quotient bits / digit bits + 2."""
    text = (RTL_DIR / "rf_fp_div_pkg.sv").read_text()
    value = {m[1]: int(m[2]) for m in re.finditer(r"(DIV_\w+)\s*=\s*(\d+);", text)}
    assert re.search(r"DIV_CYCLES\s*=\s*DIV_ITER_CYCLES \+ 2;", text)
    assert re.search(r"DIV_ITER_CYCLES\s*=\s*DIV_QUOTIENT_BITS / DIV_DIGIT_BITS;", text)
    cycles = value["DIV_QUOTIENT_BITS"] // value["DIV_DIGIT_BITS"] + 2
    assert cycles == driver_div_cycles()      # what the replay's unit costs read
    return cycles


def test_package_constants_are_the_layout():
    text = (RTL_DIR / "rf_rtu_pkg.sv").read_text()
    found = {}
    for m in re.finditer(r"localparam\s+(?:int unsigned|logic \[\d+:0\])\s+(\w+)\s*=\s*"
                         r"(?:\d+'([dh]))?([0-9A-Fa-f_]+);", text):
        found[m[1]] = int(m[3].replace("_", ""), 16 if m[2] == "h" else 10)
    box, tri, req = layout.BOX_NODE, layout.TRI_NODE, wire.REQUEST.field
    expect = {
        "PTR_SHIFT": 3, "BOX_TYPE": layout.BOX_TYPE, "TRI_TYPE": layout.TRI_TYPE,
        "NO_CHILD": layout.NO_CHILD,
        "BOX_NODE_WORDS": box.itemsize // 4, "BOX_NODE_CHILD_WORD": layout.node_word(box, "child"),
        "BOX_NODE_BOX_WORD": layout.node_word(box, "box"), "TRI_NODE_WORDS": tri.itemsize // 4,
        "TRI_NODE_TRI_WORD": layout.node_word(tri, "tri"),
        "TRI_NODE_PRIM_WORD": layout.node_word(tri, "prim"), "RAY_WORDS": wire.RAY_WORDS,
        "REQ_EXTENT_WORD": req["extent"].word, "REQ_BOX_WORD": req["box"].word,
        "REQ_TRI_WORD": req["tri"].word,
    }
    assert {k: found.get(k) for k in expect} == expect
    assert layout.NodeRef.offset(np.uint32(8 | layout.BOX_TYPE)) == 8 << found["PTR_SHIFT"]


def test_unit_lint_clean():
    assert lint_unit(unit_params(rtl_params(False, False), RAYS, DEEP)) == ""
    assert lint_unit(unit_params(rtl_params(False, False, compressed=True, transform=True), RAYS,
                                 SHALLOW)) == ""
    # the culling stack, with two pipelines (two push ports carrying distances)
    assert lint_unit(unit_params(rtl_params(False, False), RAYS, SHALLOW, pipelines=2,
                                 cull=True)) == ""


def test_unit_refuses_what_it_cannot_read(scene, deep):
    bvh, o, d = scene
    q8 = as_bvh(soup(50, 2), "q8")
    with pytest.raises(ValueError, match="q8 nodes with the datapath's decode stage"):
        trace(q8, o[:4], d[:4], backend=deep)
    with pytest.raises(ValueError, match="reads box32, q8 images, not q8g"):
        trace(as_bvh(soup(50, 2), "q8g"), o[:4], d[:4], backend=deep)
    with pytest.raises(ValueError, match="only when built with CULL"):
        trace(bvh, o[:4], d[:4], backend=deep, cull_stack=True)
    with pytest.raises(ValueError, match="times the frame itself"):
        trace(bvh, o[:4], d[:4], backend=deep, rays_in_flight=8)
    for rays, depth in ((0, 8), (300, 8), (8, 1)):
        with pytest.raises(BackendError, match="is built with"):
            unit_params(rtl_params(False, False), rays, depth)


def test_a_corrupt_image_is_refused_before_the_run(scene, deep):
    bvh, o, d = scene
    import copy
    bad = copy.copy(bvh)
    img = np.array(bvh.image, copy=True).reshape(-1).view("<u4")
    root_word = int(layout.NodeRef.word(np.uint32(bvh.root)))
    img[root_word] = np.uint32((len(img) * 4 + 64) >> 3 | layout.TRI_TYPE)   # past the end
    bad.image = img.view(np.uint8)
    with pytest.raises(ValueError, match="leaves the image"):
        deep.trace_unit(bad, prepare_rays(o[:4], d[:4]))
    img[root_word] = np.uint32(bvh.root)                                      # a loop
    bad.image = img.view(np.uint8)
    with pytest.raises(ValueError, match="loop"):
        deep.trace_unit(bad, prepare_rays(o[:4], d[:4]))


def test_a_node_type_the_unit_cannot_read_is_refused_before_the_run(scene, deep):
    bvh, o, d = scene
    import copy
    bad = copy.copy(bvh)
    img = np.array(bvh.image, copy=True).reshape(-1).view("<u4")
    root_word = int(layout.NodeRef.word(np.uint32(bvh.root)))
    img[root_word] = layout.NodeRef.retype(img[root_word], layout.GROUP_TYPE)   # a q8g leaf
    bad.image = img.view(np.uint8)
    with pytest.raises(ValueError, match="names a node type the RT unit cannot read"):
        deep.trace_unit(bad, prepare_rays(o[:4], d[:4]))


def _one_triangle():
    """A root box node whose one child is a triangle node, and a ray that hits the triangle."""
    bvh = as_bvh(np.array([[[0, 0, 5], [1, 0, 5], [0, 1, 5]]], np.float32))
    return bvh, prepare_rays([[0.2, 0.2, 0]], [[0, 0, 1]], flags=FLAG_NO_CULL)


@pytest.mark.parametrize("corrupt", ["past the end", "node type", "loop"])
def test_the_unit_stops_on_a_corrupt_image_the_host_let_through(deep, monkeypatch, corrupt):
    # the host's check (check_image) bypassed: the harness and the unit stop the run themselves,
    # in one line: a loop once the rays have made more requests than the image has nodes for
    import copy
    from driver.backends import rtunit
    bvh, rays = _one_triangle()
    assert deep.trace_unit(bvh, rays).hit[0]
    monkeypatch.setattr(rtunit, "check_image", lambda *a, **k: None)
    img = np.array(bvh.image, copy=True).reshape(-1).view("<u4")
    child = int(layout.NodeRef.word(np.uint32(bvh.root)))        # the root's child 0: the hit one
    img[child] = {"past the end": np.uint32((len(img) * 4 + 64) >> 3 | layout.TRI_TYPE),
                  "node type": layout.NodeRef.retype(img[child], layout.GROUP_TYPE),
                  "loop": np.uint32(bvh.root)}[corrupt]
    bad = copy.copy(bvh)
    bad.image = img.view(np.uint8)
    expect = {"past the end": (ValueError, "leaves the image .the unit fetched past it"),
              "node type": (ValueError, "ray 0 met a node pointer the RT unit cannot read"),
              "loop": (ValueError, r"requests for 1 rays, more than this image has nodes for "
                                   r"\(\d+\): its pointers loop")}
    error, message = expect[corrupt]
    with pytest.raises(error, match=message) as info:
        deep.trace_unit(bad, rays)
    assert "\n" not in str(info.value)


def test_what_the_unit_cannot_build_or_read_is_refused_before_any_work(in_tmp, error_line, monkeypatch):
    from driver.backends import harness, rtunit
    from driver.design import DesignPoint

    def long_work(*args, **kwargs):
        raise AssertionError("long work before the options were checked")
    monkeypatch.setattr(harness, "harness_library", long_work)     # the datapath's build
    monkeypatch.setattr(rtunit, "unit_library", long_work)         # the unit's build
    monkeypatch.setattr(DesignPoint, "build", long_work)           # the BVH build
    for rays in (0, 257):
        with pytest.raises(BackendError, match=f"--rays-in-flight {rays}: .* built with 1..256"):
            backend("rtunit", rays_in_flight=rays)
    for workers in ("1", "2"):
        assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--rays-in-flight",
                     "300", "--workers", workers, "--no-progress"]) == 2
        assert "--rays-in-flight 300: the RT unit in RTL is built with 1..256" in error_line()
        # a node format it cannot read
        for fmt, message in (("q8g", "reads box32, q8 images, not q8g"),
                             ("q8", "q8 nodes with the datapath's decode stage")):
            assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--bvh-format",
                         fmt, "--workers", workers, "--no-progress"]) == 2
            assert message in error_line()
    assert not list(in_tmp.iterdir())                                # nothing written


def test_a_run_stops_at_its_cycle_budget(scene, deep):
    bvh, o, d = scene
    with pytest.raises(RuntimeError, match="within its budget of 50 cycles"):
        deep.trace_unit(bvh, prepare_rays(o[:4], d[:4]), max_cycles=50)


def test_render_replays_with_the_unit_costs(in_tmp, error_line):
    import json
    for costs in ("replay", "rtl"):
        assert main(["render", "bunny", "--size", "8", "--rtunit", "--unit-costs", costs,
                     "--json", f"{costs}.json", "--no-progress"]) == 0
    got = {c: json.loads(open(f"{c}.json").read())["rtunit_memory"] for c in ("replay", "rtl")}
    assert got["replay"]["unit_costs"] == "replay" and got["rtl"]["unit_costs"] == "rtl"
    assert got["rtl"]["ops"] == got["replay"]["ops"]
    assert got["rtl"]["cycles"] > got["replay"]["cycles"]       # the unit's costs are higher
    assert main(["render", "bunny", "--size", "8", "--rtunit", "--unit-costs", "rtl",
                 "--pipelines", "5"]) != 0
    assert "--unit-costs rtl" in error_line()


def test_stack_depth_needs_the_unit(in_tmp, error_line):
    assert main(["render", "bunny", "--size", "8", "--stack-depth", "8"]) != 0
    assert "--backend rtunit" in error_line()
    assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--pipelines", "5"]) != 0
    assert "--pipelines" in error_line()
    assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--rays-in-flight",
                 "8", "--bvh-format", "q8g"]) != 0
    assert "not q8g" in error_line()
    assert main(["render", "bunny", "--size", "8", "--backend", "rtunit", "--rays-in-flight",
                 "8", "--stack-depth", "1"]) != 0
    assert "--stack-depth" in error_line()


def test_unit_check_none_runs_the_unit_alone(in_tmp, error_line, monkeypatch):
    """--unit-check none: the unit's frame without the Python traversal and the replays (their
    figures null), the same cycles and hits; tiles on two threads, each with its own unit, give
    the frame of one thread."""
    import json
    argv = ["render", "cornell", "--workload", "ao", "--size", "8", "--tile", "4", "--backend",
            "rtunit", "--rays-in-flight", str(RAYS), "--check-embree", "--no-progress"]
    docs = {}
    for check, threads in (("traversal", "1"), ("none", "1"), ("none", "2")):
        monkeypatch.setenv("RAYFLEX_THREADS", threads)
        out = f"{check}{threads}.json"
        assert main([*argv, "--unit-check", check, "--json", out]) == 0
        docs[check, threads] = json.loads(open(out).read())
    ref = docs["traversal", "1"]
    assert ref["unit_rtl"]["traversal_mismatches"] == 0
    assert 0 < ref["unit_rtl"]["skipped_cycles"] < ref["unit_rtl"]["cycles"]
    for key in (("none", "1"), ("none", "2")):
        doc = docs[key]
        unit = doc["unit_rtl"]
        assert unit["traversal_mismatches"] is None and unit["replay_cycles_ratio"] is None
        assert {k: v for k, v in unit.items() if "replay" not in k and "traversal" not in k} \
            == {k: v for k, v in ref["unit_rtl"].items() if "replay" not in k
                and "traversal" not in k}
        assert doc["embree"]["adjudicated"]["classes"] == ref["embree"]["adjudicated"]["classes"]
        assert doc["provenance"]["design_point"]["unit_check"] == "none"
    for command in ("render", "sweep"):
        assert main([command, "--size", "8", "--unit-check", "none"]) != 0
        assert "--backend rtunit" in error_line()


def test_render_an_instanced_scene(in_tmp, error_line):
    import json
    glb = str(reuse_glb(in_tmp / "reuse.glb"))         # three instances of one icosphere
    argv = ["render", glb, "--size", "16", "--backend", "rtunit", "--rays-in-flight", str(RAYS),
            "--no-progress"]
    assert main(argv) != 0 and "--transform datapath" in error_line()
    # the build of ``shallow``: the q8 decode stage and TRANSFORM
    assert main([*argv, "--transform", "datapath", "--config", "baseline-unified-q8",
                 "--stack-depth", str(SHALLOW), "--check-embree", "--json", "f.json"]) == 0
    doc = json.loads(open("f.json").read())
    assert doc["instances"] == 3 and doc["transform_ops"] > 0
    assert doc["unit_rtl"]["traversal_mismatches"] == 0
    assert doc["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
    assert doc["unit_rtl"]["replay_cycles"] == doc["unit_rtl"]["cycles"]


def test_a_lumibench_suite_through_the_unit(tmp_path, in_tmp, error_line, monkeypatch):
    import json
    from test_lumibench_scenes import suite_root
    monkeypatch.setenv("RAYFLEX_SCENE_CACHE", str(tmp_path / "cache"))
    root = suite_root(tmp_path / "lumi")
    argv = ["suite", "lumibench", "--lumibench-root", str(root), "--scenes", "BATH",
            "--workloads", "ao", "--size", "8", "--spp", "1", "--backend", "rtunit",
            "--rays-in-flight", str(RAYS), "--out", "out", "--no-progress"]
    # LumiBench's scenes are instanced: the unit needs the datapath's TRANSFORM
    assert main(argv) == 2 and "--transform datapath" in error_line()
    assert not (in_tmp / "out").exists()
    assert main([*argv, "--ideal-replay", "--flatten"]) == 2 and "itself" in error_line()
    for bad, message in ((["--rays-in-flight", "300"], "built with 1..256"),
                         (["--bvh-format", "q8g"], "not q8g")):
        assert main([*argv, "--flatten", *bad]) == 2 and message in error_line()
        assert not (in_tmp / "out").exists()
    assert main([*argv, "--flatten"]) == 0
    doc = json.loads((in_tmp / "out" / "BATH_AO.json").read_text())
    unit = doc["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and "rtunit_memory" not in doc
    assert doc["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
    row = json.loads((in_tmp / "out" / "summary.json").read_text())["runs"][0]
    assert row["utilization_memory"] == unit["utilization"] > 0
    assert row["replay_cycles_ratio"] == unit["replay_cycles_ratio"]
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03
    # instanced, through the TRANSFORM (the q8 decode and TRANSFORM build of ``shallow``)
    assert main([*argv, "--transform", "datapath", "--config", "baseline-unified-q8",
                 "--stack-depth", str(SHALLOW), "--out", "inst"]) == 0
    inst = json.loads((in_tmp / "inst" / "BATH_AO.json").read_text())
    assert inst["unit_rtl"]["traversal_mismatches"] == 0
    assert inst["transform_ops"] > 0 and inst["instances"] > 1
    assert inst["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
    assert abs(inst["unit_rtl"]["replay_cycles_ratio"] - 1) <= 0.03


def test_the_budget_grows_with_the_requests_a_frame_makes(scene, deep, monkeypatch):
    """Rays with thousands of nodes each (LumiBench's spring) outrun a budget per ray: the
    budget grows by BUDGET_PER_REQUEST per request made, so a frame that keeps making requests
    is not stopped, and one that stops making them is."""
    from driver.backends import rtunit
    bvh, o, d = scene
    rays = prepare_rays(o[:16], d[:16])
    whole = deep.trace_unit(bvh, rays)
    assert whole.stats["cycles"] > 10 + 10 * len(rays)
    monkeypatch.setattr(rtunit, "BUDGET_BASE", 10)
    monkeypatch.setattr(rtunit, "BUDGET_PER_RAY", 10)
    again = deep.trace_unit(bvh, rays)              # the requests carry it to the end
    assert again.stats["cycles"] == whole.stats["cycles"]
    monkeypatch.setattr(rtunit, "BUDGET_PER_REQUEST", 0)
    with pytest.raises(RuntimeError, match="within its budget of 170 cycles"):
        deep.trace_unit(bvh, rays)
    assert rtunit.request_bound(bvh, 2) == 2 * (np.asarray(bvh.image).nbytes // 64 + 1)


@pytest.mark.parametrize("fmt", ["box32", "q8"])
def test_the_culling_stack_matches_the_traversal_ray_by_ray(culling, fmt):
    """Every ray's hit, primitive, t bits, box and triangle ops and culled entries equal the
    Python traversal's ``cull`` on the "rtl" datapath, with a stack that spills."""
    tris = np.concatenate([box_room(4), soup(200, 1)])
    o, d = corpus_rays(tris, 256, 3)
    bvh = as_bvh(tris, fmt)
    rays = prepare_rays(o, d)
    ref = traverse(bvh, rays["extent"], issuer(_rtl_xf(), rays, bvh, "rtl"), cull=True)
    got = culling.trace_unit(bvh, rays)
    assert got.hit.sum() > 50 and ref.culled.sum() > 100
    assert got.prim.tolist() == ref.prim.tolist()
    assert got.t.view(np.uint32).tolist() == ref.nearest.view(np.uint32).tolist()
    assert got.box_ops.tolist() == ref.box_ops.tolist()
    assert got.tri_ops.tolist() == ref.tri_ops.tolist()
    assert got.culled.tolist() == ref.culled.tolist()
    assert got.stats["overflows"] > 0 and (got.overflows == 0).any()   # both kinds of rays
    assert (got.refills > 0).any()


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_the_culling_stack_keeps_every_hit_with_fewer_box_ops(scene, shallow, culling, any_hit):
    bvh, o, d = scene
    ref = trace(bvh, o, d, backend=_rtl_xf(), any_hit=any_hit, cull_stack=True)
    got = trace(bvh, o, d, backend=culling, any_hit=any_hit, cull_stack=True)
    plain = trace(bvh, o, d, backend=shallow, any_hit=any_hit)
    _same(ref, got)
    _same(plain, got, ops=False)
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["stack_overflows"] > 0
    assert unit["cull_stack"] and not plain.stats["unit_rtl"]["cull_stack"]
    assert got.stats["stack_culls"] == ref.stats["stack_culls"] == unit["stack_culls"]
    if any_hit:     # an any-hit ray's nearest t changes only where it ends: nothing to cull
        assert unit["stack_culls"] == 0 and got.box_ops.tolist() == plain.box_ops.tolist()
    else:
        assert unit["stack_culls"] > 0
        assert got.box_ops.sum() + unit["stack_culls"] <= plain.box_ops.sum()
        assert got.box_ops.sum() < plain.box_ops.sum()
        assert unit["mem_requests"] < plain.stats["unit_rtl"]["mem_requests"]
    # the replay with the unit's costs charges a pop-port cycle per culled entry
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03


@pytest.mark.parametrize("any_hit", [False, True], ids=["closest", "any-hit"])
def test_the_culling_stack_through_instances(culling, any_hit):
    """The BLAS root a ray enters carries no cull check (the traversal issues it at once), the
    entries inside a BLAS are culled by the object-space ray's t (the world ray's scale), and
    a ray that skips an instance issues its next entry unculled, as the traversal does."""
    bvh, o, d = _with_a_skipped_instance(256)
    ref = trace(bvh, o, d, backend=_rtl_xf(), transform="datapath", any_hit=any_hit,
                cull_stack=True)
    got = trace(bvh, o, d, backend=culling, any_hit=any_hit, cull_stack=True)
    _same(ref, got)
    assert got.instance.tolist() == ref.instance.tolist()
    assert got.transform_ops.tolist() == ref.transform_ops.tolist()
    unit = got.stats["unit_rtl"]
    assert unit["traversal_mismatches"] == 0 and unit["stack_overflows"] > 0
    assert got.stats["stack_culls"] == ref.stats["stack_culls"]
    assert (unit["stack_culls"] == 0) if any_hit else (unit["stack_culls"] > 0)
    assert abs(unit["replay_cycles_ratio"] - 1) <= 0.03


def test_the_culling_stack_is_one_build_parameter(scene, shallow, culling):
    bvh, o, d = scene
    assert culling.unit_params == {**shallow.unit_params, "CULL": 1}
    assert "CULL" not in unit_params({}, RAYS, SHALLOW)
    with pytest.raises(ValueError, match="built with CULL"):
        trace(bvh, o[:4], d[:4], backend=shallow, cull_stack=True)
    with pytest.raises(ValueError, match="--cull-stack"):
        trace(bvh, o[:4], d[:4], backend=culling)


def test_render_with_the_culling_stack(in_tmp, error_line):
    import json
    glb = str(reuse_glb(in_tmp / "reuse.glb"))         # three instances of one icosphere
    # the build of ``culling``: the q8 decode stage, TRANSFORM, a stack of SHALLOW, CULL
    argv = ["render", glb, "--size", "16", "--backend", "rtunit", "--rays-in-flight", str(RAYS),
            "--transform", "datapath", "--config", "baseline-unified-q8", "--stack-depth",
            str(SHALLOW), "--cull-stack", "--check-embree", "--no-progress"]
    assert main([*argv, "--json", "f.json"]) == 0
    doc = json.loads(open("f.json").read())
    unit = doc["unit_rtl"]
    assert unit["cull_stack"] and unit["traversal_mismatches"] == 0
    assert doc["stack_culls"] == unit["stack_culls"] > 0
    assert doc["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
