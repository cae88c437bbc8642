"""The compressed images' leaf primitives (docs/compressed.md): triangle pairs that share an
edge, the leaves of the ``q8`` and ``q8g`` images, and each leaf's facing (numba kernels for
``driver.bvh.pipeline.build(..., format="q8"|"q8g")``; the group leaves are
``driver.bvh.q8g``, the writer ``driver.bvh.q8_image``).

Pairing (``pair_triangles``): vertices are identified by their exact float32 bits (or by the
mesh's own vertex indices when the input is a mesh), so a shared vertex is stored once in the
pair node and the second triangle is read back bit for bit. The matching over shared edges is
Karp and Sipser's heuristic: a triangle with a single unmatched edge neighbour is matched to it
at once; otherwise the lowest-index unmatched triangle takes, among its unmatched edge
neighbours, the one whose union box with it has the least surface area.
Unmatched triangles become one-triangle leaves (``prim1 = NO_CHILD``). Each triangle keeps its
input vertex order (the watertight test's arithmetic depends on it, not only on the winding).
The vertex ids (``_vertex_ids``: one hash table per thread, each holding one shard of the hash
values) and the edge adjacency (``_neighbours``: each thread fills the triangle lists of its own
range of vertices, then one row per triangle) run on all cores with numba's ``prange``; each
gives the same result on any number of threads, so the image does not depend on the machine
(below ``PAIRING_PARALLEL_MIN`` triangles they run on one thread: starting the threads would
cost more than the work). The matching itself is sequential (each choice depends on the last).

Facing (``facing``): the sign of each leaf's face normal per axis, which the q8 writer uses to
put a flat leaf's slack behind its surface (``driver.bvh.q8_image``).
"""

from __future__ import annotations

import types

import numpy as np
from numba import get_num_threads, njit, prange

from .phases import Phases

_HASH = np.uint64(0x9E3779B97F4A7C15)


def _vertex_ids(bits, tables):
    """(m,) int64 vertex ids of (m, 3) uint32 coordinate bits, numbered 0, 1, ... in order of
    first use: equal exactly for bit-identical rows; or, if a shard's table filled up, an
    empty array (``_bit_ids`` then uses one table of twice the rows, which cannot fill).
    ``tables`` (shards, power of two) of -1: open-addressing hash tables, one per shard of the
    hash values, each filled by one thread that reads all rows in order and inserts its
    shard's, so that each row finds the first row with its bits as one table filled in order
    would (the ids do not depend on the shards). A probe visits each slot at most once."""
    m = bits.shape[0]
    shards, size = tables.shape
    mask = np.uint64(size - 1)
    first = np.empty(m, np.int64)
    full = np.zeros(shards, np.bool_)
    for s in prange(shards):
        table = tables[s]
        for i in range(m):
            x, y, z = bits[i, 0], bits[i, 1], bits[i, 2]
            h = ((np.uint64(x) * _HASH) ^ (np.uint64(y) << np.uint64(21))
                 ^ (np.uint64(z) * np.uint64(0xC2B2AE3D27D4EB4F)))
            h ^= h >> np.uint64(29)
            if (h >> np.uint64(40)) % np.uint64(shards) != np.uint64(s):
                continue
            slot = h & mask
            found = False
            for _ in range(size):
                f = table[slot]
                if f < 0:
                    table[slot] = i
                    first[i] = i
                    found = True
                    break
                if bits[f, 0] == x and bits[f, 1] == y and bits[f, 2] == z:
                    first[i] = f
                    found = True
                    break
                slot = (slot + np.uint64(1)) & mask
            if not found:
                full[s] = True
                break
    if full.any():
        return np.empty(0, np.int64)
    rank = np.empty(m, np.int64)               # first rows numbered in order
    nv = 0
    for i in range(m):
        if first[i] == i:
            rank[i] = nv
            nv += 1
    for i in prange(m):
        first[i] = rank[first[i]]
    return first


_ADJ = 6      # edge neighbours kept per triangle: at most two per edge (``_neighbours``)
_SMALL = 16   # a vertex's edge list up to this long is sorted by insertion, longer by merge sort


