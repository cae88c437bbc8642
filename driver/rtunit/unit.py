"""RT-unit model around the RayFlex datapath: rays in flight and parallel pipelines.

Question it answers: how many cycles does a frame take on an RT unit that holds R rays in flight
(a ray pool, like the warp slots of a GPU RT unit) and feeds P copies of the datapath pipeline,
and where does latency stop being hidden?

Design: functional traversal first, timing by replay.

1. ``driver.tracer.trace`` runs the wavefront closest-hit traversal (all rays in flight, one
   ``backend.run()`` per step) and, when asked, records every datapath request as (ray index,
   node pointer, extent) in issue order, plus the response words (``Record``). A ray's requests
   depend only on that ray's own earlier responses (its stack and its nearest t), never on other
   rays, so each ray's *request chain* is fixed by the scene and the ray, whatever the schedule:
   replaying the chains in any interleaving issues exactly the same requests. (Steps are
   synchronous in the wavefront, but per ray the order is the chain order.)
2. ``replay`` issues the recorded chains through the real RTL in the C++ harness
   (``rf_replay`` in sim/rtunit_scheduler.cpp) under an RT-unit scheduler: P fresh Verilated model
   instances clocked together, a pool of R ray slots filled in ray (pixel) order; every cycle each
   pipeline accepts at most one request, from the oldest ready ray (a FIFO by ready time); a ray
   has at most one request in flight and becomes ready again ``turnaround`` cycles after its
   response is taken (default 1: the host needs a cycle to turn a response into the ray's next
   request, so there is no combinational path from rsp_o to req_i, as in the pipeline itself;
   larger values model a node-fetch latency); a ray whose chain is done leaves the pool and the
   next ray enters. The request words are assembled in C++ from the packed rays and the BVH4 image,
   by the same code as the "rtl" fast path (``HarnessBackend.run_nodes``; sim/rf_sim.h).
3. Cycles are real model clock cycles from the first accepted request to the last response taken
   (inclusive), as every cycle count of docs/statistics.md. ``utilization = ops / (pipelines *
   cycles)`` (ops per cycle of one pipeline when there is one). The replayed responses are compared with the functional run's
   bit for bit (and every response tag with its ray): same requests, so they must be equal;
   a difference raises ``ReplayMismatch``.

Why replay rather than scheduling inside the traversal: the functional run stays the vectorised
wavefront (one C++ call per step, fast and already tested), the schedule costs no Python per
request or per cycle, and the timing comes from the RTL's own handshakes rather than from a
latency formula. With R = 1 and P = 1 every request waits for the previous one: a ray's requests
are 11 + ``turnaround`` cycles apart, so cycles = ops * 12 with the defaults (>= ops * 11).

``replay`` times one recorded batch on one RT unit with a per-ray pool (the wavefront schedule
of ``driver.rtunit.gpu`` with one ray per warp): what the studies and the Python API call. A
whole frame as a GPU issues it, warps of threads over many RT units in front of an L1, an L2 and
DRAM (``MemoryModel``), is ``driver.rtunit.gpu.replay_frame`` (docs/rtunit.md); both run the
same engine.

Simulation shortcut (exact): a pipeline that holds no request at the start of a cycle and gets
none is not evaluated in that cycle (``skip_idle``): the datapath's registers load only on a
handshake (rf_skid.sv; accumulators only on an accepted beat), so a clock edge with nothing valid
changes no state. Cycles still count; ``skip_idle=False`` clocks every model every cycle and gives
identical responses and cycles (tests check).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from ..core.words import wrap
from ..tracing.record import Record
from .gpu import DEFAULT_REPLAY_DATAPATH, ReplayMismatch, UnitCosts, replay_frame
from .plan import PER_RAY_POOL, Wave
from .order import RayOrder

DEFAULT_RAYS_IN_FLIGHT = 64        # the default ray pool (see the module docstring)
DEFAULT_TURNAROUND = 1
SWEEP_RAYS_IN_FLIGHT = (1, 2, 4, 8, 16, 32, 64, 128, 256, 1024)
SWEEP_PIPELINES = (1, 2, 4, 8)




@dataclass(frozen=True)
class MemoryModel:
    """The memory hierarchy of the replay (sim/rf_memory.h, docs/rtunit.md): per RT unit a
    set-associative LRU node cache (L1) of ``cache_bytes`` with ``ways`` ways and ``line_bytes``
    lines, hit after ``hit_latency`` cycles, with ``mshrs`` miss registers (0: unlimited; misses
    to a transaction already in flight merge); an L2 of ``l2_bytes`` (0: none) shared by all
    units, ``l2_ways`` ways, hit after ``l2_latency`` cycles; DRAM shared by all units, a
    transaction arriving ``latency_cycles`` after its transfer, transfers serialised at
    ``bytes_per_cycle``. Bytes move in ``sector_bytes`` sectors of a line (0: whole lines).
    ``cache_bytes`` 0: no L1, every node fetch goes to the next level. A request waits until its
    node's bytes are present (``driver.core.layout.NODE_BYTES``: box32 box node 128 B; q8 box node,
    triangle node and pair leaf 64 B; a pair's second triangle none more); the memory changes
    timing only, never a response."""

    cache_bytes: int = 32 * 1024
    ways: int = 4
    line_bytes: int = 64
    latency_cycles: int = 200
    bytes_per_cycle: float = 32.0
    hit_latency: int = 0
    sector_bytes: int = 0
    mshrs: int = 0
    l2_bytes: int = 0
    l2_ways: int = 16
    l2_latency: int = 0

    def __post_init__(self):
        for name in ("cache_bytes", "ways", "line_bytes", "latency_cycles", "hit_latency",
                     "sector_bytes", "mshrs", "l2_bytes", "l2_ways", "l2_latency"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"memory model: {name} must be a non-negative integer, got {v!r}")
        lb, sb = self.line_bytes, self.sector_bytes
        if self.ways < 1 or lb < 4 or lb & (lb - 1):
            raise ValueError("memory model: ways >= 1, line_bytes a power of two")
        if sb and (sb < 4 or sb & (sb - 1) or sb > lb):
            raise ValueError(f"memory model: sector_bytes {sb} must be a power of two >= 4 "
                             f"and at most line_bytes ({lb}), or 0 (whole lines)")
        for what, size, ways in (("cache_bytes", self.cache_bytes, self.ways),
                                 ("l2_bytes", self.l2_bytes, self.l2_ways)):
            if ways < 1 or size % (ways * lb):
                raise ValueError(f"memory model: {what} {size} is not a multiple of "
                                 f"ways x line_bytes ({ways * lb})")
        if not float(self.bytes_per_cycle) > 0:
            raise ValueError("memory model: bytes_per_cycle must be > 0")

    @property
    def transaction_bytes(self) -> int:
        """Bytes of one transfer: a sector, or a whole line."""
        return int(self.sector_bytes or self.line_bytes)

    def config(self) -> dict:
        """The ``driver.core.layout.MEMORY_CONFIG`` values of ``rf_replay``."""
        return {"l1_bytes": int(self.cache_bytes), "l1_ways": int(self.ways),
                "line_bytes": int(self.line_bytes), "sector_bytes": int(self.sector_bytes),
                "l1_latency": int(self.hit_latency), "mshrs": int(self.mshrs),
                "l2_bytes": int(self.l2_bytes), "l2_ways": int(self.l2_ways),
                "l2_latency": int(self.l2_latency), "mem_latency": int(self.latency_cycles),
                "bytes_per_cycle": float(self.bytes_per_cycle)}

    def describe(self) -> dict:
        return {"cache_bytes": self.cache_bytes, "ways": self.ways, "line_bytes": self.line_bytes,
                "latency_cycles": self.latency_cycles, "bytes_per_cycle": self.bytes_per_cycle,
                "hit_latency": self.hit_latency, "sector_bytes": self.sector_bytes,
                "mshrs": self.mshrs, "l2_bytes": self.l2_bytes, "l2_ways": self.l2_ways,
                "l2_latency": self.l2_latency}


@dataclass
class ReplayResult:
    """One RT-unit replay. cycles: first accept to last response, inclusive; responses:
    (m, RSP_WORDS) uint32 at the record index; per_pipeline: requests accepted by each pipeline;
    starved_cycles: cycles in which a pipeline got no request because no ray was ready;
    model_evals: pipeline-cycles actually evaluated; wall_s: the C++ call; verified: whether every
    response was compared with the functional run's (None: the timing replay evaluates none)."""

    rays_in_flight: int
    pipelines: int
    turnaround: int
    rays: int
    ops: int
    box_ops: int
    cycles: int
    starved_cycles: int
    full_cycles: int
    model_evals: int
    per_pipeline: list
    wall_s: float
    verified: bool | None
    latency: int
    responses: np.ndarray
    memory: dict | None = None      # the memory model's parameters and counters, when on
    order: dict | None = None       # the ray-order policy and its cost (driver.rtunit.order)
    transform_ops: int = 0          # TRANSFORM requests among ``ops``
    datapath: str = "rtl"           # how the pipelines ran (``gpu.REPLAY_DATAPATHS``)

    @property
    def utilization(self) -> float:
        return self.ops / (self.pipelines * self.cycles) if self.cycles else 0.0

    def stats(self) -> dict:
        """Plain-Python summary (docs/statistics.md names where they apply)."""
        return {
            "rays_in_flight": self.rays_in_flight,
            "pipelines": self.pipelines,
            "turnaround_cycles": self.turnaround,
            "rays": self.rays,
            "ops": self.ops,
            "box_ops": self.box_ops,
            "tri_ops": self.ops - self.box_ops - self.transform_ops,
            "transform_ops": self.transform_ops,
            "cycles": self.cycles,
            "utilization": self.utilization,
            "frame_us_at_1ghz": self.cycles / 1000,
            "latency_cycles": self.latency,
            "starved_cycles": self.starved_cycles,
            "per_pipeline_ops": list(self.per_pipeline),
            "model_evals": self.model_evals,
            "sim_wall_s": self.wall_s,
            "sim_cycles_per_s": self.cycles / self.wall_s if self.wall_s > 0 else 0.0,
            "replay_datapath": self.datapath,
            "responses_verified": self.verified,
            **({"memory": self.memory} if self.memory else {}),
            **({"order": self.order} if self.order else {}),
        }


