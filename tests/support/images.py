"""Checks of a built image read back from its bytes, shared by the BVH tests and the generated
geometry corpus: ``check_bvh`` (box32: every invariant of docs/datapath.md#bvh4-image, walked
from the root) and ``check_image`` (q8/q8g: containment of every node's decoded child boxes,
every triangle in exactly one leaf reached from the root, bit for bit)."""

from __future__ import annotations

import numpy as np
import pytest

from driver.bvh4 import BOX_BYTES, BOX_TYPE, NO_CHILD, PAD_REL, TRI_BYTES, TRI_TYPE
from driver.core.layout import (GROUP_BYTES, GROUP_MAX_TRIS, GROUP_TYPE, PAIR_BYTES, PAIR_TYPE,
                                Q8_BYTES, Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, Q8_TYPE, NodeRef,
                                decode_q8, leaf_count, leaf_next, leaf_triangles, q8_count)


def half_area(b):
    d = b[..., 3:].astype(np.float64) - b[..., :3]
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def check_bvh(bvh):
    """Walk the image breadth-first with the decoders and check every docs/datapath.md#bvh4-image
    invariant.

    Returns {prim id: the float32 box its parent stores for its triangle node}."""
    img, n = bvh.image, len(bvh.triangles)
    words = img.view("<u4")
    assert img.dtype == np.uint8 and img.ndim == 1
    assert bvh.root == BOX_TYPE and bvh.node_offset([bvh.root])[0] == 0
    seen_box, seen_tri, leaf_box = [np.array([bvh.root], np.uint32)], [], {}
    level, level_box, parents = seen_box[0], None, np.array([NO_CHILD], np.uint32)
    area_sum, depth, counts = 0.0, 0, []
    while len(level):
        depth += 1
        children, boxes = bvh.box_nodes(level)
        parent, count = bvh.node_extras(level)
        used = children != NO_CHILD
        assert (used.sum(1) == count).all() and (count >= 1).all()
        counts.append(count)
        assert (np.sort(~used, axis=1) == ~used).all(), "used slots first"
        assert (parent == parents).all()
        off = bvh.node_offset(level)
        assert (words[(off >> 2)[:, None] + np.array([30, 31])] == 0).all(), "reserved words"
        assert np.isposinf(boxes[~used]).all(), "unused slot box is +inf"
        b = boxes[used]
        assert (b[:, 3:] > b[:, :3]).all(), "every box has positive thickness"
        if level_box is not None:                           # child box inside the parent's box
            pb = np.broadcast_to(level_box[:, None, :], boxes.shape)[used]
            assert (b[:, :3] >= pb[:, :3]).all() and (b[:, 3:] <= pb[:, 3:]).all()
        else:
            root_box = np.concatenate([b[:, :3].min(0), b[:, 3:].max(0)])
        area_sum += half_area(b).sum()
        ptr = children[used]
        typ = bvh.node_type(ptr)
        assert np.isin(typ, [BOX_TYPE, TRI_TYPE]).all()
        coff = bvh.node_offset(ptr)
        assert (coff % 64 == 0).all() and (coff > 0).all()
        assert (coff + np.where(typ == BOX_TYPE, BOX_BYTES, TRI_BYTES) <= len(img)).all()
        tri = typ == TRI_TYPE
        if tri.any():
            tris, prim = bvh.tri_nodes(ptr[tri])
            assert ((prim >= 0) & (prim < n)).all()
            assert (tris.view(np.uint32) == bvh.triangles[prim].view(np.uint32)).all()
            tb = b[tri]
            assert (tb[:, :3] < tris.min(1)).all() and (tb[:, 3:] > tris.max(1)).all(), \
                "triangle strictly inside its box"
            toff = bvh.node_offset(ptr[tri])
            assert (words[(toff >> 2)[:, None] + np.arange(10, 16)] == 0).all(), "tri node tail"
            seen_tri.append(ptr[tri])
            leaf_box.update(zip(prim.tolist(), tb))
        box = typ == BOX_TYPE
        parents = np.repeat(level, used.sum(1))[box]
        level, level_box = ptr[box], b[box]
        seen_box.append(level)
    boxes_p = np.concatenate(seen_box)
    tris_p = np.concatenate(seen_tri)
    everything = np.concatenate([boxes_p, tris_p])
    assert len(np.unique(everything)) == len(everything), "no node referenced twice"
    # the nodes tile the image exactly: all bytes belong to a reachable node, no overlaps
    off = bvh.node_offset(everything)
    size = np.where(bvh.node_type(everything) == BOX_TYPE, BOX_BYTES, TRI_BYTES)
    o = np.argsort(off)
    assert off[o][0] == 0 and (off[o][1:] == (off[o] + size[o])[:-1]).all()
    assert off[o][-1] + size[o][-1] == len(img)
    assert sorted(leaf_box) == list(range(n)), "every triangle in exactly one leaf"
    s = bvh.stats
    assert s["box_nodes"] == len(boxes_p) and s["tri_nodes"] == len(tris_p) == n
    assert s["bytes"] == len(img) == BOX_BYTES * s["box_nodes"] + TRI_BYTES * n
    assert s["depth"] == depth
    assert s["sah_cost"] == pytest.approx(1 + area_sum / half_area(root_box), rel=1e-9)
    assert s["build_s"] >= 0
    hist = np.bincount(np.concatenate(counts), minlength=5)[1:]
    assert s["child_histogram"] == hist.tolist()
    assert s["avg_children"] == pytest.approx(np.concatenate(counts).mean(), rel=1e-12)
    return leaf_box



