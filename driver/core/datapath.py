"""Datapath IO: request checks and host-side ray preparation (docs/datapath.md#ray-preparation,
#requests-and-responses).

The opcodes and the request/response dtypes are derived from the wire table in
``driver.core.wire`` and re-exported here. Every tracer (golden numpy model, RTL through the fast
harness, RTL through pyverilator) consumes a ``REQUEST_DTYPE`` array and returns a
``RESPONSE_DTYPE`` array of the same length and order.

Fields a request's opcode does not use are ignored; response fields an opcode does not produce are
zero (this is what the RTL's output stage drives, and what the golden model returns).
"""

from __future__ import annotations

import numpy as np

from .wire import (ANGULAR, EUCLIDEAN, FLAG_DECODE_Q8, FLAG_NAMES, FLAG_NO_CULL,  # noqa: F401
                   FLAGS_DEFINED, MATRIX_SHAPE, OPCODES, QUADBOX, RAY_FLAGS, REQUEST_DTYPE,
                   RESPONSE_DTYPE, TRANSFORM, TRIANGLE, carries_qnode)
from .layout import Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, node_word

LATENCY = 11
LEAST_LATENCY = 10        # the balanced pipeline: S9 and the output format in one stage (no R9)
MAX_LATENCY = 64          # the longest pipeline the tools build (pass-through registers pad it)
DECODE_STAGES = 1         # pipeline stages the q8 decode adds in a COMPRESSED build
CANONICAL_NAN = np.uint32(0x7FC00000)


class DatapathError(ValueError):
    """A request stream the datapath cannot take (bad opcode, extended op on a baseline build, a
    q8 node on a build without the decode, a TRANSFORM on a build without it)."""


def default_latency(compressed: bool = False) -> int:
    """The pipeline depth of a build when none is asked for: 11 (the paper's), plus the decode
    stage in a COMPRESSED build."""
    return LATENCY + (DECODE_STAGES if compressed else 0)


def least_latency(compressed: bool = False) -> int:
    """The shortest pipeline the RTL builds: 10, S9 (the sort's last layer) sharing the output
    stage (docs/timing.md#a-balanced-pipeline), plus the decode stage in a COMPRESSED build."""
    return LEAST_LATENCY + (DECODE_STAGES if compressed else 0)


def check_requests(req: np.ndarray, extended: bool, compressed: bool = False,
                   transform: bool = False) -> None:
    """Reject what no backend simulates (the same check for every backend): an opcode that is not
    one (``driver.core.wire.OPCODES``), an extended opcode on a baseline build, a TRANSFORM on a
    build without it (``transform``), a TRIANGLE whose kx/ky/kz is not 0, 1 or 2, a reserved flag
    bit set (any opcode: the flags are part of the ray), ``FLAG_DECODE_Q8`` on a build without
    the decode (``compressed``), and a QUADBOX to decode whose node has an exponent outside
    [Q8_EXP_MIN, Q8_EXP_MAX] (not a q8 node: its decode could overflow or round). Raises
    DatapathError."""
    if not len(req):
        return
    ops = req["opcode"]
    bad = ~np.isin(ops, [TRIANGLE, QUADBOX, *((EUCLIDEAN, ANGULAR) if extended else ()),
                         *((TRANSFORM,) if transform else ())])
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        op = int(ops[i])
        what = ("extended operations need backend(..., extended=True)" if op in (EUCLIDEAN, ANGULAR)
                else "TRANSFORM needs backend(..., transform=True)" if op == TRANSFORM
                else f"not an opcode ({', '.join(f'{k} {v}' for k, v in OPCODES.items())})")
        raise DatapathError(f"request {i}: opcode {op}: {what}")
    tri = ops == TRIANGLE
    if tri.any() and ((req["kx"][tri] > 2) | (req["ky"][tri] > 2) | (req["kz"][tri] > 2)).any():
        raise DatapathError("kx/ky/kz must be 0, 1 or 2")
    reserved = req["flags"] & np.uint8(0xFF & ~FLAGS_DEFINED)
    if reserved.any():
        i = int(np.flatnonzero(reserved)[0])
        raise DatapathError(f"request {i}: flags {int(req['flags'][i]):#04x} set reserved bits "
                            f"(only {FLAGS_DEFINED:#04x} is defined: {_flag_names()})")
    decode = (req["flags"] & np.uint8(FLAG_DECODE_Q8)) != 0
    if not decode.any():
        return
    if not compressed:
        i = int(np.flatnonzero(decode)[0])
        raise DatapathError(f"request {i}: FLAG_DECODE_Q8 needs the q8 decode: "
                            "backend(..., compressed=True)")
    rows = np.flatnonzero(carries_qnode(req))
    word = np.ascontiguousarray(req["qnode"][rows, node_word(Q8_NODE, "exp")])
    exp = word.view(np.int8).reshape(-1, 4)[:, :3]                 # exp_x, exp_y, exp_z
    bad = ((exp < Q8_EXP_MIN) | (exp > Q8_EXP_MAX)).any(axis=1)
    if bad.any():
        i = int(rows[np.flatnonzero(bad)[0]])
        raise DatapathError(f"request {i}: q8 node exponents {exp[bad][0].tolist()} outside "
                            f"[{Q8_EXP_MIN}, {Q8_EXP_MAX}]")


