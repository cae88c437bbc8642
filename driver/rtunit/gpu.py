"""The RT unit inside a GPU: a frame's recorded rays replayed as warps of threads issue them to
RT units in front of a memory hierarchy (docs/rtunit.md).

``replay_frame`` runs a frame's ``Wave``s under a ``Schedule`` (``driver.rtunit.plan``) through
``rf_replay`` (sim/rtunit_scheduler.cpp) and returns a ``FrameReplay``, whose ``summary`` and
``type_summary`` are the ``rtunit`` objects of docs/statistics.md; ``replay_point`` does it for a
design point (``driver.design.DesignPoint``): the one timing replay a command runs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..backends import harness
from ..backends.rtunit import DEFAULT_DIVIDERS, DEFAULT_SETUPS, div_cycles
from ..core.datapath import LATENCY
from ..core.layout import INSTANCE_TYPE, MEMORY_LEVELS, NodeRef
from . import order as ray_orders
from .energy import memory_energy
from .plan import PER_RAY_POOL, Combined, Plan, Schedule, Wave, build_plan, combine

SERIES_POINTS = 64          # points of the published rays-in-flight series
LEVELS = MEMORY_LEVELS[1:]          # the levels that supply node bytes
_L1, _L2, _DRAM = (MEMORY_LEVELS.index(lvl) for lvl in LEVELS)


# How the replay runs the datapath pipelines: "timing", as their handshake timing (a response
# the model's latency after its request, one request per cycle; the responses are the functional
# run's), or "rtl", each request evaluated again on a Verilated model and its response compared
# with the functional run's. Every count and time is the same (tests compare the two).
REPLAY_DATAPATHS = ("timing", "rtl")
DEFAULT_REPLAY_DATAPATH = "timing"
# What the replay charges per request: "replay", its own costs (one turnaround cycle between a
# response and the ray's next request, no divider), or "rtl", the RT unit in RTL's (``UnitCosts``)
UNIT_COSTS = ("replay", "rtl")
DEFAULT_UNIT_COSTS = "replay"


@dataclass(frozen=True)
class UnitCosts:
    """The RT unit in RTL's costs, charged by the replay in place of its one ``turnaround``
    cycle per request (docs/rtunit_rtl.md#the-replay-against-the-unit): the ray port, the pop
    port, the fetch request's register, the memory port and the scheduler's cycle per node; the
    response stage's cycle per hit child of a box; ``dividers`` binary32 dividers of
    ``div_cycles`` latency for the triangle hits (the RTL's DIV_CYCLES by default); the result
    port. ``fixed_latency`` > 0: the unit's fixed-latency memory (every node fetch that many
    cycles) when the replay has no memory hierarchy. ``any_hit``: the any-hit rays (a bool, or
    one per ray of the frame; None: each wave's own, ``Wave.any_hit``), which end at their
    accepted triangle without a last pop.
    ``stack_depth`` > 0: each ray's stack holds that many entries, more spill to memory and are
    read back when the stack empties (0: unbounded, none spill). ``setups``: the ray setups
    (``div_cycles`` each) of rays entering instances after their TRANSFORM. With several
    pipelines each has its response stage, the dividers and the ray setups are shared through
    one port each (granted round robin), as in the unit's RTL (``rtl/rf_rtu_pipes.sv``). Needs
    the per-ray pool's index order (the unit has no other scheduler). ``culls``: the
    distance-culled stack's pops (``driver.traversal.Traversal.cull_events``: rows of chain,
    requests it had issued, entries culled then; None: no culling), one pop-port cycle each."""

    dividers: int = DEFAULT_DIVIDERS
    div_cycles: int = field(default_factory=div_cycles)
    fixed_latency: int = 0
    any_hit: object = None
    stack_depth: int = 0
    setups: int = DEFAULT_SETUPS
    culls: object = None

    def config(self) -> dict:
        """Its ``REPLAY_CONFIG`` fields."""
        return {"unit_costs": 1, "dividers": self.dividers, "div_cycles": self.div_cycles,
                "fixed_latency": self.fixed_latency, "stack_depth": self.stack_depth,
                "setups": self.setups}


class ReplayMismatch(RuntimeError):
    """The replayed RTL responses differ from the functional run's (must never happen)."""


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
    verified: bool | None          # responses compared (None: the timing replay)
    responses: np.ndarray
    order_cost: dict | None = None
    window: int = 0
    extra: dict = field(default_factory=dict)
    datapath: str = "rtl"          # how the pipelines ran (REPLAY_DATAPATHS)
    unit_costs: str = DEFAULT_UNIT_COSTS   # what the replay charged (UNIT_COSTS)

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
                "line_accesses": int(s[_L1:].sum() // tx), "line_hits": int(s[_L1] // tx),
                "line_misses": int((s[_L2] + s[_DRAM]) // tx),
                "bytes_from_memory": int(s[_DRAM]),
                "node_wait_cycles": int(self.arrays["ray_wait"][chains].sum()),
                "bytes_served": {lvl: int(s[MEMORY_LEVELS.index(lvl)]) for lvl in LEVELS},
                "bytes_served_per_ray": {lvl: (float(s[MEMORY_LEVELS.index(lvl)]) / n
                                               if n else 0.0) for lvl in LEVELS},
            })
            l2_acc = int((s[_L2] + s[_DRAM]) // tx) if self.memory.l2_bytes else 0
            out["memory_energy"] = memory_energy(self.memory, out["line_accesses"], l2_acc,
                                                 int(s[_DRAM]), n)
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
               "replay_datapath": self.datapath, "responses_verified": self.verified,
               "unit_costs": self.unit_costs}
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
               "replay_datapath": self.datapath,
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
                 order: ray_orders.RayOrder = ray_orders.RayOrder(), turnaround: int = 1,
                 skip_idle: bool = True, verify: bool = True,
                 datapath: str = DEFAULT_REPLAY_DATAPATH,
                 unit_costs: UnitCosts | None = None) -> FrameReplay:
    """Replay a frame's recorded batches (``Wave``s, in trace order) on ``schedule.rt_units`` RT
    units of P pipelines and R rays in flight each, in front of ``memory`` (a
    ``driver.rtunit.MemoryModel``; None: free node fetches), on the datapath the records name
    (``Record.params``). ``width``: the frame's width in pixels (threads are pixel indices;
    None: a 1-D dispatch). ``order``: the ray order (``driver.rtunit.order.RayOrder``: policy,
    window, treelets, as ``driver.rtunit.replay``'s ``ray_order``/``ray_window``/``treelets``;
    a sorting order reorders a wavefront's ray queue, so it needs the wavefront schedule).
    ``datapath`` (``REPLAY_DATAPATHS``): "timing" models each pipeline by the handshake timing
    of its Verilated model (``harness.model_latency``) and takes the functional run's responses
    (a record without responses replays as "rtl"); "rtl" evaluates every request on the model
    again and compares each response with the functional run's (``verify``). ``unit_costs``
    (``UnitCosts``): charge the RT unit in RTL's costs instead of ``turnaround``."""
    r, p, ta = int(rays_in_flight), int(pipelines), int(turnaround)
    s = schedule
    pol, window = _check_replay(r, p, ta, s, order, datapath)
    _check_costs(unit_costs, pol.schedule or pol.treelets)
    records = [w.record for w in waves]
    comb = combine(records)
    chains = chain_layout(comb)
    plan, kernel_waves = build_plan(waves, comb, chains[2] > 0, s, order.policy, window, width)
    tl = _treelet_schedule(records, order.treelets) if pol.treelets and comb.ray.size else None
    latency = int(comb.params.get("LATENCY", LATENCY))
    timing = datapath == "timing" and comb.responses is not None
    config = {"units": s.rt_units, "pipelines": p, "slots": r, "warp_size": s.warp_size,
              "resident": s.resident(r, window if pol.schedule else 0), "turnaround": ta,
              "shader_cycles": s.shader_cycles, "skip_idle": int(bool(skip_idle)),
              "max_idle": 100 * latency + 1000, "window": window if pol.schedule else 0,
              "flush": int(bool(s.flush_between)), "active_treelets": 0, "treelet_flags": 0,
              "timing_latency": harness.model_latency(comb.params) if timing else 0,
              **(unit_costs.config() if unit_costs is not None else {})}
    t0 = time.perf_counter()
    rsp, counters, per_pipe, arrays = harness.replay_schedule(
        comb.params, config, None if memory is None else memory.config(), comb, chains[:2],
        plan, tl, _any_hit(unit_costs, waves, comb), _culls(unit_costs, chains[1]))
    wall = time.perf_counter() - t0
    if timing:
        rsp, verified = comb.responses, None          # nothing evaluated, nothing compared
    else:
        verified = _verify(rsp, counters, comb, verify)
    cost = None
    if order.policy != "index":
        depth = ray_orders.tree_depth(records[0]) if pol.schedule else 0
        cost = ray_orders.cost(order.policy, window, comb.chains, r, depth,
                               counters if pol.schedule else None,
                               treelets=(order.treelets or ray_orders.DEFAULT_TREELETS, tl)
                               if tl is not None else None)
    ptr = NodeRef.type(comb.ptr)
    ch = comb.chain.astype(np.int64)
    chain_box, chain_xf = [np.bincount(ch[sel], minlength=comb.chains).astype(np.int64)
                           for sel in (NodeRef.is_box(comb.ptr), ptr == INSTANCE_TYPE)]
    return FrameReplay(
        schedule=s, rays_in_flight=r, pipelines=p, turnaround=ta, latency=latency,
        memory=memory, kinds=[w.kind for w in waves], combined=comb, plan=plan,
        counters=counters, per_pipe=per_pipe, arrays=arrays, chain_ops=chains[2],
        chain_box=chain_box, chain_xf=chain_xf, kernel_waves=kernel_waves, wall_s=wall,
        verified=verified, responses=rsp, order_cost=cost,
        window=window if pol.schedule else 0, datapath="timing" if timing else "rtl",
        unit_costs=UNIT_COSTS[unit_costs is not None])


