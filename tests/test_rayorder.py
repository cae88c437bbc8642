"""Ray order in the RT-unit model (driver.rtunit.order, the node-affinity scheduler of
sim/rtunit_scheduler.cpp): every policy issues the same requests with the same responses, only the
order and timing change; a hand-checked trace; the default order is the scheduler without ray
orders, cycle for cycle."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import driver
from driver import prepare_rays, rtunit
from driver.backends.build import rtl_params
from driver.bvh4 import build
from driver.cli import main as cli_main
from driver.core.layout import BOX_BYTES, BOX_TYPE, NodeRef, leaf_request
from driver.core.wire import REQUEST, ray_words
from driver.rtunit import order
from driver.tracer import trace
from support import meshes

SMALL = rtunit.MemoryModel(cache_bytes=2048, ways=2, latency_cycles=50, bytes_per_cycle=16.0)


@pytest.fixture(scope="module")
def record():
    """600 rays from inside a small room in random directions: incoherent chains."""
    rng = np.random.default_rng(7)
    bvh = build(meshes.box_room(2))
    o = rng.uniform([-1.5, -0.8, -1.0], [2.5, 1.2, 1.8], (600, 3))
    d = rng.normal(size=(600, 3))
    return trace(bvh, o, d, backend="rtl", record=True).record


@pytest.mark.parametrize("name", [p for p in order.POLICIES if order.POLICIES[p].key])
@pytest.mark.parametrize("window", [1, 7, 64, 600, 4096])
def test_sorts_permute_each_window(record, name, window):
    perm = order.permutation(record, name, window)
    n = record.rays
    assert perm.dtype == np.int64 and np.array_equal(np.sort(perm), np.arange(n))
    # every window holds the same rays as in index order, sorted by key (stable)
    k = order.keys(record, order.POLICIES[name].key)
    for s in range(0, n, window):
        part = perm[s:s + window]
        assert np.array_equal(np.sort(part), np.arange(s, min(s + window, n)))
        assert (np.diff(k[part].astype(np.float64)) >= 0).all()
    if window >= 64:
        assert not np.array_equal(perm, np.arange(n))           # the key does reorder
    assert order.permutation(record, "index", window) is None


@pytest.mark.parametrize("name", list(order.POLICIES))
def test_every_policy_same_responses(record, name):
    for r, p, w, mem in ((16, 1, 16, SMALL), (16, 1, 256, SMALL), (32, 4, 64, SMALL),
                         (64, 1, 1024, rtunit.MemoryModel()), (8, 2, 64, None)):
        rep = rtunit.replay(record, r, p, memory=mem, ray_order=name, ray_window=w,
                            datapath="rtl")
        # verify=True: every response equals the functional run's at its record index, so every
        # request was issued once (none lost, none twice: each was taken once, in chain order)
        assert rep.verified and rep.ops == record.ops and sum(rep.per_pipeline) == record.ops
        assert np.array_equal(rep.responses, record.responses)
        if name != "index":
            c = rep.order
            assert c["ray_order"] == name and c["ray_window"] == w and c["rays"] == record.rays
        if order.POLICIES[name].schedule:
            assert rep.order["parked"] == rep.order["resumed"] <= record.ops
            assert rep.order["max_held"] <= w
            if mem is None:
                assert rep.order["parked"] == 0                  # nothing ever misses
    with pytest.raises(ValueError, match="unknown ray order"):
        rtunit.replay(record, 16, ray_order="sorted")


def test_scheduler_window_holds_the_pool(record):
    with pytest.raises(ValueError, match="at least the 64 rays in flight"):
        rtunit.replay(record, 64, ray_order="affinity", ray_window=32)
    with pytest.raises(ValueError, match="window"):
        rtunit.replay(record, 64, ray_order="hash", ray_window=0)


# cycles of the same record and memory models from the scheduler before ray orders existed
BEFORE = {(16, None): 4111, (16, 32768): 5603, (16, 2048): 12949,
          (64, None): 4109, (64, 32768): 4577, (64, 2048): 8027}


@pytest.mark.parametrize("r", [16, 64])
def test_default_order_is_the_scheduler_before(record, r):
    for mem in (None, rtunit.MemoryModel(), SMALL):
        base = rtunit.replay(record, r, 1, memory=mem)
        assert base.cycles == BEFORE[(r, mem and mem.cache_bytes)]
        assert base.order is None and "order" not in base.stats()
        for w in (1, 64, 4096):
            same = rtunit.replay(record, r, 1, memory=mem, ray_order="index", ray_window=w)
            assert same.cycles == base.cycles and same.memory == base.memory
    # the scheduler with a window of R rays hides nothing more: without a memory it is exact
    aff = rtunit.replay(record, r, 1, ray_order="affinity", ray_window=r)
    assert aff.cycles == rtunit.replay(record, r, 1).cycles


def test_hand_checked_order_in_a_tiny_cache():
    """Four one-request rays on two box nodes A, B; a cache of one set of two 64-byte lines holds
    one 128-byte box node. Index order A, B, A, B misses every line (8 misses); the hash order
    groups the two rays on the left (A) before the two on the right (B): A, A, B, B, so the
    second ray of each pair finds both lines (4 hits, 4 misses)."""
    bvh = build(meshes.soup(200))
    assert bvh.stats["box_nodes"] >= 2
    a, b = (int(NodeRef.encode(i * BOX_BYTES, BOX_TYPE)) for i in (0, 1))
    rays = prepare_rays([[-50, 0, -5], [50, 0, -5], [-50, 0, -5], [50, 0, -5]],
                        [[0, 0, 1]] * 4)
    rec = rtunit.Record(ray_words(rays), bvh.image.view("<u4"), np.arange(4, dtype=np.uint32),
                        np.array([a, b, a, b], np.uint32), np.full(4, np.inf, np.float32), None,
                        rtl_params(0, 0, driver.LATENCY))
    tiny = rtunit.MemoryModel(cache_bytes=128, ways=2, line_bytes=64, latency_cycles=10)
    assert order.permutation(rec, "hash", 4).tolist() == [0, 2, 1, 3]
    idx = rtunit.replay(rec, 1, 1, memory=tiny)
    assert (idx.memory["line_hits"], idx.memory["line_misses"]) == (0, 8)
    assert idx.memory["bytes_from_memory"] == 8 * 64
    for name in ("hash", "twopoint"):
        srt = rtunit.replay(rec, 1, 1, memory=tiny, ray_order=name, ray_window=4)
        assert (srt.memory["line_hits"], srt.memory["line_misses"]) == (4, 4)
        assert srt.memory["bytes_from_memory"] == 4 * 64 and srt.cycles < idx.cycles
        # a window of 2 sorts {0, 1} and {2, 3}: still A, B, A, B
        two = rtunit.replay(rec, 1, 1, memory=tiny, ray_order=name, ray_window=2)
        assert two.memory["line_hits"] == 0


def _two_node_record(ray, ptr):
    """A hand-made record on two box nodes A (the root, offset 0) and B (offset 128) of a small
    BVH: request i is ray ``ray[i]`` on node ``ptr[i]`` ("A" or "B")."""
    bvh = build(meshes.soup(200))
    assert bvh.stats["box_nodes"] >= 2
    node = {n: int(NodeRef.encode(i * BOX_BYTES, BOX_TYPE)) for i, n in enumerate("AB")}
    n = max(ray) + 1
    rays = prepare_rays([[-50, 0, -5]] * n, [[0, 0, 1]] * n)
    return rtunit.Record(ray_words(rays), bvh.image.view("<u4"), np.array(ray, np.uint32),
                         np.array([node[p] for p in ptr], np.uint32),
                         np.full(len(ray), np.inf, np.float32), None,
                         rtl_params(0, 0, driver.LATENCY))


def test_hand_checked_treelets_in_a_tiny_cache():
    """Two rays each visit A then B (requests in ray order: A, A, B, B within the wavefront, so
    index order with one ray in flight issues ray 0's A, B, then ray 1's A, B); a cache of one
    128-byte box node. Index order misses every line (8 misses). With treelets of one box node
    (128 B) and one active treelet, both rays wait in A's queue, A is picked (two rays queued),
    ray 0 misses on A and ray 1 hits; both then wait in B's queue: B is picked, ray 0 misses,
    ray 1 hits: 4 misses, 4 hits. With prefetch the pick fetches the treelet's two lines and all
    four rays' requests hit: 4 misses, 8 hits."""
    rec = _two_node_record([0, 1, 0, 1], "AABB")
    tiny = rtunit.MemoryModel(cache_bytes=128, ways=2, line_bytes=64, latency_cycles=10)
    idx = rtunit.replay(rec, 1, 1, memory=tiny)
    assert (idx.memory["line_hits"], idx.memory["line_misses"]) == (0, 8)
    one = order.TreeletConfig(treelet_bytes=128, active=1, park=False, borrow=False)
    tab = order.treelet_schedule(rec, one)
    assert tab.request_treelet[0] == tab.request_treelet[1] != tab.request_treelet[2]
    tl = rtunit.replay(rec, 1, 1, memory=tiny, ray_order="treelet", ray_window=2, treelets=one)
    assert (tl.memory["line_hits"], tl.memory["line_misses"]) == (4, 4)
    assert tl.order["picks"] == 2 and tl.order["max_queued"] == 2 and tl.cycles < idx.cycles
    pre = rtunit.replay(rec, 1, 1, memory=tiny, ray_order="treelet", ray_window=2,
                        treelets=replace(one, prefetch=True))
    assert (pre.memory["line_hits"], pre.memory["line_misses"]) == (8, 4)
    # a window of one ray: no two rays ever share a queue, index order's misses
    solo = rtunit.replay(rec, 1, 1, memory=tiny, ray_order="treelet", ray_window=1, treelets=one)
    assert solo.memory["line_misses"] == 8 and solo.order["picks"] == 4


