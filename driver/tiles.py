"""Frames as tiles: bounded memory, and Dask to spread the tiles over processes and machines.

A frame is a list of tiles (squares of ``tile`` x ``tile`` pixels, row-major); each tile is traced
by the same code as a whole frame (``driver.workloads.run`` with the tile's pixels: every ray type
and bounce is one wavefront within the tile) and its pixels, per-pixel ops, statistics and Embree
check are merged into the frame. Because every random number is a pure function of (seed, pixel,
sample, bounce, purpose) (``driver.scenes.sampling``), a tile traced alone is exactly that tile of
the whole frame: the image, hits, per-pixel ops, ray and op counts do not depend on the tile size
or on where a tile runs.

Timing: a tile is the unit of scheduling (its ray types and bounces are its wavefronts), so the
datapath ``cycles`` of a frame are the sum of its tiles' wavefront cycles (each wavefront pays its
pipeline latency once per traversal step). They are identical for any number of workers and
depend on the tile size only through that per-wavefront latency (a few per cent between 64 x 64
and whole-frame wavefronts); ``rayflex bench`` times frames on the RT-unit model instead.

Distribution (``workers > 1`` or a ``scheduler`` address): tiles are tasks on a
``dask.distributed`` cluster (a ``LocalCluster`` of one-thread worker processes, or an existing
cluster). The scene set-up and the BVH are built once on the client and scattered to every worker
once; a worker builds (or loads from the build cache) its Verilated model once per process.
Dask re-runs the tiles of a worker that dies; a tile that raises an expected error (ValueError,
OSError) stops the frame with that error. Why Dask: it is the well-kept Python engine for exactly
this (pure tasks over explicit inputs, retries, a dashboard, local or remote clusters); nothing of
it is reimplemented here.

Worker memory: Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536`` (so that freed
memory goes back to the OS). Setting any glibc malloc threshold switches off glibc's adaptive
mmap threshold, so every array above 128 KiB is a fresh ``mmap`` whose pages fault in again: a
4-tile Cornell path run took 97-115 thousand page faults in such a worker against about 100 in
this process, and 1.2-1.4 x the wall time. The local cluster started here leaves the variable
unset (``WORKER_ENV``); a tile's memory is bounded and reused, so nothing is lost. Workers of a
cluster given by ``--scheduler`` keep whatever their operator configured (docs/workloads.md).
"""

from __future__ import annotations

import json

import logging
import resource
import threading
import time
import uuid
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from .backends import DEFAULT_BACKEND, resolve
from .backends.harness import default_threads
from .check import merge_checks, prepare_check
from .rtunit.gpu import replay_point, waves_of
from .stats import merge, merge_rtunit
from .tracer import trace
from .workloads import FrameResult, embree_check, run

DEFAULT_TILE = 64
CONNECT_TIMEOUT = "5s"          # how long to wait for a Dask scheduler to answer
BYTES_PER_RAY = 2048          # peak working memory per ray in flight in one tile (measured, README)
_WORKER_BACKENDS = threading.local()      # per thread: (name, options) -> backend
# Dask configuration while the local cluster starts its workers (see the module docstring)
# (and each worker, one process of one thread, streams the datapath on one model: RAYFLEX_THREADS)
WORKER_ENV = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
              "distributed.nanny.pre-spawn-environ.RAYFLEX_THREADS": "1"}


def plan(width: int, height: int, tile: int = DEFAULT_TILE) -> list[np.ndarray]:
    """Pixel indices (row * width + column) of each tile, tiles row-major, ``tile`` x ``tile``
    pixels (smaller at the right and bottom edges)."""
    if isinstance(tile, bool) or not isinstance(tile, (int, np.integer)) or tile < 1:
        raise ValueError(f"--tile must be a positive integer, got {tile!r}")
    out = []
    for y0 in range(0, height, tile):
        for x0 in range(0, width, tile):
            ys = np.arange(y0, min(y0 + tile, height))
            xs = np.arange(x0, min(x0 + tile, width))
            out.append((ys[:, None] * width + xs[None, :]).reshape(-1))
    return out


