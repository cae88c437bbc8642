"""Embree cross-check: front-face closest hits (back faces re-cast), ray classification, and the
golden datapath against Embree on small scenes."""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver.scenes.camera import primary_rays
from driver.check import (EMBREE_KEYS, compare, embree_closest_front, embree_json,
                          point_triangle_distance)
from driver.core.datapath import TRIANGLE, prepare_rays
from driver.scenes.scene import load_scene

F32 = np.float32
# docs/datapath.md#directed-cases: faces +z, seen from above
FRONT = [[1, -1, -1], [0, 1, -1], [-1, -1, -1]]
DOWN = [[0, 0, -1]]
# Embree's distances are a third-party float result: its kernels differ per vector ISA (SSE,
# AVX2, AVX-512), so t of an exact hit at 1 comes back as 1 or 0.99999994 (1 ulp below) depending
# on the CPU. Compare Embree's t within a few float32 ulps; only our datapath is compared bit for bit.
EMBREE_RTOL = 4 * float(np.finfo(np.float32).eps)


def tris(*t):
    return np.array(t, F32)


def rays(origins, dirs):
    return np.array(origins, F32).reshape(-1, 3), np.array(dirs, F32).reshape(-1, 3)


def golden_brute_force(tri, origins, dirs):
    """Closest hit of every ray against every triangle on the golden datapath (no BVH)."""
    be = driver.backend("golden")
    n, m = len(origins), len(tri)
    t = np.full(n, np.inf, F32)
    prim = np.full(n, -1, np.int64)
    for s in range(0, n, 64):
        r = prepare_rays(origins[s:s + 64], dirs[s:s + 64])
        req = np.repeat(r, m)
        req["opcode"] = TRIANGLE
        req["tri"] = np.tile(tri, (len(r), 1, 1))
        rsp = be.run(req)
        with np.errstate(all="ignore"):
            tt = np.where(rsp["tri_hit"] == 1, rsp["t_num"] / rsp["t_den"], F32(np.inf))
        tt = tt.reshape(len(r), m)
        j = np.argmin(tt, axis=1)                        # ties: lowest primitive id
        best = tt[np.arange(len(r)), j]
        t[s:s + 64] = best
        prim[s:s + 64] = np.where(np.isfinite(best), j, -1)
    return t, prim


# ---------------------------------------------------------------------------------------------
# Embree conventions and back-face re-casting

