"""The q8 decode stage on its own (rtl/rf_s00_q8_decode.sv through sim/q8_decode_tb_top.sv):
every decoded bound equals the golden decode (``driver.core.layout.decode_q8``: one numpy float32 add
``origin + q * 2^exp``) bit for bit, NaN as the canonical quiet NaN, on nodes built to reach every
case of the decode adder (docs/q8_datapath.md, "The decode adder"): every distance between the
origin and the scale 2^exp (both paths and the boundary between them), cancellation to zero and
to subnormal results, ties to even, +-0, subnormal, NaN and inf origins, overflow to inf, q = 0,
1, 128 and 255, every exponent, every count. Fast: millions of adds a second, no datapath around.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from driver.backends.build import RTL_DIR, SIM_DIR, source_names
from driver.core.layout import Q8_EXP_MAX, Q8_EXP_MIN, Q8_NODE, decode_q8
from driver.core.wire import QNODE_WORDS
from driver.backends.verilate import build_library

F32 = np.float32
CANONICAL_NAN = np.uint32(0x7FC00000)
# the packages and the decode stage's files, in the datapath's compile order
SOURCES = [RTL_DIR / f for f in source_names() if f.endswith("_pkg.sv") or f.startswith("rf_s00_")] \
    + [SIM_DIR / "q8_decode_tb_top.sv"]
HARNESS = [SIM_DIR / "q8_decode_harness.cpp"]
BOUNDS = 24

_u32p = np.ctypeslib.ndpointer(dtype=np.uint32, flags="C_CONTIGUOUS")


class DecodeModel:
    """The Verilated q8_decode_tb_top: n nodes (Q8_NODE rows) -> (n, 4, 6) uint32 bounds."""

    def __init__(self) -> None:
        self._dll = ctypes.CDLL(str(build_library("q8_decode_tb_top", SOURCES, HARNESS)))
        self._eval = self._dll.q8_decode_eval
        self._eval.restype = ctypes.c_int
        self._eval.argtypes = [_u32p, ctypes.c_size_t, _u32p]

    def run(self, nodes: np.ndarray) -> np.ndarray:
        words = np.ascontiguousarray(nodes.view(np.uint32).reshape(-1, QNODE_WORDS))
        out = np.empty((words.shape[0], BOUNDS), np.uint32)
        self._eval(words, words.shape[0], out)
        return out.reshape(-1, 4, 6)


@pytest.fixture(scope="module")
def model():
    return DecodeModel()


def reference(nodes: np.ndarray) -> np.ndarray:
    """The golden decode's bit patterns, any NaN as the canonical quiet NaN."""
    with np.errstate(all="ignore"):
        boxes = decode_q8(nodes)
    out = boxes.view(np.uint32).copy()
    out[np.isnan(boxes)] = CANONICAL_NAN
    return out


def check(model: DecodeModel, nodes: np.ndarray) -> None:
    got, want = model.run(nodes), reference(nodes)
    bad = np.argwhere(got != want)
    if bad.size:
        k, i, j = bad[0]
        a = j % 3
        exp = int(nodes["exp"][k, a].view(np.int8))
        raise AssertionError(
            f"{len(bad)} of {got.size} bounds differ; first: origin "
            f"{nodes['origin'][k, a].view(np.uint32):#010x} exp {exp} q {nodes['q'][k, i, j]}: "
            f"rtl {got[k, i, j]:#010x}, golden {want[k, i, j]:#010x}")


def make_nodes(origin_bits: np.ndarray, exp: np.ndarray, q: np.ndarray,
               count: np.ndarray | None = None) -> np.ndarray:
    """Q8_NODE rows from (n, 3) origin bit patterns, (n, 3) exponents, (n, 4, 6) q, counts."""
    n = origin_bits.shape[0]
    nodes = np.zeros(n, Q8_NODE)
    nodes["origin"] = origin_bits.astype(np.uint32).view(F32)
    nodes["exp"][:, :3] = exp.astype(np.int8).view(np.uint8)
    nodes["exp"][:, 3] = 4 if count is None else count
    nodes["q"] = q
    return nodes


def random_q(rng, shape) -> np.ndarray:
    """q bytes: uniform, with the edges 0, 1, 128 and 255 often."""
    q = rng.integers(0, 256, shape)
    edge = rng.random(shape) < 0.25
    q[edge] = rng.choice([0, 1, 2, 127, 128, 254, 255], edge.sum())
    return q.astype(np.uint8)


