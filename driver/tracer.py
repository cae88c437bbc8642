"""``trace``: rays through a scene with every box and triangle test on a datapath backend.

Composes the layers: the BVH4 (``driver.bvh4``), a backend (``driver.backends``), the issuer that
feeds it each traversal step (``driver.tracing.issue``, optionally recording every request), the
traversal loop (``driver.traversal``), the frame statistics (``driver.stats``) and, when asked, the
RT-unit timing replay (``driver.rtunit``).
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field

import numpy as np

from . import rtunit
from .backends import DEFAULT_BACKEND, resolve
from .backends.build import backend_params
from .backends.rtunit import UNIT_BACKEND
from .bvh4 import BVH4, build, build_two_level
from .core.datapath import prepare_rays
from .core.layout import DEFAULT_FORMAT
from .core.wire import FLAG_NO_CULL
from .instances import DATAPATH, Instances, check_transform
from .tracing.stepper import InstanceStepper
from .tracing.issue import issuer
from .stats import frame_stats, unit_rtl_stats, with_replay
from .traversal import traverse

REPLAY_OPTIONS = inspect.signature(rtunit.replay)     # what ``trace(**rtunit_options)`` passes on


@dataclass
class TraceResult:
    """Hits of n rays.

    t : (n,) float32, hit distance in units of the ray direction (inf on a miss)
    prim : (n,) int64, primitive id = triangle index in the scene (-1 on a miss)
    hit : (n,) bool
    box_ops, tri_ops : (n,) int64, QUADBOX / TRIANGLE requests issued for each ray
    transform_ops : (n,) int64, TRANSFORM requests issued for each ray (the instance transform
        on the datapath; zeros otherwise), or None for a one-level image
    step_requests, step_box_requests : (calls,) int64, requests (all / QUADBOX) in each
        backend call, in order, for timing replays: one call per traversal step, and before it
        the step's TRANSFORM requests, if any (the instance transform on the datapath)
    instance : (n,) int64, the instance of the hit triangle in a two-level image (-1 on a
        miss, and for every ray of a one-level image); ``prim`` is then the triangle's index in
        the flattened triangle list (``driver.instances.Instances.flatten``)
    stats : dict, docs/datapath.md#statistics names, plain Python ints/floats/str (plus the RT-unit
        keys of ``trace(rays_in_flight=...)``)
    record : ``driver.tracing.record.Record`` of every request, when asked for (else None)
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
    instance: np.ndarray | None = None
    transform_ops: np.ndarray | None = None

    @property
    def ops(self) -> np.ndarray:
        """(n,) int64: datapath requests issued for each ray (box, triangle and transform)."""
        ops = np.asarray(self.box_ops, np.int64) + np.asarray(self.tri_ops, np.int64)
        return ops if self.transform_ops is None else ops + self.transform_ops


def as_bvh(scene, bvh_format: str | None = None) -> BVH4:
    """A BVH4 from a BVH4, a scene name/path (``driver.scenes.scene.load``), a trimesh mesh, an
    (n, 3, 3) triangle array, or an object with a ``bvh`` or ``mesh`` attribute; built in
    ``bvh_format`` (``driver.bvh4.build``'s ``format``; None: box32). A given BVH4 must be in
    ``bvh_format`` when that is not None (ValueError)."""
    if isinstance(scene, BVH4) or isinstance(getattr(scene, "bvh", None), BVH4):
        bvh = scene if isinstance(scene, BVH4) else scene.bvh
        if bvh_format is not None and bvh.format != bvh_format:
            raise ValueError(f"the BVH given is {bvh.format}, not bvh_format={bvh_format!r}")
        return bvh
    if isinstance(scene, (str, bytes)) or hasattr(scene, "__fspath__"):
        from .scenes.scene import load_scene                      # the application layer; lazy
        scene = load_scene(scene)
    if isinstance(scene, Instances) or getattr(scene, "instances", None) is not None:
        return build_two_level(scene if isinstance(scene, Instances) else scene.instances,
                               format=bvh_format or DEFAULT_FORMAT)
    if hasattr(scene, "mesh") and not hasattr(scene, "faces"):
        scene = scene.mesh
    return build(scene, format=bvh_format or DEFAULT_FORMAT)


