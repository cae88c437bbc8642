"""The compressed ``q8`` and ``q8g`` images (docs/compressed.md): triangle pairing before the
build, group leaves, and the writer of 64-byte quantized box nodes and 64-byte triangle-pair
leaves (numba kernels for ``driver.bvh4.build(..., format="q8"|"q8g")``; ``driver.layout`` owns
the structs and the decode).

Pairing (``pair_triangles``): vertices are identified by their exact float32 bits (or by the
mesh's own vertex indices when the input is a mesh), so a shared vertex is stored once in the
pair node and the second triangle is read back bit for bit. The matching over shared edges is
Karp and Sipser's heuristic: a triangle with a single unmatched edge neighbour is matched to it
at once; otherwise the lowest-index unmatched triangle takes, among its unmatched edge
neighbours, the one whose union box with it has the least surface area.
Unmatched triangles become one-triangle leaves (``prim1 = NO_CHILD``). Each triangle keeps its
input vertex order (the watertight test's arithmetic depends on it, not only on the winding).

Quantization (``_quantize``): per box node and axis, ``origin`` = the float32 minimum of the
children's stored (grown, ``driver.bvh4``) lower bounds, ``exp`` = the smallest exponent in
[-126, 119] with ``(max - origin) / 2**exp <= 255``, ``qlo = floor((lo - origin) / 2**exp)``,
``qhi = ceil((hi - origin) / 2**exp)``; where a flat leaf child is thinner than one step, the
origin moves down onto the grid of that leaf's front face instead (``_origin``), so that its
step of slack lies behind the surface. ``verify_containment`` then decodes every node with
``driver.layout.decode_q8`` (the datapath's arithmetic) and moves a ``qlo`` down or a ``qhi`` up
by one wherever the decode put a bound inside the child's stored box, until none does.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..layout import Q8_EXP_MAX, Q8_EXP_MIN, decode_q8
from .build import WIDTH

_HASH = np.uint64(0x9E3779B97F4A7C15)


@njit(cache=True)
def _vertex_ids(bits, table):
    """(n, 3) int64 vertex ids of (n, 3, 3) uint32 coordinate bits: the flat index (3 t + k) of
    the first vertex with the same bits. ``table``: a power-of-two sized array of -1 (open
    addressing)."""
    n = bits.shape[0]
    mask = np.uint64(len(table) - 1)
    ids = np.empty((n, 3), np.int64)
    for t in range(n):
        for k in range(3):
            x, y, z = bits[t, k, 0], bits[t, k, 1], bits[t, k, 2]
            h = ((np.uint64(x) * _HASH) ^ (np.uint64(y) << np.uint64(21))
                 ^ (np.uint64(z) * np.uint64(0xC2B2AE3D27D4EB4F)))
            h ^= h >> np.uint64(29)
            slot = h & mask
            while True:
                f = table[slot]
                if f < 0:
                    table[slot] = 3 * t + k
                    ids[t, k] = 3 * t + k
                    break
                ft, fk = f // 3, f % 3
                if bits[ft, fk, 0] == x and bits[ft, fk, 1] == y and bits[ft, fk, 2] == z:
                    ids[t, k] = f
                    break
                slot = (slot + np.uint64(1)) & mask
    return ids


_ADJ = 6      # edge neighbours kept per triangle (a manifold triangle has at most 3)


@njit(cache=True)
def _neighbours(ids, nv):
    """(n, _ADJ) int32 triangles sharing an edge with each triangle (-1 padded; an image holds
    fewer than 2**31 triangles), and their count (n,) int8. ids (n, 3) vertex ids below
    ``nv``."""
    n = ids.shape[0]
    cnt = np.zeros(nv + 1, np.int64)
    for t in range(n):
        for k in range(3):
            cnt[ids[t, k] + 1] += 1
    for v in range(nv):
        cnt[v + 1] += cnt[v]
    lst = np.empty(3 * n, np.int64)
    fill = cnt[:-1].copy()
    for t in range(n):
        for k in range(3):
            v = ids[t, k]
            if k and (v == ids[t, 0] or (k == 2 and v == ids[t, 1])):
                continue                                   # a repeated vertex lists t once
            lst[fill[v]] = t
            fill[v] += 1
    adj = np.full((n, _ADJ), -1, np.int32)       # n < 2**31: images hold < 2**29 nodes
    deg = np.zeros(n, np.int8)
    for t in range(n):
        for e in range(3):
            a, b = ids[t, e], ids[t, (e + 1) % 3]
            if a == b:
                continue
            for j in range(cnt[a], fill[a]):
                u = lst[j]
                if u == t or (ids[u, 0] != b and ids[u, 1] != b and ids[u, 2] != b):
                    continue
                seen = False
                for i in range(deg[t]):
                    seen |= adj[t, i] == u
                if not seen and deg[t] < _ADJ:
                    adj[t, deg[t]] = u
                    deg[t] += 1
    return adj, deg


@njit(cache=True, inline="always")
def _union_area(t, u, tris):
    """Half surface area of the union box of triangles t and u."""
    d = np.empty(3)
    for c in range(3):
        lo = min(tris[t, 0, c], tris[t, 1, c], tris[t, 2, c], tris[u, 0, c], tris[u, 1, c],
                 tris[u, 2, c])
        hi = max(tris[t, 0, c], tris[t, 1, c], tris[t, 2, c], tris[u, 0, c], tris[u, 1, c],
                 tris[u, 2, c])
        d[c] = np.float64(hi) - np.float64(lo)
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0]


@njit(cache=True)
def _match(ids, tris, nv):
    """Edge matching, Karp-Sipser style: partner (n,) int64 (-1: unmatched). A triangle left
    with one unmatched neighbour is matched to it first (no choice can do better for it);
    otherwise the lowest-index unmatched triangle takes the unmatched neighbour whose union box
    with it has the least surface area (``tris`` (n, 3, 3) float32)."""
    n = ids.shape[0]
    adj, deg = _neighbours(ids, nv)
    free = deg.astype(np.int64)                             # unmatched neighbours
    partner = np.full(n, -1, np.int64)
    stack = np.empty(2 * n, np.int64)         # pushed once at the start, once on free == 1
    sp = 0
    for t in range(n):
        if free[t] == 1:
            stack[sp] = t
            sp += 1
    nxt = 0
    while True:
        t, u = -1, -1
        while sp > 0 and t < 0:
            sp -= 1
            c = stack[sp]
            if partner[c] < 0 and free[c] == 1:
                for i in range(deg[c]):
                    if partner[adj[c, i]] < 0:
                        t, u = c, adj[c, i]
        if t < 0:
            while nxt < n and (partner[nxt] >= 0 or free[nxt] == 0):
                nxt += 1
            if nxt == n:
                break
            t = nxt
            best = np.inf
            for i in range(deg[t]):
                w = adj[t, i]
                if partner[w] < 0:
                    a = _union_area(t, w, tris)
                    if a < best:
                        best, u = a, w
        partner[t], partner[u] = u, t
        for x in (t, u):
            for i in range(deg[x]):
                w = adj[x, i]
                if partner[w] < 0:
                    free[w] -= 1
                    if free[w] == 1:
                        stack[sp] = w
                        sp += 1
    return partner


@njit(cache=True)
def _pairs(ids, partner, tris):
    """Leaf primitives from the matching, in order of their first triangle: first (m,), second
    (m,) (-1: alone), idx (m,) the second triangle's vertex selectors (bits 1:0, 3:2, 5:4), v3
    (m, 3) float32 the second triangle's own vertex, box (m, 3, 3) float32 ``(lo, hi, hi)``."""
    n = len(partner)
    m = 0
    for t in range(n):
        if partner[t] < 0 or t < partner[t]:
            m += 1
    first = np.empty(m, np.int64)
    second = np.full(m, -1, np.int64)
    idx = np.zeros(m, np.uint32)
    v3 = np.zeros((m, 3), np.float32)
    box = np.empty((m, 3, 3), np.float32)
    i = 0
    for t in range(n):
        p = partner[t]
        if p >= 0 and p < t:
            continue
        first[i] = t
        for c in range(3):
            lo = min(tris[t, 0, c], tris[t, 1, c], tris[t, 2, c])
            hi = max(tris[t, 0, c], tris[t, 1, c], tris[t, 2, c])
            if p >= 0:
                lo = min(lo, tris[p, 0, c], tris[p, 1, c], tris[p, 2, c])
                hi = max(hi, tris[p, 0, c], tris[p, 1, c], tris[p, 2, c])
            box[i, 0, c], box[i, 1, c], box[i, 2, c] = lo, hi, hi
        if p >= 0:
            second[i] = p
            sel = np.uint32(0)
            for k in range(3):
                j = 3
                for q in range(3):
                    if ids[p, k] == ids[t, q]:
                        j = q
                        break
                if j == 3:
                    for c in range(3):
                        v3[i, c] = tris[p, k, c]
                sel |= np.uint32(j) << np.uint32(2 * k)
            idx[i] = sel
        i += 1
    return first, second, idx, v3, box


