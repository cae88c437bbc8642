"""BVH4 for the RayFlex datapath: binned-SAH binary build, collapse to 4-wide, RDNA-like image.

Build pipeline (madmann91/bvh and tinybvh style):

1. Primitive boxes and centroids only (``_prim_boxes``): the binary builder never sees triangles.
2. Binary BVH by SAH, C_trav = C_int = 1, split until every leaf holds one triangle (RDNA-style
   leaves): nodes of more than ``SWEEP_MAX`` (8) primitives are binned, ``bins`` (16) bins per
   axis over the node's centroid bounds on all three axes; nodes of 3..8 primitives try every
   split of the centroid order on all three axes (the exact SAH, which no binning beats);
   2 primitives split 1 + 1; a node whose centroids all coincide is split in the middle of its
   primitive list. Two implementations of these same rules (they build the same tree):
   ``builder="fast"`` (default), numba kernels in ``driver.bvh_build`` (depth first, with a
   progress bar), and ``builder="numpy"``, the vectorised reference here (``_build_binary``:
   all nodes of a tree level binned, scored and partitioned together; the whole build is
   about 10x slower with it: docs/bvh.md). ``fill`` > 0 (fast builder only) constrains the
   split counts of small nodes so that their subtrees can become full 4-wide nodes
   (``driver.bvh_build``).
3. Collapse to 4-wide: ``collapse="sah"`` (default) picks the binary nodes that become box nodes
   by the dynamic programme of Ylitie et al. 2017 that minimises the wide tree's SAH cost
   (``driver.bvh_build.collapse_sah``); ``collapse="greedy"`` (``_collapse``) starts each 4-wide
   node with the binary node's two children and twice replaces the interior child of largest
   surface area by its two children (triangle children are never opened).
4. Memory image (``_write_image``): docs/datapath.md#bvh4-image, layout below.

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

Conservative boxes. The datapath's slab test is strict (``tmin < tmax``) and rounds ``box - o``
and ``* inv`` to float32, so an exact box would lose flat (axis-aligned) triangles entirely and
could lose grazing hits on box faces by an ulp. Every stored bound is therefore grown outward:

    stored_min = nextafter(float32(min - pad), -inf)
    stored_max = nextafter(float32(max + pad), +inf)
    pad = PAD_REL * S,   S = largest |coordinate| in the mesh,   PAD_REL = 2**-16

i.e. at least one float32 ulp of the bound (so every box, flat ones included, has positive
thickness) plus a scene-relative margin of about 256 float32 ulps of S (1.5e-5 S, far below a
triangle's size in any practical mesh, so traversal cost is unchanged). Why a margin: the slab
test rounds ``box - o`` and then ``* inv``, an error of about one ulp of ``|box - o|``, and the
watertight triangle test rounds ``P - o`` the same way; when the ray origin is far from the box
these ulps are much larger than the box's own ulps, and a box grown by one ulp only would be
flattened back to zero thickness (a miss) for e.g. a flat wall seen from a camera 20 S away.
The margin keeps every triangle that the TRIANGLE op hits inside a box that the QUADBOX op hits
for ray origins up to about 100 S from the world origin (tests/test_bvh4.py checks it on the
golden model up to 64 S; measured on the test meshes, PAD_REL = 2**-18 first lost hits at 64 S
and 2**-16 at 256 S). Growth is monotone, so a child's stored box lies inside its parent's.
"""

from __future__ import annotations

import time

import numpy as np

