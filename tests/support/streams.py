"""Random request streams drawn to hit the datapath's corner cases (golden, RTL and kNN tests).

QUADBOX / TRIANGLE (docs/datapath.md#quadbox, #triangle):

- ``mixed_stream(seed, n_box, n_tri)``: random interleaved QUADBOX/TRIANGLE requests: axis-parallel
  rays (exact +-0 components), origins on slab planes, boxes around / near / containing the origin,
  degenerate and inverted boxes, duplicated boxes (tmin ties), triangles aimed at (interior, edge,
  vertex, both windings), coplanar rays, degenerate triangles, NaN / inf / subnormal inputs and raw
  random bit patterns (built from ``quadbox_requests`` and ``triangle_requests``).
- ``random_bits(rng, shape)``: raw float32 bit patterns.

EUCLIDEAN / ANGULAR (docs/datapath.md#euclidean-and-angular):

- ``random_vectors(rng, n)``: (n, 16) operand lanes, some special.
- ``vector_requests(rng, op, lengths)``: jobs of the given beat counts with random masks, reset on
  each job's last beat.

q8 nodes (QUADBOX with ``FLAG_DECODE_Q8``, docs/q8_datapath.md):

- ``random_q8_nodes(rng, origins)``: ``Q8_NODE`` rows near the given ray origins: exponents over
  the whole range [-126, 119] and at a scene's scale, zero and full planes, every count 1-4,
  subnormal, +-0, NaN, inf and raw-bit node origins, garbage in the fields the decode ignores.
- ``q8_requests(rng, n)``: rays as ``quadbox_requests`` (NaN origins of rays included) against
  random q8 nodes; the box words after the node carry garbage.
- ``q8_stream(seed, n_q8, n_box, n_tri)``: q8 requests interleaved with ``mixed_stream``'s
  QUADBOX/TRIANGLE requests, some TRIANGLEs carrying the flag (ignored).

Mixing:

- ``interleave(rng, parts)``: request arrays merged at random, each keeping its own order.
- ``extended_stream(seed, ...)``: random multi-beat EUCLIDEAN and ANGULAR jobs interleaved with
  each other and with QUADBOX/TRIANGLE requests; every request carries garbage in the fields its
  opcode ignores. Returns the stream and the kind of each row (0 Euclidean, 1 angular, 2 other).
"""

from __future__ import annotations

import numpy as np

import driver
from driver import QUADBOX, REQUEST_DTYPE, TRIANGLE
from driver.core.datapath import transform_requests
from driver.core.wire import FLAG_DECODE_Q8, FLAG_NO_CULL
from driver.core.layout import Q8_COUNT_LSB, Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, decode_q8, q8_count

F32 = np.float32
INF = np.inf
SUBNORMALS = np.array([1e-45, 1e-40, 1e-39, 5e-39, 1.1754942e-38], F32)   # all below 2^-126


# ----------------------------------------------------------------------------------------------
# QUADBOX / TRIANGLE

def random_dirs(rng, n):
    """Directions of every flavour; never all-zero, always finite."""
    d = rng.normal(size=(n, 3)).astype(F32)
    kind = rng.integers(0, 8, n)
    sign = np.where(rng.random((n, 3)) < 0.5, F32(-1), F32(1))
    # 1: axis-parallel, the two other components +0 or -0
    m = kind == 1
    ax = rng.integers(0, 3, n)
    z = np.zeros((n, 3), F32) * sign                       # +-0 per component
    z[np.arange(n), ax] = sign[np.arange(n), ax] * rng.uniform(0.1, 10, n).astype(F32)
    d[m] = z[m]
    # 2: one component +-0
    m = kind == 2
    d[m, ax[m]] = F32(0) * sign[m, ax[m]]
    # 3: tiny / subnormal components (inv overflows to inf)
    m = kind == 3
    d[m, ax[m]] = rng.choice(np.concatenate([SUBNORMALS, [1e-30, 3e-39, 1e-38]]).astype(F32),
                             m.sum()) * sign[m, ax[m]]
    # 4: ties in |d|
    m = kind == 4
    d[m] = sign[m] * rng.choice([F32(1), F32(0.5), F32(3)], (m.sum(), 1))
    # 5: two equal, one smaller
    m = kind == 5
    d[m] = sign[m] * np.array([2, 2, 1], F32)[rng.permutation(3)]
    # 6: huge
    m = kind == 6
    d[m] *= F32(1e30)
    return d


