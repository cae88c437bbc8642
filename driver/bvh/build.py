"""Fast binary BVH builder and the stored (grown) boxes of its nodes (numba kernels, the first
stage of ``driver.bvh.pipeline``).

Why hand-written kernels: no maintained Python package builds a BVH from boxes and centroids and
hands back the binary tree (Embree's builders are not exposed by embreex; trimesh/rtree build
R-trees of another shape), and the numpy builder (``driver.bvh.reference``, ``builder="numpy"``),
which is kept as the reference, spends its time in ``reduceat``/``ufunc.at`` passes over every
level (30 s for 2 M triangles). numba rather than C++ beside the harness (see docs/bvh.md): it is
a pip dependency, compiles once per machine into its on-disk cache, and with it the whole build
is an order of magnitude faster than with the vectorised numpy builder (docs/bvh.md). The image
writers' kernels (``driver.bvh.box32``, ``driver.bvh.q8_image``) are numba for the same reason:
as numpy passes they took a third of the 2 M-triangle build.

Binary build (``build_binary``): exactly the numpy builder's rules, so the trees are the same
(tests/test_bvh4.py compares them node by node): nodes of more than ``SWEEP_MAX`` primitives are
split by binned SAH (``bins`` bins per axis over the node's centroid bounds, all three axes, one
pass over the primitives; ties go to the lowest split, then the lowest axis); nodes of
3..``SWEEP_MAX`` primitives try every split of the centroid order on all three axes (ties: lowest
position, then lowest axis; equal centroids keep list order); 2 primitives split 1 + 1; a node
whose centroids all coincide splits its list in the middle. Partitions are stable. A node of at
most ``SWEEP_MAX`` primitives is built whole by ``_small``, which sorts its centroids once and
keeps the sorted lists through the splits instead of moving primitives and sorting every node
(half the build time went there). On several threads (from ``PARALLEL_MIN`` triangles) the top
of the tree is split node by node, both children of every split becoming tasks of a thread pool
(so only the root's split runs alone), down to nodes of n / (8 threads) primitives, which are
built whole depth first (``_subtree``; smaller child first, so the stack holds at most
log2(n) + 2 entries); the kernels release the GIL, and progress advances as each subtree task
finishes. docs/bvh.md has the build times.

Fillable splits (``fill`` > 0, off by default): a subtree of n triangles needs at least
ceil((n - 1) / 3) 4-wide box nodes, and reaches that only if every wide node below its root has 4
children: a node of 1 mod 3 triangles split into two of 2 mod 3, each of those into two of 1 mod 3,
and so on down to single triangles. Nodes of at most ``fill`` triangles keep to that rule: the
sweep only considers the split positions that do, and a binned split moves the one or two
primitives nearest its boundary across it (a node of 0 mod 3 triangles, e.g. the root, splits
into 1 and 2 mod 3 and costs one non-full node). The collapse still minimises SAH, so it may
leave a node non-full where that is cheaper. Fuller nodes shrink the tree and its memory but
raise SAH and primary-ray ops a little (docs/bvh.md measures the trade-off).

Termination (every loop has a bound): a split always puts between 1 and n - 1 primitives on
each side (``_fillable_count``, the middle split when no axis splits, and the fill moves stop
when no primitive is left to move), so the binary build makes exactly 2 n - 1 nodes; the
depth-first stacks are bounded (``_STACK``, ``SWEEP_MAX`` entries) and each pop makes one node;
``check_tree`` then checks that the tree is a pre-order tree (children numbered after their
parent, one parent each), so every walk down it (``driver.bvh.collapse``, the q8 group choice)
visits each node at most once.
"""

from __future__ import annotations

import os
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

import numpy as np
from numba import njit

from .params import SWEEP_MAX

PARALLEL_MIN = 50_000   # from this many triangles, subtrees are built on several threads
_STACK = 72            # > log2(2**63) + 2: the depth-first stack never holds more


@njit(cache=True, inline="always")
def _half_area(dx, dy, dz):
    return dx * dy + dy * dz + dz * dx


@njit(cache=True, nogil=True)
def _prim_boxes(tris):
    """Primitive boxes (float32, exact) of (n, 3, 3) triangles. Their centroids are not stored
    (``_cent``): the kernels move and read less memory without them."""
    n = tris.shape[0]
    lo = np.empty((n, 3), np.float32)
    hi = np.empty((n, 3), np.float32)
    for i in range(n):
        for a in range(3):
            lo[i, a] = min(tris[i, 0, a], tris[i, 1, a], tris[i, 2, a])
            hi[i, a] = max(tris[i, 0, a], tris[i, 1, a], tris[i, 2, a])
    return lo, hi