def trace(scene_or_mesh_or_bvh, origins, directions, backend=DEFAULT_BACKEND, extent=np.inf,
          progress=None, any_hit=False, double_sided=None, cull_stack=False, bvh_format=None,
          transform=None, **rtunit_options) -> TraceResult:
    """Trace rays with every box and triangle test run on ``backend``.

    scene_or_mesh_or_bvh : BVH4, trimesh mesh, (n, 3, 3) triangles, or a scene name/path
    origins, directions : (n, 3) array-like (float32 after conversion; see ``prepare_rays``,
        which raises ValueError for non-finite values or a zero direction)
    backend : backend name ("golden", "rtl", "pyverilator"; default ``DEFAULT_BACKEND``, "rtl",
        as on the command line) or a ``driver.backends.Backend``
    extent : scalar or (n,): only hits with t < extent are reported
    any_hit : occlusion rays (docs/datapath.md#traversal): a ray ends at its first accepted triangle
        (``hit``, ``prim``, ``t`` of that triangle); otherwise the closest hit
    double_sided : set ``NO_CULL`` on every ray (docs/datapath.md): triangles are hit from both
        sides. None (default): the scene's own setting when ``scene_or_mesh_or_bvh`` is a scene
        (a name, a path or a ``driver.scenes.scene.Scene``), else False
    cull_stack : keep each stack entry's entry distance (the response's ``box_tmin``) and drop
        a popped box node that lies beyond the nearest hit without a request (beyond
        docs/datapath.md#traversal, off by default; ``driver.traversal``): the same hits with fewer
        box requests; the statistics gain ``stack_culls``, the box nodes so dropped
    bvh_format : the node image built for a scene, mesh or triangles: "box32" (None, the
        default), "q8" or "q8g" (``driver.bvh4.build``'s ``format``); a BVH4 given must be in
        this format
    transform : where a two-level image's instance transform runs
        (``driver.instances.TRANSFORMS``): "driver" (on the host) or "datapath" (a TRANSFORM
        request per instance entered, on ``backend``, which must be built with the operation:
        a backend name is made with ``transform=True``, a backend object without it is a
        ValueError before any work); None: the image's own (``TwoLevelBVH.transform``, set by
        ``driver.bvh4.build_scene``)
    progress : optional callable(done_rays, total_rays), called once per step
    rtunit_options : the RT-unit model: ``record=True`` keeps the
        ``driver.tracing.record.Record`` of every request (for ``rtunit.replay`` and sweeps) in
        ``TraceResult.record`` (always kept when ``rays_in_flight`` is given); the others are
        ``driver.rtunit.replay``'s keywords (``rays_in_flight``, ``pipelines``,
        ``turnaround``, ...). Without ``rays_in_flight`` (or
        with None, the default) the statistics are the wavefront's: every ray in flight, one
        pipeline, cycles as the backend counts them. With an int R, the recorded requests are
        replayed through ``pipelines`` Verilated pipelines (default 1) holding R rays in flight
        (``turnaround`` cycles from a response to the ray's next request, default 1); the
        statistics' ``cycles``, ``utilization`` (= ops / (pipelines * cycles)),
        ``frame_us_at_1ghz``, ``sim_wall_s`` and ``sim_cycles_per_s`` are then the replay's,
        the wavefront's are kept as ``wavefront_*``, and the replayed responses are checked
        against the functional run bit for bit. Hits never depend on these options; an option
        ``driver.rtunit.replay`` does not take is a TypeError before any work.
    """
    record = bool(rtunit_options.pop("record", False))
    REPLAY_OPTIONS.bind(None, **rtunit_options)   # an unknown option fails here (TypeError)
    replay = {k: v for k, v in rtunit_options.items() if v is not None}
    rays = prepare_rays(origins, directions, extent)   # bad rays fail before the BVH is built
    bvh, double_sided, where, be, be_name = _set_up(scene_or_mesh_or_bvh, backend, double_sided,
                                                    bvh_format, transform, cull_stack)
    instanced = getattr(bvh, "instances", None) is not None
    rays["flags"] |= FLAG_NO_CULL if double_sided else 0
    if hasattr(be, "trace_unit"):
        return _trace_unit(be, be_name, bvh, rays, any_hit, progress, cull_stack,
                           record or bool(replay))
    timed = "rays_in_flight" in replay
    issue = issuer(be, rays, bvh, be_name, record=bool(record) or timed)
    cycles0 = int(be.cycles)
    inst = InstanceStepper(bvh, rays, issue, where) if instanced else None
    trav = traverse(bvh, rays["extent"], issue, any_hit=any_hit, progress=progress,
                    cull=cull_stack, instances=inst)
    hit = trav.prim >= 0
    instance = np.full(len(hit), -1, np.int64)
    if inst is not None:
        instance = inst.hit_instance
        trav.prim[hit] += bvh.instances.prim_base[instance[hit]]
        trav.node_bytes += inst.node_bytes
    t = np.where(hit, trav.nearest, np.float32(np.inf)).astype(np.float32)
    stats = frame_stats(trav.box_ops, trav.tri_ops, hit, int(be.cycles) - cycles0,
                        int(getattr(be, "latency", 0)), issue.wall_s, be_name,
                        trav.culled if cull_stack else None, trav.node_bytes,
                        None if inst is None else inst.instance_ops,
                        None if inst is None else inst.transform_ops)
    rec = issue.record(backend_params(be)) if hasattr(issue, "record") else None
    if timed:
        stats = with_replay(stats, rtunit.replay(rec, **replay).stats())
    return TraceResult(t, trav.prim, hit, trav.box_ops, trav.tri_ops, trav.step_requests,
                       trav.step_box_requests, stats, rec, instance,
                       None if inst is None else inst.transform_ops)


