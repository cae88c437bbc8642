"""``rayflex render SCENE``: render through the datapath, write the image, heat map and stats.

Every check is made before any work: sizes, backend name, camera flags, memory for the frame, and
every output path, the request-stream exports' too (``driver.core.outputs``,
``driver.cli.export``); the files are written all or nothing once the frame is done.
"""

from __future__ import annotations

import sys

from ..backends import resolve as resolve_backend
from ..backends.rtunit import UNIT_BACKEND
from ..design import check_unit_reads, unit_flags
from ..check import failed
from ..check import summary as check_summary
from ..core import outputs
from ..core.outputs import IMAGE, JSON, Outputs
from ..core.progress import phase
from ..core.provenance import provenance
from ..design import clock_figures
from ..scenes.camera import check_size
from . import options
from .common import (EXIT_CHECK, PROG, check_backend, check_flag_size, check_positive,
                     check_workers, scene_info, view_options, wrote)
from .export import Export


def add_parser(subparsers):
    p = subparsers.add_parser(
        "render", help="render a scene through the datapath",
        description="Render SCENE with every box/triangle test run on the datapath model; write "
                    "the image, an operations-per-pixel heat map and statistics.")
    options.add(p, "render", positional_scene=True, notes={"rtunit": "with --rtunit"})
    return p


def run(args) -> int:
    from ..render import check_frame_memory, plan_tile, render
    from ..scenes.scene import load_scene, resolve, scene_name, with_camera

    point = options.from_args(args)
    if point.size is not None and (args.width is not None or args.height is not None):
        raise ValueError("give either --size or --width/--height, not both")
    for flag in ("width", "height"):
        check_flag_size(f"--{flag}", getattr(args, flag))
    unit_flags(args, args.backend)
    rt = options.given(args, ("rtunit",))
    if args.backend == UNIT_BACKEND:
        rt = []                 # the RT unit in RTL reads them (unit_flags refused the others)
    if args.backend == UNIT_BACKEND and args.rtunit:
        raise ValueError(f"--rtunit replays the Python traversal's requests: --backend "
                         f"{UNIT_BACKEND} times the frame itself (unit_rtl in the JSON)")
    if rt and not args.rtunit:
        raise ValueError(f"{rt[0]} sets the RT unit, which render models with --rtunit only")
    if args.ideal_replay and not args.rtunit:
        raise ValueError("--ideal-replay is a second RT-unit replay: give --rtunit")
    check_backend(args.backend)
    check_workers(args)
    if args.tile is not None:
        check_positive("--tile", args.tile)
    source = resolve(point.scene)
    name = scene_name(source)
    view = view_options(args, source)
    outs = Outputs(inputs=[source.ref] if source.kind != "builtin" else [])
    out = outs.add("--out", args.out or f"{name}.png", IMAGE)
    hm = outs.add("--heatmap", args.heatmap or out.with_name(f"{out.stem}_heatmap.png"), IMAGE)
    js = outs.add("--json", args.json, JSON) if args.json else None
    dump = Export(args, outs)
    if point.size is not None or (args.width is not None and args.height is not None):
        pixels = point.size ** 2 if point.size is not None else args.width * args.height
        check_frame_memory(pixels, point.spp, plan_tile(
            pixels, point.workload, point.spp, args.tile, args.workers, args.scheduler))

    check_unit_reads(args.backend, point)       # a LumiBench scene: before loading it
    distributed = args.workers > 1 or args.scheduler
    # a backend that cannot be built fails first (tiles on workers and threads make their own
    # from its name)
    if not distributed:
        resolve_backend(args.backend, **point.backend_options(args.backend))
    backend = args.backend
    with phase(f"loading {name}", not args.no_progress):
        scene = with_camera(load_scene(source, args.up_axis), **view)
    check_unit_reads(backend, point, scene)     # before the BVH build
    w, h = scene.size
    if point.size is not None:
        w = h = point.size
    w = args.width if args.width is not None else w
    h = args.height if args.height is not None else h
    w, h = check_size(w, h)
    res = render(scene, w, h, backend=backend, progress=not args.no_progress,
                 check_embree=args.check_embree, point=point,
                 rtunit=("ideal" if args.ideal_replay else True) if args.rtunit else False,
                 tile=args.tile, workers=args.workers, scheduler=args.scheduler)
    with outs.commit():
        res.save(outs.temp(out))
        res.save_heatmap(outs.temp(hm))
        if js:
            outputs.write_json({"provenance": provenance(point), "scene": scene.name,
                                "width": w, "height": h, **scene_info(scene), **res.stats,
                                "clock": clock_figures(point, res.stats)},
                               outs.temp(js))
        if dump:
            dump.write(scene, w, h, point.workload, point.workload_options(), res.stats.get("tile"),
                       point.tree_options(), not args.no_progress, point.backend_options())
    print(summary(res))
    wrote(outs.paths())
    emb = res.stats.get("embree")
    if failed(emb):
        wrong = (emb.get("adjudicated") or {}).get("classes", {}).get("datapath_wrong")
        print(f"{PROG}: Embree check: {emb['hit_mismatch']} hit/miss and "
              f"{emb['prim_mismatch']} primitive mismatches"
              + (f", {wrong} rays where the datapath is wrong" if wrong is not None else ""),
              file=sys.stderr)
        return EXIT_CHECK
    return 0


