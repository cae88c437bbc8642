"""The q8 decode in the datapath (docs/q8_datapath.md): a QUADBOX with ``FLAG_DECODE_Q8`` carries
a q8 box node in ``qnode`` and a ``COMPRESSED`` build answers exactly as a QUADBOX on the decoded
boxes.

Golden model, the fast RTL harness ("rtl"), pyverilator and the scalar reference (the node read
with ``struct``, one Python float32 step at a time), bit for bit, through the testbench (driver,
monitor, golden scoreboard): hand-computed nodes (rounding, ties, subnormal and signed-zero
origins, unused slots); every product q * 2^exp (q 1..254, every exponent) observed through tmin;
random nodes (the whole exponent range, zero and full planes, every count, subnormal, +-0, NaN
and inf node origins, NaN ray origins) in streams that interleave q8, plain QUADBOX and TRIANGLE
requests (and EUCLIDEAN/ANGULAR beats on extended builds) under gaps and stalls, in every
configuration with COMPRESSED; the wire overlay of ``qnode`` on ``box``; the request checks; the
latency (one more cycle) and the builds without the decode (unchanged: their own suites).
"""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import QUADBOX, TRIANGLE, DatapathError
from driver.backends import BackendError
from driver.core.datapath import default_latency
from driver.core.wire import (FLAG_DECODE_Q8, FLAG_NO_CULL, FLAGS_DEFINED, QNODE_WORDS, REQUEST,
                              REQUEST_DTYPE, carries_qnode, pack_requests, unpack_requests)
from driver.core.layout import Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, c_header, decode_q8
from support.scalar_ref import ScalarState, q8_boxes, scalar_run
from support.scoreboard import assert_bit_equal, bits
from support.streams import extended_stream, interleave, q8_requests, q8_stream
from support.testbench import (PRESSURE_IDS, PRESSURES, Testbench, assert_pyverilator_equals_rtl,
                               run_isolated)

F32 = np.float32
CONFIGS = [(False, False), (False, True), (True, False), (True, True)]
CONFIG_IDS = ["baseline-unified-q8", "baseline-disjoint-q8", "extended-unified-q8",
              "extended-disjoint-q8"]
# The default suite streams through the two builds that bound the others (baseline-unified-q8,
# extended-disjoint-q8); the other two, a Verilator model each, run with -m slow.
DEFAULT_CONFIGS = [(False, False), (True, True)]
CONFIG_PARAMS = [pytest.param(*c, id=i, marks=() if c in DEFAULT_CONFIGS else pytest.mark.slow)
                 for c, i in zip(CONFIGS, CONFIG_IDS)]
FAST_PRESSURES = [(0.0, 0.0), (0.5, 0.5)]


def f32bits(x) -> int:
    return int(np.array(x, F32).view(np.uint32))


def node(origin, exp, count, q) -> np.ndarray:
    """One Q8_NODE row: origin (3 floats or uint32 bit patterns), exp (3 ints), count, q (4, 6)."""
    n = np.zeros(1, Q8_NODE)
    n["origin"] = [np.uint32(v).view(F32) if isinstance(v, int) else F32(v) for v in origin]
    n["exp"][0, :3] = np.array(exp, np.int8).view(np.uint8)
    n["exp"][0, 3] = count
    n["q"] = np.asarray(q, np.uint8).reshape(4, 6)
    n["child"] = [0x11, 0x22, 0x33, 0x44]          # ignored by the decode
    n["parent"] = 0xDEADBEEF
    return n


