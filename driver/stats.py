"""Frame statistics: built once here, merged once here, published once here (docs/statistics.md).

``frame_stats`` turns a traversal's per-ray op counts and the backend's cycles into the flat
dictionary of a ``TraceResult``; ``with_replay`` merges an RT-unit replay's timing into it (the
wavefront's own timing kept as ``wavefront_*``; the Python API of ``driver.tracer.trace``).

What the commands write (render, bench, sweep JSON) is the schema of docs/statistics.md, made
by ``public``: the functional counts flat, the timing of the ideal pipeline (every ray in
flight, one pipeline, cycles as the backend counts them) under ``wavefront``, and the RT-unit
replays (``driver.rtunit``) under ``rtunit`` (node fetches free) and ``rtunit_memory`` (with the
node cache and memory; null without one), each ray type's the same under ``by_type``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import rtunit
from .core.layout import BOX_BYTES, TRI_BYTES
from .rtunit.order import merge_costs

STACK_CULLS = "stack_culls"     # box nodes a distance-culled stack dropped
INSTANCE_OPS = "instance_ops"   # instances entered (two-level images; docs/instances.md)
TRANSFORM_OPS = "transform_ops"  # TRANSFORM requests (the instance transform on the datapath)
# the replay's figures that replace the wavefront's (which are kept as wavefront_<name>)
REPLAYED = ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s")
# the replay's own figures that join the frame's statistics
REPLAY_KEYS = ("frame_us_at_1ghz", "rays_in_flight", "pipelines", "turnaround_cycles",
               "starved_cycles", "responses_verified", "latency_cycles", "per_pipeline_ops")


def frame_stats(box_ops: np.ndarray, tri_ops: np.ndarray, hit: np.ndarray, cycles: int,
                latency: int, sim_wall_s: float, backend: str,
                culled: np.ndarray | None = None, node_bytes: np.ndarray | None = None,
                instance_ops: np.ndarray | None = None,
                transform_ops: np.ndarray | None = None) -> dict:
    """Statistics of a traversal: per-ray op counts (n,), hit mask (n,), the datapath
    cycles it took, the pipeline latency, the wall time inside the backend, the backend's name;
    with ``culled`` (per-ray box nodes dropped by a distance-culled stack, ``driver.traversal``)
    also ``stack_culls``, their total (absent when the traversal does not cull); ``node_bytes``
    (n,) per-ray node bytes fetched (default: a box32 image's, 128 B per box op and 64 B per
    triangle op); ``instance_ops`` (n,) per-ray instances entered (a two-level image): adds
    ``instance_ops`` and ``instance_ops_per_ray``, and ``transform_ops`` and
    ``transform_ops_per_ray`` from ``transform_ops`` (n,), the TRANSFORM requests of the
    instance transform on the datapath (default none); those are datapath ops like the box and
    triangle ops (``ops`` is the sum of the three)."""
    n = len(box_ops)
    nb, nt = int(np.sum(box_ops)), int(np.sum(tri_ops))
    nx = 0 if transform_ops is None else int(np.sum(transform_ops))
    ops = nb + nt + nx
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
        out[TRANSFORM_OPS] = nx
        out[TRANSFORM_OPS + "_per_ray"] = nx / n if n else 0.0
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


# summed over the parts of a frame; the rest is derived from the sums
_SUMMED = ("rays", "hits", "box_ops", "tri_ops", "ops", "cycles", "node_bytes_fetched",
           "sim_wall_s")


def merge(parts: list[dict]) -> dict:
    """Statistics of several traversals taken together (ray types, bounces, tiles): counts,
    cycles and wall times add up (each traversal is its own wavefront: the datapath runs them one
    after another); the ratios are recomputed from the sums."""
    if not parts:
        return frame_stats(np.zeros(0), np.zeros(0), np.zeros(0, bool), 0, 0, 0.0, "")
    s = {k: sum(p[k] for p in parts) for k in _SUMMED}
    if all(STACK_CULLS in p for p in parts):
        s[STACK_CULLS] = sum(p[STACK_CULLS] for p in parts)
    for key in (INSTANCE_OPS, TRANSFORM_OPS):
        if all(key in p for p in parts):
            s[key] = sum(p[key] for p in parts)
            s[key + "_per_ray"] = s[key] / s["rays"] if s["rays"] else 0.0
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
    for key in (RTUNIT, RTUNIT_MEMORY):
        if all(key in p for p in parts):
            s[key] = merge_rtunit([p[key] for p in parts])
    return {k: s[k] for k in parts[0] if k in s} | {k: v for k, v in s.items()
                                                   if k not in parts[0]}


# ---------------------------------------------------------------------------------------------
# the published schema (docs/statistics.md)

WAVEFRONT, RTUNIT, RTUNIT_MEMORY = "wavefront", "rtunit", "rtunit_memory"
WAVEFRONTS = "wavefronts"      # an RT-unit object's replayed wavefronts, in the order they ran
# the wavefront's timing figures (flat in a TraceResult's statistics, an object when published)
WAVEFRONT_KEYS = ("cycles", "utilization", "frame_us_at_1ghz", "sim_wall_s", "sim_cycles_per_s")
# RT-unit figures added up over replays run one after another
_RT_SUMMED = ("rays", "ops", "cycles", "starved_cycles", "sim_wall_s")
_MEM_SUMMED = ("line_accesses", "line_hits", "line_misses", "bytes_from_memory",
               "node_wait_cycles")


def public(stats: dict) -> dict:
    """Flat traversal statistics (a ``TraceResult``'s or ``merge``'s, ``by_type`` included) in
    the published schema: the wavefront's timing moved under ``wavefront``; an RT-unit object
    already present is kept."""
    out = {k: v for k, v in stats.items() if k not in WAVEFRONT_KEYS and k != "by_type"
           and not k.startswith("wavefront_")}
    src = {k: stats.get("wavefront_" + k, stats.get(k)) for k in WAVEFRONT_KEYS}
    out[WAVEFRONT] = src
    if "by_type" in stats:
        out["by_type"] = {k: public(v) for k, v in stats["by_type"].items()}
    return out


def rtunit_stats(replays: list) -> dict:
    """The ``rtunit`` (or, replays with a memory model, ``rtunit_memory``) object of replays
    (``driver.rtunit.ReplayResult``) of wavefronts that run one after another: cycles add up
    (each wavefront starts with an empty ray pool and a cold node cache)."""
    if not replays:
        raise ValueError("no replay")
    first = replays[0]
    out = {"rays_in_flight": first.rays_in_flight, "pipelines": first.pipelines,
           "turnaround_cycles": first.turnaround, "rays": sum(r.rays for r in replays),
           "ops": sum(r.ops for r in replays), "cycles": sum(r.cycles for r in replays),
           "starved_cycles": sum(r.starved_cycles for r in replays),
           "sim_wall_s": sum(r.wall_s for r in replays),
           "responses_verified": all(r.verified for r in replays)}
    if first.memory:
        for k in _MEM_SUMMED:
            out[k] = sum(r.memory[k] for r in replays)
    out[WAVEFRONTS] = [_wavefront_row(r) for r in replays]
    costs = [r.order for r in replays if getattr(r, "order", None)]
    if costs:
        out["ray_order_cost"] = merge_costs(costs)
    return _rt_derived(out)


def _wavefront_row(r) -> dict:
    """One replayed wavefront of an RT-unit object's ``wavefronts``: its size and timing, and
    with a node memory its bytes from memory (each wavefront starts with an empty ray pool and
    a cold node cache, so a small one is bound by the memory's latency)."""
    row = {"rays": r.rays, "ops": r.ops, "cycles": r.cycles, "utilization": r.utilization}
    if r.memory:
        row["bytes_from_memory"] = r.memory["bytes_from_memory"]
    return row


def _rt_derived(s: dict) -> dict:
    cyc, n = s["cycles"], s["rays"]
    s["utilization"] = s["ops"] / (s["pipelines"] * cyc) if cyc else 0.0
    s["frame_us_at_1ghz"] = cyc / 1000
    s["cycles_per_ray"] = cyc / n if n else 0.0
    if "line_accesses" in s:
        acc = s["line_accesses"]
        s["hit_rate"] = s["line_hits"] / acc if acc else 0.0
        s["bytes_per_ray"] = s["bytes_from_memory"] / n if n else 0.0
    return s


def merge_rtunit(parts: list) -> dict | None:
    """RT-unit objects of parts run one after another (ray types, tiles), taken together."""
    if not parts or any(p is None for p in parts):
        return None
    out = {k: parts[0][k] for k in ("rays_in_flight", "pipelines", "turnaround_cycles")}
    keys = _RT_SUMMED + (_MEM_SUMMED if "line_accesses" in parts[0] else ())
    out.update({k: sum(p[k] for p in parts) for k in keys})
    out["responses_verified"] = all(p["responses_verified"] for p in parts)
    if all(WAVEFRONTS in p for p in parts):
        out[WAVEFRONTS] = [w for p in parts for w in p[WAVEFRONTS]]
    if all("ray_order_cost" in p for p in parts):
        out["ray_order_cost"] = merge_costs([p["ray_order_cost"] for p in parts])
    return _rt_derived(out)


def replay_stats(records: list, point, plain: bool = True) -> tuple[dict | None, dict | None]:
    """(``rtunit``, ``rtunit_memory``) of recorded wavefronts (``driver.tracing.record.Record``)
    replayed one after another on the RT unit of design point ``point``
    (``driver.design.DesignPoint``), without and with its node memory (``point.cache_kib`` 0: no
    cache). The records replay on the point's datapath configuration and latency; every response
    is checked against the recorded one bit for bit. ``plain`` False: no replay without the
    memory (``rtunit`` None), so that each request is simulated once more only."""
    params = point.rtl_params()
    recs = [r if r.params == params else replace(r, params=params) for r in records]
    order = point.order_options()
    plain = rtunit_stats([rtunit.replay(r, point.rays_in_flight, point.pipelines, **order)
                          for r in recs]) if plain else None
    memory = point.memory()
    mem = None if memory is None else rtunit_stats(
        [rtunit.replay(r, point.rays_in_flight, point.pipelines, memory=memory, **order)
         for r in recs])
    return plain, mem


def order_cost_line(c: dict) -> str:
    """What a ray-order policy costs in hardware (``ray_order_cost``, docs/rayorder.md), in
    the terms of docs/statistics.md."""
    parts = [f"{c['ray_order']}, window {c['ray_window']}"]
    if "sort_buffer_entries" in c:
        parts.append(f"sort buffer of {c['sort_buffer_entries']} rays, "
                     f"{c['sort_buffer_bytes']:,} bytes, {c['compare_exchanges_per_ray']:.1f} "
                     "compare-exchanges per ray")
    if "held_rays" in c:
        parts.append(f"{c['held_rays']} rays held ({c['extra_rays_held']} beyond the pool), "
                     f"{c['extra_state_bytes']:,} bytes of traversal state "
                     f"({c['traversal_state_bytes']} per ray)")
    if "queue_bytes" in c:
        parts.append(f"treelet queues {c['queue_bytes']:,} bytes, treelet table "
                     f"{c['treelet_table_bytes']:,} bytes")
    return "; ".join(parts)