def replay(record: Record, rays_in_flight: int = DEFAULT_RAYS_IN_FLIGHT, pipelines: int = 1,
           turnaround: int = DEFAULT_TURNAROUND, skip_idle: bool = True,
           verify: bool = True, memory: MemoryModel | None = None,
           ray_order: str = "index", ray_window: int | None = None,
           treelets=None, datapath: str = DEFAULT_REPLAY_DATAPATH,
           unit_costs: UnitCosts | None = None) -> ReplayResult:
    """Replay a traversal ``Record`` through P Verilated pipelines with R rays in flight (see the
    module docstring). ``verify``: compare every response with the functional run's (raises
    ``ReplayMismatch``); without recorded responses only the tags are checked. ``memory``: a
    ``MemoryModel`` of node fetches (None: every fetch is free). ``ray_order``: the order
    policy of ``driver.rtunit.order`` (``POLICIES``; "index": rays enter in index order) with a
    window of ``ray_window`` rays (default ``order.DEFAULT_WINDOW``; for a scheduling policy at
    least R); the result's ``order`` holds the policy and its cost. ``treelets``: the
    ``order.TreeletConfig`` of the "treelet" policy (default ``order.DEFAULT_TREELETS``).
    ``datapath``: "timing" (the pipelines' handshake timing, the functional run's responses) or
    "rtl" (every request evaluated again and checked; ``gpu.REPLAY_DATAPATHS``).
    ``unit_costs``: a ``UnitCosts``, the RT unit in RTL's costs charged instead of
    ``turnaround`` (docs/rtunit_rtl.md#the-replay-against-the-unit; cycles then run from the
    first ray taken to the last result taken)."""
    fr = replay_frame([Wave(record)], rays_in_flight, pipelines, memory, PER_RAY_POOL,
                      order=RayOrder(ray_order, ray_window, treelets), turnaround=turnaround, skip_idle=skip_idle, verify=verify,
                      datapath=datapath, unit_costs=unit_costs)
    c = fr.counters
    mem = None
    if memory:
        acc = c["line_accesses"]
        mem = {**memory.describe(), **{k: c[k] for k in (
            "line_accesses", "line_hits", "line_misses", "bytes_from_memory",
            "node_wait_cycles")},
            "hit_rate": c["line_hits"] / acc if acc else 0.0,
            "bytes_per_ray": c["bytes_from_memory"] / record.rays if record.rays else 0.0,
            **fr.memory_levels()}
    return ReplayResult(fr.rays_in_flight, fr.pipelines, fr.turnaround, record.rays,
                        len(fr.responses), record.box_ops, c["cycles"], c["starved_cycles"],
                        c["full_cycles"], c["model_evals"], fr.per_pipe[0].tolist(), fr.wall_s,
                        fr.verified, fr.latency, fr.responses, mem, fr.order_cost,
                        record.transform_ops, fr.datapath)


