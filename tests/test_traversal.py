"""BVH4 traversal (docs/datapath.md#traversal, #statistics) on the golden backend against a
brute-force nearest-hit search."""

import json
import sys
import types

import numpy as np
import pytest

from driver import TRIANGLE, backend, prepare_rays
from driver import trace as driver_trace
from driver.bvh4 import build
from driver.tracer import TraceResult
from driver.tracer import trace as _trace
from support import meshes
from support.recording import RecordingBackend


def trace(*args, backend="golden", **options):
    """``driver.tracer.trace`` on the golden model unless a test names a backend: these tests
    check the traversal, and every backend gives the same responses (tests/test_rtl.py)."""
    return _trace(*args, backend=backend, **options)


def brute_force(tris, o, d, extent=np.inf):
    """Every (ray, triangle) pair as a TRIANGLE request on the golden backend; nearest t wins
    (t < extent). Returns (t (r,) float32, prim (r,) lowest index on ties, t_all (r, n))."""
    r, n = len(o), len(tris)
    req = prepare_rays(np.repeat(o, n, axis=0), np.repeat(d, n, axis=0),
                       np.repeat(np.broadcast_to(np.float32(extent), (r,)), n))
    req["opcode"] = TRIANGLE
    req["tri"] = np.tile(tris, (r, 1, 1))
    rsp = backend("golden").run(req)
    with np.errstate(all="ignore"):
        t = rsp["t_num"] / rsp["t_den"]
    ok = rsp["tri_hit"].astype(bool) & (t < req["extent"])
    t_all = np.where(ok, t, np.float32(np.inf)).astype(np.float32).reshape(r, n)
    best = t_all.min(axis=1)
    prim = np.where(np.isfinite(best), np.argmin(t_all, axis=1), -1)
    return best, prim, t_all


def assert_matches_brute_force(tris, o, d, extent=np.inf, **kw):
    """Traversal t equals the brute-force minimum bit for bit; prim equal, or (an exact tie)
    the traversal's triangle gives the identical t."""
    res = trace(build(tris), o, d, backend="golden", extent=extent, **kw)
    best, prim, t_all = brute_force(tris, np.asarray(o, np.float32), np.asarray(d, np.float32),
                                    extent)
    assert res.t.dtype == np.float32 and res.prim.dtype == np.int64
    assert np.array_equal(res.t.view(np.uint32), best.view(np.uint32))
    assert np.array_equal(res.hit, prim >= 0)
    same = res.prim == prim
    tie = ~same & (res.prim >= 0)
    assert np.array_equal(t_all[tie, res.prim[tie]].view(np.uint32), best[tie].view(np.uint32))
    assert (same | tie).all()
    return res


def axis_dirs():
    """All 6 axis directions, with signed zeros in the other components."""
    out = []
    for ax in range(3):
        for s in (1.0, -1.0):
            for z in (0.0, -0.0):
                v = [z, z, z]
                v[ax] = s
                out.append(v)
    return np.array(out, np.float32)


def rays_around(rng, n, lo, hi, tris):
    """n rays from origins uniform in [lo, hi]^3: a third aimed at random triangle points, a third
    random, a third axis-parallel."""
    o = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
    k = n // 3
    pick = tris[rng.integers(0, len(tris), k)]
    w = rng.dirichlet([1, 1, 1], k).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    d[:k] = np.einsum("ij,ijk->ik", w, pick) - o[:k]
    ax = axis_dirs()
    d[2 * k:] = ax[rng.integers(0, len(ax), n - 2 * k)]
    d[(d == 0).all(axis=1)] = 1
    return o, d


def test_soup():
    rng = np.random.default_rng(1)
    tris = meshes.soup(300, seed=4)
    o, d = rays_around(rng, 300, -2, 2, tris)
    res = assert_matches_brute_force(tris, o, d)
    assert 0.2 < res.hit.mean() < 0.9


def test_soup_rays_that_miss_everything():
    tris = meshes.soup(100, seed=5)
    rng = np.random.default_rng(2)
    o = rng.uniform(3, 4, (60, 3)).astype(np.float32)        # outside [-1.7, 1.7]^3, looking out
    d = np.abs(rng.normal(size=(60, 3))).astype(np.float32)
    d[:6] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, -0.0, 0], [0, 0, 1], [1, 1, 1]]
    res = assert_matches_brute_force(tris, o, d)
    assert not res.hit.any() and np.isposinf(res.t).all() and (res.prim == -1).all()
    assert (res.tri_ops == 0).all() and (res.box_ops == 1).all()


