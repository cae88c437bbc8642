"""The RT unit inside a GPU: a frame's rays issued by warps of threads to RT units (docs/rtunit.md).

What a frame's replay needs beyond the recorded request chains (``driver.rtunit.Record``): for
every ray, its thread and its place in the thread's program (``Wave.thread``, ``Wave.slot``; the
workloads set them, ``driver.workloads.Batch``). From them and a ``Schedule`` this module builds
the kernels, warps and trace calls that ``rf_replay`` (sim/rtunit_scheduler.cpp) issues:

- ``one-kernel`` (``Schedule.frame``): the whole frame is one kernel, as a DXR/Vulkan dispatch is.
  Threads are grouped into warps of ``warp_size`` by screen tiles (``tile_shape``: 8 x 4 pixels for
  32), warps launch in tile order (row-major tiles); a warp's trace calls are its threads' slots in
  order, each call made of the warp's threads that have a ray at that slot (SIMT: the others are
  inactive for it). A warp issues its next call ``shader_cycles`` after its previous call's last
  response; no barrier separates ray types.
- ``wavefront``: one kernel per traced batch (a ray type's wavefront), in trace order, with a
  barrier between kernels (``flush_between``: the caches are dropped there, as every replay did
  before warps); a kernel's rays, in batch order, are its threads, ``warp_size`` consecutive rays
  a warp of one call. With ``warp_size`` 1 and one RT unit this is the per-ray pool of R rays.

The replay's statistics (``FrameReplay.summary``, ``FrameReplay.type_summary``) are the
``rtunit`` objects of docs/statistics.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..layout import INSTANCE_TYPE, NO_CHILD, NodeRef
from .energy import memory_energy

FRAMES = ("one-kernel", "wavefront")
MAX_WARP_SIZE = 64
MAX_RT_UNITS = 256
SERIES_POINTS = 64          # points of the published rays-in-flight series
LEVELS = ("l1", "l2", "dram")


def tile_shape(warp_size: int) -> tuple[int, int]:
    """(width, height) in pixels of a warp's screen tile: 2^ceil(k/2) x 2^floor(k/2) for a warp
    of 2^k threads (32: 8 x 4, as GPUs launch a 2-D dispatch)."""
    k = int(warp_size).bit_length() - 1
    return 1 << ((k + 1) // 2), 1 << (k // 2)


def check_warp_size(v) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1 or \
            v > MAX_WARP_SIZE or v & (v - 1):
        raise ValueError(f"warp size must be a power of two in 1..{MAX_WARP_SIZE}, got {v!r}")
    return int(v)


@dataclass(frozen=True)
class Schedule:
    """How a frame's rays reach the RT units (module docstring): the frame schedule, threads
    per warp, resident warps per unit (0: twice the warps a unit's ray pool holds), cycles of
    shader work between a warp's trace calls, whether caches are dropped at a wavefront
    barrier, and the number of RT units. The default is the replay before warps: wavefront
    kernels with cold caches, one ray per warp, one unit."""

    frame: str = "wavefront"
    warp_size: int = 1
    warps_per_unit: int = 0
    shader_cycles: int = 0
    flush_between: bool = True
    rt_units: int = 1

    def __post_init__(self):
        if self.frame not in FRAMES:
            raise ValueError(f"frame schedule: choose from {', '.join(FRAMES)}, got "
                             f"{self.frame!r}")
        check_warp_size(self.warp_size)
        for name, lo, hi in (("warps_per_unit", 0, None), ("shader_cycles", 0, None),
                             ("rt_units", 1, MAX_RT_UNITS)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo or \
                    (hi is not None and v > hi):
                raise ValueError(f"frame schedule: {name} must be an integer >= {lo}"
                                 + (f" and <= {hi}" if hi else "") + f", got {v!r}")

    def resident(self, rays_in_flight: int, window: int = 0) -> int:
        """Warps resident per unit: ``warps_per_unit``, or twice the warps the unit holds (its
        ray pool, or a scheduler's window of held rays when larger)."""
        held = max(int(rays_in_flight), int(window))
        return int(self.warps_per_unit) or 2 * max(held // self.warp_size, 1)

    def describe(self, rays_in_flight: int, window: int = 0) -> dict:
        return {"frame_schedule": self.frame, "rt_units": int(self.rt_units),
                "warp_size": int(self.warp_size),
                "warps_per_unit": self.resident(rays_in_flight, window),
                "shader_cycles": int(self.shader_cycles),
                "flush_between": bool(self.flush_between)}


PER_RAY_POOL = Schedule()            # the replay of one batch before warps


@dataclass
class Wave:
    """One traced batch as the replay sees it: its ``Record``, its ray type, and per ray its
    thread and slot (``driver.workloads.Batch``; None: thread = ray index, slot = 0)."""

    record: object
    kind: str = "primary"
    thread: np.ndarray | None = None
    slot: np.ndarray | None = None


@dataclass
class Combined:
    """The waves' records as one: requests concatenated in wave order, ray-table rows and chains
    (world rays) numbered across the frame."""

    params: dict
    ray_words: np.ndarray
    image: np.ndarray
    ray: np.ndarray
    ptr: np.ndarray
    extent: np.ndarray
    chain: np.ndarray
    before: np.ndarray
    responses: np.ndarray | None
    chain_off0: np.ndarray         # (waves + 1,): first chain of each wave
    request_off: np.ndarray        # (waves + 1,): first request of each wave

    @property
    def chains(self) -> int:
        return int(self.chain_off0[-1])


def combine(records: list) -> Combined:
    """``Combined`` of records traced on one BVH image with one datapath."""
    if not records:
        raise ValueError("no recorded batch to replay")
    first = records[0]
    for r in records[1:]:
        if r.params != first.params:
            raise ValueError("the batches of a frame were traced on different datapaths")
        if r.image is not first.image and not np.array_equal(r.image, first.image):
            raise ValueError("the batches of a frame were traced on different BVH images")
    row_off = np.cumsum([0] + [len(r.ray_words) for r in records])
    chain_off0 = np.cumsum([0] + [r.rays for r in records]).astype(np.int64)
    request_off = np.cumsum([0] + [r.ops for r in records]).astype(np.int64)

    def cat(parts, dtype):
        return (np.concatenate(parts).astype(dtype, copy=False) if parts
                else np.zeros(0, dtype))

    ray = cat([r.ray.astype(np.int64) + row_off[i] for i, r in enumerate(records)], np.uint32)
    chain = cat([(r.ray if r.chain is None else r.chain).astype(np.int64) + chain_off0[i]
                 for i, r in enumerate(records)], np.uint32)
    before = cat([np.full(r.ops, NO_CHILD, np.uint32) if r.before is None else r.before
                  for r in records], np.uint32)
    responses = (None if any(r.responses is None for r in records) else
                 np.concatenate([r.responses for r in records]))
    return Combined(first.params,
                    np.concatenate([r.ray_words for r in records]) if len(records) > 1
                    else first.ray_words, first.image, ray,
                    cat([r.ptr for r in records], np.uint32),
                    cat([r.extent for r in records], np.float32), chain, before, responses,
                    chain_off0, request_off)


@dataclass
class Plan:
    """Kernels, warps and trace calls (``rf_replay``'s schedule arrays)."""

    kernel_off: np.ndarray       # over warps
    warp_call_off: np.ndarray    # over calls
    call_ray_off: np.ndarray     # over call_rays
    call_rays: np.ndarray        # chain indices
    call_slot: np.ndarray        # the program slot of each call (wavefront: 0)

    @property
    def calls(self) -> int:
        return len(self.call_ray_off) - 1

    @property
    def warps(self) -> int:
        return len(self.warp_call_off) - 1


def wavefront_plan(kernels: list[np.ndarray], warp_size: int) -> Plan:
    """Wavefront kernels: each kernel's chains (in entry order) in warps of ``warp_size``
    consecutive rays, one call each."""
    sizes, rays = [], []
    for ids in kernels:
        n = len(ids)
        full, rest = divmod(n, warp_size)
        sizes.append(np.concatenate([np.full(full, warp_size, np.int64),
                                     np.full(1 if rest else 0, rest, np.int64)]))
        rays.append(np.asarray(ids, np.int64))
    per_kernel = np.array([len(s) for s in sizes], np.int64)
    calls = np.concatenate(sizes) if sizes else np.zeros(0, np.int64)
    kernel_off = np.concatenate([[0], np.cumsum(per_kernel)]).astype(np.int64)
    call_ray_off = np.concatenate([[0], np.cumsum(calls)]).astype(np.int64)
    return Plan(kernel_off, np.arange(len(calls) + 1, dtype=np.int64), call_ray_off,
                np.concatenate(rays) if rays else np.zeros(0, np.int64),
                np.zeros(len(calls), np.int64))


def one_kernel_plan(chain_ids: np.ndarray, thread: np.ndarray, slot: np.ndarray,
                    warp_size: int, width: int | None) -> Plan:
    """One kernel: threads (pixel indices of a ``width``-wide frame; None: a 1-D dispatch) in
    warps of screen tiles, warps in row-major tile order, each warp's calls its slots in order."""
    thread = np.asarray(thread, np.int64)
    slot = np.asarray(slot, np.int64)
    if len(thread) and (thread.min() < 0 or slot.min() < 0):
        raise ValueError("threads and slots must be >= 0")
    tw, th = tile_shape(warp_size)
    if width is None:
        tw, th, width = warp_size, 1, int(thread.max()) + 1 if len(thread) else 1
    x, y = thread % width, thread // width
    tiles_x = -(-width // tw)
    warp = (y // th) * tiles_x + x // tw
    lane = (y % th) * tw + x % tw
    order = np.lexsort((lane, slot, warp))
    w, s, ln = warp[order], slot[order], lane[order]
    if len(order) > 1:
        same = (np.diff(w) == 0) & (np.diff(s) == 0)
        if np.any(same & (np.diff(ln) == 0)):
            raise ValueError("a thread has two rays at one slot of its program")
        call_start = np.concatenate([[True], ~same])
        warp_start = np.concatenate([[True], np.diff(w) != 0])
    else:
        call_start = warp_start = np.ones(len(order), bool)
    call_first = np.flatnonzero(call_start)
    call_ray_off = np.concatenate([call_first, [len(order)]]).astype(np.int64)
    warp_call_off = np.concatenate([np.flatnonzero(warp_start[call_first]),
                                    [len(call_first)]]).astype(np.int64)
    kernel_off = np.array([0, len(warp_call_off) - 1], np.int64)
    return Plan(kernel_off, warp_call_off, call_ray_off,
                np.asarray(chain_ids, np.int64)[order], s[call_first])


@dataclass
class FrameReplay:
    """One frame's RT-unit replay: its schedule, the engine's counters and the per-ray and
    per-call times (``summary``, ``type_summary`` turn them into docs/statistics.md objects)."""

    schedule: Schedule
    rays_in_flight: int
    pipelines: int
    turnaround: int
    latency: int
    memory: object                 # MemoryModel or None
    kinds: list                    # ray type of each wave
    combined: Combined
    plan: Plan
    counters: dict                 # ReplayStats + scheduler counts
    per_pipe: np.ndarray           # (units, P)
    arrays: dict                   # ray_times, ray_served, ray_wait, call_times, call_unit, ...
    chain_ops: np.ndarray          # (chains,) requests of each chain
    chain_box: np.ndarray          # (chains,) box requests
    chain_xf: np.ndarray           # (chains,) TRANSFORM requests
    kernel_waves: list             # waves of each kernel
    wall_s: float
    verified: bool
    responses: np.ndarray
    order_cost: dict | None = None
    window: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def units(self) -> int:
        return int(self.schedule.rt_units)

    @property
    def ops(self) -> int:
        return int(self.chain_ops.sum())

    @property
    def cycles(self) -> int:
        return int(self.counters["cycles"])

    @property
    def utilization(self) -> float:
        c = self.cycles
        return self.ops / (self.units * self.pipelines * c) if c else 0.0

    def wave_chains(self, q: int) -> slice:
        c = self.combined.chain_off0
        return slice(int(c[q]), int(c[q + 1]))

    # ------------------------------------------------------------------ published objects
    def _base(self) -> dict:
        return {"rays_in_flight": int(self.rays_in_flight), "pipelines": int(self.pipelines),
                "turnaround_cycles": int(self.turnaround)}

    def _rays_part(self, chains: np.ndarray) -> dict:
        """Latency and memory figures of the rays ``chains`` (chain indices with requests)."""
        times = self.arrays["ray_times"][chains]
        lat = (times[:, 2] - times[:, 0]).astype(np.float64)
        out = {"latency_mean": float(lat.mean()) if len(lat) else 0.0,
               "latency_p95": float(np.percentile(lat, 95)) if len(lat) else 0.0,
               "queue_mean": float((times[:, 1] - times[:, 0]).mean()) if len(lat) else 0.0}
        if self.memory is not None:
            served = self.arrays["ray_served"][chains]
            tx = self.memory.transaction_bytes
            s = served.sum(axis=0)
            n = len(chains)
            out.update({
                "line_accesses": int(s[1:].sum() // tx), "line_hits": int(s[1] // tx),
                "line_misses": int((s[2] + s[3]) // tx), "bytes_from_memory": int(s[3]),
                "node_wait_cycles": int(self.arrays["ray_wait"][chains].sum()),
                "bytes_served": {lvl: int(s[i + 1]) for i, lvl in enumerate(LEVELS)},
                "bytes_served_per_ray": {lvl: (float(s[i + 1]) / n if n else 0.0)
                                         for i, lvl in enumerate(LEVELS)},
            })
            l2_acc = int((s[2] + s[3]) // tx) if self.memory.l2_bytes else 0
            out["memory_energy"] = memory_energy(self.memory, out["line_accesses"], l2_acc,
                                                 int(s[3]), n)
        return out

    def _kernel_rows(self, kernels) -> list[dict]:
        kt = self.arrays["kernel_times"]
        rows = []
        for q in kernels:
            ids = self._kernel_chains[q]
            first, last, _ = kt[q]
            cyc = int(last - first + 1) if first >= 0 else 0
            ops = int(self.chain_ops[ids].sum())
            row = {"rays": int(self._kernel_rays[q]), "ops": ops, "cycles": cyc,
                   "utilization": ops / (self.units * self.pipelines * cyc) if cyc else 0.0}
            if self.memory is not None:
                row["bytes_from_memory"] = int(self.arrays["ray_served"][ids, 3].sum())
            rows.append(row)
        return rows

    def summary(self) -> dict:
        """The frame's RT-unit object (docs/statistics.md, ``rtunit_memory``)."""
        c, m = self.counters, self.ops
        n = int(self.combined.chains)
        out = {**self._base(), **self.schedule.describe(self.rays_in_flight, self.window),
               "rays": n, "ops": m, "cycles": self.cycles,
               "frame_cycles": int(c["frame_cycles"]), "kernels": len(self.kernel_waves),
               "starved_cycles": int(c["starved_cycles"]), "sim_wall_s": self.wall_s,
               "responses_verified": self.verified}
        called = self.plan.call_rays
        out.update(self._rays_part(called))
        if self.memory is not None:
            out.update(self.memory_levels())
            out["memory_energy"] = memory_energy(self.memory, c["l1_accesses"],
                                                 c["l2_accesses"], c["dram_bytes"], n)
        out["simt"] = self.warp_stats()
        if self.schedule.frame == "wavefront":
            out["wavefronts"] = self._kernel_rows(range(len(self.kernel_waves)))
        if self.order_cost:
            out["ray_order_cost"] = self.order_cost
        out["unit_ops"] = self.per_pipe.sum(axis=1).tolist()
        return derived(out, self.units)

    def memory_levels(self) -> dict:
        """Counters of each memory level (the frame's: merged misses, MSHR stalls)."""
        c = self.counters
        levels = {}
        for lvl in ("l1", "l2"):
            acc = c[f"{lvl}_accesses"]
            hits = c[f"{lvl}_hits"] + c[f"{lvl}_merged"]
            levels[lvl] = {"line_accesses": acc, "line_hits": hits,
                           "merged_misses": c[f"{lvl}_merged"],
                           "line_misses": c[f"{lvl}_misses"], "fill_bytes": c[f"{lvl}_bytes"],
                           "wait_cycles": c[f"{lvl}_wait_cycles"],
                           "hit_rate": hits / acc if acc else 0.0}
        levels["dram"] = {"transfers": c["dram_transfers"], "transfer_bytes": c["dram_bytes"],
                          "wait_cycles": c["dram_wait_cycles"]}
        return {"levels": levels, "mshr_stalls": c["mshr_stalls"],
                "mshr_stall_cycles": c["mshr_stall_cycles"]}

    def warp_stats(self) -> dict:
        """SIMT efficiency of the trace calls, the cycles warps wait for their slowest ray, and
        rays held by the units over time."""
        p, s = self.plan, self.schedule
        active = np.diff(p.call_ray_off)
        done = self.arrays["ray_times"][p.call_rays, 2]
        call_done = self.arrays["call_times"][:, 2]
        if p.calls:
            first_done = np.minimum.reduceat(done, p.call_ray_off[:-1])
            slowest = (call_done - first_done).astype(np.float64)
        else:
            slowest = np.zeros(0)
        series = self.arrays["series"].astype(np.float64)
        bin_c = int(self.counters["series_bin_cycles"])
        span = max(int(self.counters["last_response"]) + 1, 1)
        if len(series):
            # mean rays held per unit in each bin (the last bin may be partial)
            widths = np.full(len(series), bin_c, np.float64)
            widths[-1] = span - bin_c * (len(series) - 1) if span > bin_c * (len(series) - 1) \
                else bin_c
            per = series / widths / self.units
            group = -(-len(per) // SERIES_POINTS)
            pts = [float(np.average(per[i:i + group], weights=widths[i:i + group]))
                   for i in range(0, len(per), group)]
            mean = float(series.sum() / widths.sum() / self.units)
        else:
            pts, group, mean = [], 1, 0.0
        return {"warps": p.warps, "trace_calls": p.calls,
                "simt_efficiency": float(active.mean() / s.warp_size) if p.calls else 0.0,
                "slowest_ray_wait_cycles": int(slowest.sum()),
                "slowest_ray_wait_per_call": float(slowest.mean()) if p.calls else 0.0,
                "rays_held_mean": mean, "max_rays_held": int(self.counters["max_rays_held"]),
                "rays_held_series": {"bin_cycles": bin_c * group, "per_unit": pts}}

    def type_summary(self, kind: str) -> dict:
        """One ray type's RT-unit object: its rays, ops, latency and bytes per level; with the
        wavefront schedule also its kernels' cycles (one-kernel frames: null when the ray types
        share the pipelines, the frame's when it is the only one)."""
        waves = [q for q, k in enumerate(self.kinds) if k == kind]
        ids = np.concatenate([self._wave_called[q] for q in waves]) if waves else \
            np.zeros(0, np.int64)
        rays = sum(int(self.combined.chain_off0[q + 1] - self.combined.chain_off0[q])
                   for q in waves)
        out = {**self._base(), "rays": rays, "ops": int(self.chain_ops[ids].sum()),
               "responses_verified": self.verified}
        if self.schedule.frame == "wavefront":
            kernels = [q for q, w in enumerate(self.kernel_waves) if w in waves]
            kt = self.arrays["kernel_times"]
            out["cycles"] = int(sum(kt[q, 1] - kt[q, 0] + 1 for q in kernels if kt[q, 0] >= 0))
            out["starved_cycles"] = int(sum(kt[q, 2] for q in kernels))
        elif set(self.kinds) == {kind}:     # the frame's only ray type: the frame's time
            out["cycles"] = self.cycles
            out["starved_cycles"] = int(self.counters["starved_cycles"])
        else:                                # ray types share the pipelines: no time of its own
            out["cycles"] = None
            out["starved_cycles"] = None
        out.update(self._rays_part(ids))
        if self.schedule.frame == "wavefront":
            out["wavefronts"] = self._kernel_rows(kernels)
        return derived(out, self.units)

    def __post_init__(self):
        n = self.combined.chains
        called = np.zeros(n, bool)
        called[self.plan.call_rays] = True
        off = self.combined.chain_off0
        self._wave_called = [np.flatnonzero(called[off[q]:off[q + 1]]) + off[q]
                             for q in range(len(self.kinds))]
        self._kernel_chains, self._kernel_rays = [], []
        p = self.plan
        for q in range(len(self.kernel_waves)):
            c0 = p.warp_call_off[p.kernel_off[q]]
            c1 = p.warp_call_off[p.kernel_off[q + 1]]
            self._kernel_chains.append(p.call_rays[p.call_ray_off[c0]:p.call_ray_off[c1]])
            w = self.kernel_waves[q]
            self._kernel_rays.append(int(off[w + 1] - off[w]) if w is not None else
                                     int(off[-1]))


def derived(s: dict, units: int = 1) -> dict:
    """The ratios of an RT-unit object from its counts (null where its cycles are)."""
    cyc, n = s.get("cycles"), s["rays"]
    units = int(s.get("rt_units", units))
    if cyc is None:
        s["utilization"] = s["frame_us_at_1ghz"] = s["cycles_per_ray"] = None
    else:
        s["utilization"] = s["ops"] / (units * s["pipelines"] * cyc) if cyc else 0.0
        s["frame_us_at_1ghz"] = cyc / 1000
        s["cycles_per_ray"] = cyc / n if n else 0.0
    if "line_accesses" in s:
        acc = s["line_accesses"]
        s["hit_rate"] = s["line_hits"] / acc if acc else 0.0
        s["bytes_per_ray"] = s["bytes_from_memory"] / n if n else 0.0
    return s


def replay_frame(waves: list[Wave], rays_in_flight: int, pipelines: int = 1, memory=None,
                 schedule: Schedule = PER_RAY_POOL, width: int | None = None,
                 ray_order: str = "index", ray_window: int | None = None, treelets=None,
                 turnaround: int = 1, skip_idle: bool = True, verify: bool = True,
                 params: dict | None = None) -> FrameReplay:
    """Replay a frame's recorded batches (``Wave``s, in trace order) on ``schedule.rt_units`` RT
    units of P pipelines and R rays in flight each, in front of ``memory`` (a
    ``driver.rtunit.MemoryModel``; None: free node fetches). ``width``: the frame's width in
    pixels (threads are pixel indices; None: a 1-D dispatch). ``ray_order``/``ray_window``/
    ``treelets``: as ``driver.rtunit.replay`` (a sorting order reorders a wavefront's ray queue,
    so it needs the wavefront schedule). ``params``: the datapath to replay on (default: the
    one traced on). Every response is compared with the functional run's (``verify``)."""
    from ..backends.harness import replay_schedule
    from ..datapath import LATENCY
    from . import ReplayMismatch
    from . import order as ray_orders
    r, p, ta = int(rays_in_flight), int(pipelines), int(turnaround)
    s = schedule
    if r < 1:
        raise ValueError(f"rays in flight must be >= 1, got {rays_in_flight}")
    if not 1 <= p <= 64:
        raise ValueError(f"pipelines must be in 1..64, got {pipelines}")
    if ta < 0:
        raise ValueError(f"turnaround must be >= 0 cycles, got {turnaround}")
    if r % s.warp_size:
        raise ValueError(f"rays in flight ({r}) must be a multiple of the warp size "
                         f"({s.warp_size}): the RT unit holds whole warps")
    pol = ray_orders.policy(ray_order)
    window = ray_orders.check_window(ray_orders.DEFAULT_WINDOW if ray_window is None
                                     else ray_window)
    if pol.schedule and window < r:
        raise ValueError(f"ray order {ray_order!r}: the window ({window} rays) must hold at "
                         f"least the {r} rays in flight")
    if pol.schedule and window % s.warp_size:
        raise ValueError(f"ray order {ray_order!r}: the window ({window} rays) must be a "
                         f"multiple of the warp size ({s.warp_size})")
    if pol.key is not None and s.frame == "one-kernel":
        raise ValueError(f"ray order {ray_order!r} sorts a wavefront's ray queue; in a "
                         "one-kernel frame every ray is issued by its thread: use it with "
                         "--frame wavefront, or a scheduling order (affinity, treelet)")
    records = [w.record for w in waves]
    comb = combine(records)
    if params is not None:
        comb.params = params
    n = comb.chains
    chain_idx = np.argsort(comb.chain, kind="stable").astype(np.int64)
    counts = np.bincount(comb.chain.astype(np.int64), minlength=n)
    chain_off = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=chain_off[1:])
    is_box = NodeRef.is_box(comb.ptr)
    is_xf = NodeRef.type(comb.ptr) == INSTANCE_TYPE
    ch = comb.chain.astype(np.int64)
    chain_box = np.bincount(ch[is_box], minlength=n)
    chain_xf = np.bincount(ch[is_xf], minlength=n)
    nonempty = counts > 0
    off = comb.chain_off0
    if s.frame == "wavefront":
        kernels, kernel_waves = [], []
        for q, rec in enumerate(records):
            perm = ray_orders.permutation(rec, ray_order, window)
            ids = off[q] + (np.arange(rec.rays, dtype=np.int64) if perm is None else perm)
            kernels.append(ids[nonempty[ids]])
            kernel_waves.append(q)
        plan = wavefront_plan(kernels, s.warp_size)
    else:
        threads, slots = [], []
        for q, w in enumerate(waves):
            k = records[q].rays
            threads.append(np.arange(k, dtype=np.int64) if w.thread is None
                           else np.asarray(w.thread, np.int64))
            slots.append(np.full(k, q, np.int64) if w.slot is None
                         else np.asarray(w.slot, np.int64))
            if len(threads[-1]) != k or len(slots[-1]) != k:
                raise ValueError("a wave needs one thread and one slot per ray")
        thread, slot = np.concatenate(threads), np.concatenate(slots)
        ids = np.flatnonzero(nonempty)
        plan = one_kernel_plan(ids, thread[ids], slot[ids], s.warp_size, width)
        kernel_waves = [None]
    tl = None
    if pol.treelets and comb.ray.size:
        parts = [ray_orders.treelet_schedule(rec, treelets or ray_orders.DEFAULT_TREELETS)
                 for rec in records if rec.ops]
        tl = parts[0]
        if len(parts) > 1:
            from dataclasses import replace
            tl = replace(tl, request_treelet=np.concatenate([t.request_treelet for t in parts]))
    latency = int(comb.params.get("LATENCY", LATENCY))
    config = {"units": s.rt_units, "pipelines": p, "slots": r, "warp_size": s.warp_size,
              "resident": s.resident(r, window if pol.schedule else 0), "turnaround": ta,
              "shader_cycles": s.shader_cycles, "skip_idle": int(bool(skip_idle)),
              "max_idle": 100 * latency + 1000, "window": window if pol.schedule else 0,
              "flush": int(bool(s.flush_between)), "active_treelets": 0, "treelet_flags": 0}
    t0 = time.perf_counter()
    rsp, counters, per_pipe, arrays = replay_schedule(
        comb.params, config, None if memory is None else memory.config(), comb.ray_words,
        comb.image, comb.ray, comb.ptr, comb.extent, chain_idx, chain_off, comb.chain,
        comb.before, plan.kernel_off, plan.warp_call_off, plan.call_ray_off, plan.call_rays, tl)
    wall = time.perf_counter() - t0
    m = len(rsp)
    if counters["bad_tags"]:
        raise ReplayMismatch(f"{counters['bad_tags']} replayed responses carry the wrong ray tag")
    verified = False
    if verify and comb.responses is not None:
        # word 0 is the tag: the frame's ray-table row, checked by the replay (bad_tags)
        diff = np.flatnonzero((rsp[:, 1:] != comb.responses[:, 1:]).any(axis=1))
        if len(diff):
            raise ReplayMismatch(f"{len(diff)} of {m} replayed responses differ from the "
                                 f"functional run's (first: request {int(diff[0])})")
        verified = True
    cost = None
    if ray_order != "index":
        depth = ray_orders.tree_depth(records[0]) if pol.schedule else 0
        cost = ray_orders.cost(ray_order, window, n, r, depth,
                               counters if pol.schedule else None,
                               treelets=(treelets or ray_orders.DEFAULT_TREELETS, tl)
                               if tl is not None else None)
    return FrameReplay(s, r, p, ta, latency, memory, [w.kind for w in waves], comb, plan,
                       counters, per_pipe, arrays, counts.astype(np.int64),
                       chain_box.astype(np.int64), chain_xf.astype(np.int64), kernel_waves,
                       wall, verified, rsp, cost, window if pol.schedule else 0)


def waves_of(batches) -> list[Wave]:
    """The ``Wave``s of a workload frame's traced batches (``driver.workloads.Batch``, each
    with its recorded ``result.record``), in trace order."""
    return [Wave(b.result.record, b.kind, b.thread, b.slot) for b in batches]


def replay_point(waves: list[Wave], point, width: int | None = None,
                 ideal: bool = False) -> dict:
    """A frame's RT-unit objects on design point ``point`` (``driver.design.DesignPoint``):
    ``rtunit_memory``, the replay of the point's RT units and memory hierarchy, and with
    ``ideal`` also ``rtunit``, the same replay with every node fetch free (a second replay: off
    by default); ``by_type``: each ray type's objects. The records replay on the point's datapath
    configuration and latency; every response is checked against the recorded one bit for bit."""
    kinds = list(dict.fromkeys(w.kind for w in waves))
    order = point.order_options()
    args = dict(schedule=point.schedule(), width=width, params=point.rtl_params(), **order)
    out = {"rtunit": None, "rtunit_memory": None,
           "by_type": {k: {"rtunit": None, "rtunit_memory": None} for k in kinds}}
    for key, memory in (("rtunit_memory", point.memory()), ("rtunit", None)):
        if key == "rtunit" and not ideal:
            continue
        fr = replay_frame(waves, point.rays_in_flight, point.pipelines, memory, **args)
        out[key] = fr.summary()
        for k in kinds:
            out["by_type"][k][key] = fr.type_summary(k)
    return out
