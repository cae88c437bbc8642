"""The two-level BVH image: one bottom-level BVH (BLAS) per distinct mesh, a top-level BVH
(TLAS) over the instances whose leaves are 128-byte instance nodes, all in one image
(docs/instances.md).

Image layout (one contiguous little-endian buffer, every node 64-byte aligned)::

    [0, B * tlas_box_nodes)            TLAS box nodes, breadth-first, root at offset 0: box32
                                       (B = 128) under box32 BLASes, q8 (B = 64) under q8 or q8g
    [.., + 128 * instances)            instance nodes (driver.core.layout.INSTANCE_NODE), in order
    [.., ...)                          the BLASes, one after another, each as
                                       ``driver.bvh.pipeline.build``
                                       writes it (box32, q8 or q8g), its pointers moved by its
                                       offset

The TLAS is built by the same builder as any BVH4 (``tlas_format``), from one degenerate
"triangle" per instance whose box is the instance's world box: the BLAS root's stored box (the
union of its child boxes) with its 8 corners through ``object_to_world`` in float64, rounded
outward to float32 (the builder then grows it by its usual margin), so every TLAS box contains
the transformed BLAS boxes. A q8 TLAS is quantized as any q8 image, so its decoded child boxes
contain those grown boxes; its triangles are not paired (one instance per leaf). Its leaves
become instance pointers.

Mirrored instances (negative determinant): the datapath judges a triangle's facing in the space
it is tested in, the instance's object space, where a mirroring transform swaps the faces. The
driver keeps the world-space winding, as a DXR application does by setting
``TRIANGLE_FRONT_COUNTERCLOCKWISE`` on a mirrored instance: a mesh that has mirrored instances
also gets a BLAS of its triangles with the last two vertices swapped (A, C, B), and its mirrored
instances point there. So instanced hits equal those of the flattened world-space triangles, both
faces included (the BLAS's primitive ids stay those of the mesh).
"""

from __future__ import annotations

import time

import numpy as np

from ..instances import Instances, world_boxes
from .image import BVH4, box_operands
from .pipeline import build
from ..core.layout import (BOX_BYTES, BOX_NODE, BOX_TYPE, INSTANCE_BYTES, INSTANCE_NODE,
                           INSTANCE_TYPE, NO_CHILD, PAIR_NODE, PAIR_TYPE, Q8_BYTES, Q8_NODE,
                           Q8_TYPE, TRI_NODE, TRI_TYPE, NodeRef, read_nodes)


def tlas_format(format: str) -> str:
    """The TLAS's image format under BLASes in ``format``: box32 under box32, else q8 (a q8g
    TLAS would group instance leaves, which are single nodes)."""
    return "box32" if format == "box32" else "q8"


def _box_node(fmt: str):
    """(node struct, bytes, pointer type) of the box nodes of an image in ``fmt``."""
    return (BOX_NODE, BOX_BYTES, BOX_TYPE) if fmt == "box32" else (Q8_NODE, Q8_BYTES, Q8_TYPE)


class TwoLevelBVH(BVH4):
    """A two-level image (``build_two_level``). Beyond ``BVH4``: ``instances`` (the
    ``driver.instances.Instances`` it was built from), ``blas_root`` (k,) uint32 (each
    instance's BLAS pointer), ``blas`` (the per-BLAS ``BVH4`` statistics, one dict per BLAS:
    ``mesh``, ``mirrored``, ``offset``, ``bytes``, ``stats``). ``triangles`` are the flattened
    world-space triangles (computed on first use; ``prim`` indexes them)."""

    def __init__(self, image, instances: Instances, stats: dict, format: str, blas_root,
                 blas: list):
        super().__init__(image, None, stats, format)
        self.root = int(NodeRef.encode(0, _box_node(tlas_format(format))[2]))
        self.box_type = None            # box nodes of the TLAS's and the BLASes' formats
        self.instances = instances
        self.blas_root = np.asarray(blas_root, np.uint32)
        self.blas = blas
        self.transform = "driver"       # where traversals run the instance transform (default)

    @property
    def triangles(self):
        if self._flat is None:
            self._flat = self.instances.flatten()
        return self._flat

    @triangles.setter
    def triangles(self, value):
        self._flat = value

    def __repr__(self) -> str:
        s = self.stats
        return (f"TwoLevelBVH({self.format} BLAS, {s['instances']} instances of "
                f"{len(self.blas)} BLAS, {s['instanced_triangles']} instanced triangles, "
                f"{s['bytes']} bytes)")

    def box_nodes(self, ptrs):
        return box_operands(self._words, np.asarray(ptrs, np.uint32))