def random_origins(rng, n):
    o = rng.uniform(-4, 4, (n, 3)).astype(F32)
    kind = rng.integers(0, 5, n)
    o[kind == 1] = np.round(o[kind == 1])                  # on the integer grid (box planes)
    m = kind == 2
    tiny = np.concatenate([SUBNORMALS, -SUBNORMALS, [0, -0.0]]).astype(F32)
    o[m] = rng.choice(tiny, (m.sum(), 3))
    return o


def random_bits(rng, shape):
    """Raw random float32 bit patterns (NaNs with payloads, infs, subnormals, huge, tiny)."""
    return rng.integers(0, 2**32, shape, dtype=np.uint64).astype(np.uint32).view(F32)


def random_boxes(rng, o, d, extent):
    """(n, 4, 6) boxes around / near / containing the ray, degenerate, inverted, special."""
    n = len(o)
    o64, d64 = o.astype(np.float64), d.astype(np.float64)
    boxes = np.empty((n, 4, 6), F32)
    for slot in range(4):
        kind = rng.integers(0, 12, n)
        t = rng.uniform(0, 5, n)[:, None]
        with np.errstate(all="ignore"):
            p = o64 + t * d64 / np.maximum(np.abs(d64).max(axis=1, keepdims=True), 1e-30)
        h = rng.uniform(0.01, 2, (n, 3))
        b = np.concatenate([p - h, p + h], axis=1)          # 0: around a point on the ray
        # 1: near the ray (offset, about half hit)
        m = kind == 1
        off = rng.uniform(-3, 3, (n, 3)) * h
        b[m] = np.concatenate([p - h + off, p + h + off], axis=1)[m]
        # 2: containing the origin (tmin = 0 ties)
        m = kind == 2
        b[m] = np.concatenate([o64 - h, o64 + h], axis=1)[m]
        # 3: origin on a min or max plane of one or more axes
        m = kind == 3
        for a in range(3):
            on = m & (rng.random(n) < 0.6)
            which = rng.integers(0, 2, n)
            b[on & (which == 0), a] = o64[on & (which == 0), a]
            b[on & (which == 1), a + 3] = o64[on & (which == 1), a]
        # 4: flat (zero-thickness) on one axis, often through the origin
        m = kind == 4
        a = rng.integers(0, 3, n)
        r = np.flatnonzero(m)
        thru = rng.random(len(r)) < 0.5
        b[r, a[r]] = np.where(thru, o64[r, a[r]], b[r, a[r]])
        b[r, a[r] + 3] = b[r, a[r]]
        # 5: inverted (min > max on some axis)
        m = kind == 5
        b[m] = b[m][:, [3, 1, 2, 0, 4, 5]]
        # 6: unused slot at +inf, or a half-space with -inf/+inf bounds
        m = kind == 6
        b[m] = INF
        half = m & (rng.random(n) < 0.5)
        b[half] = [-INF, -INF, -INF, INF, INF, 0]
        # 7: a NaN or infinite coordinate
        m = kind == 7
        c = rng.integers(0, 6, n)
        b[m, c[m]] = rng.choice([np.nan, INF, -INF], m.sum())
        # 8: subnormal box around the origin
        m = kind == 8
        s = rng.choice(SUBNORMALS, (n, 3)).astype(np.float64)
        b[m] = np.concatenate([-s, s], axis=1)[m]
        # 10: raw random bits
        bb = b.astype(F32)
        m = kind == 10
        bb[m] = random_bits(rng, (m.sum(), 6))
        # 11: integer grid box (origins on the grid lie on its planes)
        m = kind == 11
        lo = np.floor(o64) - rng.integers(0, 2, (n, 3))
        bb[m] = np.concatenate([lo, lo + rng.integers(0, 3, (n, 3))], axis=1)[m]
        # 9: duplicate of slot 0, bit for bit (tie on tmin, resolved by index)
        if slot:
            m = kind == 9
            bb[m] = boxes[m, 0]
        boxes[:, slot] = bb
    return boxes


