"""Scalar reference model of the RayFlex datapath, one operation at a time, from
docs/datapath.md#ray-preparation, #quadbox, #triangle, #euclidean-and-angular.

This is deliberately the slow, obvious version: one request at a time, one ``np.float32`` scalar
operation per step of docs/datapath.md (every add, subtract, multiply and divide is rounded to
binary32 on its own, nearest-even, subnormals kept), comparisons as plain IEEE compares, the box
sort as five explicit compare-and-swap comparators. It shares nothing with ``driver/core/golden.py``
except the request and response dtypes, so the golden model and the RTL can both be checked against
it bit for bit.

Public surface:

- ``prepare_ray(origin, direction, extent)`` -> dict of docs/datapath.md#ray-preparation ray fields
  for one ray
- ``quadbox(row)``, ``triangle(row)`` -> per-request results (docs/datapath.md#quadbox, #triangle);
  a QUADBOX with ``FLAG_DECODE_Q8`` first decodes its q8 node (``q8_boxes``, read from the node's
  bytes with ``struct`` at the word positions of docs/q8_datapath.md, in Python floats)
- ``euclid_beat(row)``, ``angular_beat(row)`` -> one beat's tree sums
  (docs/datapath.md#euclidean-and-angular)
- ``transform(row)`` -> a TRANSFORM's (o', d') (docs/transform.md), element by element
- ``ScalarState`` -> the two stateful accumulators (Euclidean; angular dot and norm) and cycle count
- ``scalar_run(requests, state)`` -> ``RESPONSE_DTYPE`` array (same length and order)

Choices the contract leaves open (docs/datapath.md#choices-the-paper-leaves-open) (all shared with
the golden model):

- non-final EUCLIDEAN/ANGULAR beats output the running accumulator value (``*_last = 0``);
- ``min``/``max`` are comparator selects (``a if a < b else b``); NaN never reaches them from the
  slabs (that box is a miss first), and a NaN ``extent`` therefore gives ``tmax = NaN`` -> miss;
- response fields an opcode does not produce are zero; ``tag`` is carried through.
"""

from __future__ import annotations

import struct

import numpy as np

from driver.core.datapath import (ANGULAR, EUCLIDEAN, LATENCY, QUADBOX, RESPONSE_DTYPE, TRANSFORM,
                                  TRIANGLE, DatapathError)
from driver.core.wire import FLAG_DECODE_Q8, FLAG_NO_CULL

F32 = np.float32
ZERO = F32(0.0)          # +0
ONE = F32(1.0)
INF = F32(np.inf)
CANONICAL_NAN_BITS = 0x7FC00000


# ----------------------------------------------------------------------------------------------
# binary32 primitives: each returns a float32 rounded once (numpy float32 scalar arithmetic)

def f(x) -> F32:
    return F32(x)


def add(a, b) -> F32:
    return F32(F32(a) + F32(b))


def sub(a, b) -> F32:
    return F32(F32(a) - F32(b))


def mul(a, b) -> F32:
    return F32(F32(a) * F32(b))


def div(a, b) -> F32:
    return F32(F32(a) / F32(b))


def sign_bit(x) -> bool:
    return bool(np.signbit(F32(x)))


def is_nan(x) -> bool:
    return bool(x != x)


def fmax(a, b) -> F32:
    """Comparator max: a if a > b else b (callers keep NaN away)."""
    return a if a > b else b


def fmin(a, b) -> F32:
    """Comparator min: a if a < b else b (callers keep NaN away, except extent: NaN -> NaN)."""
    return a if a < b else b


def out_bits(x) -> int:
    """uint32 bit pattern of an output float, NaN replaced by the canonical quiet NaN."""
    x = F32(x)
    if is_nan(x):
        return CANONICAL_NAN_BITS
    return int(np.array(x, F32).view(np.uint32))


def out_f32(x) -> F32:
    """An output float with NaN canonicalised (as a float32 scalar)."""
    return np.array(out_bits(x), np.uint32).view(F32)[()]


# ----------------------------------------------------------------------------------------------
# docs/datapath.md#ray-preparation: ray prepared on the host

