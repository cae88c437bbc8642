"""Golden (vectorised numpy) model vs the scalar reference bit for bit, and SPEC 4/5 special rules.

The random streams mix QUADBOX and TRIANGLE requests drawn to hit the corner cases: axis-parallel
rays (exact +-0 components), origins on slab planes, boxes around / near / containing the origin,
degenerate and inverted boxes, duplicated boxes (tmin ties), triangles aimed at (interior, edge,
vertex, both windings), coplanar rays, degenerate triangles, NaN / inf / subnormal inputs and raw
random bit patterns.
"""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import QUADBOX, TRIANGLE, EUCLIDEAN, ANGULAR, REQUEST_DTYPE, RESPONSE_DTYPE
from scalar_ref import ScalarState, scalar_run

F32 = np.float32
INF = np.inf
SUBNORMALS = np.array([1e-45, 1e-40, 1e-39, 5e-39, 1.1754942e-38], F32)   # all below 2^-126


# ----------------------------------------------------------------------------------------------
# comparison helper

def _bits(a):
    a = np.ascontiguousarray(a)
    if a.dtype.kind == "f":
        return a.view(np.uint32)
    return a


def hexrow(row) -> str:
    """A request row with every float shown as its uint32 hex pattern (for failure reports)."""
    parts = []
    for name in row.dtype.names:
        v = np.asarray(row[name])
        if v.dtype.kind == "f":
            v = np.vectorize(lambda x: f"{x:08x}")(v.view(np.uint32))
        parts.append(f"{name}={v.tolist()}")
    return " ".join(parts)


