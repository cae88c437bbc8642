"""The q8 and q8g image writer (docs/compressed.md): numbers the 4-wide tree's nodes and
writes 64-byte quantized box nodes, 64-byte triangle-pair leaves and 128-byte group leaves
(numba kernels; ``driver.core.layout`` owns the structs and the decode).

Quantization (``_quantize``): per box node and axis, ``origin`` = the float32 minimum of the
children's stored (grown, ``driver.bvh.pipeline``) lower bounds, ``exp`` = the smallest exponent in
[-126, 119] with ``(max - origin) / 2**exp <= 255``, ``qlo = floor((lo - origin) / 2**exp)``,
``qhi = ceil((hi - origin) / 2**exp)``; where a flat leaf child is thinner than one step, the
origin moves down onto the grid of that leaf's front face instead (``_origin``), so that its
step of slack lies behind the surface. ``verify_containment`` then decodes every node with
``driver.core.layout.decode_q8`` (the datapath's arithmetic) and moves a ``qlo`` down or a ``qhi``
up by one wherever the decode put a bound inside the child's stored box, until none does.
The quantization runs on all cores and gives the same image on any number of threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..core.layout import (GROUP_MAX_TRIS, GROUP_MAX_VERTS, GROUP_NODE, GROUP_TYPE,
                           LEAF_OFFSET_LIMIT, NO_CHILD, PAIR_BYTES, PAIR_NODE, PAIR_TYPE, Q8_BYTES,
                           Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, Q8_TYPE, NodeRef, decode_q8, node_word)
from .image import _half_area
from .params import WIDTH
from . import q8
from .box32 import place_slots


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


@njit(cache=True, nogil=True, parallel=True)
def _quantize(slots, tree, pairs, groups, tris, facing, nodes, leaves, box_ptr, leaf_ptr,
              no_child):
    """Number the wide tree's nodes and write the q8 box nodes (``nodes``: origin, exp + count,
    child, q, parent, and ref) and the leaves (lw/lf: 64-byte leaf slots in the order they are referenced), as
    ``driver.bvh.box32.fill_image`` does for box32. A leaf's ``prim`` below ``len(first)`` is a
    pair leaf (one slot), else group ``prim - len(first)`` (``gtri``, ``gvert``, ``gidx``: two
    slots). ``leaf_base``: byte offset of the first slot; ``types``: (pair,
    group) pointer type codes. ``ref`` (k, 4, 6) float32 receives each used slot's stored box
    (+inf unused); ``facing`` (leaves, 3) int8: the sign of each leaf's face normal per axis
    (``_origin``). Returns 0, or the index + 1 of a node whose extent needs an exponent above
    Q8_EXP_MAX (the first such node). Node r's box children and leaf slots are numbered after
    those of nodes 0..r-1 (a prefix sum of each node's counts), so the nodes are then written
    independently, on all cores."""
    left, prim, node_lo, node_hi = tree
    first, second, idx, v3 = pairs
    gtri, gvert, gidx = groups
    origin, exp, child, q, parent, ref = nodes
    lw, lf = leaves
    leaf_base, types = leaf_ptr
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
        nl = nl0[r]
        used = place_slots(r, slots, left, child, ref, parent, node_lo, node_hi, nb0[r], box_ptr,
                           no_child)[0]
        for j in range(used):
            x = slots[r, j]
            if left[x] < 0:                                # a pair or group leaf
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


def _write_q8_image(levels, left, prim, node_lo, node_hi, pairs, groups, tris):
    """Number nodes, quantize and fill the q8/q8g image (``driver.bvh.q8``): q8 box nodes
    breadth first from offset 0, then the leaves (pair leaves, group leaves of ``groups``, the
    four arrays of ``driver.bvh.q8g.group_leaves``) in the order they are referenced. Returns
    (image, depth, sah_cost from the decoded boxes, child histogram)."""
    first, second, idx, v3 = pairs[:4]
    members, gtri, gvert, gidx = groups
    n_box = sum(len(s) for s in levels)
    n_slots = len(first) - int((members >= 0).sum()) + 2 * len(members)   # 64-byte leaf slots
    total = Q8_BYTES * n_box + PAIR_BYTES * n_slots
    if total > LEAF_OFFSET_LIMIT:
        raise ValueError(f"BVH image of {total} bytes: the leaves of a q8 image must lie in its "
                         f"first {LEAF_OFFSET_LIMIT >> 30} GiB")
    slots = np.concatenate(levels)
    image = np.zeros(total, np.uint8)
    qn = image[:Q8_BYTES * n_box].view(Q8_NODE)
    lw = image[Q8_BYTES * n_box:].view("<u4").reshape(n_slots, PAIR_BYTES // 4)
    ref = np.empty((n_box, 4, 6), np.float32)
    box0, box1 = NodeRef.encode([0, Q8_BYTES], Q8_TYPE).astype(np.int64)
    bad = _quantize(slots, (left, prim, node_lo, node_hi), (first, second, idx, v3),
                    (gtri, gvert, gidx), tris, q8.facing(tris, first, second, members),
                    (qn["origin"], qn["exp"], qn["child"], qn["q"], qn["parent"], ref),
                    (lw, lw.view("<f4")), (box0, box1 - box0),
                    (Q8_BYTES * n_box, (PAIR_TYPE, GROUP_TYPE)), NO_CHILD)
    if bad:
        raise ValueError("q8 image: the scene's extent needs a plane exponent above "
                         f"{2 ** 119 * 255:.3g} per step (box node {bad - 1}); use box32")
    dec = verify_containment(qn, ref)[1]
    count = (qn["exp"][:, 3] & 7).astype(np.int64)
    used = np.arange(4)[None, :] < count[:, None]
    u = dec[used].astype(np.float64)
    area = _half_area(u[:, :3], u[:, 3:]).sum()
    r = dec[0, :count[0]].astype(np.float64)
    root_area = _half_area(r[:, :3].min(axis=0), r[:, 3:].max(axis=0))
    hist = np.bincount(count, minlength=5)[1:]
    return image, len(levels), 1.0 + area / float(root_area), hist