def sweep(record: Record, rays_in_flight=SWEEP_RAYS_IN_FLIGHT, pipelines=SWEEP_PIPELINES,
          turnaround: int = DEFAULT_TURNAROUND, progress=None, workers: int = 1) -> list[dict]:
    """Replay ``record`` for every (pipelines, rays_in_flight) pair; returns one ``stats()``
    dict per point, in (pipelines, rays_in_flight) order (responses verified at every point).
    progress: optional callable(done, total, point_dict). workers: replays run concurrently in
    this many threads (the C++ replay releases the GIL; every replay has its own models)."""
    pairs = [(p, r) for p in pipelines for r in rays_in_flight]

    def one(pair):
        return replay(record, pair[1], pair[0], turnaround).stats()

    points = [None] * len(pairs)
    if int(workers) <= 1:
        for k, pair in enumerate(pairs):
            points[k] = one(pair)
            if progress is not None:
                progress(k + 1, len(pairs), points[k])
        return points
    with ThreadPoolExecutor(max_workers=int(workers)) as pool:
        # the slowest points (few rays in flight) first, so the pool ends evenly
        order = sorted(range(len(pairs)), key=lambda k: pairs[k][1])
        futures = {pool.submit(one, pairs[k]): k for k in order}
        for done, fut in enumerate(as_completed(futures), 1):
            points[futures[fut]] = fut.result()
            if progress is not None:
                progress(done, len(pairs), points[futures[fut]])
    return points