def assert_bit_equal(req, got, want):
    """Every field of every response equal bit for bit; on failure name the first bad request."""
    assert got.dtype == RESPONSE_DTYPE and want.dtype == RESPONSE_DTYPE
    assert len(got) == len(want) == len(req)
    for name in RESPONSE_DTYPE.names:
        g, w = _bits(got[name]), _bits(want[name])
        bad = g != w
        if bad.ndim > 1:
            bad = bad.reshape(len(bad), -1).any(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            pytest.fail(f"{int(bad.sum())} mismatches in field {name!r}; first at request {i}:\n"
                        f"  golden: {got[i]}\n  scalar: {want[i]}\n"
                        f"  golden bits {np.asarray(g[i]).tolist()}"
                        f" scalar bits {np.asarray(w[i]).tolist()}\n"
                        f"  request: {hexrow(req[i])}")


# ----------------------------------------------------------------------------------------------
# random request generators

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
    # the sign of dir (SPEC 4), the products use inv as given
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
# golden == scalar reference

@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_mixed_stream_bit_exact(seed):
    req = mixed_stream(seed, 3000, 2000)
    with np.errstate(all="ignore"):
        got = driver.backend("golden").run(req)
    want = scalar_run(req, ScalarState(extended=False))
    assert_bit_equal(req, got, want)
    # the stream really covers the interesting cases
    box = want[want["opcode"] == QUADBOX]
    tri = want[want["opcode"] == TRIANGLE]
    hits = box["box_hit"].astype(bool)
    assert hits.mean() > 0.2
    assert (box["box_tmin"][hits] == 0).sum() > 50                        # zero-distance hits
    ties = (box["box_tmin"][:, 1:] == box["box_tmin"][:, :-1]) & hits[:, 1:]
    assert ties.any(axis=1).sum() > 20                                     # tie ordering exercised
    assert (hits.sum(axis=1) == 4).any() and (hits.sum(axis=1) == 0).any()
    assert 0.1 < tri["tri_hit"].mean() < 0.7
    assert np.isnan(tri["t_num"]).any() and np.isnan(tri["t_den"]).any()
    assert ((tri["t_num"] == 0) & (tri["tri_hit"] == 1)).sum() > 20       # t = 0 hits


def test_scalar_f32_ops_are_single_roundings():
    """The scalar reference's float32 scalar ops round once (checked against exact double results
    rounded to float32, which is innocuous double rounding for + - * /), subnormals kept."""
    from scalar_ref import add, sub, mul, div
    rng = np.random.default_rng(7)
    a = random_bits(rng, 3000)
    b = random_bits(rng, 3000)
    a[:500] = rng.choice(SUBNORMALS, 500) * rng.choice([-1, 1], 500)
    b[500:1000] = rng.uniform(0.5, 2, 500).astype(F32)
    with np.errstate(all="ignore"):
        for op, ref in ((add, np.add), (sub, np.subtract), (mul, np.multiply), (div, np.divide)):
            want = ref(a.astype(np.float64), b.astype(np.float64)).astype(F32)
            got = np.array([op(x, y) for x, y in zip(a, b)], F32)
            same = (got.view(np.uint32) == want.view(np.uint32)) | (np.isnan(got) & np.isnan(want))
            assert same.all(), (op.__name__, a[~same][:3], b[~same][:3])
    assert mul(F32(1e-30), F32(1e-30)) == 0                                # underflow to 0
    assert mul(F32(1e-20), F32(1e-20)) == F32(1e-40) != 0                 # subnormal, not flushed
    assert mul(F32(2 ** -70), F32(2 ** -70)) == F32(2.0 ** -140)           # subnormal, not flushed


def test_golden_is_stateless_across_runs_and_chunking():
    req = mixed_stream(11, 300, 200)
    g = driver.backend("golden")
    with np.errstate(all="ignore"):
        whole = g.run(req)
        parts = np.concatenate([g.run(req[:1]), g.run(req[1:250]), g.run(req[250:])])
    assert_bit_equal(req, parts, whole)


# ----------------------------------------------------------------------------------------------
# special rules (SPEC 4, 5)

def box_req(origin, direction, boxes, extent=INF):
    r = driver.prepare_rays([origin], [direction], extent)
    r["opcode"] = QUADBOX
    r["box"][0] = np.array(list(boxes) + [(INF,) * 6] * (4 - len(boxes)), F32)
    return r


def both(req, extended=False):
    """Run on golden and on the scalar reference; assert they agree; return the golden responses."""
    got = driver.backend("golden", extended=extended).run(req)
    assert_bit_equal(req, got, scalar_run(req, ScalarState(extended=extended)))
    return got


def test_hit_tmin_is_plus_zero_never_minus_zero():
    # origin inside, near values negative -> max(.., +0) = +0; and an origin exactly on the min
    # plane of a negative-direction ray, where near = (max - o) * inv can come out -0
    cases = [box_req((0, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)]),
             box_req((1, 0, 0), (-1, 0, 0), [(-1, -1, -1, 1, 1, 1)]),
             box_req((1, 0.5, 0.5), (-1, -0.0, -0.0), [(0, 0, 0, 1, 1, 1)]),
             box_req((0, 0, 0), (-1, -2, -3), [(-1, -1, -1, 0, 0, 0)])]
    for r in cases:
        rsp = both(r)[0]
        assert rsp["box_hit"][0] and rsp["box_index"][0] == 0
        assert rsp["box_tmin"].view(np.uint32)[0] == 0, hex(rsp["box_tmin"].view(np.uint32)[0])


def test_miss_tmin_is_plus_inf_and_nan_slab_is_a_miss():
    # axis-parallel ray whose origin lies on a slab plane of a zero-direction axis: 0 * inf = NaN
    r = box_req((0, 1, 0), (1, 0, 0), [(-2, 1, -1, 2, 3, 1), (-2, -1, -1, 2, 1, 1),
                                       (-2, -2, -2, 2, 2, 2), (5, 5, 5, 6, 6, 6)])
    rsp = both(r)[0]
    # boxes 0 and 1 have y-slab plane at the origin -> NaN -> miss; box 2 hit at +0; 3 plain miss
    assert list(rsp["box_index"]) == [2, 0, 1, 3]
    assert list(rsp["box_hit"]) == [1, 0, 0, 0]
    assert rsp["box_tmin"][0] == 0
    assert (rsp["box_tmin"][1:].view(np.uint32) == 0x7F800000).all()
    # NaN box coordinate -> miss
    r = box_req((0, 0, 0), (1, 1, 1), [(np.nan, -1, -1, 1, 1, 1)])
    rsp = both(r)[0]
    assert not rsp["box_hit"].any() and np.isposinf(rsp["box_tmin"]).all()