def _grown(lo, hi, pad):
    """The box32 stored box of exact float32 bounds (driver.bvh4's growth rule)."""
    glo = np.nextafter(np.float32(lo.astype(np.float64) - pad), np.float32(-np.inf))
    ghi = np.nextafter(np.float32(hi.astype(np.float64) + pad), np.float32(np.inf))
    return glo.astype(np.float32), ghi.astype(np.float32)


def image_leaves(bvh):
    """Every leaf the box nodes reference: (pointers (l,) uint32, triangle count (l,),
    triangles (l, GROUP_MAX_TRIS, 3, 3) float32 and prims (l, GROUP_MAX_TRIS) int64 (-1
    padded)), read through the request pointers the traversal issues (``leaf_next``)."""
    nb = bvh.stats["box_nodes"]
    nodes = bvh.image[:Q8_BYTES * nb].view(Q8_NODE)
    ptr = nodes["child"][np.arange(4)[None, :] < q8_count(nodes)[:, None]]
    ptr = ptr[NodeRef.type(ptr) != Q8_TYPE]
    count = leaf_count(bvh.image, ptr)
    tris = np.zeros((len(ptr), GROUP_MAX_TRIS, 3, 3), np.float32)
    prim = np.full((len(ptr), GROUP_MAX_TRIS), -1, np.int64)
    for k in range(GROUP_MAX_TRIS):
        has = np.flatnonzero(count > k)
        req = ptr[has] if k == 0 else leaf_next(ptr[has], k)
        tris[has, k], prim[has, k] = leaf_triangles(bvh.image, req)
    return ptr, count, tris, prim


