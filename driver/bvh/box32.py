"""The box32 image writer: numbers the 4-wide tree's nodes and writes 128-byte float32 box
nodes and one 64-byte triangle node per triangle (the layout of ``driver.bvh.image``). The
numbering and copying is a numba kernel (``fill_image``): as numpy passes it took a third of a
2 M-triangle build."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core.layout import (BOX_BYTES, BOX_NODE, BOX_TYPE, NO_CHILD, TRI_BYTES, TRI_NODE, TRI_TYPE,
                           NodeRef)
from .image import _half_area
from .params import WIDTH


@njit(cache=True, inline="always")
def place_slots(r, slots, left, child, box, parent, node_lo, node_hi, nb, box_ptr, no_child):
    """Wide node ``r``'s slots (``slots[r]``: binary node ids, used first, -1 unused): each used
    slot's stored box into ``box[r, j]`` (xmin ymin zmin xmax ymax zmax), an unused slot pointer
    ``no_child`` and the +inf box; a box child the next box node number (breadth first, after
    ``nb``) as its pointer and ``r`` as its parent, pointers affine in the node index
    (``box_ptr``). Returns (the used slots, the last box node number). Every image writer
    places its box nodes' slots with it; the leaves are the writer's own."""
    used = 0
    for j in range(WIDTH):
        x = slots[r, j]
        if x < 0:
            child[r, j] = no_child
            for c in range(6):
                box[r, j, c] = np.inf
            continue
        used += 1
        for c in range(3):
            box[r, j, c] = node_lo[x, c]
            box[r, j, 3 + c] = node_hi[x, c]
        if left[x] >= 0:
            nb += 1
            child[r, j] = box_ptr[0] + nb * box_ptr[1]
            parent[nb] = box_ptr[0] + r * box_ptr[1]
    return used, nb


@njit(cache=True, nogil=True)
def fill_image(slots, tree, tris, nodes, leaves, box_ptr, tri_ptr, no_child):
    """Number the wide tree's nodes and write them into the image's node fields; returns the
    sum of the used slots' areas (the SAH numerator).

    tree: the binary tree's (left, prim, node_lo, node_hi, node_area); nodes: the box nodes'
    (child, box, parent, count); leaves: the triangle nodes' (tri, tri_prim).
    slots (k, 4): binary node ids per box node, breadth first (used slots first, -1 unused);
    box node i's children that are box nodes are numbered in row-major slot order over all
    rows (breadth first), triangle nodes in the order they are referenced. child/box/parent/
    count: the box nodes' fields, tri/tri_prim the triangle nodes' (views into a zeroed image,
    ``driver.core.layout``'s structs). Pointers are affine in the node index (``driver.bvh4``
    derives them from ``NodeRef``): box node i is ``box_ptr[0] + i * box_ptr[1]``, triangle node j
    ``tri_ptr[0] + j * tri_ptr[1]``; an unused slot is ``no_child`` with a +inf box."""
    left, prim, node_lo, node_hi, node_area = tree
    child, box, parent, count = nodes
    tri, tri_prim = leaves
    k = slots.shape[0]
    nb, nt = 0, 0
    area = 0.0
    parent[0] = no_child
    for r in range(k):
        used, nb = place_slots(r, slots, left, child, box, parent, node_lo, node_hi, nb, box_ptr,
                               no_child)
        for j in range(used):
            x = slots[r, j]
            area += node_area[x]
            if left[x] < 0:                                # a triangle node
                child[r, j] = tri_ptr[0] + nt * tri_ptr[1]
                p = prim[x]
                tri_prim[nt] = p
                for v in range(3):
                    for c in range(3):
                        tri[nt, v, c] = tris[p, v, c]
                nt += 1
        count[r] = used
    return area


def _write_image(levels, left, prim, node_lo, node_hi, node_area, tris):
    """Number nodes, fill the byte image (``driver.bvh.box32.fill_image``). node_lo/node_hi/
    node_area: the stored boxes of the binary nodes (``driver.bvh.build.grow_boxes``). Returns
    (image, depth, sah_cost, child histogram)."""
    n_box = sum(len(s) for s in levels)
    n_tri = len(tris)
    total = BOX_BYTES * n_box + TRI_BYTES * n_tri
    if total >= 1 << 35:
        raise ValueError(f"BVH image of {total} bytes exceeds the 32 GiB a uint32 pointer reaches")
    slots = np.concatenate(levels)                         # (n_box, 4) binary ids, breadth-first
    image = np.zeros(total, np.uint8)
    bn = image[:BOX_BYTES * n_box].view(BOX_NODE)           # the node structs (driver.core.layout)
    tn = image[BOX_BYTES * n_box:].view(TRI_NODE)
    box0, box1 = NodeRef.encode([0, BOX_BYTES], BOX_TYPE).astype(np.int64)
    tri0, tri1 = NodeRef.encode([BOX_BYTES * n_box, BOX_BYTES * n_box + TRI_BYTES],
                                TRI_TYPE).astype(np.int64)
    area = fill_image(slots, (left, prim, node_lo, node_hi, node_area), tris,
                      (bn["child"], bn["box"], bn["parent"], bn["count"]), (tn["tri"], tn["prim"]),
                      (box0, box1 - box0), (tri0, tri1 - tri0), NO_CHILD)
    r = bn["box"][0, :bn["count"][0]].astype(np.float64)
    root_area = _half_area(r[:, :3].min(axis=0), r[:, 3:].max(axis=0))
    hist = np.bincount(bn["count"], minlength=5)[1:]
    return image, len(levels), 1.0 + area / float(root_area), hist
