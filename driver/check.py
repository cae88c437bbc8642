"""Cross-check of closest hits against Intel Embree (embreex).

``embree_closest_front`` gives Embree's closest *front-face* hit per ray (the datapath culls back
faces, docs/datapath.md#triangle; Embree 4 does not, so back-face hits are re-cast from just past
the hit). ``compare`` classifies every ray of our result against Embree's:

- agree: same primitive, or both miss;
- hit/miss mismatch: one hits, the other misses;
- edge tie: different primitives, but both legally contain the hit point: the t values agree to
  ``T_REL`` and our hit point lies on Embree's triangle and Embree's on ours (within a distance
  tolerance): a hit on an edge or vertex shared by two triangles, or on coplanar overlaps;
- primitive mismatch: any other different primitive (unexplained).

``embree_json(result)`` keeps the docs/datapath.md#statistics ``embree`` object (scalars only).
``embree_sample``: the rays of an instanced scene too large to flatten that a check can take
exactly, with the world triangles of the instances they cross.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

from .core.words import plural
from .instances import Instances, world_boxes

T_REL = 1e-5          # relative t agreement of an edge tie
POINT_REL = 1e-5      # hit point to triangle distance, relative to the scene's coordinate scale
MAX_RECAST = 64       # bounded back-face re-casting per ray
NEAR_REL = 1e-3       # t errors of hits nearer than this fraction of the scene's size: see check_rays
EMBREE_KEYS = ("rays_compared", "hit_mismatch", "prim_mismatch", "edge_ties", "max_t_rel_err")


def embree_closest_front(triangles, origins, dirs):
    """Closest front-face hit per ray with Embree.

    triangles : (m, 3, 3) float32 A, B, C; front faces have d . ((B-A) x (C-A)) < 0
    origins, dirs : (n, 3) float32 rays (t measured in units of |dir|; no upper extent)
    Returns (t (n,) float32, inf on a miss; prim (n,) int64, -1 on a miss).

    A ray whose closest hit is a back face (or a degenerate triangle, whose normal is zero) is
    re-cast, all such rays as one batch, from just past the hit (``1e-6`` relative, more if it hits
    the same face again), at most ``MAX_RECAST`` times; a ray still on back faces after that is
    reported as a miss. Limitation: a front face coincident with (or within ~1e-6 relative behind)
    a back face, as in double-sided sheets made of two opposite triangles, is skipped.
    """
    tri = np.ascontiguousarray(triangles, np.float32).reshape(-1, 3, 3)
    o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)
    d = np.ascontiguousarray(dirs, np.float32).reshape(-1, 3)
    n = len(o)
    t = np.full(n, np.inf)
    prim = np.full(n, -1, np.int64)
    if n == 0 or len(tri) == 0:
        return t.astype(np.float32), prim
    scene = _embree_scene(triangles if isinstance(triangles, np.ndarray) else tri)

    rows = np.arange(n)                   # rays still being cast
    base = np.zeros(n)                    # t (units of d) of the current cast origin
    last = np.full(n, -1, np.int64)       # back face the current cast starts on
    step = np.full(n, 1e-6)               # relative advance past a back face
    for _ in range(MAX_RECAST + 1):
        if not len(rows):
            break
        oo = (o[rows].astype(np.float64) + base[rows, None] * d[rows]).astype(np.float32)
        r = scene.run(oo, d[rows], output=1)
        p = r["primID"].astype(np.int64)
        tt = base[rows] + r["tfar"].astype(np.float64)
        hit = p >= 0
        front = np.zeros(len(rows), bool)
        hp = tri[p[hit]]                  # the faces hit: their normals (float32 cross product)
        normal = np.cross(hp[:, 1] - hp[:, 0], hp[:, 2] - hp[:, 0]).astype(np.float64)
        front[hit] = np.einsum("ij,ij->i", d[rows[hit]].astype(np.float64), normal) < 0
        done = ~hit | front
        t[rows[done & hit]] = tt[done & hit]
        prim[rows[done & hit]] = p[done & hit]
        # back face: restart just past it (further, if the restart hit that same face again)
        back = rows[~done]
        same = p[~done] == last[back]
        step[back] = np.where(same, step[back] * 4, 1e-6)
        last[back] = p[~done]
        tb = tt[~done]
        scale = np.abs(o[back]).max(1) / np.maximum(np.abs(d[back]).max(1), 1e-30)
        base[back] = tb + step[back] * (np.abs(tb) + scale) + 1e-30
        rows = back
    return t.astype(np.float32), prim


def compare(our_t, our_prim, emb_t, emb_prim, triangles, origins, dirs) -> dict:
    """Classify every ray (see module docstring).

    Returns a dict with the keys ``rays_compared, hit_mismatch, prim_mismatch, edge_ties,
    max_t_rel_err`` (max over rays where both hit), plus ``agree`` and index arrays
    ``hit_mismatch_rays, prim_mismatch_rays, edge_tie_rays`` for debugging.
    """
    our_t, emb_t = np.asarray(our_t, np.float64), np.asarray(emb_t, np.float64)
    our_prim, emb_prim = np.asarray(our_prim, np.int64), np.asarray(emb_prim, np.int64)
    tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n = len(our_t)
    if not (len(our_prim) == len(emb_t) == len(emb_prim) == len(o) == len(d) == n):
        raise ValueError("compare: all per-ray arrays must have the same length")
    ours, theirs = our_prim >= 0, emb_prim >= 0
    both = ours & theirs
    hit_mismatch = np.flatnonzero(ours != theirs)
    differ = np.flatnonzero(both & (our_prim != emb_prim))

    tie = np.zeros(len(differ), bool)
    if len(differ):
        scale = max(np.abs(tri).max(), np.abs(o).max(), 1e-30)
        tol = POINT_REL * scale
        ta, tb = our_t[differ], emb_t[differ]
        t_ok = np.abs(ta - tb) <= T_REL * np.maximum(np.abs(tb), 1e-30) + tol / np.maximum(
            np.linalg.norm(d[differ], axis=1), 1e-30)
        pa = o[differ] + ta[:, None] * d[differ]
        pb = o[differ] + tb[:, None] * d[differ]
        on_theirs = point_triangle_distance(pa, tri[emb_prim[differ]]) <= tol
        on_ours = point_triangle_distance(pb, tri[our_prim[differ]]) <= tol
        tie = t_ok & on_theirs & on_ours

    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(our_t[both] - emb_t[both]) / np.maximum(np.abs(emb_t[both]), 1e-30)
    return {
        "rays_compared": int(n),
        "hit_mismatch": int(len(hit_mismatch)),
        "prim_mismatch": int((~tie).sum()),
        "edge_ties": int(tie.sum()),
        "max_t_rel_err": float(rel.max()) if len(rel) else 0.0,
        "agree": int(n - len(hit_mismatch) - len(differ)),
        "hit_mismatch_rays": hit_mismatch,
        "prim_mismatch_rays": differ[~tie],
        "edge_tie_rays": differ[tie],
    }


def embree_json(result: dict) -> dict:
    """The docs/datapath.md#statistics ``embree`` object (plus ``agree`` and, when the check
    adjudicated, ``adjudicated``) from a ``compare`` or ``check`` result."""
    out = {k: result[k] for k in EMBREE_KEYS + ("agree",)}
    if "adjudicated" in result:
        out["adjudicated"] = result["adjudicated"]
    return out


def check(triangles, origins, dirs, our_t, our_prim, double_sided: bool = False) -> dict:
    """Run Embree on the same rays (any face when ``double_sided``, as the frame was traced with
    NO_CULL; else front faces only), ``compare`` and adjudicate every disagreement
    (``driver.adjudicate``); the result also holds Embree's own ``embree_t`` and ``embree_prim``
    arrays for debugging."""
    from .adjudicate import adjudicate  # numba: loaded when a check runs
    emb_t, emb_prim = embree_closest(triangles, origins, dirs, double_sided)
    result = compare(our_t, our_prim, emb_t, emb_prim, triangles, origins, dirs)
    result.update(embree_t=emb_t, embree_prim=emb_prim)
    result["adjudicated"] = _adjudicated(adjudicate(
        triangles, origins, dirs, np.inf, (our_t, our_prim), (emb_t, emb_prim), False,
        double_sided, _scale(triangles, origins)))
    return result


def _adjudicated(verdicts) -> dict:
    from .adjudicate import EXPLAIN     # numba: loaded when a check runs
    return {"classes": verdicts.counts(), "explain": dict(EXPLAIN), "rays": verdicts.records}


def failed(embree: dict | None) -> bool:
    """Whether an ``embree`` object fails the check: rays classified ``datapath_wrong`` when
    it was adjudicated, else any hit/miss or primitive mismatch."""
    if not embree:
        return False
    if "adjudicated" in embree:
        return embree["adjudicated"]["classes"]["datapath_wrong"] > 0
    return bool(embree["hit_mismatch"] or embree["prim_mismatch"])


def point_triangle_distance(p, tri):
    """Euclidean distance from points p (n, 3) to triangles tri (n, 3, 3), float64; degenerate
    triangles (segments, points) are handled by falling back to the nearest edge."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    # distance to the three edges (covers the boundary and every degenerate case)
    dist = np.minimum(np.minimum(_segment_distance(p, a, b), _segment_distance(p, b, c)),
                      _segment_distance(p, c, a))
    # interior: project onto the plane and test barycentrics
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.einsum("ij,ij->i", p - a, n) / nn
        q = p - h[:, None] * n
        inside = ok.copy()
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("ij,ij->i", np.cross(v - u, q - u), n) >= 0
        plane = np.abs(h) * np.sqrt(nn)
    return np.where(inside, np.minimum(plane, dist), dist)


