"""The compressed q8 image (docs/compressed.md): the encoder's containment obligation on every
node of every image built here, triangle pairs that keep each triangle bit for bit (winding and
vertex order), hits equal to box32's on the built-in scenes, the node bytes the statistics and
the RT-unit memory model charge, and the harness's C++ decode equal to ``decode_q8``."""

from __future__ import annotations

import numpy as np
import pytest

from driver.bvh4 import PAD_REL, build, request_operands
from driver.core.layout import (GROUP_BYTES, GROUP_MAX_TRIS, GROUP_NODE, GROUP_TYPE,
                                LEAF_NEXT_TYPE, NO_CHILD, NODE_BYTES, PAIR_BYTES, PAIR_NODE,
                                PAIR_TYPE, Q8_BYTES, Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, Q8_TYPE,
                                NodeRef, decode_q8, leaf_count, leaf_next, leaf_triangles,
                                q8_count)
from driver.core.wire import REQUEST_DTYPE, pack_requests, ray_words
from driver.tracer import trace
from support import meshes
from support.images import check_image, image_leaves


def _grid(k: int, scale: float = 1.0, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A bumpy k x k grid surface: triangles sharing edges, consistently wound."""
    s = np.linspace(0.0, 1.0, k + 1)
    x, y = np.meshgrid(s, s, indexing="ij")
    z = 0.1 * np.sin(7 * x) * np.cos(5 * y)
    p = np.stack([x, y, z], axis=-1) * scale + np.asarray(offset)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], 2).reshape(-1, 3, 3),
                           np.stack([a, c, d], 2).reshape(-1, 3, 3)]).astype(np.float32)


MESHES = {
    "soup": lambda: meshes.soup(300, seed=2),
    "grid": lambda: _grid(12),
    "room": lambda: meshes.box_room(3),
    "degenerate": meshes.degenerate,
    "sphere": lambda: meshes.icosphere(2),
    "huge": lambda: _grid(6, 3e30, (1e30, -2e30, 5e29)),
    "tiny": lambda: _grid(6, 3e-30, (1e-30, 0.0, -2e-30)),
    "mixed": lambda: np.concatenate([_grid(5, 1e-3), _grid(5, 1e4, (-1e4, 0, 0))]),
    "subnormal": lambda: _grid(3, 1e-39),
    "one": lambda: meshes.soup(1, seed=4),
}


@pytest.mark.parametrize("name", sorted(MESHES))
def test_containment_and_leaves_on_every_node(name):
    tris = MESHES[name]()
    for fmt, fill in (("q8", 0), ("q8", 8), ("q8g", 0), ("q8g", 8)):
        bvh = build(tris, format=fmt, fill=fill)
        check_image(bvh, tris)
    assert bvh.stats["bytes_per_triangle"] == bvh.image.nbytes / len(tris)


def test_pairs_share_edges_and_cover_a_mesh():
    tris = _grid(12)
    bvh = build(tris, format="q8")
    check_image(bvh, tris)
    assert bvh.stats["pair_ratio"] >= 0.9                  # a grid pairs almost completely
    leaves = bvh.image[Q8_BYTES * bvh.stats["box_nodes"]:].view(PAIR_NODE)
    two = leaves["prim"][:, 1] != NO_CHILD
    sel = leaves["idx"][two]
    shared = sum(((sel >> (2 * k)) & 3) != 3 for k in range(3))
    assert (shared == 2).all()                               # exactly one edge in common
    soup = build(meshes.soup(200, seed=1), format="q8")     # nothing shares an edge
    assert soup.stats["pair_ratio"] == 0.0


def test_vertex_ids_number_bit_identical_points_by_first_use_on_any_shards():
    """The sharded hash tables (one per thread) give the first-use numbering of the exact
    float32 bits, whatever the number of shards: numpy's unique rows as the reference."""
    from driver.bvh.q8 import _vertex_ids_one, _vertex_ids_par
    rng = np.random.default_rng(3)
    pts = rng.integers(-6, 7, (6000, 3)).astype(np.float32)
    pts[::7, 1] = -0.0                                      # -0.0 and 0.0 are different bits
    pts[::11, 2] = 0.0
    bits = pts.view(np.uint32)
    _, first, inverse = np.unique(bits, axis=0, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    want = rank[inverse.reshape(-1)]
    assert len(first) < len(pts) / 2                         # many repeats
    for shards in (1, 2, 3, 4):
        for kernel in (_vertex_ids_par, _vertex_ids_one):
            got = kernel(bits, np.full((shards, 1 << 14), -1, np.int32))
            assert np.array_equal(got, want), shards
        assert len(_vertex_ids_one(bits, np.full((shards, 1 << 8), -1, np.int32))) == 0  # full


def _scan_neighbours(ids):
    """The edge neighbours ``_neighbours`` promises, by a plain scan: per edge in order, the
    other triangles that share it in index order, all of them if they are at most three
    triangles with t, else only the one before and the one after t; each once."""
    rows = []
    for t in range(len(ids)):
        want = []
        for e in range(3):
            a, b = ids[t, e], ids[t, (e + 1) % 3]
            if a == b:
                continue
            share = [u for u in range(len(ids)) if a in ids[u] and b in ids[u]]
            if len(share) > 3:
                i = share.index(t)
                share = share[max(0, i - 1):i + 2]
            want += [u for u in share if u != t and u not in want]
        rows.append(want)
    return rows


def test_edge_neighbours_equal_a_plain_scan():
    """The parallel adjacency (``_neighbours``) equals a plain scan whichever number of workers
    fills the per-vertex lists, on a grid with doubled edges, a degenerate triangle and an edge
    shared by 40 triangles, and is symmetric."""
    from driver.bvh.q8 import _neighbours_one, _neighbours_par, vertex_ids
    rng = np.random.default_rng(4)
    fan = np.zeros((40, 3, 3), np.float32)                   # 40 triangles on one edge
    fan[:, 1, 2] = 1.0
    fan[:, 2] = rng.normal(size=(40, 3))
    fan[17, 2] = fan[3, 2]                                   # and a duplicate among them
    tris = np.concatenate([_grid(5), _grid(5)[:9], meshes.soup(4, seed=2), fan, fan[:3]])
    tris[3, 2] = tris[3, 1]                                  # a degenerate triangle
    tris[60, 2] = tris[60, 0]                                # and one with an edge twice
    ids = vertex_ids(tris)
    want = _scan_neighbours(ids)
    for shards, kernel in ((1, _neighbours_one), (1, _neighbours_par), (2, _neighbours_par),
                           (3, _neighbours_par), (7, _neighbours_one)):   # the lists' owners
        adj, deg = kernel(ids, int(ids.max()) + 1, shards)
        for t in range(len(ids)):
            assert list(adj[t, :deg[t]]) == want[t], (shards, t)
            assert (adj[t, deg[t]:] == -1).all()
            assert all(t in adj[u, :deg[u]] for u in adj[t, :deg[t]])
        assert deg.max() == 6


def test_matching_ends_on_the_mesh_that_looped():
    """Nine triangles on five vertices, every edge shared by 3 to 5 of them: the adjacency cut
    at six per triangle was asymmetric, a triangle's count of unmatched neighbours stayed
    above zero with none left, and the matching picked it forever. Now every triangle but one
    is paired with an edge neighbour, and the step cap holds."""
    from driver.bvh.q8 import _match, match_limit, neighbours, pair_triangles, vertex_ids
    v = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)], np.float32)
    f = [[0, 1, 2], [3, 1, 0], [3, 0, 4], [2, 0, 3], [4, 0, 1], [1, 2, 4], [0, 2, 3],
         [3, 1, 0], [1, 3, 2]]
    tris = v[np.array(f)]
    first, second = pair_triangles(tris)[:2]
    assert (second >= 0).sum() == 4
    ids = vertex_ids(tris)
    for a, b in zip(first[second >= 0], second[second >= 0]):
        assert len(set(ids[a]) & set(ids[b])) >= 2
    check_image(build(tris, format="q8"), tris)
    adj, deg = neighbours(ids)
    partner, steps = _match(adj, deg, tris, match_limit(len(tris)))
    assert steps < match_limit(len(tris))