def random_extents(rng, n):
    e = np.full(n, INF, F32)
    kind = rng.integers(0, 6, n)
    e[kind == 1] = rng.uniform(0, 6, (kind == 1).sum())
    e[kind == 2] = 0
    e[kind == 3] = rng.choice([1e-45, 1e-30, 0.5, 1.0, -1.0], (kind == 3).sum())
    return e


def quadbox_requests(rng, n):
    o, d = random_origins(rng, n), random_dirs(rng, n)
    ext = random_extents(rng, n)
    req = driver.prepare_rays(o, d, ext)
    req["opcode"] = QUADBOX
    req["box"] = random_boxes(rng, o, d, ext)
    # a few requests whose origin itself is NaN / inf (bypassing prepare_rays' check)
    m = rng.random(n) < 0.02
    req["origin"][m, rng.integers(0, 3)] = rng.choice([np.nan, INF, -INF])
    # a few with an inv that disagrees with dir (negated / random bits): the near/far swap follows
    # the sign of dir (docs/datapath.md#quadbox), the products use inv as given
    m = rng.random(n) < 0.02
    req["inv"][m] = -req["inv"][m]
    m = rng.random(n) < 0.01
    req["inv"][m] = random_bits(rng, (m.sum(), 3))
    req["tag"] = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    return req


def random_triangles(rng, n):
    c = rng.uniform(-5, 5, (n, 1, 3))
    return c + rng.normal(size=(n, 3, 3)) * rng.uniform(0.05, 3, (n, 1, 1))


