"""The Embree check's adjudication (driver/adjudicate.py): every class reproduced on a small
constructed scene, the datapath's own answers on the two-sided sheet that fools Embree's
culling emulation, and the failing verdict."""

from __future__ import annotations

import numpy as np

from driver.adjudicate import CLASSES, adjudicate
from driver.check import check_rays, failed, merge_checks
from driver.tracer import trace

F32 = np.float32
# a front face (seen from +z) at z = 0, and a second front face behind it at z = -5
NEAR = [[-1, -1, 0], [1, -1, 0], [0, 1, 0]]
FAR = [[-2, -2, -5], [2, -2, -5], [0, 2, -5]]
# the two-sided sheet: the near face once more with the opposite winding (a back face seen from
# +z), 2e-6 in front of the front face: Embree's culling emulation meets the back face first,
# re-casts past it by 1e-6 of (t + scale) and so steps over the front face too
SHEET_BACK = [[-1, -1, 2e-6], [0, 1, 2e-6], [1, -1, 2e-6]]
DOWN = ((0.0, 0.0, 10.0), (0.0, 0.0, -1.0))


def ray(o, d, n=1):
    return np.tile(np.array(o, F32), (n, 1)), np.tile(np.array(d, F32), (n, 1))


def classes(result) -> dict:
    return result["adjudicated"]["classes"]


def test_agree_and_every_class_is_counted():
    tri = np.array([NEAR, FAR], F32)
    o, d = ray(*DOWN)
    hit = trace(tri, o, d, backend="golden")
    assert hit.prim.tolist() == [0]
    r = check_rays(tri, o, d, np.inf, hit.t, hit.prim, False, False)
    assert classes(r) == {"agree": 1, "edge_tie": 0, "embree_wrong": 0, "datapath_wrong": 0}
    assert set(r["adjudicated"]["explain"]) == set(CLASSES)
    assert not failed(r)


def test_embree_wrong_on_the_two_sided_sheet_traced_by_the_datapath():
    """The bathroom's case: the datapath (culling back faces) hits the front face of a two-sided
    sheet; Embree's emulation of culling re-casts past the coincident back face and reports the
    face behind. Exact arithmetic says ours is the nearest front face: Embree wrong, counted,
    not failed, and explained."""
    tri = np.array([SHEET_BACK, NEAR, FAR], F32)
    o, d = ray(*DOWN)
    hit = trace(tri, o, d, backend="golden")
    assert hit.prim.tolist() == [1]                        # the front face, not the back face
    r = check_rays(tri, o, d, np.inf, hit.t, hit.prim, False, False)
    assert r["prim_mismatch"] == 1                         # Embree says the far face
    assert classes(r)["embree_wrong"] == 1 and classes(r)["datapath_wrong"] == 0
    (rec,) = r["adjudicated"]["rays"]
    assert rec["embree_prim"] == 2 and rec["back_prim"] == 0
    assert "two-sided sheet" in rec["reason"]
    assert abs(rec["ours_t_exact"] - 10.0) < 1e-5 and abs(rec["embree_t_exact"] - 15.0) < 1e-5
    assert not failed(merge_checks([r]))


def test_edge_tie_on_a_shared_edge():
    """Two triangles sharing the edge x = 0: a ray down the edge hits both at the same t."""
    left = [[0, -1, 0], [0, 1, 0], [-1, 0, 0]]
    right = [[0, -1, 0], [1, 0, 0], [0, 1, 0]]
    tri = np.array([left, right], F32)
    o, d = ray((0.0, 0.25, 3.0), (0.0, 0.0, -1.0))
    v = adjudicate(tri, o, d, np.inf, (np.array([3.0], F32), np.array([0])),
                   (np.array([3.0], F32), np.array([1])), False, False, 3.0)
    assert v.counts()["edge_tie"] == 1
    assert "same t" in v.records[0]["reason"]


