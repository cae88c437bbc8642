"""The binary32 divider's testbench: model loader (driver + monitor in C++), numpy reference,
division-specific operand generators.

    div = DivModel()                            # builds (cached) sim/fp_div_tb_top.sv + harness
    run = div.run(a, b, tags, gaps=0.5, stalls=0.5, seed=1)   # DivRun: results in taken order
    want = reference(a, b)                      # numpy float32 a / b, NaN -> 0x7FC00000

The harness (sim/fp_div_harness.cpp) is the driver and the monitor: it offers the divisions in
order with input gaps (an offered division stays offered until taken; garbage on the operand and
tag inputs between offers), stalls the output, records each result with its tag and its latency,
and counts protocol errors.  The scoreboard is ``check`` in tests/test_fp_div.py.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from driver.backends.build import SIM_DIR, rtl_sources, DIV_SOURCE_LIST
from driver.backends.rtlbase import pattern
from driver.backends.verilate import build_library

from . import testbench
from .fpu import CANONICAL_NAN, _bits, _from_int_scaled, _rand_frac, _rand_sign

DIV_SOURCES = rtl_sources(DIV_SOURCE_LIST)
DIV_TB_SOURCES = DIV_SOURCES + [SIM_DIR / "fp_div_tb_top.sv"]
DIV_HARNESS = [SIM_DIR / "fp_div_harness.cpp"]

_u32p = np.ctypeslib.ndpointer(dtype=np.uint32, flags="C_CONTIGUOUS")
_i32p = np.ctypeslib.ndpointer(dtype=np.int32, flags="C_CONTIGUOUS")
_i64p = np.ctypeslib.ndpointer(dtype=np.int64, flags="C_CONTIGUOUS")


def tags_for(n: int, salt: int = 0) -> np.ndarray:
    """n distinct 32-bit tags (every bit toggles), different for each ``salt``."""
    return testbench.tags_for(np.arange(n, dtype=np.uint64) + np.uint64(salt) * np.uint64(n))


@dataclass
class DivRun:
    q: np.ndarray            # uint32 (n,) results, in the order they were taken
    tag: np.ndarray          # uint32 (n,) their tags
    latency: np.ndarray      # int32 (n,) cycles from input handshake to out_valid_o
    cycles: int
    protocol_errors: int     # out_valid_o dropped or its data changed before it was taken
    ready_while_busy: int    # cycles with in_ready_o high while a division was in the unit
    div_cycles: int          # the RTL's DIV_CYCLES


class DivModel:
    """The Verilated fp_div_tb_top (rf_fp_div with a 32-bit tag)."""

    def __init__(self) -> None:
        self.library = build_library("fp_div_tb_top", DIV_TB_SOURCES, DIV_HARNESS)
        self._dll = ctypes.CDLL(str(self.library))
        self._run = self._dll.fp_div_run
        self._run.restype = ctypes.c_int64
        self._run.argtypes = [_u32p, _u32p, _u32p, ctypes.c_int64,
                              ctypes.c_void_p, ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64,
                              _u32p, _u32p, _i32p, _i64p, ctypes.c_int64]

    def run(self, a: np.ndarray, b: np.ndarray, tags: np.ndarray | None = None,
            gaps: float = 0.0, stalls: float = 0.0, seed: int = 0,
            max_cycles: int = 0) -> DivRun | None:
        """Stream a[i] / b[i] (uint32 bit patterns) with tags (default ``tags_for``), with input
        gaps and output stalls of the given probabilities (repeating patterns from ``seed``), after
        a reset.  With ``max_cycles``: stop after that many cycles, whatever is inside the unit
        (None if the run did not finish)."""
        a = np.ascontiguousarray(a, dtype=np.uint32)
        b = np.ascontiguousarray(b, dtype=np.uint32)
        n = a.shape[0]
        assert b.shape == (n,)
        tags = tags_for(n) if tags is None else np.ascontiguousarray(tags, dtype=np.uint32)
        gap, stall = pattern(gaps, seed), pattern(stalls, seed + 1)
        q = np.zeros(n, np.uint32)
        tag = np.zeros(n, np.uint32)
        lat = np.zeros(n, np.int32)
        stats = np.zeros(4, np.int64)

        def ptr(p):
            return (None, 0) if p is None else (p.ctypes.data, p.size)

        cycles = self._run(a, b, tags, n, *ptr(gap), *ptr(stall), q, tag, lat, stats, max_cycles)
        if cycles == -2:
            return None
        if cycles < 0:
            raise AssertionError(f"the divider stopped (no handshake for 1000 cycles) after "
                                 f"{int(np.count_nonzero(lat))} of {n} results")
        return DivRun(q, tag, lat, int(cycles), int(stats[1]), int(stats[2]), int(stats[3]))


# ------------------------------------------------------------------------------------------------
# Reference: numpy float32


def reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """numpy float32 a / b for uint32 bit patterns, as uint32 (NaN results canonicalised)."""
    with np.errstate(all="ignore"):
        r = a.view(np.float32) / b.view(np.float32)
    bits = r.view(np.uint32).copy()
    bits[np.isnan(r)] = CANONICAL_NAN
    return bits


# ------------------------------------------------------------------------------------------------
# Operand generators (division-specific; the shared mix of support.fpu covers the rest): each
# returns (a, b) uint32 arrays of length n


def _odd_inverse(m: np.ndarray, bits: int) -> np.ndarray:
    """m^-1 mod 2^bits for odd m (Newton iteration)."""
    mask = (1 << bits) - 1
    inv = np.ones_like(m)
    for _ in range(6):
        inv = (inv * (2 - m * inv)) & mask
    return inv


def gen_div_near_ties(rng, n):
    """Quotients within 2^-48 (relative) of a rounding midpoint or of a float: the sticky bit
    alone decides.  Integers A, B < 2^24 with A * 2^25 = B * M + e, M odd and e = +-1: the exact
    quotient A / B * 2^25 = M + e / B.  M of 25 bits is a midpoint of the 24-bit grid; a shorter M
    is a float and the quotient lies just beside it.  Scaled to any exponent (subnormal results
    included: there the midpoints lie elsewhere, and these are quotients with a long tail)."""
    bm = rng.integers(1 << 22, 1 << 24, n, dtype=np.int64) | 1
    e = np.where(rng.random(n) < 0.5, 1, -1)
    m = (-e * _odd_inverse(bm, 25)) & ((1 << 25) - 1)        # B * M = -e mod 2^25
    am = (bm * m + e) >> 25
    ok = (am >= 1) & (am < (1 << 24))
    am, bm = np.where(ok, am, 1), np.where(ok, bm, 3)        # 1/3 where the draw failed
    qexp = rng.integers(-170, 130, n)                        # result ~ 2^qexp
    xa = rng.integers(-149, 104, n)
    xb = np.clip(xa - qexp, -149, 104)
    return (_from_int_scaled(am, xa, _rand_sign(rng, n)),
            _from_int_scaled(bm, xb, _rand_sign(rng, n)))


def gen_div_ties(rng, n):
    """Exact ties (only possible below the normal range, where the grid is coarser): an odd
    integer k < 2^24 times a power of two, divided so that the quotient is k * 2^-150, halfway
    between two subnormals (or between 0 and the smallest); the divisor is a power of two or an
    odd integer m with k * m < 2^24 so that the dividend is exact."""
    k = rng.integers(0, 1 << 23, n, dtype=np.int64) * 2 + 1
    k = k >> rng.integers(0, 24, n)
    k |= 1
    pow2 = rng.random(n) < 0.5
    m = np.where(pow2, 1, rng.integers(0, 1 << 12, n, dtype=np.int64) * 2 + 1)
    m = np.where(k * m < (1 << 24), m, 1)
    xb = rng.integers(-149, 104, n)                         # b = m * 2^xb
    xa = np.clip(xb - 150, -149, None)                      # a = k m 2^(xb - 150)
    xb = xa + 150
    ok = xb + np.log2(m).astype(np.int64) < 104
    xa, xb = np.where(ok, xa, -149), np.where(ok, xb, 1)
    return (_from_int_scaled(k * m, xa, _rand_sign(rng, n)),
            _from_int_scaled(m, xb, _rand_sign(rng, n)))


def gen_div_exact(rng, n):
    """Exact quotients: a = b * c with the significands of b and c short enough that the product
    is exact; the quotient c is anywhere from subnormal to huge."""
    p = rng.integers(1, 24, n)                              # bits of c
    c = (rng.integers(0, 1 << 23, n, dtype=np.int64) >> (23 - p)) | 1
    mb = (rng.integers(0, 1 << 23, n, dtype=np.int64) >> (p - 1)) | 1    # 24 - p bits
    mb &= (np.int64(1) << (24 - p)) - 1
    mb |= 1
    xc = rng.integers(-149, 104, n)
    xb = rng.integers(-149, 104, n)
    xa = np.clip(xb + xc, -149, 104)
    xb = xa - xc
    ok = (xb >= -149) & (xb <= 104)
    xb = np.where(ok, xb, 0)
    xa = np.where(ok, xa, xc)
    return (_from_int_scaled(c * mb, xa, _rand_sign(rng, n)),
            _from_int_scaled(mb, xb, _rand_sign(rng, n)))


def gen_div_binade(rng, n):
    """Quotients just below a power of two 2^k, within one step of the grid below it.

    A quotient of two floats never rounds up to a power of two from below where the grid has 24
    bits: A / B with integer significands A < B < 2^24 is at most 1 - 1/B < 1 - 2^-24, below the
    midpoint 1 - 2^-25 under 1 (likewise below 2^-126, whose grid step is the subnormal one, and
    below the overflow threshold 2^128 (1 - 2^-25)).  Below 2^-127 the subnormal grid is coarser,
    and about half of these quotients round up into the next binade.  A third of the pairs aim at
    2^-126, 2^128 and 1 instead (as close as a quotient comes)."""
    k = rng.integers(-148, -126, n)
    k = np.where(rng.random(n) < 0.33, rng.choice(np.array([-126, 128, 0]), n), k)
    lo, hi = np.maximum(1, 1 - k), np.minimum(254, 254 - k)  # a = b 2^k (1 - u) is normal
    eb = lo + (rng.random(n) * (hi - lo + 1)).astype(np.int64)
    b = _bits(_rand_sign(rng, n), eb, _rand_frac(rng, n))
    step = np.ldexp(1.0, np.maximum(-149 - k, -24))          # the grid step below 2^k, relative
    u = rng.random(n) * step
    with np.errstate(all="ignore"):
        fa = (b.view(np.float32).astype(np.float64) * np.ldexp(1.0 - u, k)).astype(np.float32)
    return fa.view(np.uint32).astype(np.uint32), b.astype(np.uint32)


def gen_div_range(rng, n):
    """Exponent differences at the edges of the range: quotients that overflow, just stay
    finite, underflow into the subnormals or to zero; subnormal dividends and divisors."""
    ea = rng.integers(0, 255, n)
    d = rng.choice(np.array([-128, -127, -126, -125, -150, -149, -148, -24, -23, 0, 1, 126, 127,
                             128, 129, 150, 151]), n) + rng.integers(-2, 3, n)
    eb = np.clip(ea - d, 0, 254)
    return (_bits(_rand_sign(rng, n), ea, _rand_frac(rng, n)),
            _bits(_rand_sign(rng, n), eb, _rand_frac(rng, n)))


DIV_GENERATORS = {
    "div_near_ties": gen_div_near_ties,
    "div_ties": gen_div_ties,
    "div_exact": gen_div_exact,
    "div_binade": gen_div_binade,
    "div_range": gen_div_range,
}


def div_mix(rng: np.random.Generator, per_category: int):
    """The division categories, ``per_category`` pairs each: a, b uint32 (n,), category (n,)."""
    parts = [(name, gen(rng, per_category)) for name, gen in DIV_GENERATORS.items()]
    a = np.concatenate([p[1][0] for p in parts]).astype(np.uint32)
    b = np.concatenate([p[1][1] for p in parts]).astype(np.uint32)
    cat = np.repeat(np.array([p[0] for p in parts]), per_category)
    return a, b, cat


# ------------------------------------------------------------------------------------------------
# What the exact quotient is (to check that the generators make what they promise)


def _value(bits: int) -> Fraction:
    f = bits & 0x7FFFFF
    e = (bits >> 23) & 0xFF
    v = Fraction(f | (1 << 23), 1 << 23) * Fraction(2) ** (e - 127) if e else \
        Fraction(f, 1 << 23) * Fraction(2) ** -126
    return -v if bits >> 31 else v


def quotient_kinds(a: np.ndarray, b: np.ndarray) -> dict[str, np.ndarray]:
    """For finite a and non-zero finite b (uint32 patterns), with exact rational arithmetic: which
    quotients are exact ties (halfway between the two floats around them), lie within 2^-20 ulp of
    a midpoint without being one, or round up to a power of two from below (into the next binade).
    Each a bool array of a.shape."""
    want = reference(a, b)
    kinds = {k: np.zeros(a.size, bool) for k in ("tie", "near_tie", "binade_up")}
    for i, (x, y, r) in enumerate(zip(a.tolist(), b.tolist(), want.tolist())):
        if 0x7F800000 in (x & 0x7F800000, y & 0x7F800000, r & 0x7F800000) or \
                y & 0x7FFFFFFF == 0:
            continue                            # inf or NaN operand or result, zero divisor
        q = abs(_value(x) / _value(y))
        rv = abs(_value(r))
        if rv == q:
            continue
        exp = (r >> 23) & 0xFF
        ulp = Fraction(2) ** (max(exp, 1) - 150)
        if q > rv:
            step = ulp
        else:                                   # below a power of two the grid is twice as fine
            step = -ulp / 2 if (r & 0x7FFFFF) == 0 and exp > 1 else -ulp
        dist = abs(q - (rv + step / 2)) / abs(step)
        kinds["tie"][i] = dist == 0
        kinds["near_tie"][i] = 0 < dist < Fraction(1, 1 << 20)
        mag = r & 0x7FFFFFFF
        pow2 = (mag & 0x7FFFFF) == 0 if exp else (mag & (mag - 1)) == 0
        kinds["binade_up"][i] = pow2 and q < rv
    return kinds