def test_misses_sorted_last_in_index_order_and_ties_by_index():
    unit = (-1, -1, -1, 1, 1, 1)
    far = (10, -1, -1, 11, 1, 1)
    away = (-11, -1, -1, -10, 1, 1)
    r = box_req((-2, 0, 0), (1, 0, 0), [away, far, away, unit])
    rsp = both(r)[0]
    assert list(rsp["box_index"]) == [3, 1, 0, 2] and list(rsp["box_hit"]) == [1, 1, 0, 0]
    assert list(rsp["box_tmin"]) == [1, 12, INF, INF]
    # all four identical -> all tie -> index order
    rsp = both(box_req((-2, 0, 0), (1, 0, 0), [unit] * 4))[0]
    assert list(rsp["box_index"]) == [0, 1, 2, 3] and list(rsp["box_tmin"]) == [1] * 4
    # ties among a subset, the rest ordered around them
    rsp = both(box_req((-2, 0, 0), (1, 0, 0), [far, unit, far, unit]))[0]
    assert list(rsp["box_index"]) == [1, 3, 0, 2] and list(rsp["box_tmin"]) == [1, 1, 12, 12]
    # all eight orders of a permuted set: the comparator network sorts every permutation
    import itertools
    boxes = [unit, far, (0, -1, -1, 1, 1, 1), away]
    rows = np.concatenate([box_req((-2, 0, 0), (1, 0, 0), [boxes[p] for p in perm])
                           for perm in itertools.permutations(range(4))])
    rsp = both(rows)
    assert (rsp["box_tmin"] == np.array([1, 2, 12, INF], F32)).all()


def test_strict_compare_flat_box_and_extent():
    # zero-thickness box perpendicular to the ray: tmin == tmax -> miss (strict)
    rsp = both(box_req((-2, 0, 0), (1, 0, 0), [(1, -1, -1, 1, 1, 1)]))[0]
    assert not rsp["box_hit"].any()
    # extent cuts off: box entered at t = 1, extent 1 -> miss; extent 1.0000001 -> hit
    rsp = both(box_req((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)], extent=1))[0]
    assert not rsp["box_hit"].any()
    rsp = both(box_req((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)],
                       extent=np.nextafter(F32(1), F32(2))))[0]
    assert rsp["box_hit"][0]


def test_subnormals_not_flushed():
    """Bit patterns written as literals, so a flush-to-zero FPU mode cannot hide itself."""
    sub = np.array([0x000116C2], np.uint32).view(F32)[0]             # 1e-40, subnormal
    r = box_req((0, 0, 0), (1, 0, 0), [(0, -1, -1, 1, 1, 1)])
    r["box"][0, 0, 0] = sub                                           # box starts at x = 1e-40
    rsp = both(r)[0]
    assert rsp["box_hit"][0] and rsp["box_tmin"].view(np.uint32)[0] == 0x000116C2
    # triangle in the plane z = -2^-140: t_num = 4 * 2^-140 = 2^-138, subnormal
    tiny = np.array([0x00000200], np.uint32).view(F32)[0]             # 2^-140
    r = tri_req(((1, -1, 0), (0, 1, 0), (-1, -1, 0)), (0, 0, -1))
    r["tri"][0, :, 2] = -tiny
    rsp = both(r)[0]
    assert rsp["tri_hit"] and rsp["t_den"] == 4
    assert rsp["t_num"].view(np.uint32) == 0x00000800                # 4 * 2^-140 = 2^-138


def tri_req(tri, direction, origin=(0, 0, 0), extent=4000):
    r = driver.prepare_rays([origin], [direction], extent)
    r["opcode"] = TRIANGLE
    r["tri"][0] = np.array(tri, F32)
    return r


