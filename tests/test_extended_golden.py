"""EUCLIDEAN and ANGULAR (docs/datapath.md#euclidean-and-angular) on the golden backend
(extended=True) vs the scalar reference.

Covers single- and multi-beat jobs, random masks, the reset rule (accumulator back to +0 after the
last beat), jobs interleaved with QUADBOX/TRIANGLE requests and with each other, jobs split across
run() calls, and the final value against an explicit numpy float32 computation of the same tree.
"""

from __future__ import annotations

import numpy as np
import pytest

import driver
from driver import ANGULAR, EUCLIDEAN, REQUEST_DTYPE
from support.scalar_ref import ScalarState, scalar_run
from support.scoreboard import assert_bit_equal
from support.streams import interleave, mixed_stream, random_vectors, vector_requests

F32 = np.float32


def golden():
    return driver.backend("golden", extended=True)


def ext_equal(req, state=None, backend=None):
    """Run req on golden and on the scalar model, assert bit-equality, return golden responses."""
    backend = backend or golden()
    state = state or ScalarState(extended=True)
    with np.errstate(all="ignore"):
        got = backend.run(req)
    assert_bit_equal(req, got, scalar_run(req, state), "golden", "scalar")
    return got


# ----------------------------------------------------------------------------------------------
# independent numpy computation of the tree (docs/datapath.md#euclidean-and-angular, written out)

def np_euclid_beats(a, b, mask):
    on = ((mask[:, None].astype(np.uint32) >> np.arange(16, dtype=np.uint32)) & 1).astype(bool)
    d = a - b
    e = np.where(on, d * d, F32(0))
    s8 = e[:, 0:8] + e[:, 8:16]
    s4 = s8[:, 0:4] + s8[:, 4:8]
    s2 = s4[:, 0:2] + s4[:, 2:4]
    return s2[:, 0] + s2[:, 1]


def np_angular_beats(a, b, mask):
    on = ((mask[:, None].astype(np.uint32) >> np.arange(8, dtype=np.uint32)) & 1).astype(bool)
    out = []
    for x in (a[:, :8] * b[:, :8], b[:, :8] * b[:, :8]):
        x = np.where(on, x, F32(0))
        s4 = x[:, 0:4] + x[:, 4:8]
        s2 = s4[:, 0:2] + s4[:, 2:4]
        out.append(s2[:, 0] + s2[:, 1])
    return out


def sequential(beats):
    acc = F32(0)
    for x in beats:
        acc = F32(acc + x)
    return acc


# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_single_beat_jobs(op):
    rng = np.random.default_rng(100 + op)
    req = vector_requests(rng, op, [1] * 1500)
    rsp = ext_equal(req)
    last = "euclid_last" if op == EUCLIDEAN else "angular_last"
    assert rsp[last].all()
    assert np.isnan(rsp["euclid_acc" if op == EUCLIDEAN else "angular_dot"]).any()  # specials reach
    other = ("angular_dot", "angular_norm", "angular_last") if op == EUCLIDEAN else \
        ("euclid_acc", "euclid_last")
    for name in other + ("box_index", "box_hit", "box_tmin", "tri_hit", "t_num", "t_den"):
        assert not np.ascontiguousarray(rsp[name]).view(np.uint8).any(), name
    assert (rsp["tag"] == req["tag"]).all() and (rsp["opcode"] == op).all()


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_multi_beat_jobs_random_masks(op):
    rng = np.random.default_rng(200 + op)
    lengths = rng.integers(1, 25, 150)
    req = vector_requests(rng, op, lengths)
    rsp = ext_equal(req)
    last = "euclid_last" if op == EUCLIDEAN else "angular_last"
    assert (np.flatnonzero(rsp[last]) == np.cumsum(lengths) - 1).all()


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_final_value_matches_numpy_tree_and_float64(op):
    rng = np.random.default_rng(300 + op)
    for length in (1, 2, 7, 64):
        req = vector_requests(rng, op, [length], special=False)
        a, b, mask = req["vec_a"], req["vec_b"], req["vec_mask"]
        rsp = ext_equal(req)
        on = ((mask[:, None].astype(np.uint32) >> np.arange(16, dtype=np.uint32)) & 1).astype(bool)
        if op == EUCLIDEAN:
            got = rsp["euclid_acc"][-1]
            want = sequential(np_euclid_beats(a, b, mask))
            approx = np.sum(np.where(on, (a.astype(np.float64) - b) ** 2, 0))
            assert got.view(np.uint32) == want.view(np.uint32)
            np.testing.assert_allclose(got, approx, rtol=1e-4)
        else:
            dot, norm = (sequential(x) for x in np_angular_beats(a, b, mask))
            assert rsp["angular_dot"][-1].view(np.uint32) == dot.view(np.uint32)
            assert rsp["angular_norm"][-1].view(np.uint32) == norm.view(np.uint32)
            on = on[:, :8]
            a64, b64 = a[:, :8].astype(np.float64), b[:, :8].astype(np.float64)
            np.testing.assert_allclose(rsp["angular_norm"][-1], np.sum(np.where(on, b64 * b64, 0)),
                                       rtol=1e-4)
            # dot can cancel: compare with an absolute scale
            scale = np.sum(np.where(on, np.abs(a64 * b64), 0))
            assert abs(rsp["angular_dot"][-1] - np.sum(np.where(on, a64 * b64, 0))) <= 1e-5 * scale
        # running values: beat j carries the sum of beats 0..j
        if op == EUCLIDEAN:
            beats = np_euclid_beats(a, b, mask)
            running = np.array([sequential(beats[:j + 1]) for j in range(length)], F32)
            assert (rsp["euclid_acc"].view(np.uint32) == running.view(np.uint32)).all()


def test_long_euclidean_job_against_float64():
    """A 1024-dimensional distance as 64 full beats: close to the float64 value."""
    rng = np.random.default_rng(4)
    a = rng.normal(size=1024).astype(F32)
    b = rng.normal(size=1024).astype(F32)
    req = np.zeros(64, REQUEST_DTYPE)
    req["opcode"] = EUCLIDEAN
    req["vec_a"], req["vec_b"] = a.reshape(64, 16), b.reshape(64, 16)
    req["vec_mask"] = 0xFFFF
    req["reset_accumulator"][-1] = 1
    rsp = ext_equal(req)
    np.testing.assert_allclose(rsp["euclid_acc"][-1], np.sum((a.astype(np.float64) - b) ** 2),
                               rtol=1e-5)


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_reset_clears_to_plus_zero(op):
    g, s = golden(), ScalarState(extended=True)
    # job 1: ends with reset; it left a large value in the accumulator
    req = np.zeros(3, REQUEST_DTYPE)
    req["opcode"] = op
    req["vec_a"] = 100.0
    req["vec_b"] = 3.0
    req["vec_mask"] = 0xFFFF
    req["reset_accumulator"] = [0, 0, 1]
    rsp = ext_equal(req, s, g)
    # job 2: a single beat whose sum is -0 (angular: (-0)*1; Euclidean has no -0 beat, use mask 0):
    # +0 + -0 = +0 only if the accumulator really restarted at +0
    req2 = np.zeros(2, REQUEST_DTYPE)
    req2["opcode"] = op
    req2["vec_a"] = -0.0
    req2["vec_b"] = 1.0
    req2["vec_mask"] = [0xFFFF if op == ANGULAR else 0, 0x0001]
    req2["reset_accumulator"] = [0, 1]
    rsp2 = ext_equal(req2, s, g)
    field = "euclid_acc" if op == EUCLIDEAN else "angular_dot"
    assert rsp2[field].view(np.uint32)[0] == 0             # +0: not -0, nothing left of job 1
    if op == ANGULAR:
        assert rsp2["angular_norm"][0] == 8 and rsp2["angular_norm"][1] == 9
        assert rsp[field][2] == 3 * 8 * 300
    else:
        assert rsp[field][2] == 3 * 16 * 97 ** 2
        assert rsp2[field][1] == 1
    # a NaN job is forgotten after its reset
    req3 = req.copy()
    req3["vec_a"][0, 0] = np.nan
    ext_equal(req3, s, g)
    rsp4 = ext_equal(req, s, g)
    assert (rsp4[field] == rsp[field]).all()


