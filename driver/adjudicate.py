"""Which answer is right when the datapath and Embree disagree (docs/statistics.md, ``embree``).

Embree is a third party whose floats depend on the CPU's vector ISA and whose back-face culling
the check emulates by re-casting past back faces (``driver.check.embree_closest_front``); a
disagreement alone says nothing about our datapath. Every disagreeing ray is decided here from
the scene's float32 triangles and the ray in float64, whose rounding (about 1e-16 relative) is
far below the tie band below, so the decision is exact for this purpose:

- ``agree``: the same primitive, or both miss (any-hit rays: both occluded or both not).
- ``edge_tie``: both answers are right to float32 precision: the two hits lie within the tie
  band of each other, or the hit in question lies within the band of its triangle's edge, of
  the ray's origin or of its extent (a ray through a shared edge or vertex, coplanar overlaps,
  a ray leaving a surface). The band: ``POINT_REL`` of the scene's coordinate scale as a
  distance (where float32 coordinates put a triangle's plane and edges), which along a ray that
  crosses the plane at a grazing angle is that distance over the sine of the angle
  (``tie_band``), plus ``T_REL`` of t.
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
RECORDS = 16          # explained rays of each class kept in an ``embree`` object
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
    front, degenerate, slope). ``margin``: the signed distance of the plane point from the
    nearest edge line (positive inside); ``front``: d . n < 0 (n = (B - A) x (C - A));
    ``slope``: |d . n| / |n|, how far the ray moves off the plane per unit of t (a grazing ray's
    crossing moves far along the ray for a small change of the plane: ``tie_band``)."""
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
        slope = np.abs(den) / nn
    t = np.where(degenerate, np.nan, t)
    margin = np.where(degenerate, -np.inf, np.nan_to_num(margin, nan=-np.inf))
    return t, margin, den < 0, degenerate, np.where(degenerate, 0.0, slope)