def summary(res) -> str:
    """A short human-readable report of a RenderResult."""
    s, b = res.stats, res.bvh_stats
    wf = s["wavefront"]
    rays = s.get("rays", res.width * res.height)
    lines = [
        f"{res.scene.name} {res.width}x{res.height} on {s.get('backend', '?')}: "
        f"{rays} rays, {s.get('hits', 0)} hits ({100 * s.get('hits', 0) / max(rays, 1):.1f} %)",
        f"datapath: {s.get('box_ops', 0)} box ops + {s.get('tri_ops', 0)} tri ops"
        + (f" + {s['transform_ops']} transform ops" if s.get("transform_ops") else "")
        + f" = {s.get('ops', 0)} ops ({s.get('box_ops_per_ray', 0):.1f} + "
        f"{s.get('tri_ops_per_ray', 0):.1f}"
        + (f" + {s['transform_ops_per_ray']:.2f}" if s.get("transform_ops") else "")
        + " per ray)",
    ]
    u = s.get("unit_rtl")
    if u:       # the RT unit in RTL ran the traversal: its cycles are the frame's
        ratio = u.get("replay_cycles_ratio")
        lines.append(
            f"RT unit in RTL R={u['rays_in_flight']}, stack {u['stack_depth']}, "
            f"{u['dividers']} dividers ({u['memory']} memory): {u['cycles']} cycles, "
            f"utilization {u['utilization']:.3f}, max stack depth {u['max_stack_depth']}, "
            f"{u['stack_overflows']} stack overflows"
            + (f", {u['stack_culls']} box nodes culled" if u.get("cull_stack") else "")
            + f"; simulated in {wf['sim_wall_s']:.2f} s"
            + (f"; {u['traversal_mismatches']} rays differ from the traversal"
               if u.get("traversal_mismatches") is not None else "")
            + (f"; replay cycles {ratio:.3f} x the unit's" if ratio is not None else ""))
    else:
        lines.append(
            f"wavefront (every ray in flight, one pipeline): {wf['cycles']} cycles, utilization "
            f"{wf['utilization']:.3f}, {wf['frame_us_at_1ghz']:.1f} us at 1 GHz; simulated in "
            f"{wf['sim_wall_s']:.2f} s ({wf['sim_cycles_per_s']:.3g} cycles/s)")
    for key, what in (("rtunit", "node fetches free"), ("rtunit_memory", "memory hierarchy")):
        r = s.get(key)
        if r:
            lines.append(f"RT units {r['rt_units']} x R={r['rays_in_flight']} "
                         f"P={r['pipelines']}, warp {r['warp_size']}, "
                         f"{r['frame_schedule']} ({what}): "
                         f"{r['cycles']} cycles, utilization {r['utilization']:.3f}"
                         + (f", L1 hit rate {r['hit_rate']:.3f}, {r['bytes_per_ray']:.0f} B/ray "
                            "from DRAM" if "hit_rate" in r else ""))
    if b:
        lines.append(f"BVH4: {res.scene.counts()['instanced_triangles']} triangles, "
                     f"{b.get('box_nodes', '?')} box "
                     f"nodes, depth {b.get('depth', '?')}, SAH {b.get('sah_cost', 0):.1f}, "
                     f"{b.get('bytes', 0) / 2**20:.2f} MiB, built in {b.get('build_s', 0):.2f} s")
    for kind, t in s.get("by_type", {}).items():
        lines.append(f"  {kind:>8}: {t['rays']} rays, {t['hits']} hits, "
                     f"{t['box_ops_per_ray']:.1f} box + {t['tri_ops_per_ray']:.1f} tri"
                     + (f" + {t['transform_ops_per_ray']:.2f} transform" if t.get("transform_ops")
                        else "") + f" ops per ray, {t['ops']} ops")
    if s.get("embree"):
        lines.append(check_summary(s["embree"]))
    return "\n".join(lines)
