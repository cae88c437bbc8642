"""The compressed ``q8`` and ``q8g`` images (docs/compressed.md): triangle pairing before the
build, group leaves, and the writer of 64-byte quantized box nodes, 64-byte triangle-pair leaves
and 128-byte group leaves (numba kernels for ``driver.bvh4.build(..., format="q8"|"q8g")``;
``driver.layout`` owns the structs and the decode).

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
range of vertices, then one row per triangle) run on all cores with numba's ``prange``, as do
the group-leaf fits and layout (``_group_fits``, ``_apply_groups``) and the quantization
(``_quantize``); each gives the same result on any number of threads, so the image does not
depend on the machine (below ``PAIRING_PARALLEL_MIN`` triangles the vertex ids and adjacency run
on one thread: starting the threads would cost more than the work). The matching itself is sequential (each choice depends on the last), as
is the group choice's pass over the tree (``_group_dp``).

Group leaves (``group_leaves``, q8g): after the build over pair leaves, binary subtrees of 3 to 6
triangles whose vertices fit the group leaf's 8 slots may become one 128-byte leaf; which ones
do is chosen with the 4-wide collapse by the SAH cost of datapath ops plus ``GROUP_LAMBDA``
times the bytes (``_group_dp``).

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
import types

import numpy as np
from numba import get_num_threads, njit, prange

from ..layout import (GROUP_BYTES, GROUP_COUNT_LSB, GROUP_MAX_TRIS, GROUP_MAX_VERTS, GROUP_NODE,
                      GROUP_SEL_BITS, GROUP_SEL_LSB, PAIR_BYTES, PAIR_NODE, Q8_BYTES, Q8_EXP_MAX,
                      Q8_EXP_MIN, decode_q8, node_word)
from .build import WIDTH, dp_table
from .phases import Phases

_HASH = np.uint64(0x9E3779B97F4A7C15)
_CHUNKS_PER_THREAD = 8    # work items of a parallel loop with scratch: a few per thread


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


@njit(cache=True, nogil=True)
def _group_order(members, first, second, ids, gtri, gvert):
    """Lay out one group leaf of the pair leaves ``members`` (-1 padded): the triangles in
    ``gtri`` (GROUP_MAX_TRIS,) (-1 padded; pairs first, each first triangle first, so that
    triangle 1 shares an edge with triangle 0), the vertex slots in ``gvert``
    (GROUP_MAX_VERTS,) (the flat index 3 t + corner of a triangle corner with that vertex; -1
    unused). Returns the 64-bit ``idx`` word (selectors and count), or -1 when the triangles need
    more than GROUP_MAX_VERTS vertex slots or triangle 1 a vertex beyond v3."""
    nt = 0
    for pass_ in range(2):                   # pairs first, then single triangles
        for i in range(len(members)):
            p = members[i]
            if p < 0 or (second[p] >= 0) != (pass_ == 0):
                continue
            gtri[nt] = first[p]
            nt += 1
            if second[p] >= 0:
                gtri[nt] = second[p]
                nt += 1
    for i in range(nt, GROUP_MAX_TRIS):
        gtri[i] = -1
    gvert[:] = -1
    slot_id = np.full(GROUP_MAX_VERTS, -1, np.int64)
    nv = 0
    sel = np.int64(0)
    for k in range(nt):
        t = gtri[k]
        for j in range(3):
            v = -1
            if k > 0:                          # triangle 0 is (v0, v1, v2), even if degenerate
                for u in range(nv):
                    if slot_id[u] == ids[t, j]:
                        v = u
                        break
            if v < 0:
                if nv == GROUP_MAX_VERTS:
                    return -1
                v = nv
                slot_id[v] = ids[t, j]
                gvert[v] = 3 * t + j
                nv += 1
            if k == 1:
                if v > 3:
                    return -1
                sel |= np.int64(v) << np.int64(2 * j)
            elif k >= 2:
                sel |= np.int64(v) << np.int64(GROUP_SEL_LSB + GROUP_SEL_BITS * (k - 2) + 3 * j)
    return sel | (np.int64(nt) << np.int64(GROUP_COUNT_LSB))


@njit(cache=True, nogil=True)
def _members(x, left, right, prim, members, stack):
    """The pair leaves of binary node x's subtree, left to right, into ``members`` (-1
    padded); returns their number (at most ``len(members)``: callers pass small subtrees)."""
    nm, sp = 0, 1
    stack[0] = x
    while sp:
        sp -= 1
        y = stack[sp]
        if left[y] < 0:
            members[nm] = prim[y]
            nm += 1
        else:
            stack[sp] = right[y]
            stack[sp + 1] = left[y]
            sp += 2
    members[nm:] = -1
    return nm


@njit(cache=True, parallel=True, nogil=True)
def _group_fits(left, right, prim, first, second, ids, chunks):
    """(tri (m,) int64, ok (m,) bool): per binary node its triangles, and whether its subtree
    of 3 to GROUP_MAX_TRIS triangles fits a group leaf (``_group_order``; never the root). The
    triangle counts go bottom up (children are numbered after their parent); the fit of each
    small subtree is independent of the others' and runs on all cores, in chunks that each
    have their own scratch (``chunks``: a few per thread)."""
    m = len(left)
    tri = np.zeros(m, np.int64)
    for n in range(m - 1, -1, -1):
        tri[n] = (1 + (second[prim[n]] >= 0)) if left[n] < 0 else tri[left[n]] + tri[right[n]]
    ok = np.zeros(m, np.bool_)
    for c in prange(chunks):
        members = np.empty(GROUP_MAX_TRIS, np.int64)
        stack = np.empty(2 * GROUP_MAX_TRIS + 2, np.int64)
        gtri = np.empty(GROUP_MAX_TRIS, np.int64)
        gvert = np.empty(GROUP_MAX_VERTS, np.int64)
        for n in range(max(1, c * m // chunks), (c + 1) * m // chunks):
            if left[n] >= 0 and 3 <= tri[n] <= GROUP_MAX_TRIS:
                _members(n, left, right, prim, members, stack)
                ok[n] = _group_order(members, first, second, ids, gtri, gvert) >= 0
    return tri, ok


@njit(cache=True, nogil=True)
def _group_dp(left, right, prim, area, tri, ok, lam):
    """Choose the group leaves together with the 4-wide collapse (``driver.bvh.build.dp_table``,
    the collapse's table with leaf costs and bytes): D(n, k) is the least ``cost + lam *
    bytes`` of binary node n's subtree in k slots of its parent, where cost is the SAH of
    datapath ops (``area``: the stored boxes' half areas; a wide box node costs its area once, a
    leaf its area times its triangles: each is tested when the leaf's box is hit) and bytes the
    image's (64 per q8 box node and pair leaf, GROUP_BYTES per group leaf). In one slot, a
    subtree whose triangles fit a group leaf (``ok``, ``tri`` from ``_group_fits``) may become
    one. ``lam`` weighs bytes against cost: a pair leaf's 64 bytes are worth ``lam`` times the
    cost of the median pair leaf (a scale of the mesh's own leaves, which a few large
    triangles, a floor under a model, do not move). Returns merge (m,) bool: the nodes that
    become group leaves."""
    m = len(left)
    W = WIDTH
    leaves = left < 0
    lw = lam * np.median(area[leaves] * tri[leaves]) / PAIR_BYTES     # cost per byte
    leaf_cost = area * tri + lw * PAIR_BYTES
    node_cost = area + lw * Q8_BYTES
    alt_cost = np.where(ok, area * tri + lw * GROUP_BYTES, np.inf)
    choice, group = dp_table(left, right, leaf_cost, node_cost, alt_cost)
    # top down as driver.bvh.build._emit walks the table: (node, slots) to place
    merge = np.zeros(m, np.bool_)
    work = np.empty((m + 2 * W, 2), np.int64)
    work[0, 0], work[0, 1], wp = 0, 1, 1
    while wp > 0:
        wp -= 1
        x, k = work[wp, 0], work[wp, 1]
        while k > 1 and choice[x, k - 1] == 0:
            k -= 1
        if k == 1:
            if group[x]:
                merge[x] = True
                continue
            if left[x] < 0:
                continue
            c = choice[x, 0]
            k = W                                # a wide box node: its W slots split below
        else:
            c = choice[x, k - 1]
        work[wp, 0], work[wp, 1] = right[x], k - c
        work[wp + 1, 0], work[wp + 1, 1] = left[x], c
        wp += 2
    return merge


# lam of ``_group_dp`` for q8g images: 39.2 bytes per triangle on the bunny, 7-14 % more ops
# than box32 on the path workload of docs/compressed.md (which gives the bytes for other values)
GROUP_LAMBDA = 2.2


def group_leaves(left, right, prim, area, pairs, enabled: bool = True, lam: float | None = None):
    """Turn (``enabled``; else none), in place, the binary subtrees that ``_group_dp`` picks
    into group leaves (``prim`` = the number of pairs + the group's index); the node keeps its
    (grown) box, which contains its triangles. Returns (groups (g, GROUP_MAX_TRIS) the member
    pair leaves (-1 padded), gtri (g, GROUP_MAX_TRIS) the triangles in leaf order, gvert (g,
    GROUP_MAX_VERTS) each vertex slot's source corner 3 t + j, gidx (g,) uint64 the ``idx``
    words)."""
    first, second, ids = pairs[0], pairs[1], pairs[5]
    lam = GROUP_LAMBDA if lam is None else lam
    chunks = _CHUNKS_PER_THREAD * get_num_threads()
    if enabled and left[0] >= 0:
        tri, ok = _group_fits(left, right, prim, first, second, ids, chunks)
        merge = _group_dp(left, right, prim, area, tri, ok, lam)
    else:
        merge = np.zeros(len(left), np.bool_)
    return _apply_groups(merge, left, right, prim, first, second, ids, len(first), chunks)


@njit(cache=True, parallel=True, nogil=True)
def _apply_groups(merge, left, right, prim, first, second, ids, n_pairs, chunks):
    """Group i is merged node ``nodes[i]`` (in node order); the groups are independent (each
    writes its own rows and its own node) and are laid out on all cores."""
    nodes = np.flatnonzero(merge)
    g = len(nodes)
    groups = np.full((g, GROUP_MAX_TRIS), -1, np.int64)
    gtri = np.empty((g, GROUP_MAX_TRIS), np.int64)
    gvert = np.empty((g, GROUP_MAX_VERTS), np.int64)
    gidx = np.empty(g, np.uint64)
    for c in prange(chunks):
        stack = np.empty(2 * GROUP_MAX_TRIS + 2, np.int64)
        for i in range(c * g // chunks, (c + 1) * g // chunks):
            x = nodes[i]
            _members(x, left, right, prim, groups[i], stack)
            gidx[i] = np.uint64(_group_order(groups[i], first, second, ids, gtri[i], gvert[i]))
            left[x] = right[x] = -1
            prim[x] = n_pairs + i
    return groups, gtri, gvert, gidx


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


@njit(cache=True, nogil=True)
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


_PV, _PPRIM, _PIDX = (node_word(PAIR_NODE, f) for f in ("v", "prim", "idx"))
_GV2, _GPRIM2 = (node_word(GROUP_NODE, f) - PAIR_BYTES // 4 for f in ("v2", "prim2"))


@njit(cache=True, nogil=True)
def _write_pair(p, slot, first, second, idx, v3, tris, lw, lf, no_child):
    """Pair leaf ``p`` (``_pairs``'s arrays) into 64-byte leaf slot ``slot`` (``lw``/``lf``:
    the leaf slots as (slots, 16) uint32 and float32 views of the same bytes)."""
    t = first[p]
    lw[slot, _PPRIM] = t
    for v in range(3):
        for c in range(3):
            lf[slot, _PV + 3 * v + c] = tris[t, v, c]
    if second[p] >= 0:
        lw[slot, _PPRIM + 1] = second[p]
        lw[slot, _PIDX] = idx[p]
        for c in range(3):
            lf[slot, _PV + 9 + c] = v3[p, c]
    else:
        lw[slot, _PPRIM + 1] = no_child


@njit(cache=True, nogil=True)
def _write_group(g, slot, gtri, gvert, gidx, tris, lw, lf, no_child):
    """Group leaf ``g`` (``group_leaves``'s arrays) into the leaf slots ``slot`` and ``slot +
    1``."""
    for v in range(GROUP_MAX_VERTS):
        src = gvert[g, v]
        if src < 0:
            continue
        row, w = (slot, _PV + 3 * v) if v < 4 else (slot + 1, _GV2 + 3 * (v - 4))
        for c in range(3):
            lf[row, w + c] = tris[src // 3, src % 3, c]
    for k in range(GROUP_MAX_TRIS):
        row, w = (slot, _PPRIM + k) if k < 2 else (slot + 1, _GPRIM2 + k - 2)
        lw[row, w] = gtri[g, k] if gtri[g, k] >= 0 else no_child
    lw[slot, _PIDX] = np.uint32(gidx[g] & np.uint64(0xFFFFFFFF))
    lw[slot, _PIDX + 1] = np.uint32(gidx[g] >> np.uint64(32))


@njit(cache=True, parallel=True, nogil=True)
def _quantize(slots, left, prim, node_lo, node_hi, first, second, idx, v3, gtri, gvert, gidx,
              tris, facing, origin, exp, child, q, parent, ref, lw, lf, box_ptr, leaf_base, types,
              no_child):
    """Number the wide tree's nodes and write the q8 box nodes (origin, exp + count, child, q,
    parent) and the leaves (lw/lf: 64-byte leaf slots in the order they are referenced), as
    ``driver.bvh.build.fill_image`` does for box32. A leaf's ``prim`` below ``len(first)`` is a
    pair leaf (one slot), else group ``prim - len(first)`` (``gtri``, ``gvert``, ``gidx``: two
    slots). ``leaf_base``: byte offset of the first slot; ``types``: (pair,
    group) pointer type codes. ``ref`` (k, 4, 6) float32 receives each used slot's stored box
    (+inf unused); ``facing`` (leaves, 3) int8: the sign of each leaf's face normal per axis
    (``_origin``). Returns 0, or the index + 1 of a node whose extent needs an exponent above
    Q8_EXP_MAX (the first such node). Node r's box children and leaf slots are numbered after
    those of nodes 0..r-1 (a prefix sum of each node's counts), so the nodes are then written
    independently, on all cores."""
    k = slots.shape[0]
    n_pairs = len(first)
    nb0 = np.zeros(k + 1, np.int64)                # box children / leaf slots before node r
    nl0 = np.zeros(k + 1, np.int64)
    for r in range(k):
        b, sl = 0, 0
        for j in range(WIDTH):
            x = slots[r, j]
            if x < 0:
                continue
            if left[x] >= 0:
                b += 1
            else:
                sl += 1 if prim[x] < n_pairs else 2
        nb0[r + 1] = nb0[r] + b
        nl0[r + 1] = nl0[r] + sl
    parent[0] = no_child
    bad = np.zeros(k, np.bool_)
    for r in prange(k):
        nb, nl = nb0[r], nl0[r]
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
                    _write_pair(p, nl, first, second, idx, v3, tris, lw, lf, no_child)
                    nl += 1
                else:
                    _write_group(p - n_pairs, nl, gtri, gvert, gidx, tris, lw, lf, no_child)
                    nl += 2
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
                bad[r] = True
                break
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
    for r in range(k):
        if bad[r]:
            return r + 1
    return 0


def verify_containment(nodes: np.ndarray, ref: np.ndarray, rounds: int = 256):
    """Decode every q8 node with ``decode_q8`` and widen, in place, each quantized bound whose
    decode lies inside the stored box ``ref`` (k, 4, 6) by one step, until every decoded child
    box contains its stored box. Returns (the number of bounds moved, the final decoded boxes).
    A bound moves at most 255 times, so ``rounds`` (256) passes always suffice. Raises
    ValueError if a bound cannot move (a plane at 0 or 255 that still does not contain it) or
    the rounds run out."""
    moved = 0
    for _ in range(rounds + 1):
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
    raise ValueError(f"q8 encoding: child boxes still not contained after {rounds} widenings")
