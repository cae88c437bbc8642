"""Golden (vectorised numpy) model vs the scalar reference bit for bit, and
docs/datapath.md#quadbox, #triangle special rules.

The random streams (``support.streams.mixed_stream``) mix QUADBOX and TRIANGLE requests drawn to hit
the corner cases; the directed requests are built as in the paper's cases (``support.cases``).
"""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import QUADBOX, TRIANGLE, EUCLIDEAN, ANGULAR, REQUEST_DTYPE, RESPONSE_DTYPE
from support.cases import box_request, tri_request
from support.scalar_ref import ScalarState, scalar_run
from support.scoreboard import assert_bit_equal
from support.streams import SUBNORMALS, mixed_stream, random_bits

F32 = np.float32
INF = np.inf


# ----------------------------------------------------------------------------------------------
# golden == scalar reference

@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_mixed_stream_bit_exact(seed):
    req = mixed_stream(seed, 3000, 2000)
    with np.errstate(all="ignore"):
        got = driver.backend("golden").run(req)
    want = scalar_run(req, ScalarState(extended=False))
    assert_bit_equal(req, got, want, "golden", "scalar")
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
    from support.scalar_ref import add, sub, mul, div
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
    assert_bit_equal(req, parts, whole, "golden in chunks", "golden in one run")


# ----------------------------------------------------------------------------------------------
# special rules (docs/datapath.md#quadbox, #triangle)

def both(req, extended=False):
    """Run on golden and on the scalar reference; assert they agree; return the golden responses."""
    got = driver.backend("golden", extended=extended).run(req)
    assert_bit_equal(req, got, scalar_run(req, ScalarState(extended=extended)), "golden",
                     "scalar")
    return got


def test_hit_tmin_is_plus_zero_never_minus_zero():
    # origin inside, near values negative -> max(.., +0) = +0; and an origin exactly on the min
    # plane of a negative-direction ray, where near = (max - o) * inv can come out -0
    cases = [box_request((0, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)]),
             box_request((1, 0, 0), (-1, 0, 0), [(-1, -1, -1, 1, 1, 1)]),
             box_request((1, 0.5, 0.5), (-1, -0.0, -0.0), [(0, 0, 0, 1, 1, 1)]),
             box_request((0, 0, 0), (-1, -2, -3), [(-1, -1, -1, 0, 0, 0)])]
    for r in cases:
        rsp = both(r)[0]
        assert rsp["box_hit"][0] and rsp["box_index"][0] == 0
        assert rsp["box_tmin"].view(np.uint32)[0] == 0, hex(rsp["box_tmin"].view(np.uint32)[0])


def test_miss_tmin_is_plus_inf_and_nan_slab_is_a_miss():
    # axis-parallel ray whose origin lies on a slab plane of a zero-direction axis: 0 * inf = NaN
    r = box_request((0, 1, 0), (1, 0, 0), [(-2, 1, -1, 2, 3, 1), (-2, -1, -1, 2, 1, 1),
                                       (-2, -2, -2, 2, 2, 2), (5, 5, 5, 6, 6, 6)])
    rsp = both(r)[0]
    # boxes 0 and 1 have y-slab plane at the origin -> NaN -> miss; box 2 hit at +0; 3 plain miss
    assert list(rsp["box_index"]) == [2, 0, 1, 3]
    assert list(rsp["box_hit"]) == [1, 0, 0, 0]
    assert rsp["box_tmin"][0] == 0
    assert (rsp["box_tmin"][1:].view(np.uint32) == 0x7F800000).all()
    # NaN box coordinate -> miss
    r = box_request((0, 0, 0), (1, 1, 1), [(np.nan, -1, -1, 1, 1, 1)])
    rsp = both(r)[0]
    assert not rsp["box_hit"].any() and np.isposinf(rsp["box_tmin"]).all()