def _check_replay(r: int, p: int, ta: int, s: Schedule, order: ray_orders.RayOrder,
                  datapath: str) -> tuple:
    """``replay_frame``'s options, each a one-line ValueError when wrong; returns the order's
    policy and its window."""
    if r < 1:
        raise ValueError(f"rays in flight must be >= 1, got {r}")
    if not 1 <= p <= 64:
        raise ValueError(f"pipelines must be in 1..64, got {p}")
    if ta < 0:
        raise ValueError(f"turnaround must be >= 0 cycles, got {ta}")
    if datapath not in REPLAY_DATAPATHS:
        raise ValueError(f"replay datapath {datapath!r}: choose from "
                         f"{', '.join(REPLAY_DATAPATHS)}")
    if r % s.warp_size:
        raise ValueError(f"rays in flight ({r}) must be a multiple of the warp size "
                         f"({s.warp_size}): the RT unit holds whole warps")
    name = order.policy
    pol = ray_orders.policy(name)
    window = ray_orders.check_window(ray_orders.DEFAULT_WINDOW if order.window is None
                                     else order.window)
    if pol.schedule and window < r:
        raise ValueError(f"ray order {name!r}: the window ({window} rays) must hold at "
                         f"least the {r} rays in flight")
    if pol.schedule and window % s.warp_size:
        raise ValueError(f"ray order {name!r}: the window ({window} rays) must be a "
                         f"multiple of the warp size ({s.warp_size})")
    if pol.key is not None and s.frame == "one-kernel":
        raise ValueError(f"ray order {name!r} sorts a wavefront's ray queue; in a "
                         "one-kernel frame every ray is issued by its thread: use it with "
                         "--frame wavefront, or a scheduling order (affinity, treelet)")
    return pol, window