def test_datapath_wrong_when_a_nearer_hit_is_reported_farther():
    """A datapath that reports the far face while the near one is hit exactly: the check fails."""
    tri = np.array([NEAR, FAR], F32)
    o, d = ray(*DOWN)
    r = check_rays(tri, o, d, np.inf, np.array([15.0], F32), np.array([1]), False, False)
    assert classes(r)["datapath_wrong"] == 1
    assert failed(r)


def test_datapath_wrong_when_the_reported_triangle_is_missed():
    """A hit on a triangle the ray passes beside (off its edges by far more than the band)."""
    tri = np.array([NEAR, FAR], F32)
    o, d = ray((5.0, 5.0, 10.0), (0.0, 0.0, -1.0))
    r = check_rays(tri, o, d, np.inf, np.array([10.0], F32), np.array([0]), False, False)
    assert classes(r)["datapath_wrong"] == 1
    assert "outside its triangle" in r["adjudicated"]["rays"][0]["reason"]


def test_embree_wrong_when_ours_is_the_nearest_among_all_triangles():
    """Embree's candidate is farther (or missing) and nothing nearer than ours exists in the
    scene: the search over every triangle settles it, for the rays that need it among others
    (rays 0 and 3 agree; 1 and 2 are searched; on ray 4 Embree's nearer hit shows the
    datapath's error)."""
    hidden = [[-0.5, -0.5, 5.0], [0.5, -0.5, 5.0], [0.0, 0.5, 5.0]]   # between camera and NEAR
    tri = np.array([NEAR, FAR, hidden], F32)
    o, d = ray((0.9, -0.9, 10.0), (0.0, 0.0, -1.0), n=5)
    o[[1, 4]] = (0.0, 0.0, 10.0)
    o[3] = (1.5, -1.5, 10.0)
    our_t = np.array([10.0, 5.0, 10.0, 15.0, 10.0], F32)
    ours = np.array([0, 2, 0, 1, 0])
    o[2] = (0.9, -0.9, 10.0)
    emb_t = np.array([10.0, 15.0, np.inf, 15.0, 5.0], F32)
    emb = np.array([0, 1, -1, 1, 2])
    v = adjudicate(tri, o, d, np.inf, (our_t, ours), (emb_t, emb), False, False, 10.0)
    assert [CLASSES[c] for c in v.cls] == ["agree", "embree_wrong", "embree_wrong", "agree",
                                           "datapath_wrong"]
    reasons = {r["ray"]: r["reason"] for r in v.records}
    assert "Embree's is farther" in reasons[1] and "Embree reports no hit" in reasons[2]


def test_any_hit_classes():
    """Occlusion rays: any triangle within the extent is right. Ours occluded where Embree is
    not: Embree wrong when our hit is exact and clear; a reported miss where a triangle is hit
    clearly within the extent: datapath wrong; a hit at the very end of the extent: a tie."""
    tri = np.array([NEAR], F32)
    o, d = ray(*DOWN, n=3)
    ext = np.array([20.0, 20.0, 10.0], np.float64)
    our_t = np.array([10.0, np.inf, 10.0], F32)
    our_prim = np.array([0, -1, 0])
    emb_occ = np.array([False, True, False])
    v = adjudicate(tri, o, d, ext, (our_t, our_prim),
                   (np.array([np.inf, 10.0, np.inf], F32), np.array([-1, 0, -1])), True, False,
                   10.0, emb_occluded=emb_occ)
    assert [CLASSES[c] for c in v.cls] == ["embree_wrong", "datapath_wrong", "edge_tie"]


def test_the_check_on_real_occlusion_rays_agrees():
    tri = np.array([NEAR, FAR], F32)
    o, d = ray((0.0, 0.0, 10.0), (0.0, 0.0, -1.0), n=2)
    ext = np.array([20.0, 5.0], F32)
    hit = trace(tri, o, d, backend="golden", extent=ext, any_hit=True)
    assert hit.hit.tolist() == [True, False]
    r = check_rays(tri, o, d, ext, hit.t, hit.prim, True, False)
    assert classes(r)["agree"] == 2 and not failed(r)