def test_matching_falls_back_at_its_cap_and_on_an_inconsistent_adjacency():
    """The step cap is reachable: at the cap the matching stops with the rest unpaired; an
    adjacency whose rows disagree (u lists t, t does not list u) ends too, the triangle whose
    count was wrong left alone."""
    from driver.bvh.q8 import _match, neighbours, vertex_ids
    tris = _grid(6)
    ids = vertex_ids(tris)
    adj, deg = neighbours(ids)
    full, _ = _match(adj, deg, tris, 10 ** 6)
    part, steps = _match(adj, deg, tris, 3)
    assert steps == 3 and (part >= 0).sum() <= 6 < (full >= 0).sum()
    assert all(part[part[t]] == t for t in np.flatnonzero(part >= 0))
    # t = 0 counts a neighbour that does not list it back: the old loop never ended here
    bad_adj = np.full((3, 6), -1, np.int32)
    bad_adj[0, :2] = 1, 2
    bad_adj[1, 0] = 2
    bad_adj[2, 0] = 1
    bad_deg = np.array([2, 1, 1], np.int8)
    partner, steps = _match(bad_adj, bad_deg, tris[:3], 100)
    assert list(partner) == [-1, 2, 1] and steps < 100


@pytest.mark.parametrize("fmt", ["q8", "q8g"])
def test_image_does_not_depend_on_the_threads(fmt):
    """The encoder's parallel parts (vertex ids, adjacency, group fits and layout,
    quantization) split their work by the number of threads; the image is the same on 1, 2 and
    3 threads, byte for byte."""
    import numba
    tris = np.concatenate([_grid(24), _grid(9, 0.5, (2.0, 0.0, 0.0)), meshes.soup(40, seed=5)])
    saved = numba.get_num_threads()
    images = []
    try:
        for threads in (1, 2, 3):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            images.append(build(tris, format=fmt).image)
    finally:
        numba.set_num_threads(saved)
    assert all(np.array_equal(images[0], im) for im in images[1:])
    if fmt == "q8g":
        assert build(tris, format=fmt).stats["group_leaves"] > 0


