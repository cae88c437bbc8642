"""The RTL in all four configurations (EXTENDED x DISJOINT) vs the golden model, bit for bit.

EUCLIDEAN/ANGULAR (docs/datapath.md#euclidean-and-angular) on both extended builds: random
multi-beat jobs with random masks, interleaved with each other and with QUADBOX/TRIANGLE requests,
under random gaps and stalls. The accumulators change only on accepted beats (the paper's code
updated them every clock): a job interrupted by bubbles, back-pressure and other requests gives the
same result as the same job run alone, and so does a job split across run() calls. QUADBOX/TRIANGLE
on all four builds; every configuration gives identical responses and identical cycle counts
(docs/datapath.md#pipeline).
"""

from __future__ import annotations

import numpy as np
import pytest

from driver import ANGULAR, EUCLIDEAN, RESPONSE_DTYPE
from support.streams import (extended_stream, interleave, mixed_stream, random_vectors,
                             vector_requests)
from support.testbench import PRESSURE_IDS, PRESSURES, Testbench, burst_pattern, run_isolated

CONFIGS = [(False, False), (False, True), (True, False), (True, True)]
CONFIG_IDS = ["baseline-unified", "baseline-disjoint", "extended-unified", "extended-disjoint"]
EXTENDED = CONFIGS[2:]
EXTENDED_IDS = CONFIG_IDS[2:]
NO_TAG = [f for f in RESPONSE_DTYPE.names if f != "tag"]


def same_but_tags(a, b):
    """Responses identical bit for bit in every field but the (testbench-stamped) tag."""
    return len(a) == len(b) and all(np.ascontiguousarray(a[f]).tobytes()
                                    == np.ascontiguousarray(b[f]).tobytes() for f in NO_TAG)


# ----------------------------------------------------------------------------------------------
# QUADBOX / TRIANGLE on every build

@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5)], ids=["steady", "gaps0.5-stalls0.5"])
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_box_triangle_every_build(extended, disjoint, gaps, stalls):
    Testbench("rtl", extended=extended, disjoint=disjoint, gaps=gaps, stalls=stalls, seed=3).run(
        mixed_stream(50 + extended + 2 * disjoint, 6000, 4000))


# ----------------------------------------------------------------------------------------------
# EUCLIDEAN / ANGULAR

@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
@pytest.mark.parametrize("extended,disjoint", EXTENDED, ids=EXTENDED_IDS)
def test_random_jobs_interleaved(extended, disjoint, gaps, stalls):
    stream, kind = extended_stream(60 + int(10 * gaps + stalls))
    tb = Testbench("rtl", extended=True, disjoint=disjoint, gaps=gaps, stalls=stalls, seed=6)
    rsp = np.concatenate([tb.run(c) for c in np.array_split(stream, 3)])
    # the stream covers what it should: many jobs closed, NaN/inf results, masked lanes
    assert rsp["euclid_last"][kind == 0].sum() == 40 and rsp["angular_last"][kind == 1].sum() == 40
    assert np.isnan(rsp["euclid_acc"]).any() and np.isnan(rsp["angular_dot"]).any()
    assert (stream["vec_mask"][kind < 2] != 0xFFFF).mean() > 0.5
    assert rsp["box_hit"].any() and rsp["tri_hit"].any()


def _jobs(seed):
    rng = np.random.default_rng(seed)
    e = vector_requests(rng, EUCLIDEAN, [40, 1, 25, 60], special=False)
    a = vector_requests(rng, ANGULAR, [33, 50, 1, 12], special=False)
    return rng, e, a


INTERRUPTIONS = {
    "bubbles": (burst_pattern(20, 1), None),                 # 20 idle input cycles per beat
    "backpressure": (None, burst_pattern(40, 2)),            # output blocked 40 of 42 cycles
    "both-bursts": (burst_pattern(7, 2, 3), burst_pattern(25, 4)),
    "random-0.9": "random",
}


@pytest.mark.parametrize("how", list(INTERRUPTIONS))
@pytest.mark.parametrize("extended,disjoint", EXTENDED, ids=EXTENDED_IDS)
def test_interrupted_job_equals_uninterrupted(extended, disjoint, how):
    """docs/datapath.md#euclidean-and-angular: bubbles, back-pressure and interleaved requests never
    disturb the accumulators.

    Each job runs once back to back on its own and once interrupted: with long input bubbles
    between its beats (a datapath that accumulates every clock adds stale beats), with the output
    blocked so that beats wait in the accumulator stage (one that accumulates while not accepted
    adds them twice), and interleaved with the other operation's jobs and QUADBOX/TRIANGLE requests
    that carry reset flags and vector data. The job's responses must be identical."""
    rng, e, a = _jobs(70)
    alone_e = Testbench("rtl", extended=True, disjoint=disjoint).run(e)
    alone_a = Testbench("rtl", extended=True, disjoint=disjoint).run(a)
    other = mixed_stream(70, 60, 40)
    other["vec_a"], other["vec_b"] = random_vectors(rng, len(other), special=False)
    other["vec_mask"] = 0xFFFF
    other["reset_accumulator"] = 1
    stream, kind = interleave(rng, (e, a, other))
    if INTERRUPTIONS[how] == "random":
        tb = Testbench("rtl", extended=True, disjoint=disjoint, gaps=0.9, stalls=0.9, seed=70)
    else:
        tb = Testbench("rtl", extended=True, disjoint=disjoint)
        tb.set_patterns(*INTERRUPTIONS[how])
    rsp = tb.run(stream)
    assert tb.dut.cycles > 3 * len(stream)              # it really was interrupted
    assert same_but_tags(rsp[kind == 0], alone_e)
    assert same_but_tags(rsp[kind == 1], alone_a)
    assert np.isfinite(alone_e["euclid_acc"]).all() and (alone_e["euclid_acc"] > 0).all()