def triangle_requests(rng, n):
    """Triangles with rays aimed at them (interior, edge, vertex; both windings) and others."""
    tri = random_triangles(rng, n)
    o = random_origins(rng, n).astype(np.float64)
    kind = rng.integers(0, 11, n)
    # barycentric target point: interior / on an edge / a vertex
    bary = rng.dirichlet([1, 1, 1], n)
    edge = kind == 1
    bary[edge, rng.integers(0, 3)] = 0
    bary[edge] /= bary[edge].sum(axis=1, keepdims=True)
    vert = kind == 2
    bary[vert] = np.eye(3)[rng.integers(0, 3, vert.sum())]
    tri32 = tri.astype(F32)
    target = np.einsum("nk,nkj->nj", bary, tri32.astype(np.float64))
    d = (target - o) * rng.choice([0.25, 1, 3, 1e-3, 1e4], (n, 1))
    # 3: ray fully random (mostly misses)
    m = kind == 3
    d[m] = random_dirs(rng, m.sum())
    # 4: axis-parallel ray aimed at a triangle that is arranged around its axis
    m = kind == 4
    ax = rng.integers(0, 3, n)
    dd = np.zeros((n, 3)) * np.where(rng.random((n, 3)) < .5, -1, 1)
    dd[np.arange(n), ax] = np.where(rng.random(n) < .5, -1.0, 1.0)
    d[m] = dd[m]
    shift = (o + 2 * dd)[:, None, :]
    local = rng.normal(size=(n, 3, 3))
    local[np.arange(n), :, ax] = rng.normal(scale=0.3, size=(n, 3))
    tri32[m] = (shift + local).astype(F32)[m]
    # 5: coplanar ray: triangle in an axis plane through the origin, direction in that plane
    m = kind == 5
    r = np.flatnonzero(m)
    tri32[r, :, ax[r]] = o[r, ax[r]][:, None]
    d[r, ax[r]] = 0
    d[r] = np.where((d[r] == 0).all(axis=1, keepdims=True), 1.0, d[r])
    d[r, ax[r]] = 0
    # 6: degenerate triangle (repeated vertex or collinear)
    m = kind == 6
    tri32[m, 2] = np.where(rng.random((m.sum(), 1)) < .5, tri32[m, 1],
                           2 * tri32[m, 1] - tri32[m, 0])
    # 7: NaN / inf vertex coordinate
    m = kind == 7
    tri32[m, rng.integers(0, 3), rng.integers(0, 3)] = rng.choice([np.nan, INF, -INF])
    # 8: subnormal triangle around the origin's axis
    m = kind == 8
    tri32[m] = o[m, None, :].astype(F32) + rng.choice(np.concatenate([SUBNORMALS, -SUBNORMALS]),
                                                       (m.sum(), 3, 3))
    # 10: the origin lies in the triangle (an axis plane through it): t_num = 0 exactly, t = 0 hit
    m = kind == 10
    ang = (rng.uniform(0, 2 * np.pi, n)[:, None] + np.array([0, 2.1, 4.2])
           + rng.normal(0, .2, (n, 3)))
    rad = rng.uniform(0.1, 3, (n, 3))
    a1, a2 = (ax + 1) % 3, (ax + 2) % 3
    flat = np.repeat(o[:, None, :], 3, axis=1)
    flat[np.arange(n), :, a1] += rad * np.cos(ang)
    flat[np.arange(n), :, a2] += rad * np.sin(ang)
    tri32[m] = flat.astype(F32)[m]
    dn = rng.normal(size=(n, 3))
    dn[np.arange(n), ax] = np.where(rng.random(n) < .5, -3.0, 3.0)
    d[m] = dn[m]
    d = d.astype(F32)
    d[(d == 0).all(axis=1) | ~np.isfinite(d).all(axis=1)] = [0, 0, 1]
    # 9: raw random bits for the triangle
    m = kind == 9
    tri32[m] = random_bits(rng, (m.sum(), 3, 3))
    # both windings
    flip = rng.random(n) < 0.5
    tri32[flip] = tri32[flip][:, [0, 2, 1]]
    req = driver.prepare_rays(o.astype(F32), d, random_extents(rng, n))
    req["opcode"] = TRIANGLE
    req["tri"] = tri32
    # a few with garbage (2-bit-valid) kx/ky/kz or garbage shear: the datapath uses them as given
    m = rng.random(n) < 0.01
    req["kx"][m] = rng.integers(0, 3, m.sum())
    m = rng.random(n) < 0.01
    req["shear"][m] = random_bits(rng, (m.sum(), 3))
    req["tag"] = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    return req


def mixed_stream(seed, n_box, n_tri):
    rng = np.random.default_rng(seed)
    req = np.concatenate([quadbox_requests(rng, n_box), triangle_requests(rng, n_tri)])
    return req[rng.permutation(len(req))]


# ----------------------------------------------------------------------------------------------
# q8 nodes

