"""The "rtl" backend: the Verilated RayFlex datapath behind a C++ harness, one call per batch.

``HarnessBackend.run`` streams ready-made request words (sim/rayflex_harness.cpp);
``HarnessBackend.run_nodes`` is the traversal fast path: the harness assembles QUADBOX/TRIANGLE
requests from a packed ray table (``driver.core.wire.ray_words``) and the BVH4 image, so the host
sends three numbers per request instead of 320 bytes. ``replay_chains`` runs the RT-unit scheduler
(sim/rtunit_scheduler.cpp) for ``driver.rtunit``. ``harness_library(params)`` builds (cached; see
``driver.backends.build``) and loads the library once per process.
"""

from __future__ import annotations

import ctypes

import numpy as np

from ..core.layout import NO_CHILD, REPLAY_STATS
from ..core.wire import RAY_WORDS, REQ_WORDS, RSP_WORDS, pack_requests, unpack_responses
from .build import build_harness
from .rtlbase import PATTERN_LEN, RtlBackendBase

_U8P = ctypes.POINTER(ctypes.c_uint8)
_U32P = ctypes.POINTER(ctypes.c_uint32)
_I32P = ctypes.POINTER(ctypes.c_int32)
_I64P = ctypes.POINTER(ctypes.c_int64)
_LIBS: dict = {}
BAD_NODE = -2             # return code of the harness calls: a pointer that names no node


class ReplayStats(ctypes.Structure):
    """rf_layout::ReplayStats (fields: ``driver.core.layout.REPLAY_STATS``)."""

    _fields_ = [(name, ctypes.c_int64) for name in REPLAY_STATS]

    def as_dict(self) -> dict:
        return {name: int(getattr(self, name)) for name in REPLAY_STATS}


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
    lib.rf_replay.restype = i64
    lib.rf_replay.argtypes = [i64, i64, i64, i64, _U32P, i64, _U32P, i64, _U32P, _U32P, _U32P,
                              i64, _I64P, _I64P, i64, _U32P, _U32P, _U32P,
                              ctypes.POINTER(ReplayStats), _I64P, i64, i64, i64, i64, i64,
                              ctypes.c_double, _I64P, i64, _I64P,
                              _I32P, i64, i64, _I64P, _I64P, _I64P, i64]
    lib.rf_memory_trace.restype = i64
    lib.rf_memory_trace.argtypes = [i64, i64, i64, i64, ctypes.c_double, i64, _I64P, _I64P,
                                    _I64P, _I64P, _I64P]
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
    """The (n, REQ_WORDS) request words ``run_nodes``/``replay_chains`` assemble for these
    triples."""
    lib = harness_library(params)
    rw, img, r, p, e = node_arrays(ray_words, image_words, ray, ptr, extent)
    out = np.zeros((len(r), REQ_WORDS), np.uint32)
    if lib.rf_build_requests(_u32p(rw), _u32p(img), img.size, _u32p(r), _u32p(p), _u32p(e),
                             _u32p(out), len(r)) == BAD_NODE:
        raise _bad_node()
    return out


NO_MEMORY = (-1, 1, 64, 0, 1.0)      # cache_bytes < 0: no memory model, every node fetch is free
BAD_GEOMETRY = -4


SCHED_STATS = ("parked", "resumed", "max_parked", "max_held", "picks", "max_queued",
               "borrowed")