def test_unused_fields_are_zero():
    front = ((1, -1, -1), (0, 1, -1), (-1, -1, -1))
    req = np.concatenate([tri_req(front, (0, 0, -1)),
                          box_req((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)])])
    req["vec_a"] = 1.5
    req["vec_mask"] = 0xFFFF
    req["reset_accumulator"] = 1
    for ext in (False, True):
        rsp = both(req, extended=ext)
        t, b = rsp[0], rsp[1]
        assert t["tri_hit"] == 1 and (t["t_num"], t["t_den"]) == (4, 4)
        for name in ("box_index", "box_hit", "box_tmin", "euclid_acc", "euclid_last",
                     "angular_dot", "angular_norm", "angular_last"):
            assert not np.atleast_1d(t[name]).view(np.uint8).any(), name
        for name in ("tri_hit", "t_num", "t_den", "euclid_acc", "euclid_last", "angular_dot",
                     "angular_norm", "angular_last"):
            assert not np.atleast_1d(b[name]).view(np.uint8).any(), name
        assert list(rsp["opcode"]) == [TRIANGLE, QUADBOX]


def test_triangle_rules():
    front = ((1, -1, -1), (0, 1, -1), (-1, -1, -1))
    back = (front[0], front[2], front[1])
    # t_num/t_den output on a miss too (back face: the same plane, U, V, W negative)
    rsp = both(np.concatenate([tri_req(front, (0, 0, -1)), tri_req(back, (0, 0, -1)),
                               tri_req(front, (1, 0, 0))]))
    assert rsp["tri_hit"].tolist() == [1, 0, 0]
    assert rsp[1]["t_den"] == -4 and rsp[1]["t_num"] == -4
    assert rsp[2]["t_den"] == 0                                      # parallel: t_den = 0 -> miss
    # NaN vertex -> canonical NaN outputs and a miss
    rsp = both(tri_req(((np.nan, -1, -1), (0, 1, -1), (-1, -1, -1)), (0, 0, -1)))[0]
    assert not rsp["tri_hit"]
    assert rsp["t_den"].view(np.uint32) == 0x7FC00000
    # a negative NaN payload input still comes out canonical
    nan_neg = np.array(0xFFC12345, np.uint32).view(F32)
    r = tri_req(front, (0, 0, -1))
    r["tri"][0, 0, 0] = nan_neg
    rsp = both(r)[0]
    assert rsp["t_den"].view(np.uint32) == 0x7FC00000 and rsp["t_num"].view(np.uint32) == 0x7FC00000
    # triangle behind the origin: t_num < 0 -> miss
    rsp = both(tri_req(front, (0, 0, 1), origin=(0, 0, -5)))[0]
    assert not rsp["tri_hit"]


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_extended_opcode_on_baseline_raises(op):
    g = driver.backend("golden")
    req = np.zeros(3, REQUEST_DTYPE)
    req["opcode"] = [QUADBOX, op, TRIANGLE]
    with pytest.raises(driver.DatapathError):
        g.run(req)
    with pytest.raises(driver.DatapathError):
        scalar_run(req, ScalarState(extended=False))
    assert g.cycles == 0                                           # nothing ran
    # the same stream is fine on an extended build
    rsp = driver.backend("golden", extended=True).run(req)
    assert list(rsp["opcode"]) == [QUADBOX, op, TRIANGLE]


def test_cycles_n_plus_latency_per_run():
    g = driver.backend("golden")
    assert g.cycles == 0
    g.run(np.zeros(0, REQUEST_DTYPE))
    assert g.cycles == 0
    req = mixed_stream(5, 30, 20)
    with np.errstate(all="ignore"):
        g.run(req)
        assert g.cycles == 50 + 11
        g.run(req[:1])
        assert g.cycles == 50 + 11 + 1 + 11
        g.run(req[:0])
    assert g.cycles == 50 + 11 + 1 + 11
    assert driver.LATENCY == 11
    s = ScalarState(extended=False)
    scalar_run(req, s)
    scalar_run(req[:0], s)
    assert s.cycles == 61
    rsp = driver.backend("golden").run(np.zeros(0, REQUEST_DTYPE))
    assert rsp.dtype == RESPONSE_DTYPE and len(rsp) == 0


def test_tag_carried_through():
    req = mixed_stream(6, 20, 20)
    req["tag"] = np.arange(40, dtype=np.uint32) * 0x9E3779B1
    with np.errstate(all="ignore"):
        rsp = driver.backend("golden").run(req)
    assert (rsp["tag"] == req["tag"]).all()
    assert (rsp["opcode"] == req["opcode"]).all()