def random_q8_nodes(rng, origins, targets=None):
    """One ``Q8_NODE`` per row of ``origins`` (n, 3): mostly a node whose boxes lie around the
    point, at a scale from a few ulps to the whole exponent range (see the module docstring);
    about a quarter of the child boxes surround the point or the row of ``targets`` (e.g. a point
    on a ray)."""
    n = len(origins)
    targets = origins if targets is None else targets
    node = np.zeros(n, Q8_NODE)
    # exponents: a scene's scale (the node spans 2^-6 .. 2^4 around the ray), anywhere in the
    # range, or its ends
    exp = rng.integers(-14, -3, (n, 3))
    kind = rng.integers(0, 6, n)
    exp[kind == 1] = rng.integers(Q8_EXP_MIN, Q8_EXP_MAX + 1, ((kind == 1).sum(), 3))
    ends = rng.choice([Q8_EXP_MIN, Q8_EXP_MIN + 1, Q8_EXP_MAX - 1, Q8_EXP_MAX], (n, 3))
    exp[kind == 2] = ends[kind == 2]
    # origin: the node's corner a little below the ray origin (boxes around the ray), or special
    o = origins.astype(np.float64) - rng.uniform(0, 2, (n, 3)) * np.exp2(exp + 7.0)
    with np.errstate(over="ignore"):
        org = o.astype(F32)
    ok = rng.integers(0, 14, n)
    m = ok == 1                                                 # subnormal or signed zero
    org[m] = rng.choice(np.concatenate([SUBNORMALS, -SUBNORMALS, [0.0, -0.0]]).astype(F32),
                        (m.sum(), 3))
    m = ok == 2                                                 # NaN or inf on one axis
    org[m, rng.integers(0, 3)] = rng.choice(np.array([np.nan, INF, -INF], F32), m.sum())
    m = ok == 3
    org[m] = random_bits(rng, (m.sum(), 3))
    m = ok == 4                                                 # huge: the sum may overflow
    org[m] = rng.choice(np.array([3.4e38, -3.4e38, 1e38], F32), (m.sum(), 3))
    node["origin"] = org
    node["exp"][:, :3] = exp.astype(np.int8).view(np.uint8)
    count = rng.integers(1, 5, n)
    node["exp"][:, 3] = count
    # planes: lo <= hi mostly; zero and full planes; some inverted; raw bytes
    lo = rng.integers(0, 256, (n, 4, 3))
    hi = np.maximum(lo, rng.integers(0, 256, (n, 4, 3)))
    q = np.concatenate([lo, hi], axis=2)
    pk = rng.integers(0, 10, (n, 4))
    q[pk == 1] = 0
    q[pk == 2] = 255
    q[pk == 3] = np.where(rng.random(((pk == 3).sum(), 6)) < 0.5, 0, 255)
    q[pk == 4] = q[pk == 4][:, [3, 4, 5, 0, 1, 2]]                 # inverted
    q[pk == 5] = rng.integers(0, 256, ((pk == 5).sum(), 6))
    # around the origin (pk 6) or the target (pk 7-9), where the node's scale allows it
    with np.errstate(all="ignore"):
        scale = np.exp2(exp.astype(np.float64))
        for k, point in ((6, origins), (7, targets), (8, targets), (9, targets)):
            at = (point.astype(np.float64) - org.astype(np.float64)) / scale
            at = np.clip(np.nan_to_num(at, nan=128.0), 0, 255).astype(np.int64)[:, None, :]
            near = np.concatenate([np.maximum(at - rng.integers(0, 30, (n, 4, 3)), 0),
                                   np.minimum(at + rng.integers(1, 30, (n, 4, 3)), 255)], axis=2)
            q[pk == k] = near[pk == k]
    node["q"] = q
    # fields the decode ignores: pointers, the unused slots' planes, a few reserved bits
    node["child"] = rng.integers(0, 2**32, (n, 4), dtype=np.uint64).astype(np.uint32)
    node["parent"] = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    m = rng.random(n) < 0.05
    node["exp"][m, 3] |= np.uint8(0xF8 & (rng.integers(0, 256) | 0x08))
    node["rsvd"][rng.random(n) < 0.05] = 0xFFFFFFFF
    assert ((node["exp"][:, 3] & 7) == count).all() and Q8_COUNT_LSB == 24
    return node


def q8_requests(rng, n):
    """``n`` QUADBOX requests with ``FLAG_DECODE_Q8`` (see the module docstring)."""
    req = quadbox_requests(rng, n)
    req["box"] = random_bits(rng, (n, 4, 6))                   # words after the node: garbage
    with np.errstate(all="ignore"):
        o = np.where(np.isfinite(req["origin"]), req["origin"], F32(0)).astype(np.float64)
        d = req["dir"].astype(np.float64)
        ahead = o + rng.uniform(0, 5, (n, 1)) * d / np.abs(d).max(axis=1, keepdims=True)
    nodes = random_q8_nodes(rng, o, ahead)
    # half the rays are aimed at the centre of a used child box from outside it (a hit whose tmin
    # depends on the decoded planes)
    with np.errstate(all="ignore"):
        boxes = decode_q8(nodes).astype(np.float64)
        pick = boxes[np.arange(n), rng.integers(0, 4, n) % q8_count(nodes)]   # (n, 6)
        centre = (pick[:, :3] + pick[:, 3:]) / 2
        size = np.abs(pick[:, 3:] - pick[:, :3]).max(axis=1, keepdims=True)
        d = random_dirs(rng, n).astype(np.float64)
        o = centre - rng.uniform(0.6, 3, (n, 1)) * size * d / np.linalg.norm(d, axis=1,
                                                                             keepdims=True)
        aim = (rng.random(n) < 0.5) & np.isfinite(o).all(axis=1) & (size[:, 0] > 0)
        aim &= np.isfinite(o.astype(F32)).all(axis=1)
    if aim.any():
        rays = driver.prepare_rays(o[aim].astype(F32), d[aim].astype(F32))
        for f in ("origin", "dir", "inv", "kx", "ky", "kz", "shear", "extent"):
            req[f][aim] = rays[f]
    m = rng.random(n) < 0.03                                   # NaN / inf ray origins
    req["origin"][m, rng.integers(0, 3, m.sum())] = rng.choice(np.array([np.nan, INF, -INF], F32),
                                                                m.sum())
    req["qnode"] = nodes.view(np.uint32).reshape(n, 16)
    req["flags"] |= FLAG_DECODE_Q8
    return req


