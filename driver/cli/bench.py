"""``rayflex bench``: datapath throughput of a real frame and simulation speed (``driver.bench``)."""

from __future__ import annotations

from .common import add_json, add_progress, check_flag_size, check_positive, wrote


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
                        "rayflex_bench_rtunit.png)")
    p.add_argument("--pyverilator-requests", type=int, default=PYVERILATOR_REQUESTS,
                   metavar="N", help=f"requests streamed through pyverilator (default "
                                     f"{PYVERILATOR_REQUESTS}; 0: skip)")
    p.add_argument("--repeat", type=int, default=REPEAT, metavar="N",
                   help=f"timed passes of the rtl and pyverilator streams; the best counts "
                        f"(default {REPEAT})")
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

    from ..bench import bench, table
    from ..outputs import JSON, PNG, Outputs, write_json
    from ..render import check_memory

    check_flag_size("--size", args.size)
    check_positive("--rays-in-flight", args.rays_in_flight)
    check_positive("--pipelines", args.pipelines, 1, MAX_PIPELINES)
    check_positive("--sweep-size", args.sweep_size, 0)
    check_positive("--pyverilator-requests", args.pyverilator_requests, 0)
    check_positive("--repeat", args.repeat)
    sweep_rays = _int_list(args.sweep_rays, "--sweep-rays")
    sweep_pipes = _int_list(args.sweep_pipelines, "--sweep-pipelines")
    if max(sweep_pipes) > MAX_PIPELINES:
        raise ValueError(f"--sweep-pipelines: at most {MAX_PIPELINES} pipelines")
    if args.size is not None:
        check_memory(args.size * args.size)
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    plot = None
    if args.sweep_size:
        plot = outs.add("--plot", args.plot or (
            Path(args.json).with_name(Path(args.json).stem + "_rtunit.png") if args.json
            else "rayflex_bench_rtunit.png"), PNG)

    with outs.commit():
        doc = bench(args.scene, size=args.size, rays_in_flight=args.rays_in_flight,
                    pipelines=args.pipelines, sweep_size=args.sweep_size,
                    sweep_rays=sweep_rays, sweep_pipelines=sweep_pipes,
                    plot=outs.temp(plot) if plot else None,
                    pyverilator_requests=args.pyverilator_requests,
                    repeat=args.repeat, progress=not args.no_progress)
        if plot and doc.get("rtunit_sweep"):
            doc["rtunit_sweep"]["plot"] = str(plot)     # the target, not the temporary file
        if js:
            write_json(doc, outs.temp(js))
    print(table(doc))
    wrote(outs.paths())
    return 0