@njit(cache=True, inline="always")
def _mid(l, h):
    """Centroid of a float32 interval, float64 (exact: the numpy builder's value)."""
    return 0.5 * (np.float64(l) + np.float64(h))


@njit(cache=True, inline="always")
def _cent(lo, hi, p, a):
    """Centroid of primitive p's box on axis a."""
    return _mid(lo[p, a], hi[p, a])


@njit(cache=True, inline="always")
def _scale(cbox, a, bins):
    """Bins per unit of centroid extent on axis a (0 for a flat extent: every centroid in bin 0)."""
    ext = cbox[3 + a] - cbox[a]
    return bins / ext if ext > 0 else 0.0


@njit(cache=True, inline="always")
def _bin(c, c0, scale, bins):
    """The bin of centroid c over bounds starting at c0."""
    return min(max(int((c - c0) * scale), 0), bins - 1)


@njit(cache=True, nogil=True)
def _bounds(s, e, lo, hi, box, cbox):
    """Node box (float32) into box[0:6] = (min xyz, max xyz), the centroid bounds (float64) of
    primitives s:e into cbox[0:6]."""
    x0 = y0 = z0 = np.float32(np.inf)
    x1 = y1 = z1 = np.float32(-np.inf)
    cx0 = cy0 = cz0 = np.inf
    cx1 = cy1 = cz1 = -np.inf
    for p in range(s, e):                                  # scalars: kept in registers
        x0, y0, z0 = min(x0, lo[p, 0]), min(y0, lo[p, 1]), min(z0, lo[p, 2])
        x1, y1, z1 = max(x1, hi[p, 0]), max(y1, hi[p, 1]), max(z1, hi[p, 2])
        c0, c1, c2 = _cent(lo, hi, p, 0), _cent(lo, hi, p, 1), _cent(lo, hi, p, 2)
        cx0, cy0, cz0 = min(cx0, c0), min(cy0, c1), min(cz0, c2)
        cx1, cy1, cz1 = max(cx1, c0), max(cy1, c1), max(cz1, c2)
    box[0], box[1], box[2], box[3], box[4], box[5] = x0, y0, z0, x1, y1, z1
    cbox[0], cbox[1], cbox[2], cbox[3], cbox[4], cbox[5] = cx0, cy0, cz0, cx1, cy1, cz1


@njit(cache=True, inline="always")
def _fills(nl, cnt, fill):
    """Whether a split of ``cnt`` primitives with ``nl`` on the left keeps the subtree fillable
    (``fill``: see ``build_binary``): always for ``cnt > fill``; else the left count must be
    2 mod 3 when cnt is 1 mod 3, 1 mod 3 when cnt is 2 mod 3, and not 0 mod 3 when cnt is."""
    if cnt > fill:
        return True
    r = cnt % 3
    if r == 1:
        return nl % 3 == 2
    if r == 2:
        return nl % 3 == 1
    return nl % 3 != 0