def replay_chains(params: dict[str, int], record, chains, pipelines: int, slots: int,
                  turnaround: int, skip_idle: bool, max_idle: int, memory=NO_MEMORY, order=None,
                  window: int = 0, treelets=None):
    """Run the RT-unit scheduler (sim/rtunit_scheduler.cpp) over recorded request chains.
    ``record``: the requests (a ``driver.tracing.record.Record``: ``ray_words``, ``image``,
    ``ray``, ``ptr``, ``extent``, ``chain``, ``before``); ``chains``: (chain_idx, chain_off), its
    requests in chain order (``Record.chains``).
    ``memory``: (cache_bytes, ways, line_bytes, latency_cycles, bytes_per_cycle) of the node
    memory (sim/rf_memory.h; cache_bytes = 0: no cache, every line from memory; < 0: no memory
    model). ``order``: the order in which chains (world rays) enter (a permutation of the chain
    indices; None: index order). ``window``: rays held by the node-affinity scheduler (0: none;
    else >= slots). ``chain``: the chain (world ray) of each request (default: its ray), when a
    ray's requests use several rows of the ray table (instances); ``before``: per request a node
    fetched before its own (an instance node; ``NO_CHILD``: none, the default). ``treelets``:
    treelet scheduling (needs a window) as a ``driver.rtunit.order.TreeletSchedule`` (the
    treelet of each request, the treelets active at once, the prefetch lists). Returns
    (responses (m, RSP_WORDS) uint32 at the record index, ``ReplayStats`` dict plus the
    scheduler's ``SCHED_STATS`` counts, requests per pipeline (P,) int64)."""
    lib = harness_library(params)
    rw, img, r, p, e = node_arrays(record.ray_words, record.image, record.ray, record.ptr,
                                   record.extent)
    chain, before = record.chain, record.before
    ci = np.ascontiguousarray(chains[0], np.int64)
    co = np.ascontiguousarray(chains[1], np.int64)
    ch = r if chain is None else np.ascontiguousarray(chain, np.uint32).reshape(-1)
    bf = (np.full(len(r), NO_CHILD, np.uint32) if before is None
          else np.ascontiguousarray(before, np.uint32).reshape(-1))
    if len(ch) != len(r) or len(bf) != len(r) or (len(r) and int(ch.max()) >= len(co) - 1):
        raise ValueError("chain and before need one entry per request, chains within chain_off")
    if order is not None:
        order = np.ascontiguousarray(order, np.int64)
        n_chains = len(co) - 1
        if order.shape != (n_chains,) or not np.array_equal(np.sort(order), np.arange(n_chains)):
            raise ValueError("the ray order must be a permutation of the chain (world ray) "
                             "indices")
    if window and not int(window) >= slots:
        raise ValueError(f"the scheduler's window ({window} rays) must hold at least the "
                         f"{slots} rays in flight")
    ids, n_tl, active, pre, flags = None, 0, 0, (None,) * 3, 0
    if treelets is not None:
        if not window:
            raise ValueError("treelet scheduling needs a window")
        ids = np.ascontiguousarray(treelets.request_treelet, np.int32)
        if ids.shape != (len(r),):
            raise ValueError("treelet scheduling needs one treelet per request")
        n_tl, active = int(treelets.n_treelets), int(treelets.active)
        pre = treelets.prefetch_lists()
        flags = int(treelets.park) | 2 * int(treelets.borrow)     # rf_replay's treelet_flags
    rsp = np.zeros((len(r), RSP_WORDS), np.uint32)
    stats = ReplayStats()
    per_pipe = np.zeros(pipelines, np.int64)
    sched = np.zeros(len(SCHED_STATS), np.int64)
    rc = lib.rf_replay(pipelines, slots, turnaround, int(bool(skip_idle)), _u32p(rw), len(rw),
                       _u32p(img), img.size, _u32p(r), _u32p(p), _u32p(e), len(r), _i64p(ci),
                       _i64p(co), len(co) - 1, _u32p(ch), _u32p(bf), _u32p(rsp),
                       ctypes.byref(stats), _i64p(per_pipe), max_idle, *memory,
                       None if order is None else _i64p(order), int(window), _i64p(sched),
                       None if ids is None else ids.ctypes.data_as(_I32P), n_tl, active,
                       *(None if a is None else _i64p(a) for a in pre), flags)
    if rc == BAD_GEOMETRY:
        raise ValueError(f"node cache geometry {memory[:3]} cannot be modelled: the cache size must "
                         "be a multiple of ways x line size, the line a power of two >= 4 bytes")
    if rc == BAD_NODE:
        raise ValueError("a recorded request names a node pointer outside the BVH image")
    if rc < 0:
        raise RuntimeError(f"RT-unit replay failed ({'deadlock' if rc == -1 else rc})")
    return rsp, {**stats.as_dict(), **dict(zip(SCHED_STATS, sched.tolist()))}, per_pipe


class HarnessBackend(RtlBackendBase):
    """The fast path: one C++ call streams a batch through the Verilated model.

    ``run(requests)`` takes a ``REQUEST_DTYPE`` array; ``run_nodes(...)`` takes traversal requests
    as (ray, node pointer, extent) triples and lets the harness assemble the request words from the
    packed rays and the BVH4 image (no per-request Python work; see ``driver.traversal``)."""

    name = "rtl"

    def __init__(self, **options):
        super().__init__(**options)
        self._lib = harness_library(self.params)
        self._sim = self._lib.rf_new()

    def __del__(self):
        sim, self._sim = getattr(self, "_sim", None), None
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
        cycles = self._lib.rf_run_nodes(self._sim, _u32p(rw), _u32p(img), img.size, _u32p(r),
                                        _u32p(p), _u32p(e), _u32p(out), n, *self._patterns())
        self._account(cycles, n)
        return out


def memory_trace(params: dict[str, int], memory, offset, nbytes, now):
    """The node memory alone (tests): fetch nodes (byte offset, bytes, cycle) in order. Returns
    (cycle each node is present (n,) int64, {line_accesses, line_hits, line_misses,
    bytes_from_memory})."""
    lib = harness_library(params)
    off, nb, t = (np.ascontiguousarray(x, np.int64) for x in (offset, nbytes, now))
    ready = np.zeros(len(off), np.int64)
    counts = np.zeros(4, np.int64)
    if lib.rf_memory_trace(*memory, len(off), _i64p(off), _i64p(nb), _i64p(t), _i64p(ready),
                           _i64p(counts)) == BAD_GEOMETRY:
        raise ValueError(f"node cache geometry {tuple(memory[:3])} cannot be modelled")
    keys = ("line_accesses", "line_hits", "line_misses", "bytes_from_memory")
    return ready, dict(zip(keys, counts.tolist()))