@pytest.mark.parametrize("fmt", ["box32", "q8", "q8g"])
@pytest.mark.parametrize("budget", [64, 512, 4096])
def test_treelets_cover_every_node_once(fmt, budget):
    """The treelet table holds every node of the image once (their bytes add up to the image's);
    every treelet is connected (a node's parent is in its treelet, or the node is the treelet's
    root) and within the budget unless it is one node; every request of a traversal has its
    treelet."""
    bvh = build(meshes.box_room(2), format=fmt)
    ptrs, parent = order.image_tree(bvh.image, bvh.root)
    off = NodeRef.offset(ptrs)
    assert len(np.unique(off)) == len(off) and parent[0] == -1 and (parent[1:] >= 0).all()
    assert order.node_bytes(ptrs).sum() == bvh.image.nbytes
    tl = order.treelets(ptrs, parent, budget)
    size = np.bincount(tl, weights=order.node_bytes(ptrs))
    count = np.bincount(tl)
    assert ((size <= budget) | (count == 1)).all() and tl[0] == 0
    roots = np.flatnonzero((parent < 0) | (tl != tl[np.maximum(parent, 0)]))
    assert np.array_equal(np.sort(tl[roots]), np.arange(tl.max() + 1))   # one root each
    rng = np.random.default_rng(3)
    rec = trace(bvh, rng.uniform(-0.5, 0.5, (50, 3)), rng.normal(size=(50, 3)), backend="rtl",
                record=True).record
    sched = order.treelet_schedule(rec, order.TreeletConfig(treelet_bytes=budget))
    assert sched.n_treelets == tl.max() + 1 and len(sched.request_treelet) == rec.ops
    of_node = dict(zip(off.tolist(), tl.tolist()))
    leaf_word = leaf_request(rec.ptr)[0]            # a leaf's later triangle: its leaf's node
    assert sched.request_treelet.tolist() == [of_node[4 * w] for w in leaf_word.tolist()]