def _neighbours(ids, nv, shards):
    """(n, _ADJ) int32 edge neighbours of each triangle (-1 padded; an image holds fewer than
    2**29 triangles) and their count (n,) int8, a symmetric relation (u is t's neighbour exactly
    when t is u's, which the matching's counts rely on). ids (n, 3) vertex ids below ``nv``.

    Edge k of triangle t is entry 3 t + k, keyed by its two vertex ids (an edge whose ids are
    equal, of a degenerate triangle, has no neighbours). The triangles sharing one edge, in
    index order, are all neighbours of each other when they are at most three (every edge of
    a manifold mesh, and most non-manifold ones); when there are more, each is the neighbour
    of the one before and the one after it only (a path). So a triangle has at most two
    neighbours per edge and six in all, however many triangles share its edges: every row is
    whole, hence symmetric, and the work per triangle is bounded. The entries are grouped by
    their lower vertex id (a counting sort, each of ``shards`` workers filling and sorting the
    lists of its own range of vertices, so the result is the same on any number of threads),
    then sorted by the higher id within a vertex's list (stable: insertion up to _SMALL entries,
    else merge sort, O(d log d) for a vertex of d edges). A row lists its edges in order, each
    edge's neighbours in index order, each neighbour once."""
    n = ids.shape[0]
    cnt = np.zeros(nv + 1, np.int64)
    for t in range(n):
        for k in range(3):
            a, b = ids[t, k], ids[t, (k + 1) % 3]
            if a != b:
                cnt[min(a, b) + 1] += 1
    for v in range(nv):
        cnt[v + 1] += cnt[v]
    lst = np.empty(cnt[nv], np.int32)            # edge entries grouped by their lower vertex
    hi = np.empty(cnt[nv], np.int32)             # and each entry's higher vertex
    link = np.full((3 * n, 2), -1, np.int32)     # per entry: up to two neighbours on it
    for c in prange(shards):
        v0, v1 = c * nv // shards, (c + 1) * nv // shards
        fill = cnt[v0:v1].copy()
        for t in range(n):
            for k in range(3):
                a, b = ids[t, k], ids[t, (k + 1) % 3]
                lo = min(a, b)
                if a == b or lo < v0 or lo >= v1:
                    continue
                j = fill[lo - v0]
                lst[j] = 3 * t + k
                hi[j] = max(a, b)
                fill[lo - v0] += 1
        for v in range(v0, v1):
            s, e = cnt[v], cnt[v + 1]
            if e - s > _SMALL:
                order = np.argsort(hi[s:e], kind="mergesort")
                lst[s:e] = lst[s:e][order]
                hi[s:e] = hi[s:e][order]
            else:
                for i in range(s + 1, e):                # stable insertion sort by hi
                    x, h = lst[i], hi[i]
                    j = i
                    while j > s and hi[j - 1] > h:
                        lst[j], hi[j] = lst[j - 1], hi[j - 1]
                        j -= 1
                    lst[j], hi[j] = x, h
            i = s
            while i < e:                                 # each run of one edge (j > i)
                j = i + 1
                while j < e and hi[j] == hi[i]:
                    j += 1
                _link_edge(lst, i, j, link)
                i = j
    adj = np.full((n, _ADJ), -1, np.int32)
    deg = np.zeros(n, np.int8)
    for t in prange(n):                          # each triangle's row
        d = 0
        for j in range(3 * t, 3 * t + 3):
            for side in range(2):
                u = link[j, side]
                if u < 0:
                    continue
                seen = False
                for i in range(d):
                    seen |= adj[t, i] == u
                if not seen:
                    adj[t, d] = u
                    d += 1
        deg[t] = d
    return adj, deg


