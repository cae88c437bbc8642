"""The TRANSFORM operation (docs/transform.md): a ray (origin, dir) and a 3x4 matrix in, o' and d'
out, every product and sum rounded to float32 in the one order
``o'[r] = ((m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]) + m[r][3]``,
``d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]``.

Golden model (``driver.core.golden.transform``), the fast RTL harness ("rtl"), pyverilator and the
scalar reference, bit for bit, through the testbench (driver, monitor, golden scoreboard):
directed matrices (identity, pure translation, rotation, mirror, zero), random matrices and rays
(huge and tiny scales, negative determinants, zero and rank-2 matrices, +-0, subnormals, NaN,
inf, random bit patterns) in streams that interleave TRANSFORM with QUADBOX/TRIANGLE (q8
QUADBOXes on COMPRESSED builds, EUCLIDEAN/ANGULAR beats on extended ones) under gaps and stalls,
in every configuration with TRANSFORM; the wire overlay of ``matrix`` on ``box``; the builds
without it reject the opcode in every backend; latency and throughput unchanged.
"""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import QUADBOX, TRIANGLE, DatapathError
from driver.core import golden
from driver.core.datapath import run_transform, transform_requests, transform_results
from driver.core.wire import (MATRIX_SHAPE, OPCODES, REQUEST, REQUEST_DTYPE, TRANSFORM,
                              carries_matrix, pack_requests, unpack_requests)
from support.scalar_ref import ScalarState, scalar_run
from support.scoreboard import assert_bit_equal, bits
from support.streams import (extended_stream, interleave, q8_requests, random_matrices,
                             random_ray_vectors, transform_requests_random, transform_stream)
from support.testbench import (PRESSURE_IDS, PRESSURES, Testbench, assert_pyverilator_equals_rtl,
                               run_isolated)

F32 = np.float32
# (extended, disjoint, compressed): every configuration, each with TRANSFORM
CONFIGS = [(e, d, c) for c in (False, True) for e in (False, True) for d in (False, True)]
CONFIG_IDS = [f"{'extended' if e else 'baseline'}-{'disjoint' if d else 'unified'}"
              f"{'-q8' if c else ''}-xf" for e, d, c in CONFIGS]
FAST_PRESSURES = [(0.0, 0.0), (0.5, 0.5)]
# The default suite streams through the two builds that bound the others (no option, every
# option); each build is a Verilator model of its own, compiled on first use (~1 min), so the
# other six run with -m slow (test_random_stream_rtl_all_pressures runs all eight).
DEFAULT_CONFIGS = [(False, False, False), (True, True, True)]
CONFIG_PARAMS = [pytest.param(*c, id=i, marks=() if c in DEFAULT_CONFIGS else pytest.mark.slow)
                 for c, i in zip(CONFIGS, CONFIG_IDS)]


def reference_transform(m, o, d):
    """The transform in float64 of float32 steps, written out (independent of golden.transform)."""
    m, o, d = (np.asarray(x, F32) for x in (m, o, d))
    o2, d2 = np.zeros((len(o), 3), F32), np.zeros((len(o), 3), F32)
    for r in range(3):
        p = [F32(m[:, r, c] * o[:, c]) for c in range(3)]
        o2[:, r] = F32(F32(F32(p[0] + p[1]) + p[2]) + m[:, r, 3])
        q = [F32(m[:, r, c] * d[:, c]) for c in range(3)]
        d2[:, r] = F32(F32(q[0] + q[1]) + q[2])
    return o2, d2


# ----------------------------------------------------------------------------------------------
# the operation on the wire, the checks, the golden model

def test_opcode_and_overlay_on_the_wire():
    assert OPCODES["TRANSFORM"] == TRANSFORM == 4 and REQUEST.field["opcode"].bits == 3
    mat, box = REQUEST.field["matrix"], REQUEST.field["box"]
    assert mat.overlays == "box" and mat.word == box.word and mat.count == 12
    m = np.arange(12, dtype=F32).reshape(MATRIX_SHAPE) + 1
    req = transform_requests(m, [[1, 2, 3]], [[4, 5, 6]])
    words = pack_requests(req)
    # word 15 + 4r + c is m[r][c]; the box words after the matrix stay the box's (zero here)
    assert np.array_equal(words[0, 15:27].view(F32), m.ravel())
    assert carries_matrix(req).all() and not words[0, 27:39].any()
    back = unpack_requests(words)
    assert bits(back["matrix"]).tobytes() == bits(req["matrix"]).tobytes()
    quad = req.copy()
    quad["opcode"] = QUADBOX                     # a QUADBOX puts its box there, not a matrix
    quad["box"] = 7.0
    assert (pack_requests(quad)[0, 15:39].view(F32) == 7).all()