def prepare_ray(origin, direction, extent=np.inf) -> dict:
    """Ray fields of docs/datapath.md#ray-preparation for one ray: origin, dir, inv, extent, kx, ky,
    kz, shear."""
    o = [f(v) for v in origin]
    d = [f(v) for v in direction]
    inv = [div(ONE, d[0]), div(ONE, d[1]), div(ONE, d[2])]
    # kz: index of the largest |d|, ties to the lowest index (only a strictly larger one replaces)
    kz = 0
    if abs(d[1]) > abs(d[kz]):
        kz = 1
    if abs(d[2]) > abs(d[kz]):
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    if d[kz] < ZERO:
        kx, ky = ky, kx
    shear = [div(d[kx], d[kz]), div(d[ky], d[kz]), div(ONE, d[kz])]
    return {"origin": o, "dir": d, "inv": inv, "extent": f(extent),
            "kx": kx, "ky": ky, "kz": kz, "shear": shear}


# ----------------------------------------------------------------------------------------------
# docs/datapath.md#quadbox: QUADBOX

def slab_box(o, d, inv, box, extent):
    """One box: returns (hit, tmin) with tmin +0 on a zero-distance hit and +inf on a miss."""
    near, far = [], []
    for a in range(3):
        lo = mul(sub(box[a], o[a]), inv[a])
        hi = mul(sub(box[a + 3], o[a]), inv[a])
        if sign_bit(d[a]):
            near.append(hi)
            far.append(lo)
        else:
            near.append(lo)
            far.append(hi)
    if any(is_nan(v) for v in near + far):
        return False, INF
    tmin = fmax(fmax(fmax(near[0], near[1]), near[2]), ZERO)
    tmax = fmin(fmin(fmin(far[0], far[1]), far[2]), extent)
    hit = bool(tmin < tmax)
    if not hit:
        return False, INF
    if tmin == ZERO:          # covers -0: a hit's tmin is never -0
        tmin = ZERO
    return True, tmin


def _before(a, b) -> bool:
    """Lexicographic (tmin, index) order: a strictly before b."""
    return bool(a[0] < b[0]) or (bool(a[0] == b[0]) and a[1] < b[1])


def _comparator(v, i, j):
    """Compare-and-swap: after it, v[i] is not after v[j]."""
    if _before(v[j], v[i]):
        v[i], v[j] = v[j], v[i]


def sort4(entries):
    """The 5-comparator sorting network for 4 keys: (0,1) (2,3) (0,2) (1,3) (1,2)."""
    v = list(entries)
    _comparator(v, 0, 1)
    _comparator(v, 2, 3)
    _comparator(v, 0, 2)
    _comparator(v, 1, 3)
    _comparator(v, 1, 2)
    return v


# q8 node: words 0-2 origin (float32), word 3 bytes 0-2 exp_x/y/z (int8) and byte 3 bits 2:0 count,
# words 4-7 children, bytes 32 + 6i + j the planes of child i, words 14-15 parent and 0
_Q8 = struct.Struct("<3f3bB4I24B2I")


def q8_boxes(node_bytes: bytes) -> list:
    """The four child boxes of a q8 node (64 bytes): used child i, bound j, axis j % 3:
    origin + q * 2**exp (the product exact in a Python float and in float32), one float32 add;
    unused slots six +inf."""
    v = _Q8.unpack(node_bytes)
    origin, exp, count, q = v[0:3], v[3:6], v[6] & 7, v[11:35]
    boxes = []
    for i in range(4):
        if i >= count:
            boxes.append([INF] * 6)
            continue
        boxes.append([add(origin[j % 3], f(q[6 * i + j] * 2.0 ** exp[j % 3])) for j in range(6)])
    return boxes


def quadbox(row):
    """docs/datapath.md#quadbox for one request row: returns (index[4], hit[4], tmin[4]) in sorted
    order."""
    o = [f(v) for v in row["origin"]]
    d = [f(v) for v in row["dir"]]
    inv = [f(v) for v in row["inv"]]
    extent = f(row["extent"])
    boxes = [[f(v) for v in row["box"][i]] for i in range(4)]
    if int(row["flags"]) & FLAG_DECODE_Q8:
        boxes = q8_boxes(np.asarray(row["qnode"], "<u4").tobytes())
    entries = []
    for i in range(4):
        box = boxes[i]
        hit, tmin = slab_box(o, d, inv, box, extent)
        entries.append((tmin, i, hit))
    s = sort4(entries)
    return [e[1] for e in s], [e[2] for e in s], [e[0] for e in s]


