"""``rayflex bench``: datapath throughput of a real frame and simulation speed (``driver.bench``)."""

from __future__ import annotations

import json

from .common import (add_json, add_progress, add_tree, add_workload, check_flag_size,
                     check_positive, tree_options, workload_options, wrote)


def add_parser(subparsers):
    from .. import rtunit
    from ..bench import DEFAULT_SCENE, PYVERILATOR_REQUESTS, REPEAT, SWEEP_SIZE
    p = subparsers.add_parser(
        "bench", help="datapath utilization and simulation speed on a real frame",
        description="Run the default bunny frame through the RTL (C++ harness over Verilator) "
                    "and report its datapath statistics on the RT-unit model, the simulation "
                    "speed of the rtl and pyverilator backends, golden and Embree ray rates, the "
                    "BVH build time, and a sweep of rays in flight x pipelines (PNG plot).")
    add_json(p, "write the results as JSON")
    p.add_argument("--size", type=int, metavar="N",
                   help="square frame N x N (default: the scene's size, 256)")
    p.add_argument("--scene", default=DEFAULT_SCENE, metavar="SCENE",
                   help=f"scene name or file (default: {DEFAULT_SCENE})")
    p.add_argument("--rays-in-flight", type=int, default=rtunit.DEFAULT_RAYS_IN_FLIGHT,
                   metavar="R", help="ray pool of the RT-unit model for the frame "
                                     f"(default {rtunit.DEFAULT_RAYS_IN_FLIGHT})")
    p.add_argument("--pipelines", type=int, default=1, metavar="P",
                   help="datapath pipelines of the RT-unit model for the frame (default 1)")
    p.add_argument("--sweep-size", type=int, default=SWEEP_SIZE, metavar="N",
                   help=f"frame size of the rays-in-flight x pipelines sweep (default "
                        f"{SWEEP_SIZE}, at most --size; 0: no sweep)")
    p.add_argument("--sweep-rays", default=",".join(map(str, rtunit.SWEEP_RAYS_IN_FLIGHT)),
                   metavar="LIST", help="rays in flight of the sweep (comma-separated)")
    p.add_argument("--sweep-pipelines", default=",".join(map(str, rtunit.SWEEP_PIPELINES)),
                   metavar="LIST", help="pipeline counts of the sweep (comma-separated)")
    p.add_argument("--plot", metavar="PATH",
                   help="sweep plot PNG (default: beside --json as JSONSTEM_rtunit.png, else "
                        "rayflex_bench_rtunit.png; with --bvh, the BVH shape plot "
                        "JSONSTEM_bvh.png or rayflex_bench_bvh.png)")
    p.add_argument("--pyverilator-requests", type=int, default=PYVERILATOR_REQUESTS,
                   metavar="N", help=f"requests streamed through pyverilator (default "
                                     f"{PYVERILATOR_REQUESTS}; 0: skip)")
    p.add_argument("--repeat", type=int, default=REPEAT, metavar="N",
                   help=f"timed passes of the rtl and pyverilator streams; the best counts "
                        f"(default {REPEAT})")
    add_workload(p, default=None)
    add_tree(p)
    p.add_argument("--no-memory", action="store_true",
                   help="no node cache and memory model (the JSON's memory object; with "
                        "--workload, the per-type replays and the sweep with memory)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="also time the --workload (default path) frame tiled on a local Dask "
                        "cluster of N processes against one process: the speed-up")
    p.add_argument("--tile", type=int, default=64, metavar="N",
                   help="tile size of the --workers comparison (default 64)")
    p.add_argument("--bvh", action="store_true",
                   help="the BVH builder instead: build time and peak memory for the bunny and "
                        "2 M / 5 M instanced bunnies, tree quality of the SAH vs greedy collapse, "
                        "box nodes vs ops per ray for each --bvh-fill with and without "
                        "--cull-stack (PNG plot)")
    add_progress(p)
    return p


MAX_PIPELINES = 64


def _int_list(text: str, flag: str) -> list[int]:
    try:
        vals = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{flag} must be comma-separated integers, got {text!r}") from None
    if not vals or min(vals) < 1:
        raise ValueError(f"{flag} must list integers >= 1, got {text!r}")
    return sorted(set(vals))


