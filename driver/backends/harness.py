"""The "rtl" backend: the Verilated RayFlex datapath behind a C++ harness, one call per batch.

``HarnessBackend.run`` streams ready-made request words (sim/rayflex_harness.cpp);
``HarnessBackend.run_nodes`` is the traversal fast path: the harness assembles QUADBOX/TRIANGLE
requests from a packed ray table (``driver.core.wire.ray_words``) and the BVH4 image, so the host
sends three numbers per request instead of 320 bytes. ``replay_schedule`` runs the RT-unit replay
(sim/rtunit_scheduler.cpp) for ``driver.rtunit``. ``harness_library(params)`` builds (cached; see
``driver.backends.build``) and loads the library once per process.
"""

from __future__ import annotations

import ctypes
import os

import numpy as np

from ..core.layout import (MEMORY_CONFIG, MEMORY_LEVELS, NO_CHILD, REPLAY_CONFIG, REPLAY_INPUTS,
                           REPLAY_OUTPUTS, REPLAY_STATS)
from ..core.wire import RAY_WORDS, REQ_WORDS, RSP_WORDS, pack_requests, unpack_responses
from .build import build_harness
from .rtlbase import PATTERN_LEN, RtlBackendBase

_U8P = ctypes.POINTER(ctypes.c_uint8)
_U32P = ctypes.POINTER(ctypes.c_uint32)
_I32P = ctypes.POINTER(ctypes.c_int32)
_I64P = ctypes.POINTER(ctypes.c_int64)
_LIBS: dict = {}
BAD_NODE = -2             # return code of the harness calls: a pointer that names no node
# A traversal step is split over several models (one thread each) only when each gets at least
# this many requests: starting a thread costs about as much as streaming 20 requests.
SPLIT_MIN_REQUESTS = 256
THREADS_ENV = "RAYFLEX_THREADS"


def default_threads() -> int:
    """Models (threads) the "rtl" backend streams a big traversal step through: ``RAYFLEX_THREADS``,
    else the CPUs this process may run on."""
    text = os.environ.get(THREADS_ENV, "").strip()
    if not text:
        return max(1, len(os.sched_getaffinity(0)))
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"{THREADS_ENV}={text!r}: give a positive number of threads")
    return int(text)


class ReplayStats(ctypes.Structure):
    """rf_layout::ReplayStats (fields: ``driver.core.layout.REPLAY_STATS``)."""

    _fields_ = [(name, ctypes.c_int64) for name in REPLAY_STATS]

    def as_dict(self) -> dict:
        return {name: int(getattr(self, name)) for name in REPLAY_STATS}


class ReplayConfig(ctypes.Structure):
    """rf_layout::ReplayConfig (fields: ``driver.core.layout.REPLAY_CONFIG``)."""

    _fields_ = [(name, ctypes.c_int64) for name in REPLAY_CONFIG]


def _ctype(c: str):
    return ctypes.c_int64 if c == "int64_t" else ctypes.c_void_p


class ReplayInputs(ctypes.Structure):
    """rf_layout::ReplayInputs (fields: ``driver.core.layout.REPLAY_INPUTS``; a pointer field
    is a numpy array's data address, or None)."""

    _fields_ = [(name, _ctype(c)) for name, c in REPLAY_INPUTS]


class ReplayOutputs(ctypes.Structure):
    """rf_layout::ReplayOutputs (fields: ``driver.core.layout.REPLAY_OUTPUTS``)."""

    _fields_ = [(name, _ctype(c)) for name, c in REPLAY_OUTPUTS]


def _data(a):
    return None if a is None else a.ctypes.data


class MemoryConfig(ctypes.Structure):
    """rf_layout::MemoryConfig (fields: ``driver.core.layout.MEMORY_CONFIG``)."""

    _fields_ = [(name, ctypes.c_double if ctype == "double" else ctypes.c_int64)
                for name, ctype in MEMORY_CONFIG]


