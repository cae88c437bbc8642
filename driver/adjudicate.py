"""Which answer is right when the datapath and Embree disagree (docs/statistics.md, ``embree``).

Embree is a third party whose floats depend on the CPU's vector ISA and whose back-face culling
the check emulates by re-casting past back faces (``driver.check.embree_closest_front``); a
disagreement alone says nothing about our datapath. Every disagreeing ray is decided here from
the scene's float32 triangles and the ray in float64, whose rounding (about 1e-16 relative) is
far below the tie band below, so the decision is exact for this purpose:

- ``agree``: the same primitive, or both miss (any-hit rays: both occluded or both not).
- ``edge_tie``: both answers are right to float32 precision: the two hits lie within the tie
  band of each other (``T_REL`` of t, or ``POINT_REL`` of the scene's size along the ray), or the
  hit in question lies within ``POINT_REL`` of the scene's size of its triangle's edge or of the
  ray's extent (a ray through a shared edge or vertex, coplanar overlaps).
- ``embree_wrong``: our hit is the exact nearest valid hit (closest-hit rays: among both
  candidates, then among all triangles of the scene; any-hit rays: a valid hit within the
  extent), Embree's answer is not; counted, not a failure. Each such ray is explained, e.g. a
  back face at the same t (a two-sided sheet of two opposite triangles: the culling emulation
  re-casts past the back face and skips the coincident front face).
- ``datapath_wrong``: a valid hit clearly nearer than ours exists, or ours is no hit of the
  ray (its point off its triangle beyond the band, beyond the extent, or a culled back face);
  the check fails (``rayflex render`` exits 1).

A hit is valid when t > 0 and t < the extent, its point is on the triangle (within the band)
and, for culled rays, the triangle faces the ray (d . n < 0). The search over all triangles is
a numba kernel (one pass over the triangles per ray); it runs only for the rays whose answer
the two candidates cannot settle, at most ``MAX_SEARCH`` per call (more are ``unsettled`` and
fail the check, as a datapath error would).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

T_REL = 1e-5          # relative t band of a tie
POINT_REL = 1e-5      # distance band (edges, extent), relative to the scene's coordinate scale
MAX_SEARCH = 4096     # rays searched over all triangles per call
RECORDS = 16          # per-ray explanations kept in an ``embree`` object
CLASSES = ("agree", "edge_tie", "embree_wrong", "datapath_wrong")
EXPLAIN = {
    "agree": "the same primitive, or both miss (any-hit rays: both occluded or both not)",
    "edge_tie": "different answers, both right to float32 precision: the hits are within "
                f"{T_REL:g} of each other in t (or {POINT_REL:g} of the scene's size), or on a "
                "triangle's edge or the ray's extent within that band (shared edges and "
                "vertices, coplanar overlaps)",
    "embree_wrong": "our hit is the exact (float64) nearest valid hit among all triangles of "
                    "the scene, or Embree's hit is no exact hit of the ray; Embree's answer is "
                    "counted here, not failed (each such ray's reason is in 'rays')",
    "datapath_wrong": "a valid hit clearly nearer than ours exists, or our hit is no exact hit "
                      "of the ray; the check fails",
}


def exact(tri, o, d):
    """Exact (float64) intersection of rays with the planes of their triangles: (t, margin,
    front, degenerate). ``margin``: the signed distance of the plane point from the nearest
    edge line (positive inside); ``front``: d . n < 0 (n = (B - A) x (C - A))."""
    tri = np.asarray(tri, np.float64).reshape(-1, 3, 3)
    o = np.asarray(o, np.float64).reshape(-1, 3)
    d = np.asarray(d, np.float64).reshape(-1, 3)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.linalg.norm(n, axis=1)
    den = np.einsum("ij,ij->i", d, n)
    degenerate = (nn == 0) | (den == 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.einsum("ij,ij->i", a - o, n) / den
        q = o + t[:, None] * d
        margin = np.full(len(t), np.inf)
        for u, v in ((a, b), (b, c), (c, a)):
            e = v - u
            s = np.einsum("ij,ij->i", np.cross(e, q - u), n) / (nn * np.linalg.norm(e, axis=1))
            margin = np.minimum(margin, s)
    t = np.where(degenerate, np.nan, t)
    margin = np.where(degenerate, -np.inf, np.nan_to_num(margin, nan=-np.inf))
    return t, margin, den < 0, degenerate


@njit(cache=True, parallel=True)
def _search(tri, o, d, limit, same_t, band, t_rel, double_sided):
    """For each ray: the nearest clearly valid hit (margin > band, 0 < t < limit, facing the
    ray unless double-sided) over all triangles, and the nearest back face within the tie band
    of ``same_t`` (culled rays). Returns (t, prim, back_prim)."""
    k = o.shape[0]
    best_t = np.full(k, np.inf)
    best_p = np.full(k, -1, np.int64)
    back_p = np.full(k, -1, np.int64)
    m = tri.shape[0]
    for r in prange(k):
        ox, oy, oz = o[r, 0], o[r, 1], o[r, 2]
        dx, dy, dz = d[r, 0], d[r, 1], d[r, 2]
        dn = np.sqrt(dx * dx + dy * dy + dz * dz)
        lim = limit[r]
        st = same_t[r]
        tol = t_rel * abs(st) + band / dn
        bt = np.inf
        bp = -1
        kp = -1
        kd = np.inf
        for i in range(m):
            ax, ay, az = float(tri[i, 0, 0]), float(tri[i, 0, 1]), float(tri[i, 0, 2])
            bx, by, bz = float(tri[i, 1, 0]), float(tri[i, 1, 1]), float(tri[i, 1, 2])
            cx, cy, cz = float(tri[i, 2, 0]), float(tri[i, 2, 1]), float(tri[i, 2, 2])
            e1x, e1y, e1z = bx - ax, by - ay, bz - az
            e2x, e2y, e2z = cx - ax, cy - ay, cz - az
            nx = e1y * e2z - e1z * e2y
            ny = e1z * e2x - e1x * e2z
            nz = e1x * e2y - e1y * e2x
            den = dx * nx + dy * ny + dz * nz
            if den == 0.0:
                continue
            t = ((ax - ox) * nx + (ay - oy) * ny + (az - oz) * nz) / den
            if not t > band / dn:
                continue
            front = den < 0.0
            near_same = abs(t - st) <= tol
            if not (t < lim or (near_same and not front)):
                continue
            qx, qy, qz = ox + t * dx, oy + t * dy, oz + t * dz
            nl = np.sqrt(nx * nx + ny * ny + nz * nz)
            margin = np.inf
            for j in range(3):
                ux, uy, uz = float(tri[i, j, 0]), float(tri[i, j, 1]), float(tri[i, j, 2])
                jj = (j + 1) % 3
                vx, vy, vz = float(tri[i, jj, 0]), float(tri[i, jj, 1]), float(tri[i, jj, 2])
                ex, ey, ez = vx - ux, vy - uy, vz - uz
                wx, wy, wz = qx - ux, qy - uy, qz - uz
                cxx = ey * wz - ez * wy
                cyy = ez * wx - ex * wz
                czz = ex * wy - ey * wx
                el = np.sqrt(ex * ex + ey * ey + ez * ez)
                s = (cxx * nx + cyy * ny + czz * nz) / (nl * el) if el > 0 else -np.inf
                if s < margin:
                    margin = s
            if t < lim and margin > band and (double_sided or front) and t < bt:
                bt = t
                bp = i
            if near_same and not front and margin >= -band and abs(t - st) < kd:
                kd = abs(t - st)
                kp = i
        best_t[r] = bt
        best_p[r] = bp
        back_p[r] = kp
    return best_t, best_p, back_p


class Verdicts:
    """Classes and explanations of the rays of one checked batch."""

    def __init__(self, n: int):
        self.cls = np.zeros(n, np.int8)                 # index into CLASSES (0: agree)
        self.records: list = []

    def set(self, i: int, cls: str, reason: str, **fields) -> None:
        self.cls[i] = CLASSES.index(cls)
        if cls != "agree" and len(self.records) < RECORDS:
            self.records.append({"ray": int(i), "class": cls, "reason": reason,
                                 **{k: _plain(v) for k, v in fields.items()}})

    def counts(self) -> dict:
        c = np.bincount(self.cls, minlength=len(CLASSES))
        return {name: int(c[i]) for i, name in enumerate(CLASSES)}


def _plain(v):
    if isinstance(v, (np.floating, float)):
        return float(v) if np.isfinite(v) else None
    if isinstance(v, (np.integer, int)):
        return int(v)
    return v


def _cand(tri, prim, o, d):
    """(t, margin, front, degenerate) of each ray's candidate triangle (nan where prim < 0)."""
    k = len(prim)
    t = np.full(k, np.nan)
    margin = np.full(k, -np.inf)
    front = np.zeros(k, bool)
    deg = np.ones(k, bool)
    has = prim >= 0
    if has.any():
        t[has], margin[has], front[has], deg[has] = exact(
            np.asarray(tri[prim[has]], np.float64), o[has], d[has])
    return t, margin, front, deg


