"""The RT unit inside a GPU (driver.rtunit.gpu, sim/rtunit_scheduler.cpp, sim/rf_memory.h):
hand-checked warps, memory hierarchy and many RT units, and the warp scheduler against an
independent Python model."""

from __future__ import annotations

import heapq
import itertools

import numpy as np
import pytest

from driver import rtunit
from driver.backends.build import rtl_params
from driver.backends.harness import memory_trace
from driver.bvh4 import build
from driver.rtunit.gpu import replay_frame
from driver.rtunit.order import RayOrder
from driver.rtunit.plan import Schedule, Wave, one_kernel_plan, tile_shape, wavefront_plan
from driver.scenes.camera import primary_rays
from driver.scenes.scene import load_scene
from driver.tracer import trace

PARAMS = rtl_params(False, False, 11)
LAT = 11


def trace_levels(memory: rtunit.MemoryModel, fetches, units=1, flush_at=-1):
    """fetches: [(unit, byte offset, bytes, cycle)] -> (ready list, level list, counts)."""
    u, off, nb, now = zip(*fetches)
    ready, level, counts = memory_trace(PARAMS, memory.config(), off, nb, now, unit=u,
                                        units=units, flush_at=flush_at)
    return ready.tolist(), level.tolist(), counts


# ------------------------------------------------------------------------------- hierarchy

def test_l1_l2_dram_counts_on_a_known_sequence():
    # L1: one set of 2 ways of 64-byte lines, hit latency 2; L2: 2 sets x 4 ways, latency 10;
    # DRAM latency 100 at 64 B/cycle (a line's transfer takes one cycle)
    mem = rtunit.MemoryModel(cache_bytes=128, ways=2, line_bytes=64, latency_cycles=100,
                             bytes_per_cycle=64.0, hit_latency=2, l2_bytes=512, l2_ways=4,
                             l2_latency=10)
    ready, level, c = trace_levels(mem, [
        (0, 0, 64, 0),      # line 0: L1 miss, reaches the L2 at 2, misses, DRAM at 12: 13 + 100
        (0, 0, 64, 50),     # line 0 still under way: merged in the L1, no traffic
        (0, 0, 64, 200),    # line 0: L1 hit, 2 cycles
        (0, 64, 64, 200),   # line 1: L1 miss, L2 miss, DRAM at 212: 213 + 100
        (0, 128, 64, 400),  # line 2: L1 miss (evicts line 0, the least recent), L2 miss
        (0, 0, 64, 600),    # line 0: L1 miss (evicted), L2 hit: 602 + 10
    ])
    assert ready == [113, 113, 202, 313, 513, 612]
    assert level == [3, 3, 1, 3, 3, 2]
    assert c == {"l1_accesses": 6, "l1_hits": 1, "l1_merged": 1, "l1_misses": 4,
                 "l1_bytes": 256, "l2_accesses": 4, "l2_hits": 1, "l2_merged": 0,
                 "l2_misses": 3, "l2_bytes": 192, "dram_transfers": 3, "dram_bytes": 192,
                 "mshr_stalls": 0, "mshr_stall_cycles": 0}


@pytest.mark.parametrize("mshrs", [1, 0])
def test_mshr_merges_count_once_and_a_full_file_stalls(mshrs):
    mem = rtunit.MemoryModel(cache_bytes=4096, ways=4, line_bytes=64, latency_cycles=100,
                             bytes_per_cycle=64.0, mshrs=mshrs)
    ready, _, c = trace_levels(mem, [
        (0, 0, 64, 0),      # miss: the MSHR (if one) is taken until the line arrives at 101
        (0, 0, 64, 1),      # the same line in flight: merged, no MSHR, no traffic
        (0, 64, 64, 2),     # another line: with one MSHR it waits for the first to return
        (0, 0, 64, 3),      # merged again
    ])
    if mshrs:
        assert ready == [101, 101, 202, 101]
        assert (c["mshr_stalls"], c["mshr_stall_cycles"]) == (1, 99)
    else:
        assert ready == [101, 101, 103, 101]
        assert (c["mshr_stalls"], c["mshr_stall_cycles"]) == (0, 0)
    assert (c["l1_accesses"], c["l1_merged"], c["l1_misses"], c["dram_transfers"]) == (4, 2, 2, 2)


