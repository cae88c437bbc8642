"""The binary32 divider (rtl/rf_fp_div.sv): every result bit-exact to numpy's float32 a / b, under
random back-pressure on both ports, with a scoreboard of order, tags and the constant latency.

A test bench in the shape of cocotb's: the driver and the monitor are the C++ harness
(sim/fp_div_harness.cpp: offers held until taken, garbage between offers, output stalls), the
reference is numpy, the scoreboard is ``check``.  Operands: directed cases, every pair of the
FP units' special values, the FP units' shared operand mix (tests/support/fpu.py), the division
categories of tests/support/fpdiv.py (near-ties, exact ties, exact quotients, binade edges, range
edges) and hypothesis' random pairs.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from driver.backends.build import RTL_DIR, DIV_SOURCE_LIST, source_names
from driver.core.resources import ROOT
from driver.backends.verilate import lint
from support.fpdiv import (DIV_SOURCES, DIV_TB_SOURCES, DivModel, div_mix, quotient_kinds,
                           reference, tags_for)
from support.fpu import SPECIALS, operand_mix
from support.testbench import PRESSURE_IDS, PRESSURES

DEFAULT_PER_CATEGORY = 12288     # (12 shared + 5 division categories) x 12,288 = 208,896 pairs
PRESSURE_PAIRS = 49152           # per back-pressure mix: 6 x 49,152 = 294,912 pairs
SLOW_PAIRS = 24_000_000
MAX_REPORTED = 8


@pytest.fixture(scope="module")
def div():
    return DivModel()


def div_cycles_documented() -> int:
    """The latency docs/fp_div.md gives its users."""
    text = (ROOT / "docs" / "fp_div.md").read_text()
    return int(re.search(r"`DIV_CYCLES` = (\d+)", text)[1])


def check(div: DivModel, a, b, cat=None, gaps=0.0, stalls=0.0, seed=0, salt=0):
    """Run a / b through the RTL under the given back-pressure; the scoreboard: one result per
    division, in order, each with its own tag, bit-exact to numpy, every latency DIV_CYCLES, no
    protocol error, never ready while busy.  Returns the run."""
    a = np.asarray(a, np.uint32)
    b = np.asarray(b, np.uint32)
    cat = np.full(a.size, "directed") if cat is None else cat
    tags = tags_for(a.size, salt)
    run = div.run(a, b, tags, gaps=gaps, stalls=stalls, seed=seed)
    errors = []
    if run.protocol_errors:
        errors.append(f"{run.protocol_errors} protocol errors (out_valid_o dropped or q_o/tag_o "
                      "changed before the result was taken)")
    if run.ready_while_busy:
        errors.append(f"in_ready_o high in {run.ready_while_busy} cycles with a division inside")
    bad_tag = np.flatnonzero(run.tag != tags)
    if bad_tag.size:
        i = bad_tag[0]
        errors.append(f"{bad_tag.size} results out of order or with a wrong tag; first at result "
                      f"{i}: tag 0x{int(run.tag[i]):08x}, expected 0x{int(tags[i]):08x}")
    bad_lat = np.flatnonzero(run.latency != run.div_cycles)
    if bad_lat.size:
        i = bad_lat[0]
        errors.append(f"{bad_lat.size} latencies differ from DIV_CYCLES = {run.div_cycles}; "
                      f"first: {int(run.latency[i])} cycles for a=0x{int(a[i]):08x} "
                      f"b=0x{int(b[i]):08x}")
    want = reference(a, b)
    bad = np.flatnonzero(run.q != want)
    if bad.size:
        rows = [f"  a=0x{int(a[i]):08x} b=0x{int(b[i]):08x} rtl=0x{int(run.q[i]):08x} "
                f"numpy=0x{int(want[i]):08x} [{cat[i]}]" for i in bad[:MAX_REPORTED]]
        errors.append(f"{bad.size} of {a.size} quotients differ, first ones:\n" + "\n".join(rows))
    if errors:
        pytest.fail("\n".join(errors), pytrace=False)
    return run


# ------------------------------------------------------------------------------------------------
# Directed cases

NAN, NNAN, SNAN = 0x7FC00000, 0xFFC00000, 0x7F800001
INF, NINF, ZERO, NZERO = 0x7F800000, 0xFF800000, 0x00000000, 0x80000000
ONE, TWO, THREE, HALF = 0x3F800000, 0x40000000, 0x40400000, 0x3F000000
MAXF, MINN, MINS, MAXS = 0x7F7FFFFF, 0x00800000, 0x00000001, 0x007FFFFF

DIRECTED = {
    # zeros and infinities
    "+0/+0": (ZERO, ZERO), "-0/+0": (NZERO, ZERO), "+0/-0": (ZERO, NZERO),
    "-0/-0": (NZERO, NZERO), "1/+0": (ONE, ZERO), "1/-0": (ONE, NZERO), "-1/+0": (0xBF800000, ZERO),
    "min subnormal/-0": (MINS, NZERO), "inf/0": (INF, ZERO), "-inf/-0": (NINF, NZERO),
    "+0/1": (ZERO, ONE), "-0/1": (NZERO, ONE), "+0/-3": (ZERO, 0xC0400000),
    "0/inf": (ZERO, INF), "-0/-inf": (NZERO, NINF), "0/min subnormal": (ZERO, MINS),
    "inf/inf": (INF, INF), "-inf/inf": (NINF, INF), "inf/3": (INF, THREE),
    "-inf/min subnormal": (NINF, MINS), "3/inf": (THREE, INF), "max/-inf": (MAXF, NINF),
    "min subnormal/inf": (MINS, INF),
    # NaN in each position
    "NaN/1": (NAN, ONE), "1/NaN": (ONE, NAN), "NaN/NaN": (NAN, NNAN), "-NaN/2": (NNAN, TWO),
    "sNaN/1": (SNAN, ONE), "1/sNaN": (ONE, SNAN), "NaN/0": (NAN, ZERO), "0/NaN": (ZERO, NAN),
    "NaN/inf": (NAN, INF), "inf/NaN": (INF, 0x7FFFFFFF),
    "payload NaN/subnormal": (0xFFD23456, MINS),
    # plain quotients
    "1/3": (ONE, THREE), "2/3": (TWO, THREE), "-1/3": (0xBF800000, THREE),
    "1/10": (ONE, 0x41200000),
    "1/7": (ONE, 0x40E00000), "355/113": (0x43B18000, 0x42E20000),
    # exact quotients
    "6/3": (0x40C00000, THREE), "1/1": (ONE, ONE), "1/2": (ONE, TWO),
    "0.75/0.5": (0x3F400000, HALF), "max/max": (MAXF, MAXF), "max/1": (MAXF, ONE),
    "max/2": (MAXF, TWO), "-max/-1": (0xFF7FFFFF, 0xBF800000),
    "min normal/min normal": (MINN, MINN), "min subnormal/min subnormal": (MINS, MINS),
    "min normal/min subnormal": (MINN, MINS),
    # extremes
    "max/min normal": (MAXF, MINN), "min normal/max": (MINN, MAXF), "max/0.5": (MAXF, HALF),
    "max/(1 - 2^-24) overflows": (MAXF, 0x3F7FFFFF), "max/(1 + 2^-23)": (MAXF, 0x3F800001),
    "min subnormal/max": (MINS, MAXF), "max/min subnormal": (MAXF, MINS),
    "1/min subnormal": (ONE, MINS), "1/max": (ONE, MAXF), "1/min normal": (ONE, MINN),
    "2^-127/2^-127": (0x00400000, 0x00400000),
    # subnormal / normal and normal / subnormal
    "max subnormal/(1 + 2^-23)": (MAXS, 0x3F800001), "max subnormal/3": (MAXS, THREE),
    "min subnormal/1.5": (MINS, 0x3FC00000), "min subnormal/1": (MINS, ONE),
    "1/max subnormal": (ONE, MAXS), "2^-140/max subnormal": (0x00000200, MAXS),
    "max subnormal/2^-140": (MAXS, 0x00000200), "3e-39/7e-45": (0x0020A9E5, 0x00000005),
    # overflow and underflow
    "2^127/0.25": (0x7F000000, 0x3E800000), "2^127/0.5": (0x7F000000, HALF),
    "-2^127/(0.5 - ulp)": (0xFF000000, 0x3EFFFFFF), "2^100/2^-30": (0x71800000, 0x30800000),
    "min normal/2": (MINN, TWO), "min normal/3": (MINN, THREE),
    "2^-100/2^40": (0x0D800000, 0x53800000), "2^-100/2^60": (0x0D800000, 0x5D800000),
    "1/2^149 (exact min subnormal)": (ONE, 0x7A000000), "1/2^150 (tie to 0)": (ONE, 0x7A800000),
    "1/(2^150 - ulp)": (ONE, 0x7A7FFFFF), "-1/(2^149 + ulp)": (0xBF800000, 0x7A000001),
    # exact ties below the normal range (round half to even) and their neighbours
    "min subnormal/2 (tie to 0)": (MINS, TWO),
    "3 min subnormal/2 (tie up to 2)": (0x00000003, TWO),
    "5 min subnormal/2 (tie down to 2)": (0x00000005, TWO),
    "(2^-126 + ulp)/2 (tie to even)": (0x00800001, TWO),
    "(2^-126 + 3 ulp)/2 (tie up)": (0x00800003, TWO), "3 min subnormal/6": (0x00000003, 0x40C00000),
    "min subnormal/(2 - ulp)": (MINS, 0x3FFFFFFF), "min subnormal/(2 + ulp)": (MINS, 0x40000001),
    # rounding up into the next (subnormal) binade; the quotients closest below 1 and 2^-126 (a
    # quotient never rounds up to a power of two on the 24-bit grid: fpdiv.gen_div_binade)
    "up to 2^-136": (0x05F13F54, 0x47F13F55), "up to 2^-127": (0x3248D184, 0x7348D18D),
    "(1 - 2^-23)/(1 - 2^-24), closest below 1": (0x3F7FFFFE, 0x3F7FFFFF),
    "max subnormal/(1 - 2^-24), closest below 2^-126": (MAXS, 0x3F7FFFFF),
    "min normal/(1 + 2^-23)": (MINN, 0x3F800001),
}


def test_directed(div):
    a, b = np.array(list(DIRECTED.values()), np.uint32).T
    check(div, a, b, np.array(list(DIRECTED)))


def test_directed_cases_reach_their_targets():
    """The directed list holds what it claims: ties, binade crossings, overflow, every special."""
    a, b = np.array(list(DIRECTED.values()), np.uint32).T
    kinds = quotient_kinds(a, b)
    names = np.array(list(DIRECTED))
    assert {"min subnormal/2 (tie to 0)", "3 min subnormal/2 (tie up to 2)"} <= \
        set(names[kinds["tie"]])
    assert {"up to 2^-136", "up to 2^-127"} <= set(names[kinds["binade_up"]])
    want = reference(a, b)
    assert np.count_nonzero(want == 0x7FC00000) >= 15
    assert np.count_nonzero((want & 0x7FFFFFFF) == 0x7F800000) >= 10
    assert np.count_nonzero(((want & 0x7F800000) == 0) & ((want & 0x7FFFFF) != 0)) >= 15


def test_every_pair_of_special_values(div):
    """Every pair of the FP units' special and boundary values, in both orders."""
    a, b = np.meshgrid(SPECIALS, SPECIALS)
    check(div, a.ravel(), b.ravel())


