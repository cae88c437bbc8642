"""The BVH4 memory image and its readers: ``BVH4`` (a built image with vectorised decoders
that read it like an RT unit) and the request operands a node pointer becomes on the
datapath (the Python side of sim/rf_sim.h); the layouts are ``driver.core.layout``'s
(docs/datapath.md#bvh4-image, docs/compressed.md).

Memory image (one contiguous little-endian byte buffer; every node 64-byte aligned)::

    node pointer (uint32) = (byte_offset >> 3) | type        type: 5 = box node, 0 = triangle node
        byte_offset is a multiple of 64, so byte_offset >> 3 has its low 3 bits clear and the type
        fills them; byte_offset = (pointer & ~7) << 3.   0xFFFFFFFF = no child (its type bits, 7,
        are neither 0 nor 5). The root box node is at offset 0, so its pointer is 5.

    [0, 128 * box_nodes)                          box nodes, breadth-first (root first)
    [128 * box_nodes, + 64 * tri_nodes)           triangle nodes, in the order they are referenced

    box node, 128 bytes                           triangle node, 64 bytes
      0  uint32  child[4]    pointers               0  float32 A[3]
     16  float32 box[4][6]   xmin ymin zmin         12  float32 B[3]
                             xmax ymax zmax         24  float32 C[3]
    112  uint32  parent      (root: 0xFFFFFFFF)     36  uint32  primitive id (index into input)
    116  uint32  child count (1..4)                 40  24 bytes zero
    120  uint32  reserved[2] (zero)

    Valid children come first; an unused slot has pointer 0xFFFFFFFF and the box
    (+inf, +inf, +inf, +inf, +inf, +inf), which the docs/datapath.md#quadbox slab test never hits:
    on an axis with d > 0 (or d = +0) near = +inf so tmin = +inf; with d < 0 (or d = -0) far = -inf
    so tmax = -inf.
"""

from __future__ import annotations

import numpy as np

from ..core.layout import (BOX_NODE, BOX_TYPE, DEFAULT_FORMAT, FORMATS, GROUP_TYPE, INSTANCE_NODE,
                           INSTANCE_TYPE, LEAF_NEXT_TYPE, PAIR_TYPE, Q8_NODE, Q8_TYPE, TRI_NODE,
                           TRI_TYPE, NodeRef, decode_q8, image_format, leaf_triangles, node_word,
                           read_nodes)
from ..core.wire import FLAG_DECODE_Q8, QNODE_WORDS, QUADBOX, TRANSFORM, TRIANGLE


class BVH4:
    """A built BVH4: the memory image plus vectorised decoders that read it like an RT unit.

    Attributes
    ----------
    image : (bytes,) uint8, the memory image (layout in the module docstring; ``format="q8"``:
        docs/compressed.md)
    format : "box32" (the layout above), "q8" (64-byte quantized box nodes, pair leaves) or
        "q8g" (q8 with 128-byte group leaves of 3 to 6 triangles sharing vertices)
    root : int, pointer of the root box node (offset 0, so 5 for box32 and 4 for q8)
    triangles : (n, 3, 3) float32, the input triangles; primitive id i is ``triangles[i]``
    stats : dict with ``box_nodes``, ``tri_nodes``, ``depth`` (box-node levels on the longest
        root-to-leaf path; a root with only triangle children has depth 1), ``sah_cost``,
        ``build_s`` (wall seconds), ``bytes`` (= 128 * box_nodes + 64 * tri_nodes),
        ``avg_children`` (used child slots per box node), ``child_histogram`` (list: number of
        box nodes with 1, 2, 3, 4 used slots), ``format``, ``bytes_per_triangle``,
        ``leaf_nodes`` (triangle nodes or pair leaves), ``pair_ratio`` (fraction of the
        triangles that share a pair leaf; 0 for box32).

    ``sah_cost`` is the expected number of datapath ops of a random ray that hits the root box,
    with C_trav = C_int = 1, computed from the stored (grown) float32 boxes in float64:

        sah_cost = sum over box nodes N of A(N) / A(root) * 1 + sum over triangle nodes L of
                   A(L) / A(root) * 1
                 = 1 + sum over all used child slots s of A(box[s]) / A(root)

    where A is the surface area of a box, a node's box is the box its parent stores for it, and
    A(root) is the area of the union of the root's child boxes.
    """

    def __init__(self, image: np.ndarray, triangles: np.ndarray, stats: dict,
                 format: str = DEFAULT_FORMAT):
        fmt = image_format(format)
        self.image = image
        self.format = format
        self.box_type = fmt.box_type
        self.root = self.box_type       # box node at offset 0
        self.child_word = node_word(fmt.box_node, "child")
        self.triangles = triangles
        self.stats = stats
        self._words = image.view("<u4")

    def __repr__(self) -> str:
        s = self.stats
        return (f"BVH4({self.format}, {len(self.triangles)} triangles, {s['box_nodes']} box "
                f"nodes, depth {s['depth']}, SAH {s['sah_cost']:.2f}, {s['bytes']} bytes)")

    node_type = staticmethod(NodeRef.type)        # type bits of node pointers
    node_offset = staticmethod(NodeRef.offset)    # byte offsets (int64) of node pointers

    def box_nodes(self, ptrs):
        """Decode box nodes (box32 or q8, the image's). ptrs : (m,) uint32 box-node pointers.

        Returns (children (m, 4) uint32, boxes (m, 4, 6) float32), read from ``image``; q8
        boxes are decoded (``driver.core.layout.decode_q8``)."""
        ptrs = np.asarray(ptrs, np.uint32)
        if (self.node_type(ptrs) != self.box_type).any():
            raise ValueError("box_nodes: a pointer is not a box-node pointer of this image")
        return box_operands(self._words, ptrs)

    def tri_nodes(self, ptrs):
        """Decode the triangles that triangle requests name. ptrs : (m,) uint32 pointers of
        triangle nodes, pair or group leaves (their first triangle) or ``LEAF_NEXT_TYPE`` (a
        leaf's later triangle).

        Returns (tris (m, 3, 3) float32, prim (m,) int64), read from ``image``."""
        ptrs = np.asarray(ptrs, np.uint32)
        return tri_operands(self._words, ptrs)

    def node_extras(self, ptrs):
        """(parent pointer (m,) uint32, child count (m,) int64) of box nodes."""
        ptrs = np.asarray(ptrs, np.uint32)
        if FORMATS[self.format].compressed:
            nodes = read_nodes(self._words, ptrs, Q8_NODE)
            return nodes["parent"].astype(np.uint32), (nodes["exp"][:, 3] & 7).astype(np.int64)
        nodes = read_nodes(self._words, ptrs, BOX_NODE)
        return nodes["parent"].astype(np.uint32), nodes["count"].astype(np.int64)