def tie_band(t, slope, band):
    """The tie band in t of a plane crossing at ``t`` whose ray moves ``slope`` off the plane
    per unit of t: ``T_REL`` of t, plus the plane's position band (``band``, a distance) seen
    along the ray."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return T_REL * np.abs(np.nan_to_num(t)) + band / np.asarray(slope, np.float64)


@njit(cache=True, parallel=True)
def _search(tri, o, d, limit, same_t, same_tol, band, t_rel, double_sided):
    """For each ray: the nearest clearly valid hit (margin > band, clearly in front of the
    origin and clearly before ``limit`` by its own tie band, facing the ray unless
    double-sided) over all triangles, and the nearest back face within the tie bands of
    ``same_t`` (culled rays). Returns (t, prim, back_prim)."""
    k = o.shape[0]
    best_t = np.full(k, np.inf)
    best_p = np.full(k, -1, np.int64)
    back_p = np.full(k, -1, np.int64)
    m = tri.shape[0]
    for r in prange(k):
        ox, oy, oz = o[r, 0], o[r, 1], o[r, 2]
        dx, dy, dz = d[r, 0], d[r, 1], d[r, 2]
        lim = limit[r]
        st = same_t[r]
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
            nl = np.sqrt(nx * nx + ny * ny + nz * nz)
            tol = t_rel * abs(t) + band * nl / abs(den)
            front = den < 0.0
            near_same = abs(t - st) <= tol + same_tol[r]
            candidate = t - tol > 0.0 and t + tol < lim and (double_sided or front)
            if not (candidate or (near_same and not front)):
                continue
            qx, qy, qz = ox + t * dx, oy + t * dy, oz + t * dz
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
            if candidate and margin > band and t < bt:
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
        self.by_class: dict = {c: [] for c in CLASSES[1:]}

    def set(self, i: int, cls: str, reason: str, **fields) -> None:
        self.cls[i] = CLASSES.index(cls)
        if cls != "agree" and len(self.by_class[cls]) < RECORDS:
            self.by_class[cls].append({"ray": int(i), "class": cls, "reason": reason,
                                       **{k: _plain(v) for k, v in fields.items()}})

    @property
    def records(self) -> list:
        """The explained rays: up to ``RECORDS`` of each class, datapath-wrong ones first."""
        return [r for c in reversed(CLASSES[1:]) for r in self.by_class[c]]

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
    """(t, margin, front, degenerate, slope) of each ray's candidate triangle (t nan where
    prim < 0)."""
    k = len(prim)
    t, margin, slope = np.full(k, np.nan), np.full(k, -np.inf), np.zeros(k)
    front, deg = np.zeros(k, bool), np.ones(k, bool)
    has = prim >= 0
    if has.any():
        t[has], margin[has], front[has], deg[has], slope[has] = exact(
            np.asarray(tri[prim[has]], np.float64), o[has], d[has])
    return t, margin, front, deg, slope


class _Candidate:
    """One side's candidate hit of the rays being decided, and whether it is valid (a hit of
    the ray to float32 precision) and clear (valid, and clear of its edges, the origin and the
    extent by the tie bands)."""

    def __init__(self, tri, prim, o, d, ext, band, double_sided):
        self.has = prim >= 0
        self.t, self.margin, self.front, self.degenerate, slope = _cand(tri, prim, o, d)
        self.tol = tie_band(self.t, slope, band)
        with np.errstate(invalid="ignore"):
            self.valid = (self.has & ~self.degenerate & (self.t > -self.tol)
                          & (self.t < ext + self.tol) & (self.margin >= -band)
                          & (self.front | double_sided))
            self.clear = (self.valid & (self.margin > band) & (self.t > self.tol)
                          & (self.t < ext - self.tol))


def adjudicate(triangles, origins, dirs, extent, ours, embree, any_hit: bool,
               double_sided: bool, scale: float, rays=None, emb_occluded=None) -> Verdicts:
    """The verdict on every ray of a batch (module docstring). ``ours`` and ``embree``: each
    side's answers, a pair of arrays (t, prim). ``rays``: the rays to decide (default: every ray
    where the answers differ; the rest agree). Any-hit rays: ``emb_occluded`` is Embree's
    occlusion answer and ``embree`` its closest valid hit within the extent (for the rays it
    occludes; prim -1 elsewhere)."""
    (our_t, our_prim), (emb_t, emb_prim) = ours, embree
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
    a = _Candidate(triangles, prim[rays], oo, dd, ee, band, double_sided)
    b = _Candidate(triangles, eprim[rays], oo, dd, ee, band, double_sided)
    search = []
    for k, i in enumerate(rays):
        info = dict(ours_prim=prim[i], ours_t=our_t[i], ours_t_exact=a.t[k],
                    ours_margin=a.margin[k], embree_prim=eprim[i], embree_t=emb_t[i],
                    embree_t_exact=b.t[k], embree_margin=b.margin[k])
        if a.has[k] and not a.valid[k]:
            v.set(i, "datapath_wrong", _why_invalid("our", a, k, ee[k], band, double_sided),
                  **info)
        elif any_hit:
            if a.has[k]:                     # we are occluded, Embree is not
                _clear_or_tie(v, i, "embree_wrong", "Embree's occlusion query reports nothing "
                              "within the extent; our triangle is hit exactly within it",
                              ("our", a, k, ee[k], band), info)
            elif b.clear[k]:
                v.set(i, "datapath_wrong", "Embree's occluder is hit exactly within the extent "
                      "and clear of its edges; we report no hit", **info)
            elif b.valid[k]:
                v.set(i, "edge_tie", _why_marginal("Embree's", b, k, ee[k], band), **info)
            else:
                v.set(i, "embree_wrong", "Embree reports an occluder that is no exact hit of "
                      "the ray within its extent", **info)
        elif b.valid[k] and (not a.has[k] or b.t[k] + b.tol[k] < a.t[k] - a.tol[k]):
            _clear_or_tie(v, i, "datapath_wrong", "Embree's triangle is hit exactly, clearly "
                          "nearer than ours (or we report no hit)", ("Embree's", b, k, ee[k], band),
                          info)
        elif a.has[k]:
            if b.valid[k] and abs(a.t[k] - b.t[k]) <= a.tol[k] + b.tol[k]:
                v.set(i, "edge_tie", "both triangles are hit at the same t to float32 precision "
                      "(a shared edge or vertex, or coplanar triangles)", **info)
            else:
                search.append((k, i, info))
        elif b.has[k]:
            v.set(i, "embree_wrong", _why_invalid("Embree's", b, k, ee[k], band, double_sided),
                  **info)
        else:
            v.set(i, "agree", "", **info)
    if search:
        _settle(v, search, np.asarray(triangles, np.float32).reshape(-1, 3, 3), oo, dd, ee, a, b,
                band, double_sided)
    return v


def _clear_or_tie(v, i, cls: str, why: str, marginal: tuple, info: dict) -> None:
    """Ray ``i`` is ``cls`` when the candidate of ``marginal`` (who, candidate, k, extent,
    band) is hit clear of its triangle's edges and of the extent, else an edge tie."""
    _, c, k = marginal[:3]
    if c.clear[k]:
        v.set(i, cls, why, **info)
    else:
        v.set(i, "edge_tie", _why_marginal(*marginal), **info)


