"""Frame statistics (SPEC section 10): built once here, merged once here.

``frame_stats`` turns a traversal's per-ray op counts and the backend's cycles into the SPEC 10
dictionary; ``with_replay`` merges an RT-unit replay's timing into it (the wavefront's own timing
kept as ``wavefront_*``). ``driver.tracer`` and ``rayflex bench`` both use these two.
"""

from __future__ import annotations

import numpy as np

from .layout import BOX_BYTES, TRI_BYTES

STACK_CULLS = "stack_culls"     # beyond SPEC 10: box nodes a distance-culled stack dropped
INSTANCE_OPS = "instance_ops"   # instances entered (two-level images; docs/instances.md)
# the replay's figures that replace the wavefront's (which are kept as wavefront_<name>)
REPLAYED = ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s")
# the replay's own figures that join the frame's statistics
REPLAY_KEYS = ("frame_us_at_1ghz", "rays_in_flight", "pipelines", "turnaround_cycles",
               "starved_cycles", "responses_verified", "latency_cycles", "per_pipeline_ops")


def frame_stats(box_ops: np.ndarray, tri_ops: np.ndarray, hit: np.ndarray, cycles: int,
                latency: int, sim_wall_s: float, backend: str,
                culled: np.ndarray | None = None, node_bytes: np.ndarray | None = None,
                instance_ops: np.ndarray | None = None) -> dict:
    """SPEC 10 statistics of a traversal: per-ray op counts (n,), hit mask (n,), the datapath
    cycles it took, the pipeline latency, the wall time inside the backend, the backend's name;
    with ``culled`` (per-ray box nodes dropped by a distance-culled stack, ``driver.traversal``)
    also ``stack_culls``, their total (absent when the traversal does not cull); ``node_bytes``
    (n,) per-ray node bytes fetched (default: a box32 image's, 128 B per box op and 64 B per
    triangle op); ``instance_ops`` (n,) per-ray instances entered (a two-level image): adds
    ``instance_ops`` and ``instance_ops_per_ray``."""
    n = len(box_ops)
    nb, nt = int(np.sum(box_ops)), int(np.sum(tri_ops))
    ops = nb + nt
    out = {
        "rays": n,
        "hits": int(np.sum(hit)),
        "box_ops": nb,
        "tri_ops": nt,
        "ops": ops,
        "cycles": int(cycles),
        "utilization": ops / cycles if cycles else 0.0,
        "latency_cycles": int(latency),
        "box_ops_per_ray": nb / n if n else 0.0,
        "tri_ops_per_ray": nt / n if n else 0.0,
        "node_bytes_fetched": (BOX_BYTES * nb + TRI_BYTES * nt if node_bytes is None
                               else int(np.sum(node_bytes))),
        "sim_wall_s": sim_wall_s,
        "sim_cycles_per_s": cycles / sim_wall_s if sim_wall_s > 0 else 0.0,
        "frame_us_at_1ghz": cycles / 1000,
        "backend": backend,
    }
    if culled is not None:
        out[STACK_CULLS] = int(np.sum(culled))
    if instance_ops is not None:
        out[INSTANCE_OPS] = int(np.sum(instance_ops))
        out[INSTANCE_OPS + "_per_ray"] = out[INSTANCE_OPS] / n if n else 0.0
    return out


def with_replay(stats: dict, replay: dict) -> dict:
    """A copy of frame ``stats`` with the timing of an RT-unit replay (``ReplayResult.stats()``):
    the replay's cycles, utilization and simulation speed replace the wavefront's, which are
    kept as ``wavefront_*``; the replay's pool, pipelines and checks join."""
    out = dict(stats)
    for k in REPLAYED:
        out["wavefront_" + k] = stats[k]
        out[k] = replay[k]
    out.update({k: replay[k] for k in REPLAY_KEYS})
    return out


# summed over the parts of a frame; the rest of SPEC 10 is derived from the sums
_SUMMED = ("rays", "hits", "box_ops", "tri_ops", "ops", "cycles", "node_bytes_fetched",
           "sim_wall_s")


def merge(parts: list[dict]) -> dict:
    """SPEC 10 statistics of several traversals taken together (ray types, bounces, tiles): counts,
    cycles and wall times add up (each traversal is its own wavefront: the datapath runs them one
    after another); the ratios are recomputed from the sums."""
    if not parts:
        return frame_stats(np.zeros(0), np.zeros(0), np.zeros(0, bool), 0, 0, 0.0, "")
    s = {k: sum(p[k] for p in parts) for k in _SUMMED}
    if all(STACK_CULLS in p for p in parts):
        s[STACK_CULLS] = sum(p[STACK_CULLS] for p in parts)
    if all(INSTANCE_OPS in p for p in parts):
        s[INSTANCE_OPS] = sum(p[INSTANCE_OPS] for p in parts)
        s[INSTANCE_OPS + "_per_ray"] = s[INSTANCE_OPS] / s["rays"] if s["rays"] else 0.0
    n, cycles, wall = s["rays"], s["cycles"], s["sim_wall_s"]
    s.update({
        "utilization": s["ops"] / cycles if cycles else 0.0,
        "latency_cycles": parts[0]["latency_cycles"],
        "box_ops_per_ray": s["box_ops"] / n if n else 0.0,
        "tri_ops_per_ray": s["tri_ops"] / n if n else 0.0,
        "sim_cycles_per_s": cycles / wall if wall > 0 else 0.0,
        "frame_us_at_1ghz": cycles / 1000,
        "backend": parts[0]["backend"],
    })
    return {k: s[k] for k in parts[0] if k in s} | {k: v for k, v in s.items()
                                                   if k not in parts[0]}