def adjudicate(triangles, origins, dirs, extent, our_t, our_prim, emb_t, emb_prim,
               any_hit: bool, double_sided: bool, scale: float, rays=None,
               emb_occluded=None) -> Verdicts:
    """The verdict on every ray of a batch (module docstring). ``rays``: the rays to decide
    (default: every ray where the answers differ; the rest agree). Any-hit rays:
    ``emb_occluded`` is Embree's occlusion answer and ``emb_prim``/``emb_t`` its closest valid
    hit within the extent (for the rays it occludes; -1 elsewhere)."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n = len(o)
    ext = np.broadcast_to(np.asarray(extent, np.float64), (n,))
    prim = np.asarray(our_prim, np.int64)
    eprim = np.asarray(emb_prim, np.int64)
    v = Verdicts(n)
    if rays is None:
        if any_hit:
            rays = np.flatnonzero((prim >= 0) != np.asarray(emb_occluded, bool))
        else:
            rays = np.flatnonzero(prim != eprim)
    rays = np.asarray(rays, np.int64)
    if not len(rays):
        return v
    band = POINT_REL * scale
    oo, dd, ee = o[rays], d[rays], ext[rays]
    dn = np.linalg.norm(dd, axis=1)
    ta, ma, fa, ga = _cand(triangles, prim[rays], oo, dd)
    tb, mb, fb, gb = _cand(triangles, eprim[rays], oo, dd)

    def tol(t):
        return T_REL * np.abs(np.nan_to_num(t)) + band / dn

    def valid(t, m, f, g):
        with np.errstate(invalid="ignore"):
            return (~g & (t > -tol(t)) & (t < ee + tol(t)) & (m >= -band)
                    & (f | double_sided))

    def clear(t, m, f, g):
        with np.errstate(invalid="ignore"):
            return valid(t, m, f, g) & (m > band) & (t > tol(t)) & (t < ee - tol(t))

    va, vb = valid(ta, ma, fa, ga), valid(tb, mb, fb, gb)
    ca, cb = clear(ta, ma, fa, ga), clear(tb, mb, fb, gb)
    has_a, has_b = prim[rays] >= 0, eprim[rays] >= 0
    search = []
    for k, i in enumerate(rays):
        info = dict(ours_prim=prim[i], ours_t=our_t[i], ours_t_exact=ta[k], ours_margin=ma[k],
                    embree_prim=eprim[i], embree_t=emb_t[i], embree_t_exact=tb[k],
                    embree_margin=mb[k])
        if has_a[k] and not va[k]:
            v.set(i, "datapath_wrong", _why_invalid("our", ta[k], ma[k], fa[k], ga[k], ee[k],
                                                    band, double_sided), **info)
        elif any_hit:
            if has_a[k]:                     # we are occluded, Embree is not
                if ca[k]:
                    v.set(i, "embree_wrong", "Embree's occlusion query reports nothing within "
                          "the extent; our triangle is hit exactly within it", **info)
                else:
                    v.set(i, "edge_tie", _why_marginal("our", ta[k], ma[k], ee[k], band), **info)
            elif has_b[k] and cb[k]:
                v.set(i, "datapath_wrong", "Embree's occluder is hit exactly within the extent "
                      "and clear of its edges; we report no hit", **info)
            elif has_b[k] and vb[k]:
                v.set(i, "edge_tie", _why_marginal("Embree's", tb[k], mb[k], ee[k], band),
                      **info)
            else:
                v.set(i, "embree_wrong", "Embree reports an occluder that is no exact hit of "
                      "the ray within its extent", **info)
        elif has_b[k] and vb[k] and (not has_a[k] or tb[k] < ta[k] - tol(ta[k:k + 1])[0]):
            if cb[k]:
                v.set(i, "datapath_wrong", "Embree's triangle is hit exactly, clearly nearer "
                      "than ours (or we report no hit)", **info)
            else:
                v.set(i, "edge_tie", _why_marginal("Embree's", tb[k], mb[k], ee[k], band), **info)
        elif has_a[k]:
            if has_b[k] and vb[k] and abs(ta[k] - tb[k]) <= tol(ta[k:k + 1])[0]:
                v.set(i, "edge_tie", "both triangles are hit at the same t to float32 precision "
                      "(a shared edge or vertex, or coplanar triangles)", **info)
            else:
                search.append((k, i, info))
        elif has_b[k]:
            v.set(i, "embree_wrong", _why_invalid("Embree's", tb[k], mb[k], fb[k], gb[k], ee[k],
                                                  band, double_sided), **info)
        else:
            v.set(i, "agree", "", **info)
    if search:
        _settle(v, search, np.asarray(triangles, np.float32).reshape(-1, 3, 3), oo, dd, ta, ma,
                has_b, vb, band, double_sided, tol)
    return v


def _settle(v, search, tri, oo, dd, ta, ma, has_b, vb, band, double_sided, tol):
    """Rays where our hit is valid and at least as near as Embree's candidate: search every
    triangle for a clearly nearer valid hit."""
    todo = search[:MAX_SEARCH]
    ks = np.array([k for k, _, _ in todo], np.int64)
    limit = ta[ks] - tol(ta[ks])
    bt, bp, back = _search(tri, np.ascontiguousarray(oo[ks]), np.ascontiguousarray(dd[ks]),
                           limit, ta[ks], band, T_REL, bool(double_sided))
    for j, (k, i, info) in enumerate(todo):
        if bp[j] >= 0:
            v.set(i, "datapath_wrong", f"triangle {bp[j]} is hit exactly at t {bt[j]:.9g}, "
                  "clearly nearer than ours", nearest_prim=bp[j], nearest_t=bt[j], **info)
        elif ma[k] <= band:
            v.set(i, "edge_tie", _why_marginal("our", ta[k], ma[k], np.inf, band), **info)
        elif back[j] >= 0 and not double_sided:
            v.set(i, "embree_wrong", f"ours is the nearest front face; back face {back[j]} lies "
                  "at the same t (a two-sided sheet of two opposite triangles): the culling "
                  "emulation re-casts past the back face and skips the coincident front face",
                  back_prim=back[j], **info)
        elif has_b[k] and vb[k]:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree's is farther", **info)
        elif has_b[k]:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree's is no exact hit of the ray", **info)
        else:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree reports no hit", **info)
    for k, i, info in search[MAX_SEARCH:]:
        v.set(i, "datapath_wrong", f"not settled: more than {MAX_SEARCH} rays to search in one "
              "batch", **info)


def _why_invalid(who, t, m, front, degenerate, ext, band, double_sided) -> str:
    if degenerate:
        return f"{who} triangle is degenerate or parallel to the ray (no hit)"
    if not t > 0:
        return f"{who} hit lies behind the ray's origin (exact t {t:.6g})"
    if not t < ext:
        return f"{who} hit lies beyond the ray's extent (exact t {t:.6g}, extent {ext:.6g})"
    if m < -band:
        return f"{who} hit point lies {-m:.3g} outside its triangle"
    if not (front or double_sided):
        return f"{who} triangle is a back face of the ray (culled)"
    return f"{who} hit is no exact hit"


def _why_marginal(who, t, m, ext, band) -> str:
    if m <= band:
        return f"{who} hit lies on its triangle's edge (within {band:.3g} of it: {m:.3g})"
    if abs(t) < abs(ext - t):
        return f"{who} hit lies at the ray's origin to float32 precision (exact t {t:.3g})"
    return f"{who} hit lies at the ray's extent to float32 precision (t {t:.6g}, extent {ext:.6g})"


def merge(parts: list[dict]) -> dict:
    """Adjudication objects of several batches taken together."""
    out = {c: sum(p["classes"][c] for p in parts) for c in CLASSES}
    rays = [r for p in parts for r in p.get("rays", [])][:RECORDS]
    return {"classes": out, "explain": dict(EXPLAIN), "rays": rays}
