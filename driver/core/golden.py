"""Golden model of the RayFlex datapath: vectorised numpy float32, bit-exact by construction.

One numpy float32 operation per step of the datapath contract, in the order of
docs/datapath.md#quadbox, #triangle, #euclidean-and-angular. numpy rounds every float32 add/multiply
to nearest-even and keeps subnormals, which is exactly the datapath's arithmetic; NaN results are
written as the canonical quiet NaN 0x7FC00000 at the outputs (a NaN anywhere in a chain of
adds/multiplies stays NaN, and compares are false on NaN, so canonicalising at the output is the
same as canonicalising after every step).

The FUSED build (``fused=True``; docs/tradeoffs.md#forgoing-rounding) rounds less often: the box
slab value ``(bound - origin) * inv`` and the triangle's edge functions ``U = Cx*By - Cy*Bx`` (V, W
likewise) are each one operation with one rounding (``sum_of_products``, ``slab``).
"""

from __future__ import annotations

import numpy as np

from .datapath import CANONICAL_NAN
from .wire import ANG_LANES, EUC_LANES, carries_qnode
from .layout import Q8_NODE, decode_q8

F32 = np.float32
_INF = F32(np.inf)


def canonical(x: np.ndarray) -> np.ndarray:
    """Replace every NaN by the canonical quiet NaN (in place on a float32 array)."""
    x.view(np.uint32)[np.isnan(x)] = CANONICAL_NAN
    return x