@njit(cache=True)
def _compact(ids):
    """Renumber vertex ids 0, 1, ... in order of first use, in place (a dense id range keeps
    the vertex tables of ``_neighbours`` small); returns the number of vertices."""
    new = np.full(3 * ids.shape[0], -1, np.int64)
    nv = 0
    for t in range(ids.shape[0]):
        for k in range(3):
            f = ids[t, k]
            if new[f] < 0:
                new[f] = nv
                nv += 1
            ids[t, k] = new[f]
    return nv


def vertex_ids(tris: np.ndarray, faces=None) -> np.ndarray:
    """(n, 3) int64 vertex ids: ``faces`` when given (a mesh's vertex indices), else equal ids
    (numbered in order of first use) for bit-identical float32 vertices."""
    if faces is not None:
        return np.ascontiguousarray(faces, np.int64)
    m = 3 * len(tris)
    size = 1 << max(4, int(2 * m - 1).bit_length())
    table = np.full(size, -1, np.int32 if m < 1 << 31 else np.int64)
    ids = _vertex_ids(np.ascontiguousarray(tris).view(np.uint32), table)
    del table
    _compact(ids)
    return ids


@njit(cache=True)
def _normals(tris, first, second):
    """(m, 3) float64: per pair leaf the sum of its triangles' ``(B - A) x (C - A)``."""
    n = np.zeros((len(first), 3))
    for i in range(len(first)):
        for t in (first[i], second[i]):
            if t < 0:
                continue
            ax, ay, az = np.float64(tris[t, 0, 0]), np.float64(tris[t, 0, 1]), tris[t, 0, 2]
            ux, uy, uz = tris[t, 1, 0] - ax, tris[t, 1, 1] - ay, tris[t, 1, 2] - np.float64(az)
            vx, vy, vz = tris[t, 2, 0] - ax, tris[t, 2, 1] - ay, tris[t, 2, 2] - np.float64(az)
            n[i, 0] += uy * vz - uz * vy
            n[i, 1] += uz * vx - ux * vz
            n[i, 2] += ux * vy - uy * vx
    return n