@dataclass
class TileResult:
    """One tile: its pixels, radiance (k, 3) float32, ops per pixel per ray type (k,) int32,
    statistics per ray type, Embree checks per ray type (empty without a check)."""

    pixels: np.ndarray
    radiance: np.ndarray
    ops: dict
    stats: dict
    embree: dict = field(default_factory=dict)
    replay: dict = field(default_factory=dict)    # the tile's frame-level RT-unit objects


def _backend(spec):
    """This process's backend for ``spec`` (a name, or (name, options)), made once; a backend
    object is used as it is (in this process only)."""
    if not isinstance(spec, (str, tuple)):
        return spec
    name, options = (spec, {}) if isinstance(spec, str) else spec
    key = (name, json.dumps(options, sort_keys=True))     # options may hold a dict (memory)
    made = _WORKER_BACKENDS.__dict__
    if key not in made:
        made[key] = resolve(name, **options)[0]
    return made[key]


class TileCancelled(Exception):
    """A tile traced on a thread of ``render_tiles`` stopped because the frame stopped."""


def run_tile(setup, bvh, width: int, height: int, pixels, workload: str, options: dict,
             backend_spec, check_embree: bool = False, stop=None) -> TileResult:
    """Trace one tile (a task: pure in its inputs, the backend cached per process and thread).
    ``options``: the workload's (``driver.workloads.run``), ``cull_stack``, and ``rtunit``: a
    design point whose RT unit replays the tile's wavefronts (``add_replays``), or None.
    ``stop``: a ``threading.Event``; once it is set the tile raises ``TileCancelled`` at its
    next traversal step."""

    be = _backend(backend_spec)
    options = dict(options)
    cull = bool(options.pop("cull_stack", False))
    point = options.pop("rtunit", None)
    ideal = bool(options.pop("ideal", False))
    frame_width = options.pop("width", width)

    def stopped(done, total):
        if stop.is_set():
            raise TileCancelled

    def tracer(bvh_, o, d, **kw):
        return trace(bvh_, o, d, backend=be, cull_stack=cull, record=point is not None,
                     progress=stopped if stop is not None else None, **kw)

    res = run(setup, bvh, width, height, tracer, workload, pixels=pixels, **options)
    if point is not None:
        add_replays(res, point, frame_width, ideal)
    embree = {}
    if check_embree:
        embree_check(res, setup)
        embree = {k: v["embree"] for k, v in res.stats["by_type"].items()}
    return TileResult(np.asarray(pixels, np.int64), res.radiance.astype(np.float32),
                      {k: v.astype(np.int32) for k, v in res.ops.items()},
                      res.stats["by_type"], embree,
                      {k: res.stats[k] for k in ("rtunit", "rtunit_memory")}
                      if point is not None else {})


def add_replays(res: FrameResult, point, width: int | None = None, ideal: bool = False) -> None:
    """Replay a traced frame (or tile: a dispatch of its own) on the RT units of design point
    ``point`` (``driver.rtunit.gpu.replay_point``; threads are pixels of a ``width``-wide
    frame): ``rtunit_memory`` (and with ``ideal`` ``rtunit``) into the frame's statistics and
    each ``by_type`` entry."""
    rp = replay_point(waves_of(res.batches), point, width, ideal)
    for kind, entry in res.stats["by_type"].items():
        entry.update(rp["by_type"][kind])
    for key in ("rtunit", "rtunit_memory"):
        res.stats[key] = rp[key]