def test_cost_follows_the_layout_and_the_window(record):
    bits = sum(REQUEST.field[f].total_bits for f in order.RAY_STATE_FIELDS)
    assert order.ray_state_bytes() == -(-bits // 8)
    assert order.bitonic_compare_exchanges(2) == 1 and order.bitonic_compare_exchanges(4) == 6
    assert order.bitonic_compare_exchanges(8) == 24 and order.bitonic_compare_exchanges(5) == 24
    c = order.cost("hash", 256, 1000, 64, 10)
    assert c["keys_computed"] == 1000 and c["sort_buffer_entries"] == 256
    assert c["compare_exchanges"] == 3 * order.bitonic_compare_exchanges(256) + \
        order.bitonic_compare_exchanges(232)
    s = order.cost("affinity", 256, 1000, 64, 10)
    assert s["extra_rays_held"] == 192
    assert s["traversal_state_bytes"] == order.ray_state_bytes() + 4 * (1 + 3 * 10 + 2)
    assert s["extra_state_bytes"] == 192 * s["traversal_state_bytes"]
    assert order.tree_depth(record) >= 2
    # treelets: a queue entry (a 8-bit next index) per held ray; per treelet a head, a tail
    # (8 bits each) and a count (9 bits); a treelet number (4 bits for 10 treelets) per node
    t = order.treelet_cost(order.TreeletConfig(), 10, 100, 256)
    assert t["queue_bytes"] == -(-(256 * 8 + 10 * (8 + 8 + 9)) // 8)
    assert t["treelet_table_bytes"] == 100 * 4 // 8 and t["queue_entries"] == 256
    rep = rtunit.replay(record, 16, 1, memory=SMALL, ray_order="treelet", ray_window=64)
    c = rep.order
    assert c["extra_rays_held"] == 48 and c["picks"] >= 1 and c["treelets"] >= 1
    assert c["pick_comparisons"] == c["picks"] * (c["treelets"] - 1)


def test_floor_bounds_every_order(record):
    floor = order.floor_bytes([record], 64)
    for name in order.POLICIES:
        rep = rtunit.replay(record, 16, 1, memory=SMALL, ray_order=name, ray_window=256)
        assert rep.memory["bytes_from_memory"] >= floor
    big = rtunit.MemoryModel(cache_bytes=1 << 20)
    assert rtunit.replay(record, 16, 1, memory=big).memory["bytes_from_memory"] == floor


def test_bench_cli_ray_order(in_tmp, error_line):
    assert cli_main(["bench", "--scene", "room", "--workload", "shadow", "--size", "12",
                     "--sweep-rays", "4", "--ray-order", "hash", "--ray-window", "64",
                     "--frame", "wavefront", "--json", "b.json", "--no-progress"]) == 0
    doc = json.loads((in_tmp / "b.json").read_text())
    pt = doc["provenance"]["design_point"]
    assert pt["ray_order"] == "hash" and pt["ray_window"] == 64
    mem = doc["frame"]["rtunit_memory"]
    assert mem["replay_datapath"] == "timing" and mem["ray_order_cost"]["ray_order"] == "hash"
    assert mem["ray_order_cost"]["keys_computed"] == doc["frame"]["rays"]
    # a one-kernel frame: threads issue their rays, only the schedulers reorder them
    assert cli_main(["bench", "--scene", "room", "--workload", "shadow", "--size", "8",
                     "--ray-order", "affinity", "--ray-window", "128", "--json", "a.json",
                     "--no-progress"]) == 0
    mem = json.loads((in_tmp / "a.json").read_text())["frame"]["rtunit_memory"]
    assert mem["frame_schedule"] == "one-kernel" and mem["ray_order_cost"]["held_rays"] == 128
    assert cli_main(["bench", "--workload", "path", "--ray-order", "affinity",
                     "--ray-window", "16"]) == 2
    assert "--ray-window (16) must be at least --rays-in-flight (64)" in error_line()
    assert cli_main(["bench", "--ray-order", "sorted"]) == 2
    assert "--ray-order" in error_line()


def test_the_study_runs_on_the_published_replay_schema(tmp_path):
    """rayflex study rayorder (docs/rayorder.md) on a tiny frame: every policy's point is
    an ``rtunit_memory`` object (docs/statistics.md), sorting policies carry their cost, index
    order is one point, the plot is written."""
    from driver.studies import rayorder as order
    doc = order.study(scenes=("cornell",), size=8, windows=(64, order.ALL_RAYS), progress=False,
                      formats=("box32", "q8"), variants=True)
    for fmt in ("box32", "q8"):
        types = doc["formats"][fmt]["scenes"]["cornell"]
        assert "primary" in types
        for kind, t in types.items():
            pols = t["policies"]
            assert set(pols["index"]) == {"0"} and set(pols) == set(order.POLICIES)
            for name, pts in pols.items():
                for p in pts.values():
                    assert p["responses_verified"] is None and 0 < p["utilization"] <= 1
                    assert ("ray_order_cost" in p) == (name != "index")
            assert t["floor_bytes_per_ray"] <= pols["index"]["0"]["bytes_per_ray"] + 1e-9
    var = doc["treelet_variants"]["variants"]
    assert set(var) == set(order.TREELET_VARIANTS)
    assert var["prefetch"]["config"]["prefetch"] and not var["default"]["config"]["prefetch"]
    assert all(v["shadow"]["responses_verified"] is None for v in var.values())
    png = tmp_path / "o.png"
    order.plot_study(doc, png)
    assert png.read_bytes()[:4] == b"\x89PNG"
    text = order.study_tables(doc)
    assert "primary** (q8)" in text and "W = all" in text and "treelet variants" in text


def test_study_command_rejects_bad_arguments(tmp_path, capsys):
    """rayflex study rayorder: a bad option is one error line and exit 2 before any replay, and
    no output file."""
    for argv, what in ((["--policies", "index,sorted"], "--policies"),
                       (["--windows", "64,0"], "--windows"),
                       (["--variants-window", "x"], "--variants-window"),
                       (["--bvh-formats", "q9"], "--bvh-formats")):
        assert cli_main(["study", "rayorder", "--json", str(tmp_path / "x.json"), *argv]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"rayflex: error: {what}") and err.count("\n") == 1
    assert not list(tmp_path.iterdir())