@njit(cache=True, nogil=True)
def _small(nid, s, e, lo, hi, fill, order, tree, scratch):
    """Build the whole subtree of node ``nid``, of at most SWEEP_MAX primitives (s:e), boxes
    included. Nodes of 3 or more primitives take the exact SAH split: every split of the centroid
    order on each axis that ``_fills`` (ties: lowest position, then lowest axis; equal centroids
    keep list order); 2 primitives split 1 + 1. The primitives are not moved: each node is a
    list of offsets into s:e, sorted by centroid on each axis once, at the top (a stable
    partition of a sorted list is the child's sorted list), so the result is the one sorting and
    partitioning every node would give. Scratch (``_scratch``): lists (SWEEP_MAX, 4, SWEEP_MAX)
    int64 (per stack entry: the offsets sorted on x, y, z, then in list order), stk (SWEEP_MAX,
    2) int64 (node id, count), a_r (SWEEP_MAX,) float64."""
    left, right, prim, node_box = tree
    lists, stk, a_r = scratch[5], scratch[6], scratch[7]
    cnt = e - s
    for r in range(cnt):
        lists[0, 3, r] = r
    for a in range(3):
        idx = lists[0, a]
        for r in range(cnt):                               # stable insertion sort by centroid
            key = _cent(lo, hi, s + r, a)
            j = r
            while j > 0 and _cent(lo, hi, s + idx[j - 1], a) > key:
                idx[j] = idx[j - 1]
                j -= 1
            idx[j] = r
    stk[0, 0], stk[0, 1] = nid, cnt
    sp = 1
    while sp > 0:                                          # a node's children: lists sp, sp + 1
        sp -= 1
        nid, c = stk[sp, 0], stk[sp, 1]
        lst = lists[sp]
        x0 = y0 = z0 = np.float32(np.inf)
        x1 = y1 = z1 = np.float32(-np.inf)
        for r in range(c):
            p = s + lst[3, r]
            x0, y0, z0 = min(x0, lo[p, 0]), min(y0, lo[p, 1]), min(z0, lo[p, 2])
            x1, y1, z1 = max(x1, hi[p, 0]), max(y1, hi[p, 1]), max(z1, hi[p, 2])
        box = node_box[nid]
        box[0], box[1], box[2], box[3], box[4], box[5] = x0, y0, z0, x1, y1, z1
        if c == 1:
            prim[nid] = order[s + lst[3, 0]]
            continue
        best_axis, best_i = 3, 0                           # 2 primitives: list order, 1 + 1
        if c > 2:
            best_cost, best_axis = np.inf, 0
            for a in range(3):
                idx = lst[a]
                x0 = y0 = z0 = np.inf
                x1 = y1 = z1 = -np.inf
                for i in range(c - 1, 0, -1):              # suffix areas: right = sorted i..
                    p = s + idx[i]
                    x0, y0, z0 = min(x0, lo[p, 0]), min(y0, lo[p, 1]), min(z0, lo[p, 2])
                    x1, y1, z1 = max(x1, hi[p, 0]), max(y1, hi[p, 1]), max(z1, hi[p, 2])
                    a_r[i] = _half_area(x1 - x0, y1 - y0, z1 - z0)
                x0 = y0 = z0 = np.inf
                x1 = y1 = z1 = -np.inf
                ai, ci = 0, np.inf
                for i in range(c - 1):                     # split after sorted position i
                    p = s + idx[i]
                    x0, y0, z0 = min(x0, lo[p, 0]), min(y0, lo[p, 1]), min(z0, lo[p, 2])
                    x1, y1, z1 = max(x1, hi[p, 0]), max(y1, hi[p, 1]), max(z1, hi[p, 2])
                    cost = _half_area(x1 - x0, y1 - y0, z1 - z0) * (i + 1) + a_r[i + 1] * (c - i - 1)
                    if cost < ci and _fills(i + 1, c, fill):
                        ci, ai = cost, i
                if ci < best_cost:
                    best_cost, best_axis, best_i = ci, a, ai
        go = a_r                                           # reused: 1.0 = goes right
        for i in range(c):
            go[lst[best_axis, i]] = 1.0 if i > best_i else 0.0
        nl = best_i + 1
        rl = lists[sp + 1]
        for q in range(4):                                 # stable partition of every list
            k, kr = 0, 0
            for i in range(c):
                o = lst[q, i]
                if go[o] > 0.0:
                    rl[q, kr] = o
                    kr += 1
                else:
                    lst[q, k] = o
                    k += 1
        left[nid], right[nid] = nid + 1, nid + 2 * nl
        stk[sp, 0], stk[sp, 1] = nid + 1, nl
        stk[sp + 1, 0], stk[sp + 1, 1] = nid + 2 * nl, c - nl
        sp += 2