def test_misses_sorted_last_in_index_order_and_ties_by_index():
    unit = (-1, -1, -1, 1, 1, 1)
    far = (10, -1, -1, 11, 1, 1)
    away = (-11, -1, -1, -10, 1, 1)
    r = box_request((-2, 0, 0), (1, 0, 0), [away, far, away, unit])
    rsp = both(r)[0]
    assert list(rsp["box_index"]) == [3, 1, 0, 2] and list(rsp["box_hit"]) == [1, 1, 0, 0]
    assert list(rsp["box_tmin"]) == [1, 12, INF, INF]
    # all four identical -> all tie -> index order
    rsp = both(box_request((-2, 0, 0), (1, 0, 0), [unit] * 4))[0]
    assert list(rsp["box_index"]) == [0, 1, 2, 3] and list(rsp["box_tmin"]) == [1] * 4
    # ties among a subset, the rest ordered around them
    rsp = both(box_request((-2, 0, 0), (1, 0, 0), [far, unit, far, unit]))[0]
    assert list(rsp["box_index"]) == [1, 3, 0, 2] and list(rsp["box_tmin"]) == [1, 1, 12, 12]
    # all eight orders of a permuted set: the comparator network sorts every permutation
    import itertools
    boxes = [unit, far, (0, -1, -1, 1, 1, 1), away]
    rows = np.concatenate([box_request((-2, 0, 0), (1, 0, 0), [boxes[p] for p in perm])
                           for perm in itertools.permutations(range(4))])
    rsp = both(rows)
    assert (rsp["box_tmin"] == np.array([1, 2, 12, INF], F32)).all()


def test_strict_compare_flat_box_and_extent():
    # zero-thickness box perpendicular to the ray: tmin == tmax -> miss (strict)
    rsp = both(box_request((-2, 0, 0), (1, 0, 0), [(1, -1, -1, 1, 1, 1)]))[0]
    assert not rsp["box_hit"].any()
    # extent cuts off: box entered at t = 1, extent 1 -> miss; extent 1.0000001 -> hit
    rsp = both(box_request((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)], extent=1))[0]
    assert not rsp["box_hit"].any()
    rsp = both(box_request((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)],
                       extent=np.nextafter(F32(1), F32(2))))[0]
    assert rsp["box_hit"][0]


def test_subnormals_not_flushed():
    """Bit patterns written as literals, so a flush-to-zero FPU mode cannot hide itself."""
    sub = np.array([0x000116C2], np.uint32).view(F32)[0]             # 1e-40, subnormal
    r = box_request((0, 0, 0), (1, 0, 0), [(0, -1, -1, 1, 1, 1)])
    r["box"][0, 0, 0] = sub                                           # box starts at x = 1e-40
    rsp = both(r)[0]
    assert rsp["box_hit"][0] and rsp["box_tmin"].view(np.uint32)[0] == 0x000116C2
    # triangle in the plane z = -2^-140: t_num = 4 * 2^-140 = 2^-138, subnormal
    tiny = np.array([0x00000200], np.uint32).view(F32)[0]             # 2^-140
    r = tri_request(((1, -1, 0), (0, 1, 0), (-1, -1, 0)), (0, 0, -1))
    r["tri"][0, :, 2] = -tiny
    rsp = both(r)[0]
    assert rsp["tri_hit"] and rsp["t_den"] == 4
    assert rsp["t_num"].view(np.uint32) == 0x00000800                # 4 * 2^-140 = 2^-138


def test_unused_fields_are_zero():
    front = ((1, -1, -1), (0, 1, -1), (-1, -1, -1))
    req = np.concatenate([tri_request(front, (0, 0, -1)),
                          box_request((-2, 0, 0), (1, 0, 0), [(-1, -1, -1, 1, 1, 1)])])
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
    rsp = both(np.concatenate([tri_request(front, (0, 0, -1)), tri_request(back, (0, 0, -1)),
                               tri_request(front, (1, 0, 0))]))
    assert rsp["tri_hit"].tolist() == [1, 0, 0]
    assert rsp[1]["t_den"] == -4 and rsp[1]["t_num"] == -4
    assert rsp[2]["t_den"] == 0                                      # parallel: t_den = 0 -> miss
    # NaN vertex -> canonical NaN outputs and a miss
    rsp = both(tri_request(((np.nan, -1, -1), (0, 1, -1), (-1, -1, -1)), (0, 0, -1)))[0]
    assert not rsp["tri_hit"]
    assert rsp["t_den"].view(np.uint32) == 0x7FC00000
    # a negative NaN payload input still comes out canonical
    nan_neg = np.array(0xFFC12345, np.uint32).view(F32)
    r = tri_request(front, (0, 0, -1))
    r["tri"][0, 0, 0] = nan_neg
    rsp = both(r)[0]
    assert rsp["t_den"].view(np.uint32) == 0x7FC00000 and rsp["t_num"].view(np.uint32) == 0x7FC00000
    # triangle behind the origin: t_num < 0 -> miss
    rsp = both(tri_request(front, (0, 0, 1), origin=(0, 0, -5)))[0]
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