def facing(tris: np.ndarray, first: np.ndarray, second: np.ndarray,
           groups: np.ndarray) -> np.ndarray:
    """(m + g, 3) int8: per pair leaf, then per group leaf, and axis the sign of its face normal
    (the sum of its triangles' ``(B - A) x (C - A)``, float64), the side rays leave it on."""
    n = _normals(tris, first, second)
    n = np.concatenate([n, n[groups[:, 0]] + n[groups[:, 1]]])
    return np.sign(n).astype(np.int8)


def group_leaves(left, right, prim, n_pairs: int) -> np.ndarray:
    """Turn, in place, every binary node whose two children are leaves into one leaf (a group
    leaf of two pairs, ``prim`` = ``n_pairs`` + its index); returns the groups (g, 2) int64: the
    two pairs' indices, in the children's order. The node keeps its (grown) box, the union of
    the two."""
    inner = np.flatnonzero(left >= 0)
    both = inner[(left[left[inner]] < 0) & (left[right[inner]] < 0)]
    groups = np.stack([prim[left[both]], prim[right[both]]], axis=1)
    prim[both] = n_pairs + np.arange(len(both))
    left[both] = right[both] = -1
    return groups


def pair_triangles(tris: np.ndarray, faces=None):
    """Pair triangles that share an edge (module docstring). Returns (first, second, idx, v3,
    box): see ``_pairs``; ``box`` is a fake triangle per leaf whose bounding box is the leaf's,
    the builder's input."""
    ids = vertex_ids(tris, faces)
    partner = _match(ids, tris, int(ids.max()) + 1)
    return _pairs(ids, partner, tris)