def q8_stream(seed, n_q8, n_box, n_tri):
    """q8 requests interleaved at random with QUADBOX/TRIANGLE requests."""
    rng = np.random.default_rng(seed)
    other = mixed_stream(seed + 7, n_box, n_tri)
    tri = np.flatnonzero(other["opcode"] == TRIANGLE)
    other["flags"][tri[rng.random(len(tri)) < 0.3]] |= FLAG_DECODE_Q8     # ignored by TRIANGLE
    stream, _ = interleave(rng, (q8_requests(rng, n_q8), other))
    return stream


# ----------------------------------------------------------------------------------------------
# EUCLIDEAN / ANGULAR

def random_vectors(rng, n, special=True):
    """(n, 16) a and b: mostly normal values at random scales, some special lanes."""
    scale = rng.choice([1e-3, 1, 10, 1e3], (n, 1)).astype(F32)
    a = (rng.normal(size=(n, 16)) * scale).astype(F32)
    b = (a + rng.normal(size=(n, 16)).astype(F32) * scale * F32(0.5)).astype(F32)
    if special:
        for x in (a, b):
            m = rng.random((n, 16)) < 0.02
            x[m] = rng.choice(np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-40, 1e-45, 3e19,
                                        -3e19], F32), m.sum())
            m = rng.random((n, 16)) < 0.005
            x[m] = random_bits(rng, m.sum())
    return a, b


def vector_requests(rng, op, lengths, special=True, masks=None):
    """One job per entry of ``lengths`` (beats), reset on each job's last beat."""
    n = int(sum(lengths))
    req = np.zeros(n, REQUEST_DTYPE)
    req["opcode"] = op
    req["vec_a"], req["vec_b"] = random_vectors(rng, n, special)
    req["vec_mask"] = rng.integers(0, 2**16, n) if masks is None else masks
    full = rng.random(n) < 0.3
    req["vec_mask"][full] = 0xFFFF
    req["reset_accumulator"][np.cumsum(lengths) - 1] = 1
    req["tag"] = np.arange(n)
    return req


# ----------------------------------------------------------------------------------------------
# mixing

def interleave(rng, parts):
    """Randomly interleave request arrays, keeping the order within each. Returns (stream, kind)."""
    kind = np.concatenate([np.full(len(p), k) for k, p in enumerate(parts)])
    kind = kind[rng.permutation(len(kind))]
    stream = np.zeros(len(kind), REQUEST_DTYPE)
    for k, p in enumerate(parts):
        stream[kind == k] = p
    return stream, kind


