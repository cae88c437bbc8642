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

import numpy as np

from .core.layout import BOX_BYTES, TRI_BYTES
from .rtunit.gpu import derived
from .rtunit.order import merge_costs

STACK_CULLS = "stack_culls"     # box nodes a distance-culled stack dropped
INSTANCE_OPS = "instance_ops"   # instances entered (two-level images; docs/instances.md)
TRANSFORM_OPS = "transform_ops"  # TRANSFORM requests (the instance transform on the datapath)
# the replay's figures that replace the wavefront's (which are kept as wavefront_<name>)
REPLAYED = ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s")
# the replay's own figures that join the frame's statistics
REPLAY_KEYS = ("frame_us_at_1ghz", "rays_in_flight", "pipelines", "turnaround_cycles",
               "starved_cycles", "replay_datapath", "responses_verified", "latency_cycles",
               "per_pipeline_ops")


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
    if all(UNIT_RTL in p for p in parts):
        s[UNIT_RTL] = merge_unit_rtl([p[UNIT_RTL] for p in parts], s["ops"])
    return {k: s[k] for k in parts[0] if k in s} | {k: v for k, v in s.items()
                                                   if k not in parts[0]}


def unit_rtl_stats(res, be) -> dict:
    """The ``unit_rtl`` object of a batch run through the RT unit in RTL
    (``driver.backends.rtunit``: ``res`` its ``UnitResult``, ``be`` the backend)."""
    st = res.stats
    cycles = st["cycles"]
    out = {
        "cycles": cycles,
        "utilization": st["dp_requests"] / (be.pipelines * cycles) if cycles else 0.0,
        "rays_in_flight": be.rays_in_flight,
        "stack_depth": be.stack_depth,
        "memory": "hierarchy" if be.memory is not None else "fixed",
        "mem_latency": None if be.memory is not None else be.mem_latency,
        "max_stack_depth": st["max_stack_depth"],
        "stack_overflows": st["overflows"],
        "stack_refills": st["refill_reads"],
        "rays_overflowed": int(np.count_nonzero(res.overflows)),
        "cull_stack": be.cull,
        "stack_culls": int(np.sum(res.culled)),
        "mem_requests": st["mem_requests"],
        "mem_bytes": st["mem_bytes"],
        "mem_busy_cycles": st["mem_outstanding_cycles"],
        "busy_cycles": st["busy_cycles"],
        "dividers": be.dividers,
        "divider_busy_cycles": st["divider_busy_cycles"],
        "divider_full_cycles": st["divider_full_cycles"],
        "setups": be.setups,
        "setup_busy_cycles": st["setup_busy_cycles"],
        "pipelines": be.pipelines,
        "pipeline_requests": list(st["pipeline_requests"]),
        "pipeline_utilization": [n / cycles if cycles else 0.0
                                 for n in st["pipeline_requests"]],
        "skipped_cycles": st["skipped_cycles"],
        "reused_batches": int(getattr(res, "reused", False)),
    }
    if getattr(res, "activity", None) is not None:     # the traced unit (rayflex power)
        out[ACTIVITY] = res.activity
    return out


UNIT_RTL = "unit_rtl"
ACTIVITY = "activity"          # a traced unit's bit toggles per module, and its cycles
_UNIT_SUMMED = ("cycles", "stack_overflows", "stack_refills", "rays_overflowed", "stack_culls",
                "mem_requests",
                "mem_bytes", "mem_busy_cycles", "busy_cycles", "divider_busy_cycles",
                "divider_full_cycles", "setup_busy_cycles", "skipped_cycles", "reused_batches")


def merge_unit_rtl(parts: list[dict], ops: int) -> dict:
    """``unit_rtl`` objects of batches run one after another, taken together (``ops``: the
    datapath requests of all of them)."""
    out = dict(parts[0])
    out.update({k: sum(p[k] for p in parts) for k in _UNIT_SUMMED})
    out["max_stack_depth"] = max(p["max_stack_depth"] for p in parts)
    out["pipeline_requests"] = [sum(n) for n in zip(*(p["pipeline_requests"] for p in parts))]
    out["pipeline_utilization"] = [n / out["cycles"] if out["cycles"] else 0.0
                                   for n in out["pipeline_requests"]]
    for key in ("traversal_mismatches", "replay_cycles", "replay_default_cycles"):
        values = [p[key] for p in parts]
        out[key] = None if None in values else sum(values)
    for key in ("replay_cycles", "replay_default_cycles"):
        out[f"{key}_ratio"] = (None if out[key] is None or not out["cycles"]
                               else out[key] / out["cycles"])
    out["utilization"] = (ops / (out["pipelines"] * out["cycles"]) if out["cycles"]
                          else 0.0)
    if all(ACTIVITY in p for p in parts):
        acts = [p[ACTIVITY] for p in parts]
        out[ACTIVITY] = {"toggles": {k: sum(a["toggles"][k] for a in acts)
                                     for k in acts[0]["toggles"]},
                         "nets": acts[0]["nets"], "cycles": sum(a["cycles"] for a in acts)}
    return out