def test_room_from_inside():
    """Inward walls (flat, axis-aligned, sharing edges) and a crate, seen from inside, including
    axis-parallel rays and rays whose origin lies on a wall plane."""
    rng = np.random.default_rng(3)
    tris = meshes.box_room(3)
    o, d = rays_around(rng, 450, -0.9, 0.9, tris)
    o[:40, 0] = 3                                            # on the x = 3 wall plane
    d[:20] = axis_dirs()[rng.integers(0, 12, 20)]
    corners = tris[rng.integers(0, len(tris), 60), rng.integers(0, 3, 60)]
    d[60:120] = corners - o[60:120]                          # at shared grid vertices
    res = assert_matches_brute_force(tris, o, d)
    assert res.hit[40:].all()                               # a closed room: every ray hits a wall


def test_room_from_outside():
    """Outside, the near walls are back faces: rays pass through them to the far walls' inside."""
    rng = np.random.default_rng(4)
    tris = meshes.box_room(2)
    o = np.float32(8) * rng.normal(size=(200, 3)).astype(np.float32)
    o[:100] = np.sign(o[:100]) * 6
    d = rng.uniform(-1, 1, (200, 3)).astype(np.float32) - o / 8
    assert_matches_brute_force(tris, o, d)


@pytest.mark.parametrize("inside", [False, True])
def test_sphere(inside):
    rng = np.random.default_rng(5)
    tris = meshes.icosphere(2)
    if inside:                                              # only back faces: all miss
        o, d = rays_around(rng, 240, -0.5, 0.5, tris)
    else:
        u = rng.normal(size=(240, 3))
        o = (3 * u / np.linalg.norm(u, axis=1, keepdims=True)).astype(np.float32)
        d = (rng.uniform(-0.8, 0.8, (240, 3)) - o).astype(np.float32)
        d[:12] = -o[:12] * np.float32(0.5)
        o[12:24] = 3 * axis_dirs()                          # axis-parallel, signed zeros
        d[12:24] = -axis_dirs()
    res = assert_matches_brute_force(tris, o, d)
    assert res.hit.any() != inside


def test_extent():
    rng = np.random.default_rng(6)
    tris = meshes.soup(200, seed=7)
    o, d = rays_around(rng, 200, -1.5, 1.5, tris)
    extent = rng.uniform(0, 2, 200).astype(np.float32)
    res = assert_matches_brute_force(tris, o, d, extent=extent)
    assert (res.t[res.hit] < extent[res.hit]).all()
    assert_matches_brute_force(tris, o, d, extent=0.5)


def test_degenerate_mesh():
    rng = np.random.default_rng(7)
    tris = meshes.degenerate()
    o, d = rays_around(rng, 300, -1.5, 1.5, tris)
    dup = [5, 29, 31]                                        # three identical triangles
    d[:40] = tris[dup].mean(axis=(0, 1)) - o[:40]
    res = assert_matches_brute_force(tris, o, d)
    assert np.isin(res.prim[:40], dup).sum() > 5             # exact-t ties among duplicates


# ---- statistics and plumbing ------------------------------------------------------------------