def test_two_units_share_one_l2_line_one_dram_fetch():
    mem = rtunit.MemoryModel(cache_bytes=1024, ways=4, line_bytes=64, latency_cycles=100,
                             bytes_per_cycle=64.0, l2_bytes=65536, l2_latency=10)
    ready, level, c = trace_levels(mem, [
        (0, 0, 64, 0),      # unit 0: L1 miss, L2 miss: DRAM at 10, arrives 111
        (1, 0, 64, 5),      # unit 1: its own L1 misses; the L2 line is in flight: merged
        (1, 0, 64, 200),    # unit 1: now in its L1
        (0, 0, 64, 300),    # unit 0: in its L1
    ], units=2)
    assert ready == [111, 111, 200, 300]
    assert level == [3, 3, 1, 1]
    assert (c["l1_accesses"], c["l1_hits"], c["l1_misses"]) == (4, 2, 2)
    assert (c["l2_accesses"], c["l2_misses"], c["l2_merged"]) == (2, 1, 1)
    assert (c["dram_transfers"], c["dram_bytes"]) == (1, 64)


def test_sectors_move_only_the_bytes_asked_for():
    lines = rtunit.MemoryModel(cache_bytes=1024, ways=2, line_bytes=128, latency_cycles=10,
                               bytes_per_cycle=32.0)
    sectors = rtunit.MemoryModel(cache_bytes=1024, ways=2, line_bytes=128, latency_cycles=10,
                                 bytes_per_cycle=32.0, sector_bytes=32)
    seq = [(0, 0, 64, 0), (0, 32, 64, 500)]          # bytes 0-63, then 32-95 of one line
    _, _, cl = trace_levels(lines, seq)
    ready, _, cs = trace_levels(sectors, seq)
    assert (cl["l1_accesses"], cl["l1_misses"], cl["dram_bytes"]) == (2, 1, 128)
    # sectors 0, 1 miss (one line allocated), then sector 1 hits and sector 2 misses
    assert (cs["l1_accesses"], cs["l1_hits"], cs["l1_misses"], cs["dram_bytes"]) == (4, 1, 3, 96)
    assert ready == [12, 511]              # two 1-cycle transfers + 10; then one at 500


def test_flush_drops_every_cache():
    mem = rtunit.MemoryModel(cache_bytes=1024, ways=4, latency_cycles=10, l2_bytes=4096,
                             l2_latency=5)
    seq = [(0, 0, 64, 0), (0, 0, 64, 100)]
    _, level, _ = trace_levels(mem, seq)
    assert level == [3, 1]
    _, level, c = trace_levels(mem, seq, flush_at=1)
    assert level == [3, 3] and c["dram_transfers"] == 2


