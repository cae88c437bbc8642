"""The NO_CULL request flag (docs/datapath.md#requests-and-responses, #triangle): the TRIANGLE test
accepts both faces.

Golden model, the fast RTL harness ("rtl") and pyverilator, bit for bit, through the testbench
(driver, monitor, golden scoreboard): random streams where half the requests set NO_CULL (random
triangles of both windings with the golden tests' special cases, boxes that must ignore the flag)
under gaps and stalls on every build; the paper's 11 TRIANGLE cases with NO_CULL (the same results
except the back face, which hits); directed both-face, edge-on, -0 and NaN cases; the wire
placement of ``flags`` (a ray field: the harness's traversal requests carry it) and the checks of
reserved flag bits.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import driver
from driver import FLAG_NO_CULL, QUADBOX, TRIANGLE, DatapathError
from driver.backends.build import RTL_DIR, rtl_params
from driver.backends.harness import build_requests
from driver.core.wire import (CONTROL_WORD, RAY_FIELDS, RAY_WORDS, REQUEST, ray_words,
                              unpack_requests)
from driver.core.layout import TRI_NODE, TRI_TYPE, NodeRef
from support.cases import CASES, FRONT, expect_tri, t_of, tri_request
from support.streams import mixed_stream
from support.testbench import PRESSURE_IDS, PRESSURES, Testbench, run_isolated

CONFIGS = [(False, False), (False, True), (True, False), (True, True)]
CONFIG_IDS = ["baseline-unified", "baseline-disjoint", "extended-unified", "extended-disjoint"]
BACK = (FRONT[0], FRONT[2], FRONT[1])           # FRONT wound the other way: seen from its back


def no_cull_stream(seed: int, n_box: int, n_tri: int) -> np.ndarray:
    """The golden tests' random QUADBOX/TRIANGLE stream with NO_CULL set on a random half."""
    req = mixed_stream(seed, n_box, n_tri)
    rng = np.random.default_rng(seed + 7000)
    req["flags"] = np.where(rng.random(len(req)) < 0.5, FLAG_NO_CULL, 0)
    return req


def with_flags(req: np.ndarray, flags: int) -> np.ndarray:
    out = req.copy()
    out["flags"] = flags
    return out


# ----------------------------------------------------------------------------------------------
# wire placement and request checks

def test_flags_are_a_ray_field_in_the_control_word():
    f = REQUEST.field["flags"]
    assert (f.word, f.bits) == (CONTROL_WORD, 8) and "flags" in RAY_FIELDS
    assert f.word + f.words <= RAY_WORDS                   # the harness's ray table carries it
    assert "reset_accumulator" not in RAY_FIELDS           # an extended-op field, not a ray's
    req = driver.prepare_rays([[0, 0, 0]], [[0, 0, -1]], flags=FLAG_NO_CULL)
    word = ray_words(req)[0, CONTROL_WORD]
    assert (word >> np.uint32(f.lsb)) & np.uint32(0xFF) == FLAG_NO_CULL
    assert driver.FLAG_NO_CULL == 1 and "FLAG_NO_CULL" in driver.__all__


def test_flag_bit_matches_the_rtl_package():
    """rf_pkg::FLAG_NO_CULL_BIT is the bit of driver.FLAG_NO_CULL (the RTL's one copy)."""
    pkg = (RTL_DIR / "rf_pkg.sv").read_text()
    bit = re.search(r"localparam int unsigned FLAG_NO_CULL_BIT\s*=\s*(\d+);", pkg)
    assert bit and 1 << int(bit.group(1)) == FLAG_NO_CULL


def test_prepare_rays_flags_scalar_or_per_ray():
    o, d = np.zeros((3, 3)), [[0, 0, -1], [0, 1, 0], [1, 0, 0]]
    assert (driver.prepare_rays(o, d)["flags"] == 0).all()
    assert (driver.prepare_rays(o, d, flags=FLAG_NO_CULL)["flags"] == FLAG_NO_CULL).all()
    assert driver.prepare_rays(o, d, flags=[0, 1, 0])["flags"].tolist() == [0, 1, 0]
    for bad in (2, 0x80, -1, [1, 0], 0.5, [[1, 1, 1]]):
        with pytest.raises(ValueError, match="flags"):
            driver.prepare_rays(o, d, flags=bad)