def _relocate(image: np.ndarray, box_nodes: int, fmt: str, base: int) -> None:
    """Move the pointers of a BLAS image (in place) to its place ``base`` bytes into the image."""
    node, size, _ = _box_node(fmt)
    rows = image[:size * box_nodes].view(node)
    shift = np.uint32(base >> 3)
    for field in ("child", "parent"):
        v = rows[field]
        v[v != NO_CHILD] += shift


def _root_box(bvh: BVH4) -> np.ndarray:
    """(6,) float64: the union of the BLAS root's stored child boxes."""
    children, boxes = bvh.box_nodes(np.array([bvh.root], np.uint32))
    used = boxes[0][children[0] != NO_CHILD].astype(np.float64)
    return np.concatenate([used[:, :3].min(0), used[:, 3:].max(0)])


def build_two_level(instances: Instances, format: str = "box32", progress=None,
                    **build_kw) -> TwoLevelBVH:
    """The two-level image of ``instances`` (module docstring): BLASes in ``format`` ("box32",
    "q8" or "q8g"), the TLAS in ``tlas_format(format)``; ``build_kw`` go to every
    ``driver.bvh.pipeline.build``."""
    t0 = time.perf_counter()
    mirrored = instances.mirrored
    keys = sorted({(int(j), bool(mi)) for j, mi in zip(instances.mesh, mirrored)})
    blases = {}
    for j, mi in keys:
        tris = instances.meshes[j]
        if mi:
            tris = np.ascontiguousarray(tris[:, [0, 2, 1]])
        blases[(j, mi)] = build(tris, format=format, progress=progress, **build_kw)
    key_of = [(int(j), bool(mi)) for j, mi in zip(instances.mesh, mirrored)]
    root_box = {key: _root_box(b) for key, b in blases.items()}
    local = np.stack([root_box[key] for key in key_of])
    wb = world_boxes(instances, local)
    k = len(instances)
    t_fmt = tlas_format(format)
    t_node, t_bytes, _ = _box_node(t_fmt)
    tlas = build(np.stack([wb[:, 0], wb[:, 1], wb[:, 0]], axis=1), format=t_fmt, pair=False,
                 progress=False, **{key: v for key, v in build_kw.items() if key != "fill"})
    nb_t = tlas.stats["box_nodes"]
    inst_off = t_bytes * nb_t
    offset = inst_off + INSTANCE_BYTES * k
    layout, blas_info = {}, []
    for key in keys:
        layout[key] = offset
        offset += blases[key].image.nbytes
    if offset >= 1 << 35:
        raise ValueError(f"two-level image of {offset} bytes exceeds the 32 GiB a uint32 "
                         "pointer reaches")
    image = np.zeros(offset, np.uint8)
    tnodes = image[:inst_off].view(t_node)
    tnodes[:] = tlas.image[:inst_off].view(t_node)
    child = tnodes["child"]
    leaf, which = _tlas_leaves(tlas, child, t_fmt, k)
    child[leaf] = NodeRef.encode(inst_off + INSTANCE_BYTES * which, INSTANCE_TYPE)
    for key in keys:
        b, off = blases[key], layout[key]
        part = image[off:off + b.image.nbytes]
        part[:] = b.image
        _relocate(part, b.stats["box_nodes"], format, off)
        blas_info.append({"mesh": key[0], "mirrored": key[1], "offset": off,
                          "bytes": int(b.image.nbytes), "stats": b.stats})
    roots = np.array([NodeRef.encode(layout[key], NodeRef.type(blases[key].root))
                      for key in key_of], np.uint32)
    inodes = image[inst_off:inst_off + INSTANCE_BYTES * k].view(INSTANCE_NODE)
    inodes["world_to_object"] = instances.world_to_object()
    inodes["object_to_world"] = instances.object_to_world
    inodes["blas"] = roots
    inodes["instance"] = np.arange(k, dtype=np.uint32)
    blas_bytes = sum(b["bytes"] for b in blas_info)
    depth = tlas.stats["depth"] + max(b.stats["depth"] for b in blases.values())
    phase_s, phase_cpu_s = _phase_totals((tlas, *blases.values()))
    tri = sum(b.stats["tri_nodes"] for b in blases.values())
    paired = sum(b.stats["pair_ratio"] * b.stats["tri_nodes"] for b in blases.values())
    stats = {"format": format, "tlas_format": t_fmt, "instances": k,
             "instanced_triangles": instances.triangles_total,
             "blas_triangles": instances.blas_triangles, "blas": len(keys),
             "tlas_box_nodes": nb_t, "tlas_bytes": inst_off, "instance_bytes": INSTANCE_BYTES * k,
             "blas_bytes": blas_bytes,
             "box_nodes": nb_t + sum(b.stats["box_nodes"] for b in blases.values()),
             "tri_nodes": tri,
             "leaf_nodes": sum(b.stats["leaf_nodes"] for b in blases.values()),
             "depth": depth, "sah_cost": tlas.stats["sah_cost"], "fill": 0,
             "build_s": time.perf_counter() - t0, "bytes": int(image.nbytes),
             "bytes_per_triangle": image.nbytes / instances.triangles_total,
             "pair_ratio": paired / tri, "avg_children": tlas.stats["avg_children"],
             "child_histogram": tlas.stats["child_histogram"], "phase_s": phase_s,
             "phase_cpu_s": phase_cpu_s}
    return TwoLevelBVH(image, instances, stats, format, roots, blas_info)


