"""The ``q8g`` image's group leaves (docs/compressed.md): binary subtrees of 3 to 6 triangles
that become one 128-byte leaf sharing up to 8 vertices (numba kernels).

Group leaves (``group_leaves``, q8g): after the build over pair leaves, binary subtrees of 3 to 6
triangles whose vertices fit the group leaf's 8 slots may become one 128-byte leaf; which ones
do is chosen with the 4-wide collapse by the SAH cost of datapath ops plus ``GROUP_LAMBDA``
times the bytes (``_group_dp``). The fits and the layout run on all cores
(``_group_fits``, ``_apply_groups``) and give the same result on any number of threads; the
choice's pass over the tree (``_group_dp``) is sequential.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from ..core.layout import (GROUP_BYTES, GROUP_COUNT_LSB, GROUP_MAX_TRIS, GROUP_MAX_VERTS,
                           GROUP_SEL_BITS, GROUP_SEL_LSB, PAIR_BYTES, Q8_BYTES)
from .collapse import dp_table, pop_slots, push_children
from .params import WIDTH

_CHUNKS_PER_THREAD = 8    # work items of a parallel loop with scratch: a few per thread


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


@njit(cache=True, nogil=True, parallel=True)
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
    """Choose the group leaves together with the 4-wide collapse (``driver.bvh.collapse.dp_table``,
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
    # top down as driver.bvh.collapse._emit walks the table: (node, slots) to place
    merge = np.zeros(m, np.bool_)
    work = np.empty((m + 2 * W, 2), np.int64)
    work[0, 0], work[0, 1], wp = 0, 1, 1
    while wp > 0:
        wp, x, k = pop_slots(work, wp, choice)
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
        wp = push_children(work, wp, x, k, c, left, right)
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


@njit(cache=True, nogil=True, parallel=True)
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