def _settle(v, search, tri, oo, dd, ee, a, b, band, double_sided):
    """Rays where our hit is valid and at least as near as Embree's candidate: search every
    triangle for a clearly nearer valid hit."""
    todo = search[:MAX_SEARCH]
    ks = np.array([k for k, _, _ in todo], np.int64)
    limit = a.t[ks] - a.tol[ks]
    bt, bp, back = _search(tri, np.ascontiguousarray(oo[ks]), np.ascontiguousarray(dd[ks]),
                           limit, a.t[ks], a.tol[ks], band, T_REL, bool(double_sided))
    for j, (k, i, info) in enumerate(todo):
        if bp[j] >= 0:
            v.set(i, "datapath_wrong", f"triangle {bp[j]} is hit exactly at t {bt[j]:.9g}, "
                  "clearly nearer than ours", nearest_prim=bp[j], nearest_t=bt[j], **info)
        elif not a.clear[k]:
            v.set(i, "edge_tie", _why_marginal("our", a, k, ee[k], band), **info)
        elif back[j] >= 0 and not double_sided:
            v.set(i, "embree_wrong", f"ours is the nearest front face; back face {back[j]} lies "
                  "at the same t (a two-sided sheet of two opposite triangles): the culling "
                  "emulation re-casts past the back face and skips the coincident front face",
                  back_prim=back[j], **info)
        elif b.valid[k]:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree's is farther", **info)
        elif b.has[k]:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree's is no exact hit of the ray", **info)
        else:
            v.set(i, "embree_wrong", "ours is the exact nearest valid hit among all triangles; "
                  "Embree reports no hit", **info)
    for k, i, info in search[MAX_SEARCH:]:
        v.set(i, "datapath_wrong", f"not settled: more than {MAX_SEARCH} rays to search in one "
              "batch", **info)


def _why_invalid(who, c: _Candidate, k, ext, band, double_sided) -> str:
    t, m = c.t[k], c.margin[k]
    if c.degenerate[k]:
        return f"{who} triangle is degenerate or parallel to the ray (no hit)"
    if not t > -c.tol[k]:
        return f"{who} hit lies behind the ray's origin (exact t {t:.6g})"
    if not t < ext + c.tol[k]:
        return f"{who} hit lies beyond the ray's extent (exact t {t:.6g}, extent {ext:.6g})"
    if m < -band:
        return f"{who} hit point lies {-m:.3g} outside its triangle"
    if not (c.front[k] or double_sided):
        return f"{who} triangle is a back face of the ray (culled)"
    return f"{who} hit is no exact hit"


def _why_marginal(who, c: _Candidate, k, ext, band) -> str:
    t, m = c.t[k], c.margin[k]
    if m <= band:
        return f"{who} hit lies on its triangle's edge (within {band:.3g} of it: {m:.3g})"
    if abs(t) <= c.tol[k]:
        return (f"{who} hit lies at the ray's origin to float32 precision (exact t {t:.3g}, "
                f"band {c.tol[k]:.3g})")
    return f"{who} hit lies at the ray's extent to float32 precision (t {t:.6g}, extent {ext:.6g})"


def merge(parts: list[dict]) -> dict:
    """Adjudication objects of several batches taken together (up to ``RECORDS`` explained rays
    of each class, datapath-wrong ones first)."""
    out = {c: sum(p["classes"][c] for p in parts) for c in CLASSES}
    rays = [r for c in reversed(CLASSES[1:])
            for r in [r for p in parts for r in p.get("rays", []) if r["class"] == c][:RECORDS]]
    return {"classes": out, "explain": dict(EXPLAIN), "rays": rays}
