"""The vectorised numpy reference of the binary BVH builder (``builder="numpy"`` of
``driver.bvh.pipeline.build``): the same rules as the numba kernels of
``driver.bvh.build``, which must make the same tree (tests/test_bvh4.py compares them
node by node); all nodes of a tree level are binned, scored and partitioned together,
and the whole build is about 10x slower with it (docs/bvh.md)."""

from __future__ import annotations

import numpy as np

from .image import _half_area
from .params import SWEEP_MAX


def _prim_boxes(tris: np.ndarray):
    """Primitive boxes (lo, hi) and box centroids, float64 (n, 3) each (exact float32 values)."""
    lo = tris.min(axis=1).astype(np.float64)
    hi = tris.max(axis=1).astype(np.float64)
    return lo, hi, 0.5 * (lo + hi)


def _rows(x, idx):
    """x[idx] along axis 0 (np.take: several times faster than fancy indexing for (n, 3) rows)."""
    return np.take(x, idx, axis=0)


def _build_binary(lo, hi, cent, bins: int):
    """Binary BVH with one primitive per leaf, built level by level.

    Returns (left, right, prim, node_lo, node_hi) over 2n-1 nodes, node 0 the root, parents
    numbered before children; left/right are -1 for a leaf, prim is -1 for an interior node."""
    n = len(lo)
    m = 2 * n - 1
    left = np.full(m, -1, np.int64)
    right = np.full(m, -1, np.int64)
    prim = np.full(m, -1, np.int64)
    node_lo = np.empty((m, 3))
    node_hi = np.empty((m, 3))
    order = np.arange(n)
    if n == 1:
        prim[0] = 0
        node_lo[0], node_hi[0] = lo[0], hi[0]
        return left, right, prim, node_lo, node_hi
    # active nodes of the current level: node id, first position in `order`, primitive count
    ids, start, cnt = np.array([0]), np.array([0]), np.array([n])
    next_id = 1
    while len(ids):
        k = len(ids)
        seg_off = np.concatenate(([0], np.cumsum(cnt)[:-1]))       # segment starts, compacted
        total = int(cnt.sum())
        seg = np.repeat(np.arange(k), cnt)
        rank = np.arange(total) - seg_off[seg]                     # index within the segment
        pidx = order[start[seg] + rank]
        node_lo[ids] = np.minimum.reduceat(_rows(lo, pidx), seg_off, axis=0)
        node_hi[ids] = np.maximum.reduceat(_rows(hi, pidx), seg_off, axis=0)

        # go right: a 2-primitive node splits 1 + 1; nodes of 3..SWEEP_MAX primitives take the
        # exact SAH sweep; larger ones binned SAH (a node whose centroids all coincide splits
        # its list in the middle)
        go_right = rank >= (cnt // 2)[seg]
        for lo_n, hi_n in ((3, 4), (5, SWEEP_MAX)):
            grp = (cnt >= lo_n) & (cnt <= hi_n)
            if grp.any():
                sel = grp[seg]
                p = pidx[sel]
                go_right[sel] = _sweep_sah((np.cumsum(grp) - 1)[seg[sel]], rank[sel],
                                           int(grp.sum()), hi_n, _rows(cent, p), _rows(lo, p),
                                           _rows(hi, p))
        big = cnt > SWEEP_MAX
        if big.any():
            sel = big[seg]
            p = pidx[sel]
            bseg = (np.cumsum(big) - 1)[seg[sel]]
            b, axis, split, ok = _binned_sah(bseg, int(big.sum()), _rows(cent, p), _rows(lo, p),
                                             _rows(hi, p), bins)
            sah_right = b[np.arange(len(bseg)), axis[bseg]] > split[bseg]
            go_right[sel] = np.where(ok[bseg], sah_right, go_right[sel])

        # stable partition of each segment: lefts first
        is_left = (~go_right).astype(np.int64)
        n_left = np.add.reduceat(is_left, seg_off)
        before = np.cumsum(is_left) - is_left                       # lefts before, global
        left_rank = before - before[seg_off][seg]
        new_pos = start[seg] + np.where(go_right, n_left[seg] + rank - left_rank, left_rank)
        order[new_pos] = pidx

        lid = next_id + 2 * np.arange(k)
        next_id += 2 * k
        left[ids], right[ids] = lid, lid + 1
        cid = np.stack([lid, lid + 1], axis=1).ravel()
        cstart = np.stack([start, start + n_left], axis=1).ravel()
        ccnt = np.stack([n_left, cnt - n_left], axis=1).ravel()
        leaf = ccnt == 1
        p = order[cstart[leaf]]
        prim[cid[leaf]] = p
        node_lo[cid[leaf]], node_hi[cid[leaf]] = _rows(lo, p), _rows(hi, p)
        ids, start, cnt = cid[~leaf], cstart[~leaf], ccnt[~leaf]
    return left, right, prim, node_lo, node_hi


def _binned_sah(seg, k, c, plo, phi, bins):
    """Best SAH split of k nodes at once. seg (P,) node of each primitive (sorted), c/plo/phi (P, 3)
    centroids and boxes. Returns (bin (P, 3) int, axis (k,), split (k,), ok (k,)): a primitive
    goes right iff bin[axis] > split; ok is False where no axis has distinct centroids."""
    nb = bins - 1                                          # split candidates per axis
    seg_off = np.flatnonzero(np.concatenate(([True], seg[1:] != seg[:-1])))
    cmin = np.minimum.reduceat(c, seg_off, axis=0)
    cext = np.maximum.reduceat(c, seg_off, axis=0) - cmin
    scale = np.divide(bins, cext, out=np.zeros_like(cext), where=cext > 0)
    b = ((c - _rows(cmin, seg)) * _rows(scale, seg)).astype(np.int64)
    np.clip(b, 0, bins - 1, out=b)

    # per (bin, axis, [component,] node), bins first so the prefix scans run over long rows
    count = np.empty((bins, 3, k))
    blo = np.empty((bins, 3, 3, k), np.float32)             # exact: bounds are float32 values
    bhi = np.empty((bins, 3, 3, k), np.float32)
    plo32, phi32 = plo.astype(np.float32), phi.astype(np.float32)
    for a in range(3):
        key = b[:, a] * k + seg
        count[:, a] = np.bincount(key, minlength=bins * k).reshape(bins, k)
        for comp in range(3):
            acc = np.full(bins * k, np.inf, np.float32)
            np.minimum.at(acc, key, plo32[:, comp])
            blo[:, a, comp] = acc.reshape(bins, k)
            acc = np.full(bins * k, -np.inf, np.float32)
            np.maximum.at(acc, key, phi32[:, comp])
            bhi[:, a, comp] = acc.reshape(bins, k)

    # SAH of the split after bin i (left = bins 0..i, right = bins i+1..): A_L n_L + A_R n_R
    n_l = np.cumsum(count, axis=0)[:nb]
    n_r = np.cumsum(count[::-1], axis=0)[::-1][1:]
    with np.errstate(invalid="ignore"):
        a_l = _half_area_c(np.minimum.accumulate(blo, axis=0)[:nb],
                           np.maximum.accumulate(bhi, axis=0)[:nb])
        a_r = _half_area_c(np.minimum.accumulate(blo[::-1], axis=0)[::-1][1:],
                           np.maximum.accumulate(bhi[::-1], axis=0)[::-1][1:])
        cost = np.where((n_l > 0) & (n_r > 0), a_l * n_l + a_r * n_r, np.inf)
    cost = cost.reshape(nb * 3, k)                         # row = split * 3 + axis
    best = np.argmin(cost, axis=0)
    ok = np.isfinite(cost[best, np.arange(k)])
    return b, best % 3, best // 3, ok


def _sweep_sah(seg, rank, k, width, c, plo, phi):
    """Exact SAH sweep for k small nodes (at most ``width`` primitives each): every split of the
    centroid order along every axis. seg/rank (P,) node and index within it, c/plo/phi (P, 3).
    Returns go_right (P,) bool."""
    p = len(seg)
    slot = np.full((width, k), -1)
    slot[rank, seg] = np.arange(p)
    cnt = np.bincount(seg, minlength=k)
    n_l = np.arange(1, width)[:, None]                      # split after sorted position i
    n_r = cnt - n_l
    valid = slot >= 0
    pos = np.empty((3, p), np.int64)
    best_cost = np.full(k, np.inf)
    best_axis = np.zeros(k, np.int64)
    best_i = np.zeros(k, np.int64)
    j = np.broadcast_to(np.arange(width)[:, None], slot.shape)
    for a in range(3):
        key = np.where(valid, c[slot, a], np.inf)           # padding sorts last
        s = np.take_along_axis(slot, np.argsort(key, axis=0, kind="stable"), 0)
        used = s >= 0
        pos[a, s[used]] = j[used]
        slo = np.where(used[..., None], _rows(plo, s), np.inf)
        shi = np.where(used[..., None], _rows(phi, s), -np.inf)
        with np.errstate(invalid="ignore"):
            a_l = _half_area(np.minimum.accumulate(slo, 0), np.maximum.accumulate(shi, 0))[:-1]
            a_r = _half_area(np.minimum.accumulate(slo[::-1], 0)[::-1],
                             np.maximum.accumulate(shi[::-1], 0)[::-1])[1:]
            cost = np.where(n_r >= 1, a_l * n_l + a_r * n_r, np.inf)
        i = np.argmin(cost, axis=0)
        ci = cost[i, np.arange(k)]
        better = ci < best_cost
        best_cost[better], best_axis[better], best_i[better] = ci[better], a, i[better]
    return pos[best_axis[seg], np.arange(p)] > best_i[seg]


def _half_area_c(lo, hi):
    """Half surface area, float64, of boxes with the component on axis -2: (..., 3, k)."""
    d = hi.astype(np.float64) - lo
    return d[..., 0, :] * d[..., 1, :] + d[..., 1, :] * d[..., 2, :] + d[..., 2, :] * d[..., 0, :]