def _culls(costs: UnitCosts | None, chain_off: np.ndarray):
    """The unit costs' culled pops per chain position, or None: (requests + chains,) int64,
    the entries a distance-culled stack pops before each request of each chain and after its
    last (chain r's request k at chain_off[r] + r + k)."""
    if costs is None or costs.culls is None:
        return None
    ev = np.asarray(costs.culls, np.int64).reshape(-1, 3)
    n = len(chain_off) - 1
    out = np.zeros(int(chain_off[-1]) + n, np.int64)
    ray, pos, k = ev.T
    if ((ray < 0) | (ray >= n) | (pos < 0) | (pos > np.diff(chain_off)[ray.clip(0, n - 1)])).any():
        raise ValueError("a stack cull names a request its chain does not have")
    np.add.at(out, chain_off[ray] + ray + pos, k)
    return out


def _any_hit(costs: UnitCosts | None, waves: list[Wave], comb: Combined):
    """The unit costs' any-hit flags per chain (None without unit costs)."""
    if costs is None:
        return None
    if costs.any_hit is not None:
        return costs.any_hit
    return np.repeat([bool(w.any_hit) for w in waves], np.diff(comb.chain_off0))


def _check_costs(costs: UnitCosts | None, scheduled: bool) -> None:
    """A one-line ValueError for unit costs the replay cannot charge."""
    if costs is None:
        return
    if scheduled:
        raise ValueError("the RT unit in RTL's costs need the index ray order (the unit has no "
                         "other scheduler)")
    if (costs.dividers < 1 or costs.div_cycles < 1 or costs.fixed_latency < 0
            or costs.stack_depth < 0 or costs.setups < 1):
        raise ValueError(f"unit costs: {costs.dividers} dividers of {costs.div_cycles} cycles, "
                         f"fixed latency {costs.fixed_latency}, stack depth "
                         f"{costs.stack_depth}, {costs.setups} ray setups: give >= 1, >= 1, "
                         ">= 0, >= 0, >= 1")