def origins_near_the_scale(rng, exp: np.ndarray, span: int = 40) -> np.ndarray:
    """Origin bit patterns +-m * 2^(exp + k): a random 24-bit significand m (or one with few bits
    set: exact sums and ties) whose last bit weighs 2^(exp + k), k in [-span, span]: every
    distance between the origin and the addend's scale, both signs, clipped to finite floats."""
    shape = exp.shape
    k = rng.integers(-span, span + 1, shape)
    m = rng.integers(1 << 23, 1 << 24, shape).astype(np.float64)
    few = rng.random(shape) < 0.4                       # significands with few bits: exact sums
    m[few] = (1 << 23) + rng.integers(0, 8, few.sum()) * (1 << rng.integers(0, 21, few.sum()))
    sign = np.where(rng.random(shape) < 0.5, -1.0, 1.0)
    with np.errstate(all="ignore"):
        v = np.ldexp(sign * m, exp + k).astype(F32)    # rounds only at the edges of the range
    return v.view(np.uint32)


def origins_that_cancel(rng, exp: np.ndarray, q: np.ndarray) -> np.ndarray:
    """-(q0 * 2^exp) moved by a few units in its last place: q0 + origin cancels to (nearly)
    zero, subnormal for the smallest exponents, for the bound whose q is q0."""
    q0 = np.maximum(q, 1).astype(np.float64)
    v = -np.ldexp(q0, exp).astype(F32)
    steps = rng.integers(-3, 4, exp.shape).astype(np.int64)
    bits = v.view(np.uint32).astype(np.int64) + steps
    return bits.astype(np.uint32)


SPECIAL_ORIGINS = np.array([0x00000000, 0x80000000, 0x00000001, 0x80000001, 0x007FFFFF,
                            0x807FFFFF, 0x00800000, 0x80800000, 0x7F7FFFFF, 0xFF7FFFFF,
                            0x7F800000, 0xFF800000, 0x7FC00000, 0xFFC00001, 0x7F800001,
                            0x3F800000, 0xBF800000, 0x4B7FFFFF, 0xCB7FFFFF], np.uint32)


def node_mix(rng, n: int) -> np.ndarray:
    """n nodes mixing every origin class above, exponents over the whole range."""
    exp = rng.integers(Q8_EXP_MIN, Q8_EXP_MAX + 1, (n, 3))
    edge = rng.random((n, 3)) < 0.2
    exp[edge] = rng.choice([Q8_EXP_MIN, Q8_EXP_MIN + 1, -100, 0, 100, Q8_EXP_MAX - 1,
                            Q8_EXP_MAX], edge.sum())
    q = random_q(rng, (n, 4, 6))
    kind = rng.integers(0, 5, (n, 3))
    origin = np.select(
        [kind == 0, kind == 1, kind == 2, kind == 3],
        [origins_near_the_scale(rng, exp),
         origins_near_the_scale(rng, exp, span=4),
         origins_that_cancel(rng, exp, q[:, rng.integers(0, 4), :3]),
         rng.choice(SPECIAL_ORIGINS, (n, 3))],
        rng.integers(0, 1 << 32, (n, 3), dtype=np.uint64).astype(np.uint32))
    count = rng.integers(1, 5, n)
    return make_nodes(origin, exp, q, count)


def cases_reached(nodes: np.ndarray) -> dict[str, int]:
    """How many axes or bounds of ``nodes`` reach each case of the decode adder
    (docs/q8_datapath.md, "The decode adder")."""
    bits = nodes["origin"].view(np.uint32).astype(np.int64)              # (n, 3)
    ea = (bits >> 23) & 0xFF
    e = nodes["exp"][:, :3].view(np.int8).astype(np.int64)
    dp = np.maximum(ea, 1) - 150 - e          # A's last significand bit weighs 2^(dp + e)
    normal = (ea > 0) & (ea < 255)
    far = normal & (dp >= -14)
    near = (ea < 255) & ~far
    y = reference(nodes)
    used = np.arange(4)[None, :, None] < (nodes["exp"][:, 3] & 7)[:, None, None]
    q = np.where(used, nodes["q"].astype(np.int64), -1)                   # -1: an unused slot
    finite_origin = np.tile(ea < 255, 2)[:, None, :]                       # (n, 1, 6)
    with np.errstate(all="ignore"):
        a_u = np.abs(nodes["origin"].astype(np.float64)) / np.ldexp(1.0, e)   # |A| / 2^e, exact
    neg_near = np.tile(near & (bits >> 31 == 1), 2)[:, None, :]
    int_a = np.tile(np.floor(np.where(near, a_u, -9)), 2)[:, None, :]
    cases = {
        "near, integer part of the sum zero": (neg_near & ((q == int_a) | (q == int_a + 1))).sum(),
        "far": far.sum(), "near": near.sum(), "near, dp = -15": (near & (dp == -15)).sum(),
        "far, dp = -14": (far & (dp == -14)).sum(),
        "near, origin bits lost": (near & (dp < -26) & ((bits & 0x7FFFFFFF) != 0)).sum(),
        "far, q bits shifted out": (far & (dp > 11)).sum(),
        "far, q's shift clamped to 31": (far & (dp >= 16)).sum(),
        "nan/inf origin": (ea == 255).sum(),
        "sum +0": ((y == 0) & (q > 0) & finite_origin).sum(),
        "subnormal sum": (((y & 0x7F800000) == 0) & ((y & 0x7FFFFF) != 0) & (q > 0)).sum(),
        "overflow to inf": ((y & 0x7FFFFFFF) == 0x7F800000) & (q > 0) & finite_origin,
        "q = 0": (q == 0).sum(),
    }
    cases["overflow to inf"] = cases["overflow to inf"].sum()
    return {k: int(v) for k, v in cases.items()}


