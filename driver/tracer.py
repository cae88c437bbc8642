"""``trace``: rays through a scene with every box and triangle test on a datapath backend.

Composes the layers: the BVH4 (``driver.bvh4``), a backend (``driver.backends``), the issuer that
feeds it each traversal step (``driver.issue``, optionally recording every request), the traversal
loop (``driver.traversal``), the frame statistics (``driver.stats``) and, when asked, the RT-unit
timing replay (``driver.rtunit``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .backends import resolve
from .bvh4 import BVH4, build
from .datapath import prepare_rays
from .layout import FLAG_NO_CULL
from .issue import issuer
from .stats import frame_stats, with_replay
from .traversal import traverse


@dataclass
class TraceResult:
    """Hits of n rays.

    t : (n,) float32, hit distance in units of the ray direction (inf on a miss)
    prim : (n,) int64, primitive id = triangle index in the scene (-1 on a miss)
    hit : (n,) bool
    box_ops, tri_ops : (n,) int64, QUADBOX / TRIANGLE requests issued for each ray
    step_requests, step_box_requests : (steps,) int64, requests (all / QUADBOX) in each
        traversal step (one backend call each), in order, for timing replays
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
        from .scenes.scene import load                            # the application layer; lazy
        scene = load(scene)
    if isinstance(getattr(scene, "bvh", None), BVH4):
        return scene.bvh
    if hasattr(scene, "mesh") and not hasattr(scene, "faces"):
        scene = scene.mesh
    return build(scene)


def trace(scene_or_mesh_or_bvh, origins, directions, backend="golden", extent=np.inf,
          progress=None, rays_in_flight=None, pipelines=1, turnaround=None, record=False,
          any_hit=False, double_sided=None, cull_stack=False) -> TraceResult:
    """Trace rays with every box and triangle test run on ``backend``.

    scene_or_mesh_or_bvh : BVH4, trimesh mesh, (n, 3, 3) triangles, or a scene name/path
    origins, directions : (n, 3) array-like (float32 after conversion; see ``prepare_rays``,
        which raises ValueError for non-finite values or a zero direction)
    backend : backend name ("golden", "rtl", ...) or a ``driver.backends.Backend``
    extent : scalar or (n,): only hits with t < extent are reported
    any_hit : occlusion rays (SPEC 9): a ray ends at its first accepted triangle (``hit``,
        ``prim``, ``t`` of that triangle); otherwise the closest hit
    double_sided : set ``NO_CULL`` on every ray (docs/datapath.md): triangles are hit from both
        sides. None (default): the scene's own setting when ``scene_or_mesh_or_bvh`` is a scene
        (a name, a path or a ``driver.scene.Scene``), else False
    cull_stack : keep each stack entry's entry distance (the response's ``box_tmin``) and drop
        a popped box node that lies beyond the nearest hit without a request (beyond SPEC 9,
        off by default; ``driver.traversal``): the same hits with fewer box requests; the
        statistics gain ``stack_culls``, the box nodes so dropped
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
    if isinstance(scene_or_mesh_or_bvh, (str, bytes)) or hasattr(scene_or_mesh_or_bvh,
                                                                 "__fspath__"):
        from .scenes.scene import load_scene                      # the application layer; lazy
        scene_or_mesh_or_bvh = load_scene(scene_or_mesh_or_bvh)
    if double_sided is None:
        double_sided = bool(getattr(scene_or_mesh_or_bvh, "double_sided", False))
    bvh = as_bvh(scene_or_mesh_or_bvh)
    be, be_name = resolve(backend)
    rays = prepare_rays(origins, directions, extent,
                        **({"flags": FLAG_NO_CULL} if double_sided else {}))
    timed = rays_in_flight is not None
    issue = issuer(be, rays, bvh, be_name, record=bool(record) or timed)
    cycles0 = int(be.cycles)
    trav = traverse(bvh, rays["extent"], issue, any_hit=any_hit, progress=progress,
                    cull=cull_stack)
    hit = trav.prim >= 0
    t = np.where(hit, trav.nearest, np.float32(np.inf)).astype(np.float32)
    stats = frame_stats(trav.box_ops, trav.tri_ops, hit, int(be.cycles) - cycles0,
                        int(getattr(be, "latency", 0)), issue.wall_s, be_name,
                        trav.culled if cull_stack else None)
    rec = issue.record(_replay_params(be)) if hasattr(issue, "record") else None
    if timed:
        from . import rtunit
        ta = rtunit.DEFAULT_TURNAROUND if turnaround is None else turnaround
        stats = with_replay(stats, rtunit.replay(rec, rays_in_flight, pipelines, ta).stats())
    return TraceResult(t, trav.prim, hit, trav.box_ops, trav.tri_ops, trav.step_requests,
                       trav.step_box_requests, stats, rec)


def _replay_params(be) -> dict:
    """RTL build parameters for replaying this backend's requests (an RTL backend's own, else
    the defaults with the backend's extended/disjoint/latency where it has them)."""
    params = getattr(be, "params", None)
    if isinstance(params, dict) and {"EXTENDED", "DISJOINT", "LATENCY"} <= set(params):
        return dict(params)
    from .backends.build import MIN_LATENCY, rtl_params
    lat = getattr(be, "latency", MIN_LATENCY)
    compressed = bool(getattr(be, "compressed", False))
    return rtl_params(getattr(be, "extended", False), getattr(be, "disjoint", False),
                      lat if isinstance(lat, int) and lat >= MIN_LATENCY + compressed else None,
                      compressed)