def _flag_names(mask: int = FLAGS_DEFINED) -> str:
    return ", ".join(FLAG_NAMES[m] for m in sorted(FLAG_NAMES) if m & mask)


def vectors(x, name: str) -> np.ndarray:
    """(n, 3) float32 of an array-like of x, y, z rows (``(n, 3)``, one ``(3,)`` vector, or any
    ``(..., 3)``, rows in C order); a one-line ValueError naming ``name`` and the shape it
    wants otherwise."""
    try:
        a = np.asarray(x, dtype=np.float32)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (n, 3) array of numbers, one x, y, z row per ray "
                         "(got rows of unequal length, or values that are not numbers)") from None
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{name} must be an (n, 3) array, one x, y, z row per ray; got shape "
                         f"{a.shape}")
    return a.reshape(-1, 3)


def per_ray(x, n: int, name: str) -> np.ndarray:
    """(n,) float32 of a scalar or one value per ray; a one-line ValueError naming ``name``
    otherwise."""
    try:
        a = np.asarray(x, dtype=np.float32)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or one number per ray, shape ({n},)"
                         ) from None
    if a.ndim > 1 or (a.ndim == 1 and len(a) != n):
        raise ValueError(f"{name} must be a scalar or one value per ray, shape ({n},); got "
                         f"shape {a.shape}")
    return np.broadcast_to(a, (n,))