def test_more_l2_never_adds_dram_bytes_on_one_access_stream():
    """Monotone where physics says so: LRU has the inclusion property, so on a fixed access
    stream a larger L2 (same line size, fully associative here) never fetches more from DRAM."""
    rng = np.random.default_rng(3)
    n = 4000
    # a stream with reuse: nodes of a small working set, four units
    off = (rng.zipf(1.3, n) % 700) * 64
    fetches = [(int(rng.integers(4)), int(o), 64, int(t)) for o, t in
               zip(off, np.sort(rng.integers(0, 40000, n)))]
    last = None
    for l2_kib in (0, 4, 8, 16, 32, 64):
        ways = max(l2_kib * 1024 // 64, 1)
        mem = rtunit.MemoryModel(cache_bytes=1024, ways=4, latency_cycles=50,
                                 l2_bytes=l2_kib * 1024, l2_ways=ways, l2_latency=20)
        dram = trace_levels(mem, fetches, units=4)[2]["dram_bytes"]
        if last is not None:
            assert dram <= last
        last = dram
    assert last < trace_levels(rtunit.MemoryModel(cache_bytes=1024, latency_cycles=50),
                               fetches, units=4)[2]["dram_bytes"]


def test_fully_associative_l1_is_lru_over_all_lines():
    # 512 ways (Vulkan-Sim's L1D: 64 KiB of 128-byte lines in one set): the 513th line evicts
    # the first, and nothing else
    mem = rtunit.MemoryModel(cache_bytes=65536, ways=512, line_bytes=128, latency_cycles=1)
    seq = [(0, 128 * i, 128, i) for i in range(513)] + [(0, 128 * 1, 128, 10000),
                                                         (0, 0, 128, 10001)]
    _, level, c = trace_levels(mem, seq)
    assert level[-2:] == [1, 3]
    assert c["l1_misses"] == 514


# ------------------------------------------------------------------------------- warps

@pytest.fixture(scope="module")
def base():
    scene = load_scene("room")
    bvh = build(scene.mesh)
    o, d = primary_rays(scene.camera, 16, 8)
    return trace(bvh, o, d, backend="rtl", record=True).record


def fake_record(base, lengths):
    """A record whose ray i issues ``lengths[i]`` requests, each a box test of the root node (the
    replay's timing does not depend on what a request computes)."""
    n = len(lengths)
    assert n <= len(base.ray_words), f"the base record has {len(base.ray_words)} rays, {n} asked"
    ray = np.repeat(np.arange(n, dtype=np.uint32), lengths)
    root = base.ptr[0]
    return rtunit.Record(base.ray_words[:n], base.image, ray, np.full(len(ray), root, np.uint32),
                         np.full(len(ray), np.inf, np.float32), None, base.params)


def test_two_warps_hand_checked(base):
    # warp A (threads 0, 1): slot 0: thread 0 one request, thread 1 two; slot 1: thread 0 one
    # warp B (threads 2, 3): slot 0: one request each. Latency 11, turnaround 1, shader 5.
    rec = fake_record(base, [1, 2, 1, 1, 1])
    wave = Wave(rec, thread=np.array([0, 1, 2, 3, 0]), slot=np.array([0, 0, 0, 0, 1]))

    def run(rays, units=1):
        s = Schedule("one-kernel", warp_size=2, warps_per_unit=2, shader_cycles=5,
                     rt_units=units)
        fr = replay_frame([wave], rays, 1, None, s)
        return fr, fr.arrays["ray_times"].tolist()

    # one call in the unit at a time (2 rays): A0 at 0 (accepts 0, 1; thread 1's second request
    # at 13, done 24); B0 admitted at 25 (done 36, 37); A1 issued at 24 + 1 + 5 = 30, admitted
    # when B0 leaves, at 38, done 49
    fr, t = run(2)
    assert fr.cycles == 50 and fr.counters["frame_cycles"] == 50
    assert t == [[0, 0, 11], [0, 0, 24], [0, 25, 36], [0, 25, 37], [30, 38, 49]]
    w = fr.summary()["simt"]
    assert (w["warps"], w["trace_calls"]) == (2, 3)
    assert w["simt_efficiency"] == pytest.approx(5 / 3 / 2)
    assert w["slowest_ray_wait_cycles"] == (24 - 11) + (37 - 36) + 0
    # both calls at once (4 rays): A1 goes at 30, done 41
    fr, t = run(4)
    assert fr.cycles == 42
    assert t == [[0, 0, 11], [0, 0, 24], [0, 0, 13], [0, 0, 14], [30, 30, 41]]
    # two RT units: warp A on unit 0, warp B on unit 1, both from cycle 0
    fr, t = run(2, units=2)
    assert fr.cycles == 42
    assert t[2:4] == [[0, 0, 11], [0, 0, 12]]
    assert fr.arrays["call_unit"].tolist() == [0, 0, 1]


def test_tile_shapes_and_warps_of_screen_tiles():
    assert [tile_shape(s) for s in (1, 2, 4, 8, 16, 32, 64)] == [
        (1, 1), (2, 1), (2, 2), (4, 2), (4, 4), (8, 4), (8, 8)]
    # a 16 x 8 frame, warps of 32: two tiles of 8 x 4 per tile row
    thread = np.arange(16 * 8)
    plan = one_kernel_plan(thread, thread, np.zeros_like(thread), 32, 16)
    assert plan.warps == 4 and plan.calls == 4
    first = plan.call_rays[plan.call_ray_off[1]:plan.call_ray_off[2]]      # the second tile
    assert first[:9].tolist() == [8, 9, 10, 11, 12, 13, 14, 15, 24]
    with pytest.raises(ValueError, match="two rays at one slot"):
        one_kernel_plan(np.arange(2), np.array([0, 0]), np.array([1, 1]), 1, 4)


# ------------------------------------------------------------------------------- reference

def reference(lengths, plan, rays, warp, resident, units, pipes, ta, shader, latency=LAT):
    """The warp scheduler of rf_replay in plain Python, with free node fetches and a datapath
    that answers every request ``latency`` cycles after accepting it: (cycles summed over
    kernels, per-ray done cycles)."""
    n = len(lengths)
    cap = rays // warp
    ko, wo, co, cr = plan.kernel_off, plan.warp_call_off, plan.call_ray_off, plan.call_rays
    warp_of = np.repeat(np.arange(len(wo) - 1), np.diff(wo))
    done = [-1] * n
    seq = itertools.count()
    pos = [0] * n
    total = 0
    k = 0
    for q in range(len(ko) - 1):
        nxt, end = ko[q], ko[q + 1]
        left = wo[end] - wo[nxt]
        if not left:
            continue
        ready = [[] for _ in range(units)]       # heaps (at, seq, ray)
        waiting = [[] for _ in range(units)]     # heaps (at, seq, call)
        held = [0] * units
        remaining = {c: co[c + 1] - co[c] for c in range(wo[nxt], wo[end])}
        inflight = [[[] for _ in range(pipes)] for _ in range(units)]
        per = resident or -(-(end - nxt) // units)
        unit_of = {}

        def resident_warp(u, w, at):
            unit_of[w] = u
            heapq.heappush(waiting[u], (at, next(seq), wo[w]))

        def admit(u, now):
            while held[u] < cap and waiting[u] and waiting[u][0][0] <= now:
                _, _, c = heapq.heappop(waiting[u])
                held[u] += 1
                for r in cr[co[c]:co[c + 1]]:
                    heapq.heappush(ready[u], (now, next(seq), r))

        for _ in range(per):
            for u in range(units):
                if nxt < end:
                    resident_warp(u, nxt, k)
                    nxt += 1
        for u in range(units):
            admit(u, k)
        first = last = -1
        while left:
            for u in range(units):
                admit(u, k)
                for p in range(pipes):
                    fl = inflight[u][p]
                    if fl and fl[0][1] + latency == k:
                        r, _ = fl.pop(0)
                        last = k
                        pos[r] += 1
                        if pos[r] < lengths[r]:
                            heapq.heappush(ready[u], (k + ta, next(seq), r))
                            continue
                        done[r] = k
                        c = next(c for c in remaining if co[c] <= np.flatnonzero(cr == r)[0]
                                 < co[c + 1])
                        remaining[c] -= 1
                        if remaining[c] == 0:
                            left -= 1
                            held[u] -= 1
                            w = warp_of[c]
                            if c + 1 < wo[w + 1]:
                                heapq.heappush(waiting[u], (k + ta + shader, next(seq), c + 1))
                            elif nxt < end:
                                resident_warp(u, nxt, k + ta)
                                nxt += 1
                        admit(u, k + ta)
                for p in range(pipes):
                    if ready[u] and ready[u][0][0] <= k:
                        _, _, r = heapq.heappop(ready[u])
                        inflight[u][p].append((r, k))
                        first = k if first < 0 else first
            k += 1
        total += last - first + 1
    return total, done


@pytest.mark.parametrize("frame,warp,rays,resident,units,pipes,shader", [
    ("one-kernel", 1, 4, 0, 1, 1, 0),
    ("one-kernel", 2, 4, 3, 1, 1, 7),
    ("one-kernel", 4, 8, 4, 2, 1, 3),
    ("one-kernel", 8, 16, 2, 3, 2, 20),
    ("wavefront", 4, 8, 0, 2, 1, 0),
    ("wavefront", 2, 2, 1, 3, 2, 0),
])
def test_warp_scheduler_is_the_reference(base, frame, warp, rays, resident, units, pipes,
                                         shader):
    rng = np.random.default_rng(warp * 31 + units)
    threads = 24
    lengths, thread, slot = [], [], []
    for t in range(threads):
        for s in range(3):
            if rng.random() < 0.7 or s == 0:
                lengths.append(int(rng.integers(1, 6)))
                thread.append(t)
                slot.append(s)
    rec = fake_record(base, lengths)
    s = Schedule(frame, warp_size=warp, warps_per_unit=resident, shader_cycles=shader,
                 rt_units=units)
    fr = replay_frame([Wave(rec, thread=np.array(thread), slot=np.array(slot))], rays, pipes,
                      None, s, width=6)
    if frame == "one-kernel":
        plan = one_kernel_plan(np.arange(len(lengths)), np.array(thread), np.array(slot), warp, 6)
    else:
        plan = wavefront_plan([np.arange(len(lengths))], warp)
    cycles, done = reference(lengths, plan, rays, warp, resident or 2 * rays // warp, units,
                             pipes, 1, shader)
    assert fr.cycles == cycles
    assert fr.arrays["ray_times"][:, 2].tolist() == done


def test_bad_schedules_are_clear_errors(base):
    rec = fake_record(base, [1, 1])
    with pytest.raises(ValueError, match="power of two"):
        Schedule(warp_size=3)
    with pytest.raises(ValueError, match="multiple of the warp size"):
        replay_frame([Wave(rec)], 6, 1, None, Schedule(warp_size=4))
    with pytest.raises(ValueError, match="one-kernel"):
        replay_frame([Wave(rec)], 4, 1, None, Schedule("one-kernel"), order=RayOrder("hash"))
    with pytest.raises(ValueError, match="frame schedule"):
        Schedule("megakernel")


def test_docs_preset_table_is_the_presets():
    """docs/rtunit.md's preset table is driver.rtunit.presets' (one fact, one place)."""
    from pathlib import Path

    from driver.rtunit.presets import markdown
    doc = (Path(__file__).resolve().parent.parent / "docs" / "rtunit.md").read_text()
    start = "<!-- presets table: driver.rtunit.presets -->\n"
    table = doc[doc.index(start) + len(start):doc.index("<!-- end presets table -->")]
    assert table.strip() == markdown().strip()


def test_study_gpu_tables_and_plot_from_a_sweep(tmp_path, capsys):
    """``rayflex study gpu``: the one-kernel studies' tables (and plots) from a real ``rayflex
    sweep`` document; a table without a plot or a document of another kind is a one-line error
    before anything is written."""
    from driver.cli import main as cli_main
    sweep_json, png = tmp_path / "s.json", tmp_path / "c.png"
    assert cli_main(["sweep", "--scene", "sphere", "--workload", "shadow", "--size", "8",
                     "--bvh-format", "box32,q8", "--frame", "wavefront,one-kernel",
                     "--flush-between", "yes,no", "--json", str(sweep_json),
                     "--no-progress"]) == 0
    capsys.readouterr()
    assert cli_main(["study", "gpu", "compressed", str(sweep_json), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "| box32 |" in out and "| q8 |" in out and "| shadow | q8 |" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert cli_main(["study", "gpu", "schedules", str(sweep_json)]) == 0
    out = capsys.readouterr().out
    assert "wavefront, cold caches" in out and "one kernel" in out
    assert cli_main(["study", "gpu", "units", str(sweep_json), "--plot",
                     str(tmp_path / "u.png")]) == 2
    assert "has no plot" in capsys.readouterr().err and not (tmp_path / "u.png").exists()
    other = tmp_path / "other.json"
    other.write_text('{"points": [{"design_point": {}}]}')
    assert cli_main(["study", "gpu", "compressed", str(other), "--plot",
                     str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not a rayflex sweep" in err
    assert not (tmp_path / "o.png").exists()


def test_memory_levels_are_the_replays_numbering():
    """``driver.core.layout.MEMORY_LEVELS`` (the columns of a ray's bytes per level) numbers the
    levels as sim/rf_memory.h's ``enum Level`` does."""
    import re

    from driver.backends.build import SIM_DIR
    from driver.core.layout import MEMORY_LEVELS
    text = (SIM_DIR / "rf_memory.h").read_text()
    enum = re.search(r"enum Level : int \{([^}]*)\}", text).group(1)
    levels = {int(v): name for name, v in re.findall(r"kLevel(\w+) = (\d+)", enum)}
    assert [levels[i].lower() for i in range(len(levels))] == list(MEMORY_LEVELS)