@pytest.mark.parametrize("name", ["golden", "rtl"])
@pytest.mark.parametrize("opcode", [TRIANGLE, QUADBOX], ids=["TRIANGLE", "QUADBOX"])
def test_reserved_flag_bits_are_rejected(name, opcode):
    req = tri_request(FRONT, (0, 0, -1))
    req["opcode"] = opcode
    for bits in (4, 0x80, 0xFF):           # bit 1 is FLAG_DECODE_Q8 (tests/test_q8_datapath.py)
        req["flags"] = bits
        with pytest.raises(DatapathError, match="reserved"):
            driver.backend(name).run(req)


# ----------------------------------------------------------------------------------------------
# directed cases

TRI_CASES = [c for c in CASES if c[0].startswith("tri")]


def _no_cull_check(name, check):
    """The TRIANGLE directed cases (docs/datapath.md#directed-cases) with NO_CULL: the same
    result, except that case 1 (the back face of FRONT, 5 units per t along -z, the plane at
    z = -1) hits at t = 0.2 with t_den < 0."""
    if name != "tri1_back_face":
        return check
    hit = expect_tri(0.2)

    def back_hit(rsp):
        hit(rsp)
        assert rsp["t_den"] < 0 and rsp["t_num"] < 0
    return back_hit


def test_spec11_triangle_cases_with_no_cull():
    assert len(TRI_CASES) == 11
    for gaps, stalls in ((0, 0), (0.5, 0.5)):
        tb = Testbench("rtl", gaps=gaps, stalls=stalls, seed=11)
        for name, req, check in TRI_CASES:
            rsp = tb.run(with_flags(req, FLAG_NO_CULL))
            _no_cull_check(name, check)(rsp[0])
            check(tb.run(req)[0])                       # and the flag off: the paper's result


def test_spec11_triangle_cases_with_no_cull_pyverilator():
    req = np.concatenate([with_flags(r, FLAG_NO_CULL) for _, r, _ in TRI_CASES])
    (rsp,), _ = run_isolated("pyverilator", dict(gaps=0.5, stalls=0.5, seed=12), [req])
    for (name, _, check), row in zip(TRI_CASES, rsp):
        _no_cull_check(name, check)(row)


NEG0 = ((-0.0, -0.0, -1), (-1, -1, -1), (1, -1, -1))     # a front face with a vertex at (-0, -0, -1)


def _directed():
    """(name, request, expected hit, expected t, whether the ray sees the front face) for each
    winding and both flag values."""
    out = []
    for flags in (0, FLAG_NO_CULL):
        both = flags == FLAG_NO_CULL
        for face, tri, neg0 in (("front", FRONT, NEG0), ("back", BACK, NEG0[::-1])):
            front = face == "front"
            cases = [
                # from above (the triangle at z = -1 seen along -z) and from below (along +z)
                ("above", tri_request(tri, (0, 0, -2)), front or both, 0.5, front),
                ("below", tri_request(tri, (0, 0, 2), origin=(0, 0, -3)), not front or both, 1.0,
                 not front),
                ("behind", tri_request(tri, (0, 0, 2)), False, None, None),
                # edge-on: the ray lies in the plane (t_den = 0) and crosses the triangle
                ("edge-on", tri_request(tri, (0, 5, 0), origin=(0, -2, -1)), False, None, None),
                # -0 coordinates: hit exactly at the vertex (-0, -0, -1), direction (-0, -0, -1)
                ("neg0-vertex", tri_request(neg0, (-0.0, -0.0, -1)), front or both, 1.0, front),
                # NaN: a NaN vertex coordinate makes U, V, W or t_den NaN
                ("nan-vertex", tri_request(((np.nan, -1, -1),) + tri[1:], (0, 0, -1)), False,
                 None, None),
            ]
            out += [(f"{face}-{n}-{'nocull' if both else 'cull'}", with_flags(r, flags), h, t, fr)
                    for n, r, h, t, fr in cases]
    return out


DIRECTED = _directed()


def test_directed_cases_are_what_they_claim():
    names = [n for n, *_ in DIRECTED]
    assert len(names) == len(set(names)) == 24
    for n, r, *_ in DIRECTED:
        if "neg0" in n:
            assert ((r["tri"] == 0) & np.signbit(r["tri"])).any() and np.signbit(r["dir"]).all()