def test_mesh_and_triangle_inputs_give_the_same_image():
    m = meshes.bunny()
    a = build(m, format="q8")
    b = build(np.asarray(m.triangles, np.float32), format="q8")
    assert np.array_equal(a.image, b.image)
    check_image(a, np.asarray(m.vertices, np.float32)[m.faces])
    assert a.stats["pair_ratio"] > 0.9 and a.stats["bytes_per_triangle"] < 50
    assert a.stats["box_nodes"] * 64 + a.stats["leaf_nodes"] * 64 == a.stats["bytes"]
    g = build(m, format="q8g")                  # the denser leaves: at most 40 bytes a triangle
    check_image(g, np.asarray(m.vertices, np.float32)[m.faces])
    assert g.stats["bytes_per_triangle"] <= 40 and g.stats["group_leaves"] > 0


def test_bad_format():
    with pytest.raises(ValueError, match="format"):
        build(meshes.soup(4), format="q16")
    with pytest.raises(ValueError, match="box32"):
        trace(build(meshes.soup(4)), [[0, 0, 0]], [[0, 0, 1]], bvh_format="q8", backend="golden")


# ----------------------------------------------------------------------------------------------
# hits: q8 == box32 on the same rays


def _rays(scene, n, seed):
    rng = np.random.default_rng(seed)
    v = scene.triangles.reshape(-1, 3)
    lo, hi = v.min(0), v.max(0)
    o = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (n, 3))
    d = rng.normal(size=(n, 3))
    return o, d


def assert_same_hits(a, b):
    """t bit for bit; prim too except between triangles hit at exactly the same t."""
    assert np.array_equal(a.hit, b.hit)
    assert np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32))
    diff = a.prim != b.prim
    assert (a.hit[diff]).all()                              # only ties of two hits at one t
    return int(diff.sum())


@pytest.fixture(scope="module", params=["bunny", "cornell", "bunny_floor"])
def scene_pair(request):
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    scene = load_scene(request.param)
    o1, d1 = primary_rays(scene.camera, 20, 20)
    o2, d2 = _rays(scene, 400, 7)
    o, d = np.concatenate([o1, o2]), np.concatenate([d1, d2])
    return (scene, build(scene.mesh), {f: build(scene.mesh, format=f) for f in ("q8", "q8g")},
            o, d)