def test_builds_without_transform_reject_it():
    req = transform_requests(np.eye(3, 4), [[0, 0, 0]], [[0, 0, 1]])
    for opts in ({}, {"extended": True}, {"compressed": True}):
        with pytest.raises(DatapathError, match="TRANSFORM needs"):
            driver.backend("golden", **opts).run(req)
    with pytest.raises(DatapathError, match="TRANSFORM needs"):
        driver.backend("rtl").run(req)
    with pytest.raises(DatapathError):
        scalar_run(req, ScalarState(transform=False))
    bad = req.copy()
    bad["opcode"] = 5
    with pytest.raises(DatapathError, match="not an opcode"):
        driver.backend("golden", transform=True).run(bad)


def test_pyverilator_without_transform_rejects_it():
    req = transform_requests(np.eye(3, 4), [[0, 0, 0]], [[0, 0, 1]])
    with pytest.raises(DatapathError, match="TRANSFORM needs"):
        run_isolated("pyverilator", {}, [req])


def test_request_and_result_helpers():
    m = random_matrices(np.random.default_rng(1), 5)
    o = np.ones((5, 3), F32)
    req = transform_requests(m, o, -o, tag=np.arange(5) + 10)
    assert (req["opcode"] == TRANSFORM).all() and list(req["tag"]) == list(range(10, 15))
    assert transform_requests(np.eye(3, 4), o, o)["matrix"].shape == (5, 3, 4)
    with pytest.raises(ValueError, match="matrices must be"):
        transform_requests(np.eye(3), o, o)
    with pytest.raises(ValueError, match="differ in shape"):
        transform_requests(m, o, o[:3])
    rsp = driver.backend("golden", transform=True).run(req)
    o2, d2 = transform_results(rsp)
    want = golden.transform(m, o, -o)
    assert bits(o2).tobytes() == bits(golden.canonical(want[0])).tobytes()
    assert bits(d2).tobytes() == bits(golden.canonical(want[1])).tobytes()
    o3, d3 = run_transform(driver.backend("golden", transform=True), m, o, -o)
    assert bits(o3).tobytes() == bits(o2).tobytes() and bits(d3).tobytes() == bits(d2).tobytes()
    rsp["opcode"][2] = TRIANGLE
    with pytest.raises(DatapathError, match="response 2"):
        transform_results(rsp)


def test_golden_transform_is_the_order_of_the_operation():
    rng = np.random.default_rng(2)
    m, o, d = random_matrices(rng, 5000), random_ray_vectors(rng, 5000), random_ray_vectors(rng,
                                                                                         5000)
    got = golden.transform(m, o, d)
    with np.errstate(all="ignore"):
        want = reference_transform(m, o, d)
    for g, w in zip(got, want):
        assert bits(golden.canonical(g)).tobytes() == bits(golden.canonical(w)).tobytes()
    # one (3, 4) matrix for every ray is the same as it repeated
    one = golden.transform(m[0], o, d)
    rep = golden.transform(np.repeat(m[:1], len(o), 0), o, d)
    assert bits(one[0]).tobytes() == bits(rep[0]).tobytes()


def test_the_order_matters():
    """A case where the operation's order gives another float32 than other orders: the test
    cannot pass with a model that sums in another order."""
    m = np.array([[1.0, 1e8, -1e8, 1.0], [0, 1, 0, 0], [0, 0, 1, 0]], F32)
    o = np.array([[1.0, 1.0, 1.0]], F32)
    o2, _ = golden.transform(m, o, o)
    # ((1 + 1e8) - 1e8) + 1 = 1 in float32; 1 + (1e8 - 1e8) + 1 would be 2
    assert o2[0, 0] == F32(1.0)