class Assembler:
    """Merges tile results into a frame (in any order)."""

    def __init__(self, width: int, height: int):
        self.npix = width * height
        self.radiance = np.zeros((self.npix, 3), np.float32)
        self.ops: dict = {}
        self.parts: dict = {}
        self.checks: dict = {}
        self.replays: list = []

    def add(self, t: TileResult) -> None:
        self.radiance[t.pixels] = t.radiance
        for kind, ops in t.ops.items():
            self.ops.setdefault(kind, np.zeros(self.npix, np.int32))[t.pixels] = ops
        for kind, s in t.stats.items():
            self.parts.setdefault(kind, []).append((tuple(t.pixels[:1].tolist()), s))
        for kind, e in t.embree.items():
            self.checks.setdefault(kind, []).append((tuple(t.pixels[:1].tolist()), e))
        if t.replay:
            self.replays.append((tuple(t.pixels[:1].tolist()), t.replay))

    def frame(self) -> FrameResult:
        # merge in tile order, so that float sums (wall times) do not depend on arrival order
        by_type = {k: merge([s for _, s in sorted(v, key=lambda x: x[0])])
                   for k, v in self.parts.items()}
        total = merge([s for v in self.parts.values() for _, s in sorted(v, key=lambda x: x[0])])
        for kind, parts in self.checks.items():
            by_type[kind]["embree"] = merge_checks([e for _, e in parts])
        if self.checks:
            total["embree"] = merge_checks([e for v in self.checks.values() for _, e in v])
        if self.replays:                 # tiles are dispatches one after another
            parts = [r for _, r in sorted(self.replays, key=lambda x: x[0])]
            for key in ("rtunit", "rtunit_memory"):
                total[key] = merge_rtunit([p[key] for p in parts])
        total["by_type"] = by_type
        return FrameResult(self.radiance, self.ops, total, [])


def render_tiles(setup, bvh, width: int, height: int, workload: str = "primary",
                 options: dict | None = None, backend=DEFAULT_BACKEND,
                 tile: int = DEFAULT_TILE, workers: int = 1, scheduler: str | None = None,
                 check_embree: bool = False, progress=None) -> FrameResult:
    """Trace a frame tile by tile: in this process (``workers=1`` and no ``scheduler``), or as
    Dask tasks on a new ``LocalCluster`` of ``workers`` processes or on the cluster at
    ``scheduler``. ``progress(done_tiles, total_tiles)``. Returns the merged ``FrameResult``;
    its ``timings`` hold a distributed run's wall-time phases in seconds:
    ``start_s`` (importing Dask, starting the cluster or connecting, sending the scene and
    BVH), ``first_tile_s`` (from then to the first tile's result: a worker's one-time set-up and
    one tile), ``tiles_s`` (from then to the last result) and ``close_s``."""
    options = dict(options or {})
    tiles = plan(width, height, tile)
    asm = Assembler(width, height)
    if workers == 1 and not scheduler:
        prep = prepare_check(setup.triangles) if check_embree else None
        try:
            lanes = tile_lanes(backend, len(tiles))
            if lanes > 1:
                _tiles_on_threads(asm, tiles, lanes, (setup, bvh, width, height), workload,
                                  options, backend, check_embree, progress)
                return asm.frame()
            for i, px in enumerate(tiles):
                asm.add(run_tile(setup, bvh, width, height, px, workload, options, backend,
                                 check_embree))
                if progress:
                    progress(i + 1, len(tiles))
            return asm.frame()
        finally:
            if prep is not None:
                prep.join()
    clock = _Phases({})
    with _client(workers, scheduler) as client:
        setup_f, bvh_f = client.scatter([setup, bvh], broadcast=True)
        clock.mark("start_s")
        frame_id = uuid.uuid4().hex[:12]
        futures = [client.submit(run_tile, setup_f, bvh_f, width, height, px, workload, options,
                                 backend, check_embree, key=f"rayflex-tile-{frame_id}-{i}",
                                 retries=3)
                   for i, px in enumerate(tiles)]
        from distributed import as_completed
        try:
            for done, fut in enumerate(as_completed(futures), 1):
                asm.add(fut.result())
                clock.mark("first_tile_s" if done == 1 else None)
                if progress:
                    progress(done, len(tiles))
        finally:
            client.cancel(futures)
        clock.mark("tiles_s")
        peaks = sorted(client.run(peak_rss).values())
    clock.mark("close_s")
    frame = asm.frame()
    frame.timings = clock.out
    frame.stats[WORKER_PEAKS] = peaks
    return frame


