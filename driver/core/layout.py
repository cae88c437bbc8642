"""The node image's layouts the driver shares with the RTL and the C++ harness, defined once
(docs/datapath.md#bvh4-image, docs/compressed.md, docs/instances.md).

This table is the single source of truth on the host side for

- the **BVH4 node image** (docs/datapath.md#bvh4-image): node pointers (``NodeRef``), the box and
  triangle node structs as numpy dtypes (``BOX_NODE``, ``TRI_NODE``), and those of the compressed
  images (``Q8_NODE``, ``PAIR_NODE``, ``GROUP_NODE``, the type codes and ``NODE_BYTES``:
  docs/compressed.md) and of the two-level image (``INSTANCE_NODE``);
- the **C header** of the harness (``c_header()``), generated from these tables and the wire
  words of ``driver.core.wire`` at build time into the build cache (never committed), so
  ``sim/rayflex_harness.cpp`` names no word index itself.

The request and response words are ``driver.core.wire``; the names a node needs from it (the
opcodes a node becomes, ``QNODE_WORDS``) are imported here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .wire import (FLAG_NAMES, MATRIX_SHAPE, OPCODES, QNODE_WORDS, QUADBOX, RAY_WORDS, REQ_WORDS,
                   REQUEST, RESPONSE, RSP_WORDS, TRANSFORM, TRIANGLE)

# ----------------------------------------------------------------------------------------------
# BVH4 node image (docs/datapath.md#bvh4-image)

BOX_TYPE = 5
TRI_TYPE = 0
NO_CHILD = 0xFFFFFFFF
NODE_ALIGN = 64                 # every node starts at a multiple of 64 bytes
_TYPE_MASK = 7
_PTR_SHIFT = 3                  # pointer = (byte offset >> 3) | type

BOX_NODE = np.dtype([
    ("child", "<u4", (4,)),     # node pointers; unused slots NO_CHILD
    ("box", "<f4", (4, 6)),     # child boxes: xmin ymin zmin xmax ymax zmax
    ("parent", "<u4"),          # the parent's pointer (root: NO_CHILD)
    ("count", "<u4"),           # used child slots (1..4)
    ("rsvd", "<u4", (2,)),
])
TRI_NODE = np.dtype([
    ("tri", "<f4", (3, 3)),     # A, B, C
    ("prim", "<u4"),            # primitive id (index into the input triangles)
    ("rsvd", "<u4", (6,)),
])
BOX_BYTES = BOX_NODE.itemsize
TRI_BYTES = TRI_NODE.itemsize
assert BOX_BYTES == 128 and TRI_BYTES == 64 and BOX_BYTES % NODE_ALIGN == TRI_BYTES % NODE_ALIGN == 0
NODE_BYTES = {BOX_TYPE: BOX_BYTES, TRI_TYPE: TRI_BYTES}
NODE_OPCODE = {BOX_TYPE: QUADBOX, TRI_TYPE: TRIANGLE}   # the request a node becomes


class NodeRef:
    """Encode/decode node pointers (uint32): ``(byte_offset >> 3) | type``; ``NO_CHILD`` is no
    node (its type bits, 7, are neither type). The one place that knows the bit layout."""

    @staticmethod
    def encode(byte_offset, node_type) -> np.ndarray:
        off = np.asarray(byte_offset, np.int64)
        if (off % NODE_ALIGN).any() or (off < 0).any() or (off >> (32 + _PTR_SHIFT)).any():
            raise ValueError("node offsets must be non-negative multiples of 64 below 32 GiB")
        return ((off >> _PTR_SHIFT) | np.asarray(node_type, np.int64)).astype(np.uint32)

    @staticmethod
    def type(ptrs) -> np.ndarray:
        """Type bits: BOX_TYPE, TRI_TYPE (7 for NO_CHILD)."""
        return np.asarray(ptrs, np.uint32) & np.uint32(_TYPE_MASK)

    @staticmethod
    def offset(ptrs) -> np.ndarray:
        """Byte offsets (int64) in the image."""
        p = np.asarray(ptrs, np.uint32) & np.uint32(~_TYPE_MASK & 0xFFFFFFFF)
        return p.astype(np.int64) << _PTR_SHIFT

    @staticmethod
    def retype(ptrs, node_type) -> np.ndarray:
        """The same offsets with another type code (e.g. ``LEAF_NEXT_TYPE``)."""
        keep = np.uint32(~_TYPE_MASK & 0xFFFFFFFF)
        return (np.asarray(ptrs, np.uint32) & keep) | np.uint32(node_type)

    @staticmethod
    def word(ptrs) -> np.ndarray:
        """Offsets in uint32 words (int64)."""
        return NodeRef.offset(ptrs) >> 2

    @staticmethod
    def is_box(ptrs) -> np.ndarray:
        """Box nodes of either image format (box32 ``BOX_TYPE``, q8 ``Q8_TYPE``)."""
        t = NodeRef.type(ptrs)
        return (t == BOX_TYPE) | (t == Q8_TYPE)


# ----------------------------------------------------------------------------------------------
# The compressed image ("q8", docs/compressed.md): 64-byte quantized box nodes and triangle-pair leaves

Q8_TYPE = 4                     # q8 box node (64 B)
PAIR_TYPE = 1                   # triangle pair leaf (64 B)
Q8_EXP_MIN, Q8_EXP_MAX = -126, 119   # per-axis exponents: 2**exp and 255 * 2**exp are float32
Q8_COUNT_LSB = 24               # bits 26:24 of the exponent word: used children (1..4)

Q8_NODE = np.dtype([
    ("origin", "<f4", (3,)),    # float32 x, y, z the child planes are relative to
    ("exp", "u1", (4,)),        # int8 exp_x, exp_y, exp_z (two's complement); byte 3 = count
    ("child", "<u4", (4,)),     # node pointers; unused slots NO_CHILD (used slots first)
    ("q", "u1", (4, 6)),        # child i: qlo_x, qlo_y, qlo_z, qhi_x, qhi_y, qhi_z (uint8)
    ("parent", "<u4"),
    ("rsvd", "<u4"),
])
PAIR_NODE = np.dtype([
    ("v", "<f4", (4, 3)),       # four vertices; triangle 0 = (v0, v1, v2)
    ("prim", "<u4", (2,)),      # primitive ids; prim[1] = NO_CHILD when the leaf holds one
    ("idx", "<u4"),             # bits 1:0, 3:2, 5:4: triangle 1 = (v[i0], v[i1], v[i2])
    ("rsvd", "<u4"),
])
Q8_BYTES = Q8_NODE.itemsize
PAIR_BYTES = PAIR_NODE.itemsize
assert Q8_BYTES == 64 == 4 * QNODE_WORDS and PAIR_BYTES == 64

# The group leaf (type 2, the "q8g" image), 128 bytes: 3 to 6 triangles sharing up to 8 vertices,
# one child slot of its parent. Its first 64 bytes are a complete pair leaf (PAIR_NODE: vertices
# v0..v3, prim[0..1], triangle 1's 2-bit selectors in idx bits 5:0); the second 64 bytes hold
# vertices v4..v7 and prim[2..5]. Triangle k >= 2 is (v[a], v[b], v[c]) with 3-bit selectors at
# bits 6 + 9 (k - 2) + 3 j of the 64-bit ``idx`` (j = 0, 1, 2: each triangle in its input vertex
# order), and bits 50:48 of ``idx`` hold the triangle count (a pair leaf's are 0: its word 15 is
# 0). Unused prims are NO_CHILD.
GROUP_TYPE = 2
GROUP_NODE = np.dtype([
    ("v", "<f4", (4, 3)),       # v0..v3; triangle 0 = (v0, v1, v2)
    ("prim", "<u4", (2,)),      # primitive ids of triangles 0 and 1
    ("idx", "<u8"),             # selectors (above) and, bits 50:48, the triangle count (3..6)
    ("v2", "<f4", (4, 3)),      # v4..v7
    ("prim2", "<u4", (4,)),     # primitive ids of triangles 2..5 (NO_CHILD unused)
])
GROUP_BYTES = GROUP_NODE.itemsize
GROUP_MAX_TRIS, GROUP_MAX_VERTS = 6, 8
GROUP_SEL_LSB, GROUP_SEL_BITS = 6, 9        # triangle k >= 2: bits 6 + 9 (k - 2) .. + 8
GROUP_COUNT_LSB = 48                       # bits 50:48 of idx: the triangle count
assert GROUP_BYTES == 128 and GROUP_NODE.fields["idx"][1] == PAIR_NODE.fields["idx"][1] == 56
assert GROUP_SEL_LSB + GROUP_SEL_BITS * (GROUP_MAX_TRIS - 2) <= GROUP_COUNT_LSB

# A request pointer, never stored in an image: a later triangle of the leaf the ray already
# holds (the pair or group leaf at this pointer's offset). A leaf is one TRIANGLE request per
# triangle of the same ray, in order: the traversal issues triangle 0 with the leaf's own
# pointer and pushes this one for the next, so every request names its operand by one pointer
# (the harness, the replay and the Python issuer read the triangle from the leaf).
# Bits 31:29 hold the triangle's index - 1 (0 for a pair's second triangle), bits 28:3 the
# leaf's byte offset >> 6 << 3 as in any pointer: so a q8 or q8g image's leaves lie in its first
# 4 GiB (LEAF_OFFSET_LIMIT, checked by the build).
LEAF_NEXT_TYPE = 3
LEAF_INDEX_LSB = 29
LEAF_OFFSET_LIMIT = 1 << (LEAF_INDEX_LSB + 3)
NODE_BYTES.update({Q8_TYPE: Q8_BYTES, PAIR_TYPE: PAIR_BYTES, LEAF_NEXT_TYPE: 0,
                   GROUP_TYPE: GROUP_BYTES})
#   node bytes an RT unit fetches for a request of each pointer type: a leaf's later triangles
#   are in the node the ray fetched for its first (0 more bytes); a group leaf is fetched whole
#   (two 64-byte lines)
NODE_OPCODE.update({Q8_TYPE: QUADBOX, PAIR_TYPE: TRIANGLE, LEAF_NEXT_TYPE: TRIANGLE,
                    GROUP_TYPE: TRIANGLE})


@dataclass(frozen=True)
class ImageFormat:
    """A node image ``driver.bvh4.build`` writes (docs/compressed.md), with its properties:
    ``compressed`` (quantized q8 box nodes, which a datapath built with the q8 decode reads
    itself; triangle-pair leaves), ``groups`` (group leaves of 3 to 6 triangles sharing
    vertices), its box nodes (struct, pointer type) and the format of a two-level image's TLAS
    over BLASes in it (a TLAS has no groups: its instance leaves are single nodes)."""

    name: str
    compressed: bool
    groups: bool
    box_node: np.dtype
    box_type: int
    tlas: str

    @property
    def box_bytes(self) -> int:
        return self.box_node.itemsize


# the one table of the image formats; the first is the default (and the studies' reference)
FORMATS = {f.name: f for f in (
    ImageFormat("box32", False, False, BOX_NODE, BOX_TYPE, "box32"),
    ImageFormat("q8", True, False, Q8_NODE, Q8_TYPE, "q8"),
    ImageFormat("q8g", True, True, Q8_NODE, Q8_TYPE, "q8"),
)}
IMAGE_FORMATS = tuple(FORMATS)
DEFAULT_FORMAT = IMAGE_FORMATS[0]


def image_format(name: str) -> ImageFormat:
    """The ``FORMATS`` entry of ``name``; ValueError (one line) for an unknown one."""
    if name not in FORMATS:
        raise ValueError(f"BVH image format must be one of {IMAGE_FORMATS}, got {name!r}")
    return FORMATS[name]
assert Q8_NODE.fields["q"][1] == 32 and Q8_NODE.fields["exp"][1] == 12


# The two-level image (docs/instances.md): a top-level BVH (TLAS) whose leaves are instance nodes,
# each pointing at the bottom-level BVH (BLAS) of a mesh in the same image.
INSTANCE_TYPE = 6               # instance node (128 B)
INSTANCE_NODE = np.dtype([
    ("world_to_object", "<f4", (3, 4)),     # 3x4 row-major: word 4r + c is m[r][c]
    ("object_to_world", "<f4", (3, 4)),
    ("blas", "<u4"),            # pointer to the BLAS root box node
    ("instance", "<u4"),        # instance index (the scene's instance order)
    ("rsvd", "<u4", (6,)),
])
INSTANCE_BYTES = INSTANCE_NODE.itemsize
assert INSTANCE_BYTES == 128 and INSTANCE_NODE.fields["blas"][1] == 96
NODE_BYTES[INSTANCE_TYPE] = INSTANCE_BYTES
#   an instance node is fetched by the traversal when a ray enters the instance; with the
#   transform on the datapath (``--transform datapath``) it becomes a TRANSFORM request of the
#   world ray by the node's ``world_to_object`` (on the request's ``matrix``); with the transform
#   in the driver it becomes no datapath request
NODE_OPCODE[INSTANCE_TYPE] = TRANSFORM
assert INSTANCE_NODE["world_to_object"].shape == MATRIX_SHAPE


def q8_count(nodes: np.ndarray) -> np.ndarray:
    """Used child slots (1..4) of ``Q8_NODE`` rows (byte 3 of the exponent word, bits 2:0)."""
    return (nodes["exp"][..., 3] & 7).astype(np.int64)


def q8_scales(nodes: np.ndarray) -> np.ndarray:
    """(n, 3) float32 ``2**exp`` per axis of ``Q8_NODE`` rows (exact: exp in [-126, 119])."""
    e = nodes["exp"][..., :3].view(np.int8).astype(np.int32)
    return np.ldexp(np.float32(1.0), e).astype(np.float32)


def decode_q8(nodes: np.ndarray) -> np.ndarray:
    """(n, 4, 6) float32 child boxes (xmin ymin zmin xmax ymax zmax) of ``Q8_NODE`` rows: per
    axis ``origin + float32(q) * 2**exp``; the product is exact (8-bit integer times a power of
    two) and the add is one float32 round-to-nearest-even add, as the datapath's decode does.
    Unused slots (index >= count) decode to the unused box: six +inf."""
    nodes = np.asarray(nodes).reshape(-1)
    q = nodes["q"].astype(np.float32)                              # (n, 4, 6), exact
    scale = np.tile(q8_scales(nodes), 2)[:, None, :]               # (n, 1, 6)
    origin = np.tile(nodes["origin"].astype(np.float32), 2)[:, None, :]
    boxes = (origin + (q * scale).astype(np.float32)).astype(np.float32)
    unused = np.arange(4)[None, :] >= q8_count(nodes)[:, None]
    boxes[unused] = np.float32(np.inf)
    return boxes


def leaf_request(ptrs):
    """(word offset (m,) int64 of the leaf, triangle index k (m,) int64) of triangle request
    pointers: a triangle node, pair or group leaf (k = 0) or ``LEAF_NEXT_TYPE`` (k = bits
    31:29 + 1)."""
    ptrs = np.asarray(ptrs, np.uint32)
    nxt = NodeRef.type(ptrs) == LEAF_NEXT_TYPE
    k = np.where(nxt, (ptrs >> np.uint32(LEAF_INDEX_LSB)).astype(np.int64) + 1, 0)
    p = np.where(nxt, ptrs & np.uint32((1 << LEAF_INDEX_LSB) - 1), ptrs)
    return NodeRef.word(p), k


def leaf_next(ptrs, k) -> np.ndarray:
    """``LEAF_NEXT_TYPE`` pointers naming triangle k (>= 1) of the leaves at ``ptrs``."""
    k = np.asarray(k, np.int64)
    word = leaf_request(ptrs)[0]
    if (word >= LEAF_OFFSET_LIMIT >> 2).any():
        raise ValueError("a leaf's later triangles are addressable in the first 4 GiB only")
    return (NodeRef.encode(word << 2, LEAF_NEXT_TYPE)
            | ((k - 1).astype(np.uint32) << np.uint32(LEAF_INDEX_LSB))).astype(np.uint32)


def leaf_prim_word(ptrs) -> np.ndarray:
    """(m,) int64 image word of the primitive id of each triangle request (``leaf_request``):
    a triangle node's, or prim[k] of a pair or group leaf."""
    ptrs = np.asarray(ptrs, np.uint32)
    word, k = leaf_request(ptrs)
    tri = NodeRef.type(ptrs) == TRI_TYPE
    return word + np.where(tri, node_word(TRI_NODE, "prim"),
                           np.where(k < 2, node_word(GROUP_NODE, "prim") + k,
                                    node_word(GROUP_NODE, "prim2") + k - 2))