@njit(cache=True)
def _origin(r, a, o, top, s, used, slots, left, prim, ref, facing):
    """The origin of node r on axis a: ``o`` (the children's lowest bound), or, when a leaf
    child is thinner than one step ``s`` on this axis, a grid that puts that leaf's bound on its
    front side (the side its face normal points to) on a grid plane, so that the step of slack
    its decoded box must have lies behind the surface, where rays leaving the surface (shadow
    and bounce rays start just in front of it) do not pass; the leaf of largest cross-section
    wins, and only a grid that still spans the node in 255 steps."""
    best, area = o, 0.0
    b, c = (a + 1) % 3, (a + 2) % 3
    for j in range(used):
        x = slots[r, j]
        lo, hi = np.float64(ref[r, j, a]), np.float64(ref[r, j, 3 + a])
        if left[x] >= 0 or hi - lo >= s or facing[prim[x], a] == 0:
            continue
        cross = ((np.float64(ref[r, j, 3 + b]) - ref[r, j, b])
                 * (np.float64(ref[r, j, 3 + c]) - ref[r, j, c]))
        if cross <= area:
            continue
        up = facing[prim[x], a] > 0
        plane = hi if up else lo
        exact = plane - np.ceil((plane - np.float64(o)) / s) * s
        cand = np.float32(exact)
        # rounded so that the plane's step decodes on the front side of the plane (hi: at or
        # above it, lo: at or below it)
        if up and np.float64(cand) < exact:
            cand = np.nextafter(cand, np.float32(np.inf))
        elif not up and np.float64(cand) > exact:
            cand = np.nextafter(cand, np.float32(-np.inf))
        if cand <= o and np.float64(top) - np.float64(cand) <= 255.0 * s:
            best, area = cand, cross
    return best


@njit(cache=True)
def _write_pair(p, slot, first, second, idx, v3, tris, pv, pprim, pidx, no_child):
    """Pair leaf ``p`` (``_pairs``'s arrays) into 64-byte leaf slot ``slot``."""
    t = first[p]
    pprim[slot, 0] = t
    for v in range(3):
        for c in range(3):
            pv[slot, v, c] = tris[t, v, c]
    if second[p] >= 0:
        pprim[slot, 1] = second[p]
        pidx[slot] = idx[p]
        for c in range(3):
            pv[slot, 3, c] = v3[p, c]
    else:
        pprim[slot, 1] = no_child