# ---------------------------------------------------------------------------------------------
# the published schema (docs/statistics.md)

WAVEFRONT, RTUNIT, RTUNIT_MEMORY = "wavefront", "rtunit", "rtunit_memory"
WAVEFRONTS = "wavefronts"      # an RT-unit object's replayed wavefronts, in the order they ran
# the wavefront's timing figures (flat in a TraceResult's statistics, an object when published)
WAVEFRONT_KEYS = ("cycles", "utilization", "frame_us_at_1ghz", "sim_wall_s", "sim_cycles_per_s")


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


# an RT-unit object's settings (the same in every part of a frame)
_RT_CONFIG = ("rays_in_flight", "pipelines", "turnaround_cycles", "frame_schedule", "rt_units",
              "warp_size", "warps_per_unit", "shader_cycles", "flush_between",
              "replay_datapath", "unit_costs")
# RT-unit figures added up over parts run one after another (tiles); null stays null
_RT_SUMMED = ("rays", "ops", "cycles", "frame_cycles", "kernels", "starved_cycles",
              "sim_wall_s", "line_accesses", "line_hits", "line_misses", "bytes_from_memory",
              "node_wait_cycles", "mshr_stalls", "mshr_stall_cycles")


def _sum(values):
    values = list(values)
    return None if any(v is None for v in values) else sum(values)


def merge_rtunit(parts: list) -> dict | None:
    """RT-unit objects (``driver.rtunit.gpu.FrameReplay.summary``/``type_summary``) of parts
    replayed one after another (tiles of a frame), taken together: counts and cycles add up,
    means are weighted by rays (or trace calls), ratios are recomputed; a per-ray percentile
    cannot be merged (null) and neither can the rays-in-flight series (left out)."""
    if not parts or any(p is None for p in parts):
        return None
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    out = {k: first[k] for k in _RT_CONFIG if k in first}
    out.update({k: _sum(p[k] for p in parts) for k in _RT_SUMMED if k in first})
    checked = [p["responses_verified"] for p in parts]
    out["responses_verified"] = None if None in checked else all(checked)
    rays = out["rays"]
    for k in ("latency_mean", "queue_mean"):
        if k in first:
            out[k] = (sum(p[k] * p["rays"] for p in parts) / rays) if rays else 0.0
    if "latency_p95" in first:
        out["latency_p95"] = None
    if "bytes_served" in first:
        out["bytes_served"] = {lvl: sum(p["bytes_served"][lvl] for p in parts)
                               for lvl in first["bytes_served"]}
        out["bytes_served_per_ray"] = {lvl: v / rays if rays else 0.0
                                       for lvl, v in out["bytes_served"].items()}
    if "levels" in first:
        out["levels"] = {}
        for lvl, d in first["levels"].items():
            merged = {k: sum(p["levels"][lvl][k] for p in parts) for k in d if k != "hit_rate"}
            if "hit_rate" in d:
                acc = merged["line_accesses"]
                merged["hit_rate"] = merged["line_hits"] / acc if acc else 0.0
            out["levels"][lvl] = merged
    if "simt" in first:
        ws = [p["simt"] for p in parts]
        calls = sum(w["trace_calls"] for w in ws)
        w = {"warps": sum(x["warps"] for x in ws), "trace_calls": calls,
             "simt_efficiency": (sum(x["simt_efficiency"] * x["trace_calls"] for x in ws)
                                 / calls) if calls else 0.0,
             "slowest_ray_wait_cycles": sum(x["slowest_ray_wait_cycles"] for x in ws),
             "max_rays_held": max(x["max_rays_held"] for x in ws)}
        w["slowest_ray_wait_per_call"] = w["slowest_ray_wait_cycles"] / calls if calls else 0.0
        span = sum(p.get("frame_cycles") or 0 for p in parts)
        w["rays_held_mean"] = (sum(x["rays_held_mean"] * (p.get("frame_cycles") or 0)
                                   for x, p in zip(ws, parts)) / span) if span else 0.0
        w["rays_held_series"] = None         # series of several dispatches are not one series
        out["simt"] = {k: w[k] for k in first["simt"]}
    if all(WAVEFRONTS in p for p in parts):
        out[WAVEFRONTS] = [w for p in parts for w in p[WAVEFRONTS]]
    if "unit_ops" in first:
        out["unit_ops"] = [sum(v) for v in zip(*(p["unit_ops"] for p in parts))]
    if all("ray_order_cost" in p for p in parts):
        out["ray_order_cost"] = merge_costs([p["ray_order_cost"] for p in parts])
    if "memory_energy" in first:
        e = {lvl: sum(p["memory_energy"][lvl] for p in parts) for lvl in ("l1", "l2", "dram",
                                                                            "total")}
        out["memory_energy"] = {**e, "per_ray": e["total"] / rays if rays else 0.0,
                                "unit": first["memory_energy"]["unit"]}
    for k in first:                       # every key of the parts' objects, null if unmerged
        out.setdefault(k, None)
    return derived({k: out[k] for k in first} | {k: v for k, v in out.items() if k not in first})


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