@njit(cache=True, nogil=True)
def _binned(s, e, lo, hi, cbox, bins, fill, go_right, scratch):
    """Binned SAH over the centroid bounds cbox; fills go_right[s:e] and returns True, or
    returns False if no axis can split. A split that does not ``_fills`` moves the one or two
    primitives nearest the bin boundary (by centroid on the split axis) across it. Scratch
    (``_scratch``): count (3, bins) int64, tab (3, bins, 6) float32 (bin bounds: min xyz, max
    xyz), cost (bins - 1, 3), a_r/n_r (bins,)."""
    count, tab, cost, a_r, n_r = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    count[:] = 0
    tab[:, :, :3] = np.inf
    tab[:, :, 3:] = -np.inf
    c0, c1, c2 = cbox[0], cbox[1], cbox[2]
    s0, s1, s2 = _scale(cbox, 0, bins), _scale(cbox, 1, bins), _scale(cbox, 2, bins)
    for p in range(s, e):                                  # one pass, all three axes
        l0, l1, l2, h0, h1, h2 = lo[p, 0], lo[p, 1], lo[p, 2], hi[p, 0], hi[p, 1], hi[p, 2]
        k0 = _bin(_mid(l0, h0), c0, s0, bins)
        k1 = _bin(_mid(l1, h1), c1, s1, bins)
        k2 = _bin(_mid(l2, h2), c2, s2, bins)
        for a, k in ((0, k0), (1, k1), (2, k2)):
            count[a, k] += 1
            tab[a, k, 0] = min(tab[a, k, 0], l0)
            tab[a, k, 1] = min(tab[a, k, 1], l1)
            tab[a, k, 2] = min(tab[a, k, 2], l2)
            tab[a, k, 3] = max(tab[a, k, 3], h0)
            tab[a, k, 4] = max(tab[a, k, 4], h1)
            tab[a, k, 5] = max(tab[a, k, 5], h2)
    nb = bins - 1
    cost[:] = np.inf                                      # (split, axis): ties -> first in order
    for a in range(3):
        x0 = y0 = z0 = np.float32(np.inf)
        x1 = y1 = z1 = np.float32(-np.inf)
        nr = 0.0
        for k in range(bins - 1, 0, -1):                   # right side = bins k..
            x0, y0, z0 = min(x0, tab[a, k, 0]), min(y0, tab[a, k, 1]), min(z0, tab[a, k, 2])
            x1, y1, z1 = max(x1, tab[a, k, 3]), max(y1, tab[a, k, 4]), max(z1, tab[a, k, 5])
            nr += count[a, k]
            n_r[k] = nr
            a_r[k] = _half_area(np.float64(x1) - x0, np.float64(y1) - y0, np.float64(z1) - z0)
        x0 = y0 = z0 = np.float32(np.inf)
        x1 = y1 = z1 = np.float32(-np.inf)
        nl = 0.0
        for i in range(nb):                                # left side = bins 0..i
            x0, y0, z0 = min(x0, tab[a, i, 0]), min(y0, tab[a, i, 1]), min(z0, tab[a, i, 2])
            x1, y1, z1 = max(x1, tab[a, i, 3]), max(y1, tab[a, i, 4]), max(z1, tab[a, i, 5])
            nl += count[a, i]
            if nl > 0 and n_r[i + 1] > 0:
                a_l = _half_area(np.float64(x1) - x0, np.float64(y1) - y0, np.float64(z1) - z0)
                cost[i, a] = a_l * nl + a_r[i + 1] * n_r[i + 1]
    best, bi, ba = np.inf, 0, 0
    for i in range(nb):
        for a in range(3):
            if cost[i, a] < best:
                best, bi, ba = cost[i, a], i, a
    if not np.isfinite(best):
        return False
    nl, sa = 0, _scale(cbox, ba, bins)
    for j in range(s, e):
        k = _bin(_cent(lo, hi, j, ba), cbox[ba], sa, bins)
        go_right[j] = k > bi
        nl += k <= bi
    want = _fillable_count(nl, e - s, fill)
    while nl < want:                                       # nearest right primitive goes left
        bj, bv = -1, np.inf
        for j in range(s, e):
            if go_right[j] and _cent(lo, hi, j, ba) < bv:
                bj, bv = j, _cent(lo, hi, j, ba)
        if bj < 0:                                         # none right (cannot: nl < want < e - s)
            break
        go_right[bj] = False
        nl += 1
    while nl > want:                                       # nearest left primitive goes right
        bj, bv = -1, -np.inf
        for j in range(s, e):
            if not go_right[j] and _cent(lo, hi, j, ba) >= bv:
                bj, bv = j, _cent(lo, hi, j, ba)
        if bj < 0:                                         # none left (cannot: nl > want >= 1)
            break
        go_right[bj] = True
        nl -= 1
    return True


@njit(cache=True, nogil=True)
def _fillable_count(nl, cnt, fill):
    """The left count nearest ``nl`` (within 2; the smaller on a tie) that ``_fills``."""
    for dd in (0, -1, 1, -2, 2):
        if 1 <= nl + dd <= cnt - 1 and _fills(nl + dd, cnt, fill):
            return nl + dd
    return nl