def _u32p(a: np.ndarray):
    return a.ctypes.data_as(_U32P)


def _i64p(a: np.ndarray):
    return a.ctypes.data_as(_I64P)


def harness_library(params: dict[str, int]) -> ctypes.CDLL:
    """The harness over the Verilated model with these parameters, built on first use and loaded
    once per process."""
    lib = _LIBS.get(tuple(sorted(params.items())))
    if lib is None:
        lib = use_library(params, build_harness(params))
    return lib


def use_library(params: dict[str, int], path) -> ctypes.CDLL:
    """Load the harness library at ``path`` and make it this process's library for ``params``
    (``harness_library``, the "rtl" backend and the RT-unit replay then use it). The build's
    profile-guided-optimisation training (``driver.pgo``) runs the instrumented library this way."""
    lib = ctypes.CDLL(str(path))
    i64, vp = ctypes.c_int64, ctypes.c_void_p
    lib.rf_new.restype = vp
    lib.rf_free.argtypes = [vp]
    lib.rf_run.restype = i64
    lib.rf_run.argtypes = [vp, _U32P, _U32P, i64, _U8P, i64, _U8P, i64, i64]
    lib.rf_run_nodes.restype = i64
    lib.rf_run_nodes.argtypes = [vp, _U32P, _U32P, i64, _U32P, _U32P, _U32P, _U32P, i64,
                                 _U8P, i64, _U8P, i64, i64]
    lib.rf_build_requests.restype = i64
    lib.rf_build_requests.argtypes = [_U32P, _U32P, i64, _U32P, _U32P, _U32P, _U32P, i64]
    lib.rf_run_nodes_split.restype = i64
    lib.rf_run_nodes_split.argtypes = [ctypes.POINTER(vp), i64, _U32P, _U32P, i64, _U32P, _U32P,
                                       _U32P, _U32P, i64, i64, _I64P]
    lib.rf_latency.restype = i64
    lib.rf_latency.argtypes = []
    lib.rf_replay.restype = i64
    lib.rf_replay.argtypes = [ctypes.POINTER(ReplayConfig), ctypes.POINTER(MemoryConfig),
                              ctypes.POINTER(ReplayInputs), ctypes.POINTER(ReplayStats),
                              ctypes.POINTER(ReplayOutputs)]
    lib.rf_memory_trace.restype = i64
    lib.rf_memory_trace.argtypes = [ctypes.POINTER(MemoryConfig), i64, i64, _I64P, _I64P, _I64P,
                                    _I64P, i64, _I64P, _I64P, _I64P]
    _LIBS[tuple(sorted(params.items()))] = lib
    return lib


def node_arrays(ray_words, image_words, ray, ptr, extent):
    """Checked contiguous arrays (ray table, image words, ray, ptr, extent bits: uint32) for the
    harness calls that assemble traversal requests."""
    rw = np.ascontiguousarray(ray_words, np.uint32)
    if rw.ndim != 2 or rw.shape[1] != RAY_WORDS:
        raise ValueError(f"ray words must be (n, {RAY_WORDS}) uint32")
    img = np.ascontiguousarray(image_words).reshape(-1).view(np.uint32)
    r = np.ascontiguousarray(ray, np.uint32).reshape(-1)
    p = np.ascontiguousarray(ptr, np.uint32).reshape(-1)
    e = np.ascontiguousarray(extent, np.float32).reshape(-1).view(np.uint32)
    if not len(r) == len(p) == len(e):
        raise ValueError("ray, ptr and extent must have the same length")
    if len(r) and int(r.max()) >= len(rw):
        raise ValueError("a ray index is out of range of the ray table")
    return rw, img, r, p, e


def _bad_node() -> ValueError:
    return ValueError("a traversal request names a node pointer outside the BVH image")