def extended_stream(seed, n_jobs=40, max_beats=12, n_box=300, n_tri=200):
    """``n_jobs`` EUCLIDEAN and ``n_jobs`` ANGULAR jobs of 1..``max_beats`` beats interleaved with
    ``mixed_stream(seed, n_box, n_tri)``, garbage in every ignored field. Returns (stream, kind)."""
    rng = np.random.default_rng(seed)
    e_jobs = vector_requests(rng, 2, rng.integers(1, max_beats + 1, n_jobs))
    a_jobs = vector_requests(rng, 3, rng.integers(1, max_beats + 1, n_jobs))
    other = mixed_stream(seed, n_box, n_tri)
    # box/triangle requests carry vector data and reset flags that must be ignored ...
    other["vec_a"], other["vec_b"] = random_vectors(rng, len(other))
    other["vec_mask"] = rng.integers(0, 2**16, len(other))
    other["reset_accumulator"] = rng.random(len(other)) < 0.5
    # ... and vector beats carry ray/box/triangle data that must be ignored
    for jobs in (e_jobs, a_jobs):
        donor = mixed_stream(seed + 1000, len(jobs), 0)
        for f in ("origin", "dir", "inv", "extent", "kx", "ky", "kz", "shear", "box", "tri"):
            jobs[f] = donor[f]
        m = rng.random(len(jobs)) < 0.1
        jobs["box"][m] = random_bits(rng, (m.sum(), 4, 6))
    return interleave(rng, (e_jobs, a_jobs, other))


# ----------------------------------------------------------------------------------------------
# TRANSFORM

def random_matrices(rng, n):
    """(n, 3, 4) float32 matrices: rotations with translations, random entries at random scales
    (huge and tiny: products overflow to inf and underflow to subnormals or zero), mirrors
    (negative determinant), zero and rank-deficient matrices, and entries that are +-0,
    subnormal, +-inf, NaN or random bit patterns."""
    kind = rng.integers(0, 6, n)
    m = (rng.normal(size=(n, 3, 4)) * 10.0 ** rng.uniform(-3, 3, (n, 1, 1))).astype(F32)
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))              # rotations or reflections
    m[kind == 0, :, :3] = q[kind == 0]
    huge = kind == 1
    m[huge] *= rng.choice(np.array([1e-30, 1e-20, 1e20, 1e30], F32), (huge.sum(), 1, 1))
    m[kind == 2, 0] *= F32(-1)                                   # mirror: det < 0
    m[kind == 3] = 0
    m[kind == 4, 2] = m[kind == 4, 0]                            # rank 2
    special = rng.random((n, 3, 4)) < 0.04
    m[special] = rng.choice(np.concatenate([SPECIALS, SUBNORMALS]), special.sum())
    bits = rng.random((n, 3, 4)) < 0.01
    m[bits] = random_bits(rng, bits.sum())
    return m


SPECIALS = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, -1.0, 3e38, -3e38], F32)


def random_ray_vectors(rng, n):
    """(n, 3) float32 origins or directions at random scales with special components (+-0,
    subnormal, +-inf, NaN, random bit patterns)."""
    v = (rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-20, 20, (n, 1))).astype(F32)
    special = rng.random((n, 3)) < 0.04
    v[special] = rng.choice(np.concatenate([SPECIALS, SUBNORMALS]), special.sum())
    bits = rng.random((n, 3)) < 0.01
    v[bits] = random_bits(rng, bits.sum())
    return v


def transform_requests_random(rng, n):
    """TRANSFORM requests of random matrices and rays, garbage in every field they ignore (the
    box words after the matrix, the triangle, the vectors, the ray's other fields)."""
    donor = mixed_stream(int(rng.integers(1 << 30)), n, 0)
    req = transform_requests(random_matrices(rng, n), random_ray_vectors(rng, n),
                             random_ray_vectors(rng, n))
    for f in ("inv", "extent", "kx", "ky", "kz", "shear", "tri"):
        req[f] = donor[f]
    req["flags"] = (rng.random(n) < 0.5) * FLAG_NO_CULL
    req["vec_a"], req["vec_b"] = random_vectors(rng, n)
    req["vec_mask"] = rng.integers(0, 2**16, n)
    req["reset_accumulator"] = rng.random(n) < 0.5
    return req


def transform_stream(seed, n_xf, n_box, n_tri):
    """TRANSFORM requests interleaved at random with QUADBOX/TRIANGLE requests."""
    rng = np.random.default_rng(seed)
    stream, _ = interleave(rng, (transform_requests_random(rng, n_xf),
                                 mixed_stream(seed + 11, n_box, n_tri)))
    return stream