# the node image's layout is driver.layout's (docs/datapath.md#bvh4-image, docs/compressed.md);
# the names are re-exported for users
from .layout import (BOX_BYTES, BOX_NODE, BOX_TYPE, FLAG_DECODE_Q8, IMAGE_FORMATS,  # noqa: F401
                     NO_CHILD, QNODE_WORDS,
                     GROUP_BYTES, GROUP_NODE, GROUP_TYPE, INSTANCE_NODE, INSTANCE_TYPE,
                     LEAF_NEXT_TYPE, LEAF_OFFSET_LIMIT,
                     PAIR_BYTES, PAIR_NODE, PAIR_TYPE, Q8_BYTES, Q8_NODE, Q8_TYPE, QUADBOX,
                     TRANSFORM, TRI_BYTES, TRI_NODE, TRI_TYPE, TRIANGLE, NodeRef, decode_q8,
                     leaf_triangles, node_word, read_nodes)

PAD_REL = 2.0 ** -16
from .bvh.params import SWEEP_MAX  # noqa: E402  (nodes of <= 8 primitives: exact SAH sweep)


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
                 format: str = "box32"):
        if format not in IMAGE_FORMATS:
            raise ValueError(f"BVH image format must be one of {IMAGE_FORMATS}, got {format!r}")
        self.image = image
        self.format = format
        q8 = format != "box32"
        self.box_type = Q8_TYPE if q8 else BOX_TYPE
        self.root = self.box_type       # box node at offset 0
        self.child_word = node_word(Q8_NODE if q8 else BOX_NODE, "child")
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
        boxes are decoded (``driver.layout.decode_q8``)."""
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
        if self.format != "box32":
            nodes = read_nodes(self._words, ptrs, Q8_NODE)
            return nodes["parent"].astype(np.uint32), (nodes["exp"][:, 3] & 7).astype(np.int64)
        nodes = read_nodes(self._words, ptrs, BOX_NODE)
        return nodes["parent"].astype(np.uint32), nodes["count"].astype(np.int64)


# ----------------------------------------------------------------------------------------------
# request operands: what a node pointer becomes on the datapath (the Python side of sim/rf_sim.h)

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
    triangle, ``driver.layout.leaf_triangles``)."""
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


# ----------------------------------------------------------------------------------------------
# input

def as_triangles(mesh_or_triangles) -> np.ndarray:
    """(n, 3, 3) float32 C-contiguous triangles from a trimesh mesh or an array-like.

    Raises ValueError (one line) for no triangles, a wrong shape or non-finite coordinates."""
    with np.errstate(over="ignore"):                        # > float32 max -> inf -> rejected
        if hasattr(mesh_or_triangles, "vertices") and hasattr(mesh_or_triangles, "faces"):
            v = np.asarray(mesh_or_triangles.vertices, np.float32).reshape(-1, 3)
            f = np.asarray(mesh_or_triangles.faces, np.int64)
            if f.ndim != 2 or f.shape[1] != 3:
                raise ValueError(f"mesh faces must be (n, 3), got {f.shape}")
            if f.size and (f.min() < 0 or f.max() >= len(v)):
                raise ValueError("mesh faces index vertices that do not exist")
            tris = v[f]
        else:
            try:
                tris = np.asarray(mesh_or_triangles, np.float32)
            except (TypeError, ValueError) as e:
                raise ValueError(f"triangles must be an (n, 3, 3) float array: {e}") from None
    if tris.ndim != 3 or tris.shape[1:] != (3, 3):
        raise ValueError(f"triangles must have shape (n, 3, 3), got {tris.shape}")
    if len(tris) == 0:
        raise ValueError("no triangles: cannot build a BVH of an empty mesh")
    if not np.isfinite(tris).all():
        raise ValueError("triangle coordinates must be finite (in float32)")
    return np.ascontiguousarray(tris)


def _prim_boxes(tris: np.ndarray):
    """Primitive boxes (lo, hi) and box centroids, float64 (n, 3) each (exact float32 values)."""
    lo = tris.min(axis=1).astype(np.float64)
    hi = tris.max(axis=1).astype(np.float64)
    return lo, hi, 0.5 * (lo + hi)


def _rows(x, idx):
    """x[idx] along axis 0 (np.take: several times faster than fancy indexing for (n, 3) rows)."""
    return np.take(x, idx, axis=0)