def test_stats_and_steps():
    rng = np.random.default_rng(8)
    tris = meshes.box_room(2)
    o, d = rays_around(rng, 500, -0.9, 0.9, tris)
    be = RecordingBackend(backend("golden"))
    be.cycles                                               # property works before any run
    seen = []
    res = trace(tris, o, d, backend=be, progress=lambda done, total: seen.append((done, total)))
    s = res.stats
    assert isinstance(res, TraceResult)
    json.dumps(s)
    assert all(type(v) in (int, float, str) for v in s.values())
    assert set(s) == {"rays", "hits", "box_ops", "tri_ops", "ops", "cycles", "utilization",
                      "latency_cycles", "box_ops_per_ray", "tri_ops_per_ray",
                      "node_bytes_fetched", "sim_wall_s", "sim_cycles_per_s",
                      "frame_us_at_1ghz", "backend"}
    assert s["rays"] == 500 and s["hits"] == int(res.hit.sum()) == 500
    assert s["box_ops"] == res.box_ops.sum() == res.step_box_requests.sum()
    assert s["tri_ops"] == res.tri_ops.sum()
    assert s["ops"] == s["box_ops"] + s["tri_ops"] == res.step_requests.sum()
    assert s["latency_cycles"] == 11
    assert s["cycles"] >= s["ops"] + s["latency_cycles"]
    assert s["cycles"] == s["ops"] + 11 * len(res.step_requests)    # golden: ideal pipeline
    assert s["utilization"] == s["ops"] / s["cycles"]
    assert s["node_bytes_fetched"] == 128 * s["box_ops"] + 64 * s["tri_ops"]
    assert s["box_ops_per_ray"] == s["box_ops"] / 500 and s["tri_ops_per_ray"] == s["tri_ops"] / 500
    assert s["frame_us_at_1ghz"] == s["cycles"] / 1000
    assert s["sim_wall_s"] > 0 and s["sim_cycles_per_s"] == s["cycles"] / s["sim_wall_s"]
    assert s["backend"] == "recorder"
    assert (res.box_ops >= 1).all()
    # one run() per step, QUADBOX and TRIANGLE interleaved in ray order, tags = ray index
    assert [len(c) for c in be.calls] == res.step_requests.tolist()
    assert [int((c["opcode"] == 1).sum()) for c in be.calls] == res.step_box_requests.tolist()
    assert all((np.diff(c["tag"].astype(np.int64)) > 0).all() for c in be.calls)
    assert len(be.calls[0]) == 500 and (be.calls[0]["opcode"] == 1).all()
    assert any(len(np.unique(c["opcode"])) == 2 for c in be.calls)
    # progress once per step, ending at (n, n)
    assert len(seen) == len(be.calls) and seen[-1] == (500, 500)
    assert all(a[0] <= b[0] for a, b in zip(seen, seen[1:]))


def test_backend_tag_mismatch_raises():
    tris = meshes.soup(20)
    with pytest.raises(RuntimeError):
        trace(tris, [[0, 0, -3]] * 4, [[0, 0, 1]] * 4,
              backend=RecordingBackend(backend("golden"), corrupt=True))


def test_inputs_and_names(monkeypatch):
    tris = meshes.icosphere(1)
    o, d = [[0, 0, -3], [5, 5, 5]], [[0, 0, 1], [1, 0, 0]]
    ref = trace(build(tris), o, d)
    import trimesh
    mesh = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3),
                           process=False)
    fake = types.ModuleType("driver.scenes.scene")
    fake.load = fake.load_scene = lambda name: mesh if name == "ball" else None
    monkeypatch.setitem(sys.modules, "driver.scenes.scene", fake)
    for scene in (tris, mesh, "ball"):
        res = trace(scene, o, d, backend="golden")
        assert np.array_equal(res.t, ref.t) and np.array_equal(res.prim, ref.prim)
    res = driver_trace(tris, o, d, backend="golden")
    assert np.array_equal(res.prim, ref.prim) and res.stats["backend"] == "golden"
    assert ref.hit.tolist() == [True, False]