def _trace_unit(be, be_name: str, bvh, rays, any_hit, progress, cull_stack,
                replay) -> TraceResult:
    """The whole batch through an RT unit in RTL (``driver.backends.rtunit``): the unit runs the
    traversal itself; the statistics gain ``unit_rtl`` (docs/statistics.md). With the backend's
    ``compare`` the Python traversal runs too, on the unit's datapath: ``unit_rtl`` then counts
    the rays where the unit differs from it (``traversal_mismatches``; hit, primitive, t bits and
    op counts) and gives the RT-unit replay's cycles for the same pool and memory over the
    unit's (``replay_cycles_ratio``)."""
    if bool(cull_stack) != be.cull:
        raise ValueError("the RT unit in RTL culls its stack only when built with CULL: give "
                         "--cull-stack for both the unit (cull=True) and the frame"
                         if cull_stack else "this RT unit is built with CULL (the "
                         "distance-culled stack): trace with --cull-stack (cull_stack=True)")
    if replay:
        raise ValueError("the RT unit in RTL times the frame itself: the RT-unit replay "
                         "(--rtunit, rays_in_flight=, record=) replays the Python traversal's "
                         "requests: use --backend rtl for it")
    t0 = time.perf_counter()
    res = be.trace_unit(bvh, rays, any_hit=any_hit, progress=progress)
    wall = time.perf_counter() - t0
    t = np.where(res.hit, res.t, np.float32(np.inf)).astype(np.float32)
    instanced = getattr(bvh, "instances", None) is not None
    entered = res.xf_ops if instanced else None     # every instance entered is a TRANSFORM
    stats = frame_stats(res.box_ops, res.tri_ops, res.hit, res.stats["cycles"],
                        int(be.latency), wall, be_name, res.culled if be.cull else None,
                        instance_ops=entered, transform_ops=entered)
    unit = unit_rtl_stats(res, be)
    unit.update(dict.fromkeys(("traversal_mismatches", "replay_cycles", "replay_cycles_ratio",
                               "replay_default_cycles", "replay_default_cycles_ratio")))
    if be.compare:
        issue = issuer(be, rays, bvh, be_name, record=True)
        inst = InstanceStepper(bvh, rays, issue, DATAPATH) if instanced else None
        trav = traverse(bvh, rays["extent"], issue, any_hit=any_hit, cull=be.cull,
                        instances=inst)
        hit = trav.prim >= 0
        t_ref = np.where(hit, trav.nearest, np.float32(np.inf)).astype(np.float32)
        differ = ((hit != res.hit) | (trav.prim != res.prim)
                  | (t_ref.view(np.uint32) != t.view(np.uint32))
                  | (trav.box_ops != res.box_ops) | (trav.tri_ops != res.tri_ops)
                  | (trav.culled != res.culled))
        if inst is not None:
            differ |= ((inst.hit_instance != res.instance)
                       | (inst.transform_ops != res.xf_ops))
        unit["traversal_mismatches"] = int(np.count_nonzero(differ))
        unit.update(_replay_unit(be, issue.record(backend_params(be)), any_hit, len(rays),
                                 res.stats["cycles"],
                                 trav.cull_events if be.cull else None))
    stats["unit_rtl"] = unit
    steps = np.zeros(0, np.int64)
    prim = res.prim.copy()
    if instanced:          # the primitive in the flattened triangle list, as ``trace`` gives it
        prim[res.hit] += bvh.instances.prim_base[res.instance[res.hit]]
    return TraceResult(t, prim, res.hit, res.box_ops, res.tri_ops, steps, steps, stats, None,
                       res.instance, res.xf_ops if instanced else None)