def build_requests(params: dict[str, int], ray_words, image_words, ray, ptr, extent) -> np.ndarray:
    """The (n, REQ_WORDS) request words ``run_nodes``/``replay_schedule`` assemble for these
    triples."""
    lib = harness_library(params)
    rw, img, r, p, e = node_arrays(ray_words, image_words, ray, ptr, extent)
    out = np.zeros((len(r), REQ_WORDS), np.uint32)
    if lib.rf_build_requests(_u32p(rw), _u32p(img), img.size, _u32p(r), _u32p(p), _u32p(e),
                             _u32p(out), len(r)) == BAD_NODE:
        raise _bad_node()
    return out


BAD_GEOMETRY = -4
SCHED_STATS = ("parked", "resumed", "max_parked", "max_held", "picks", "max_queued",
               "borrowed")
SERIES_CAPACITY = 1024               # bins of the rays-in-flight series (rf_replay halves them)


def memory_config(memory: dict | None) -> MemoryConfig:
    """The ``MemoryConfig`` of a memory hierarchy given as a dict of ``MEMORY_CONFIG`` names
    (``driver.rtunit.MemoryModel.config()``); None: no memory model (every fetch free)."""
    mc = MemoryConfig()
    if memory is None:
        mc.l1_bytes, mc.l1_ways, mc.line_bytes, mc.bytes_per_cycle = -1, 1, 64, 1.0
        return mc
    for name, _ in MEMORY_CONFIG:
        setattr(mc, name, memory[name])
    return mc


def _check_chains(r, co, chain, before):
    ch = r if chain is None else np.ascontiguousarray(chain, np.uint32).reshape(-1)
    bf = (np.full(len(r), NO_CHILD, np.uint32) if before is None
          else np.ascontiguousarray(before, np.uint32).reshape(-1))
    if len(ch) != len(r) or len(bf) != len(r) or (len(r) and int(ch.max()) >= len(co) - 1):
        raise ValueError("chain and before need one entry per request, chains within chain_off")
    return ch, bf


def model_latency(params: dict[str, int]) -> int:
    """The cycles from a request's input handshake to its response on the Verilated model with
    these parameters (``rf_latency``: measured on a fresh model, once per process)."""
    key = tuple(sorted(params.items()))
    if key not in _LATENCY:
        d = int(harness_library(params).rf_latency())
        if d < 1:
            raise RuntimeError(f"the RTL model {params} returned no response to a request")
        _LATENCY[key] = d
    return _LATENCY[key]


_LATENCY: dict = {}