def test_embree_geometric_normal_is_outward_like_trimesh():
    """Embree's Ng has the direction of (B-A) x (C-A): a front face has dot(d, Ng) < 0."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    tri = tris(FRONT)
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tri)
    o, d = rays([[0, 0, 0]], DOWN)
    r = scene.run(o, d, output=1)
    ng = r["Ng"][0]
    assert r["primID"][0] == 0 and r["tfar"][0] == pytest.approx(1, rel=EMBREE_RTOL)
    assert np.dot(ng, np.cross(tri[0, 1] - tri[0, 0], tri[0, 2] - tri[0, 0])) > 0
    # ... and the datapath hits it (docs/datapath.md#directed-cases #2)
    assert np.dot(d[0], ng) < 0


def test_front_face_hit_and_miss():
    t, p = embree_closest_front(tris(FRONT), *rays([[0, 0, 0], [0, 0, 0]], [[0, 0, -1], [0, 0, 1]]))
    assert p.tolist() == [0, -1] and t[0] == pytest.approx(1, rel=EMBREE_RTOL)
    assert t[1] == np.inf                                  # a miss is exactly inf on every ISA
    assert t.dtype == np.float32 and p.dtype == np.int64


def test_back_face_is_recast_to_the_front_face_behind_it():
    # docs/datapath.md#directed-cases #1: a back face from above
    back = [[-1, -1, -1], [0, 1, -1], [1, -1, -1]]
    front = [[1, -1, -3], [0, 1, -3], [-1, -1, -3]]
    t, p = embree_closest_front(tris(back, front), *rays([[0, 0, 0]], DOWN))
    assert p.tolist() == [1] and t[0] == pytest.approx(3, rel=EMBREE_RTOL)
    # only the back face: a miss
    t, p = embree_closest_front(tris(back), *rays([[0, 0, 0]], DOWN))
    assert p.tolist() == [-1] and t[0] == np.inf


def test_recast_through_several_back_faces_and_from_an_origin_on_one():
    layers = [[[-1, -1, z], [0, 1, z], [1, -1, z]] for z in (-1, -1.000001, -2, -2.5)]
    front = [[1, -1, -4], [0, 1, -4], [-1, -1, -4]]
    o, d = rays([[0, 0, 0], [0, 0, -1], [0.1, -0.2, 0]], [[0, 0, -1], [0, 0, -1], [0, 0, -2]])
    t, p = embree_closest_front(tris(*layers, front), o, d)
    assert p.tolist() == [4, 4, 4]
    assert np.allclose(t, [4, 3, 2], rtol=1e-5)


def test_closed_mesh_seen_from_inside():
    """Inside a sphere every face is a back face: Embree hits them, re-casts and misses; with the
    winding flipped every ray hits a front face. Both agree with the golden datapath."""
    scene = load_scene("sphere")
    cam = type(scene.camera)((0.1, 0.05, -0.2), (1, 0.3, 0.2), (0, 0, 1), 100)
    o, d = primary_rays(cam, 12, 12)
    for tri, hits in ((scene.triangles, False), (scene.triangles[:, ::-1].copy(), True)):
        t, p = embree_closest_front(tri, o, d)
        assert ((p >= 0) == hits).all()
        gt, gp = golden_brute_force(tri, o, d)
        c = compare(gt, gp, t, p, tri, o, d)
        assert c["agree"] == len(o), c


# ---------------------------------------------------------------------------------------------
# classification

def test_compare_classifies_each_kind():
    # two triangles sharing the edge x = 0 (both face +z), and one far below
    left = [[0, -1, -1], [0, 1, -1], [-1, 0, -1]]
    right = [[0, 1, -1], [0, -1, -1], [1, 0, -1]]
    below = [[1, -1, -5], [0, 1, -5], [-1, -1, -5]]
    tri = tris(left, right, below)
    o, d = rays([[0, 0, 0]] * 5, [[0, 0, -1], [0, 0, -1], [0.5, 0, -1], [0.5, 0, -1], [0, 0, 1]])
    ours_t = np.array([1, 1, 1, 1, np.inf], F32)
    ours_p = np.array([0, 0, 1, 1, -1])
    emb_t = np.array([1, 1, 5, np.inf, np.inf], F32)
    emb_p = np.array([0, 1, 2, -1, -1])
    c = compare(ours_t, ours_p, emb_t, emb_p, tri, o, d)
    assert c["rays_compared"] == 5 and c["agree"] == 2
    assert c["edge_ties"] == 1 and c["edge_tie_rays"].tolist() == [1]
    assert c["prim_mismatch"] == 1 and c["prim_mismatch_rays"].tolist() == [2]
    assert c["hit_mismatch"] == 1 and c["hit_mismatch_rays"].tolist() == [3]
    assert c["max_t_rel_err"] == pytest.approx(0.8)
    j = embree_json(c)
    assert set(EMBREE_KEYS) <= set(j) and all(np.isscalar(v) for v in j.values())


def test_compare_same_t_but_not_on_the_other_triangle_is_a_mismatch():
    a = [[1, -1, -1], [0, 1, -1], [-1, -1, -1]]
    b = [[11, -1, -1], [10, 1, -1], [9, -1, -1]]           # same plane, far away
    o, d = rays([[0, 0, 0]], DOWN)
    c = compare(np.array([1], F32), np.array([0]), np.array([1], F32), np.array([1]),
                tris(a, b), o, d)
    assert c["prim_mismatch"] == 1 and c["edge_ties"] == 0


def test_point_triangle_distance():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 4 + [[[0, 0, 0], [1, 0, 0], [2, 0, 0]]],
                   float)
    p = np.array([[0.2, 0.2, 0.5], [2, 0, 0], [0.5, 0.5, 0], [-1, -1, 0], [1, 1, 0]], float)
    dist = point_triangle_distance(p, tri)
    assert np.allclose(dist, [0.5, 1, 0, np.sqrt(2), 1])


# ---------------------------------------------------------------------------------------------
# golden datapath against Embree on whole (small) frames

@pytest.mark.parametrize("name", ["sphere", "room", "soup"])
def test_golden_agrees_with_embree(name):
    scene = load_scene(name)
    o, d = primary_rays(scene.camera, 20, 20)
    tri = scene.triangles
    gt, gp = golden_brute_force(tri, o, d)
    et, ep = embree_closest_front(tri, o, d)
    c = compare(gt, gp, et, ep, tri, o, d)
    assert c["hit_mismatch"] == 0 and c["prim_mismatch"] == 0, c
    assert c["max_t_rel_err"] < 1e-5
    assert (gp >= 0).sum() > 20
