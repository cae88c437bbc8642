"""The FUSED build (docs/tradeoffs.md#forgoing-rounding): the box slab value and the triangle's
edge functions rounded once.

- the golden model's one-rounding operations (``sum_of_products``, ``slab``) against exact rational
  arithmetic (``fractions.Fraction``) on random, subnormal, cancelling, tie and special operands;
- the RTL of the FUSED builds against that golden model bit for bit on the random streams under
  random back-pressure, as every configuration is checked;
- directed requests whose results differ between the fused and today's datapath (the RTL gives the
  fused value, the golden model of today's the other);
- how many hits change on a small scene, each change adjudicated (``driver.adjudicate``).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import driver
from driver import QUADBOX, TRIANGLE
from driver.core.configs import FUSED_SUFFIX, parse_config
from driver.core.golden import slab, sum_of_products
from driver.design import DesignPoint
from support.streams import extended_stream, mixed_stream
from support.testbench import PRESSURE_IDS, PRESSURES, Testbench

F32 = np.float32
U32 = np.uint32


def bits(x) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x, F32)).view(U32)


def rne32(x: Fraction) -> F32:
    """The binary32 nearest to the exact non-zero rational x (ties to even; overflow to inf)."""
    a = abs(x)
    if a >= Fraction(2**128) - Fraction(2**103):
        m = F32(np.inf)
    else:
        e = max(a.numerator.bit_length() - a.denominator.bit_length(), -126)
        while Fraction(2) ** e > a:                 # 2^e <= a < 2^(e+1), or the subnormal grid
            e -= 1
        while Fraction(2) ** (e + 1) <= a:
            e += 1
        ulp = Fraction(2) ** (max(e, -126) - 23)
        q, r = divmod(a, ulp)
        q = int(q) + (1 if r > ulp / 2 or (r == ulp / 2 and q % 2) else 0)
        m = F32(float(q * ulp))
    return -m if x < 0 else m


def operands(rng, n):
    """Random binary32 operands: random bits (finite), normals near 1, subnormals, small integers."""
    kind = rng.integers(0, 4, n)
    x = rng.integers(0, 2**32, n, dtype=np.uint64).astype(U32).view(F32).copy()
    x[~np.isfinite(x)] = F32(1.5)
    x[kind == 1] = rng.standard_normal((kind == 1).sum()).astype(F32)
    sub = rng.integers(1, 2**23, n, dtype=np.uint64).astype(U32) | (bits(x) & U32(0x80000000))
    x[kind == 2] = sub.view(F32)[kind == 2]
    x[kind == 3] = rng.choice(np.array([1, 2, 3, 0.5, 1.5, -1, -0.75], F32), (kind == 3).sum())
    return x


def check_exact(got, exact_values):
    bad = [(i, v) for i, v in enumerate(exact_values)
           if v is not None and bits(rne32(v)) != bits(got[i])]
    assert not bad, f"{len(bad)} wrong, first at {bad[0][0]}: want {rne32(bad[0][1])!r}"


def test_sum_of_products_is_one_rounding():
    rng = np.random.default_rng(1)
    a, b, c, d = (operands(rng, 3000) for _ in range(4))
    near = rng.random(3000) < 0.4                     # near-cancellation: c*d ~ -a*b
    c[near], d[near] = -a[near], np.nextafter(b[near], F32(np.inf))
    # exact ties: 1 + 2^-23 + 2^-24 (to even: up) and 1 + 2^-24 (down), then a hair off each
    a[:4] = [1 + 2**-23, 1, 1 + 2**-23, 1]
    b[:4] = 1
    c[:4] = [2**-24, 2**-24, 2**-24 + 2**-47, 2**-24 + 2**-47]
    d[:4] = 1
    with np.errstate(all="ignore"):
        got = sum_of_products(a, b, c, d)
    exact = [Fraction(float(a[i])) * Fraction(float(b[i]))
             + Fraction(float(c[i])) * Fraction(float(d[i])) for i in range(len(a))]
    check_exact(got, [x or None for x in exact])
    assert list(bits(got[:4])) == list(bits([1 + 2**-22, 1, 1 + 2**-22, 1 + 2**-23]))


def test_slab_is_one_rounding():
    rng = np.random.default_rng(2)
    b, o, m = (operands(rng, 3000) for _ in range(3))
    with np.errstate(all="ignore"):
        got = slab(b, o, m)
    exact = [(Fraction(float(b[i])) - Fraction(float(o[i]))) * Fraction(float(m[i]))
             for i in range(len(b))]
    check_exact(got, [x or None for x in exact])


def test_special_values_as_ieee():
    """Non-finite and zero results as the IEEE expressions give them (float64 is exact there)."""
    inf, nan = np.inf, np.nan
    b = np.array([1, inf, inf, -inf, 2, 2, 0, -0.0, -0.0, 1, nan, 3], F32)
    o = np.array([1, inf, -inf, 5, 2, 1, -0.0, 0, -0.0, 2, 0, 3], F32)
    m = np.array([inf, 1, 0, -2, -0.0, inf, 1, 1, 1, 0, 1, -1], F32)
    with np.errstate(all="ignore"):
        got = slab(b, o, m)
        want = ((b.astype(np.float64) - o) * m).astype(F32)
    assert (bits(np.where(np.isnan(got), nan, got)) == bits(np.where(np.isnan(want), nan, want))
            ).all()
    with np.errstate(all="ignore"):
        got = sum_of_products(np.array([inf, 0, -0.0, 1, inf], F32), np.array([1, inf, 1, 1, 1], F32),
                              np.array([-inf, 1, -0.0, -1, 1], F32), np.array([1, 1, 1, 1, 1], F32))
    assert np.isnan(got[0]) and np.isnan(got[1])
    assert list(bits(got[2:])) == list(bits([-0.0, 0.0, inf]))


def test_config_names():
    assert parse_config("extended-disjoint-q8-fused") == {
        "EXTENDED": 1, "DISJOINT": 1, "COMPRESSED": 1, "FUSED": 1}
    assert parse_config("baseline-unified" + FUSED_SUFFIX) == {
        "EXTENDED": 0, "DISJOINT": 0, "FUSED": 1}
    assert parse_config("baseline-unified-fused-q8") is None       # suffixes in their order
    assert parse_config("fused") is None
    p = DesignPoint(config="baseline-unified-q8-fused")
    assert p.fused and p.compressed and not p.extended and p.latency == 12
    assert p.rtl_params()["FUSED"] == 1 and "FUSED" not in DesignPoint().rtl_params()
    with pytest.raises(ValueError, match="--config: unknown value 'baseline-fused'"):
        DesignPoint(config="baseline-fused")


# ----------------------------------------------------------------------------------------------
# the RTL of the FUSED builds vs its golden model

@pytest.mark.parametrize("gaps,stalls", [PRESSURES[0], PRESSURES[3], PRESSURES[5]],
                         ids=[PRESSURE_IDS[0], PRESSURE_IDS[3], PRESSURE_IDS[5]])
def test_rtl_fused_random(gaps, stalls):
    req = mixed_stream(11, 3000, 2000)
    rsp = Testbench("rtl", fused=True, gaps=gaps, stalls=stalls, seed=11).run(req)
    assert 0.2 < rsp["box_hit"][req["opcode"] == QUADBOX].mean() < 0.8
    assert 0.1 < rsp["tri_hit"][req["opcode"] == TRIANGLE].mean() < 0.7


# extended-disjoint-fused bounds the extended builds in the default suite; extended-unified-fused,
# a Verilator model of its own, runs with -m slow.
@pytest.mark.parametrize("disjoint", [pytest.param(False, marks=pytest.mark.slow), True],
                         ids=["unified", "disjoint"])
def test_rtl_fused_extended_random(disjoint):
    req, _ = extended_stream(12, n_jobs=20, n_box=1500, n_tri=1000)
    Testbench("rtl", extended=True, disjoint=disjoint, fused=True, gaps=0.5, stalls=0.5,
              seed=12).run(req)


RESULTS = ("box_tmin", "box_hit", "box_index", "tri_hit", "t_num", "t_den")


def differing(a, b):
    """Per row: whether responses a and b differ in a result field (bit for bit)."""
    differ = np.zeros(len(a), bool)
    for f in RESULTS:
        x, y = np.ascontiguousarray(a[f]), np.ascontiguousarray(b[f])
        differ |= (x.view(np.uint8).reshape(len(a), -1)
                   != y.view(np.uint8).reshape(len(a), -1)).any(axis=1)
    return differ


def edge_requests(x, y):
    """TRIANGLEs whose X and Y are the given (n, 3) vertex coordinates exactly (origin 0, shear
    (0, 0, 1), kx ky kz = x y z: X = P'x - 0*P'z), vertex A at X = Y = 0 so that V and W are
    zeros and t_den = U."""
    n = len(x)
    req = np.zeros(n, driver.REQUEST_DTYPE)
    req["opcode"] = TRIANGLE
    req["kx"], req["ky"], req["kz"] = 0, 1, 2
    req["shear"] = [0, 0, 1]
    req["tri"][:, :, 0], req["tri"][:, :, 1], req["tri"][:, :, 2] = x, y, 1
    req["tri"][:, 0, :2] = 0
    return req


def test_rtl_fused_directed_differences():
    """Requests where one rounding gives other results than two: the RTL gives the fused ones."""
    # U = Cx*By - Cy*Bx = (1 + 2^-12)^2 - (1 + 2^-11) = 2^-24 exactly; today's products round
    # (1 + 2^-12)^2 to 1 + 2^-11 and U to 0
    e = 2.0 ** -12
    x = np.array([[0, 1, 1 + e]], F32)
    y = np.array([[0, 1 + e, 1 + 2 * e]], F32)
    tri = edge_requests(x, y)
    # boxes and triangles of the random stream whose fused results differ
    rng_req = mixed_stream(13, 4000, 4000)
    rows = np.flatnonzero(differing(driver.backend("golden", fused=True).run(rng_req),
                                    driver.backend("golden").run(rng_req)))
    req = np.concatenate([tri, rng_req[rows]])
    assert (rng_req["opcode"][rows] == QUADBOX).sum() > 10
    assert (rng_req["opcode"][rows] == TRIANGLE).sum() > 10
    fused = driver.backend("golden", fused=True).run(req)
    plain = driver.backend("golden").run(req)
    assert bits(fused["t_den"][0]) == bits(2.0 ** -24) and plain["t_den"][0] == 0
    rsp = Testbench("rtl", fused=True, gaps=0.3, stalls=0.3, seed=13).run(req)
    assert bits(rsp["t_den"][0]) == bits(2.0 ** -24)
    assert differing(rsp, plain).all()


def test_hits_changed_small_scene():
    """Hits that change with the fused datapath on a small closed mesh, rays aimed at its vertices
    and edges (where rounding decides), each change adjudicated: some change, none is a wrong
    hit (the exact float64 adjudication calls each one a tie at an edge or vertex)."""
    from driver.adjudicate import adjudicate
    from support.meshes import icosphere
    tris = icosphere(3).astype(F32)
    rng = np.random.default_rng(14)
    n = 20000
    k = rng.integers(0, len(tris), n)
    a, b = tris[k, 0].astype(np.float64), tris[k, 1].astype(np.float64)
    w = np.where(rng.random(n) < 0.3, 0, rng.random(n))[:, None]     # vertices and edge points
    o = rng.normal(size=(n, 3)) * 3
    d = a + (b - a) * w - o
    fused = driver.trace(tris, o, d, backend=driver.backend("golden", fused=True))
    plain = driver.trace(tris, o, d, backend="golden")
    assert fused.hit.mean() > 0.9
    changed = np.flatnonzero(fused.prim != plain.prim)
    assert 0 < len(changed) < n // 1000
    v = adjudicate(tris, o, d, np.inf, (fused.t, fused.prim), (plain.t, plain.prim), False, False,
                   float(np.abs(tris).max()), rays=changed)
    counts = v.counts()
    assert counts["datapath_wrong"] == 0, v.records
    assert counts["edge_tie"] + counts["embree_wrong"] == len(changed)