def test_empty_and_bad_rays():
    bvh = build(meshes.soup(10))
    res = trace(bvh, np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(res.t) == 0 and res.stats["rays"] == 0 and res.stats["ops"] == 0
    with pytest.raises(ValueError):
        trace(bvh, [[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(ValueError):
        trace(bvh, [[0, 0, np.nan]], [[0, 0, 1]])


def test_bunny_view_matches_embree():
    """A 32 x 32 view of the bunny: hits and primitives agree with Embree except at edge ties."""
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    import trimesh
    m = meshes.bunny()
    bvh = build(m)
    lo, hi = m.bounds
    c, ext = (lo + hi) / 2, (hi - lo).max()
    u = np.linspace(-0.55, 0.55, 32) * ext
    x, y = np.meshgrid(u, -u)
    eye = c + [0, 0, 1.6 * ext]
    d = c + np.stack([x, y, np.zeros_like(x)], -1).reshape(-1, 3) - eye
    o = np.broadcast_to(eye, d.shape)
    res = trace(bvh, o, d)
    tri = bvh.triangles.reshape(-1, 3).astype(np.float64)
    em = RayMeshIntersector(trimesh.Trimesh(tri, np.arange(len(tri)).reshape(-1, 3),
                                            process=False))
    first = em.intersects_first(np.asarray(o, np.float32).astype(np.float64),
                                d.astype(np.float32).astype(np.float64))
    assert res.hit.sum() > 300
    assert (res.prim == first).mean() > 0.99


# ---- the distance-culled stack (trace(cull_stack=True)) -----------------------------------------

def _bunny_view(n=32):
    m = meshes.bunny()
    lo, hi = m.bounds
    c, ext = (lo + hi) / 2, (hi - lo).max()
    u = np.linspace(-0.55, 0.55, n) * ext
    x, y = np.meshgrid(u, -u)
    eye = c + [0, 0, 1.6 * ext]
    d = c + np.stack([x, y, np.zeros_like(x)], -1).reshape(-1, 3) - eye
    return np.asarray(m.triangles, np.float32), np.broadcast_to(eye, d.shape), d


def _cull_cases():
    rng = np.random.default_rng(11)
    room = meshes.box_room(3)
    soup = meshes.soup(300, seed=4)
    sphere = meshes.icosphere(2)
    u = rng.normal(size=(240, 3))
    so = (3 * u / np.linalg.norm(u, axis=1, keepdims=True)).astype(np.float32)
    return {
        "bunny": (*_bunny_view(), {}),
        "room_inside": (room, *rays_around(rng, 450, -0.9, 0.9, room), {}),
        "soup": (soup, *rays_around(rng, 300, -2, 2, soup), {}),
        "soup_extent": (soup, *rays_around(rng, 300, -2, 2, soup),
                        {"extent": rng.uniform(0, 3, 300).astype(np.float32)}),
        "sphere_double_sided": (sphere, so, (rng.uniform(-0.8, 0.8, (240, 3)) - so)
                                .astype(np.float32), {"double_sided": True}),
    }


@pytest.mark.parametrize("case", list(_cull_cases()))
def test_culled_stack_same_hits_fewer_box_requests(case):
    """Dropping box nodes beyond the nearest hit changes no hit (bits of t, primitive), no
    triangle request, and removes exactly the box requests that would have missed: per frame,
    box ops without culling = box ops with culling + stack culls."""
    tris, o, d, kw = _cull_cases()[case]
    bvh = build(tris)
    plain = trace(bvh, o, d, **kw)
    cull = trace(bvh, o, d, cull_stack=True, **kw)
    assert np.array_equal(plain.t.view(np.uint32), cull.t.view(np.uint32))
    assert np.array_equal(plain.prim, cull.prim)
    assert np.array_equal(plain.tri_ops, cull.tri_ops)
    assert (cull.box_ops <= plain.box_ops).all() and (cull.box_ops >= 1).all()
    assert "stack_culls" not in plain.stats
    assert plain.stats["box_ops"] == cull.stats["box_ops"] + cull.stats["stack_culls"]
    assert cull.stats["ops"] == cull.box_ops.sum() + cull.tri_ops.sum() == cull.step_requests.sum()
    if case == "bunny":
        assert cull.stats["stack_culls"] > 0.05 * plain.stats["box_ops"]
    if case != "bunny":                                     # brute force: small meshes only
        assert_matches_brute_force(tris, o, d, cull_stack=True, **kw)


def test_culled_stack_any_hit_culls_nothing():
    """An any-hit ray ends at its first accepted triangle, so its nearest never falls below the
    extent while it still has a stack: nothing is culled, every count is the plain one."""
    tris, o, d = _bunny_view(16)
    bvh = build(tris)
    plain = trace(bvh, o, d, any_hit=True)
    cull = trace(bvh, o, d, any_hit=True, cull_stack=True)
    assert cull.stats["stack_culls"] == 0
    assert np.array_equal(plain.box_ops, cull.box_ops) and np.array_equal(plain.prim, cull.prim)


def test_culled_stack_on_the_rtl_with_replay():
    """On the Verilated datapath: the same bits as the golden model with culling, and the RT-unit
    replay of the culled frame's requests verifies every response."""
    tris, o, d = _bunny_view(24)
    bvh = build(tris)
    gold = trace(bvh, o, d, backend="golden", cull_stack=True)
    rtl = trace(bvh, o, d, backend="rtl", cull_stack=True, rays_in_flight=64, datapath="rtl")
    assert np.array_equal(gold.t.view(np.uint32), rtl.t.view(np.uint32))
    assert np.array_equal(gold.box_ops, rtl.box_ops)
    assert rtl.stats["stack_culls"] == gold.stats["stack_culls"] > 0
    assert rtl.stats["responses_verified"] is True
