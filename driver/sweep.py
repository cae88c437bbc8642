"""``rayflex sweep``: a grid of design points on one workload.

Every design-point option (``driver.design``) takes a comma-separated list; the grid is every
combination. What each point costs:

1. The functional trace: the workload's hits and datapath requests do not depend on the RT unit,
   so the frame is traced once per distinct (BVH options, workload options) on the "rtl" backend
   of the first configuration listed, every wavefront recorded (``driver.tracing.record.Record``).
2. Per point, the frame's recorded batches are replayed on the point's RT units and memory
   hierarchy (``driver.rtunit.gpu.replay_point``: ``rtunit_memory``; with ``ideal`` also
   ``rtunit``, every node fetch free), on the RTL of the point's datapath configuration and
   latency. Every replayed response is compared bit for bit with the functional trace's, so each
   configuration is checked against the one that traced the frame, on the frame's requests.
3. Energy per ray: each ray type's box and triangle ops times the configuration's energy per op
   as ``rayflex power`` measures it (``driver.power``): level ``signals`` always, level
   ``gates`` when that configuration's gate netlist is in the cache (a synthesis takes minutes);
   and the node fetches' energy per memory level (``memory_pj``, ``driver.rtunit.energy``).

4. With ``unit`` (``rayflex sweep --backend rtunit``) each point's frame also runs through the
   RT unit in RTL (``driver.backends.rtunit``) with the point's ray slots, stack depth and
   memory hierarchy: its ``unit_rtl`` (docs/rtunit_rtl.md), every ray checked against the Python
   traversal and the replay with the unit's costs timed beside it (``replay_cycles_ratio``).

Points are independent tasks: with ``workers`` > 1 or a Dask ``scheduler`` they run on the
cluster code of ``driver.tiles`` (records scattered once). Each finished point is appended to a
results file (JSON lines keyed by the point and the source tree's version and commit,
``results``); a sweep started again with the same file skips the points found there, so an
interrupted sweep resumes where it stopped.

The document (``sweep``): ``provenance``, the ``grid`` (the options that vary), the functional
traces, the energy per op used, and one entry per point: its design point, its frame statistics
(docs/statistics.md) with ``energy_per_ray`` and ``by_type``, and its wall time. ``rows`` flattens
it to one row per point x ray type (the CSV); ``plot`` draws utilization vs rays in flight per
cache size and energy per ray vs RT-unit cycles per ray.
"""

from __future__ import annotations

import csv
import json
import os
import sys
import time
import uuid
from dataclasses import dataclass, fields
from pathlib import Path

from . import backends, design, power, workloads
from .backends.rtunit import UNIT_BACKEND, UNIT_OPTIONS
from .core.outputs import jsonable
from .design import DesignPoint
from .plotting import describe, wrap
from .core.progress import bar as progress_bar
from .core.progress import phase
from .rtunit.gpu import replay_point, waves_of
from .stats import merge, public
from .core.provenance import git_commit, provenance, rayflex_version
from .core.words import cell, plural
from .power.report import UNITS
from .power.stimulus import box_op
from .tiles import _client
from .tracer import trace
from .core.layout import FORMATS

ENERGY_LEVELS = ("signals", "gates")
# the options that make the functional trace (everything else is replayed)
FUNCTIONAL = ("scene", "workload", "size", "spp", "bounces", "ao_rays", "seed", "bvh_fill",
              "bvh_format", "flatten", "transform", "cull_stack")


def functional_key(point: DesignPoint) -> tuple:
    return tuple(getattr(point, k) for k in FUNCTIONAL)


@dataclass
class Trace:
    """The functional trace of one workload: per ray type its statistics (counts and the
    wavefront, docs/statistics.md), its recorded batches in trace order (``waves``, each ray's
    thread and program slot with them), the configuration and latency it was traced on, and
    its wall time."""

    by_type: dict
    waves: list
    config: str
    latency: int
    width: int
    wall_s: float