@njit(cache=True, nogil=True, inline="always")
def _link_edge(lst, i, j, link):
    """Link the entries lst[i:j] of one edge (in index order; a degenerate triangle may have two
    entries, next to each other) to their neighbours on it (``_neighbours``)."""
    c = 1                                        # distinct triangles
    for q in range(i + 1, j):
        c += lst[q] // 3 != lst[q - 1] // 3
    for q in range(i, j):
        t = lst[q] // 3
        if c <= 3:                               # all the others
            side = 0
            for r in range(i, j):
                u = lst[r] // 3
                if u != t and (r == i or u != lst[r - 1] // 3):
                    link[lst[q], side] = u
                    side += 1
        else:                                    # the one before and the one after
            r = q - 1
            while r >= i and lst[r] // 3 == t:   # at most one more entry of t
                r -= 1
            if r >= i:
                link[lst[q], 0] = lst[r] // 3
            r = q + 1
            while r < j and lst[r] // 3 == t:
                r += 1
            if r < j:
                link[lst[q], 1] = lst[r] // 3


# each pairing kernel twice: on all cores, and on one (prange runs as range) for small meshes,
# where starting the threads costs more than the work (and, on a loaded machine, waits for them)
PAIRING_PARALLEL_MIN = 100_000     # triangles


def _twins(fn):
    """(parallel, one-thread) kernels of ``fn``; the second compiles a copy under its own name,
    so that numba's on-disk cache keeps the two apart."""
    one = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__ + "_one")
    one.__qualname__ = fn.__qualname__ + "_one"
    one.__doc__ = fn.__doc__
    return (njit(cache=True, parallel=True, nogil=True)(fn),
            njit(cache=True, nogil=True)(one))


_vertex_ids_par, _vertex_ids_one = _twins(_vertex_ids)
_neighbours_par, _neighbours_one = _twins(_neighbours)


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


@njit(cache=True, nogil=True)
def _match(adj, deg, tris, limit):
    """Edge matching, Karp-Sipser style: (partner (n,) int64 (-1: unmatched), steps). A
    triangle left with one unmatched neighbour is matched to it first (no choice can do better
    for it); otherwise the lowest-index unmatched triangle takes the unmatched neighbour whose
    union box with it has the least surface area (``tris`` (n, 3, 3) float32).

    Termination: each step matches two unmatched triangles or, where a triangle counted as
    having unmatched neighbours has none, leaves it alone for good (with ``_neighbours``'s
    symmetric rows the counts are exact and this never happens; an asymmetric adjacency, as
    rows cut at a fixed width once gave on non-manifold edges, made the old loop pick that
    triangle forever), so a matching takes at most 1.5 n + 1 steps, and the stack and the scan
    at most 2 n pops and n advances. ``limit`` caps the steps anyway: at the cap the matching
    stops and every triangle not yet matched stays alone (``steps == limit`` says so)."""
    n = len(deg)
    free = deg.astype(np.int64)                             # unmatched neighbours
    partner = np.full(n, -1, np.int64)
    stack = np.empty(2 * n, np.int64)         # pushed once at the start, once on free == 1
    sp = 0
    for t in range(n):
        if free[t] == 1:
            stack[sp] = t
            sp += 1
    nxt = 0
    steps = 0
    while steps < limit:
        steps += 1
        t, u = -1, -1
        while sp > 0 and t < 0:
            sp -= 1
            c = stack[sp]
            if partner[c] < 0 and free[c] == 1:
                for i in range(deg[c]):
                    if partner[adj[c, i]] < 0:
                        t, u = c, adj[c, i]
        if t < 0:
            while nxt < n and (partner[nxt] >= 0 or free[nxt] <= 0):
                nxt += 1
            if nxt == n:
                return partner, steps
            t = nxt
            best = np.inf
            for i in range(deg[t]):
                w = adj[t, i]
                if partner[w] < 0:
                    a = _union_area(t, w, tris)
                    if u < 0 or a < best:
                        best, u = a, w
            if u < 0:                         # counted free but none is: t stays alone
                free[t] = 0
                continue
        partner[t], partner[u] = u, t
        for x in (t, u):
            for i in range(deg[x]):
                w = adj[x, i]
                if partner[w] < 0:
                    free[w] -= 1
                    if free[w] == 1 and sp < len(stack):
                        stack[sp] = w
                        sp += 1
    return partner, steps


def match_limit(n: int) -> int:
    """The matching's step cap for n triangles (``_match``): above the 1.5 n + 1 steps it can
    take."""
    return 2 * n + 2