def _tlas_leaves(tlas: BVH4, child: np.ndarray, t_fmt: str, k: int) -> tuple:
    """The TLAS's leaf slots among its box nodes' ``child`` pointers (a mask) and the instance
    each holds; AssertionError unless each of the ``k`` instances is exactly one leaf."""
    if t_fmt == "box32":
        leaf = (child != NO_CHILD) & (NodeRef.type(child) == TRI_TYPE)
        which = read_nodes(tlas.image, child[leaf], TRI_NODE)["prim"].astype(np.int64)
    else:                               # unpaired pair leaves: prim[0] is the instance
        leaf = (child != NO_CHILD) & (NodeRef.type(child) == PAIR_TYPE)
        which = read_nodes(tlas.image, child[leaf], PAIR_NODE)["prim"][:, 0].astype(np.int64)
    if leaf.sum() != k or not np.array_equal(np.sort(which), np.arange(k)):
        raise AssertionError("TLAS: every instance must be exactly one leaf")
    return leaf, which


def _phase_totals(bvhs) -> tuple[dict, dict]:
    """The build phases' wall and CPU seconds summed over the images ``bvhs``."""
    phase_s: dict[str, float] = {}
    phase_cpu_s: dict[str, float] = {}
    for b in bvhs:
        for total, key in ((phase_s, "phase_s"), (phase_cpu_s, "phase_cpu_s")):
            for name, seconds in b.stats[key].items():
                total[name] = total.get(name, 0.0) + seconds
    return phase_s, phase_cpu_s