def q8_request(rays: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    req = rays.copy()
    req["opcode"] = QUADBOX
    req["qnode"] = nodes.view(np.uint32).reshape(-1, QNODE_WORDS)
    req["flags"] |= FLAG_DECODE_Q8
    return req


def box_request(rays: np.ndarray, boxes) -> np.ndarray:
    req = rays.copy()
    req["opcode"] = QUADBOX
    req["box"] = boxes
    return req


# ----------------------------------------------------------------------------------------------
# the request: flag, overlay, checks

def test_flag_and_overlay_on_the_wire():
    assert FLAG_DECODE_Q8 == 2 and FLAGS_DEFINED == FLAG_NO_CULL | FLAG_DECODE_Q8
    q, box = REQUEST.field["qnode"], REQUEST.field["box"]
    assert q.overlays == "box" and q.word == box.word and q.count == QNODE_WORDS == 16
    assert Q8_NODE.itemsize == 4 * QNODE_WORDS
    req = np.zeros(4, REQUEST_DTYPE)
    req["opcode"] = [QUADBOX, QUADBOX, QUADBOX, TRIANGLE]
    req["flags"] = [FLAG_DECODE_Q8, FLAG_DECODE_Q8 | FLAG_NO_CULL, 0, FLAG_DECODE_Q8]
    boxes = np.arange(4 * 24, dtype=F32).reshape(4, 4, 6) + 1
    req["box"] = boxes
    nodes = np.random.default_rng(0).integers(0, 2**32, (4, 16), dtype=np.uint64)
    req["qnode"] = nodes.astype(np.uint32)
    assert carries_qnode(req).tolist() == [True, True, False, False]
    words = pack_requests(req)
    span = slice(box.word, box.word + QNODE_WORDS)
    assert np.array_equal(words[:2, span], nodes[:2])            # the node on the box words
    assert np.array_equal(words[2:, span].view(F32), boxes[2:].reshape(2, 24)[:, :16])
    assert np.array_equal(words[:, box.word + 16:box.word + 24].view(F32),   # box's own words
                          boxes.reshape(4, 24)[:, 16:])
    back = unpack_requests(words)
    assert np.array_equal(back["qnode"], words[:, span])
    assert np.array_equal(pack_requests(np.concatenate([back[:2], back[2:]])), words)
    assert "constexpr uint32_t kFlagDecodeQ8 = 2;" in c_header()
    assert "constexpr int kReqQnodeWord = 15;" in c_header()


def test_decode_needs_the_compressed_build():
    rays = driver.prepare_rays([[0, 0, 0]], [[1, 0, 0]])
    req = q8_request(rays, node([0, 0, 0], [0, 0, 0], 1, np.ones((4, 6))))
    for be in (driver.backend("golden"), driver.backend("rtl")):
        with pytest.raises(DatapathError, match="compressed=True"):
            be.run(req)
    with pytest.raises(DatapathError, match="q8 decode"):
        scalar_run(req, ScalarState(extended=False, compressed=False))


@pytest.mark.parametrize("bad", [Q8_EXP_MIN - 1, Q8_EXP_MAX + 1, -128, 127])
def test_exponents_outside_the_range_are_rejected(bad):
    rays = driver.prepare_rays([[0, 0, 0]] * 2, [[1, 0, 0]] * 2)
    nodes = np.concatenate([node([0, 0, 0], [Q8_EXP_MIN, Q8_EXP_MAX, 0], 2, np.ones((4, 6))),
                            node([0, 0, 0], [0, bad, 0], 2, np.ones((4, 6)))])
    req = q8_request(rays, nodes)
    with pytest.raises(DatapathError, match=r"request 1: q8 node exponents \[0, "):
        driver.backend("golden", compressed=True).run(req)
    tri = req.copy()
    tri["opcode"] = TRIANGLE                            # the flag and node mean nothing there
    driver.backend("golden", compressed=True).run(tri)


def test_reserved_flag_bits_stay_reserved():
    rays = driver.prepare_rays([[0, 0, 0]], [[1, 0, 0]])
    for bit in range(2, 8):
        req = rays.copy()
        req["flags"] = 1 << bit
        with pytest.raises(DatapathError, match="reserved"):
            driver.backend("golden", compressed=True).run(req)


def test_latency_one_more_and_checked():
    assert default_latency(False) == driver.LATENCY == 11 and default_latency(True) == 12
    assert driver.backend("golden", compressed=True).latency == 12
    with pytest.raises(BackendError, match="at least 11"):
        driver.backend("rtl", compressed=True, latency=10)


# ----------------------------------------------------------------------------------------------
# the decode arithmetic

def test_every_product_is_an_exact_normal_float32():
    """q * 2^exp for q 1..255 and every exponent of the range is a normal float32, exactly (the
    decode's int-to-float needs no rounding and no subnormal case); q = 1, exp = -126 is the
    smallest normal."""
    q = np.arange(1, 256, dtype=np.float64)[:, None]
    e = np.arange(Q8_EXP_MIN, Q8_EXP_MAX + 1)[None, :]
    p64 = np.ldexp(q, e)
    p32 = p64.astype(F32)
    assert np.array_equal(p32.astype(np.float64), p64)
    field = (p32.view(np.uint32) >> 23) & 0xFF
    assert field.min() == 1 and field.max() == 253
    assert f32bits(np.ldexp(F32(1), -126)) == 0x00800000


# Hand-computed nodes: (origin, exp, count, q[4][6], expected box bits of the used children)
ONE_P = 0x3F800001                                   # 1 + 2^-23
DIRECTED = [
    # exact sums; an unused slot
    ([1.0, -2.0, 0.5], [-4, 0, 3], 2,
     [[0, 0, 0, 16, 1, 2], [255, 255, 255, 255, 255, 255], [9] * 6, [9] * 6],
     [[1.0, -2.0, 0.5, 2.0, -1.0, 16.5], [16.9375, 253.0, 2040.5, 16.9375, 253.0, 2040.5]]),
    # rounding: 1 + 255 * 2^-30 = 1 + 1.99 ulp -> 1 + 2 ulp; ties to even: 1 + 2^-24 -> 1,
    # (1 + 2^-23) + 2^-24 -> 1 + 2^-22; 1 + 3 * 2^-24 -> 1 + 2^-22 (tie up to even)
    ([1.0, 1.0, ONE_P], [-30, -24, -24], 1,
     [[255, 1, 1, 0, 3, 0], [0] * 6, [0] * 6, [0] * 6],
     [[0x3F800002, 1.0, 0x3F800002, 1.0, 0x3F800002, ONE_P]]),
    # subnormal and signed-zero origins: +0 + 2^-126, -2^-126 + 2^-126 = +0, 2^-149 + 2^-126,
    # -0 + 0 = +0, -0 + 2^-126 * 3
    ([0.0, 0x80800000, 0x00000001], [-126, -126, -126], 4,
     [[1, 1, 1, 0, 0, 3]] * 4,
     [[0x00800000, 0, 0x00800001, 0, 0x80800000, 0x01400000]] * 4),   # last: a tie, to even
    ([0x80000000, 0x80000000, 0x80000000], [-126, 0, 119], 3,
     [[0, 0, 0, 3, 255, 255], [0, 1, 2, 0, 0, 0], [128, 0, 0, 0, 0, 0], [7] * 6],
     [[0, 0, 0, 0x01400000, 255.0, 0x7EFF0000], [0, 1.0, 0x7B800000, 0, 0, 0],
      [0x04000000, 0, 0, 0, 0, 0]]),
    # overflow of the add and inf/NaN origins: decoded bounds inf or NaN (the box is then a
    # miss or unbounded)
    ([3.4e38, 0x7F800000, 0x7FC00001], [119, 0, 0], 1,
     [[255, 1, 1, 0, 0, 0], [0] * 6, [0] * 6, [0] * 6],
     [[0x7F800000, 0x7F800000, 0x7FC00000, 0x7F7FC99E, 0x7F800000, 0x7FC00000]]),
]


def _expect_bits(expected, count):
    out = np.full((4, 6), 0x7F800000, np.uint32)            # unused slots: +inf
    for i, row in enumerate(expected):
        out[i] = [v if isinstance(v, int) else f32bits(v) for v in row]
    assert len(expected) == count
    return out


@pytest.mark.parametrize("case", range(len(DIRECTED)))
def test_directed_decode(case):
    origin, exp, count, q, expected = DIRECTED[case]
    n = node(origin, exp, count, q)
    want = _expect_bits(expected, count)
    got = bits(decode_q8(n))[0]
    nan = (want & 0x7FFFFFFF) > 0x7F800000
    assert np.array_equal(got[~nan], want[~nan]) and np.isnan(decode_q8(n)[0][nan]).all()
    ref = np.array(q8_boxes(n.tobytes()), F32)               # the scalar reference's decode
    assert np.array_equal(bits(ref)[~nan], want[~nan]) and np.isnan(ref[nan]).all()


@pytest.mark.parametrize("extended,disjoint", CONFIG_PARAMS)
def test_directed_nodes_answer_as_their_boxes(extended, disjoint):
    """Every directed node against rays from all sides: the DECODE_Q8 request's responses are
    those of a plain QUADBOX on the hand-computed boxes, on the RTL and the golden model."""
    rng = np.random.default_rng(5)
    req, want_req = [], []
    for origin, exp, count, q, expected in DIRECTED:
        n = node(origin, exp, count, q)
        boxes = _expect_bits(expected, count).view(F32)
        lo, hi = np.nan_to_num(boxes[:, :3], posinf=0), np.nan_to_num(boxes[:, 3:], neginf=0)
        with np.errstate(all="ignore"):
            centre = ((lo.astype(np.float64) + hi) / 2).clip(-1e30, 1e30)[rng.integers(0, 4, 64)]
        d = rng.normal(size=(64, 3))
        o = centre - d * rng.uniform(0.5, 50, (64, 1))
        o[:8] = 0
        rays = driver.prepare_rays(o.astype(F32), d.astype(F32))
        req.append(q8_request(rays, np.repeat(n, 64)))
        want_req.append(box_request(rays, np.repeat(boxes[None], 64, axis=0)))
    req, want_req = np.concatenate(req), np.concatenate(want_req)
    tb = Testbench("rtl", extended=extended, disjoint=disjoint, compressed=True, stamp=False)
    got = tb.run(req)
    want = driver.backend("golden").run(want_req)
    assert_bit_equal(req, got, want, "rtl (q8)", "golden (boxes)")
    assert got["box_hit"].any() and not got["box_hit"].all()


def test_every_product_through_the_datapath():
    """q * 2^exp for every q 1..254 and every exponent, seen bit for bit as a tmin: node origin
    x = 0, the ray along +x from 0 (tmin = max(lo_x, -inf, -inf, +0) = lo_x; the y and z slabs
    straddle the ray). Golden, RTL and the product itself agree."""
    per = np.append(np.arange(1, 255), [1, 2]).reshape(64, 4)     # q 1..254 on 64 nodes
    exps = np.arange(Q8_EXP_MIN, Q8_EXP_MAX + 1)
    n = len(exps) * len(per)
    q = np.zeros((n, 4, 6), np.uint8)
    q[:, :, 0] = np.tile(per, (len(exps), 1))                   # lo_x = q * 2^exp
    q[:, :, 3:] = 255                                           # hi_x, and y, z: [-1, 254]
    nodes = np.zeros(n, Q8_NODE)
    nodes["origin"] = [0.0, -1.0, -1.0]
    nodes["q"] = q
    exp = np.repeat(exps, len(per))
    nodes["exp"][:, 0] = exp.astype(np.int8).view(np.uint8)
    nodes["exp"][:, 3] = 4
    rays = driver.prepare_rays(np.zeros((n, 3)), np.tile([1.0, 0, 0], (n, 1)))
    req = q8_request(rays, nodes)
    got = Testbench("rtl", compressed=True, stamp=False).run(req)
    prod = np.ldexp(q[:, :, 0].astype(F32), exp[:, None]).astype(F32)
    assert got["box_hit"].all()
    assert np.array_equal(bits(got["box_tmin"]),
                          bits(np.take_along_axis(prod, got["box_index"].astype(int), 1)))


# ----------------------------------------------------------------------------------------------
# random nodes, every configuration, gaps and stalls

def test_random_nodes_golden_equals_scalar_reference():
    req = q8_stream(11, 1500, 300, 300)
    got = driver.backend("golden", compressed=True).run(req)
    assert_bit_equal(req, got, scalar_run(req, ScalarState(extended=False)), "golden", "scalar")
    q8 = req["flags"] & FLAG_DECODE_Q8 != 0
    assert got["box_hit"][q8 & (req["opcode"] == QUADBOX)].any()


def test_random_stream_covers_the_node_space():
    """The random q8 requests hold what the tests claim: both ends of the exponent range, zero
    and full planes, every count, subnormal / +-0 / NaN / inf node origins, NaN ray origins,
    hits with tmin > 0."""
    req = q8_requests(np.random.default_rng(12), 4000)
    nodes = np.ascontiguousarray(req["qnode"]).view(Q8_NODE)[:, 0]
    exp = nodes["exp"][:, :3].view(np.int8)
    assert exp.min() == Q8_EXP_MIN and exp.max() == Q8_EXP_MAX
    assert set(nodes["exp"][:, 3] & 7) == {1, 2, 3, 4}
    assert (nodes["q"] == 0).any() and (nodes["q"] == 255).any()
    o = nodes["origin"]
    assert np.isnan(o).any() and np.isinf(o).any() and (o.view(np.uint32) == 0x80000000).any()
    assert ((o != 0) & (np.abs(o) < np.finfo(F32).tiny)).any()
    assert np.isnan(req["origin"]).any()
    rsp = driver.backend("golden", compressed=True).run(req)
    assert (rsp["box_hit"].astype(bool) & (rsp["box_tmin"] > 0)).sum() > 300


@pytest.mark.parametrize("gaps,stalls", FAST_PRESSURES, ids=["steady", "gaps0.5-stalls0.5"])
@pytest.mark.parametrize("extended,disjoint", CONFIG_PARAMS)
def test_random_q8_stream_rtl(extended, disjoint, gaps, stalls):
    tb = Testbench("rtl", extended=extended, disjoint=disjoint, compressed=True, gaps=gaps,
                   stalls=stalls, seed=21)
    assert tb.latency == 12
    req = q8_stream(21, 2000, 1000, 1000)
    tb.run(req[:1700])
    tb.run(req[1700:])


@pytest.mark.slow
@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_random_q8_stream_rtl_all_pressures(extended, disjoint, gaps, stalls):
    Testbench("rtl", extended=extended, disjoint=disjoint, compressed=True, gaps=gaps,
              stalls=stalls, seed=22).run(q8_stream(22, 30_000, 10_000, 10_000))


@pytest.mark.parametrize("disjoint", [pytest.param(False, marks=pytest.mark.slow), True],
                         ids=["unified", "disjoint"])
def test_q8_with_vector_jobs_extended(disjoint):
    """q8 requests interleaved with multi-beat EUCLIDEAN/ANGULAR jobs and QUADBOX/TRIANGLE
    requests, under gaps and stalls: the decode stage holds a beat without disturbing the
    accumulators."""
    rng = np.random.default_rng(23)
    other, _ = extended_stream(23, n_jobs=30, n_box=200, n_tri=200)
    stream, _ = interleave(rng, (q8_requests(rng, 800), other))
    Testbench("rtl", extended=True, disjoint=disjoint, compressed=True, gaps=0.4, stalls=0.4,
              seed=23).run(stream)


def test_latency_and_throughput():
    """Back to back, the COMPRESSED build answers n requests in n + 12 cycles (the monitor's
    check), with or without q8 requests; the build without it keeps 11."""
    req = q8_stream(24, 300, 100, 100)
    assert Testbench("rtl", compressed=True).run(req) is not None
    plain = req[(req["flags"] & FLAG_DECODE_Q8) == 0]
    tb = Testbench("rtl")
    tb.run(plain)
    assert tb.latency == 11 and tb.runs == [len(plain) + 11]


def test_random_q8_stream_pyverilator_equals_rtl():
    assert_pyverilator_equals_rtl(q8_stream(31, 400, 100, 100),
                                  dict(compressed=True, gaps=0.5, stalls=0.5, seed=31), 350)


@pytest.mark.slow
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_random_q8_stream_pyverilator_every_build(extended, disjoint):
    req = q8_stream(32, 1500, 500, 500)
    run_isolated("pyverilator", dict(extended=extended, disjoint=disjoint, compressed=True,
                                     gaps=0.3, stalls=0.3, seed=32), [req])


def test_area_configurations_with_the_decode():
    """The -q8 configurations are the four with COMPRESSED = 1 (derived names), and the parameter
    reaches the design: elaboration (seconds) shows the decode's adders."""
    from driver import area
    assert area.ALL_CONFIGS == [*area.CONFIGS, *(n + "-q8" for n in area.CONFIGS)]
    assert area.config_params("extended-disjoint-q8") == {"EXTENDED": 1, "DISJOINT": 1,
                                                          "COMPRESSED": 1}
    assert area.config_params("baseline-unified") == {"EXTENDED": 0, "DISJOINT": 0}
    with pytest.raises(area.AreaError, match="unknown configuration"):
        area.config_params("baseline-q8")
    plain, q8 = area.elaborate(0, 0), area.elaborate(0, 0, compressed=1)
    assert q8.get("$add", 0) > plain.get("$add", 0)
    assert sum(q8.values()) > sum(plain.values())
