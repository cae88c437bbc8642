"""What every ``rayflex`` command shares: exit codes, the one-line error, and the checks of the
options of backend, image size and camera (all made before any work starts); the options
themselves are the table of ``driver.cli.options``."""

from __future__ import annotations

import sys

from ..backends import BACKENDS, BackendError
from ..scenes.camera import MAX_SIZE, Camera, check_fov, parse_number, parse_vec3

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


def check_backend(name: str) -> str:
    """Refuse an unknown backend name before any work (one-line BackendError)."""
    if name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    return name


def scene_info(scene) -> dict:
    """What a JSON says about where its scene came from: ``lumibench`` (docs/lumibench.md:
    the scene's ID, models, whether it is ``partial`` and the files missing) for a LumiBench
    scene, else nothing."""
    info = getattr(scene, "info", None)
    return {"lumibench": info()} if callable(info) else {}


def check_workers(args) -> None:
    """--workers (>= 1) and --scheduler: one place to run tiles or points, not both."""
    check_positive("--workers", args.workers)
    if args.workers > 1 and getattr(args, "scheduler", None):
        raise ValueError(f"--workers {args.workers} starts a local cluster and --scheduler "
                         f"{args.scheduler} names another: give one of them")


def check_flag_size(flag: str, value) -> None:
    """A --size/--width/--height value: None (not given) or 1..MAX_SIZE."""
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


def view_options(args, source) -> dict:
    """The checked camera flags of ``add_view`` as ``driver.scenes.scene.with_camera`` keywords
    (one-line ValueError if bad; the camera as a whole is validated once the scene is loaded,
    here already when position, look-at and up are all given)."""
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
