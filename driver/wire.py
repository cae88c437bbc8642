"""The datapath's wire format: requests/responses as little-endian uint32 words (rtl/rf_pkg.sv).

Word 0 holds bits [31:0] of the packed struct. Request (80 words): 0 tag; 1 control (opcode [1:0],
kx [3:2], ky [5:4], kz [7:6], reset_accumulator [8], vec_mask [31:16]); 2-4 origin; 5-7 dir;
8-10 inv; 11 extent; 12-14 shear; 15-38 box (4 x 6); 39-47 tri (3 x 3); 48-63 vec_a; 64-79 vec_b.
Response (11 words): 0 tag; 1 control (opcode [1:0], box_index [9:2] (2 bits each), box_hit
[13:10], tri_hit [14], euclid_last [15], angular_last [16]); 2-5 box_tmin; 6 t_num; 7 t_den;
8 euclid_acc; 9 angular_dot; 10 angular_norm.
"""

from __future__ import annotations

import numpy as np

from .datapath import REQUEST_DTYPE, RESPONSE_DTYPE

REQ_WORDS = 80
RSP_WORDS = 11

# (field, first word, number of words) for the float fields
_REQ_FLOATS = [("origin", 2, 3), ("dir", 5, 3), ("inv", 8, 3), ("extent", 11, 1),
               ("shear", 12, 3), ("box", 15, 24), ("tri", 39, 9), ("vec_a", 48, 16),
               ("vec_b", 64, 16)]
_RSP_FLOATS = [("box_tmin", 2, 4), ("t_num", 6, 1), ("t_den", 7, 1), ("euclid_acc", 8, 1),
               ("angular_dot", 9, 1), ("angular_norm", 10, 1)]


def pack_requests(req: np.ndarray) -> np.ndarray:
    """REQUEST_DTYPE (n,) -> (n, REQ_WORDS) uint32, C-contiguous."""
    if req.dtype != REQUEST_DTYPE:
        raise TypeError("requests must be a REQUEST_DTYPE array")
    n = len(req)
    w = np.zeros((n, REQ_WORDS), np.uint32)
    w[:, 0] = req["tag"]
    u = lambda f: req[f].astype(np.uint32)  # noqa: E731
    w[:, 1] = ((u("opcode") & 3) | (u("kx") & 3) << 2 | (u("ky") & 3) << 4 | (u("kz") & 3) << 6
               | (u("reset_accumulator") & 1) << 8 | u("vec_mask") << 16)
    for name, first, count in _REQ_FLOATS:
        w[:, first:first + count] = np.ascontiguousarray(req[name]).view(np.uint32).reshape(n, count)
    return w


def unpack_responses(words: np.ndarray) -> np.ndarray:
    """(n, RSP_WORDS) uint32 -> RESPONSE_DTYPE (n,)."""
    n = len(words)
    rsp = np.zeros(n, RESPONSE_DTYPE)
    rsp["tag"] = words[:, 0]
    c = words[:, 1]
    rsp["opcode"] = c & 3
    rsp["box_index"] = (c[:, None] >> (2 + 2 * np.arange(4, dtype=np.uint32))) & 3
    rsp["box_hit"] = (c[:, None] >> (10 + np.arange(4, dtype=np.uint32))) & 1
    rsp["tri_hit"] = (c >> 14) & 1
    rsp["euclid_last"] = (c >> 15) & 1
    rsp["angular_last"] = (c >> 16) & 1
    for name, first, count in _RSP_FLOATS:
        rsp[name] = words[:, first:first + count].copy().view(np.float32).reshape(rsp[name].shape)
    return rsp