def _round_to_odd(s: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The float64 value s + e rounded to odd (s = RN(s + e), e its exact error): s itself when e
    is 0 or s is odd, else the neighbour of s toward e (the odd one of the two around s + e)."""
    bits = s.view(np.uint64)
    step = (e != 0) & ((bits & np.uint64(1)) == 0) & np.isfinite(s)
    up = np.signbit(e) == np.signbit(s)                       # |s + e| > |s|
    out = bits.copy()
    out[step & up] += np.uint64(1)
    out[step & ~up] -= np.uint64(1)
    return out.view(np.float64)


def sum_of_products(a, b, c, d) -> np.ndarray:
    """a*b + c*d of float32 arrays with ONE rounding to float32 (round to nearest even), IEEE
    special values as the exact expression has them (0*inf, inf - inf: NaN).

    Exact by this argument: a product of two binary32 numbers has at most 48 significant bits and a
    magnitude in [2^-298, 2^256], so it is exact in float64 (53 bits, normal down to 2^-1022).
    The sum p + q of the two exact products is computed as TwoSum (s = RN64(p + q) and its exact
    error e, Knuth; exact for any finite float64 without overflow) and rounded to odd in float64
    (``_round_to_odd``). Rounding to odd at 53 bits, then to nearest even at 24 bits, is the
    correct rounding of p + q: every binary32 number and every midpoint between two of them (also
    in the subnormal range, and the overflow threshold 2^128 - 2^103) is a float64 with an even last
    bit, and a value rounded to odd is either exact or odd, in the same open interval between two
    consecutive float64 numbers as the exact value, so it compares with every such point exactly as
    the exact value does; nearest-even rounding depends on nothing else. (Boldo and Melquiond,
    "Emulation of FMA and correctly rounded sums: proved algorithms using rounding to odd", IEEE
    Trans. Computers 57(4), 2008.) A zero sum takes the sign IEEE gives an exact sum (float64's)."""
    p = np.asarray(a, np.float64) * np.asarray(b, np.float64)
    q = np.asarray(c, np.float64) * np.asarray(d, np.float64)
    s = p + q
    bp = s - q
    e = (p - bp) + (q - (s - bp))                              # TwoSum: s + e == p + q exactly
    return _round_to_odd(s, e).astype(F32)


def slab(bound, origin, inv) -> np.ndarray:
    """(bound - origin) * inv of float32 arrays with ONE rounding to float32: the exact real value,
    rounded to nearest even, with the special values of the IEEE expression (NaN operands,
    inf - inf, 0 * inf: NaN; infinities and zeros with their IEEE signs).

    The value's class (NaN, inf, zero and its sign, or finite non-zero) is that of float64's
    (bound - origin) * inv: float64 rounding keeps the sign and the zero-ness of the difference and
    of the product (a product of non-zero numbers of binary32 range is at least 2^-298, no float64
    underflow). A finite non-zero value is rounded from the exact
    bound*inv - origin*inv (``sum_of_products``: the same real number)."""
    b = np.asarray(bound, np.float64)
    o = np.asarray(origin, np.float64)
    m = np.asarray(inv, np.float64)
    plain = (b - o) * m
    fused = sum_of_products(bound, inv, -np.asarray(origin, F32), inv)
    return np.where(np.isfinite(plain) & (plain != 0), fused, plain.astype(F32))


def quadbox(origin, inv, dirs, boxes, extent, fused=False):
    """docs/datapath.md#quadbox before the sort. origin, inv, dirs: (n, 3); boxes: (n, 4, 6);
    extent: (n,).

    Returns (hit (n, 4) bool, tmin (n, 4) float32: +0-canonical on a hit, +inf on a miss).
    Works one axis at a time on contiguous (n, 4) arrays. A NaN near/far value (0 * inf) makes the
    box a miss: np.maximum/np.minimum propagate NaN into tmin/tmax and `tmin < tmax` is then false,
    which is exactly the "any NaN -> miss" rule. ``fused``: each slab value with one rounding
    (``slab``).
    """
    near = []
    far = []
    for a in range(3):
        o = origin[:, a:a + 1]
        if fused:
            lo = slab(boxes[:, :, a], o, inv[:, a:a + 1])
            hi = slab(boxes[:, :, 3 + a], o, inv[:, a:a + 1])
        else:
            lo = (boxes[:, :, a] - o) * inv[:, a:a + 1]
            hi = (boxes[:, :, 3 + a] - o) * inv[:, a:a + 1]
        neg = np.signbit(dirs[:, a:a + 1])
        near.append(np.where(neg, hi, lo))
        far.append(np.where(neg, lo, hi))
    tmin = np.maximum(np.maximum(np.maximum(near[0], near[1]), near[2]), F32(0))
    tmax = np.minimum(np.minimum(np.minimum(far[0], far[1]), far[2]), extent[:, None])
    hit = tmin < tmax
    tmin = np.where(hit, tmin + F32(0), _INF)      # -0 + +0 = +0: a hit's tmin is never -0
    return hit, tmin.astype(F32)


def request_boxes(req):
    """The (n, 4, 6) boxes the QUADBOX requests ``req`` test: their ``box``, except on the rows
    that carry a q8 node (``driver.core.wire.carries_qnode``), where they are its decode
    (``driver.core.layout.decode_q8``)."""
    boxes, qnode = req["box"], req["qnode"]
    rows = np.flatnonzero(carries_qnode(req))
    if not len(rows):
        return boxes
    out = np.array(boxes, F32)
    out[rows] = decode_q8(np.ascontiguousarray(qnode[rows], np.uint32).view(Q8_NODE))
    return out


def sort4(hit, tmin):
    """The 5-comparator network on (tmin, index): equivalent to a stable sort by tmin, since a
    hit's tmin is finite and non-negative and every miss is +inf (ties resolve by index)."""
    order = np.argsort(tmin, axis=1, kind="stable").astype(np.uint8)
    return order, np.take_along_axis(hit, order, 1), np.take_along_axis(tmin, order, 1)


def triangle(origin, kxyz, shear, tri, no_cull=False, fused=False):
    """docs/datapath.md#triangle. origin (n,3), kxyz (n,3) int, shear (n,3), tri (n,3,3); no_cull:
    bool, scalar or (n,), the NO_CULL flag (both faces hit); ``fused``: U, V, W each with one
    rounding (``sum_of_products``).

    Returns (hit (n,) bool, t_num (n,), t_den (n,))."""
    p = tri - origin[:, None, :]                                  # P' = P - o
    px = np.take_along_axis(p, kxyz[:, None, 0:1], 2)[:, :, 0]    # (n, 3 vertices)
    py = np.take_along_axis(p, kxyz[:, None, 1:2], 2)[:, :, 0]
    pz = np.take_along_axis(p, kxyz[:, None, 2:3], 2)[:, :, 0]
    sx, sy, sz = shear[:, 0:1], shear[:, 1:2], shear[:, 2:3]
    x = px - sx * pz
    y = py - sy * pz
    z = sz * pz
    (ax, bx, cx), (ay, by, cy), (az, bz, cz) = x.T, y.T, z.T
    if fused:
        u = sum_of_products(cx, by, -cy, bx)
        v = sum_of_products(ax, cy, -ay, cx)
        w = sum_of_products(bx, ay, -by, ax)
    else:
        u = cx * by - cy * bx
        v = ax * cy - ay * cx
        w = bx * ay - by * ax
    t_den = (u + v) + w
    t_num = ((u * az) + (v * bz)) + (w * cz)
    front = (u >= 0) & (v >= 0) & (w >= 0)
    culled = front & (t_num >= 0) & (t_den != 0)
    back = (u <= 0) & (v <= 0) & (w <= 0)
    both = (front | back) & (t_den != 0) & np.where(t_den > 0, t_num >= 0, t_num <= 0)
    hit = np.where(no_cull, both, culled)
    return hit, t_num, t_den


def transform(m, o, d):
    """The ray transform by 3x4 matrices (docs/transform.md), every product and sum a float32
    rounding, in this order: ``o'[r] = ((m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]) + m[r][3]``,
    ``d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]``. m (n, 3, 4) or (3, 4); o, d (n, 3)
    (converted to float32). Returns (o', d'), each (n, 3) float32, NaNs as they come (the
    datapath's responses carry them canonical: ``canonical``)."""
    m = np.asarray(m, F32)
    o = np.asarray(o, F32).reshape(-1, 3)
    d = np.asarray(d, F32).reshape(-1, 3)
    m = np.broadcast_to(m, (len(o), 3, 4)) if m.ndim == 2 else m
    with np.errstate(all="ignore"):
        po = m[:, :, :3] * o[:, None, :]                           # (n, r, c) products
        pd = m[:, :, :3] * d[:, None, :]
        o2 = ((po[:, :, 0] + po[:, :, 1]) + po[:, :, 2]) + m[:, :, 3]
        d2 = (pd[:, :, 0] + pd[:, :, 1]) + pd[:, :, 2]
    return o2.astype(F32), d2.astype(F32)


def tree_sum(x: np.ndarray) -> np.ndarray:
    """Fixed reduction tree over the last axis (length a power of two): (i, i+half) pairs, halving."""
    while x.shape[-1] > 1:
        half = x.shape[-1] // 2
        x = x[..., :half] + x[..., half:]
    return x[..., 0]


def euclid_beat(a, b, mask):
    """One EUCLIDEAN beat: sum over the 16 lanes of (a-b)^2, masked lanes +0."""
    d = a - b
    e = d * d
    e = np.where(_lanes(mask, EUC_LANES), e, F32(0))
    return tree_sum(e)


def angular_beat(a, b, mask):
    """One ANGULAR beat over 8 lanes: (sum a*b, sum b*b), masked lanes +0."""
    a, b = a[:, :ANG_LANES], b[:, :ANG_LANES]
    on = _lanes(mask, ANG_LANES)
    return tree_sum(np.where(on, a * b, F32(0))), tree_sum(np.where(on, b * b, F32(0)))


def _lanes(mask, n):
    return ((mask[:, None].astype(np.uint32) >> np.arange(n, dtype=np.uint32)) & 1).astype(bool)


def accumulate(beats: np.ndarray, last: np.ndarray, acc0: F32):
    """Sequential accumulator over beats in order: acc = acc + beat; after a beat with last set the
    accumulator clears to +0. Vectorised across jobs (one loop step per beat position).

    Returns (running acc after each beat (float32), final accumulator state)."""
    n = len(beats)
    out = np.empty(n, F32)
    if n == 0:
        return out, acc0
    last = last.astype(bool)
    job = np.concatenate(([0], np.cumsum(last)[:-1]))             # job id of each beat
    starts = np.flatnonzero(np.concatenate(([True], job[1:] != job[:-1])))
    pos = np.arange(n) - np.repeat(starts, np.diff(np.append(starts, n)))
    acc = np.zeros(job[-1] + 1, F32)
    acc[0] = acc0
    for p in range(pos.max() + 1):
        rows = np.flatnonzero(pos == p)
        acc[job[rows]] = acc[job[rows]] + beats[rows]
        out[rows] = acc[job[rows]]
    final = F32(0) if last[-1] else acc[-1]
    return out, final