def trace_workload(point: DesignPoint, progress: bool = True) -> Trace:
    """Trace ``point``'s workload on the "rtl" backend of its datapath, every wavefront
    recorded."""
    from .scenes.scene import load_scene

    t0 = time.perf_counter()
    scene = point.scene_of(load_scene(point.scene))
    size = point.size or scene.size[0]
    rtl = backends.backend("rtl", **point.backend_options())
    with phase(f"building the BVH4 of {len(scene.triangles):,} triangles", progress):
        bvh = point.build(scene)
    setup = workloads.setup_for(scene)

    def tracer(bvh_, o, d, **kw):
        return trace(bvh_, o, d, backend=rtl, record=True, cull_stack=point.cull_stack, **kw)

    with phase(f"tracing {point.workload} {size}x{size} on {point.config}", progress):
        res = workloads.run(setup, bvh, size, size, tracer, point.workload,
                            **point.workload_options())
    by_type = public(res.stats)["by_type"]
    return Trace(by_type, waves_of(res.batches), point.config, point.latency, size,
                 time.perf_counter() - t0)


def measure_point(point: DesignPoint, waves: list, width: int, ideal: bool = False,
                  unit: bool = False) -> dict:
    """The RT-unit figures of one design point (a task: pure in its inputs): the frame's and
    each ray type's (``driver.rtunit.gpu.replay_point``), with ``unit`` the frame through the
    RT unit in RTL (``unit_frame``), and the point's wall time."""
    t0 = time.perf_counter()
    out = replay_point(waves, point, width, ideal)
    if unit:
        out["unit_rtl"] = unit_frame(point, width)
    return {**out, "wall_s": time.perf_counter() - t0}


def unit_frame(point: DesignPoint, width: int) -> dict:
    """``point``'s frame (``width`` square) through the RT unit in RTL: its ``unit_rtl``
    (docs/rtunit_rtl.md), every ray checked against the Python traversal on the same datapath."""
    from .render import render

    be = backends.backend(UNIT_BACKEND, **point.backend_options(UNIT_BACKEND))
    res = render(point.scene, width, width, backend=be, progress=False, point=point)
    return res.stats["unit_rtl"]


# the RT-unit options the replay models and the unit in RTL does not (one RT unit, one-kernel
# order of rays by index): a unit point keeps their defaults; the replay's own switches aside
_REPLAY_ONLY = ("rt_preset", "ray_window", "replay_datapath", "unit_costs")


def check_unit_points(points) -> None:
    """Refuse (ValueError, one line, before any work) a point the RT unit in RTL cannot run:
    a ray count, stack depth or node format it cannot take, or a setting only the replay
    models."""
    for p in points:
        p.backend_options(UNIT_BACKEND)
        for o in design.OPTIONS:
            if (o.group == "rtunit" and o.name not in UNIT_OPTIONS and o.name not in _REPLAY_ONLY
                    and getattr(p, o.name) != o.default):
                raise ValueError(f"{o.flag} {getattr(p, o.name)} is a setting of the RT-unit "
                                 f"replay, which the RT unit in RTL does not model: drop it or "
                                 f"--backend {UNIT_BACKEND} (docs/rtunit_rtl.md)")


# ---------------------------------------------------------------------------------------------
# energy per op (driver.power)

def energy_tables(points, progress: bool = True) -> dict:
    """Energy per box and triangle op of every (configuration, latency) of ``points`` (a q8
    image's box op: box_q8 or box_q8_host, ``_box_op``): {"CONFIG@LATENCY": {level: {"box": e,
    "triangle": e, ["box_q8" or "box_q8_host": e,] "unit": unit} or None}}; level ``gates``
    only for configurations whose gate netlist is cached (at the netlist's latency)."""
    out: dict = {}
    for cfg, lat in sorted({(p.config, p.latency) for p in points}):
        entry = out[energy_key(cfg, lat)] = {lvl: None for lvl in ENERGY_LEVELS}
        ops = tuple(dict.fromkeys(["box", "triangle", *(_box_op(p) for p in points
                                                        if p.config == cfg)]))
        with phase(f"energy per op of {cfg} (signals)", progress):
            r = power.run_level("signals", [cfg], latency=lat, ops=ops)
        entry["signals"] = _per_op(r["configs"][cfg], UNITS["signals"])
        if lat == power.own_latency(cfg) and power.netlist_cached(cfg):
            with phase(f"energy per op of {cfg} (gates)", progress):
                r = power.run_level("gates", [cfg], ops=ops)
            entry["gates"] = _per_op(r["configs"][cfg], UNITS["gates"])
    return out