@pytest.mark.parametrize("fmt", ["q8", "q8g"])
@pytest.mark.parametrize("any_hit", [False, True])
@pytest.mark.parametrize("double_sided", [False, True])
def test_q8_hits_equal_box32(scene_pair, fmt, any_hit, double_sided):
    scene, b32, q8s, o, d = scene_pair
    q8 = q8s[fmt]
    extent = np.float32(0.5 * np.ptp(scene.triangles.reshape(-1, 3), axis=0).max())
    kw = dict(backend="golden", any_hit=any_hit, double_sided=double_sided,
              extent=extent if any_hit else np.inf)
    a, b = trace(b32, o, d, **kw), trace(q8, o, d, **kw)
    assert a.hit.sum() > 40
    if any_hit:
        assert np.array_equal(a.hit, b.hit)                 # occluded exactly when box32 is
        assert np.array_equal(a.t <= extent, b.t <= extent)
    else:
        assert_same_hits(a, b)
    ratio = b.stats["ops"] / a.stats["ops"]
    assert 0.8 < ratio < 1.3
    # node bytes: 64 per q8 node and per pair leaf fetched, none for a pair's second triangle
    assert b.stats["node_bytes_fetched"] < 0.7 * a.stats["node_bytes_fetched"]


@pytest.mark.parametrize("fmt", ["q8", "q8g"])
def test_leaves_keep_winding(fmt):
    """Culled (single-sided) hits on a closed mesh seen from outside and inside: box32 and
    q8/q8g agree ray by ray, so no triangle of a pair or group leaf turned its face."""
    tris = meshes.icosphere(3)
    rng = np.random.default_rng(11)
    o = rng.normal(size=(600, 3))
    o *= (rng.uniform(0.2, 3.0, 600) / np.linalg.norm(o, axis=1))[:, None]  # inside and out
    d = rng.normal(size=(600, 3))
    a = trace(build(tris), o, d, backend="golden")
    q8 = build(tris, format=fmt)
    assert q8.stats["pair_ratio"] > 0.9
    assert (q8.stats["grouped_triangles"] > 0.2 * len(tris)) == (fmt == "q8g")
    b = trace(q8, o, d, backend="golden")
    inside = np.linalg.norm(o, axis=1) < 0.95
    assert not a.hit[inside].any()                          # the inside sees only back faces
    assert a.hit.sum() > 30
    assert_same_hits(a, b)
    both = trace(q8, o, d, backend="golden", double_sided=True)
    assert both.hit[inside].all()


def test_traversal_requests_per_leaf():
    """A leaf is one TRIANGLE request per triangle of the ray, in the leaf's order: its own
    pointer, then LEAF_NEXT_TYPE pointers to triangles 1, 2, ... of the same leaf; an any-hit ray
    finished by a triangle issues no more of the leaf; node bytes count each leaf once (a group
    leaf's 128 bytes at its first request)."""
    tris = _grid(8)
    for fmt in ("q8", "q8g"):
        _leaf_requests(build(tris, format=fmt))


def _leaf_requests(q8):
    from support.recording import RecordingBackend
    from driver import backend
    rng = np.random.default_rng(5)
    o = np.column_stack([rng.uniform(0.05, 0.95, (40, 2)), np.ones(40)])
    d = np.tile([0.0, 0.0, -1.0], (40, 1))
    lptr, lcount, _, _ = image_leaves(q8)
    count = dict(zip(lptr.tolist(), lcount.tolist()))
    seen_group = False
    for any_hit in (False, True):
        res = trace(q8, o, d, backend=RecordingBackend(backend("golden")), record=True,
                    any_hit=any_hit)
        rec = res.record
        typ = NodeRef.type(rec.ptr)
        assert res.hit.all()
        for r in range(len(o)):
            t, p = typ[rec.ray == r], rec.ptr[rec.ray == r]
            i = 0
            while i < len(t):
                if t[i] not in (PAIR_TYPE, GROUP_TYPE):
                    assert t[i] == Q8_TYPE
                    i += 1
                    continue
                seen_group |= t[i] == GROUP_TYPE
                n = count[int(p[i])]
                got = 1
                while i + got < len(t) and t[i + got] == LEAF_NEXT_TYPE:
                    assert p[i + got] == leaf_next(p[i:i + 1], got)[0]
                    got += 1
                assert got == n or (any_hit and got < n and i + got == len(t))
                i += got
        nbytes = sum(NODE_BYTES[int(x)] for x in typ)
        assert res.stats["node_bytes_fetched"] == nbytes
        assert res.stats["ops"] == len(rec.ptr)
    assert seen_group == (q8.format == "q8g")