def plot_sweep(points: list[dict], path, title: str = "") -> None:
    """PNG: cycles per frame vs rays in flight (log x), one line per pipeline count, with the
    throughput bound ops / P and the latency bound ops * (latency + turnaround) / R dotted."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 5.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    pipes = sorted({pt["pipelines"] for pt in points})
    ops = max(pt["ops"] for pt in points) if points else 0
    rs = sorted({pt["rays_in_flight"] for pt in points})
    markers = ("o", "s", "^", "D", "v", "P")
    for i, p in enumerate(pipes):        # the curves coincide on the latency bound at small R:
        pts = sorted((pt for pt in points if pt["pipelines"] == p),    # markers tell them apart
                     key=lambda pt: pt["rays_in_flight"])
        c = f"C{i}"
        ax.plot([pt["rays_in_flight"] for pt in pts], [pt["cycles"] for pt in pts],
                marker=markers[i % len(markers)], ms=9 - 1.5 * i, color=c,
                mfc="none" if i % 2 else c, label=f"{p} pipeline{'s' if p > 1 else ''}")
        ax.axhline(ops / p, color=c, ls=":", lw=1)
    if points and rs:
        per_req = points[0]["latency_cycles"] + points[0]["turnaround_cycles"]
        x = np.array(rs, float)
        ax.plot(x, ops * per_req / x, "k--", lw=1,
                label=f"latency bound ops\u00b7{per_req}/R")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    if rs:
        ax.set_xticks(rs)
        ax.set_xticklabels([str(r) for r in rs])
        ax.minorticks_off()
    ax.set_xlabel("rays in flight (ray pool size R)")
    ax.set_ylabel("cycles per frame (= ns at 1 GHz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(title="dotted: throughput\nbound ops / P", fontsize=8, loc="upper left",
              bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)      # beside the data
    ax.set_title(wrap(title or "RT-unit sweep", 100), fontsize=9)
    fig.tight_layout()
    fig.savefig(str(path), format="png")