def _half_area(lo, hi):
    d = hi - lo
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


# ----------------------------------------------------------------------------------------------
# binary binned-SAH builder (boxes and centroids only)

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


# ----------------------------------------------------------------------------------------------
# binary -> 4-wide

def _collapse(left, right, area):
    """Greedy collapse: 4-wide levels from the binary tree: a list, root level first, of (k, 4) arrays of binary
    node ids per 4-wide box node (-1 = unused slot; used slots first)."""
    levels = []
    if left[0] < 0:                                       # single triangle: root has one child
        slots = np.array([[0, -1, -1, -1]])
    else:
        slots = np.full((1, 4), -1)
        slots[0, :2] = left[0], right[0]
    while len(slots):
        rows = np.arange(len(slots))
        for free in (2, 3):                               # open the largest interior child, twice
            interior = (slots >= 0) & (left[slots] >= 0)
            a = np.where(interior, area[slots], -np.inf)
            j = np.argmax(a, axis=1)
            ok = interior[rows, j]
            r, jj = rows[ok], j[ok]
            opened = slots[r, jj]
            slots[r, jj] = left[opened]
            slots[r, free] = right[opened]
        levels.append(slots)
        nxt = slots[(slots >= 0) & (left[slots] >= 0)]          # row-major: breadth-first order
        slots = np.full((len(nxt), 4), -1)
        slots[:, 0], slots[:, 1] = left[nxt], right[nxt]
    return levels


# ----------------------------------------------------------------------------------------------
# memory image

def _write_image(levels, left, prim, node_lo, node_hi, node_area, tris):
    """Number nodes, fill the byte image (``driver.bvh_build.fill_image``). node_lo/node_hi/
    node_area: the stored boxes of the binary nodes (``driver.bvh_build.grow_boxes``). Returns
    (image, depth, sah_cost, child histogram)."""
    from .bvh.build import fill_image
    n_box = sum(len(s) for s in levels)
    n_tri = len(tris)
    total = BOX_BYTES * n_box + TRI_BYTES * n_tri
    if total >= 1 << 35:
        raise ValueError(f"BVH image of {total} bytes exceeds the 32 GiB a uint32 pointer reaches")
    slots = np.concatenate(levels)                         # (n_box, 4) binary ids, breadth-first
    image = np.zeros(total, np.uint8)
    bn = image[:BOX_BYTES * n_box].view(BOX_NODE)           # the node structs (driver.layout)
    tn = image[BOX_BYTES * n_box:].view(TRI_NODE)
    box0, box1 = NodeRef.encode([0, BOX_BYTES], BOX_TYPE).astype(np.int64)
    tri0, tri1 = NodeRef.encode([BOX_BYTES * n_box, BOX_BYTES * n_box + TRI_BYTES],
                                TRI_TYPE).astype(np.int64)
    area = fill_image(slots, left, prim, node_lo, node_hi, node_area, tris, bn["child"],
                      bn["box"], bn["parent"], bn["count"], tn["tri"], tn["prim"],
                      (box0, box1 - box0), (tri0, tri1 - tri0), NO_CHILD)
    r = bn["box"][0, :bn["count"][0]].astype(np.float64)
    root_area = _half_area(r[:, :3].min(axis=0), r[:, 3:].max(axis=0))
    hist = np.bincount(bn["count"], minlength=5)[1:]
    return image, len(levels), 1.0 + area / float(root_area), hist


def _write_q8_image(levels, left, prim, node_lo, node_hi, pairs, groups, tris):
    """Number nodes, quantize and fill the q8/q8g image (``driver.bvh.q8``): q8 box nodes
    breadth first from offset 0, then the leaves (pair leaves, group leaves of ``groups``, the
    four arrays of ``driver.bvh.q8.group_leaves``) in the order they are referenced. Returns
    (image, depth, sah_cost from the decoded boxes, child histogram)."""
    from .bvh.q8 import _quantize, facing, verify_containment
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
    bad = _quantize(slots, left, prim, node_lo, node_hi, first, second, idx, v3, gtri, gvert,
                    gidx, tris, facing(tris, first, second, members), qn["origin"], qn["exp"],
                    qn["child"], qn["q"], qn["parent"], ref, lw, lw.view("<f4"),
                    (box0, box1 - box0), Q8_BYTES * n_box, (PAIR_TYPE, GROUP_TYPE), NO_CHILD)
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