# ----------------------------------------------------------------------------------------------
# the harness (C++): decode and memory model


def random_q8_image(n: int, seed: int):
    """n random q8 nodes (exponents over the whole range, zero and full planes, every count,
    subnormal and signed-zero origins) followed by n random pair leaves and n random group
    leaves; the pointers name every node and every triangle of every leaf."""
    rng = np.random.default_rng(seed)
    nodes = np.zeros(n, Q8_NODE)
    origin = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-40, 30, (n, 3))
    origin[::7, 0] = 0.0
    origin[1::7, 1] = -0.0
    origin[2::7, 2] = 1e-42                                  # subnormal
    nodes["origin"] = origin.astype(np.float32)
    e = rng.integers(Q8_EXP_MIN, Q8_EXP_MAX + 1, (n, 3))
    e[:4] = [[Q8_EXP_MIN] * 3, [Q8_EXP_MAX] * 3, [0, -1, 1], [Q8_EXP_MIN, 0, Q8_EXP_MAX]]
    nodes["exp"][:, :3] = e.astype(np.int8).view(np.uint8)
    nodes["exp"][:, 3] = np.arange(n) % 4 + 1
    q = rng.integers(0, 256, (n, 4, 6))
    q[::5] = 0
    q[1::5] = 255
    nodes["q"] = q
    leaves = np.zeros(n, PAIR_NODE)
    leaves["v"] = rng.normal(size=(n, 4, 3))
    leaves["prim"] = rng.integers(0, 1000, (n, 2))
    leaves["idx"] = rng.integers(0, 64, n)
    groups = np.zeros(n, GROUP_NODE)
    groups["v"] = rng.normal(size=(n, 4, 3))
    groups["v2"] = rng.normal(size=(n, 4, 3))
    groups["prim"] = rng.integers(0, 1000, (n, 2))
    groups["prim2"] = rng.integers(0, 1000, (n, 4))
    groups["idx"] = rng.integers(0, 1 << 42, n, dtype=np.uint64) | (np.uint64(6) << np.uint64(48))
    image = np.concatenate([nodes.view(np.uint8), leaves.view(np.uint8), groups.view(np.uint8)])
    pairs = 64 * (n + np.arange(n))
    grp = 64 * 2 * n + GROUP_BYTES * np.arange(n)
    ptr = np.concatenate([NodeRef.encode(64 * np.arange(n), Q8_TYPE),
                          NodeRef.encode(pairs, PAIR_TYPE),
                          leaf_next(NodeRef.encode(pairs, PAIR_TYPE), 1),
                          NodeRef.encode(grp, GROUP_TYPE),
                          *(leaf_next(NodeRef.encode(grp, GROUP_TYPE), k)
                            for k in range(1, GROUP_MAX_TRIS))])
    return image, ptr


def test_harness_decode_equals_python_on_random_nodes():
    from driver import LATENCY, prepare_rays
    from driver.backends.build import rtl_params
    from driver.backends.harness import build_requests
    image, ptr = random_q8_image(300, 3)
    rng = np.random.default_rng(1)
    rays = prepare_rays(rng.normal(size=(len(ptr), 3)), rng.normal(size=(len(ptr), 3)))
    idx = np.arange(len(ptr), dtype=np.uint32)
    ext = np.full(len(ptr), np.inf, np.float32)
    words = build_requests(rtl_params(False, False, LATENCY), ray_words(rays), image.view("<u4"),
                           idx, ptr, ext)
    req = rays.copy()
    req["tag"] = idx
    req["extent"] = ext
    request_operands(req, image, ptr)
    assert np.array_equal(words, pack_requests(req))
    # and the decode is decode_q8's, unused slots +inf included
    got = np.ascontiguousarray(words[:300, 15:39]).view(np.float32).reshape(300, 4, 6)
    assert np.array_equal(got.view(np.uint32),
                          decode_q8(image[:300 * 64].view(Q8_NODE)).view(np.uint32))
    assert REQUEST_DTYPE["box"].shape == (4, 6)
    # a harness built with the decode sends the nodes as stored, flagged, as the host does
    words = build_requests(rtl_params(False, False, None, True), ray_words(rays),
                           image.view("<u4"), idx, ptr, ext)
    req = rays.copy()
    req["tag"] = idx
    req["extent"] = ext
    request_operands(req, image, ptr, compressed=True)
    assert np.array_equal(words, pack_requests(req))
    assert (req["flags"][:300] & 2).all() and not (req["flags"][300:] & 2).any()