@njit(cache=True)
def _quantize(slots, left, prim, node_lo, node_hi, first, second, idx, v3, groups, tris, facing,
              origin, exp, child, q, parent, ref, pv, pprim, pidx, box_ptr, leaf_base, types,
              no_child):
    """Number the wide tree's nodes and write the q8 box nodes (origin, exp + count, child, q,
    parent) and the leaves (pv, pprim, pidx: 64-byte pair slots in the order they are
    referenced), as ``driver.bvh.build.fill_image`` does for box32. A leaf's ``prim`` below
    ``len(first)`` is a pair leaf, else group ``prim - len(first)`` of ``groups`` (g, 2): two
    pairs in consecutive slots. ``leaf_base``: byte offset of the first slot; ``types``: (pair,
    group) pointer type codes. ``ref`` (k, 4, 6) float32 receives each used slot's stored box
    (+inf unused); ``facing`` (leaves, 3) int8: the sign of each leaf's face normal per axis
    (``_origin``). Returns 0, or the index + 1 of a node whose extent needs an exponent above
    Q8_EXP_MAX."""
    k = slots.shape[0]
    nb, nl = 0, 0
    n_pairs = len(first)
    parent[0] = no_child
    for r in range(k):
        used = 0
        for j in range(WIDTH):
            x = slots[r, j]
            if x < 0:
                child[r, j] = no_child
                for c in range(6):
                    ref[r, j, c] = np.inf
                continue
            used += 1
            for c in range(3):
                ref[r, j, c] = node_lo[x, c]
                ref[r, j, 3 + c] = node_hi[x, c]
            if left[x] >= 0:
                nb += 1
                child[r, j] = box_ptr[0] + nb * box_ptr[1]
                parent[nb] = box_ptr[0] + r * box_ptr[1]
            else:
                p = prim[x]
                kind = types[0] if p < n_pairs else types[1]
                child[r, j] = ((leaf_base + 64 * nl) >> 3) | kind
                if p < n_pairs:
                    _write_pair(p, nl, first, second, idx, v3, tris, pv, pprim, pidx, no_child)
                    nl += 1
                else:
                    for h in range(2):
                        _write_pair(groups[p - n_pairs, h], nl, first, second, idx, v3, tris, pv,
                                    pprim, pidx, no_child)
                        nl += 1
        for a in range(3):
            o = np.float32(np.inf)
            top = np.float32(-np.inf)
            for j in range(used):
                o = min(o, ref[r, j, a])
                top = max(top, ref[r, j, 3 + a])
            ext = np.float64(top) - np.float64(o)
            e = Q8_EXP_MIN
            if ext > 0:                                    # a first guess, then exact steps
                e = max(Q8_EXP_MIN, int(np.ceil(np.log2(ext / 255.0))) - 1)
            while e <= Q8_EXP_MAX and ext > 255.0 * math.ldexp(1.0, e):
                e += 1
            if e > Q8_EXP_MAX:
                return r + 1
            s = math.ldexp(1.0, e)
            o = _origin(r, a, o, top, s, used, slots, left, prim, ref, facing)
            origin[r, a] = o
            exp[r, a] = np.uint8(e & 0xFF)
            for j in range(used):
                lo = np.floor((np.float64(ref[r, j, a]) - np.float64(o)) / s)
                hi = np.ceil((np.float64(ref[r, j, 3 + a]) - np.float64(o)) / s)
                q[r, j, a] = np.uint8(min(max(lo, 0.0), 255.0))
                q[r, j, 3 + a] = np.uint8(min(max(hi, 0.0), 255.0))
        exp[r, 3] = np.uint8(used)
    return 0


def verify_containment(nodes: np.ndarray, ref: np.ndarray):
    """Decode every q8 node with ``decode_q8`` and widen, in place, each quantized bound whose
    decode lies inside the stored box ``ref`` (k, 4, 6) by one step, until every decoded child
    box contains its stored box. Returns (the number of bounds moved, the final decoded boxes).
    Raises ValueError if a bound cannot move (a plane at 0 or 255 that still does not contain
    it)."""
    moved = 0
    while True:
        dec = decode_q8(nodes)
        low = dec[..., :3] > ref[..., :3]                  # unused slots: inf > inf is False
        high = dec[..., 3:] < ref[..., 3:]
        if not (low.any() or high.any()):
            return moved, dec
        q = nodes["q"]
        if (q[..., :3][low] == 0).any() or (q[..., 3:][high] == 255).any():
            raise ValueError("q8 encoding: a child box cannot be contained by its node's planes")
        q[..., :3][low] -= 1
        q[..., 3:][high] += 1
        moved += int(low.sum() + high.sum())