@pytest.mark.parametrize("name", ["golden", "rtl"])
def test_directed_both_faces_edge_on_neg0_nan(name):
    req = np.concatenate([r for _, r, *_ in DIRECTED])
    rsp = Testbench(name, gaps=0.5, stalls=0.5, seed=3).run(req)
    for (case, _, hit, t, sees_front), row in zip(DIRECTED, rsp):
        assert bool(row["tri_hit"]) == hit, case
        if hit:
            assert t_of(row) == np.float32(t), case
            assert (row["t_den"] > 0) == sees_front and (row["t_num"] > 0) == sees_front, case
        if "nan" in case:
            assert np.isnan(row["t_den"]), case


def test_flag_changes_only_the_hit_bit():
    """Same stream with NO_CULL on and off: t_num/t_den identical bits, every culled hit still a
    hit, the new hits are back faces (t_den < 0), and boxes ignore the flag."""
    req = mixed_stream(21, 2000, 3000)
    off = driver.backend("golden").run(with_flags(req, 0))
    on = driver.backend("golden").run(with_flags(req, FLAG_NO_CULL))
    for f in ("t_num", "t_den", "box_index", "box_hit", "box_tmin"):
        assert on[f].tobytes() == off[f].tobytes(), f
    tri = req["opcode"] == TRIANGLE
    on_hit, off_hit = on["tri_hit"].astype(bool), off["tri_hit"].astype(bool)
    assert (on_hit | ~off_hit).all()
    new = on_hit & ~off_hit
    assert new.sum() > 0.05 * tri.sum() and (on["t_den"][new] < 0).all()
    assert (off["t_den"][off_hit] > 0).all()


# ----------------------------------------------------------------------------------------------
# random streams, bit exact

FAST_PRESSURES = [(0.0, 0.0), (0.5, 0.5)]


@pytest.mark.parametrize("gaps,stalls", FAST_PRESSURES, ids=["steady", "gaps0.5-stalls0.5"])
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_random_no_cull_stream_rtl(extended, disjoint, gaps, stalls):
    req = no_cull_stream(31, 1500, 2500)
    rsp = Testbench("rtl", extended=extended, disjoint=disjoint, gaps=gaps, stalls=stalls,
                seed=31).run(req)
    tri = req["opcode"] == TRIANGLE
    back = tri & (rsp["t_den"] < 0) & rsp["tri_hit"].astype(bool)
    assert back.any() and (req["flags"][back] == FLAG_NO_CULL).all()   # the flag did something


@pytest.mark.slow
@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_random_no_cull_stream_rtl_all_pressures(extended, disjoint, gaps, stalls):
    Testbench("rtl", extended=extended, disjoint=disjoint, gaps=gaps, stalls=stalls,
          seed=32).run(no_cull_stream(32, 20_000, 30_000))


def test_random_no_cull_stream_pyverilator():
    req = no_cull_stream(41, 300, 500)
    run_isolated("pyverilator", dict(gaps=0.5, stalls=0.5, seed=41), [req[:400], req[400:]])


@pytest.mark.slow
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_random_no_cull_stream_pyverilator_every_build(extended, disjoint):
    req = no_cull_stream(42, 1500, 2500)
    run_isolated("pyverilator", dict(extended=extended, disjoint=disjoint, gaps=0.3, stalls=0.3,
                                     seed=42), [req])


def test_harness_traversal_requests_carry_the_flag():
    """The fast path's requests (a TRIANGLE node against a ray of the ray table, assembled in the
    C++ harness) keep each ray's flags: the back face hits only for the NO_CULL ray."""
    image = np.zeros(1, TRI_NODE)
    image["tri"][0] = BACK
    rays = driver.prepare_rays(np.zeros((2, 3)), [[0, 0, -1]] * 2, 4000, flags=[0, FLAG_NO_CULL])
    ptr = NodeRef.encode(0, TRI_TYPE)
    words = build_requests(rtl_params(False, False, driver.LATENCY), ray_words(rays), image,
                           [0, 1], [ptr, ptr], rays["extent"])
    req = unpack_requests(words)
    assert req["flags"].tolist() == [0, FLAG_NO_CULL] and (req["opcode"] == TRIANGLE).all()
    rsp = Testbench("rtl").run(req)
    assert rsp["tri_hit"].tolist() == [0, 1]


def test_scalar_reference_applies_no_cull_like_golden():
    """The scalar reference (one Python float32 step at a time) and the numpy golden model agree
    bit for bit on a stream where half the requests set NO_CULL."""
    from support.scalar_ref import scalar_run
    from support.scoreboard import assert_bit_equal
    req = no_cull_stream(17, 200, 400)
    assert_bit_equal(req, scalar_run(req), driver.backend("golden").run(req), "scalar", "golden")