@njit(cache=True, inline="always")
def _move(dst, i, src, j):
    for a in range(3):
        dst[i, a] = src[j, a]


@njit(cache=True, nogil=True)
def _partition(s, e, go_right, order, lo, hi, t_order, t_lo, t_hi):
    """Stable partition of the primitives s:e (ids and their boxes move
    together, so that every pass reads memory in order), lefts first; the t_* arrays are
    scratch of the same shapes. Returns the number of lefts."""
    nl = 0
    for j in range(s, e):
        if not go_right[j]:
            i = s + nl
            nl += 1
        else:
            i = j - nl                                      # parked in the scratch arrays
            t_order[i] = order[j]
            _move(t_lo, i, lo, j)
            _move(t_hi, i, hi, j)
            continue
        order[i] = order[j]
        _move(lo, i, lo, j)
        _move(hi, i, hi, j)
    for j in range(s + nl, e):
        order[j] = t_order[j - nl]
        _move(lo, j, t_lo, j - nl)
        _move(hi, j, t_hi, j - nl)
    return nl


@njit(cache=True, nogil=True)
def _scratch(bins):
    """Per-thread scratch arrays of ``_binned`` and ``_small`` (allocated once per task)."""
    return (np.zeros((3, bins), np.int64), np.empty((3, bins, 6), np.float32),
            np.empty((bins - 1, 3)), np.empty(bins), np.empty(bins),
            np.empty((SWEEP_MAX, 4, SWEEP_MAX), np.int64), np.empty((SWEEP_MAX, 2), np.int64),
            np.empty(SWEEP_MAX))


