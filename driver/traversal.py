"""Closest-hit BVH4 traversal on a datapath backend, wavefront style (SPEC section 9).

Every ray has a stack of node pointers (root first). Each step, every ray with a non-empty stack
pops one node and turns it into one datapath request:

- box node -> QUADBOX with the node's four child boxes and ``extent`` = the ray's nearest t so far;
  the response lists the children nearest first (``box_index``/``box_hit``), and the hit ones are
  pushed in reverse so that the nearest is popped next;
- triangle node -> TRIANGLE; on ``tri_hit`` the host computes
  ``t = float32(t_num) / float32(t_den)`` and keeps it if ``t < nearest`` (strictly: on an
  exact tie the triangle found first stays).

All of a step's requests (QUADBOX and TRIANGLE interleaved, in ray order) go to the backend in ONE
``run()`` call, so the datapath sees a full stream and never waits on Python per request. Nodes are
decoded from the BVH4 byte image (``BVH4.box_nodes``/``tri_nodes``) as an RT unit would fetch them;
fetched bytes are counted (128 per box node, 64 per triangle node). The ray index travels in the
request ``tag`` and is checked on the way back.

Fast path: a backend with ``run_nodes`` (the "rtl" C++ harness) gets each step as (ray index,
node pointer, extent) triples and assembles the request words itself from the packed rays and the
BVH4 image, by the same rules (tests check the words are identical to the generic path's); the
host then decodes only the response bits it needs. Per step the Python work is a handful of
vectorised numpy operations on arrays of the step's length; no per-request Python.

RT-unit model: with ``record=True`` the requests are kept as a ``driver.rtunit.Record``; with
``rays_in_flight=R`` (and ``pipelines=P``) they are also replayed through the RTL with R rays in
flight on P pipelines, and the timing statistics are the replay's (see ``driver.rtunit``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .bvh4 import BOX_BYTES, BOX_TYPE, NO_CHILD, TRI_BYTES, BVH4, build
from .datapath import QUADBOX, TRIANGLE, prepare_rays


@dataclass
class TraceResult:
    """Closest hits of n rays.

    t : (n,) float32, hit distance in units of the ray direction (inf on a miss)
    prim : (n,) int64, primitive id = triangle index in the scene (-1 on a miss)
    hit : (n,) bool
    box_ops, tri_ops : (n,) int64, QUADBOX / TRIANGLE requests issued for each ray
    step_requests, step_box_requests : (steps,) int64, requests (all / QUADBOX) in each
        ``backend.run()`` call, in order, for timing replays
    stats : dict, SPEC section 10 names, plain Python ints/floats/str (plus the RT-unit keys
        of ``trace(rays_in_flight=...)``)
    record : ``driver.rtunit.Record`` of every request, when asked for (else None)
    """

    t: np.ndarray
    prim: np.ndarray
    hit: np.ndarray
    box_ops: np.ndarray
    tri_ops: np.ndarray
    step_requests: np.ndarray
    step_box_requests: np.ndarray
    stats: dict = field(default_factory=dict)
    record: object = None


def as_bvh(scene) -> BVH4:
    """A BVH4 from a BVH4, a scene name/path (``driver.scene.load``), a trimesh mesh, an
    (n, 3, 3) triangle array, or an object with a ``bvh`` or ``mesh`` attribute."""
    if isinstance(scene, BVH4):
        return scene
    if isinstance(scene, (str, bytes)) or hasattr(scene, "__fspath__"):
        from .scene import load                            # someone else's module; lazy
        scene = load(scene)
    if isinstance(getattr(scene, "bvh", None), BVH4):
        return scene.bvh
    if hasattr(scene, "mesh") and not hasattr(scene, "faces"):
        scene = scene.mesh
    return build(scene)


def _backend(backend):
    if isinstance(backend, str):
        from .backends import backend as make               # noqa: PLC0415
        return make(backend), backend
    return backend, str(getattr(backend, "name", type(backend).__name__))


def trace(scene_or_mesh_or_bvh, origins, directions, backend="golden", extent=np.inf,
          progress=None, rays_in_flight=None, pipelines=1, turnaround=None,
          record=False) -> TraceResult:
    """Closest-hit trace with every box and triangle test run on ``backend``.

    scene_or_mesh_or_bvh : BVH4, trimesh mesh, (n, 3, 3) triangles, or a scene name/path
    origins, directions : (n, 3) array-like (float32 after conversion; see ``prepare_rays``,
        which raises ValueError for non-finite values or a zero direction)
    backend : backend name ("golden", "rtl", ...) or an object with ``run()``, ``cycles``,
        ``latency``
    extent : scalar or (n,): only hits with t < extent are reported
    progress : optional callable(done_rays, total_rays), called once per step
    rays_in_flight, pipelines, turnaround : RT-unit model (``driver.rtunit``). With
        ``rays_in_flight=None`` (default) the statistics are the wavefront's: every ray in
        flight, one pipeline, cycles as the backend counts them. With an int R, the recorded
        requests are replayed through ``pipelines`` Verilated pipelines holding R rays in flight
        (``turnaround`` cycles from a response to the ray's next request, default 1); the
        statistics' ``cycles``, ``utilization`` (= ops / (pipelines * cycles)),
        ``frame_us_at_1ghz``, ``sim_wall_s`` and ``sim_cycles_per_s`` are then the replay's,
        the wavefront's are kept as ``wavefront_*``, and the replayed responses are checked
        against the functional run bit for bit. Hits never depend on these parameters.
    record : keep the ``driver.rtunit.Record`` of every request (for ``rtunit.replay``/sweeps)
        in ``TraceResult.record`` (always kept when ``rays_in_flight`` is given).
    """
    bvh = as_bvh(scene_or_mesh_or_bvh)
    be, be_name = _backend(backend)
    rays = prepare_rays(origins, directions, extent)
    n = len(rays)
    timed = rays_in_flight is not None
    keep = bool(record) or timed
    fast = callable(getattr(be, "run_nodes", None))
    nearest = rays["extent"].copy()
    prim = np.full(n, -1, np.int64)
    box_ops = np.zeros(n, np.int64)
    tri_ops = np.zeros(n, np.int64)
    # a popped box node leaves <= 3 siblings per level on the stack and pushes <= 4 children
    stack = np.empty((n, 3 * bvh.stats["depth"] + 2), np.uint32)
    stack[:, 0] = bvh.root
    sp = np.ones(n, np.int64)
    steps, steps_box = [], []
    rec_ray, rec_ptr, rec_ext, rec_rsp = [], [], [], []
    image = bvh.image.view("<u4")
    if fast or keep:
        from .rtl import ray_words
        rw = ray_words(rays)
    cycles0 = int(be.cycles)
    sim_wall = 0.0
    active = np.arange(n)
    lane4 = np.arange(4, dtype=np.uint32)
    while len(active):
        sp[active] -= 1
        ptr = stack[active, sp[active]]
        ext = nearest[active]
        is_box = bvh.node_type(ptr) == BOX_TYPE
        bi, ti = np.flatnonzero(is_box), np.flatnonzero(~is_box)
        base = bvh.node_offset(ptr) >> 2                       # word offset of each node

        t0 = time.perf_counter()
        if fast:
            # the harness assembles the requests from the ray table and the image
            words = be.run_nodes(rw, image, active, ptr, ext)
            sim_wall += time.perf_counter() - t0
            if len(words) != len(active) or not np.array_equal(words[:, 0], active):
                raise RuntimeError(f"backend {be_name!r} returned responses out of order or "
                                   "with altered tags")
            ctrl = words[:, 1]
            cb = ctrl[bi, None]
            box_index = (cb >> (2 + 2 * lane4)) & 3
            box_hit = ((cb >> (10 + lane4)) & 1).astype(bool)
            tri_hit = ((ctrl[ti] >> 14) & 1).astype(bool)
            t_num = words[ti, 6].view(np.float32)
            t_den = words[ti, 7].view(np.float32)
        else:
            req = rays[active]
            req["extent"] = ext
            req["opcode"] = np.where(is_box, QUADBOX, TRIANGLE)
            req["tag"] = active
            req["box"][bi] = bvh.box_nodes(ptr[bi])[1]
            req["tri"][ti] = bvh.tri_nodes(ptr[ti])[0]
            rsp = be.run(req)
            sim_wall += time.perf_counter() - t0
            if len(rsp) != len(req) or not np.array_equal(rsp["tag"], req["tag"]):
                raise RuntimeError(f"backend {be_name!r} returned responses out of order or "
                                   "with altered tags")
            box_index = rsp["box_index"][bi]
            box_hit = rsp["box_hit"][bi].astype(bool)
            tri_hit = rsp["tri_hit"][ti].astype(bool)
            t_num = rsp["t_num"][ti].astype(np.float32)
            t_den = rsp["t_den"][ti].astype(np.float32)
            if keep:
                from .rtunit import response_words
                words = response_words(rsp)
        steps.append(len(active))
        steps_box.append(len(bi))
        if keep:
            rec_ray.append(active.astype(np.uint32))
            rec_ptr.append(ptr)
            rec_ext.append(ext)
            rec_rsp.append(words)

        # box nodes: push the hit children, farthest first, so that the nearest is popped next
        ray_b = active[bi]
        box_ops[ray_b] += 1
        children = image[base[bi, None] + np.arange(4)]
        hit = box_hit[:, ::-1]
        child = np.take_along_axis(children, box_index.astype(np.intp), 1)[:, ::-1]
        if (child[hit] == NO_CHILD).any():
            raise RuntimeError(f"backend {be_name!r} reported a hit on an unused box slot")
        col = sp[ray_b][:, None] + np.cumsum(hit, axis=1) - 1
        r, c = np.nonzero(hit)
        stack[ray_b[r], col[r, c]] = child[r, c]
        sp[ray_b] += hit.sum(axis=1)

        # triangle nodes: keep a strictly nearer hit
        ray_t = active[ti]
        tri_ops[ray_t] += 1
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = t_num / t_den
        better = tri_hit & (t < nearest[ray_t])
        nearest[ray_t[better]] = t[better]
        prim[ray_t[better]] = image[base[ti[better]] + 9].astype(np.int64)

        active = active[sp[active] > 0]
        if progress is not None:
            progress(n - len(active), n)

    hit = prim >= 0
    t = np.where(hit, nearest, np.float32(np.inf)).astype(np.float32)
    cycles = int(be.cycles) - cycles0
    nb, nt = int(box_ops.sum()), int(tri_ops.sum())
    ops = nb + nt
    stats = {
        "rays": n,
        "hits": int(hit.sum()),
        "box_ops": nb,
        "tri_ops": nt,
        "ops": ops,
        "cycles": cycles,
        "utilization": ops / cycles if cycles else 0.0,
        "latency_cycles": int(getattr(be, "latency", 0)),
        "box_ops_per_ray": nb / n if n else 0.0,
        "tri_ops_per_ray": nt / n if n else 0.0,
        "node_bytes_fetched": BOX_BYTES * nb + TRI_BYTES * nt,
        "sim_wall_s": sim_wall,
        "sim_cycles_per_s": cycles / sim_wall if sim_wall > 0 else 0.0,
        "frame_us_at_1ghz": cycles / 1000,
        "backend": be_name,
    }
    rec = None
    if keep:
        from .rtunit import Record
        from .wire import RSP_WORDS
        cat = lambda parts, dt: np.concatenate(parts) if parts else np.zeros(0, dt)  # noqa: E731
        rec = Record(rw, image, cat(rec_ray, np.uint32), cat(rec_ptr, np.uint32),
                     cat(rec_ext, np.float32),
                     np.concatenate(rec_rsp) if rec_rsp else np.zeros((0, RSP_WORDS), np.uint32),
                     _replay_params(be))
    if timed:
        from . import rtunit
        ta = rtunit.DEFAULT_TURNAROUND if turnaround is None else turnaround
        rs = rtunit.replay(rec, rays_in_flight, pipelines, ta).stats()
        for k in ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s"):
            stats["wavefront_" + k] = stats[k]
        stats.update({k: rs[k] for k in (
            "cycles", "utilization", "frame_us_at_1ghz", "sim_wall_s", "sim_cycles_per_s",
            "rays_in_flight", "pipelines", "turnaround_cycles", "starved_cycles",
            "responses_verified")})
        stats["latency_cycles"] = rs["latency_cycles"]
        stats["per_pipeline_ops"] = rs["per_pipeline_ops"]
    return TraceResult(t, prim, hit, box_ops, tri_ops, np.array(steps, np.int64),
                       np.array(steps_box, np.int64), stats, rec)


def _replay_params(be) -> dict:
    """RTL build parameters for replaying this backend's requests (an RTL backend's own, else
    the defaults with the backend's extended/disjoint/latency where it has them)."""
    params = getattr(be, "params", None)
    if isinstance(params, dict) and {"EXTENDED", "DISJOINT", "LATENCY"} <= set(params):
        return dict(params)
    from .datapath import LATENCY
    from .rtl import rtl_params
    lat = getattr(be, "latency", LATENCY)
    return rtl_params(getattr(be, "extended", False), getattr(be, "disjoint", False),
                      lat if isinstance(lat, int) and lat >= 11 else LATENCY)
