"""The binary32 FP units' testbench: RTL model loader, numpy reference, operand generators.

    fpu = FpuModel()                   # builds (cached) sim/fpu_tb_top.sv + sim/fpu_harness.cpp
    a, b, cat = operand_mix(rng, 4096) # uint32 (n,), uint32 (n,), category name per pair (n,)
    got = fpu.run(a, b)                # dict of numpy arrays, keys as in OUTPUTS
    want = reference(a, b)             # same keys, numpy float32 semantics, NaN -> 0x7FC00000
"""

from __future__ import annotations

import ctypes

import numpy as np

from driver.backends.build import RTL_DIR, SIM_DIR, source_names
from driver.backends.verilate import build_library

CANONICAL_NAN = np.uint32(0x7FC00000)

# The FP unit files are those of the datapath's one source list (rtl/sources.txt, compile order:
# the package first) plus the two wrappers that exist only to test the package's normalize and
# round functions on their own (the arithmetic units call the functions, not the modules).
FP_PREFIX = "rf_fp_"
TEST_WRAPPERS = ("rf_fp_normalize.sv", "rf_fp_round.sv")
FP_SOURCES = [RTL_DIR / f for f in source_names() if f.startswith(FP_PREFIX)] + \
    [RTL_DIR / f for f in TEST_WRAPPERS]
# Every unit module (not the package) is linted on its own as the top of the FP file set.
UNIT_SOURCES = {p.stem: FP_SOURCES for p in FP_SOURCES if not p.stem.endswith("_pkg")}
FPU_TB_SOURCES = FP_SOURCES + [SIM_DIR / "fpu_tb_top.sv"]
FPU_HARNESS = [SIM_DIR / "fpu_harness.cpp"]

OUTPUTS = ("add", "sub", "mul", "lt", "le", "eq", "unord", "min", "max")

_u32p = np.ctypeslib.ndpointer(dtype=np.uint32, flags="C_CONTIGUOUS")
_u8p = np.ctypeslib.ndpointer(dtype=np.uint8, flags="C_CONTIGUOUS")


class FpuModel:
    """The Verilated fpu_tb_top: every unit evaluated on the same operand pairs, one C call."""

    def __init__(self) -> None:
        self.library = build_library("fpu_tb_top", FPU_TB_SOURCES, FPU_HARNESS)
        self._dll = ctypes.CDLL(str(self.library))
        self._eval = self._dll.fpu_eval
        self._eval.restype = ctypes.c_int
        self._eval.argtypes = [_u32p, _u32p, ctypes.c_size_t, _u32p, _u32p, _u32p, _u8p,
                               _u32p, _u32p]

    def run(self, a: np.ndarray, b: np.ndarray) -> dict[str, np.ndarray]:
        """a, b: (n,) uint32 bit patterns -> dict of (n,) arrays (uint32 values, bool flags)."""
        a = np.ascontiguousarray(a, dtype=np.uint32)
        b = np.ascontiguousarray(b, dtype=np.uint32)
        n = a.shape[0]
        assert b.shape == (n,)
        out = {k: np.empty(n, np.uint32) for k in ("add", "sub", "mul", "min", "max")}
        flags = np.empty(n, np.uint8)
        self._eval(a, b, n, out["add"], out["sub"], out["mul"], flags, out["min"], out["max"])
        for bit, name in enumerate(("lt", "le", "eq", "unord")):
            out[name] = (flags >> bit) & 1 == 1
        return out


# ------------------------------------------------------------------------------------------------
# Reference: numpy float32


def _canon(x: np.ndarray) -> np.ndarray:
    bits = x.view(np.uint32).copy()
    bits[np.isnan(x)] = CANONICAL_NAN
    return bits


def reference(a: np.ndarray, b: np.ndarray) -> dict[str, np.ndarray]:
    """numpy float32 results for uint32 operand bit patterns (NaN results canonicalised)."""
    fa = a.view(np.float32)
    fb = b.view(np.float32)
    with np.errstate(all="ignore"):
        ref = {"add": _canon(fa + fb), "sub": _canon(fa - fb), "mul": _canon(fa * fb),
               "lt": fa < fb, "le": fa <= fb, "eq": fa == fb,
               "unord": np.isnan(fa) | np.isnan(fb)}
    # IEEE 754-2019 minimum/maximum; among equal values (only -0/+0 differ) -0 is the smaller.
    lt, gt = fa < fb, fb < fa
    a_neg = (a >> 31) == 1
    a_min = lt | (~gt & a_neg)
    ref["min"] = np.where(ref["unord"], CANONICAL_NAN, np.where(a_min, a, b)).astype(np.uint32)
    ref["max"] = np.where(ref["unord"], CANONICAL_NAN, np.where(a_min, b, a)).astype(np.uint32)
    return ref