def test_random_golden_equals_scalar_reference():
    req = transform_requests_random(np.random.default_rng(3), 3000)
    state = ScalarState(extended=False, compressed=False)
    want = scalar_run(req, state)
    got = driver.backend("golden", transform=True).run(req)
    assert_bit_equal(req, got, want, "golden", "scalar")


def test_random_matrices_cover_the_cases():
    """The random stream holds what it claims: negative and zero determinants, overflow to inf,
    subnormal and zero results, NaN, +-0 inputs."""
    rng = np.random.default_rng(4)
    req = transform_requests_random(rng, 3000)
    with np.errstate(all="ignore"):
        m = req["matrix"].astype(np.float64)
        det = np.linalg.det(np.nan_to_num(m[:, :, :3]))
        o2, d2 = golden.transform(req["matrix"], req["origin"], req["dir"])
    assert (det < 0).sum() > 300 and (det == 0).sum() > 300
    out = np.concatenate([o2, d2], 1)
    assert np.isinf(out).any() and np.isnan(out).any()
    tiny = (out != 0) & (np.abs(out) < np.finfo(F32).tiny)
    assert tiny.any() and (out == 0).any() and np.signbit(out[out == 0]).any()
    assert (req["origin"] == 0).any() and np.isnan(req["dir"]).any()


DIRECTED = {
    "identity": np.eye(3, 4, dtype=F32),
    "translation": np.array([[1, 0, 0, 5], [0, 1, 0, -2.5], [0, 0, 1, 1e-3]], F32),
    "rotation": np.array([[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0]], F32),
    "rotation_30": np.array([[np.cos(0.5), -np.sin(0.5), 0, 1], [np.sin(0.5), np.cos(0.5), 0, 2],
                             [0, 0, 1, 3]], F32),
    "mirror": np.array([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], F32),
    "scale": np.array([[2, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, -4, 0]], F32),
    "zero": np.zeros((3, 4), F32),
}


@pytest.mark.parametrize("name", sorted(DIRECTED))
def test_directed_matrices(name):
    m = DIRECTED[name].astype(F32)
    o = np.array([[1, 2, 3], [-0.0, 0.0, -0.0], [0.1, -7, 1e-40]], F32)
    d = np.array([[0, 0, 1], [1, -1, 0.5], [-0.0, 3, 1e30]], F32)
    req = transform_requests(m, o, d)
    rsp = Testbench("rtl", transform=True, stamp=False).run(req)
    o2, d2 = transform_results(rsp)
    ref = scalar_run(req, ScalarState(transform=True))
    assert_bit_equal(req, rsp, ref, "rtl", "scalar")
    if name == "identity":                       # x*1 + (+0) is x except that -0 becomes +0
        assert (o2 == o).all() and (d2 == d).all()
        assert not np.signbit(o2[1]).any()
    if name == "translation":
        assert np.array_equal(o2, o + m[:, 3]) and np.array_equal(bits(d2)[0], bits(d)[0])
    if name == "rotation":                       # (x, y, z) -> (-y, x, z): exact
        assert np.array_equal(o2[0], [-2, 1, 3]) and np.array_equal(d2[1], [1, 1, 0.5])
    if name == "zero":
        assert (o2 == 0).all() and (d2 == 0).all()


# ----------------------------------------------------------------------------------------------
# the RTL, every configuration, under gaps and stalls