@pytest.mark.parametrize("fmt", ["q8", "q8g"])
def test_rtl_frame_and_memory_model_charge_the_bytes_of_each_node(fmt):
    from driver import rtunit
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    scene = load_scene("bunny")
    o, d = primary_rays(scene.camera, 16, 16)
    q8 = build(scene.mesh, format=fmt)
    gold = trace(q8, o, d, backend="golden")
    res = trace(q8, o, d, backend="rtl", record=True)
    assert_same_hits(gold, res)
    assert np.array_equal(gold.prim, res.prim)
    rec = res.record
    typ = NodeRef.type(rec.ptr)
    nbytes = np.array([NODE_BYTES[int(x)] for x in typ])
    assert res.stats["node_bytes_fetched"] == nbytes.sum()
    assert (nbytes[typ == GROUP_TYPE] == 128).all() and (typ == GROUP_TYPE).any() == (fmt == "q8g")
    rep = rtunit.replay(rec, 16, memory=rtunit.MemoryModel(), datapath="rtl")
    m = rep.memory
    # a q8 node or a pair leaf is one 64-byte line, a group leaf two; a leaf's later triangles
    # fetch nothing
    assert m["line_accesses"] == nbytes.sum() // 64
    assert m["bytes_from_memory"] == 64 * m["line_misses"] > 0
    assert rep.verified


def test_quantization_slack_lies_behind_flat_leaves():
    """A floor (two big flat triangles facing +z) beside a tall object in one node: the floor's
    decoded box is one step thick, and that step lies below the floor, so rays leaving the floor
    upwards from just above it (as shadow and bounce rays do) test no floor triangle."""
    floor = np.array([[[-10, -10, 0], [10, -10, 0], [10, 10, 0]],
                      [[-10, -10, 0], [10, 10, 0], [-10, 10, 0]]], np.float32)
    tower = _grid(4, 1.0, (0.0, 0.0, 0.0)).copy()
    tower[..., 2] = tower[..., 0] * 30.0 + 1.0             # a steep slope up to z = 31
    tris = np.concatenate([tower, floor])
    q8 = build(tris, format="q8")
    check_image(q8, tris)
    rng = np.random.default_rng(2)
    o = np.column_stack([rng.uniform(-9, -2, 200), rng.uniform(-9, 9, 200), np.full(200, 0.01)])
    d = np.column_stack([rng.normal(size=(200, 2)), rng.uniform(0.2, 1.0, 200)])
    a = trace(build(tris), o, d, backend="golden", any_hit=True)
    b = trace(q8, o, d, backend="golden", any_hit=True)
    assert np.array_equal(a.hit, b.hit)
    assert b.stats["tri_ops"] <= a.stats["tri_ops"]