@pytest.mark.parametrize("extended,disjoint", EXTENDED, ids=EXTENDED_IDS)
def test_job_split_across_runs(extended, disjoint):
    rng, e, a = _jobs(80)
    stream, _ = interleave(rng, (e, a))
    one = Testbench("rtl", extended=True, disjoint=disjoint).run(stream)
    for gaps, stalls in ((0, 0), (0.5, 0.5)):
        tb = Testbench("rtl", extended=True, disjoint=disjoint, gaps=gaps, stalls=stalls, seed=8)
        parts = [tb.run(stream[:17]),                  # jobs of both kinds left open ...
                 tb.run(mixed_stream(80, 30, 20)),     # ... other requests in between ...
                 tb.run(stream[:0]),                   # ... an empty run ...
                 tb.run(stream[17:])]                  # ... and they continue
        split = np.concatenate([parts[0], parts[3]])
        assert same_but_tags(split, one)


@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5), (0.9, 0.1)],
                         ids=["steady", "gaps0.5-stalls0.5", "gaps0.9-stalls0.1"])
def test_disjoint_equals_unified(gaps, stalls):
    """Same stream, same gap/stall pattern: identical responses and cycles on every build."""
    stream, _ = extended_stream(90)
    unified = Testbench("rtl", extended=True, gaps=gaps, stalls=stalls, seed=9)
    disjoint = Testbench("rtl", extended=True, disjoint=True, gaps=gaps, stalls=stalls, seed=9)
    assert unified.run(stream).tobytes() == disjoint.run(stream).tobytes()
    assert unified.dut.cycles == disjoint.dut.cycles
    boxtri = mixed_stream(91, 1200, 800)
    got = [Testbench("rtl", extended=x, disjoint=d, gaps=gaps, stalls=stalls, seed=9).run(boxtri)
           for x, d in CONFIGS]
    assert all(g.tobytes() == got[0].tobytes() for g in got[1:])


@pytest.mark.parametrize("extended,disjoint", EXTENDED, ids=EXTENDED_IDS)
def test_cycles_extended_builds(extended, disjoint):
    stream, _ = extended_stream(95)
    tb = Testbench("rtl", extended=True, disjoint=disjoint)
    for n in (1, 2, 12, 500):
        tb.run(stream[:n])                             # the monitor checks n + 11 exactly
    assert tb.dut.cycles == 515 + 4 * 11


# ----------------------------------------------------------------------------------------------
# heavy variants

@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("gaps,stalls", PRESSURES, ids=PRESSURE_IDS)
@pytest.mark.parametrize("extended,disjoint", CONFIGS, ids=CONFIG_IDS)
def test_many_seeds_every_build(extended, disjoint, gaps, stalls, seed):
    tb = Testbench("rtl", extended=extended, disjoint=disjoint, gaps=gaps, stalls=stalls,
                  seed=seed)
    if extended:
        stream, _ = extended_stream(1000 + seed, n_jobs=400, max_beats=40, n_box=6000,
                                    n_tri=4000)
    else:
        stream = mixed_stream(1000 + seed, 60_000, 40_000)
    for chunk in np.array_split(stream, 7):
        tb.run(chunk)


@pytest.mark.slow
@pytest.mark.parametrize("gaps,stalls", [(0, 0), (0.5, 0.5), (0.9, 0.9)],
                         ids=["steady", "gaps0.5-stalls0.5", "gaps0.9-stalls0.9"])
@pytest.mark.parametrize("extended,disjoint", EXTENDED, ids=EXTENDED_IDS)
def test_pyverilator_extended_agrees(extended, disjoint, gaps, stalls):
    stream, _ = extended_stream(1100, n_jobs=10, max_beats=10, n_box=60, n_tri=40)
    options = dict(extended=True, disjoint=disjoint, gaps=gaps, stalls=stalls, seed=11)
    chunks = np.array_split(stream, 2)                    # a job split across the two runs
    fast = Testbench("rtl", **options)
    slow, runs = run_isolated("pyverilator", options, chunks)
    for chunk, rsp in zip(chunks, slow):
        assert fast.run(chunk).tobytes() == rsp.tobytes()
    assert fast.runs == runs