def test_node_mix_reaches_every_case():
    """The mix of test_every_origin_class reaches each case many times: both paths and the
    boundary between them, origin bits lost to the sticky bit (near) and q's bits shifted out
    (far), sums cancelling to zero and into the subnormal range, overflow to inf, NaN and inf
    origins, q = 0."""
    cases = cases_reached(node_mix(np.random.default_rng(1), 100_000))
    rare = {k: v for k, v in cases.items() if v < 100}
    assert not rare, rare


def test_every_origin_class(model):
    nodes = node_mix(np.random.default_rng(1), 100_000)
    check(model, nodes)


def test_every_exponent_and_q_against_special_origins(model):
    """Each special origin with every exponent and every q (all 256 values on the 24 bounds)."""
    exps = np.arange(Q8_EXP_MIN, Q8_EXP_MAX + 1)
    o, e, part = np.meshgrid(SPECIAL_ORIGINS, exps, np.arange(11), indexing="ij")
    o, e, part = o.ravel(), e.ravel(), part.ravel()
    q = ((part[:, None] * 24 + np.arange(24)[None, :]) % 256).astype(np.uint8).reshape(-1, 4, 6)
    nodes = make_nodes(np.repeat(o[:, None], 3, 1), np.repeat(e[:, None], 3, 1), q)
    check(model, nodes)


def test_ties_round_to_even(model):
    """Origins whose last bit weighs 2^(exp + 1) and odd q: every sum is an exact tie."""
    rng = np.random.default_rng(3)
    n = 20_000
    exp = rng.integers(Q8_EXP_MIN, Q8_EXP_MAX - 30, (n, 3))
    m = rng.integers(1 << 23, 1 << 24, (n, 3)).astype(np.float64)
    sign = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0)
    origin = np.ldexp(sign * m, exp + 1).astype(F32).view(np.uint32)
    q = (rng.integers(0, 128, (n, 4, 6)) * 2 + 1).astype(np.uint8)
    nodes = make_nodes(origin, exp, q)
    with np.errstate(all="ignore"):
        exact = np.ldexp(sign[:, None, [0, 1, 2, 0, 1, 2]] * m[:, None, [0, 1, 2, 0, 1, 2]], 1) \
            + q.astype(np.float64)
    assert np.all(exact % 2 == 1)                    # in units of 2^exp: odd, ulp 2: a tie
    check(model, nodes)


def test_cancellation_to_zero_and_subnormal(model):
    """origin = -(q * 2^exp) (+- a few ulps) with the smallest exponents: exact zeros (+0) and
    subnormal differences."""
    rng = np.random.default_rng(4)
    n = 20_000
    exp = rng.integers(Q8_EXP_MIN, Q8_EXP_MIN + 30, (n, 3))
    q = random_q(rng, (n, 4, 6))
    q[:, 0, :3] = np.maximum(q[:, 0, :3], 1)
    origin = origins_that_cancel(rng, exp, q[:, 0, :3])
    nodes = make_nodes(origin, exp, q)
    want = reference(nodes)
    got_bits = want[:, 0, :3]
    assert np.any(got_bits == 0) and np.any((got_bits & 0x7F800000) == 0)
    check(model, nodes)


@pytest.mark.slow
def test_many_nodes(model):
    rng = np.random.default_rng(11)
    for _ in range(20):
        check(model, node_mix(rng, 200_000))
