"""``rayflex bench``: datapath throughput of a real frame and simulation speed (``driver.bench``)."""

from __future__ import annotations

import json
from pathlib import Path

from .. import bench, design
from ..core import outputs
from ..core.outputs import JSON, PNG, Outputs
from ..check import summary as check_summary
from ..core.provenance import provenance
from ..frame_bench import end_to_end
from ..load_bench import load_bench
from ..backends import DEFAULT_BACKEND
from ..backends.rtunit import UNIT_BACKEND
from ..design import unit_flags
from ..rtunit import SWEEP_RAYS_IN_FLIGHT
from ..scenes.lumibench import is_lumibench, root
from ..studies.bvh import bvh_bench
from . import options
from ..core.words import cell, plural
from .common import check_positive, wrote
from ..core.layout import FORMATS


def add_parser(subparsers):
    p = subparsers.add_parser(
        "bench", help="datapath utilization and simulation speed on a real frame",
        description="Run a design point's frame (default: the bunny, primary rays) through the "
                    "RTL (C++ harness over Verilator) and report its statistics "
                    "(docs/statistics.md): the functional wavefront and the RT-unit replay of "
                    "the design point (docs/rtunit.md), per ray type. The primary workload "
                    "also measures the simulation speed of the rtl and pyverilator backends, "
                    "golden and Embree ray rates, the BVH build time, and a sweep of rays in "
                    "flight x pipelines (PNG plot); any other workload, with --sweep-rays, "
                    "utilization over rays in flight (PNG plot).")
    options.add(p, "bench")
    return p


def scene_load(args, point) -> int:
    """``--scene-load``: ``driver.load_bench``."""
    synthetic = None
    if args.synthetic:
        _int_list(args.synthetic, "--synthetic")
        if len(args.synthetic.split(",")) != 2:
            raise ValueError(f"--synthetic is FILES,TRIANGLES, got {args.synthetic!r}")
        synthetic = tuple(int(x) for x in args.synthetic.split(","))
        if not 1 <= synthetic[0] <= synthetic[1] or synthetic[1] > 50_000_000:
            raise ValueError("--synthetic: 1 <= FILES <= TRIANGLES <= 50,000,000")
    elif not is_lumibench(point.scene):
        raise ValueError("--scene-load measures a LumiBench scene: give --scene lumibench:ID "
                         "(or --synthetic FILES,TRIANGLES)")
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    lroot = None if synthetic else root()
    doc = {"provenance": provenance(point),
           **load_bench(point.scene, lroot, synthetic, point.bvh_format, not args.no_progress)}
    with outs.commit():
        if js:
            outputs.write_json(doc, outs.temp(js))
    for name in ("cold", "warm"):
        r = doc[name]
        print(f"{name:>4}: {r['triangles']:,} triangles in {r['models']:,} models: start "
              f"{r['start_s']:.2f} s + imports {r['import_s']:.2f} s + load {r['load_s']:.2f} s "
              f"+ BVH {r['build_s']:.2f} s = tracing after {r['to_tracing_s']:.2f} s; peak "
              f"{r['peak_rss_bytes'] / 2**20:,.0f} MiB")
    wrote(outs.paths())
    return 0


def frame_end_to_end(args, point) -> int:
    """``--end-to-end``: ``driver.frame_bench``."""
    check_positive("--repeat", args.repeat)
    given = [f for f in ("--sweep-rays", "--plot", "--bvh", "--scene-load")
             if getattr(args, f[2:].replace("-", "_"), None) not in (None, False)]
    if given or args.workers != 1:
        raise ValueError(f"--end-to-end times the frame alone: drop "
                         f"{given[0] if given else '--workers'}")
    if point.size is None:
        point = point.replace(size=128)
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    if args.backend == UNIT_BACKEND:        # what the unit cannot be built with, at once
        point.backend_options(UNIT_BACKEND)
    doc = {"provenance": provenance(point),
           **end_to_end(point, args.repeat, not args.no_progress, args.backend)}
    with outs.commit():
        if js:
            outputs.write_json(doc, outs.temp(js))
    for k, r in enumerate(doc["runs"], 1):
        parts = (f"the RT unit {r['functional_s']:.2f} s" if r["replay_s"] is None else
                 f"functional pass {r['functional_s']:.2f} s, replay {r['replay_s']:.2f} s")
        print(f"run {k}: {r['rays']:,} rays in {r['trace_s']:.2f} s outside loading and the BVH "
              f"({r['rays_per_s']:,.0f} rays/s; {parts}); the process {r['process_s']:.2f} s, "
              f"peak {r['peak_rss_bytes'] / 2**20:,.0f} MiB")
    m = doc["summary"]["rays_per_s"]
    print(f"rays per second outside loading and the BVH: median {m['median']:,.0f} (min "
          f"{m['min']:,.0f}, max {m['max']:,.0f}) over {plural(len(doc['runs']), 'run')}")
    wrote(outs.paths())
    return 0