def _treelet_schedule(records, treelets) -> ray_orders.TreeletSchedule:
    """The treelet policy's schedule of the frame's records (their requests concatenated)."""
    parts = [ray_orders.treelet_schedule(rec, treelets or ray_orders.DEFAULT_TREELETS)
             for rec in records if rec.ops]
    tl = parts[0]
    if len(parts) > 1:
        tl = replace(tl, request_treelet=np.concatenate([t.request_treelet for t in parts]))
    return tl


def timing_differences(a: FrameReplay, b: FrameReplay) -> list[str]:
    """The names of the counts, times and per-ray arrays in which two replays of the same frame
    differ (empty: the same timing); how the model is run (``datapath``, ``model_evals``) and
    the wall time are not compared."""
    out = [k for k in a.counters if k != "model_evals" and a.counters[k] != b.counters.get(k)]
    if not np.array_equal(a.per_pipe, b.per_pipe):
        out.append("per_pipe")
    out += [k for k in a.arrays if not np.array_equal(a.arrays[k], b.arrays[k])]
    return out


def chain_layout(comb: Combined) -> tuple:
    """(chain_idx, chain_off, requests per chain): chain r's requests, in issue order, are the
    record indices chain_idx[chain_off[r]:chain_off[r + 1]]."""
    n = comb.chains
    chain_idx = np.argsort(comb.chain, kind="stable").astype(np.int64)
    counts = np.bincount(comb.chain.astype(np.int64), minlength=n).astype(np.int64)
    chain_off = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=chain_off[1:])
    return chain_idx, chain_off, counts


def _verify(rsp, counters: dict, comb: Combined, verify: bool) -> bool:
    """Every replayed response's tag is its ray's (``bad_tags``) and, with ``verify`` and
    recorded responses, every response equals the functional run's bit for bit (else
    ``ReplayMismatch``); whether the responses were compared."""
    if counters["bad_tags"]:
        raise ReplayMismatch(f"{counters['bad_tags']} replayed responses carry the wrong ray tag")
    if not verify or comb.responses is None:
        return False
    if np.array_equal(rsp, comb.responses):      # one batch: the same tags too
        return True
    # word 0 is the tag: the frame's ray-table row, checked by the replay (bad_tags)
    diff = np.flatnonzero((rsp[:, 1:] != comb.responses[:, 1:]).any(axis=1))
    if len(diff):
        raise ReplayMismatch(f"{len(diff)} of {len(rsp)} replayed responses differ from the "
                             f"functional run's (first: request {int(diff[0])})")
    return True


def waves_of(batches) -> list[Wave]:
    """The ``Wave``s of a workload frame's traced batches (``driver.workloads.Batch``, each
    with its recorded ``result.record``), in trace order."""
    return [Wave(b.result.record, b.kind, b.thread, b.slot, b.any_hit) for b in batches]


def replay_point(waves: list[Wave], point, width: int | None = None,
                 ideal: bool = False) -> dict:
    """A frame's RT-unit objects on design point ``point`` (``driver.design.DesignPoint``):
    ``rtunit_memory``, the replay of the point's RT units and memory hierarchy, and with
    ``ideal`` also ``rtunit``, the same replay with every node fetch free (a second replay: off
    by default); ``by_type``: each ray type's objects. The records replay on the point's datapath
    configuration and latency: as the pipelines' timing (``point.replay_datapath``, by default
    "timing") when the functional run was on that configuration, else evaluated on its model
    with every response checked against the recorded one bit for bit."""
    kinds = list(dict.fromkeys(w.kind for w in waves))
    params = point.rtl_params()
    same = all(w.record.params == params for w in waves)
    waves = [w if w.record.params == params else replace(w, record=replace(w.record,
                                                                             params=params))
             for w in waves]
    # the timing replay takes the functional run's responses: only when that run was on this
    # configuration's datapath (a sweep traces once and replays every configuration on its RTL)
    order = point.order_options()
    args = dict(schedule=point.schedule(), width=width,
                order=ray_orders.RayOrder(order["ray_order"], order["ray_window"]),
                datapath=point.replay_datapath if same else "rtl",
                unit_costs=UnitCosts() if point.unit_costs == "rtl" else None)
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