# ----------------------------------------------------------------------------------------------
# docs/datapath.md#triangle: TRIANGLE

def triangle(row):
    """docs/datapath.md#triangle for one request row: returns (hit, t_num, t_den) (t_num, t_den not
    canonicalised)."""
    o = [f(v) for v in row["origin"]]
    kx, ky, kz = int(row["kx"]), int(row["ky"]), int(row["kz"])
    sx, sy, sz = (f(v) for v in row["shear"])
    xyz = []
    for p in row["tri"]:                        # A, B, C
        pp = [sub(p[0], o[0]), sub(p[1], o[1]), sub(p[2], o[2])]
        x = sub(pp[kx], mul(sx, pp[kz]))
        y = sub(pp[ky], mul(sy, pp[kz]))
        z = mul(sz, pp[kz])
        xyz.append((x, y, z))
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = xyz
    u = sub(mul(cx, by), mul(cy, bx))
    v = sub(mul(ax, cy), mul(ay, cx))
    w = sub(mul(bx, ay), mul(by, ax))
    t_den = add(add(u, v), w)
    t_num = add(add(mul(u, az), mul(v, bz)), mul(w, cz))
    front = (u >= ZERO) and (v >= ZERO) and (w >= ZERO)
    # docs/datapath.md#triangle with NO_CULL: either face
    if int(row["flags"]) & FLAG_NO_CULL:
        both = front or ((u <= ZERO) and (v <= ZERO) and (w <= ZERO))
        hit = both and (t_den != ZERO) and ((t_num >= ZERO) if t_den > ZERO else (t_num <= ZERO))
    else:
        hit = front and (t_num >= ZERO) and (t_den != ZERO)
    return bool(hit), t_num, t_den


# ----------------------------------------------------------------------------------------------
# docs/datapath.md#euclidean-and-angular: EUCLIDEAN and ANGULAR

def _mask_bit(mask, i) -> bool:
    return bool((int(mask) >> i) & 1)


def tree(values):
    """Fixed reduction tree: (i, i+n/2) pairs, then (i, i+n/4), ... down to one value."""
    v = list(values)
    while len(v) > 1:
        half = len(v) // 2
        v = [add(v[i], v[i + half]) for i in range(half)]
    return v[0]


def euclid_beat(row) -> F32:
    """Sum over 16 lanes of (a_i - b_i)^2; masked-off lanes contribute +0."""
    lanes = []
    for i in range(16):
        if _mask_bit(row["vec_mask"], i):
            e = sub(row["vec_a"][i], row["vec_b"][i])
            lanes.append(mul(e, e))
        else:
            lanes.append(ZERO)
    return tree(lanes)


def angular_beat(row):
    """(sum a_i*b_i, sum b_i*b_i) over 8 lanes (mask bits 0-7); masked-off lanes contribute +0."""
    dots, norms = [], []
    for i in range(8):
        if _mask_bit(row["vec_mask"], i):
            a, b = f(row["vec_a"][i]), f(row["vec_b"][i])
            dots.append(mul(a, b))
            norms.append(mul(b, b))
        else:
            dots.append(ZERO)
            norms.append(ZERO)
    return tree(dots), tree(norms)


def transform(row):
    """TRANSFORM: (o', d') as two lists of three float32, one rounding per product and sum, in
    the order o'[r] = ((m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]) + m[r][3] and
    d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]."""
    m = [[F32(row["matrix"][r][c]) for c in range(4)] for r in range(3)]
    o = [F32(x) for x in row["origin"]]
    d = [F32(x) for x in row["dir"]]
    o2, d2 = [], []
    for r in range(3):
        acc = add(mul(m[r][0], o[0]), mul(m[r][1], o[1]))
        acc = add(acc, mul(m[r][2], o[2]))
        o2.append(add(acc, m[r][3]))
        acc = add(mul(m[r][0], d[0]), mul(m[r][1], d[1]))
        d2.append(add(acc, mul(m[r][2], d[2])))
    return o2, d2