def models(points) -> list[tuple[str, dict]]:
    """The RTL models a sweep of ``points`` runs, as ``driver.power.uncached_models`` takes
    them: each point's rtl harness (its datapath's ``rtl_params``) and the traced model of
    each (configuration, latency) that ``energy_tables`` measures (``power.params_of``, the
    parameters ``run_level`` builds it with)."""
    out = []
    for p in points:
        for model in (("rtl", p.rtl_params()), ("signals", power.params_of(p.config, p.latency))):
            if model not in out:
                out.append(model)
    return out


def energy_key(config: str, latency: int) -> str:
    return f"{config}@{latency}"


def _box_op(p: DesignPoint) -> str:
    """The operation a box node of point ``p``'s frame is (``stimulus.box_op``: box, or for a
    q8 image box_q8 / box_q8_host, decoded by the datapath / the host)."""
    return box_op({"COMPRESSED": p.compressed}, FORMATS[p.bvh_format].compressed)


def _per_op(measured: dict, unit: str) -> dict:
    return {**{op: r["energy_per_op"] for op, r in measured.items()
               if isinstance(r, dict) and "energy_per_op" in r}, "unit": unit}


def energy_per_ray(counts: dict, table: dict | None, box_op: str = "box"):
    """Energy per ray of a frame's ``counts`` with the energies per op of ``table`` (``box_op``:
    the operation its box ops are, ``_box_op``); its TRANSFORM ops are priced when the table has
    a ``transform`` energy (a TRANSFORM configuration). None without a table, without rays, or
    with TRANSFORM ops and no energy for them."""
    xf = counts.get("transform_ops") or 0
    if not table or not counts["rays"] or (xf and "transform" not in table):
        return None
    return (counts["box_ops"] * table[box_op] + counts["tri_ops"] * table["triangle"]
            + (xf * table["transform"] if xf else 0)) \
        / counts["rays"]


# ---------------------------------------------------------------------------------------------
# the results file (resume)

def load_results(path: Path) -> dict:
    """Finished points of an earlier run of this source tree (same version and commit):
    {point key: result}; a torn last line (an interrupted write) is ignored."""
    done = {}
    if path is None or not path.is_file():
        return done
    source = _source()
    for line in path.read_text().splitlines():
        try:
            entry = json.loads(line)
            if entry["source"] == source:
                done[entry["key"]] = entry["result"]
        except (ValueError, KeyError, TypeError):
            continue
    return done


def _source() -> list:
    return [rayflex_version(), git_commit()]


def _append(path: Path, key: str, result: dict) -> None:
    with open(path, "a") as f:
        f.write(json.dumps({"key": key, "source": _source(), "result": jsonable(result)})
                + "\n")
        f.flush()
        os.fsync(f.fileno())


# ---------------------------------------------------------------------------------------------
# the sweep

