"""What every ``rayflex`` command shares: exit codes, the one-line error, and the options for
backend, image size, outputs (``--json PATH``; older spellings kept as hidden aliases) and
progress, with their checks (all made before any work starts)."""

from __future__ import annotations

import argparse
import sys

from ..instances import TRANSFORMS
from ..layout import IMAGE_FORMATS

PROG = "rayflex"
EXIT_OK = 0
EXIT_CHECK = 1              # a result check failed (Embree mismatch, kNN disagreement)
EXIT_USAGE = 2              # bad input / usage / environment: one line, nothing written
EXIT_INTERNAL = 3           # a bug
EXIT_INTERRUPTED = 130      # SIGINT (128 + 2)
EXIT_TERMINATED = 143       # SIGTERM (128 + 15)


def one_line(e: BaseException) -> str:
    """The first line of an exception's message (an OSError as 'reason: file')."""
    if isinstance(e, OSError) and e.strerror:
        text = f"{e.strerror}: {e.filename}" if e.filename else e.strerror
    else:
        text = str(e).strip() or type(e).__name__
    return text.splitlines()[0]


def note(text: str) -> None:
    """A one-line note on stderr (not an error)."""
    print(f"{PROG}: {text}", file=sys.stderr)


# ---------------------------------------------------------------------------------------------
# options

def add_backend(p, default: str = "rtl") -> None:
    from ..backends import BACKENDS
    p.add_argument("--backend", default=default, metavar="NAME",
                   help=f"datapath model: {', '.join(BACKENDS)} (default: {default})")


def check_backend(name: str) -> str:
    """Refuse an unknown backend name before any work (one-line BackendError)."""
    from ..backends import BACKENDS, BackendError
    if name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    return name


def add_json(p, help_text: str, *aliases: str) -> None:
    """``--json PATH``; each older spelling in ``aliases`` still works but is not shown."""
    p.add_argument("--json", metavar="PATH", help=help_text)
    for alias in aliases:
        p.add_argument(alias, dest="json", metavar="PATH", help=argparse.SUPPRESS)


def add_workload(p, default: str | None = "primary") -> None:
    """The workload flags of SPEC 12/13 (render and bench)."""
    from ..workloads import WORKLOADS
    p.add_argument("--workload", default=default, choices=WORKLOADS,
                   help="rays of the frame: primary (camera rays), shadow (+ one shadow ray per "
                        "hit), ao (+ --ao-rays ambient-occlusion rays per hit), path (diffuse "
                        "path tracing with next-event estimation)"
                        + (f" (default: {default})" if default else ""))
    p.add_argument("--spp", type=int, default=1, metavar="N", help="samples per pixel (default 1)")
    p.add_argument("--bounces", type=int, default=1, metavar="N",
                   help="path: diffuse bounces after the camera ray (default 1; 0: direct light)")
    p.add_argument("--ao-rays", type=int, default=4, metavar="N",
                   help="ao: rays per hit (default 4)")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="seed of the counter-based random numbers (default 0)")


def add_tree(p) -> None:
    """The BVH shape and traversal flags (render and bench): ``tree_options`` checks them."""
    p.add_argument("--bvh-fill", type=int, default=0, metavar="N",
                   help="split subtrees of at most N triangles so that their 4-wide nodes can "
                        "all be full: fewer box nodes and bytes, slightly more ops per ray "
                        "(default 0: plain SAH; docs/bvh.md)")
    p.add_argument("--cull-stack", action="store_true",
                   help="keep each stack entry's entry distance and drop box nodes beyond the "
                        "nearest hit without a request: the same hits, fewer box ops (beyond "
                        "SPEC 9: a float per stack entry in the RT unit)")
    p.add_argument("--bvh-format", default="box32", choices=IMAGE_FORMATS,
                   help="node image: box32 (128-byte float32 box nodes, a 64-byte node per "
                        "triangle) or q8 (64-byte quantized box nodes, 64-byte triangle-pair "
                        "leaves: docs/compressed.md) (default: box32)")
    p.add_argument("--transform", default="driver", choices=tuple(TRANSFORMS),
                   help="where an instanced scene's ray transform runs: driver (on the host, "
                        "as a traversal shader does; docs/instances.md) (default: driver)")
    p.add_argument("--flatten", action="store_true",
                   help="trace an instanced scene (glTF mesh reuse, bunny_grid) as one mesh: its "
                        "flattened world-space triangles in one BVH instead of a two-level BVH "
                        "of instances (docs/instances.md)")


def tree_options(args) -> dict:
    """The checked flags of ``add_tree`` as keyword arguments: ``fill``, ``cull_stack``,
    ``bvh_format``, ``flatten``, ``transform``."""
    check_positive("--bvh-fill", args.bvh_fill, 0)
    return dict(fill=args.bvh_fill, cull_stack=bool(args.cull_stack), bvh_format=args.bvh_format,
                flatten=bool(args.flatten), transform=args.transform)


def workload_options(args) -> dict:
    """The checked workload options of ``add_workload`` (one-line ValueError if bad)."""
    from ..workloads import check_arguments
    check_arguments(args.spp, args.bounces, args.ao_rays, args.seed)
    return dict(spp=args.spp, bounces=args.bounces, ao_rays=args.ao_rays, seed=args.seed)


def add_workers(p) -> None:
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="trace tiles on a local Dask cluster of N one-thread processes "
                        "(default 1: this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="trace tiles on the Dask cluster at ADDRESS (e.g. tcp://host:8786)")
    p.add_argument("--tile", type=int, metavar="N",
                   help="tile size in pixels (default: the whole frame as one wavefront when it "
                        "fits in memory and one worker traces the primary workload; 256 when it "
                        "does not fit; else 64)")


def add_progress(p) -> None:
    p.add_argument("--no-progress", action="store_true", help="no progress on stderr")


def check_flag_size(flag: str, value) -> None:
    """A --size/--width/--height value: None (not given) or 1..MAX_SIZE."""
    from ..scenes.camera import MAX_SIZE
    if value is not None and not 1 <= value <= MAX_SIZE:
        raise ValueError(f"{flag} must be in 1..{MAX_SIZE}, got {value}")


def check_positive(flag: str, value, minimum: int = 1, maximum: int | None = None) -> None:
    if value < minimum or (maximum is not None and value > maximum):
        rng = f"in {minimum}..{maximum}" if maximum is not None else f">= {minimum}"
        raise ValueError(f"{flag} must be {rng}, got {value}")


def wrote(paths) -> None:
    paths = [str(p) for p in paths]
    if paths:
        print("wrote " + ", ".join(paths))