def tile_lanes(backend, tiles: int) -> int:
    """Tiles one process traces at once, each on a thread with its own backend: the CPUs it may
    use (``driver.backends.harness.default_threads``: ``RAYFLEX_THREADS``), at most the tiles,
    for the "rtl", "rtunit" and "golden" backends named (``THREAD_SAFE_BACKENDS``); else 1 (a
    backend object has one model; pyverilator's runs in the interpreter)."""
    name = backend if isinstance(backend, str) else \
        backend[0] if isinstance(backend, tuple) else None
    if name not in THREAD_SAFE_BACKENDS:
        return 1
    return max(1, min(default_threads(), tiles))


THREAD_SAFE_BACKENDS = ("rtl", "rtunit", "golden")


def _tiles_on_threads(asm, tiles, lanes, frame, workload, options, backend, check_embree,
                      progress) -> None:
    """Trace ``tiles`` on ``lanes`` threads, at most ``lanes`` tiles at a time (the memory of
    that many tiles), merged as they finish. Each thread has its own backend; the datapath
    models, the replay and numpy release the interpreter, so one tile's Python runs while
    another's model is clocked. An error or an interrupt stops the other tiles at their next
    traversal step."""
    stop = threading.Event()
    name, opts = (backend, {}) if isinstance(backend, str) else backend
    if name == "rtl":                       # the CPUs shared out among the tiles
        backend = (name, {**opts, "threads": max(1, default_threads() // lanes)})
    pool = ThreadPoolExecutor(max_workers=lanes, thread_name_prefix="rayflex-tile")
    running: set = set()
    todo = iter(tiles)
    done = 0
    try:
        while True:
            while len(running) < lanes:
                px = next(todo, None)
                if px is None:
                    break
                running.add(pool.submit(run_tile, *frame, px, workload, options, backend,
                                        check_embree, stop))
            if not running:
                break
            finished, running = wait(running, return_when=FIRST_COMPLETED)
            for fut in finished:
                asm.add(fut.result())
                done += 1
                if progress:
                    progress(done, len(tiles))
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)


WORKER_PEAKS = "workers_peak_rss_bytes"     # peak resident memory of each Dask worker


def peak_rss() -> int:
    """This process's peak resident memory in bytes (``ru_maxrss``)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


class _Phases:
    """Wall-clock phases of a distributed frame, written into ``out`` (nothing if ``None``)."""

    def __init__(self, out: dict | None):
        self.out, self.last = out, time.perf_counter()

    def mark(self, name: str | None) -> None:
        if self.out is None or name is None:
            return
        t = time.perf_counter()
        self.out[name], self.last = t - self.last, t


class _client:
    """A ``distributed.Client`` on a new LocalCluster or at an address; closes what it made."""

    def __init__(self, workers: int, scheduler: str | None):
        if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
            raise ValueError(f"--workers must be a positive integer, got {workers!r}")
        self.workers, self.scheduler, self.cluster = int(workers), scheduler, None

    def __enter__(self):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ValueError("--workers/--scheduler need dask.distributed "
                             "(pip install 'dask[distributed]')") from None
        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout=CONNECT_TIMEOUT)
            except (OSError, TimeoutError) as e:
                raise OSError(f"no Dask scheduler answers at {self.scheduler} ({e})") from None
            return self.client

        import dask
        # silence_logs: the workers' own log lines (e.g. a heartbeat that races the scheduler's
        # shutdown at the end of a frame) are not the user's business; a tile's error reaches the
        # client as the task's exception, and the dashboard keeps the logs
        with dask.config.set(WORKER_ENV):
            self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                        processes=True, dashboard_address=":0",
                                        silence_logs=logging.CRITICAL)
        self.client = Client(self.cluster)
        return self.client

    def __exit__(self, *exc):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        return False


def estimate_bytes(rays_in_flight: int) -> int:
    """Peak working memory of tracing ``rays_in_flight`` rays in one wavefront (bytes)."""
    return BYTES_PER_RAY * int(rays_in_flight)