class ScalarState:
    """The datapath's state: accumulators (change only on accepted EUCLIDEAN/ANGULAR beats) and an
    ideal-pipeline cycle count (n + latency per non-empty run)."""

    def __init__(self, extended: bool = True, latency: int = LATENCY, compressed: bool = True,
                 transform: bool = True):
        self.extended = extended
        self.compressed = compressed
        self.transform = transform
        self.latency = latency
        self.euclid_acc = ZERO
        self.angular_dot = ZERO
        self.angular_norm = ZERO
        self.cycles = 0

    def euclid(self, row):
        """One EUCLIDEAN beat: returns (acc including this beat, last)."""
        acc = add(self.euclid_acc, euclid_beat(row))
        last = bool(int(row["reset_accumulator"]) & 1)
        self.euclid_acc = ZERO if last else acc
        return acc, last

    def angular(self, row):
        """One ANGULAR beat: returns (dot, norm including this beat, last)."""
        dot_b, norm_b = angular_beat(row)
        dot = add(self.angular_dot, dot_b)
        norm = add(self.angular_norm, norm_b)
        last = bool(int(row["reset_accumulator"]) & 1)
        self.angular_dot = ZERO if last else dot
        self.angular_norm = ZERO if last else norm
        return dot, norm, last


# ----------------------------------------------------------------------------------------------
# whole request stream

def scalar_run(requests: np.ndarray, state: ScalarState | None = None) -> np.ndarray:
    """Run a REQUEST_DTYPE array through the scalar model; returns a RESPONSE_DTYPE array.

    Raises DatapathError (before touching any state) for opcodes the build does not have."""
    if state is None:
        state = ScalarState()
    ops = {TRIANGLE, QUADBOX} | ({EUCLIDEAN, ANGULAR} if state.extended else set()) | (
        {TRANSFORM} if state.transform else set())
    for op, flags in zip(requests["opcode"], requests["flags"]):
        if int(op) not in ops:
            raise DatapathError(f"opcode {int(op)} not supported by this build")
        if int(flags) & FLAG_DECODE_Q8 and not state.compressed:
            raise DatapathError("FLAG_DECODE_Q8 needs a build with the q8 decode")
    rsp = np.zeros(len(requests), RESPONSE_DTYPE)
    with np.errstate(all="ignore"):
        for n, row in enumerate(requests):
            op = int(row["opcode"])
            out = rsp[n]
            out["opcode"] = op
            out["tag"] = row["tag"]
            if op == QUADBOX:
                index, hit, tmin = quadbox(row)
                for j in range(4):
                    out["box_index"][j] = index[j]
                    out["box_hit"][j] = hit[j]
                    out["box_tmin"][j] = out_f32(tmin[j])
            elif op == TRIANGLE:
                hit, t_num, t_den = triangle(row)
                out["tri_hit"] = hit
                out["t_num"] = out_f32(t_num)
                out["t_den"] = out_f32(t_den)
            elif op == EUCLIDEAN:
                acc, last = state.euclid(row)
                out["euclid_acc"] = out_f32(acc)
                out["euclid_last"] = last
            elif op == ANGULAR:
                dot, norm, last = state.angular(row)
                out["angular_dot"] = out_f32(dot)
                out["angular_norm"] = out_f32(norm)
                out["angular_last"] = last
            elif op == TRANSFORM:
                o2, d2 = transform(row)
                for r in range(3):
                    out["xf_origin"][r] = out_f32(o2[r])
                    out["xf_dir"][r] = out_f32(d2[r])
    if len(requests):
        state.cycles += len(requests) + state.latency
    return rsp


def prepare_rays(origins, directions, extent=np.inf) -> np.ndarray:
    """Scalar counterpart of driver.prepare_rays (no input validation): a REQUEST_DTYPE array."""
    from driver.core.datapath import REQUEST_DTYPE
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    ext = np.broadcast_to(np.asarray(extent, np.float32), (len(o),))
    req = np.zeros(len(o), REQUEST_DTYPE)
    with np.errstate(all="ignore"):
        for n in range(len(o)):
            r = prepare_ray(o[n], d[n], ext[n])
            for k in ("origin", "dir", "inv", "shear"):
                req[n][k] = np.array(r[k], np.float32)
            for k in ("extent", "kx", "ky", "kz"):
                req[n][k] = r[k]
    return req
