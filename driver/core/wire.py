"""The wire words of a request and a response, defined once
(docs/datapath.md#requests-and-responses).

The single source of truth on the host side for the opcodes, the request flags and the packed
``req_t``/``rsp_t`` structs of ``rtl/rf_pkg.sv`` as little-endian uint32 words, word 0 holding
bits [31:0] (``REQUEST``, ``RESPONSE``); the numpy dtypes ``REQUEST_DTYPE``/``RESPONSE_DTYPE`` and
the pack and unpack functions are derived from it. The node image's layouts and the harness's C
header are ``driver.core.layout``.

**Overlays.** A field may share the wires of another field (``Field.overlays``), the wire's
rule for it (``overlay_rows[name]``) saying which requests carry it: the request field ``qnode``
(the 16 words of a q8 box node, ``Q8_NODE``, as stored in the image) travels on the first 16 of
the 24 ``box`` words of a QUADBOX with ``FLAG_DECODE_Q8`` (``carries_qnode``), which a
``COMPRESSED`` build decodes (docs/q8_datapath.md); the request field ``matrix`` (a TRANSFORM's
3x4 matrix) travels on the first 12 ``box`` words of a TRANSFORM (``carries_matrix``,
docs/transform.md); every other request carries ``box`` there. In the numpy dtype they are
separate fields (their own bytes, so arrays concatenate and copy like any other); ``pack`` writes
an overlay over the box words of the requests its rule selects, ``unpack`` fills every view from
the words, and in the RTL the node is an ``rf_pkg::q8_node_t`` cast of those box words (the
matrix an ``rf_pkg::matrix_t`` cast, ``req_matrix``).

The SystemVerilog structs remain the hardware's definition; ``tests/test_layout.py`` elaborates
``rtl/rf_pkg.sv`` with Verilator and checks every field's bit position and width, and the two
structs' ``$bits``, against this table. Adding a request field is one row here plus the RTL struct
and the logic that uses it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# ----------------------------------------------------------------------------------------------
# Opcodes (docs/datapath.md#requests-and-responses; rf_pkg::opcode_e)

OPCODES = {"TRIANGLE": 0, "QUADBOX": 1, "EUCLIDEAN": 2, "ANGULAR": 3, "TRANSFORM": 4}
TRIANGLE, QUADBOX, EUCLIDEAN, ANGULAR, TRANSFORM = (
    OPCODES[k] for k in ("TRIANGLE", "QUADBOX", "EUCLIDEAN", "ANGULAR", "TRANSFORM"))
OPCODE_BITS = 3     # rf_pkg::opcode_e: TRANSFORM, the fifth opcode, needs a third bit
assert max(OPCODES.values()) < 1 << OPCODE_BITS <= 2 * max(OPCODES.values())
EUC_LANES = 16      # rf_pkg::EUC_LANES: lanes of one EUCLIDEAN beat
ANG_LANES = 8       # rf_pkg::ANG_LANES: lanes of one ANGULAR beat
QNODE_WORDS = 16    # rf_pkg::QNODE_WORDS: a q8 box node (Q8_NODE) in words, request field qnode
MATRIX_SHAPE = (3, 4)   # a TRANSFORM's 3x4 float32 matrix (request field matrix), row-major

# Request flags (docs/datapath.md#requests-and-responses): bit masks of the ``flags`` field
# (rf_pkg::FLAG_*_BIT are their bit indices). The other bits are reserved and must be 0.
FLAG_NO_CULL = 1    # TRIANGLE accepts both faces (docs/datapath.md#triangle)
FLAG_DECODE_Q8 = 2  # QUADBOX: the boxes are the q8 node in ``qnode``, decoded by the datapath
FLAGS_DEFINED = FLAG_NO_CULL | FLAG_DECODE_Q8
RAY_FLAGS = FLAG_NO_CULL      # the flags of a ray (prepare_rays); FLAG_DECODE_Q8 is a request's
FLAG_NAMES = {FLAG_NO_CULL: "FLAG_NO_CULL", FLAG_DECODE_Q8: "FLAG_DECODE_Q8"}


@dataclass(frozen=True)
class Field:
    """One field of a wire struct.

    name : numpy field name (docs/datapath.md#requests-and-responses); sv : the SystemVerilog member
        name when it differs
    word, lsb : position of element 0 (word index, bit within the word)
    bits : width of one element; shape : numpy element shape (elements are consecutive, each
        ``bits`` wide: 32-bit elements take one word each, narrower ones share a word)
    kind : "f32" (IEEE binary32 bits) or a numpy unsigned integer type name
    overlays : the name of the field whose wires this one shares (an alternative view of the
        same bits, lying inside that field), or None; the wire's ``overlay_rows[name]`` says
        which requests carry it
    """

    name: str
    word: int
    lsb: int = 0
    bits: int = 32
    shape: tuple = ()
    kind: str = "f32"
    sv: str | None = None
    overlays: str | None = None

    @property
    def count(self) -> int:
        return math.prod(self.shape)          # 1 for a scalar (shape ())

    @property
    def first_bit(self) -> int:
        return 32 * self.word + self.lsb

    @property
    def total_bits(self) -> int:
        return self.bits * self.count

    @property
    def words(self) -> int:
        """Words spanned (for 32-bit fields: one per element)."""
        return (self.lsb + self.total_bits + 31) // 32

    @property
    def dtype(self):
        return np.float32 if self.kind == "f32" else np.dtype(self.kind)


def _f32(name, word, shape=(), sv=None):
    return Field(name, word, 0, 32, tuple(shape), "f32", sv)


def _uint(name, word, lsb, bits, shape=(), kind="u1", sv=None, overlays=None):
    return Field(name, word, lsb, bits, tuple(shape), kind, sv, overlays)


class Wire:
    """A wire struct: its fields (in numpy dtype order), its width in words, its dtype, and
    vectorised pack/unpack between the dtype and (n, words) uint32 arrays."""

    def __init__(self, name: str, sv_type: str, fields: list[Field], words: int,
                 overlay_rows=None):
        self.name, self.sv_type, self.fields, self.words = name, sv_type, fields, words
        self.field = {f.name: f for f in fields}
        self.dtype = np.dtype([(f.name, f.dtype, f.shape) if f.shape else (f.name, f.dtype)
                               for f in fields])
        # overlays: {overlay field name: rule}, the rule saying which rows put it on the wire
        # instead of the field it overlays
        self.overlay_rows = dict(overlay_rows or {})
        used = np.zeros(32 * words, bool)
        for f in fields:
            span = slice(f.first_bit, f.first_bit + f.total_bits)
            if f.overlays is not None:
                base = self.field[f.overlays]
                if not (base.first_bit <= f.first_bit and f.first_bit + f.total_bits <=
                        base.first_bit + base.total_bits and f.name in self.overlay_rows
                        and f.bits == 32 and f.lsb == 0):
                    raise AssertionError(f"{name}.{f.name} must be whole words inside "
                                         f"{base.name}, with a rule for its rows")
                continue
            if f.first_bit + f.total_bits > 32 * words or used[span].any():
                raise AssertionError(f"{name}.{f.name} overlaps another field or the end")
            used[span] = True

    def pack(self, rows: np.ndarray, words: int | None = None) -> np.ndarray:
        """(n,) rows of ``dtype`` -> (n, words) uint32, C-contiguous; ``words`` packs only the
        fields that lie entirely in the first ``words`` words (default: all)."""
        if rows.dtype != self.dtype:
            raise TypeError(f"{self.name}s must be a {self.name.upper()}_DTYPE array")
        nw = self.words if words is None else int(words)
        n = len(rows)
        out = np.zeros((n, nw), np.uint32)
        for f in sorted(self.fields, key=lambda f: f.overlays is not None):   # overlays last
            if f.word + f.words > nw:
                continue
            v = np.ascontiguousarray(rows[f.name]).reshape(n, f.count)
            sel = slice(None)
            if f.overlays is not None:
                sel = np.flatnonzero(self.overlay_rows[f.name](rows))
                v = v[sel]
            if f.kind == "f32":
                out[sel, f.word:f.word + f.count] = v.view(np.uint32)
                continue
            mask = np.uint32((1 << f.bits) - 1)
            for j in range(f.count):
                bit = f.lsb + j * f.bits
                if f.overlays is not None:      # whole words: replace the overlaid field's bits
                    out[sel, f.word + bit // 32] = v[:, j].astype(np.uint32)
                    continue
                out[:, f.word + bit // 32] |= (v[:, j].astype(np.uint32) & mask) << np.uint32(
                    bit % 32)
        return out

    def unpack(self, words: np.ndarray) -> np.ndarray:
        """(n, words) uint32 -> (n,) rows of ``dtype`` (inverse of ``pack``; an overlay field is
        read on every row, as the other view of its words)."""
        w = np.ascontiguousarray(words, np.uint32)
        if w.ndim != 2 or w.shape[1] != self.words:
            raise ValueError(f"{self.name} words must be (n, {self.words}) uint32")
        n = len(w)
        rows = np.zeros(n, self.dtype)
        for f in self.fields:
            if f.kind == "f32":
                rows[f.name] = (np.ascontiguousarray(w[:, f.word:f.word + f.count])
                                .view(np.float32).reshape(rows[f.name].shape))
                continue
            mask = np.uint32((1 << f.bits) - 1)
            bits = f.lsb + f.bits * np.arange(f.count)
            vals = (w[:, f.word + bits // 32] >> (bits % 32).astype(np.uint32)) & mask
            rows[f.name] = vals.reshape(rows[f.name].shape)
        return rows


# ----------------------------------------------------------------------------------------------
# Wire words (rf_pkg::req_t, rf_pkg::rsp_t)


def carries_qnode(rows: np.ndarray) -> np.ndarray:
    """(n,) bool: the requests whose box words carry the q8 node ``qnode`` instead of ``box``
    (QUADBOX with ``FLAG_DECODE_Q8``)."""
    return (rows["opcode"] == QUADBOX) & ((rows["flags"] & FLAG_DECODE_Q8) != 0)


def carries_matrix(rows: np.ndarray) -> np.ndarray:
    """(n,) bool: the requests whose box words carry a 3x4 ``matrix`` instead of ``box``
    (TRANSFORM)."""
    return rows["opcode"] == TRANSFORM


REQUEST = Wire("request", "req_t", [
    _uint("opcode", 1, 0, OPCODE_BITS),
    _f32("origin", 2, (3,)),
    _f32("dir", 5, (3,)),
    _f32("inv", 8, (3,)),
    _f32("extent", 11),
    _uint("kx", 1, 3, 2),
    _uint("ky", 1, 5, 2),
    _uint("kz", 1, 7, 2),
    # FLAG_* bits of the ray (docs/datapath.md#requests-and-responses); the others must be 0
    _uint("flags", 1, 9, 8),
    _f32("shear", 12, (3,)),
    _f32("box", 15, (4, 6)),            # per box: xmin, ymin, zmin, xmax, ymax, zmax
    # the q8 box node as stored (Q8_NODE, 16 words), on the first 16 words of ``box`` in the
    # requests ``carries_qnode`` selects
    _uint("qnode", 15, 0, 32, (QNODE_WORDS,), kind="u4", overlays="box"),
    # a TRANSFORM's matrix (docs/transform.md; word 15 + 4r + c is m[r][c]), on the first 12
    # words of ``box`` in the requests ``carries_matrix`` selects
    Field("matrix", 15, 0, 32, MATRIX_SHAPE, "f32", None, "box"),
    _f32("tri", 39, (3, 3), sv="triangle"),   # A, B, C
    _f32("vec_a", 48, (EUC_LANES,)),
    _f32("vec_b", 64, (EUC_LANES,)),
    _uint("vec_mask", 80, 16, 16, kind="u2"),   # extended-op fields, not part of a ray
    _uint("reset_accumulator", 80, 0, 1),
    _uint("tag", 0, 0, 32, kind="u4"),  # opaque, carried through unchanged
], words=81, overlay_rows={"qnode": carries_qnode, "matrix": carries_matrix})

RESPONSE = Wire("response", "rsp_t", [
    _uint("opcode", 1, 0, OPCODE_BITS),
    _uint("box_index", 1, 3, 2, (4,)),
    _uint("box_hit", 1, 11, 1, (4,)),
    _f32("box_tmin", 2, (4,)),
    _uint("tri_hit", 1, 15, 1),
    _f32("t_num", 6),
    _f32("t_den", 7),
    _f32("euclid_acc", 8),
    _uint("euclid_last", 1, 16, 1),
    _f32("angular_dot", 9),
    _f32("angular_norm", 10),
    _uint("angular_last", 1, 17, 1),
    _f32("xf_origin", 11, (3,)),        # TRANSFORM: o' = M o (docs/transform.md)
    _f32("xf_dir", 14, (3,)),           # TRANSFORM: d' = M d
    _uint("tag", 0, 0, 32, kind="u4"),
], words=17)

REQUEST_DTYPE = REQUEST.dtype
RESPONSE_DTYPE = RESPONSE.dtype
REQ_WORDS = REQUEST.words
RSP_WORDS = RESPONSE.words

# A traversal request is a ray (the first RAY_WORDS words: the ray fields and whatever shares
# their words) plus one node's box or triangle: the harness keeps a table of packed rays and fills
# the rest.
RAY_FIELDS = ("tag", "opcode", "kx", "ky", "kz", "flags", "origin", "dir", "inv", "extent",
              "shear")
RAY_WORDS = max(REQUEST.field[f].word + REQUEST.field[f].words for f in RAY_FIELDS)
CONTROL_WORD = REQUEST.field["opcode"].word          # the word of opcode, kx/ky/kz and flags


def pack_requests(req: np.ndarray) -> np.ndarray:
    """REQUEST_DTYPE (n,) -> (n, REQ_WORDS) uint32, C-contiguous."""
    return REQUEST.pack(req)


def unpack_requests(words: np.ndarray) -> np.ndarray:
    """(n, REQ_WORDS) uint32 -> REQUEST_DTYPE (n,)."""
    return REQUEST.unpack(words)


def pack_responses(rsp: np.ndarray) -> np.ndarray:
    """RESPONSE_DTYPE (n,) -> (n, RSP_WORDS) uint32."""
    return RESPONSE.pack(rsp)


def unpack_responses(words: np.ndarray) -> np.ndarray:
    """(n, RSP_WORDS) uint32 -> RESPONSE_DTYPE (n,)."""
    return RESPONSE.unpack(words)


def ray_words(rays: np.ndarray) -> np.ndarray:
    """(n, RAY_WORDS) uint32: the ray part of prepared rays (``prepare_rays``), the ray table of
    the harness's traversal requests (the opcode, box and triangle are filled per request)."""
    return REQUEST.pack(rays, RAY_WORDS)