def run(args) -> int:
    from pathlib import Path

    from .. import rtunit
    from ..bench import bench, bench_workers, bench_workload, table
    from ..outputs import JSON, PNG, Outputs, write_json
    from ..render import check_memory

    check_flag_size("--size", args.size)
    check_positive("--rays-in-flight", args.rays_in_flight)
    check_positive("--pipelines", args.pipelines, 1, MAX_PIPELINES)
    check_positive("--sweep-size", args.sweep_size, 0)
    check_positive("--pyverilator-requests", args.pyverilator_requests, 0)
    check_positive("--repeat", args.repeat)
    check_positive("--workers", args.workers)
    check_positive("--tile", args.tile)
    options = workload_options(args)
    tree = tree_options(args)
    if args.bvh and (tree["fill"] or tree["cull_stack"] or tree["bvh_format"] != "box32"
                     or tree["flatten"]):
        raise ValueError("--bvh measures the BVH fills, the culled stack and both image formats "
                         "itself; drop --bvh-fill/--cull-stack/--bvh-format/--flatten")
    memory = None if args.no_memory else rtunit.MemoryModel()
    sweep_rays = _int_list(args.sweep_rays, "--sweep-rays")
    sweep_pipes = _int_list(args.sweep_pipelines, "--sweep-pipelines")
    if max(sweep_pipes) > MAX_PIPELINES:
        raise ValueError(f"--sweep-pipelines: at most {MAX_PIPELINES} pipelines")
    if args.size is not None:
        check_memory(args.size * args.size)
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    plot = None
    if args.bvh or (args.sweep_size and args.workers == 1):        # --workers draws no plot
        kind = "bvh" if args.bvh else "rtunit"
        plot = outs.add("--plot", args.plot or (
            Path(args.json).with_name(f"{Path(args.json).stem}_{kind}.png") if args.json
            else f"rayflex_bench_{kind}.png"), PNG)

    with outs.commit():
        if args.bvh:
            from ..bvh.bench import bvh_bench
            doc = bvh_bench(progress=not args.no_progress, plot=outs.temp(plot))
            doc["quality"]["fills"]["plot"] = str(plot)
            if js:
                write_json(doc, outs.temp(js))
            print(json.dumps(doc, indent=1))
            wrote(outs.paths())
            return 0
        if args.workers > 1:
            doc = bench_workers(args.scene, args.workload or "path", args.size or 128,
                                args.workers, args.tile, not args.no_progress, **options, **tree)
            if js:
                write_json(doc, outs.temp(js))
            print("\n".join(f"{k:<18} {v}" for k, v in doc.items()))
            wrote(outs.paths())
            return 0 if doc["identical"] else 1
        if args.workload:
            doc = bench_workload(args.scene, args.workload, args.size or 64,
                                 rays_in_flight=args.rays_in_flight, pipelines=args.pipelines,
                                 sweep_rays=sweep_rays, plot=outs.temp(plot) if plot else None,
                                 progress=not args.no_progress, memory=memory, **options, **tree)
            if plot:
                doc["plot"] = str(plot)
            if js:
                write_json(doc, outs.temp(js))
            print(workload_table(doc))
            wrote(outs.paths())
            return 0
        doc = bench(args.scene, size=args.size, rays_in_flight=args.rays_in_flight,
                    pipelines=args.pipelines, sweep_size=args.sweep_size,
                    sweep_rays=sweep_rays, sweep_pipelines=sweep_pipes,
                    plot=outs.temp(plot) if plot else None,
                    pyverilator_requests=args.pyverilator_requests,
                    repeat=args.repeat, progress=not args.no_progress, memory=memory, **tree)
        if plot and doc.get("rtunit_sweep"):
            doc["rtunit_sweep"]["plot"] = str(plot)     # the target, not the temporary file
        if js:
            write_json(doc, outs.temp(js))
    print(table(doc))
    wrote(outs.paths())
    return 0


def workload_table(doc: dict) -> str:
    """The per-ray-type mix of a ``bench --workload`` run, one row per ray type."""
    head = (f"{doc['scene']} {doc['width']}x{doc['height']} {doc['workload']} (spp {doc['spp']}, "
            f"bounces {doc['bounces']}): {doc['frame']['rays']} rays, {doc['frame']['ops']} ops")
    rows = [head, f"{'type':>8} {'rays':>8} {'box/ray':>8} {'tri/ray':>8} {'util':>6} "
                  f"{'util+mem':>8} {'hit rate':>8} {'B/ray':>7} {'anyhit/closest':>14}"]
    for kind, t in doc["by_type"].items():
        m = t.get("memory", {})
        ratio = t.get("any_hit_vs_closest_ops")
        rows.append(f"{kind:>8} {t['rays']:>8} {t['box_ops_per_ray']:>8.2f} "
                    f"{t['tri_ops_per_ray']:>8.2f} {t['replay_utilization']:>6.3f} "
                    f"{m.get('replay_utilization', float('nan')):>8.3f} "
                    f"{m.get('hit_rate', float('nan')):>8.3f} {m.get('bytes_per_ray', 0):>7.0f} "
                    f"{'' if ratio is None else format(ratio, '.3f'):>14}")
    return "\n".join(rows)