@njit(cache=True, nogil=True)
def _split(nid, s, e, cbox, lo, hi, bins, fill, work, tree, scratch):
    """Split node ``nid`` (primitives s:e, more than SWEEP_MAX; centroid bounds cbox) by binned
    SAH; returns the left count. Children are numbered in pre-order with contiguous subtrees:
    left = nid + 1, right = nid + 2 * (left count)."""
    order, tmp, go_right = work
    left, right = tree[0], tree[1]
    cnt = e - s
    ok = _binned(s, e, lo, hi, cbox, bins, fill, go_right, scratch)
    nl = _fillable_count(cnt // 2, cnt, fill)              # all centroids coincide: middle
    if ok:
        nl = _partition(s, e, go_right, order, lo, hi, tmp[0], tmp[1], tmp[2])
    left[nid], right[nid] = nid + 1, nid + 2 * nl
    return nl


@njit(cache=True, nogil=True)
def _subtree(nid, s, e, lo, hi, bins, fill, work, tree):
    """Build the whole subtree of node ``nid`` (box not yet computed), depth first with a
    bounded stack (smaller child first: at most log2(n) + 2 entries)."""
    stack = np.empty((_STACK, 3), np.int64)
    cbox = np.empty(6)
    scratch = _scratch(bins)
    stack[0, 0], stack[0, 1], stack[0, 2] = nid, s, e
    sp = 1
    while sp > 0:
        sp -= 1
        nid, s, e = stack[sp, 0], stack[sp, 1], stack[sp, 2]
        if e - s <= SWEEP_MAX:
            _small(nid, s, e, lo, hi, fill, work[0], tree, scratch)
            continue
        _bounds(s, e, lo, hi, tree[3][nid], cbox)
        nl = _split(nid, s, e, cbox, lo, hi, bins, fill, work, tree, scratch)
        small_left = nl <= e - s - nl
        for first in (not small_left, small_left):         # larger first, smaller on top
            if first:
                stack[sp, 0], stack[sp, 1], stack[sp, 2] = nid + 1, s, s + nl
            else:
                stack[sp, 0], stack[sp, 1], stack[sp, 2] = nid + 2 * nl, s + nl, e
            sp += 1


@njit(cache=True, nogil=True)
def _node(nid, s, e, lo, hi, bins, fill, work, tree):
    """Compute the box of node ``nid`` (primitives s:e, more than SWEEP_MAX) and split it;
    returns the left count. The top of the tree is built node by node with it, in parallel."""
    cbox = np.empty(6)
    _bounds(s, e, lo, hi, tree[3][nid], cbox)
    return _split(nid, s, e, cbox, lo, hi, bins, fill, work, tree, _scratch(bins))


def build_binary(tris, bins: int, progress=None, fill: int = 0, threads: int | None = None):
    """Binary BVH with one triangle per leaf. tris : (n, 3, 3) float32; progress : a tqdm-like
    object (``update(triangles)``) or None; fill : split every node of at most ``fill``
    primitives so that its subtree can be collapsed into full 4-wide nodes (0: never; module
    docstring); threads : None = the machine's cores (at most 8) from ``PARALLEL_MIN``
    triangles, else one (``driver.bvh4.warm_up`` forces 2 to load every kernel).

    Returns (left, right, prim, node_lo, node_hi) over 2n-1 nodes, node 0 the root, parents
    numbered before children (pre-order); left/right are -1 for a leaf, prim is -1 for an
    interior node; node_lo/node_hi (2n-1, 3) float32 views of the node boxes."""
    n = len(tris)
    m = 2 * n - 1
    lo, hi = _prim_boxes(tris)
    left = np.full(m, -1, np.int64)
    right = np.full(m, -1, np.int64)
    prim = np.full(m, -1, np.int64)
    node_box = np.empty((m, 6), np.float32)                 # float32 bounds are exact
    order = np.arange(n, dtype=np.int64)
    tmp = (np.empty(n, np.int64), np.empty((n, 3), np.float32), np.empty((n, 3), np.float32))
    #                                                         partition scratch
    go_right = np.zeros(n, np.bool_)
    # the kernels take the work arrays and the tree's arrays as two tuples
    args = (lo, hi, int(bins), int(fill), (order, tmp, go_right), (left, right, prim, node_box))
    if threads is None:
        threads = min(os.cpu_count() or 1, 8) if n >= PARALLEL_MIN else 1
    # nodes of more than `grain` primitives are split one task each (both children become tasks:
    # after the root, all threads are busy); smaller ones are whole depth-first subtree tasks
    grain = max(SWEEP_MAX, n // (8 * threads)) if threads > 1 else n

    def task(nid, s, e):
        if e - s > grain:
            nl = _node(nid, s, e, *args)
            return [(nid + 1, s, s + nl), (nid + 2 * nl, s + nl, e)]
        _subtree(nid, s, e, *args)
        return e - s

    with ThreadPoolExecutor(threads) as pool:
        pending = {pool.submit(task, 0, 0, n)}
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for job in done:
                result = job.result()
                if isinstance(result, list):
                    pending |= {pool.submit(task, *child) for child in result}
                elif progress is not None:
                    progress.update(result)
    return left, right, prim, node_box[:, :3], node_box[:, 3:]


def check_tree(left, right) -> None:
    """Raise RuntimeError unless (left, right) (m,) is a binary tree in pre-order rooted at 0:
    a leaf has both -1, an interior node two children numbered after it, and every node but
    the root exactly one parent (so any walk down the tree ends within m steps)."""
    m = len(left)
    inner = left >= 0
    kids = np.concatenate([left[inner], right[inner]])
    i = np.flatnonzero(inner)
    ok = (np.array_equal(inner, right >= 0) and (left[inner] > i).all()
          and (right[inner] > i).all() and (kids < m).all()
          and np.array_equal(np.bincount(kids, minlength=m), np.r_[0, np.ones(m - 1, np.int64)]))
    if not ok:
        raise RuntimeError("BVH build: the binary tree is malformed (a builder bug)")


# ----------------------------------------------------------------------------------------------
# the stored boxes of the binary nodes (``driver.bvh.pipeline`` says why they are grown)

@njit(cache=True, nogil=True)
def grow_boxes(lo, hi, pad):
    """Grow the (m, 3) node bounds in place into the stored boxes, ``nextafter(float32(min -
    pad), -inf)`` and ``nextafter(float32(max + pad), +inf)`` (``driver.bvh.pipeline`` says why;
    float32 values, exact in either array dtype), and return their half areas (m,) float64."""
    m = lo.shape[0]
    area = np.empty(m)
    down, up = np.float32(-np.inf), np.float32(np.inf)
    for i in range(m):
        for a in range(3):
            lo[i, a] = np.nextafter(np.float32(np.float64(lo[i, a]) - pad), down)
            hi[i, a] = np.nextafter(np.float32(np.float64(hi[i, a]) + pad), up)
        dx = np.float64(hi[i, 0]) - np.float64(lo[i, 0])
        dy = np.float64(hi[i, 1]) - np.float64(lo[i, 1])
        dz = np.float64(hi[i, 2]) - np.float64(lo[i, 2])
        area[i] = _half_area(dx, dy, dz)
    return area

