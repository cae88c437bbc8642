"""What every ``rayflex`` command shares: exit codes, the one-line error, and the options for
backend, image size, outputs (``--json PATH``; older spellings kept as hidden aliases) and
progress, with their checks (all made before any work starts)."""

from __future__ import annotations

import argparse
import sys

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

def add_backend(p, default: str | None = None) -> None:
    from ..backends import BACKENDS, DEFAULT_BACKEND
    default = default or DEFAULT_BACKEND
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


def provenance(point=None) -> dict:
    """The ``provenance`` object of a JSON document (``driver.stats.provenance``)."""
    from ..stats import provenance as make
    return make(point)


def add_workers(p) -> None:
    from ..render import MEMORY_TILE, WHOLE_FRAME_PIXELS
    from ..tiles import DEFAULT_TILE
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="trace tiles on a local Dask cluster of N one-thread processes "
                        "(default 1: this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="trace tiles on the Dask cluster at ADDRESS (e.g. tcp://host:8786)")
    p.add_argument("--tile", type=int, metavar="N",
                   help="tile size in pixels (default: a primary frame traced by one worker is "
                        "one wavefront up to "
                        f"{WHOLE_FRAME_PIXELS:,} pixels, tiles of {MEMORY_TILE} above; else "
                        f"{DEFAULT_TILE})")


def check_workers(args) -> None:
    """--workers (>= 1) and --scheduler: one place to run tiles or points, not both."""
    check_positive("--workers", args.workers)
    if args.workers > 1 and getattr(args, "scheduler", None):
        raise ValueError(f"--workers {args.workers} starts a local cluster and --scheduler "
                         f"{args.scheduler} names another: give one of them")


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


def add_view(p) -> None:
    """The camera override and the up axis of mesh files: ``view_options`` checks them."""
    from ..scenes.scene import UP_AXES
    g = p.add_argument_group("camera", "replace parts of the scene's camera (the rest stays the "
                             "scene's); write --camera=-1,2,3 when a value starts with a minus")
    g.add_argument("--camera", metavar="X,Y,Z", help="camera position")
    g.add_argument("--look-at", metavar="X,Y,Z", help="the point the camera looks at")
    g.add_argument("--up", metavar="X,Y,Z", help="the camera's up direction (fixes the roll)")
    g.add_argument("--fov", metavar="DEG", help="vertical field of view in degrees, in (0, 180)")
    g.add_argument("--up-axis", choices=list(UP_AXES),
                   help="mesh files: the axis pointing up for the automatic camera (default y, "
                        "the glTF and usual OBJ convention; z for most CAD and scan data)")


def view_options(args, source) -> dict:
    """The checked camera flags of ``add_view`` as ``driver.scenes.scene.with_camera`` keywords
    (one-line ValueError if bad; the camera as a whole is validated once the scene is loaded,
    here already when position, look-at and up are all given)."""
    from ..scenes.camera import Camera, check_fov, parse_number, parse_vec3
    from ..scenes.scene import check_up_axis
    check_up_axis(args.up_axis, source.kind)
    view = {k: parse_vec3(getattr(args, a), f"--{a.replace('_', '-')}")
            for k, a in (("position", "camera"), ("look_at", "look_at"), ("up", "up"))}
    view["fov_deg"] = parse_number(args.fov, "--fov")
    if view["fov_deg"] is not None:
        check_fov(view["fov_deg"])
    if all(view[k] is not None for k in ("position", "look_at", "up")):
        Camera(view["position"], view["look_at"], view["up"]).validate()
    return view