# ------------------------------------------------------------------------------------------------
# Operand mixes, latency and throughput


@pytest.fixture(scope="module")
def mix():
    rng = np.random.default_rng(20240601)
    a1, b1, c1 = operand_mix(rng, DEFAULT_PER_CATEGORY)
    a2, b2, c2 = div_mix(rng, DEFAULT_PER_CATEGORY)
    return np.concatenate([a1, a2]), np.concatenate([b1, b2]), np.concatenate([c1, c2])


def test_operand_mix_back_to_back(div, mix):
    """The shared mix and the division categories, the output always ready: a division every
    DIV_CYCLES + 1 cycles, exactly."""
    a, b, cat = mix
    assert a.size >= 200_000
    run = check(div, a, b, cat)
    assert run.div_cycles == div_cycles_documented()
    assert run.cycles == a.size * (run.div_cycles + 1)


@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
def test_back_pressure(div, mix, gaps, stalls):
    """Random input gaps and output stalls: order, tags, results and latency unchanged."""
    a, b, cat = mix
    rng = np.random.default_rng(int(gaps * 100 + stalls * 10))
    pick = rng.choice(a.size, PRESSURE_PAIRS, replace=False)
    run = check(div, a[pick], b[pick], cat[pick], gaps=gaps, stalls=stalls, seed=7,
                salt=int(gaps * 1000 + stalls * 10))
    if gaps or stalls:
        assert run.cycles > PRESSURE_PAIRS * (run.div_cycles + 1)