def replay_schedule(params: dict[str, int], config: dict, memory: dict | None, frame, chains,
                    plan, treelets=None, any_hit=None, culls=None):
    """Run the RT-unit replay (sim/rtunit_scheduler.cpp, ``rf_replay``) of recorded request
    chains issued by warps of trace calls. ``config``: the ``REPLAY_CONFIG`` values
    (``series_capacity`` is filled in); ``memory``: the ``MEMORY_CONFIG`` values, or None (every
    node fetch free). ``frame``: the requests (``ray_words``, ``image``, ``ray``, ``ptr``,
    ``extent``, ``chain``, ``before`` as in ``driver.tracing.record.Record``; ``driver.rtunit.plan.
    Combined``); ``chains``: (chain_idx, chain_off) of its chains; ``plan``: kernels, warps and
    calls (``kernel_off`` over warps, ``warp_call_off`` over calls, ``call_ray_off`` /
    ``call_rays``: chain indices). ``treelets``: a ``driver.rtunit.order.TreeletSchedule`` (needs
    a window). Returns (responses (m, RSP_WORDS) uint32 at the record index (none, (0,
    RSP_WORDS), when ``config["timing_latency"]`` makes the pipelines their timing),
    ``ReplayStats`` dict plus ``SCHED_STATS``, requests per pipeline (units, P) int64, per-ray
    and per-call arrays: ``ray_times`` (n, 3), ``ray_served`` (n, one column per
    ``MEMORY_LEVELS``), ``ray_wait`` (n,), ``call_times`` (calls, 3), ``call_unit`` (calls,),
    ``series``, ``kernel_times`` (kernels, 3)). ``config["unit_costs"]``: the RT unit in RTL's
    costs (``driver.rtunit.UnitCosts``; timing pipelines read ``frame.responses``), any_hit:
    (chains,) bool or None; culls: the culled pops (``driver.rtunit.gpu._culls``) or None."""
    lib = harness_library(params)
    rw, img, r, p, e = node_arrays(frame.ray_words, frame.image, frame.ray, frame.ptr,
                                   frame.extent)
    ci, co = (np.ascontiguousarray(a, np.int64) for a in chains)
    ch, bf = _check_chains(r, co, frame.chain, frame.before)
    ko, wo, cro, crs = (np.ascontiguousarray(a, np.int64) for a in
                        (plan.kernel_off, plan.warp_call_off, plan.call_ray_off,
                         plan.call_rays))
    cfg = ReplayConfig(**{k: int(v) for k, v in {**config,
                                                 "series_capacity": SERIES_CAPACITY}.items()})
    ids, n_tl, pre = None, 0, (None,) * 3
    if treelets is not None:
        if not cfg.window:
            raise ValueError("treelet scheduling needs a window")
        ids = np.ascontiguousarray(treelets.request_treelet, np.int32)
        if ids.shape != (len(r),):
            raise ValueError("treelet scheduling needs one treelet per request")
        n_tl = int(treelets.n_treelets)
        cfg.active_treelets = int(treelets.active)
        cfg.treelet_flags = int(treelets.park) | 2 * int(treelets.borrow)
        pre = treelets.prefetch_lists()
    n_chains, n_calls = len(co) - 1, len(cro) - 1
    # the timing replay (timing_latency > 0) writes no responses
    rsp = np.zeros((0 if cfg.timing_latency else len(r), RSP_WORDS), np.uint32)
    known, ah, cu = _unit_cost_inputs(cfg, frame.responses, len(r), n_chains, any_hit, culls)
    stats = ReplayStats()
    per_pipe = np.zeros((cfg.units, cfg.pipelines), np.int64)
    sched = np.zeros(len(SCHED_STATS), np.int64)
    out = {"ray_times": np.zeros((n_chains, 3), np.int64),
           "ray_served": np.zeros((n_chains, len(MEMORY_LEVELS)), np.int64),
           "ray_wait": np.zeros(n_chains, np.int64),
           "call_times": np.zeros((max(n_calls, 0), 3), np.int64),
           "call_unit": np.zeros(max(n_calls, 0), np.int64),
           "series": np.zeros(SERIES_CAPACITY, np.int64),
           "kernel_times": np.zeros((len(ko) - 1, 3), np.int64)}
    mc = memory_config(memory)
    inputs = ReplayInputs(
        rays=_data(rw), n_rays=len(rw), image=_data(img), image_words=img.size, ray=_data(r),
        ptr=_data(p), ext=_data(e), m=len(r), chain_idx=_data(ci), chain_off=_data(co),
        n_chains=n_chains, chain=_data(ch), before=_data(bf), n_kernels=len(ko) - 1,
        kernel_off=_data(ko), warp_call_off=_data(wo), call_ray_off=_data(cro),
        call_rays=_data(crs), treelet=_data(ids), n_treelets=n_tl,
        **dict(zip(("tl_off", "tl_node_off", "tl_node_bytes"), map(_data, pre))),
        responses=_data(known), any_hit=_data(ah), culls=_data(cu))
    outputs = ReplayOutputs(rsp=_data(rsp), per_pipe=_data(per_pipe), sched=_data(sched),
                            **{k: _data(v) for k, v in out.items()})
    rc = lib.rf_replay(ctypes.byref(cfg), ctypes.byref(mc), ctypes.byref(inputs),
                       ctypes.byref(stats), ctypes.byref(outputs))
    if rc == BAD_GEOMETRY:
        raise ValueError("memory geometry cannot be modelled: each cache a multiple of ways x "
                         "line size, the line a power of two >= 4 bytes, sectors a power of two "
                         "dividing the line")
    if rc == BAD_NODE:
        raise ValueError("a recorded request names a node pointer outside the BVH image")
    if rc == -3:
        raise ValueError("RT-unit replay: inconsistent arguments (warps, calls and chains must "
                         "cover every request once; slots a multiple of the warp size)")
    if rc < 0:
        raise RuntimeError(f"RT-unit replay failed ({'deadlock' if rc == -1 else rc})")
    st = {**stats.as_dict(), **dict(zip(SCHED_STATS, sched.tolist()))}
    out["series"] = out["series"][:st["series_bins"]]
    return rsp, st, per_pipe, out