# ------------------------------------------------------------------------------------------------
# Operand generators: each returns (a, b) uint32 arrays of length n


def _bits(sign, exp, frac) -> np.ndarray:
    return ((np.asarray(sign, np.uint32) << 31) | (np.asarray(exp, np.uint32) << 23)
            | np.asarray(frac, np.uint32)).astype(np.uint32)


def _rand_sign(rng, n):
    return rng.integers(0, 2, n, dtype=np.uint32)


def _rand_frac(rng, n):
    return rng.integers(0, 1 << 23, n, dtype=np.uint32)


def _from_int_scaled(m: np.ndarray, e: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """Bits of (-1)^sign * m * 2^e (exact: m < 2^24 and the result is representable)."""
    v = np.ldexp(m.astype(np.float64), e.astype(np.int64)).astype(np.float32)
    return v.view(np.uint32) | (sign.astype(np.uint32) << 31)


def gen_random_bits(rng, n):
    return (rng.integers(0, 1 << 32, n, dtype=np.uint32),
            rng.integers(0, 1 << 32, n, dtype=np.uint32))


def gen_subnormal_both(rng, n):
    return (_bits(_rand_sign(rng, n), 0, _rand_frac(rng, n)),
            _bits(_rand_sign(rng, n), 0, _rand_frac(rng, n)))


def gen_subnormal_one(rng, n):
    sub = _bits(_rand_sign(rng, n), 0, _rand_frac(rng, n))
    # the other operand: small normals (interesting sums/products) or anything
    small = _bits(_rand_sign(rng, n), rng.integers(1, 40, n), _rand_frac(rng, n))
    other = np.where(rng.random(n) < 0.6, small, rng.integers(0, 1 << 32, n, dtype=np.uint32))
    swap = rng.random(n) < 0.5
    return (np.where(swap, sub, other).astype(np.uint32),
            np.where(swap, other, sub).astype(np.uint32))


SPECIALS = np.array([
    0x00000000, 0x80000000,              # +-0
    0x7F800000, 0xFF800000,              # +-inf
    0x7FC00000, 0xFFC00000, 0x7FC00001,  # quiet NaNs
    0x7FFFFFFF, 0xFFFFFFFF, 0x7FD23456,
    0x7F800001, 0xFF800001, 0x7FA00000,  # signalling NaNs
    0x7FBFFFFF,
    0x00000001, 0x80000001, 0x007FFFFF, 0x807FFFFF,  # subnormal extremes
    0x00800000, 0x80800000,              # smallest normals
    0x7F7FFFFF, 0xFF7FFFFF, 0x7F7FFFFE,  # largest finite
    0x3F800000, 0xBF800000, 0x3F800001, 0x3F7FFFFF,  # 1 and neighbours
], dtype=np.uint32)


def gen_specials(rng, n):
    """Zeros, infinities, NaNs (quiet, signalling, payloads), extremes vs specials and randoms."""
    a = rng.choice(SPECIALS, n)
    b = np.where(rng.random(n) < 0.5, rng.choice(SPECIALS, n),
                 rng.integers(0, 1 << 32, n, dtype=np.uint32)).astype(np.uint32)
    swap = rng.random(n) < 0.5
    return np.where(swap, b, a).astype(np.uint32), np.where(swap, a, b).astype(np.uint32)


def gen_add_ties(rng, n, near: bool = False):
    """a + b exactly halfway between two floats: b's bits below a's lsb are exactly 100...0.
    With ``near``: just above or below halfway (100...01, 011...11): the sticky bit decides."""
    ea = rng.integers(26, 254, n)
    d = rng.integers(1, 25, n)                         # exponent difference 1..24
    a = _bits(_rand_sign(rng, n), ea, _rand_frac(rng, n))
    sig_b = rng.integers(1 << 23, 1 << 24, n, dtype=np.uint32)
    low_mask = (np.uint32(1) << d.astype(np.uint32)) - np.uint32(1)
    half = np.uint32(1) << (d - 1).astype(np.uint32)
    low = half
    if near:
        low = np.where(rng.random(n) < 0.5, half | np.uint32(1), half - np.uint32(1)) & low_mask
    sig_b = (sig_b & ~low_mask) | low
    sig_b |= np.uint32(1 << 23)                        # keep it normal
    b = _bits(_rand_sign(rng, n), ea - d, sig_b & np.uint32(0x7FFFFF))
    return a, b


def gen_near_ties(rng, n):
    """Full-width products and sums at, just above and just below a halfway point.

    Products: m1 (24-bit, odd) times m2 = T / m1 mod 2^24, so that the full-width 48-bit
    product's low bits are T = 100..01 or 011..1 below its rounding position (for either
    normalisation): only the last bit of the product separates it from a tie.  (Exact product
    ties need exactly 25 significant bits: gen_mul_ties.)  Sums: gen_add_ties(near=True).
    """
    h = n // 2
    m1 = rng.integers(1 << 23, 1 << 24, h, dtype=np.int64) | 1
    inv = np.ones(h, np.int64)                          # m1^-1 mod 2^24 by Newton iteration
    for _ in range(5):
        inv = (inv * (2 - m1 * inv)) & 0xFFFFFF
    half = np.where(rng.random(h) < 0.5, 1 << 23, 1 << 22)   # lzc 0 or 1 rounding position
    target = half + np.where(rng.random(h) < 0.5, 1, -1)
    m2 = (target * inv) & 0xFFFFFF                      # odd, so never 0
    total = rng.integers(-140, 60, h)
    x = np.clip(rng.integers(-149, 104, h), np.maximum(-149, total - 103),
                np.minimum(103, total + 149))
    ma = _from_int_scaled(m1, x, _rand_sign(rng, h))
    mb = _from_int_scaled(m2, total - x, _rand_sign(rng, h))
    aa, ab = gen_add_ties(rng, n - h, near=True)
    return np.concatenate([ma, aa]).astype(np.uint32), np.concatenate([mb, ab]).astype(np.uint32)


def gen_mul_ties(rng, n):
    """a * b exactly halfway between two floats.

    Normal ties: odd integer significands m1, m2 whose product has exactly 25 bits, scaled into
    the normal range.  Subnormal ties (a quarter): odd m1, m2 with a product below 2^24, scaled by
    2^-150 so that the product's last bit is exactly half the smallest subnormal.
    """
    p = rng.integers(1, 25, n)                         # bits in m1
    m1 = (rng.integers(0, 1 << 24, n, dtype=np.int64) >> (24 - p)) | 1
    m1 |= np.int64(1) << (p - 1)
    lo = -(-(1 << 24) // m1)                           # ceil(2^24 / m1)
    hi = ((1 << 25) - 1) // m1
    m2 = np.minimum(lo + (rng.random(n) * (hi - lo + 1)).astype(np.int64), hi)
    m2 = np.where(m2 % 2 == 0, np.where(m2 + 1 <= hi, m2 + 1, m2 - 1), m2)
    ok = (m2 >= lo) & (m2 <= hi) & (m2 % 2 == 1) & (m1 < (1 << 24)) & (m2 < (1 << 24))
    m1 = np.where(ok, m1, 3)
    m2 = np.where(ok, m2, 5592407)                     # 3 * 5592407 = 2^24 + 5: 25 bits, odd
    total = rng.integers(-150, 100, n)                 # product = m1 * m2 * 2^total
    # subnormal ties: p1 + p2 <= 24 bits, product scaled by exactly 2^-150
    sub = rng.random(n) < 0.25
    p1 = rng.integers(1, 24, n)
    s1 = (rng.integers(0, 1 << 23, n, dtype=np.int64) >> (23 - p1)) | 1
    s2 = (rng.integers(0, 1 << 23, n, dtype=np.int64) >> (p1 - 1).clip(0)) | 1
    s2 = s2 & ((np.int64(1) << (24 - p1)) - 1) | 1
    m1 = np.where(sub, s1, m1)
    m2 = np.where(sub, s2, m2)
    total = np.where(sub, -150, total)
    x = rng.integers(-149, 104, n)
    x = np.clip(x, np.maximum(-149, total - 103), np.minimum(103, total + 149))
    y = total - x
    return (_from_int_scaled(m1, x, _rand_sign(rng, n)),
            _from_int_scaled(m2, y, _rand_sign(rng, n)))


def gen_overflow(rng, n):
    """Huge operands: products and sums that overflow to inf or just stay finite."""
    a = _bits(_rand_sign(rng, n), rng.integers(190, 255, n), _rand_frac(rng, n))
    big = _bits(_rand_sign(rng, n), rng.integers(250, 255, n), _rand_frac(rng, n))
    b = np.where(rng.random(n) < 0.5, big,
                 _bits(_rand_sign(rng, n), rng.integers(100, 255, n), _rand_frac(rng, n)))
    near_max = np.uint32(0x7F7FFFFF) - rng.integers(0, 4, n, dtype=np.uint32)
    sel = rng.random(n) < 0.3
    a = np.where(sel, near_max | (_rand_sign(rng, n) << 31), a)
    return a.astype(np.uint32), b.astype(np.uint32)


def gen_underflow(rng, n):
    """Products with exponents around the subnormal range; sums of tiny normals."""
    ea = rng.integers(1, 128, n)
    eb = np.clip(127 - ea + rng.integers(-30, 6, n) - 0, 0, 254)
    a = _bits(_rand_sign(rng, n), ea, _rand_frac(rng, n))
    b = _bits(_rand_sign(rng, n), eb, _rand_frac(rng, n))
    tiny = rng.random(n) < 0.3
    a = np.where(tiny, _bits(_rand_sign(rng, n), rng.integers(0, 4, n), _rand_frac(rng, n)), a)
    b = np.where(tiny, _bits(_rand_sign(rng, n), rng.integers(0, 4, n), _rand_frac(rng, n)), b)
    return a.astype(np.uint32), b.astype(np.uint32)


def gen_cancellation(rng, n):
    """a ~ -b (for add) and a ~ b (for sub): same or adjacent exponent, few differing low bits."""
    a = rng.integers(0, 0x7F800000, n, dtype=np.uint32) | (_rand_sign(rng, n) << 31)
    k = rng.integers(0, 24, n).astype(np.uint32)
    noise = rng.integers(0, 1 << 23, n, dtype=np.uint32) & ((np.uint32(1) << k) - np.uint32(1))
    b = (a ^ noise).astype(np.int64)
    b += rng.integers(-1, 2, n) * (1 << 23) * (rng.random(n) < 0.3)   # adjacent exponent
    b = np.clip(b & 0x7FFFFFFF, 0, 0x7F7FFFFF).astype(np.uint32)
    b |= np.where(rng.random(n) < 0.5, a & np.uint32(0x80000000),
                  ~a & np.uint32(0x80000000)).astype(np.uint32)
    return a, b


def gen_exp_diff(rng, n):
    """Exponent differences around 22..28 (the alignment shifter's edge), both orders."""
    ea = rng.integers(30, 255, n)
    d = rng.integers(20, 30, n)
    a = _bits(_rand_sign(rng, n), ea, _rand_frac(rng, n))
    fb = np.where(rng.random(n) < 0.3, rng.choice(np.array([0, 1, 0x7FFFFF, 0x400000], np.uint32),
                                                  n), _rand_frac(rng, n))
    b = _bits(_rand_sign(rng, n), np.maximum(ea - d, 0), fb)
    swap = rng.random(n) < 0.5
    return np.where(swap, b, a).astype(np.uint32), np.where(swap, a, b).astype(np.uint32)


def gen_compare(rng, n):
    """Equal, neighbouring and sign-flipped pairs (order edge cases for cmp and minmax)."""
    a = rng.integers(0, 1 << 32, n, dtype=np.uint32)
    kind = rng.integers(0, 4, n)
    b = np.select([kind == 0, kind == 1, kind == 2],
                  [a, a + np.uint32(1), a ^ np.uint32(0x80000000)],
                  a - np.uint32(1)).astype(np.uint32)
    zeros = rng.random(n) < 0.1
    a = np.where(zeros, _rand_sign(rng, n) << 31, a).astype(np.uint32)
    b = np.where(zeros, _rand_sign(rng, n) << 31, b).astype(np.uint32)
    return a, b


GENERATORS = {
    "random_bits": gen_random_bits,
    "subnormal_both": gen_subnormal_both,
    "subnormal_one": gen_subnormal_one,
    "specials": gen_specials,
    "add_ties": gen_add_ties,
    "mul_ties": gen_mul_ties,
    "near_ties": gen_near_ties,
    "overflow": gen_overflow,
    "underflow": gen_underflow,
    "cancellation": gen_cancellation,
    "exp_diff_22_28": gen_exp_diff,
    "compare_edges": gen_compare,
}


def operand_mix(rng: np.random.Generator, per_category: int):
    """All categories, ``per_category`` pairs each.

    Returns a uint32 (n,), b uint32 (n,), category name (n,)."""
    parts = [(name, gen(rng, per_category)) for name, gen in GENERATORS.items()]
    a = np.concatenate([p[1][0] for p in parts]).astype(np.uint32)
    b = np.concatenate([p[1][1] for p in parts]).astype(np.uint32)
    cat = np.repeat(np.array([p[0] for p in parts]), per_category)
    return a, b, cat


def exact_tie_fraction(a: np.ndarray, b: np.ndarray, op: str) -> float:
    """Fraction of pairs whose exact (float64) sum/product lies exactly halfway between two
    adjacent float32 values (for checking that the tie generators really make ties)."""
    fa = a.view(np.float32).astype(np.float64)
    fb = b.view(np.float32).astype(np.float64)
    with np.errstate(all="ignore"):
        exact = fa + fb if op == "add" else fa * fb   # exact in float64 for these generators
        r32 = exact.astype(np.float32)
        toward = np.where(exact > r32, np.float32(np.inf), np.float32(-np.inf)).astype(np.float32)
        other = np.nextafter(r32, toward).astype(np.float64)
        tie = np.isfinite(exact) & (exact != r32) & (2 * exact == r32.astype(np.float64) + other)
    return float(np.mean(tie))
