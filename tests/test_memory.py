"""The node memory of the RT-unit model (sim/rf_memory.h, driver.rtunit.MemoryModel): the cache
on hand-checked traces, the bandwidth limit, and replays with the memory off equal to an
independent Python model of the scheduler."""

from collections import deque

import numpy as np
import pytest

from driver import rtunit
from driver.backends.build import rtl_params
from driver.backends.harness import memory_trace
from driver.bvh4 import build
from driver.scenes.camera import primary_rays
from driver.scenes.scene import load_scene
from driver.tracer import trace

PARAMS = rtl_params(False, False, 11)


def fetch(memory, trace_):
    """memory: MemoryModel arguments (cache bytes, ways, line bytes, latency, bytes per cycle);
    trace_: [(byte offset, bytes, cycle)] -> (ready cycles list, the L1's counts)."""
    off, nb, now = zip(*trace_)
    ready, _, c = memory_trace(PARAMS, rtunit.MemoryModel(*memory).config(), off, nb, now)
    return ready.tolist(), {"line_accesses": c["l1_accesses"],
                            "line_hits": c["l1_hits"] + c["l1_merged"],
                            "line_misses": c["l1_misses"], "bytes_from_memory": c["dram_bytes"]}


def test_cache_hits_misses_and_lru_evictions():
    # 2 sets x 2 ways of 64-byte lines (256 B); latency 10; 64 B/cycle: a line takes 1 cycle
    mem = (256, 2, 64, 10, 64.0)
    ready, c = fetch(mem, [
        (0, 64, 0),        # line 0 (set 0): miss, transfer [0, 1), arrives 1 + 10
        (0, 64, 5),        # line 0 again while its fill is under way: waits for it, no traffic
        (0, 64, 20),       # line 0: hit, present at once
        (128, 64, 20),     # line 2 (set 0): miss, set 0 now holds lines 0, 2
        (256, 64, 40),     # line 4 (set 0): miss, evicts the least recently used: line 0
        (128, 64, 60),     # line 2: still there (hit)
        (0, 64, 60),       # line 0: evicted -> miss again
        (64, 128, 80),     # a 128-byte node on lines 1 and 2: line 1 miss (set 1), line 2 hit
    ])
    assert ready == [11, 11, 20, 31, 51, 60, 71, 91]
    assert c == {"line_accesses": 9, "line_hits": 4, "line_misses": 5,
                 "bytes_from_memory": 5 * 64}


def test_bandwidth_limit_serialises_transfers():
    # 8 B/cycle: a 64-byte line occupies the channel for 8 cycles; latency 100
    mem = (4096, 4, 64, 100, 8.0)
    ready, c = fetch(mem, [(64 * i, 64, 0) for i in range(5)])
    assert ready == [108, 116, 124, 132, 140]          # one line per 8 cycles, then the latency
    assert c["bytes_from_memory"] == 5 * 64
    ready, _ = fetch((4096, 4, 64, 100, 2.5), [(0, 64, 0), (64, 64, 0)])
    assert ready == [126, 152]                         # 25.6 cycles per line, rounded up


def test_bad_cache_geometry_is_a_clear_error():
    with pytest.raises(ValueError, match="multiple"):
        rtunit.MemoryModel(cache_bytes=1000)
    with pytest.raises(ValueError, match="power of two"):
        rtunit.MemoryModel(line_bytes=48, cache_bytes=48 * 4)
    with pytest.raises(ValueError, match="bytes_per_cycle"):
        rtunit.MemoryModel(bytes_per_cycle=0)


def reference_cycles(record, rays_in_flight, pipelines, turnaround, latency=11):
    """The scheduler of driver.rtunit in plain Python, for the datapath's fixed latency with
    nothing stalled: a request accepted at cycle k is answered at k + latency."""
    chains = [[] for _ in range(record.rays)]
    for i, r in enumerate(record.ray.tolist()):
        chains[r].append(i)
    order = deque(r for r in range(record.rays) if chains[r])
    ready = deque()
    pos = [0] * record.rays
    for _ in range(rays_in_flight):
        if order:
            ready.append((order.popleft(), 0))
    inflight = [deque() for _ in range(pipelines)]
    k, taken, first, last = 0, 0, -1, -1
    while taken < len(record.ray):
        for p in range(pipelines):
            if inflight[p] and inflight[p][0][1] + latency == k:
                r, _ = inflight[p].popleft()
                taken += 1
                last = k
                pos[r] += 1
                if pos[r] < len(chains[r]):
                    ready.append((r, k + turnaround))
                elif order:
                    ready.append((order.popleft(), k + turnaround))
        for p in range(pipelines):
            if ready and ready[0][1] <= k:
                r, _ = ready.popleft()
                inflight[p].append((r, k))
                first = k if first < 0 else first
        k += 1
    return last - first + 1


@pytest.fixture(scope="module")
def record():
    scene = load_scene("room")
    o, d = primary_rays(scene.camera, 24, 16)
    return trace(build(scene.mesh), o, d, backend="rtl", record=True).record


@pytest.mark.parametrize("r,p,ta", [(1, 1, 1), (5, 1, 1), (64, 1, 1), (64, 2, 3), (300, 4, 0)])
def test_memory_off_replay_is_the_reference_scheduler(record, r, p, ta):
    assert rtunit.replay(record, r, p, ta).cycles == reference_cycles(record, r, p, ta)


def test_memory_changes_timing_only(record):
    off = rtunit.replay(record, 64, 1)
    on = rtunit.replay(record, 64, 1, memory=rtunit.MemoryModel(), datapath="rtl")
    assert on.verified and np.array_equal(on.responses, off.responses)
    assert on.cycles > off.cycles
    m = on.memory
    assert m["line_hits"] + m["line_misses"] == m["line_accesses"] > record.ops
    assert m["bytes_from_memory"] == 64 * m["line_misses"]
    assert 0 < m["hit_rate"] < 1
    # more bandwidth and a shorter latency never cost cycles; a bigger cache hits more
    fast = rtunit.replay(record, 64, 1, memory=rtunit.MemoryModel(latency_cycles=20,
                                                                   bytes_per_cycle=256.0))
    assert fast.cycles <= on.cycles
    big = rtunit.replay(record, 64, 1, memory=rtunit.MemoryModel(cache_bytes=1 << 22))
    assert big.memory["hit_rate"] >= m["hit_rate"]
    # more rays in flight hide more of the latency
    few = rtunit.replay(record, 4, 1, memory=rtunit.MemoryModel())
    assert few.cycles > on.cycles