def test_division_generators_make_what_they_promise():
    rng = np.random.default_rng(3)
    a, b, cat = div_mix(rng, 2000)
    kinds = quotient_kinds(a, b)
    frac = {name: {k: float(np.mean(v[cat == name])) for k, v in kinds.items()}
            for name in np.unique(cat)}
    assert frac["div_ties"]["tie"] == 1.0
    assert frac["div_near_ties"]["near_tie"] > 0.4
    assert frac["div_binade"]["binade_up"] > 0.25
    exact = a.view(np.float32).astype(np.float64) / b.view(np.float32) == \
        reference(a, b).view(np.float32)
    assert exact[cat == "div_exact"].all()


def test_single_division_and_empty_run(div):
    run = check(div, [0x40490FDB], [0x402DF854])
    assert run.cycles == run.div_cycles + 1
    empty = div.run(np.zeros(0, np.uint32), np.zeros(0, np.uint32))
    assert empty.cycles == 0 and empty.q.size == 0


def test_reset_during_a_division(div):
    """A reset in any cycle of a division empties the unit: the next run starts clean (its
    results, tags, latencies and cycle count are those of a run from power-up)."""
    a, b = np.array([[0x3F800000, 0x40400000], [0x00000003, 0x40000000]], np.uint32).T
    for stop in range(1, a.size * (div_cycles_documented() + 1)):   # every cycle of the run
        assert div.run(a, b, max_cycles=stop) is None
        run = check(div, a, b)
        assert run.cycles == a.size * (run.div_cycles + 1)