def prepare_rays(origins, directions, extent=np.inf, flags=0) -> np.ndarray:
    """Fill the ray fields of a new request array (docs/datapath.md#ray-preparation,
    #requests-and-responses).

    origins, directions : (n, 3) array-like (``vectors``), converted to float32
    extent : scalar or (n,) ray extent (tmax)
    flags : scalar or (n,) ray flags (``FLAG_NO_CULL`` or 0; ``FLAG_DECODE_Q8`` is not a ray's but
        a request's: whoever puts a q8 node into a QUADBOX sets it)
    Returns an (n,) ``REQUEST_DTYPE`` array, every non-ray field zero.
    Raises ValueError (one line naming the argument) for origins or directions that are not
    (n, 3) or not finite, an all-zero direction, an extent that is not a scalar or (n,), or
    flags that are not integers made of defined flag bits.
    """
    o = vectors(origins, "origins")
    d = vectors(directions, "directions")
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} differ in shape")
    if not (np.isfinite(o).all() and np.isfinite(d).all()):
        raise ValueError("ray origins and directions must be finite")
    if (d == 0).all(axis=1).any():
        raise ValueError("a ray direction is the zero vector")
    n = len(o)
    fl = np.asarray(flags)
    if fl.ndim > 1 or (fl.ndim == 1 and len(fl) != n):
        raise ValueError(f"flags must be a scalar or one per ray ({n}), not shape {fl.shape}")
    if fl.dtype.kind not in "biu" or (fl.astype(np.int64) & ~RAY_FLAGS).any():
        raise ValueError(f"flags must be integers made of ray flag bits ({RAY_FLAGS:#x}: "
                         f"{_flag_names(RAY_FLAGS)}), not {fl.ravel()[:4].tolist()}")
    req = np.zeros(n, REQUEST_DTYPE)
    req["flags"] = np.broadcast_to(fl, (n,))
    req["origin"] = o
    req["dir"] = d
    req["extent"] = per_ray(extent, n, "extent")
    one = np.float32(1)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        req["inv"] = one / d
        kz = np.argmax(np.abs(d), axis=1)          # ties: lowest index
        kx = (kz + 1) % 3
        ky = (kx + 1) % 3
        rows = np.arange(n)
        dz = d[rows, kz]
        swap = dz < 0
        kx, ky = np.where(swap, ky, kx), np.where(swap, kx, ky)
        req["kx"], req["ky"], req["kz"] = kx, ky, kz
        req["shear"][:, 0] = d[rows, kx] / dz
        req["shear"][:, 1] = d[rows, ky] / dz
        req["shear"][:, 2] = one / dz
    return req


def transform_requests(m, o, d, tag=None) -> np.ndarray:
    """TRANSFORM requests (``REQUEST_DTYPE``) of rays (o, d) by 3x4 matrices m: m (n, 3, 4) or
    one (3, 4) for every ray, o and d (n, 3), converted to float32; ``tag`` (n,) defaults to the
    row index. The datapath answers o' and d' (``transform_results``; docs/transform.md)."""
    o = vectors(o, "origins")
    d = vectors(d, "directions")
    if o.shape != d.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} differ in shape")
    n = len(o)
    m = np.asarray(m, np.float32)
    if m.shape[-2:] != MATRIX_SHAPE or m.ndim not in (2, 3) or (m.ndim == 3 and len(m) != n):
        raise ValueError(f"matrices must be {MATRIX_SHAPE} or ({n}, *{MATRIX_SHAPE}), "
                         f"not {m.shape}")
    req = np.zeros(n, REQUEST_DTYPE)
    req["opcode"] = TRANSFORM
    req["tag"] = np.arange(n, dtype=np.uint32) if tag is None else tag
    req["origin"] = o
    req["dir"] = d
    req["matrix"] = np.broadcast_to(m, (n, *MATRIX_SHAPE))
    return req


def transform_results(rsp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(o', d'), each (n, 3) float32, of the responses to ``transform_requests``; DatapathError
    if a response is not a TRANSFORM's."""
    if rsp.dtype != RESPONSE_DTYPE:
        raise TypeError("responses must be a RESPONSE_DTYPE array")
    if (rsp["opcode"] != TRANSFORM).any():
        i = int(np.flatnonzero(rsp["opcode"] != TRANSFORM)[0])
        raise DatapathError(f"response {i} is not a TRANSFORM's (opcode {int(rsp['opcode'][i])})")
    return rsp["xf_origin"].copy(), rsp["xf_dir"].copy()


def run_transform(backend, m, o, d) -> tuple[np.ndarray, np.ndarray]:
    """(o', d') of rays (o, d) by matrices m computed by ``backend`` (a model of a build with
    TRANSFORM, e.g. ``driver.backend("rtl", transform=True)``): the same signature and bits as
    the host's transform, except that a NaN comes back as the canonical quiet NaN."""
    return transform_results(backend.run(transform_requests(m, o, d)))