def check_image(bvh, tris) -> None:
    """Every triangle in exactly one leaf, bit for bit in its input vertex order; every used
    child slot's decoded box contains the box32 stored box of that child, recomputed here from
    the triangles below it; unused slots decode to +inf; exponents and counts in range; group
    leaves hold 3 to 6 triangles and 128 bytes, pair leaves 1 or 2 and 64."""
    tris = np.asarray(tris, np.float32)
    nb = bvh.stats["box_nodes"]
    nodes = bvh.image[:Q8_BYTES * nb].view(Q8_NODE)
    assert bvh.format in ("q8", "q8g") and bvh.root == Q8_TYPE
    lptr, lcount, ltris, lprim = image_leaves(bvh)
    group = NodeRef.type(lptr) == GROUP_TYPE
    assert np.isin(NodeRef.type(lptr), (PAIR_TYPE, GROUP_TYPE)).all()
    assert bvh.format == "q8g" or not group.any()
    assert ((lcount[group] >= 3) & (lcount[group] <= GROUP_MAX_TRIS)).all()
    assert ((lcount[~group] >= 1) & (lcount[~group] <= 2)).all()
    assert group.sum() == bvh.stats["group_leaves"] and len(lptr) == bvh.stats["leaf_nodes"]
    assert lcount[group].sum() == bvh.stats["grouped_triangles"]
    assert bvh.stats["bytes"] == bvh.image.nbytes == 64 * nb + 64 * (~group).sum() + \
        GROUP_BYTES * group.sum()
    # leaves follow the box nodes back to back, each in its own 64-byte slots
    off = np.sort(NodeRef.offset(lptr))
    size = np.where(group, GROUP_BYTES, PAIR_BYTES)[np.argsort(NodeRef.offset(lptr))]
    assert off[0] == 64 * nb and np.array_equal(off[1:], (off + size)[:-1])

    # reached from the root: every box node and leaf exactly once (a tree)
    child_all = nodes["child"][np.arange(4)[None, :] < q8_count(nodes)[:, None]]
    level, seen, leaves_seen = np.array([0]), [np.array([0])], []
    for _ in range(nb):
        if not len(level):
            break
        ptr = nodes["child"][level][np.arange(4)[None, :] < q8_count(nodes[level])[:, None]]
        box = NodeRef.type(ptr) == Q8_TYPE
        level = NodeRef.offset(ptr[box]) // Q8_BYTES
        seen.append(level)
        leaves_seen.append(ptr[~box])
    seen, leaves_seen = np.concatenate(seen), np.concatenate(leaves_seen)
    assert np.array_equal(np.sort(seen), np.arange(nb)), "every box node reached once"
    assert np.array_equal(np.sort(leaves_seen), np.sort(lptr)), "every leaf reached once"
    assert len(child_all) == nb - 1 + len(lptr)

    used = lprim >= 0
    assert np.array_equal(np.sort(lprim[used]), np.arange(len(tris)))
    assert np.array_equal(ltris[used].view(np.uint32), tris[lprim[used]].view(np.uint32))
    if bvh.format == "q8":
        assert np.isclose(bvh.stats["pair_ratio"], 2 * (lcount == 2).sum() / len(tris))

    exp = nodes["exp"][:, :3].view(np.int8)
    assert ((exp >= Q8_EXP_MIN) & (exp <= Q8_EXP_MAX)).all()
    count = q8_count(nodes)
    assert ((count >= 1) & (count <= 4)).all()
    assert not (nodes["exp"][:, 3] & ~np.uint8(7)).any()

    # exact bounds of every leaf and, bottom up (children follow their parent), of every node
    big = np.float32(np.inf)
    leaf_lo = np.where(used[..., None, None], ltris, big).min(axis=(1, 2))
    leaf_hi = np.where(used[..., None, None], ltris, -big).max(axis=(1, 2))
    leaf_at = {int(p): i for i, p in enumerate(lptr)}
    node_lo = np.full((nb, 3), np.inf, np.float32)
    node_hi = np.full((nb, 3), -np.inf, np.float32)
    child_lo = np.zeros((nb, 4, 3), np.float32)
    child_hi = np.zeros((nb, 4, 3), np.float32)
    ptr = nodes["child"]
    typ, off = NodeRef.type(ptr), NodeRef.offset(ptr)
    used = np.arange(4)[None, :] < count[:, None]
    assert (ptr[~used] == NO_CHILD).all()
    for i in range(nb - 1, -1, -1):
        for j in range(count[i]):
            if typ[i, j] == Q8_TYPE:
                k = off[i, j] // Q8_BYTES
                assert k > i
                lo, hi = node_lo[k], node_hi[k]
            else:
                k = leaf_at[int(ptr[i, j])]
                lo, hi = leaf_lo[k], leaf_hi[k]
            child_lo[i, j], child_hi[i, j] = lo, hi
            node_lo[i] = np.minimum(node_lo[i], lo)
            node_hi[i] = np.maximum(node_hi[i], hi)
    pad = PAD_REL * float(max(-tris.min(), tris.max()))
    ref_lo, ref_hi = _grown(child_lo, child_hi, pad)
    dec = decode_q8(nodes)
    assert (dec[..., :3][used] <= ref_lo[used]).all()
    assert (dec[..., 3:][used] >= ref_hi[used]).all()
    assert (dec[~used] == np.inf).all()