# ------------------------------------------------------------------------------------------------
# Property-based: hypothesis' pairs (it favours zeros, extremes and repeated values)

_pairs = st.lists(st.tuples(st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1)),
                  min_size=1, max_size=64)
_float_pairs = st.lists(st.tuples(st.floats(width=32), st.floats(width=32)), min_size=1,
                        max_size=64)


@settings(max_examples=60, deadline=None)
@given(pairs=_pairs, pressure=st.sampled_from(PRESSURES))
def test_hypothesis_bit_patterns(div, pairs, pressure):
    a, b = np.array(pairs, np.uint32).T
    check(div, a, b, gaps=pressure[0], stalls=pressure[1], seed=len(pairs))


@settings(max_examples=60, deadline=None)
@given(pairs=_float_pairs)
def test_hypothesis_floats(div, pairs):
    f = np.array(pairs, np.float32)
    a, b = f.view(np.uint32).T
    check(div, np.ascontiguousarray(a), np.ascontiguousarray(b))


@pytest.mark.slow
def test_slow_many_pairs(div):
    """Millions of pairs (the shared mix and the division categories), with a different
    back-pressure mix for every chunk."""
    rng = np.random.default_rng(99)
    done = chunk = 0
    while done < SLOW_PAIRS:
        a1, b1, c1 = operand_mix(rng, 1 << 16)
        a2, b2, c2 = div_mix(rng, 1 << 16)
        gaps, stalls = PRESSURES[chunk % len(PRESSURES)]
        check(div, np.concatenate([a1, a2]), np.concatenate([b1, b2]),
              np.concatenate([c1, c2]), gaps=gaps, stalls=stalls, seed=chunk, salt=chunk)
        done += a1.size + a2.size
        chunk += 1
    assert done >= SLOW_PAIRS


# ------------------------------------------------------------------------------------------------
# Sources and lint


@pytest.mark.parametrize("tag_w", [1, 8, 32])
def test_lint_clean(tag_w):
    assert lint("rf_fp_div", [RTL_DIR / "lint.vlt", *DIV_SOURCES], {"TAG_W": tag_w}) == ""


def test_tb_top_lint_clean():
    assert lint("fp_div_tb_top", [RTL_DIR / "lint.vlt", *DIV_TB_SOURCES]) == ""


def test_divider_is_no_part_of_the_datapath_build():
    """The datapath's source list (every file of it keys the datapath's build) does not name the
    divider's own files; the divider's list names the FP package it shares, first."""
    own = source_names(DIV_SOURCE_LIST)
    shared = set(own) & set(source_names())
    assert own[0] == "rf_fp_pkg.sv" and shared == {"rf_fp_pkg.sv"}
    assert "rf_fp_div.sv" in own and all((RTL_DIR / f).is_file() for f in own)
