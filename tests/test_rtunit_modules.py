"""Two modules of the RT unit alone (sim/rtu_units_tb.cpp drives them cycle by cycle): the
traversal stacks (rf_rtu_stack) under random pushes, pops, clears and refills against a reference
model of unbounded stacks with spills, and the divider pool (rf_rtu_divs) under random input gaps
and output stalls against numpy, every division's result taken exactly once."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from driver.backends import verilate
from driver.backends.build import SIM_DIR
from driver.backends.rtunit import unit_sources

U8, U32, I64 = (np.ctypeslib.ndpointer(t, flags="C") for t in (np.uint8, np.uint32, np.int64))


def _lib(top: str, define: str, params: dict) -> ctypes.CDLL:
    path = verilate.build_library(top, unit_sources(), [SIM_DIR / "rtu_units_tb.cpp"],
                                  params=params, name=f"{top}_tb",
                                  verilator_args=["-CFLAGS", f"-D{define}"])
    return ctypes.CDLL(str(path))


RAYS, DEPTH = 4, 3


class StackRef:
    """Per slot: the STACK_DEPTH newest entries (the RAM) and the older ones spilled from it (a
    LIFO), as rf_rtu_stack's contract says; ``depth``: the most entries a slot's RAM held."""

    def __init__(self):
        self.stack = [[] for _ in range(RAYS)]
        self.spilled = [[] for _ in range(RAYS)]
        self.depth = 0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_stack_against_its_reference(seed):
    lib = _lib("rf_rtu_stack", "RTU_TB_STACK", {"RAYS": RAYS, "STACK_DEPTH": DEPTH})
    rng = np.random.default_rng(seed)
    n = 4000
    ref = StackRef()
    ctl = np.zeros(n, np.uint8)
    cs, ps, pp, qs = (np.zeros(n, np.uint32) for _ in range(4))
    exp_top = np.zeros(n, np.uint32)
    exp_flags = np.zeros(n, np.uint8)
    exp_spill = np.zeros(n, np.uint32)
    exp_depth = np.zeros(n, np.uint32)
    refills = 0
    for k in range(n):
        slots = rng.permutation(RAYS)
        c, p, q = (int(s) for s in slots[:3])
        cs[k], ps[k], qs[k], pp[k] = c, p, q, rng.integers(0, 2 ** 32)
        st, sp = ref.stack[q], ref.spilled[q]
        exp_top[k] = st[-1] if st else 0
        exp_depth[k] = ref.depth
        flags = int(not st) | int(bool(sp)) << 1
        full = len(ref.stack[p]) == DEPTH
        bits = 0
        if rng.random() < 0.6:                      # push onto slot p
            bits |= 2
            if full:
                flags |= 4
                exp_spill[k] = ref.stack[p][0]
        if st and rng.random() < 0.5:               # pop slot q
            bits |= 4
        elif not st and sp and rng.random() < 0.5:  # refill slot q
            bits |= 8
        if rng.random() < 0.05:                     # clear slot c
            bits |= 1
        ctl[k], exp_flags[k] = bits, flags
        # the reference's next state
        if bits & 2:
            if full:
                ref.spilled[p].append(ref.stack[p].pop(0))
            ref.stack[p].append(int(pp[k]))
            ref.depth = max(ref.depth, len(ref.stack[p]))
        if bits & 4:
            st.pop()
        if bits & 8:
            sp.pop()
            refills += 1
        if bits & 1:
            ref.stack[c], ref.spilled[c] = [], []
    top, spill, depth = (np.zeros(n, np.uint32) for _ in range(3))
    flags = np.zeros(n, np.uint8)
    lib.stack_run.argtypes = [ctypes.c_int64, U8, U32, U32, U32, U32, U32, U8, U32, U32]
    lib.stack_run(n, ctl, cs, ps, pp, qs, top, flags, spill, depth)
    assert refills > 50 and (exp_flags & 4).sum() > 100          # the stream spills and refills
    assert flags.tolist() == exp_flags.tolist()
    has = (exp_flags & 1) == 0
    assert top[has].tolist() == exp_top[has].tolist()
    spilt = (exp_flags & 4) != 0
    assert spill[spilt].tolist() == exp_spill[spilt].tolist()
    assert depth.tolist() == exp_depth.tolist()


@pytest.mark.parametrize("valid,ready", [(0.9, 0.9), (0.5, 0.3), (1.0, 0.1), (0.2, 1.0)])
def test_divider_pool_under_back_pressure(valid, ready):
    lib = _lib("rf_rtu_divs", "RTU_TB_DIVS", {"DIVIDERS": 3, "TAG_W": 16})
    rng = np.random.default_rng(int(10 * valid + 100 * ready))
    n = 600
    special = np.array([0, 0x80000000, 0x7F800000, 0xFF800000, 0x7FC00000, 1, 0x807FFFFF,
                        0x7F7FFFFF, 0x00800000, 0x3F800000], np.uint32)
    a = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    b = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    a[:100] = rng.choice(special, 100)
    b[50:150] = rng.choice(special, 100)
    cycles = n * 60
    in_valid = (rng.random(cycles) < valid).astype(np.uint8)
    out_ready = (rng.random(cycles) < ready).astype(np.uint8)
    q = np.zeros(n, np.uint32)
    taken = np.full(n, -1, np.int64)
    lib.divs_run.argtypes = [ctypes.c_int64, U8, U8, ctypes.c_int64, U32, U32, U32, I64]
    lib.divs_run.restype = ctypes.c_int64
    got = lib.divs_run(cycles, in_valid, out_ready, n, a, b, q, taken)
    assert got == n and (taken >= 0).all()                       # each result once
    with np.errstate(all="ignore"):
        want = (a.view(np.float32) / b.view(np.float32)).view(np.uint32)
    nan = np.isnan(want.view(np.float32))
    assert (q[nan] == 0x7FC00000).all()
    assert q[~nan].tolist() == want[~nan].tolist()
