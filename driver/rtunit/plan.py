"""How a frame's rays reach the RT units (docs/rtunit.md): the frame schedule, threads grouped
into warps of screen tiles, warps' trace calls, and the frame's recorded batches as one record.

What a frame's replay needs beyond the recorded request chains
(``driver.tracing.record.Record``): for every ray, its thread and its place in the thread's program (``Wave.thread``, ``Wave.slot``; the
workloads set them, ``driver.workloads.Batch``). From them and a ``Schedule`` this module builds
the kernels, warps and trace calls (``Plan``) that ``rf_replay`` (sim/rtunit_scheduler.cpp)
issues:

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.layout import NO_CHILD
from . import order as ray_orders

FRAMES = ("one-kernel", "wavefront")
MAX_WARP_SIZE = 64
MAX_RT_UNITS = 256


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
    """One traced batch as the replay sees it: its ``Record``, its ray type, per ray its
    thread and slot (``driver.workloads.Batch``; None: thread = ray index, slot = 0), and
    whether its rays are any-hit rays."""

    record: object
    kind: str = "primary"
    thread: np.ndarray | None = None
    slot: np.ndarray | None = None
    any_hit: bool = False           # the batch's rays are any-hit rays


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
    if len(records) == 1:                      # one batch: its own arrays, nothing renumbered
        return Combined(first.params, first.ray_words, first.image,
                        np.asarray(first.ray, np.uint32), np.asarray(first.ptr, np.uint32),
                        np.asarray(first.extent, np.float32),
                        np.asarray(first.ray if first.chain is None else first.chain, np.uint32),
                        (np.full(first.ops, NO_CHILD, np.uint32) if first.before is None
                         else np.asarray(first.before, np.uint32)), first.responses,
                        chain_off0, request_off)

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


def build_plan(waves: list[Wave], comb: Combined, nonempty: np.ndarray, s: Schedule,
               ray_order: str, window: int, width: int | None) -> tuple[Plan, list]:
    """The ``Plan`` of a frame's waves under schedule ``s`` (rays without requests left out),
    and the wave each kernel replays (one-kernel: None). A wavefront kernel's rays enter in the
    order of ``ray_order`` (``driver.rtunit.order.permutation``, windows of ``window``)."""
    records = [w.record for w in waves]
    off = comb.chain_off0
    if s.frame == "wavefront":
        kernels = []
        for q, rec in enumerate(records):
            perm = ray_orders.permutation(rec, ray_order, window)
            ids = off[q] + (np.arange(rec.rays, dtype=np.int64) if perm is None else perm)
            kernels.append(ids[nonempty[ids]])
        return wavefront_plan(kernels, s.warp_size), list(range(len(records)))
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
    return one_kernel_plan(ids, thread[ids], slot[ids], s.warp_size, width), [None]