def sweep(points: list[DesignPoint], workers: int = 1, scheduler: str | None = None,
          results: Path | None = None, progress: bool = True, ideal: bool = False,
          unit: bool = False) -> dict:
    """Measure every design point (see the module docstring); returns the document. ``unit``:
    also each point's frame through the RT unit in RTL (points measured without it are measured
    again)."""
    t0 = time.perf_counter()
    results = Path(results) if results else None
    done = load_results(results)
    if unit:                            # a point measured without the unit is measured again
        done = {k: r for k, r in done.items() if "unit_rtl" in r}
    todo = [p for p in points if p.key() not in done]
    if done and progress:
        print(f"rayflex: sweep: {len(points) - len(todo)} of {plural(len(points), 'point')} "
              f"already done in {results}, {len(todo)} to measure", flush=True,
              file=_stderr())
    traces: dict = {}
    groups: dict = {}
    for p in points:
        groups.setdefault(functional_key(p), []).append(p)
    for key, pts in groups.items():             # every point's counts come from its trace
        traces[key] = trace_workload(pts[0], progress)
    energies = energy_tables(points, progress)
    bar = progress_bar(len(todo), f"sweep: {len(points)} design points", "point", progress)
    bar.hook(0, len(todo))
    for n, (p, result) in enumerate(_run(todo, traces, workers, scheduler, ideal, unit), 1):
        done[p.key()] = result
        if results:
            _append(results, p.key(), result)
        bar.hook(n, len(todo))
    bar.close()
    entries = [_entry(p, done[p.key()], traces[functional_key(p)], energies) for p in points]
    first = traces[functional_key(points[0])]
    return {
        "provenance": provenance(None),
        "scene": points[0].scene,
        "workload": points[0].workload,
        "grid": {k: list(dict.fromkeys(getattr(p, k) for p in points))
                 for k in design.varied(points)},
        "functional": [{"design_point": {k: v for k, v in zip(FUNCTIONAL, key)},
                        "config": t.config, "latency_cycles": t.latency, "width": t.width,
                        "height": t.width, "wall_s": t.wall_s, "by_type": t.by_type}
                       for key, t in traces.items()],
        "energy_per_op": energies,
        "bit_exact": {c: all(e["rtunit_memory"]["responses_verified"] is not False
                             and (e["rtunit"] is None
                                  or e["rtunit"]["responses_verified"] is not False)
                             and not (e.get("unit_rtl") or {}).get("traversal_mismatches")
                             for e in entries if e["design_point"]["config"] == c)
                      for c in sorted({p.config for p in points})},
        "traced_on": first.config,
        "points": entries,
        "wall_s": time.perf_counter() - t0,
    }


def _stderr():
    return sys.stderr


def _run(todo, traces, workers, scheduler, ideal=False, unit=False):
    """(point, result) of every point to measure, in this process or on Dask."""
    if not todo:
        return
    if workers == 1 and not scheduler:
        for p in todo:
            t = traces[functional_key(p)]
            yield p, measure_point(p, t.waves, t.width, ideal, unit)
        return
    with _client(workers, scheduler) as client:
        recs = {k: client.scatter(t.waves, broadcast=True) for k, t in traces.items()}
        run_id = uuid.uuid4().hex[:12]
        futures = {client.submit(measure_point, p, recs[functional_key(p)],
                                 traces[functional_key(p)].width, ideal, unit,
                                 key=f"rayflex-sweep-{run_id}-{i}", retries=3): p
                   for i, p in enumerate(todo)}
        from distributed import as_completed
        try:
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        finally:
            client.cancel(list(futures))


def _entry(p: DesignPoint, result: dict, trace: Trace, energies: dict) -> dict:
    """A point's frame statistics: the functional counts with its RT-unit replays and energy."""
    key = energy_key(p.config, p.latency)
    bop = _box_op(p)
    by_type = {}
    for kind, counts in trace.by_type.items():
        e = dict(counts)
        e["rtunit"] = result["by_type"][kind]["rtunit"]
        e["rtunit_memory"] = result["by_type"][kind]["rtunit_memory"]
        e["energy_per_ray"] = {lvl: energy_per_ray(counts, energies[key][lvl], bop)
                               for lvl in ENERGY_LEVELS}
        e["energy_per_ray"]["memory_pj"] = _memory_pj(e["rtunit_memory"])
        by_type[kind] = e
    total = _totals(trace.by_type, merge)
    total["rtunit"], total["rtunit_memory"] = result["rtunit"], result["rtunit_memory"]
    total["energy_per_ray"] = {lvl: energy_per_ray(total, energies[key][lvl], bop)
                               for lvl in ENERGY_LEVELS}
    total["energy_per_ray"]["memory_pj"] = _memory_pj(total["rtunit_memory"])
    if "unit_rtl" in result:
        total["unit_rtl"] = result["unit_rtl"]
    return {"design_point": p.as_dict(), **total, "by_type": by_type, "wall_s": result["wall_s"]}