def leaf_count(image, ptrs) -> np.ndarray:
    """(m,) int64 triangles in the pair or group leaves that ``ptrs`` (leaf or
    ``LEAF_NEXT_TYPE`` pointers) name: 1 or 2 for a pair, 3..6 for a group."""
    words = np.asarray(image).reshape(-1).view("<u4")
    ptrs = np.asarray(ptrs, np.uint32)
    word = leaf_request(ptrs)[0]
    hi = words[word + node_word(GROUP_NODE, "idx") + 1].astype(np.int64)
    count = (hi >> (GROUP_COUNT_LSB - 32)) & 7
    pair = 1 + (words[word + node_word(PAIR_NODE, "prim") + 1] != NO_CHILD)
    return np.where(count > 0, count, pair)


def leaf_triangles(image, ptrs):
    """(tris (m, 3, 3) float32, prim (m,) int64) of pair, group and ``LEAF_NEXT_TYPE`` request
    pointers: triangle k of the leaf (``leaf_request``), its vertices in their stored order."""
    words = np.asarray(image).reshape(-1).view("<u4")
    word, k = leaf_request(ptrs)
    base = word[:, None]
    sel_word = node_word(GROUP_NODE, "idx")
    sel = (words[base[:, 0] + sel_word].astype(np.uint64)
           | (words[base[:, 0] + sel_word + 1].astype(np.uint64) << np.uint64(32)))
    j = np.arange(3)
    k2 = np.maximum(k - 2, 0)[:, None]
    shift = np.where(k[:, None] >= 2, GROUP_SEL_LSB + GROUP_SEL_BITS * k2 + 3 * j, 2 * j)
    mask = np.where(k[:, None] >= 2, 7, 3)
    v = (sel[:, None] >> shift.astype(np.uint64)).astype(np.int64) & mask
    v = np.where(k[:, None] == 0, j, v)                                  # (m, 3) vertex slots
    vw = np.where(v < 4, node_word(GROUP_NODE, "v") + 3 * v,
                  node_word(GROUP_NODE, "v2") + 3 * (v - 4))
    tris = words[base[:, :, None] + vw[:, :, None] + j].view(np.float32)
    prim = words[leaf_prim_word(ptrs)].astype(np.int64)
    return tris.reshape(-1, 3, 3), prim