def _int_list(text: str, flag: str) -> list[int]:
    try:
        vals = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{flag} must be comma-separated integers, got {text!r}") from None
    if not vals or min(vals) < 1:
        raise ValueError(f"{flag} must list integers >= 1, got {text!r}")
    return sorted(set(vals))


def check_backend(args) -> None:
    """Refuse (ValueError, one line) a backend bench does not run, or the RT unit in RTL outside
    ``--end-to-end`` or with a setting it does not model."""
    if args.backend not in (DEFAULT_BACKEND, UNIT_BACKEND):
        raise ValueError(f"--backend {args.backend}: bench runs the frame on {DEFAULT_BACKEND}, "
                         f"or with --end-to-end on {UNIT_BACKEND}")
    if args.backend == UNIT_BACKEND and not args.end_to_end:
        raise ValueError(f"--backend {UNIT_BACKEND} goes with --end-to-end (the other "
                         f"measurements run the {DEFAULT_BACKEND} backend)")
    unit_flags(args, args.backend)


def run(args) -> int:
    from ..render import check_memory

    point = options.from_args(args)
    check_backend(args)
    if args.synthetic and not args.scene_load:
        raise ValueError("--synthetic goes with --scene-load")
    if args.scene_load:
        return scene_load(args, point)
    if args.end_to_end:
        return frame_end_to_end(args, point)
    check_positive("--sweep-size", args.sweep_size, 0)
    check_positive("--pyverilator-requests", args.pyverilator_requests, 0)
    check_positive("--repeat", args.repeat)
    check_positive("--workers", args.workers)
    check_positive("--tile", args.tile)
    if args.bvh and options.given(args):
        raise ValueError(f"--bvh measures its own scenes, BVH fills and culled stacks; drop "
                         f"{options.given(args)[0]}")
    default_frame = point.workload == "primary" and point.spp == 1
    if args.sweep_rays is None:
        sweep_rays = list(SWEEP_RAYS_IN_FLIGHT) if default_frame else []
    else:
        sweep_rays = _int_list(args.sweep_rays, "--sweep-rays")
    sweep_pipes = _int_list(args.sweep_pipelines, "--sweep-pipelines")
    if max(sweep_pipes) > design.MAX_PIPELINES:
        raise ValueError(f"--sweep-pipelines: at most {design.MAX_PIPELINES} pipelines")
    if point.size is not None:
        check_memory(point.size * point.size)
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    plot = None
    if args.bvh or (args.workers == 1 and args.sweep_size):
        kind = "bvh" if args.bvh else "rtunit"
        plot = outs.add("--plot", args.plot or (
            Path(args.json).with_name(f"{Path(args.json).stem}_{kind}.png") if args.json
            else f"rayflex_bench_{kind}.png"), PNG)

    with outs.commit():
        if args.bvh:
            doc = {"provenance": provenance(None),
                   **bvh_bench(progress=not args.no_progress, plot=outs.temp(plot))}
            doc["quality"]["fills"]["plot"] = str(plot)
            if js:
                outputs.write_json(doc, outs.temp(js))
            print(json.dumps(doc, indent=1))
            wrote(outs.paths())
            return 0
        if args.workers > 1:
            doc = bench.bench_workers(point, args.workers, args.tile, not args.no_progress)
            if js:
                outputs.write_json(doc, outs.temp(js))
            print("\n".join(f"{k:<18} {v}" for k, v in doc.items() if k != "provenance"))
            wrote(outs.paths())
            return 0 if doc["identical"] else 1
        if not default_frame:
            doc = bench.bench_workload(point, sweep_rays=sweep_rays if args.sweep_size else (),
                                       plot=outs.temp(plot) if plot else None,
                                       progress=not args.no_progress, ideal=args.ideal_replay)
            if plot:
                doc["plot"] = str(plot)
            if js:
                outputs.write_json(doc, outs.temp(js))
            print(workload_table(doc))
            wrote(outs.paths())
            return 0
        doc = bench.bench(point, sweep_size=args.sweep_size, sweep_rays=sweep_rays,
                          sweep_pipelines=sweep_pipes, plot=outs.temp(plot) if plot else None,
                          pyverilator_requests=args.pyverilator_requests, repeat=args.repeat,
                          progress=not args.no_progress, ideal=args.ideal_replay)
        if plot and doc.get("rtunit_sweep"):
            doc["rtunit_sweep"]["plot"] = str(plot)     # the target, not the temporary file
        if js:
            outputs.write_json(doc, outs.temp(js))
    print(bench.table(doc))
    wrote(outs.paths())
    return 0