def test_initial_state_is_plus_zero():
    req = np.zeros(2, REQUEST_DTYPE)
    req["opcode"] = [EUCLIDEAN, ANGULAR]
    req["vec_a"] = -0.0
    req["vec_b"] = 1.0
    req["vec_mask"] = [0, 0xFF]
    rsp = ext_equal(req)
    assert rsp["euclid_acc"].view(np.uint32)[0] == 0
    assert rsp["angular_dot"].view(np.uint32)[1] == 0                    # +0 + (-0 tree) = +0
    assert rsp["euclid_last"][0] == 0 and rsp["angular_last"][1] == 0


def test_interleaved_jobs_and_box_triangle_requests():
    """One Euclidean job and one angular job in flight at once, interleaved with each other and
    with QUADBOX/TRIANGLE requests: each job's results equal the job run alone."""
    rng = np.random.default_rng(9)
    e_jobs = vector_requests(rng, EUCLIDEAN, rng.integers(1, 12, 40))
    a_jobs = vector_requests(rng, ANGULAR, rng.integers(1, 12, 40))
    other = mixed_stream(9, 300, 200)
    # box/triangle requests carry vector data and reset flags that must be ignored
    other["vec_a"], other["vec_b"] = random_vectors(rng, len(other))
    other["vec_mask"] = 0xFFFF
    other["reset_accumulator"] = rng.random(len(other)) < 0.5
    stream, kinds = interleave(rng, (e_jobs, a_jobs, other))    # order within each stream kept
    rsp = ext_equal(stream)
    alone_e = ext_equal(e_jobs)
    alone_a = ext_equal(a_jobs)
    with np.errstate(all="ignore"):
        alone_o = driver.backend("golden").run(other)
    for k, alone in enumerate((alone_e, alone_a, alone_o)):
        mine = rsp[kinds == k]
        assert mine.tobytes() == alone.tobytes(), k


def test_job_split_across_runs_equals_one_run():
    rng = np.random.default_rng(10)
    e = vector_requests(rng, EUCLIDEAN, [30, 5, 17])
    a = vector_requests(rng, ANGULAR, [23, 1, 28])
    stream = np.concatenate([e, a])[rng.permutation(len(e) + len(a))]
    one = golden().run(stream)
    for cuts in ([1], [10, 11], [7, 40, 41, 70], list(range(1, len(stream)))):
        g, s = golden(), ScalarState(extended=True)
        parts = [ext_equal(chunk, s, g) for chunk in np.split(stream, cuts)]
        assert np.concatenate(parts).tobytes() == one.tobytes(), cuts
        assert g.cycles == len(stream) + 11 * (len(cuts) + 1)
    # a job left open at the end of a run continues in the next one, even with only other
    # requests (or nothing) in between
    g = golden()
    with np.errstate(all="ignore"):
        r1 = g.run(e[:10])
        g.run(mixed_stream(3, 20, 20))
        g.run(e[:0])
        r2 = g.run(e[10:])
    assert np.concatenate([r1, r2]).tobytes() == golden().run(e).tobytes()


def test_rejected_run_does_not_touch_accumulators():
    rng = np.random.default_rng(12)
    e = vector_requests(rng, EUCLIDEAN, [12], special=False)
    g = golden()
    first = g.run(e[:5])
    bad = e[5:8].copy()
    bad["opcode"][1] = 4                                        # not an opcode
    with pytest.raises(driver.DatapathError):
        g.run(bad)
    rest = g.run(e[5:])
    assert np.concatenate([first, rest]).tobytes() == golden().run(e).tobytes()