def _unit_cost_inputs(cfg, responses, m: int, n_chains: int, any_hit, culls) -> tuple:
    """``rf_replay``'s inputs for the RT unit's costs: the functional run's responses (the
    timing pipelines' response stage reads them; else None), the any-hit flag per chain (or
    None) and the culled pops per chain position (or None)."""
    known = ah = cu = None
    if culls is not None:
        cu = np.ascontiguousarray(culls, np.int64)
        if cu.shape != (m + n_chains,):
            raise ValueError("the stack's culls need one count per request and one per chain")
    if cfg.unit_costs and cfg.timing_latency:
        known = np.ascontiguousarray(responses, np.uint32)
        if known.shape != (m, RSP_WORDS):
            raise ValueError("the unit's costs need one recorded response per request")
    if any_hit is not None:
        ah = np.ascontiguousarray(np.broadcast_to(np.asarray(any_hit, bool), (n_chains,)),
                                  np.uint8)
    return known, ah, cu


MEMORY_TRACE_COUNTS = ("l1_accesses", "l1_hits", "l1_merged", "l1_misses", "l1_bytes",
                       "l2_accesses", "l2_hits", "l2_merged", "l2_misses", "l2_bytes",
                       "dram_transfers", "dram_bytes", "mshr_stalls", "mshr_stall_cycles")


