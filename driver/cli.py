"""``rayflex`` command line: one argparse subcommand per module in ``COMMANDS``.

A subcommand is any object (usually a module) with ``add_parser(subparsers)`` (adds and returns
its parser) and ``run(args) -> int`` (the exit code). To add one (``bench``, ``knn``), write the
module and add one line to ``COMMANDS``.

Every expected user mistake (unknown scene, unreadable mesh, bad size or camera, unknown or
unbuildable backend: ``ValueError`` / ``OSError``) prints one line ``rayflex: error: ...`` on
stderr and exits 2; argparse usage errors exit 2 too.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

import numpy as np

# name -> "module" or "module:attribute"; each provides add_parser(subparsers) and run(args)
COMMANDS = {
    "render": "driver.cli:RenderCommand",
    "knn": "driver.knn:KnnCommand",
    "bench": "driver.bench",
    "power": "driver.power",
}

PROG = "rayflex"
EXIT_MISMATCH = 1          # render --check-embree found unexplained mismatches
EXIT_USAGE = 2


def main(argv=None) -> int:
    """Entry point of the ``rayflex`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return int(args.handler.run(args) or 0)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as e:
        print(f"{PROG}: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_USAGE


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Workload driver for the RayFlex ray-tracing datapath.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, target in COMMANDS.items():
        handler = _load(target)
        p = handler.add_parser(sub)
        p.set_defaults(handler=handler)
    return parser


def _load(target: str):
    module, _, attr = target.partition(":")
    obj = importlib.import_module(module)
    return getattr(obj, attr) if attr else obj


def _one_line(e: BaseException) -> str:
    if isinstance(e, OSError) and e.strerror:
        text = f"{e.strerror}: {e.filename}" if e.filename else e.strerror
    else:
        text = str(e).strip() or type(e).__name__
    return text.splitlines()[0]


class RenderCommand:
    """``rayflex render SCENE``: render through the datapath, write PNG, heat map and stats."""

    @staticmethod
    def add_parser(subparsers):
        from .backends import BACKENDS
        p = subparsers.add_parser(
            "render", help="render a scene through the datapath",
            description="Render SCENE with every box/triangle test run on the datapath model; "
                        "write the image, an operations-per-pixel heat map and statistics. "
                        f"Exit status: 0 ok, {EXIT_MISMATCH} Embree check found unexplained "
                        f"mismatches, {EXIT_USAGE} usage error.")
        p.add_argument("scene", metavar="SCENE",
                       help="scene name (scenes/*.toml or built-in: bunny, sphere, room, soup), "
                            "a .toml scene file or a mesh file (PLY, OBJ, STL, OFF, GLB)")
        p.add_argument("--size", type=int, metavar="N",
                       help="square image N x N (default: the scene's size, 256)")
        p.add_argument("--width", type=int, metavar="W", help="image width (1..8192)")
        p.add_argument("--height", type=int, metavar="H", help="image height (1..8192)")
        p.add_argument("--backend", default="rtl", metavar="NAME",
                       help=f"datapath model: {', '.join(BACKENDS)} (default: rtl)")
        p.add_argument("--check-embree", action="store_true",
                       help="cross-check every primary ray's closest hit against Embree")
        p.add_argument("--stats-json", metavar="PATH", help="write frame statistics as JSON")
        p.add_argument("--out", metavar="PATH", help="image PNG (default: SCENE.png)")
        p.add_argument("--heatmap", metavar="PATH",
                       help="ops-per-pixel heat map PNG (default: beside --out, OUT_heatmap.png)")
        p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
        return p

    @staticmethod
    def run(args) -> int:
        from .camera import MAX_SIZE, check_size
        from .render import render
        from .scene import load_scene

        if args.size is not None and (args.width is not None or args.height is not None):
            raise ValueError("give either --size or --width/--height, not both")
        for flag in ("size", "width", "height"):
            v = getattr(args, flag)
            if v is not None and not 1 <= v <= MAX_SIZE:
                raise ValueError(f"--{flag} must be in 1..{MAX_SIZE}, got {v}")
        scene = load_scene(args.scene)
        w, h = scene.size
        if args.size is not None:
            w = h = args.size
        w = args.width if args.width is not None else w
        h = args.height if args.height is not None else h
        w, h = check_size(w, h)
        out = Path(args.out or f"{scene.name}.png")
        hm = Path(args.heatmap or out.with_name(f"{out.stem}_heatmap.png"))
        for path in (out, hm) + ((Path(args.stats_json),) if args.stats_json else ()):
            if not path.parent.is_dir():
                raise ValueError(f"output directory does not exist: {path.parent}")

        res = render(scene, w, h, backend=args.backend, progress=not args.no_progress,
                     check_embree=args.check_embree)
        res.save(out)
        res.save_heatmap(hm)
        written = [str(out), str(hm)]
        if args.stats_json:
            doc = {"scene": scene.name, "width": w, "height": h, **res.stats}
            Path(args.stats_json).write_text(json.dumps(_jsonable(doc), indent=2) + "\n")
            written.append(str(args.stats_json))
        print(summary(res))
        print("wrote " + ", ".join(written))
        emb = res.stats.get("embree")
        if emb and (emb["hit_mismatch"] or emb["prim_mismatch"]):
            print(f"{PROG}: Embree check: {emb['hit_mismatch']} hit/miss and "
                  f"{emb['prim_mismatch']} primitive mismatches", file=sys.stderr)
            return EXIT_MISMATCH
        return 0


def summary(res) -> str:
    """A short human-readable report of a RenderResult."""
    s, b = res.stats, res.bvh_stats
    rays = s.get("rays", res.width * res.height)
    lines = [
        f"{res.scene.name} {res.width}x{res.height} on {s.get('backend', '?')}: "
        f"{rays} rays, {s.get('hits', 0)} hits ({100 * s.get('hits', 0) / max(rays, 1):.1f} %)",
        f"datapath: {s.get('box_ops', 0)} box ops + {s.get('tri_ops', 0)} tri ops = "
        f"{s.get('ops', 0)} ops ({s.get('box_ops_per_ray', 0):.1f} + "
        f"{s.get('tri_ops_per_ray', 0):.1f} per ray) in {s.get('cycles', 0)} cycles, "
        f"utilization {s.get('utilization', 0):.3f}",
        f"frame: {s.get('frame_us_at_1ghz', 0):.1f} us at 1 GHz; simulated in "
        f"{s.get('sim_wall_s', 0):.2f} s ({s.get('sim_cycles_per_s', 0):.3g} cycles/s)",
    ]
    if b:
        lines.append(f"BVH4: {len(res.scene.mesh.faces)} triangles, {b.get('box_nodes', '?')} box "
                     f"nodes, depth {b.get('depth', '?')}, SAH {b.get('sah_cost', 0):.1f}, "
                     f"{b.get('bytes', 0) / 2**20:.2f} MiB, built in {b.get('build_s', 0):.2f} s")
    e = s.get("embree")
    if e:
        lines.append(f"embree: {e['rays_compared']} rays compared, {e['hit_mismatch']} hit/miss "
                     f"mismatches, {e['prim_mismatch']} primitive mismatches, {e['edge_ties']} "
                     f"edge ties, max t rel err {e['max_t_rel_err']:.2g}")
    return "\n".join(lines)


def _jsonable(x):
    """numpy scalars/arrays and tuples to plain JSON types; non-finite floats to null."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    return x


if __name__ == "__main__":
    sys.exit(main())