def _replay_unit(be, rec, any_hit, n: int, unit_cycles: int, culls=None) -> dict:
    """The RT-unit replay of the unit's batch on its parameters (its pipelines, its rays in flight
    and memory): with the unit's costs (``rtunit.UnitCosts``: its dividers, its fixed-latency
    memory, the any-hit rays, its stack depth, the culling stack's pops ``culls``) and, when the unit has the memory hierarchy, with the replay's
    default costs; each as cycles and over the unit's."""
    mem = memory_model(be.memory) if be.memory is not None else None
    costs = rtunit.UnitCosts(be.dividers, fixed_latency=0 if mem else be.mem_latency,
                             any_hit=np.broadcast_to(np.asarray(any_hit, bool), (n,)),
                             stack_depth=be.stack_depth, setups=be.setups, culls=culls)
    out = {}
    for key, uc in (("replay", costs), ("replay_default", None)):
        cycles = None
        if uc is not None or mem is not None:
            cycles = int(rtunit.replay(rec, rays_in_flight=be.rays_in_flight,
                                       pipelines=be.pipelines,
                                       memory=mem, unit_costs=uc).cycles)
        out[f"{key}_cycles"] = cycles
        out[f"{key}_cycles_ratio"] = (None if cycles is None or not unit_cycles  # no rays
                                      else cycles / unit_cycles)
    return out


def memory_model(config: dict) -> rtunit.MemoryModel:
    """The ``MemoryModel`` of a ``MEMORY_CONFIG`` dict (``MemoryModel.config()``'s inverse)."""
    return rtunit.MemoryModel(
        config["l1_bytes"], config["l1_ways"], config["line_bytes"], config["mem_latency"],
        config["bytes_per_cycle"], hit_latency=config["l1_latency"],
        sector_bytes=config["sector_bytes"], mshrs=config["mshrs"], l2_bytes=config["l2_bytes"],
        l2_ways=config["l2_ways"], l2_latency=config["l2_latency"])


def _set_up(scene_or_mesh_or_bvh, backend, double_sided, bvh_format, transform,
            cull_stack=False):
    """``trace``'s BVH and backend: (bvh, double_sided, where the transform runs, backend, its
    name; the RT unit in RTL named with ``cull_stack`` is made with its culling stack); a
    ValueError for a transform on a backend built without it."""
    if transform is not None:
        check_transform(transform)
    if isinstance(scene_or_mesh_or_bvh, (str, bytes)) or hasattr(scene_or_mesh_or_bvh,
                                                                 "__fspath__"):
        from .scenes.scene import load_scene                      # the application layer; lazy
        scene_or_mesh_or_bvh = load_scene(scene_or_mesh_or_bvh)
    if double_sided is None:
        double_sided = bool(getattr(scene_or_mesh_or_bvh, "double_sided", False))
    bvh = as_bvh(scene_or_mesh_or_bvh, bvh_format)
    where = transform or getattr(bvh, "transform", "driver")
    xf = getattr(bvh, "instances", None) is not None and where == DATAPATH
    be, be_name = resolve(backend, **({"transform": True} if xf else {}),
                          **({"cull": True} if cull_stack and backend == UNIT_BACKEND else {}))
    if xf and not backend_params(be)["TRANSFORM"]:
        raise ValueError(f"transform='{DATAPATH}' needs a backend built with the TRANSFORM "
                         f"operation (backend({be_name!r}, transform=True))")
    return bvh, double_sided, where, be, be_name