def test_study_table_and_plot(tmp_path, capsys):
    """rayflex study compressed on the committed bench documents: ratios against box32, one row per ray
    type and image, the plot written; bad input is a one-line error."""
    import json
    from pathlib import Path
    from driver.cli import main as cli_main
    from driver.studies import compressed as study

    def study_main(argv):                    # the study's command: rayflex study compressed
        return cli_main(["study", "compressed", *argv])
    images = Path(__file__).resolve().parent.parent / "images"
    paths = [str(images / f"compressed_path64_{f}.json") for f in ("box32", "q8", "q8g")]
    docs = study.load(paths)
    rows = study.rows(docs)
    kinds = list(docs["box32"]["frame"]["by_type"])
    assert len(rows) == 3 * len(kinds)
    for r in rows:
        t = docs[r["format"]]["frame"]["by_type"][r["type"]]
        assert r["ops_per_ray"] == pytest.approx((t["box_ops"] + t["tri_ops"]) / t["rays"])
        if r["format"] == "box32":
            assert r["ops_ratio"] == r["memory_bytes_ratio"] == r["cycles_ratio"] == 1.0
    png = tmp_path / "sweep.png"
    assert study_main(paths[:2] + ["--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert len(out.splitlines()) == 2 + 2 * len(kinds) and png.stat().st_size > 1000
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"bvh_format": "q8"}))
    assert study_main([paths[0], str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rayflex: error: ") and "\n" not in err


@pytest.mark.parametrize("backend_name", ["golden", "rtl"])
def test_a_datapath_with_the_decode_gets_the_nodes_as_stored(backend_name):
    """On a backend built with the q8 decode (``compressed=True``, ``--config ...-q8``) the
    traversal sends q8 nodes as stored (``qnode``, flag DECODE_Q8) and the datapath decodes them:
    the same hits, bit for bit, as the host's decode on a datapath without it; the replay on the
    RT unit of such a configuration checks every response against the trace's."""
    from driver import backend, rtunit
    from driver.core.wire import FLAG_DECODE_Q8
    from driver.core.layout import Q8_TYPE, NodeRef
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    scene = load_scene("bunny_floor")
    o, d = primary_rays(scene.camera, 24, 24)
    bvh = build(scene.mesh, format="q8")
    host = trace(bvh, o, d, backend="golden")
    be = backend(backend_name, compressed=True)
    res = trace(bvh, o, d, backend=be, record=True)
    assert np.array_equal(res.t.view(np.uint32), host.t.view(np.uint32))
    assert np.array_equal(res.prim, host.prim) and res.hit.sum() > 0
    rec = res.record
    assert rec.params["COMPRESSED"] == 1
    req = rec.requests()
    q8 = NodeRef.type(rec.ptr) == Q8_TYPE
    assert q8.any() and ((req["flags"][q8] & FLAG_DECODE_Q8) != 0).all()
    assert ((req["flags"][~q8] & FLAG_DECODE_Q8) == 0).all()
    if backend_name == "rtl":
        assert rtunit.replay(rec, 64, 1, datapath="rtl").verified


def test_leaf_next_pointers_round_trip():
    """LEAF_NEXT_TYPE pointers carry the leaf (bits 28:3) and the triangle index - 1 (bits
    31:29); a leaf beyond the first 4 GiB has no such pointer."""
    from driver.core.layout import LEAF_OFFSET_LIMIT, leaf_request
    leaf = NodeRef.encode([0, 64, LEAF_OFFSET_LIMIT - 128], GROUP_TYPE)
    for k in range(1, GROUP_MAX_TRIS):
        p = leaf_next(leaf, k)
        assert (NodeRef.type(p) == LEAF_NEXT_TYPE).all()
        word, got = leaf_request(p)
        assert np.array_equal(word, NodeRef.word(leaf)) and (got == k).all()
        assert np.array_equal(leaf_next(p, k + 1), leaf_next(leaf, k + 1))   # from a later one
    assert (leaf_request(leaf)[1] == 0).all()
    with pytest.raises(ValueError, match="4 GiB"):
        leaf_next(NodeRef.encode([LEAF_OFFSET_LIMIT], GROUP_TYPE), 1)


def test_group_trade_off(monkeypatch):
    """GROUP_LAMBDA weighs bytes against ops: on this sphere each larger value gives an image no
    larger, lambda = 0 groups nothing and a large lambda groups most triangles; every image
    keeps the containment and the leaves."""
    import driver.bvh.q8g as q8mod
    tris = meshes.icosphere(4)
    seen = []
    for lam in (0.0, 1.0, q8mod.GROUP_LAMBDA, 16.0):
        monkeypatch.setattr(q8mod, "GROUP_LAMBDA", lam)
        bvh = build(tris, format="q8g")
        check_image(bvh, tris)
        seen.append((bvh.stats["bytes"], bvh.stats["grouped_triangles"]))
    assert seen[0][1] == 0 and seen[0][0] == build(tris, format="q8").stats["bytes"]
    assert all(b1 <= b0 for (b0, _), (b1, _) in zip(seen, seen[1:]))
    assert seen[-1][0] < 0.8 * seen[0][0] and seen[-1][1] > 0.5 * len(tris)