def _stream(seed, compressed, extended, n_xf=1500, n_box=500, n_tri=500):
    """TRANSFORM interleaved with QUADBOX/TRIANGLE, q8 QUADBOXes on a COMPRESSED build and
    EUCLIDEAN/ANGULAR jobs on an extended one."""
    rng = np.random.default_rng(seed)
    parts = [transform_stream(seed, n_xf, n_box, n_tri)]
    if compressed:
        parts.append(q8_requests(rng, n_box // 2))
    if extended:
        parts.append(extended_stream(seed, n_jobs=20, n_box=50, n_tri=50)[0])
    return interleave(rng, parts)[0]


@pytest.mark.parametrize("gaps,stalls", FAST_PRESSURES, ids=["steady", "gaps0.5-stalls0.5"])
@pytest.mark.parametrize("extended,disjoint,compressed", CONFIG_PARAMS)
def test_random_stream_rtl(extended, disjoint, compressed, gaps, stalls):
    tb = Testbench("rtl", extended=extended, disjoint=disjoint, compressed=compressed,
                   transform=True, gaps=gaps, stalls=stalls, seed=41)
    assert tb.latency == 11 + compressed           # TRANSFORM adds no stage
    req = _stream(41, compressed, extended)
    assert (req["opcode"] == TRANSFORM).sum() == 1500
    tb.run(req[:1300])
    tb.run(req[1300:])


@pytest.mark.slow
@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
@pytest.mark.parametrize("extended,disjoint,compressed", CONFIGS, ids=CONFIG_IDS)
def test_random_stream_rtl_all_pressures(extended, disjoint, compressed, gaps, stalls):
    Testbench("rtl", extended=extended, disjoint=disjoint, compressed=compressed, transform=True,
              gaps=gaps, stalls=stalls, seed=42).run(
        _stream(42, compressed, extended, 20_000, 5_000, 5_000))


def test_rtl_equals_scalar_reference():
    req = transform_stream(43, 1500, 300, 300)
    rsp = Testbench("rtl", transform=True, gaps=0.3, stalls=0.3, seed=43, stamp=False).run(req)
    want = scalar_run(req, ScalarState(extended=False, compressed=False))
    assert_bit_equal(req, rsp, want, "rtl", "scalar")


def test_latency_and_throughput():
    """Back to back, the TRANSFORM build answers n requests in n + 11 cycles (the monitor's
    check), a stream of TRANSFORMs alone too: one per cycle."""
    tb = Testbench("rtl", transform=True)
    tb.run(transform_requests_random(np.random.default_rng(44), 500))
    tb.run(transform_stream(44, 300, 100, 100))
    assert tb.latency == 11 and tb.runs == [500 + 11, 500 + 11]


def test_pyverilator_equals_rtl():
    assert_pyverilator_equals_rtl(_stream(45, False, False, 400, 100, 100),
                                  dict(transform=True, gaps=0.5, stalls=0.5, seed=45), 350)


@pytest.mark.slow
@pytest.mark.parametrize("extended,disjoint,compressed", CONFIGS, ids=CONFIG_IDS)
def test_pyverilator_every_build(extended, disjoint, compressed):
    req = _stream(46, compressed, extended, 1000, 300, 300)
    run_isolated("pyverilator", dict(extended=extended, disjoint=disjoint, compressed=compressed,
                                     transform=True, gaps=0.3, stalls=0.3, seed=46), [req])


def test_area_configurations_with_transform():
    """The -xf configurations are every configuration with TRANSFORM = 1 (derived names), and the
    parameter reaches the design: elaboration shows the unified build's two extra adders and no
    extra multiplier, the disjoint build's 18 private multipliers."""
    from driver import area
    assert area.XF_CONFIGS == [n + "-xf" for n in area.ALL_CONFIGS]
    assert area.config_params("extended-disjoint-q8-xf") == {"EXTENDED": 1, "DISJOINT": 1,
                                                             "COMPRESSED": 1, "TRANSFORM": 1}
    assert area.config_params("baseline-unified-xf") == {"EXTENDED": 0, "DISJOINT": 0,
                                                         "TRANSFORM": 1}
    with pytest.raises(area.AreaError, match="unknown configuration"):
        area.config_params("baseline-xf")
    plain, xf = area.elaborate(0, 0), area.elaborate(0, 0, transform=1)
    assert xf["$mul"] == plain["$mul"] and xf["$add"] > plain["$add"]
    plain, xf = area.elaborate(0, 1), area.elaborate(0, 1, transform=1)
    assert xf["$mul"] == plain["$mul"] + 18


@pytest.mark.parametrize("extended,disjoint,compressed", CONFIGS, ids=CONFIG_IDS)
def test_lint_clean_with_transform(extended, disjoint, compressed):
    """``verilator --lint-only -Wall`` (with rtl/lint.vlt) of every configuration with TRANSFORM."""
    from driver.backends.build import lint
    assert lint(extended, disjoint, None, compressed, transform=True) == ""