@njit(cache=True, nogil=True)
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


def _bit_ids(points: np.ndarray) -> np.ndarray:
    """(m,) int64 ids of (m, 3) float32 points, equal exactly for bit-identical points (numbered
    in order of first use)."""
    bits = np.ascontiguousarray(points, np.float32).view(np.uint32)
    small = len(bits) < 3 * PAIRING_PARALLEL_MIN
    shards = 1 if small else get_num_threads()
    kernel = _vertex_ids_one if small else _vertex_ids_par
    dtype = np.int32 if len(bits) < 1 << 31 else np.int64
    size = 1 << max(4, int(2 * len(bits) // shards).bit_length())   # half full if hashes spread
    ids = kernel(bits, np.full((shards, size), -1, dtype))
    if len(ids) < len(bits):          # a shard got more than its share: one table of 2 m slots
        ids = kernel(bits, np.full((1, 1 << max(4, 2 * len(bits)).bit_length()), -1, dtype))
    return ids


def vertex_ids(tris: np.ndarray, faces=None) -> np.ndarray:
    """(n, 3) int64 vertex ids, equal for bit-identical float32 vertices (numbered in order of
    first use). ``faces``: a mesh's vertex indices for ``tris``; then only the mesh's vertices
    are hashed (a mesh may still hold one vertex several times, e.g. a mesh whose faces do not
    share vertex rows)."""
    if faces is None:
        return _bit_ids(np.asarray(tris, np.float32).reshape(-1, 3)).reshape(-1, 3)
    faces = np.ascontiguousarray(faces, np.int64)
    verts = np.zeros((int(faces.max()) + 1, 3), np.float32)
    verts[faces.reshape(-1)] = np.asarray(tris, np.float32).reshape(-1, 3)
    return _bit_ids(verts)[faces]


@njit(cache=True, nogil=True)
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


@njit(cache=True, nogil=True)
def _facing(n, groups):
    m, g = n.shape[0], groups.shape[0]
    out = np.empty((m + g, 3), np.int8)
    for i in range(m):
        for c in range(3):
            out[i, c] = np.sign(n[i, c])
    for i in range(g):
        for c in range(3):
            s = 0.0
            for j in range(groups.shape[1]):
                if groups[i, j] >= 0:
                    s += n[groups[i, j], c]
            out[m + i, c] = np.sign(s)
    return out


def facing(tris: np.ndarray, first: np.ndarray, second: np.ndarray,
           groups: np.ndarray) -> np.ndarray:
    """(m + g, 3) int8: per pair leaf, then per group leaf, and axis the sign of its face normal
    (the sum of its triangles' ``(B - A) x (C - A)``, float64), the side rays leave it on.
    ``groups`` (g, GROUP_MAX_TRIS) int64: each group's pair leaves (-1 padded)."""
    return _facing(_normals(tris, first, second), groups)


def neighbours(ids: np.ndarray):
    """``_neighbours`` of vertex ids (n, 3): on all cores from PAIRING_PARALLEL_MIN triangles,
    else on one (the same result)."""
    if len(ids) < PAIRING_PARALLEL_MIN:
        return _neighbours_one(ids, int(ids.max()) + 1, 1)
    return _neighbours_par(ids, int(ids.max()) + 1, get_num_threads())


def pair_triangles(tris: np.ndarray, faces=None, phases=None):
    """Pair triangles that share an edge (module docstring). Returns (first, second, idx, v3,
    box, ids): see ``_pairs``; ``box`` is a fake triangle per leaf whose bounding box is the
    leaf's, the builder's input; ``ids`` (n, 3) the vertex ids (``vertex_ids``). ``phases``: a
    ``driver.bvh.phases.Phases`` that times the vertex ids, adjacency, matching and pairs."""
    phases = phases or Phases()
    with phases("vertex ids"):
        ids = vertex_ids(tris, faces)
    with phases("adjacency"):
        adj, deg = neighbours(ids)
    with phases("matching"):
        partner, _ = _match(adj, deg, tris, match_limit(len(tris)))
    with phases("pairs"):
        return (*_pairs(ids, partner, tris), ids)