class HarnessBackend(RtlBackendBase):
    """The fast path: one C++ call streams a batch through the Verilated model.

    ``run(requests)`` takes a ``REQUEST_DTYPE`` array; ``run_nodes(...)`` takes traversal requests
    as (ray, node pointer, extent) triples and lets the harness assemble the request words from the
    packed rays and the BVH4 image (no per-request Python work; see ``driver.traversal``).

    ``threads`` (default ``default_threads()``): a ``run_nodes`` batch of at least
    ``SPLIT_MIN_REQUESTS`` requests per thread and no gap or stall pattern is split into that
    many consecutive parts, each streamed through a model of its own in its own thread. The
    responses are the same (each depends only on its request); the cycles are those of one
    pipeline streaming the whole batch back to back: the parts' cycles, each N_j + latency, less
    the latency once per extra part (tests compare both ways)."""

    name = "rtl"

    def __init__(self, threads: int | None = None, **options):
        super().__init__(**options)
        self.threads = default_threads() if threads is None else int(threads)
        if self.threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads!r}")
        self._lib = harness_library(self.params)
        self._sim = self._lib.rf_new()
        self._more: list = []               # the extra models of a split batch

    def __del__(self):
        sims = [getattr(self, "_sim", None)] + list(getattr(self, "_more", []))
        self._sim, self._more = None, []
        for sim in sims:
            if sim:
                self._lib.rf_free(sim)

    def _patterns(self):
        gap = self.gap.ctypes.data_as(_U8P) if self.gap is not None else None
        stall = self.stall.ctypes.data_as(_U8P) if self.stall is not None else None
        return gap, PATTERN_LEN, stall, PATTERN_LEN, self._max_idle()

    def _account(self, cycles: int, n: int) -> None:
        if cycles == BAD_NODE:
            raise _bad_node()
        if cycles < 0:
            raise RuntimeError("RTL pipeline deadlocked: no handshake for too many cycles")
        self.cycles += int(cycles)
        self.requests += n

    def run(self, req: np.ndarray) -> np.ndarray:
        self._check(req)
        words = pack_requests(req)
        out = np.zeros((len(req), RSP_WORDS), np.uint32)
        cycles = self._lib.rf_run(self._sim, _u32p(words), _u32p(out), len(req),
                                  *self._patterns())
        self._account(cycles, len(req))
        return unpack_responses(out)

    def run_nodes(self, ray_words: np.ndarray, image_words: np.ndarray, ray: np.ndarray,
                  ptr: np.ndarray, extent: np.ndarray) -> np.ndarray:
        """Stream traversal requests: request i is ray ``ray[i]`` (a row of ``ray_words``, see
        ``driver.core.wire.ray_words``; tag = the ray index) against the node at pointer ``ptr[i]``
        of the BVH4 image ``image_words`` (QUADBOX for a box node, TRIANGLE for a triangle node),
        with extent ``extent[i]``. Returns the (n, RSP_WORDS) uint32 response words, in request
        order. Bit-identical to ``run()`` on the same requests built in Python (tests check)."""
        rw, img, r, p, e = node_arrays(ray_words, image_words, ray, ptr, extent)
        n = len(r)
        out = np.empty((n, RSP_WORDS), np.uint32)
        parts = min(self.threads, n // SPLIT_MIN_REQUESTS)
        if parts > 1 and self.gap is None and self.stall is None:
            while len(self._more) < parts - 1:
                self._more.append(self._lib.rf_new())
            sims = (ctypes.c_void_p * parts)(self._sim, *self._more[:parts - 1])
            part_cycles = np.zeros(parts, np.int64)
            rc = self._lib.rf_run_nodes_split(sims, parts, _u32p(rw), _u32p(img), img.size,
                                              _u32p(r), _u32p(p), _u32p(e), _u32p(out), n,
                                              self._max_idle(), _i64p(part_cycles))
            cycles = rc if rc < 0 else (int(part_cycles.sum())
                                        - (parts - 1) * model_latency(self.params))
        else:
            cycles = self._lib.rf_run_nodes(self._sim, _u32p(rw), _u32p(img), img.size,
                                            _u32p(r), _u32p(p), _u32p(e), _u32p(out), n,
                                            *self._patterns())
        self._account(cycles, n)
        return out


def memory_trace(params: dict[str, int], memory: dict, offset, nbytes, now, unit=None,
                 units: int = 1, flush_at: int = -1):
    """The memory hierarchy alone (tests): node fetches (byte offset, bytes, cycle; ``unit``
    each, default unit 0 of ``units``) in order; ``memory``: ``MEMORY_CONFIG`` values;
    ``flush_at``: drop the caches before that fetch. Returns (cycle each node is present (n,)
    int64, level it waited on (n,) int64 (1 L1, 2 L2, 3 DRAM), {``MEMORY_TRACE_COUNTS``})."""
    lib = harness_library(params)
    off, nb, t = (np.ascontiguousarray(x, np.int64) for x in (offset, nbytes, now))
    un = (np.zeros(len(off), np.int64) if unit is None
          else np.ascontiguousarray(unit, np.int64))
    ready = np.zeros(len(off), np.int64)
    level = np.zeros(len(off), np.int64)
    counts = np.zeros(len(MEMORY_TRACE_COUNTS), np.int64)
    mc = memory_config(memory)
    rc = lib.rf_memory_trace(ctypes.byref(mc), int(units), len(off), _i64p(un), _i64p(off),
                             _i64p(nb), _i64p(t), int(flush_at), _i64p(ready), _i64p(level),
                             _i64p(counts))
    if rc == BAD_GEOMETRY:
        raise ValueError(f"memory geometry {memory} cannot be modelled")
    if rc < 0:
        raise ValueError("memory trace: a unit out of range")
    return ready, level, dict(zip(MEMORY_TRACE_COUNTS, counts.tolist()))