@pytest.mark.parametrize("op", [EUCLIDEAN, ANGULAR])
def test_masked_off_lanes_ignore_nan_and_garbage(op):
    rng = np.random.default_rng(13 + op)
    req = vector_requests(rng, op, [4, 1, 6], special=False)
    clean = req.copy()
    bit = np.arange(16, dtype=np.uint32)
    lanes = ((req["vec_mask"][:, None].astype(np.uint32) >> bit) & 1) == 0
    if op == ANGULAR:
        lanes[:, 8:] = True                                   # lanes 8-15 never used by ANGULAR
    clean["vec_a"][lanes] = 0
    clean["vec_b"][lanes] = 0
    dirty = req.copy()
    dirty["vec_a"][lanes] = np.nan
    dirty["vec_b"][lanes] = np.where(rng.random(lanes.sum()) < .5, np.inf, -np.nan)
    r_clean, r_dirty = ext_equal(clean), ext_equal(dirty)
    assert r_clean.tobytes() == r_dirty.tobytes()
    for name in ("euclid_acc",) if op == EUCLIDEAN else ("angular_dot", "angular_norm"):
        assert np.isfinite(r_clean[name]).all()


def test_nan_outputs_canonical_and_overflow():
    req = np.zeros(4, REQUEST_DTYPE)
    req["opcode"] = [EUCLIDEAN, EUCLIDEAN, ANGULAR, ANGULAR]
    req["vec_mask"] = 0xFFFF
    req["reset_accumulator"] = 1
    req["vec_a"][0, 3] = np.inf                          # (inf - inf) -> NaN
    req["vec_b"][0, 3] = np.inf
    req["vec_a"][1, :] = 3e19                            # squares overflow to +inf
    req["vec_a"][2, 0] = np.array(0xFFC00001, np.uint32).view(F32)   # negative NaN with payload
    req["vec_b"][2, 0] = 1
    req["vec_a"][3, 0], req["vec_b"][3, 0] = 0, np.inf   # 0 * inf -> NaN dot; norm = inf
    rsp = ext_equal(req)
    assert rsp["euclid_acc"].view(np.uint32)[0] == 0x7FC00000
    assert rsp["euclid_acc"][1] == np.inf
    assert rsp["angular_dot"].view(np.uint32)[2] == 0x7FC00000 and rsp["angular_norm"][2] == 1
    assert rsp["angular_dot"].view(np.uint32)[3] == 0x7FC00000 and rsp["angular_norm"][3] == np.inf


def test_random_everything_mixed():
    """Random interleaving of many short jobs of both kinds with box/triangle traffic, resets at
    random places (including several beats in a row with reset), chunked into random runs."""
    rng = np.random.default_rng(14)
    n = 3000
    stream = mixed_stream(14, 700, 500)
    vec = np.zeros(n - len(stream), REQUEST_DTYPE)
    vec["opcode"] = rng.choice([EUCLIDEAN, ANGULAR], len(vec))
    vec["vec_a"], vec["vec_b"] = random_vectors(rng, len(vec))
    vec["vec_mask"] = rng.integers(0, 2**16, len(vec))
    vec["reset_accumulator"] = rng.random(len(vec)) < 0.2
    allreq = np.concatenate([stream, vec])[rng.permutation(n)]
    g, s = golden(), ScalarState(extended=True)
    cuts = np.sort(rng.choice(np.arange(1, n), 12, replace=False))
    for chunk in np.split(allreq, cuts):
        ext_equal(chunk, s, g)
    assert g.cycles == n + 11 * 13
    # closing beats: the accumulator states left behind agree too
    close = vector_requests(rng, EUCLIDEAN, [1], special=False)
    close = np.concatenate([close, vector_requests(rng, ANGULAR, [1], special=False)])
    ext_equal(close, s, g)