BUILDERS = ("fast", "numpy")
COLLAPSES = ("sah", "greedy")
PROGRESS_MIN = 1_000_000        # progress=None shows a bar from this many triangles (~0.5 s)


def build(triangles_or_trimesh, bins: int = 16, *, builder: str = "fast", collapse: str = "sah",
          fill: int = 0, progress=None, format: str = "box32", pair: bool = True,
          on_phase=None) -> BVH4:
    """Build a BVH4 (binned SAH, one triangle per leaf) and its memory image
    (docs/datapath.md#bvh4-image, docs/compressed.md).

    triangles_or_trimesh : (n, 3, 3) array-like (converted to float32) or a trimesh.Trimesh
    bins : SAH bins per axis (>= 2; default 16)
    builder : "fast" (numba, default) or "numpy" (the reference; same tree, ~10x slower)
    collapse : "sah" (SAH-optimal, default) or "greedy" (the earlier collapse, for comparisons)
    fill : subtrees of at most ``fill`` triangles are split so that their 4-wide nodes can all
        be full (``driver.bvh_build``; fast builder only): fewer box nodes and bytes for a
        little more SAH; 0 (default) = plain SAH splits
    progress : True/False, or None = a bar on stderr (terminal only) from PROGRESS_MIN triangles
    format : "box32" (default: 128-byte float32 box nodes, one 64-byte node per triangle, the
        module docstring's layout), "q8" (docs/compressed.md: triangles sharing an edge are
        paired first and each pair is one leaf primitive of the build; 64-byte quantized box
        nodes whose decoded child boxes contain the box32 stored boxes; 64-byte pair leaves) or
        "q8g" (q8 where the subtrees of 3 to 6 triangles that the SAH trade-off of
        ``driver.bvh.q8.group_leaves`` picks become 128-byte group leaves sharing up to 8
        vertices)
    pair : q8 formats: pair triangles that share an edge (default); False: one triangle per
        pair leaf, e.g. the instance boxes of a q8 TLAS (``driver.bvh.instances``)
    on_phase : called with each phase's name as it starts (``driver.bvh.phases``); the
        phases' wall and CPU times are ``stats["phase_s"]`` and ``stats["phase_cpu_s"]``
    Degenerate (zero-area) triangles are kept (the datapath never hits them).
    Raises ValueError for an empty input, a wrong shape, non-finite coordinates or a bad option."""
    t0 = time.perf_counter()
    if int(bins) < 2:
        raise ValueError(f"bins must be >= 2, got {bins}")
    if builder not in BUILDERS:
        raise ValueError(f"builder must be one of {BUILDERS}, got {builder!r}")
    if collapse not in COLLAPSES:
        raise ValueError(f"collapse must be one of {COLLAPSES}, got {collapse!r}")
    if isinstance(fill, bool) or not isinstance(fill, (int, np.integer)) or fill < 0:
        raise ValueError(f"fill must be an integer >= 0, got {fill!r}")
    if format not in IMAGE_FORMATS:
        raise ValueError(f"format must be one of {IMAGE_FORMATS}, got {format!r}")
    if fill and builder != "fast":
        raise ValueError("fill needs the fast builder (the numpy reference has plain SAH splits)")
    tris = as_triangles(triangles_or_trimesh)
    from .bvh.phases import Phases
    phases = Phases(on_phase)
    pairs, prims = None, tris
    if format != "box32":
        from .bvh.q8 import _pairs, pair_triangles, vertex_ids
        if pair:
            faces = getattr(triangles_or_trimesh, "faces", None)
            pairs = pair_triangles(tris, None if faces is None else np.asarray(faces), phases)
        else:                           # no partner: every leaf holds one triangle
            with phases("pairs"):
                ids = vertex_ids(tris)
                pairs = (*_pairs(ids, np.full(len(tris), -1, np.int64), tris), ids)
        prims = pairs[4]                # one box-shaped triangle per leaf: the builder's input

    from .bvh import build as bvh_build
    from .progress import bar as progress_bar
    show = None if progress is None and len(tris) >= PROGRESS_MIN else bool(progress)
    with progress_bar(len(tris), "BVH build", "tri", show, leave=False) as bar:
        with phases("binary build"):
            if builder == "fast":
                left, right, prim, node_lo, node_hi = bvh_build.build_binary(
                    prims, int(bins), bar, int(fill))
            else:
                left, right, prim, node_lo, node_hi = _build_binary(*_prim_boxes(prims),
                                                                    int(bins))
                bar.update(len(prims))
            bvh_build.check_tree(left, right)
        bar.set_postfix_str("collapse")
        with phases("stored boxes"):
            pad = PAD_REL * float(max(-tris.min(), tris.max()))
            if collapse == "greedy":                            # from the exact boxes
                greedy_area = _half_area(node_lo.astype(np.float64), node_hi)
            node_area = bvh_build.grow_boxes(node_lo, node_hi, pad)   # in place: stored boxes
        groups = None
        if format != "box32":
            from .bvh.q8 import group_leaves
            with phases("group leaves"):
                groups = group_leaves(left, right, prim, node_area, pairs, format == "q8g")
        with phases("collapse"):
            if collapse == "sah":
                levels = bvh_build.collapse_sah(left, right, node_area)
            else:
                levels = _collapse(left, right, greedy_area)
        bar.set_postfix_str("image")
        with phases("image"):
            if pairs is None:
                image, depth, sah, hist = _write_image(levels, left, prim, node_lo, node_hi,
                                                       node_area, tris)
            else:
                image, depth, sah, hist = _write_q8_image(levels, left, prim, node_lo, node_hi,
                                                          pairs, groups, tris)
    n_box = sum(len(s) for s in levels)
    paired = 0 if pairs is None else 2 * int((pairs[1] >= 0).sum())
    n_groups = 0 if groups is None else len(groups[0])
    leaves = len(prims) if groups is None else len(prims) - int((groups[0] >= 0).sum()) + n_groups
    stats = {"format": format, "box_nodes": n_box, "tri_nodes": len(tris),
             "leaf_nodes": leaves, "group_leaves": n_groups,
             "grouped_triangles": 0 if groups is None else int((groups[1] >= 0).sum()),
             "depth": depth, "sah_cost": sah, "fill": int(fill),
             "build_s": time.perf_counter() - t0, "bytes": int(image.nbytes),
             "bytes_per_triangle": image.nbytes / len(tris), "pair_ratio": paired / len(tris),
             "avg_children": float((hist * np.arange(1, 5)).sum() / n_box),
             "child_histogram": hist.tolist(), "phase_s": phases.seconds,
             "phase_cpu_s": phases.cpu_seconds}
    return BVH4(image, tris, stats, format)


def warm_up() -> float:
    """Compile (first use on a machine: ~20 s, then cached on disk by numba) or load (~1 s per
    process) the fast builder's kernels by building a tiny mesh; returns the seconds it took.
    Benchmarks call it so that a build time is the build's, as they build the Verilated model
    before timing the simulation."""
    from .bvh.build import build_binary
    t0 = time.perf_counter()
    tris = np.random.default_rng(0).random((64, 3, 3)).astype(np.float32)
    build(tris, progress=False)
    build_binary(tris, 16, threads=2)               # the threaded path's kernel (_node) too
    return time.perf_counter() - t0