def _memory_pj(obj: dict | None):
    """Energy of the node fetches per ray (pJ; ``driver.rtunit.energy``), or None."""
    return obj["memory_energy"]["per_ray"] if obj and "memory_energy" in obj else None


def _totals(by_type: dict, merge) -> dict:
    """The frame's counts and wavefront from its ray types' (public schema)."""
    flat = []
    for t in by_type.values():
        f = {k: v for k, v in t.items() if k not in ("wavefront", "embree")}
        f.update(t["wavefront"])
        flat.append(f)
    return public(merge(flat))


# ---------------------------------------------------------------------------------------------
# outputs

ROW_FIELDS = ("ray_type", "rays", "hits", "box_ops", "tri_ops", "transform_ops", "ops",
              "box_ops_per_ray",
              "tri_ops_per_ray", "rtunit_cycles", "rtunit_utilization", "rtunit_cycles_per_ray",
              "rtunit_memory_cycles", "rtunit_memory_utilization", "rtunit_memory_cycles_per_ray",
              "frame_cycles", "frame_utilization", "latency_mean", "latency_p95",
              "hit_rate", "bytes_per_ray", "l1_bytes_per_ray", "l2_bytes_per_ray",
              "dram_bytes_per_ray", "energy_per_ray_signals", "energy_per_ray_gates",
              "energy_per_ray_memory_pj", "unit_rtl_cycles", "unit_rtl_utilization",
              "unit_rtl_replay_cycles_ratio", "responses_verified", "wall_s")


def rows(doc: dict) -> list[dict]:
    """One row per point x ray type: the design point's options, then ``ROW_FIELDS`` (the
    ray type's ``rtunit``/``rtunit_memory`` keys; ``frame_*``: the frame's replay with the
    memory hierarchy, the same in each row of a point)."""
    out = []
    for e in doc["points"]:
        fm = e["rtunit_memory"] or {}
        u = e.get("unit_rtl") or {}
        for kind, t in e["by_type"].items():
            r, m = t["rtunit"] or {}, t["rtunit_memory"] or {}
            served = m.get("bytes_served_per_ray", {})
            out.append({**e["design_point"], "ray_type": kind,
                        **{k: t[k] for k in ("rays", "hits", "box_ops", "tri_ops", "ops",
                                             "box_ops_per_ray", "tri_ops_per_ray")},
                        "transform_ops": t.get("transform_ops"),      # instanced scenes
                        "rtunit_cycles": r.get("cycles"),
                        "rtunit_utilization": r.get("utilization"),
                        "rtunit_cycles_per_ray": r.get("cycles_per_ray"),
                        "rtunit_memory_cycles": m.get("cycles"),
                        "rtunit_memory_utilization": m.get("utilization"),
                        "rtunit_memory_cycles_per_ray": m.get("cycles_per_ray"),
                        "frame_cycles": fm.get("cycles"),
                        "frame_utilization": fm.get("utilization"),
                        "latency_mean": m.get("latency_mean"),
                        "latency_p95": m.get("latency_p95"),
                        "hit_rate": m.get("hit_rate"), "bytes_per_ray": m.get("bytes_per_ray"),
                        "l1_bytes_per_ray": served.get("l1"),
                        "l2_bytes_per_ray": served.get("l2"),
                        "dram_bytes_per_ray": served.get("dram"),
                        "energy_per_ray_signals": t["energy_per_ray"]["signals"],
                        "energy_per_ray_gates": t["energy_per_ray"]["gates"],
                        "energy_per_ray_memory_pj": t["energy_per_ray"]["memory_pj"],
                        "unit_rtl_cycles": u.get("cycles"),
                        "unit_rtl_utilization": u.get("utilization"),
                        "unit_rtl_replay_cycles_ratio": u.get("replay_cycles_ratio"),
                        "responses_verified": (not r or r["responses_verified"])
                        and (not m or m["responses_verified"]),
                        "wall_s": e["wall_s"]})
    return out