def node_word(node: np.dtype, field: str) -> int:
    """Word offset of ``field`` inside a node struct."""
    return node.fields[field][1] // 4


# ----------------------------------------------------------------------------------------------
# The harness's C header


def c_header() -> str:
    """``rf_layout.h`` for sim/rayflex_harness.cpp: every word index, bit position, opcode and
    node layout constant the harness uses, from the tables above."""
    lines = ["// Generated by driver/core/layout.py at build time. Do not edit.", "#pragma once",
             "#include <cstdint>", "namespace rf_layout {"]

    def const(name, value, ctype="int"):
        lines.append(f"constexpr {ctype} {name} = {value};")

    const("kReqWords", REQ_WORDS)
    const("kRspWords", RSP_WORDS)
    const("kRayWords", RAY_WORDS)
    for prefix, wire in (("kReq", REQUEST), ("kRsp", RESPONSE)):
        for f in wire.fields:
            cname = "".join(p.capitalize() for p in f.name.split("_"))
            const(f"{prefix}{cname}Word", f.word)
            const(f"{prefix}{cname}Lsb", f.lsb)
            const(f"{prefix}{cname}Bits", f.bits)
            const(f"{prefix}{cname}Count", f.count)
    for name, code in OPCODES.items():
        const(f"kOp{name.capitalize()}", code, "uint32_t")
    for mask, name in FLAG_NAMES.items():        # FLAG_DECODE_Q8 -> kFlagDecodeQ8 (a bit mask)
        const("kFlag" + "".join(p.capitalize() for p in name.split("_")[1:]), mask, "uint32_t")
    const("kBoxType", BOX_TYPE, "uint32_t")
    const("kTriType", TRI_TYPE, "uint32_t")
    const("kQ8Type", Q8_TYPE, "uint32_t")
    const("kPairType", PAIR_TYPE, "uint32_t")
    const("kLeafNextType", LEAF_NEXT_TYPE, "uint32_t")
    const("kLeafIndexLsb", LEAF_INDEX_LSB)
    const("kGroupType", GROUP_TYPE, "uint32_t")
    const("kGroupSelLsb", GROUP_SEL_LSB)
    const("kGroupSelBits", GROUP_SEL_BITS)
    const("kGroupCountLsb", GROUP_COUNT_LSB)
    const("kInstanceType", INSTANCE_TYPE, "uint32_t")
    const("kInstanceNodeMatrixWord", node_word(INSTANCE_NODE, "world_to_object"))
    const("kQ8CountLsb", Q8_COUNT_LSB)
    const("kNoChild", NO_CHILD, "uint32_t")
    node_bytes = ", ".join(str(NODE_BYTES.get(t, 0)) for t in range(_TYPE_MASK + 1))
    lines.append(f"constexpr int64_t kNodeBytes[{_TYPE_MASK + 1}] = {{{node_bytes}}};"
                 "  // by pointer type (0: not a node)")
    const("kTypeMask", _TYPE_MASK, "uint32_t")
    const("kPtrShift", _PTR_SHIFT)
    for prefix, node in (("kBoxNode", BOX_NODE), ("kTriNode", TRI_NODE), ("kQ8Node", Q8_NODE),
                         ("kPairNode", PAIR_NODE), ("kGroupNode", GROUP_NODE)):
        const(f"{prefix}Words", node.itemsize // 4)
        for fname in node.names:
            sub = node.fields[fname][0]
            count = int(np.prod(sub.shape)) if sub.shape else 1
            cname = fname.capitalize()
            const(f"{prefix}{cname}Word", node_word(node, fname))
            const(f"{prefix}{cname}Count", count)
    levels = ", ".join(f"kLevel{name.capitalize()} = {i}" for i, name in enumerate(MEMORY_LEVELS))
    lines.append(f"enum Level : int {{ {levels} }};  // MEMORY_LEVELS")
    const("kMemoryLevels", len(MEMORY_LEVELS))
    lines += [replay_stats_c(), "}  // namespace rf_layout", ""]
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------
# RT-unit replay statistics (rf_replay's output struct; driver.rtunit reads it with ctypes)

REPLAY_STATS = (
    "cycles",           # first accept to last response, inclusive (summed over kernels; with
                        # the unit costs, first ray taken to last result taken)
    "model_evals",      # pipeline-cycles actually evaluated (skip_idle leaves idle ones out)
    "starved_cycles",   # unit-cycles in which a pipeline issued nothing because no ray was ready
    "full_cycles",      # unit-cycles with every pipeline of the unit issuing
    "first_accept",     # cycle of the first accepted request
    "last_response",    # cycle of the last response taken
    "bad_tags",         # responses whose tag is not their ray's index (must be 0)
    "accepts",          # requests accepted, over all pipelines
    "line_accesses",    # L1: transactions looked up (a node touches one or more)
    "line_hits",        # L1: transactions present in the node cache (or already being fetched)
    "line_misses",      # L1: transactions fetched from the next level
    "bytes_from_memory",  # bytes transferred from DRAM
    "node_wait_cycles",  # sum over requests of the cycles a ray waited for its node
    "l1_accesses", "l1_hits", "l1_merged", "l1_misses", "l1_bytes",
    "l2_accesses", "l2_hits", "l2_merged", "l2_misses", "l2_bytes",
    "dram_transfers", "dram_bytes",
    "l1_wait_cycles",   # node waits whose last transaction came from the L1 (hit latency)
    "l2_wait_cycles",   # ... from the L2
    "dram_wait_cycles",  # ... from DRAM
    "mshr_stalls",      # L1 misses that waited for a free MSHR
    "mshr_stall_cycles",  # cycles those misses waited
    "frame_cycles",     # first accept of the frame to its last response, inclusive
    "max_rays_held",    # most rays held by one unit at once
    "series_bins",      # bins of the rays-in-flight series written
    "series_bin_cycles",  # cycles per bin of that series
)

# rf_replay's configuration (all int64): driver.rtunit fills it (docs/rtunit.md)
REPLAY_CONFIG = (
    "units",            # RT units (each its own pipelines, L1, MSHRs)
    "pipelines",        # datapath pipelines per unit
    "slots",            # rays in flight per unit (issue slots; whole warps)
    "warp_size",        # threads per warp (a trace call occupies warp_size slots)
    "resident",         # warps resident per unit (0: no limit)
    "turnaround",       # cycles from a response to the ray's next request
    "shader_cycles",    # cycles from a call's last response to the warp's next call
    "skip_idle",        # do not evaluate a pipeline with nothing in it (exact)
    "max_idle",         # cycles without progress before the replay reports a deadlock
    "window",           # rays held per unit by the affinity/treelet schedulers (0: none)
    "flush",            # drop the caches at each kernel boundary
    "active_treelets", "treelet_flags",
    "series_capacity",  # bins of the rays-in-flight series the caller provides
    "timing_latency",   # > 0: pipelines as their handshake timing (this latency), not evaluated
    "fixed_latency",    # > 0 without a memory model: every node fetch takes this many cycles
    "unit_costs",       # 1: the RT unit in RTL's costs (ports, response stage, dividers)
    "dividers",         # unit costs: binary32 dividers per pipeline
    "div_cycles",       # unit costs: a division's latency (rf_fp_div_pkg::DIV_CYCLES)
    "stack_depth",      # unit costs: entries per ray's stack (0: unbounded; more spill)
    "setups",           # unit costs: ray setups (a ray entering an instance) per pipeline
)

# the memory hierarchy's configuration (rf_memory.h; l1_bytes < 0: no memory model)
MEMORY_CONFIG = (
    ("l1_bytes", "int64_t"), ("l1_ways", "int64_t"), ("line_bytes", "int64_t"),
    ("sector_bytes", "int64_t"), ("l1_latency", "int64_t"), ("mshrs", "int64_t"),
    ("l2_bytes", "int64_t"), ("l2_ways", "int64_t"), ("l2_latency", "int64_t"),
    ("mem_latency", "int64_t"), ("bytes_per_cycle", "double"),
)
# rf_replay's inputs (a frame's recorded requests, their chains and the plan of kernels, warps
# and calls: driver.backends.harness.replay_schedule) and outputs (arrays it writes), each one
# generated struct of (name, C type); a pointer is a numpy array's data
REPLAY_INPUTS = (
    ("rays", "const uint32_t*"), ("n_rays", "int64_t"),        # packed ray table
    ("image", "const uint32_t*"), ("image_words", "int64_t"),  # the BVH image
    ("ray", "const uint32_t*"), ("ptr", "const uint32_t*"), ("ext", "const uint32_t*"),
    ("m", "int64_t"),                                          # requests
    ("chain_idx", "const int64_t*"), ("chain_off", "const int64_t*"), ("n_chains", "int64_t"),
    ("chain", "const uint32_t*"), ("before", "const uint32_t*"),
    ("n_kernels", "int64_t"), ("kernel_off", "const int64_t*"), ("warp_call_off", "const int64_t*"),
    ("call_ray_off", "const int64_t*"), ("call_rays", "const int64_t*"),
    ("treelet", "const int32_t*"), ("n_treelets", "int64_t"),  # treelet schedule (or null)
    ("tl_off", "const int64_t*"), ("tl_node_off", "const int64_t*"),
    ("tl_node_bytes", "const int64_t*"),
    ("responses", "const uint32_t*"),   # unit costs: the functional run's responses (or null)
    ("any_hit", "const uint8_t*"),      # unit costs: per chain, an any-hit ray (or null)
    # unit costs: entries the distance-culled stack pops before each request of each chain and
    # after its last (chain r's request k at chain_off[r] + r + k), or null
    ("culls", "const int64_t*"),
)
REPLAY_OUTPUTS = (
    ("rsp", "uint32_t*"), ("per_pipe", "int64_t*"), ("sched", "int64_t*"),
    ("ray_times", "int64_t*"), ("ray_served", "int64_t*"), ("ray_wait", "int64_t*"),
    ("call_times", "int64_t*"), ("call_unit", "int64_t*"), ("series", "int64_t*"),
    ("kernel_times", "int64_t*"),
)

# the memory levels as the replay numbers them (the C header's enum Level and kMemoryLevels, which
# sim/rf_memory.h and sim/rtunit_scheduler.cpp use): the level a node fetch waited on or was
# served by (none: it was free); rf_replay's ray_served has one column per level
MEMORY_LEVELS = ("none", "l1", "l2", "dram")


def replay_stats_c() -> str:
    """The C declarations of ``ReplayStats``, ``ReplayConfig`` (int64 fields in
    ``REPLAY_STATS`` / ``REPLAY_CONFIG`` order), ``MemoryConfig`` (``MEMORY_CONFIG``) and
    rf_replay's ``ReplayInputs`` and ``ReplayOutputs`` (``REPLAY_INPUTS``, ``REPLAY_OUTPUTS``)."""
    out = []
    for name, fields in (("ReplayStats", [(f, "int64_t") for f in REPLAY_STATS]),
                         ("ReplayConfig", [(f, "int64_t") for f in REPLAY_CONFIG]),
                         ("MemoryConfig", list(MEMORY_CONFIG)),
                         ("ReplayInputs", list(REPLAY_INPUTS)),
                         ("ReplayOutputs", list(REPLAY_OUTPUTS))):
        body = "\n".join(f"  {ctype} {f};" for f, ctype in fields)
        out.append(f"struct {name} {{\n{body}\n}};")
    return "\n".join(out)


def read_nodes(image, ptrs, node: np.dtype) -> np.ndarray:
    """Gather the nodes at ``ptrs`` from a node image (bytes or uint32 words) as (m,) rows of
    the node dtype ``node`` (``BOX_NODE`` or ``TRI_NODE``)."""
    words = np.asarray(image).reshape(-1).view("<u4")
    idx = NodeRef.word(ptrs)[:, None] + np.arange(node.itemsize // 4)
    return np.ascontiguousarray(words[idx]).view(node).reshape(-1)