def q8_request(req: np.ndarray, nodes: np.ndarray, compressed: bool = False) -> None:
    """Fill the operand of QUADBOX request rows ``req`` (``REQUEST_DTYPE``, opcode already set)
    for the q8 box nodes ``nodes``, one per row: the one place on the host that turns a q8 node
    into a request (``NodeSource::q8_request`` in sim/rf_sim.h is the harness's). For a
    datapath with the decode (``compressed``) the request carries the node as stored in
    ``qnode`` with the flag ``DECODE_Q8``; otherwise the host decodes it (``decode_q8``) and the
    request carries the four boxes."""
    if compressed:
        req["qnode"] = np.ascontiguousarray(nodes).view(np.uint32).reshape(-1, QNODE_WORDS)
        req["flags"] |= FLAG_DECODE_Q8
    else:
        req["box"] = decode_q8(nodes)


def box_operands(image, ptrs):
    """(children (m, 4) uint32, boxes (m, 4, 6) float32) of box nodes of either type."""
    ptrs = np.asarray(ptrs, np.uint32)
    children = np.empty((len(ptrs), 4), np.uint32)
    boxes = np.empty((len(ptrs), 4, 6), np.float32)
    typ = NodeRef.type(ptrs)
    for t, node in ((BOX_TYPE, BOX_NODE), (Q8_TYPE, Q8_NODE)):
        sel = np.flatnonzero(typ == t)
        if len(sel):
            nodes = read_nodes(image, ptrs[sel], node)
            children[sel] = nodes["child"]
            boxes[sel] = nodes["box"] if t == BOX_TYPE else decode_q8(nodes)
    if not ((typ == BOX_TYPE) | (typ == Q8_TYPE)).all():
        raise ValueError("a pointer is not a box-node pointer")
    return children, boxes


def tri_operands(image, ptrs):
    """(tris (m, 3, 3) float32, prim (m,) int64) named by triangle request pointers: a triangle
    node, a pair or group leaf (its first triangle) or ``LEAF_NEXT_TYPE`` (a leaf's later
    triangle, ``driver.core.layout.leaf_triangles``)."""
    ptrs = np.asarray(ptrs, np.uint32)
    tris = np.empty((len(ptrs), 3, 3), np.float32)
    prim = np.empty(len(ptrs), np.int64)
    typ = NodeRef.type(ptrs)
    if not np.isin(typ, (TRI_TYPE, PAIR_TYPE, GROUP_TYPE, LEAF_NEXT_TYPE)).all():
        raise ValueError("a pointer is not a triangle request pointer")
    sel = np.flatnonzero(typ == TRI_TYPE)
    if len(sel):
        nodes = read_nodes(image, ptrs[sel], TRI_NODE)
        tris[sel], prim[sel] = nodes["tri"], nodes["prim"]
    sel = np.flatnonzero(typ != TRI_TYPE)
    if len(sel):
        tris[sel], prim[sel] = leaf_triangles(image, ptrs[sel])
    return tris, prim


def request_operands(req: np.ndarray, image, ptrs, compressed: bool = False) -> None:
    """Fill ``opcode``, ``box`` and ``tri`` of ``REQUEST_DTYPE`` rows ``req`` for the node
    pointers ``ptrs`` (one per row), as the harness does (sim/rf_sim.h ``NodeSource``);
    ``compressed``: q8 nodes go to a datapath with the decode (``q8_request``). An instance
    node (two-level images) becomes a TRANSFORM of the row's ray by its ``world_to_object``
    (``matrix``; the transform on the datapath, docs/instances.md)."""
    ptrs = np.asarray(ptrs, np.uint32)
    typ = NodeRef.type(ptrs)
    xf = typ == INSTANCE_TYPE
    box = NodeRef.is_box(ptrs)
    req["opcode"] = np.where(box, QUADBOX, np.where(xf, TRANSFORM, TRIANGLE))
    if xf.any():
        sel = np.flatnonzero(xf)
        req["box"][sel] = 0
        req["tri"][sel] = 0
        req["matrix"][sel] = read_nodes(image, ptrs[sel], INSTANCE_NODE)["world_to_object"]
        box = box | xf                    # no triangle operand below
    sel = np.flatnonzero(typ == BOX_TYPE)
    req["box"][sel] = read_nodes(image, ptrs[sel], BOX_NODE)["box"]
    sel = np.flatnonzero(typ == Q8_TYPE)
    if len(sel):
        rows = req[sel]
        q8_request(rows, read_nodes(image, ptrs[sel], Q8_NODE), compressed)
        req[sel] = rows
    req["tri"][~box] = tri_operands(image, ptrs[~box])[0]


def _half_area(lo, hi):
    d = hi - lo
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]