def write_csv(doc: dict, path) -> None:
    header = [f.name for f in fields(DesignPoint)] + list(ROW_FIELDS)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header)
        w.writeheader()
        for r in rows(doc):
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})


def _timing(e: dict) -> dict:
    """A point's RT-unit figures with its node memory, or without when it has none."""
    return e["rtunit_memory"] or e["rtunit"]


def plot(doc: dict, path) -> None:
    """Two panels: the frame's utilization vs rays in flight, one line per (cache size, other
    varied options), lines with the same values merged into one whose label says so (two
    configurations with the same timing coincide); the node fetches' energy per ray vs RT-unit
    cycles per ray, one marker per point, one colour per configuration (its datapath energy per
    ray in the legend), both axes from zero. Legends below the data; the title names the frame
    and the options every point shares."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pts = doc["points"]
    others = [k for k in doc["grid"] if k not in ("rays_in_flight",)]
    fig = Figure(figsize=(12.0, 5.6), dpi=110)
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    lines: dict = {}
    for e in pts:
        dp = e["design_point"]
        label = ", ".join(f"{k} {dp[k]}" for k in others) or "this point"
        lines.setdefault(label, []).append((dp["rays_in_flight"], _timing(e)["utilization"],
                                            dp["cache_kib"]))
    merged: dict = {}                                  # identical series: one line, both named
    for label, xs in lines.items():
        merged.setdefault(tuple(sorted(xs)), []).append(label)
    markers = ("o", "s", "^", "D", "v", "P", "X", "*")
    for i, (xs, labels) in enumerate(merged.items()):
        ax1.plot([x[0] for x in xs], [x[1] for x in xs], marker=markers[i % len(markers)],
                 ls="-" if xs[0][2] else "--", color=f"C{i}",
                 label=" = ".join(labels) + (" (identical)" if len(labels) > 1 else ""))
    ax1.set_xscale("log", base=2)
    ax1.set_ylim(0, 1.05)
    ax1.set_xlabel("rays in flight (ray pool size)")
    ax1.set_ylabel("datapath utilization, ops / (pipelines x cycles)")
    ax1.set_title("the frame's RT-unit utilization with the memory hierarchy (dashed: no node "
                  "cache)", fontsize=8)
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=1,
               frameon=False)
    configs = sorted({e["design_point"]["config"] for e in pts})
    for i, cfg in enumerate(configs):
        sel = [e for e in pts if e["design_point"]["config"] == cfg
               and e["energy_per_ray"]["memory_pj"] is not None]
        dp_energy = {e["energy_per_ray"]["signals"] for e in sel} - {None}
        label = cfg + (f" (datapath {min(dp_energy):,.0f}" + (
            f"-{max(dp_energy):,.0f}" if len(dp_energy) > 1 else "") + " toggles/ray)"
                       if dp_energy else "")
        for cached in (True, False):
            part = [e for e in sel if bool(e["design_point"]["cache_kib"]) == cached]
            ax2.scatter([_timing(e)["cycles_per_ray"] for e in part],      # coinciding points
                        [e["energy_per_ray"]["memory_pj"] for e in part],   # stay visible:
                        s=max(70 - 30 * i, 16), edgecolors=f"C{i}",         # larger, hollow
                        facecolors=f"C{i}" if i % 2 else "none", linewidths=1.5,
                        marker="o" if cached else "s",
                        label=label if cached or not any(
                            bool(e["design_point"]["cache_kib"]) for e in sel) else None)
    ax2.set_xlabel("RT-unit cycles per ray (with the memory hierarchy)")
    ax2.set_ylabel("node fetches' energy per ray (pJ; docs/rtunit.md)")
    ax2.set_title("memory-side energy per ray vs time per ray (squares: no node cache)",
                  fontsize=8)
    energies = [e["energy_per_ray"]["memory_pj"] for e in pts]
    ax2.set_ylim(0, 1.1 * max([v for v in energies if v is not None] or [1.0]))  # markers whole
    ax2.set_xlim(0, 1.1 * max(_timing(e)["cycles_per_ray"] for e in pts))
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False,
               ncol=max(1, len(configs)))
    varied_keys = set(doc["grid"]) | {"rays_in_flight"}
    point = dict(pts[0]["design_point"])
    fig.suptitle(wrap(f"{len(pts)} design points: " + describe(point, omit=varied_keys), 150),
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(str(path), format="png")


def table(doc: dict) -> str:
    """One line per point and ray type, then the point's frame (all rays): the varied options,
    rays, ops per ray, utilization with the memory hierarchy (a ray type's only in a wavefront
    frame; with free node fetches when replayed, ``--ideal-replay``), mean latency, bytes from
    DRAM per ray, the datapath's energy and the node fetches' energy per ray."""
    keys = list(doc["grid"])
    unit = any("unit_rtl" in e for e in doc["points"])
    head = " ".join(f"{k:>18}" for k in keys) + \
        f" {'type':>8} {'rays':>6} {'ops/ray':>7} {'util':>6} {'ideal':>6} {'latency':>8} " \
        f"{'B/ray':>6} {'E/ray':>9} {'mem pJ/ray':>10}" + \
        (f" {'unit cycles':>11} {'unit util':>9} {'replay/unit':>11}" if unit else "")
    out = [head]
    for e in doc["points"]:
        cells = " ".join(f"{str(e['design_point'][k]):>18}" for k in keys)
        for kind, t in [*e["by_type"].items(), ("all", e)]:
            m = t["rtunit_memory"] or {}
            energy = t["energy_per_ray"]
            out.append(f"{cells} {kind:>8} {t['rays']:>6} {t['ops'] / max(t['rays'], 1):>7.2f} "
                       f"{cell(m.get('utilization'), '.3f'):>6} "
                       f"{cell((t['rtunit'] or {}).get('utilization'), '.3f'):>6} "
                       f"{cell(m.get('latency_mean'), '.0f'):>8} "
                       f"{cell(m.get('bytes_per_ray'), '.0f'):>6} "
                       f"{cell(energy['signals'], '.0f'):>9} "
                       f"{cell(energy['memory_pj'], '.0f'):>10}" + (_unit_cells(t) if unit else ""))
    out.append("(per ray type, then all rays of the point; util / ideal: utilization with the "
               "memory hierarchy / with free node fetches (--ideal-replay), a ray type's only "
               "in a wavefront frame; -: none; latency: mean cycles from the trace call to the "
               "ray's last response; B/ray: bytes from DRAM per ray; E/ray: datapath energy "
               "per ray in bit toggles; mem pJ/ray: node fetches, docs/rtunit.md; "
               + ("unit cycles, unit util: the frame on the RT unit in RTL, replay/unit: the "
                  "replay's cycles with the unit's costs over the unit's, docs/rtunit_rtl.md; "
                  if unit else "") + "docs/statistics.md)")
    return "\n".join(out)


def _unit_cells(t: dict) -> str:
    """The RT unit in RTL's columns of a table line (the frame's line only)."""
    u = t.get("unit_rtl") or {}
    return (f" {cell(u.get('cycles'), ','):>11} {cell(u.get('utilization'), '.3f'):>9} "
            f"{cell(u.get('replay_cycles_ratio'), '.3f'):>11}")