def workload_table(doc: dict) -> str:
    """The per-ray-type mix of a ``bench --workload`` run, one row per ray type: its rays, ops,
    latency (issue to done) and bytes from each memory level per ray in the design point's
    replay (``rtunit_memory``), and the frame's timing."""
    pt = doc["provenance"]["design_point"]
    f = doc["frame"]
    b = f["bvh"]
    head = (f"{doc['scene']} {doc['width']}x{doc['height']} {doc['workload']} (spp {pt['spp']}, "
            f"bounces {pt['bounces']}): {f['rays']} rays, {f['ops']} ops")
    rows = [head, f"BVH4 {b['format']}: {b['bytes']:,} bytes, {b['bytes_per_triangle']:.1f} bytes "
                  f"per triangle" + (f", {b['pair_ratio']:.1%} of the triangles paired"
                                     if FORMATS[b["format"]].compressed else "")]
    rows += [f"{a}: {v}" for a, v in bench.timing_rows(f)]
    if f.get("embree"):
        rows.append(check_summary(f["embree"]))
    rows.append(f"{'type':>8} {'rays':>8} {'box/ray':>8} {'tri/ray':>8} {'xf/ray':>7} "
                f"{'util':>6} {'lat':>7} {'p95':>7} {'L1 B/ray':>9} {'L2 B/ray':>9} "
                f"{'DRAM B/ray':>10} {'anyhit/closest':>14}")
    for kind, t in f["by_type"].items():
        m = t.get("rtunit_memory") or {}
        served = m.get("bytes_served_per_ray", {})
        rows.append(f"{kind:>8} {t['rays']:>8} {t['box_ops_per_ray']:>8.2f} "
                    f"{t['tri_ops_per_ray']:>8.2f} {t.get('transform_ops_per_ray', 0):>7.2f} "
                    f"{cell(m.get('utilization'), '.3f'):>6} "
                    f"{cell(m.get('latency_mean'), '.0f'):>7} "
                    f"{cell(m.get('latency_p95'), '.0f'):>7} "
                    f"{cell(served.get('l1'), '.0f'):>9} {cell(served.get('l2'), '.0f'):>9} "
                    f"{cell(served.get('dram'), '.0f'):>10} "
                    f"{cell(t.get('any_hit_vs_closest_ops'), '.3f'):>14}")
    frame = f.get("rtunit_memory") or {}
    if pt.get("frame_schedule") == "one-kernel":
        util = (f"util: one-kernel frame: its ray types share the pipelines, so none has "
                f"cycles or a utilization of its own (-); the frame's is "
                f"{cell(frame.get('utilization'), '.3f')}, each type's latency is shown; "
                f"--frame wavefront gives each type its own")
    else:
        util = "util: a ray type's datapath ops / (units x pipelines x its cycles)"
    rows.append(f"(xf: transform ops, with --transform datapath; {util}; lat, p95: cycles from "
                "the trace call to the ray's last response; B/ray: node bytes supplied by each "
                "level; anyhit/closest: an any-hit type's ops over the closest hit's of the "
                "same rays; -: none; docs/statistics.md)")
    return "\n".join(rows)