def _segment_distance(p, a, b):
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(den > 0, np.einsum("ij,ij->i", p - a, ab) / den, 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * ab), axis=1)


# ----------------------------------------------------------------------------------------------
# Secondary rays: extents, any-hit rays and double-sided triangles (docs/datapath.md#traversal,
# docs/workloads.md#ray-types)


_SCENES: dict = {}     # id(triangle array) -> (weak reference to it, its Embree scene)
_SCENES_LOCK = threading.Lock()      # one build at a time; a thread wanting it waits for it


def _embree_scene(triangles):
    """The Embree scene of a triangle array, built once per array object (tiles and ray types of
    one frame check against the same scene, from any thread)."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    key = id(triangles)
    with _SCENES_LOCK:
        hit = _SCENES.get(key)
        if hit is not None and hit[0]() is triangles:
            return hit[1]
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, np.ascontiguousarray(triangles, np.float32).reshape(-1, 3, 3))
        if isinstance(triangles, np.ndarray):
            for k in [k for k, (ref, _) in _SCENES.items() if ref() is None]:
                del _SCENES[k]
            _SCENES[key] = (weakref.ref(triangles), scene)
        return scene


def prepare_check(triangles) -> threading.Thread:
    """Start building what a check of ``triangles`` needs (its Embree scene, the exact
    adjudication's compiled code) on a thread of its own, so that it overlaps the tracing; the
    check waits for it where it needs it. Returns the thread (join it before the process ends).
    A failure here is left to the check, which does the same work and reports it."""
    def work():
        try:
            from . import adjudicate  # noqa: F401  (numba)
            if isinstance(triangles, np.ndarray):
                _embree_scene(triangles)
        except Exception:       # the check repeats it and reports the error
            pass
    thread = threading.Thread(target=work, name="rayflex-check-setup", daemon=True)
    thread.start()
    return thread


def embree_closest(triangles, origins, dirs, double_sided: bool = False):
    """Closest hit per ray: any face when ``double_sided`` (Embree does not cull, like NO_CULL),
    else the closest front face (``embree_closest_front``). Returns (t, prim) as that does."""
    if not double_sided:
        return embree_closest_front(triangles, origins, dirs)
    o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)
    d = np.ascontiguousarray(dirs, np.float32).reshape(-1, 3)
    if not len(o) or not len(triangles):
        return np.full(len(o), np.inf, np.float32), np.full(len(o), -1, np.int64)
    r = _embree_scene(triangles).run(o, d, output=1)
    prim = r["primID"].astype(np.int64)
    return np.where(prim >= 0, r["tfar"], np.inf).astype(np.float32), np.where(prim >= 0, prim, -1)


def embree_occluded(triangles, origins, dirs, extent, double_sided: bool = False) -> np.ndarray:
    """Whether each ray meets a triangle with t < extent: Embree's occlusion query when
    ``double_sided``; with culling, whether the closest front face lies within the extent."""
    o = np.ascontiguousarray(origins, np.float32).reshape(-1, 3)
    d = np.ascontiguousarray(dirs, np.float32).reshape(-1, 3)
    ext = np.ascontiguousarray(np.broadcast_to(np.asarray(extent, np.float32), (len(o),)))
    if not len(o) or not len(triangles):
        return np.zeros(len(o), bool)
    if double_sided:
        return _embree_scene(triangles).run(o, d, dists=ext.copy(), query="OCCLUDED") != -1
    t, _ = embree_closest_front(triangles, o, d)
    return t < ext


def exact_t(triangles, prim, origins, dirs) -> np.ndarray:
    """t of the intersection of each ray with the plane of its triangle, in float64 (the exact
    value our float32 t approximates)."""
    tri = np.asarray(triangles, np.float64)[prim]
    o, d = np.asarray(origins, np.float64), np.asarray(dirs, np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("ij,ij->i", tri[:, 0] - o, n) / np.einsum("ij,ij->i", d, n)


def check_rays(triangles, origins, dirs, extent, our_t, our_prim, any_hit: bool,
               double_sided: bool) -> dict:
    """Embree check of one batch of rays (docs/datapath.md#statistics ``embree`` keys plus
    ``max_t_rel_err_exact``: our t against the exact plane intersection of our triangle, relative to
    that t, or to ``NEAR_REL`` of the scene's size for nearer hits, where a secondary ray starting
    next to a wall meets it after a tiny t that float32 scene coordinates cannot resolve
    relatively). Closest-hit rays: ``compare`` with Embree's closest hit within the extent. Any-hit
    rays: hit/miss against Embree's occlusion query; a hit whose point is not on its triangle or not
    within the extent counts as a primitive mismatch (any triangle in the extent is a correct
    answer)."""
    from .adjudicate import adjudicate  # numba: loaded when a check runs
    tri = np.asarray(triangles)
    prim = np.asarray(our_prim, np.int64)
    ext = np.broadcast_to(np.asarray(extent, np.float64), prim.shape)
    ours = prim >= 0
    scale = _scale(tri, origins)
    if not any_hit:
        emb_t, emb_prim = embree_closest(tri, origins, dirs, double_sided)
        out = emb_t >= ext
        emb_t, emb_prim = np.where(out, np.inf, emb_t), np.where(out, -1, emb_prim)
        result = compare(our_t, prim, emb_t, emb_prim, tri, origins, dirs)
        verdicts = adjudicate(tri, origins, dirs, ext, (our_t, prim), (emb_t, emb_prim), False,
                              double_sided, scale)
    else:
        theirs = embree_occluded(tri, origins, dirs, ext, double_sided)
        o, d = np.asarray(origins, np.float64), np.asarray(dirs, np.float64)
        rows = np.flatnonzero(ours)
        p = o[rows] + np.asarray(our_t, np.float64)[rows, None] * d[rows]
        off = (point_triangle_distance(p, tri[prim[rows]].astype(np.float64))
               > POINT_REL * scale)
        bad = rows[off | (np.asarray(our_t)[rows] >= ext[rows])]
        result = {"rays_compared": int(len(prim)),
                  "hit_mismatch": int((ours != theirs).sum()), "prim_mismatch": int(len(bad)),
                  "edge_ties": 0, "hit_mismatch_rays": np.flatnonzero(ours != theirs),
                  "prim_mismatch_rays": bad}
        # Embree's occluder of the rays it occludes and we do not: its closest valid hit
        emb_t = np.full(len(prim), np.inf, np.float32)
        emb_prim = np.full(len(prim), -1, np.int64)
        only = np.flatnonzero(theirs & ~ours)
        if len(only):
            et, ep = embree_closest(tri, np.asarray(origins)[only], np.asarray(dirs)[only],
                                    double_sided)
            inside = et < ext[only]
            emb_t[only[inside]], emb_prim[only[inside]] = et[inside], ep[inside]
        verdicts = adjudicate(tri, origins, dirs, ext, (our_t, prim), (emb_t, emb_prim), True,
                              double_sided, scale,
                              rays=np.union1d(np.flatnonzero(ours != theirs), bad),
                              emb_occluded=theirs)
    result["adjudicated"] = _adjudicated(verdicts)
    rows = np.flatnonzero(ours)
    d = np.asarray(dirs, np.float64)[rows]
    with np.errstate(invalid="ignore", divide="ignore"):
        te = exact_t(tri, prim[rows], np.asarray(origins)[rows], d)
        # hits closer than NEAR_REL of the scene's size are measured against that distance: there
        # the float32 coordinates (of the scene and of P - o), not the datapath, set the error
        near = NEAR_REL * _scale(tri, origins) / np.maximum(np.linalg.norm(d, axis=1), 1e-30)
        rel = (np.abs(np.asarray(our_t, np.float64)[rows] - te)
               / np.maximum(np.abs(te), near))
    result["max_t_rel_err_exact"] = float(np.nanmax(rel)) if len(rel) else 0.0
    if any_hit:
        result["max_t_rel_err"] = result["max_t_rel_err_exact"]
    return result


def _scale(tri, origins) -> float:
    """The scene's coordinate scale: the largest |coordinate| of its triangles and ray origins."""
    t = np.asarray(tri)
    o = np.asarray(origins)
    return max(float(np.abs(t).max()) if t.size else 0.0,
               float(np.abs(o).max()) if o.size else 0.0, 1e-30)


def merge_checks(parts: list[dict]) -> dict:
    """The docs/datapath.md#statistics ``embree`` object of several checked batches (counts add,
    errors take the maximum)."""
    out = {k: 0 for k in ("rays_compared", "hit_mismatch", "prim_mismatch", "edge_ties")}
    for p in parts:
        for k in out:
            out[k] += int(p[k])
    for k in ("max_t_rel_err", "max_t_rel_err_exact"):
        out[k] = max((float(p.get(k, 0.0)) for p in parts), default=0.0)
    if parts and all("adjudicated" in p for p in parts):
        from .adjudicate import merge as merge_adjudicated
        out["adjudicated"] = merge_adjudicated([p["adjudicated"] for p in parts])
    return out


def summary(e: dict) -> str:
    """The one line the commands print for an ``embree`` object: rays compared, each kind of
    mismatch, the largest t difference and, when it was adjudicated, the count of each class."""
    text = (f"embree: {plural(e['rays_compared'], 'ray')} compared, "
            f"{plural(e['hit_mismatch'], 'hit/miss mismatch', 'hit/miss mismatches')}, "
            f"{plural(e['prim_mismatch'], 'primitive mismatch', 'primitive mismatches')}, "
            f"{plural(e['edge_ties'], 'edge tie')}, max t rel err {e['max_t_rel_err']:.2g}")
    if "adjudicated" in e:
        text += "; decided exactly: " + ", ".join(
            plural(v, "edge tie") if k == "edge_tie" else f"{v} {k.replace('_', ' ')}"
            for k, v in e["adjudicated"]["classes"].items())
    return text


EMBREE_SAMPLE_TRIANGLES = 2_000_000   # world triangles an Embree check of a large instanced
EMBREE_SAMPLE_RAYS = 4096             # scene may flatten, and the rays it may take


def embree_sample(instances: Instances, origins, dirs, extent, our_t, our_prim,
                  budget: int = EMBREE_SAMPLE_TRIANGLES, max_rays: int = EMBREE_SAMPLE_RAYS):
    """A sample of rays that an Embree check of a scene too large to flatten can take exactly:
    (rows, triangles, prim). ``rows``: the rays taken, in a fixed pseudo-random order, each ray
    whose instances still fit in ``budget`` flattened triangles, up to ``max_rays``; a ray's
    instances are every instance whose world box (grown by 1e-5 of the scene's size, for the
    float32 traversal's rounding) it crosses before its hit (or its extent, for a miss), and
    the instance it hit. ``triangles``: those instances' world-space triangles; ``prim``: our
    primitive ids of the rays taken, renumbered into them. An Embree hit nearer than ours lies
    in such an instance, so on these rays the check is the full scene's."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n = len(o)
    t = np.asarray(our_t, np.float64)
    end = np.where(np.isfinite(t), t * (1 + 1e-4),
                   np.broadcast_to(np.asarray(extent, np.float64), (n,)))
    own = np.full(n, -1, np.int64)                      # the instance each ray hit (-1: none)
    ours = np.asarray(our_prim, np.int64) >= 0
    own[ours] = instances.locate(np.asarray(our_prim, np.int64)[ours])[0]
    lo_m = np.array([m.reshape(-1, 3).min(0) for m in instances.meshes], np.float64)
    hi_m = np.array([m.reshape(-1, 3).max(0) for m in instances.meshes], np.float64)
    wb = world_boxes(instances, np.concatenate([lo_m, hi_m], 1)[instances.mesh]).astype(np.float64)
    pad = 1e-5 * max(float(np.abs(wb).max()), float(np.abs(o).max(initial=0.0)))
    wb[:, 0] -= pad                                     # the float32 traversal's rounding
    wb[:, 1] += pad
    size = np.array([len(m) for m in instances.meshes], np.int64)[instances.mesh]
    dn = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    order = np.random.default_rng(0).permutation(n)
    taken, used = [], np.zeros(len(instances), bool)
    total = 0
    for start in range(0, n, 64):
        rows = order[start:start + 64]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d[rows]
            t0 = (wb[None, :, 0] - o[rows, None]) * inv[:, None]
            t1 = (wb[None, :, 1] - o[rows, None]) * inv[:, None]
        near = np.nan_to_num(np.minimum(t0, t1), nan=-np.inf).max(2)
        far = np.nan_to_num(np.maximum(t0, t1), nan=np.inf).min(2)
        cross = (near <= far) & (far >= 0) & (near <= end[rows, None] + pad / dn[rows, None])
        for r, c in zip(rows, cross):
            c = c.copy()
            if own[r] >= 0:
                c[own[r]] = True                        # its own hit, however it rounded
            new = c & ~used
            if total + int(size[new].sum()) > budget:
                continue                        # this ray would flatten too much: not taken
            used |= new
            total += int(size[new].sum())
            taken.append(r)
        if len(taken) >= max_rays:
            taken = taken[:max_rays]
            break
    rows = np.sort(np.array(taken, np.int64))
    keep = np.flatnonzero(used)
    base = np.concatenate(([0], np.cumsum(size[keep])[:-1])).astype(np.int64)
    tris = (np.concatenate([instances.world_triangles(instances.prim_base[i] + np.arange(size[i]))
                            for i in keep]) if len(keep) else np.zeros((0, 3, 3), np.float32))
    prim = np.asarray(our_prim, np.int64)[rows]
    hit = prim >= 0
    inst, local = instances.locate(prim[hit])
    prim[hit] = base[np.searchsorted(keep, inst)] + local
    return rows, tris, prim
