"""``rayflex`` command line: one argparse subcommand per module in ``COMMANDS``.

A subcommand is a module (or an object) with ``add_parser(subparsers)`` (adds and returns its
parser) and ``run(args) -> int`` (the exit code). To add one, write the module and add one line
to ``COMMANDS``. Helpers every command shares (backend, size, output and progress options, the
one-line error) are in ``driver.cli.common``.

Exit status (the one table; also in ``--help`` and docs/faults.md): see ``EXIT_CODES``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from importlib.metadata import PackageNotFoundError, version as dist_version

from ..core import outputs
from ..core.errors import Terminated
from ..scenes.lumibench import using_root
from .common import (EXIT_CHECK, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED,
                     EXIT_USAGE, PROG, one_line)
from .interrupt import late_note, watch

# name -> "module" or "module:attribute"; each provides add_parser(subparsers) and run(args)
COMMANDS = {
    "render": "driver.cli.render",
    "knn": "driver.cli.knn",
    "bench": "driver.cli.bench",
    "sweep": "driver.cli.sweep",
    "suite": "driver.cli.suite",
    "power": "driver.cli.power",
    "study": "driver.cli.study",
}

EXIT_CODES = {
    EXIT_OK: "success",
    EXIT_CHECK: "a result check failed (render --check-embree, suite: rays where exact "
                "arithmetic finds the datapath wrong; knn: neighbours differ beyond float32 "
                "rounding)",
    EXIT_USAGE: "bad input, usage or environment error (one line on stderr; nothing written)",
    EXIT_INTERNAL: "internal error, a bug (one line; RAYFLEX_TRACEBACK=1 shows the traceback)",
    EXIT_INTERRUPTED: "interrupted (SIGINT, Ctrl-C); nothing written, builds cleaned up (once "
                      "the outputs are written, a signal no longer interrupts: the command "
                      "ends as it would have, its outputs complete)",
    EXIT_TERMINATED: "terminated (SIGTERM); nothing written, builds cleaned up (likewise)",
}

ENVIRONMENT = {
    "RAYFLEX_CACHE": "the tool's cache (default ~/.cache/rayflex): Verilator models in "
                     "verilator/, synthesized netlists in area/ and power/, LumiBench scenes "
                     "in scenes/",
    "RAYFLEX_PGO": "0: build RTL models in one pass, without profile-guided optimisation",
    "RAYFLEX_THREADS": "threads (each its own model) the rtl backend streams a big traversal "
                       "step through (default: the CPUs the process may use; 1 in the Dask "
                       "workers the tool starts)",
    "CXX": "C++ compiler for the RTL builds (default g++, else clang++)",
    "RAYFLEX_TRACEBACK": "1: print the traceback of an internal error",
    "LUMIBENCH_ROOT": "a clone of LumiBench's repository, for scenes lumibench:ID",
    "RAYFLEX_SCENE_CACHE": "LumiBench scene cache: a folder (default: RAYFLEX_CACHE/scenes), "
                           "or 0: read the OBJ files every time",
}


def version() -> str:
    try:
        return dist_version("rayflex-driver")
    except PackageNotFoundError:
        return "unknown (not installed)"


def epilog() -> str:
    codes = "\n".join(f"  {code:<4} {text}" for code, text in EXIT_CODES.items())
    env = "\n".join(f"  {name:<18} {text}" for name, text in ENVIRONMENT.items())
    return f"exit status:\n{codes}\n\nenvironment:\n{env}"


def main(argv=None) -> int:
    """Entry point of the ``rayflex`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(argv) if argv is not None else sys.argv[1:]   # what a JSON may record
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    codes = {signal.SIGINT: ("interrupted", EXIT_INTERRUPTED),
             signal.SIGTERM: ("terminated", EXIT_TERMINATED)}
    # SIGTERM raises Terminated so builds and output writes clean up; both signals end the
    # process within about a second even inside a native kernel (driver.cli.interrupt)
    outputs.forget_written()
    with watch(PROG, codes, Terminated, outputs.written) as watched:
        try:
            with using_root(args.lumibench_root):
                code = int(args.handler.run(args) or 0)
            if watched.late:                     # a signal after the outputs were written
                print(f"{PROG}: {late_note(watched.late)}", file=sys.stderr)
            return code
        except KeyboardInterrupt:
            print(f"{PROG}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        except Terminated:
            print(f"{PROG}: terminated", file=sys.stderr)
            return EXIT_TERMINATED
        except (ValueError, OSError) as e:
            print(f"{PROG}: error: {one_line(e)}", file=sys.stderr)
            return EXIT_USAGE
        except MemoryError:
            print(f"{PROG}: error: out of memory (try a smaller --size)", file=sys.stderr)
            return EXIT_USAGE
        except Exception as e:  # noqa: BLE001  (a bug: one line unless asked for the traceback)
            if os.environ.get("RAYFLEX_TRACEBACK") == "1":
                raise
            print(f"{PROG}: internal error: {type(e).__name__}: {one_line(e)} "
                  "(RAYFLEX_TRACEBACK=1 shows the traceback)", file=sys.stderr)
            return EXIT_INTERNAL


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Workload driver for the RayFlex ray-tracing datapath.",
        epilog=epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    from .options import SHARED     # trimesh, embreex: every command's options need them
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for target in COMMANDS.values():
        handler = _load(target)
        p = handler.add_parser(sub)
        SHARED["lumibench_root"].add(p)
        p.formatter_class = argparse.RawDescriptionHelpFormatter
        if p.epilog is None:
            p.epilog = epilog()
        p.set_defaults(handler=handler)
    return parser


def _load(target: str):
    module, _, attr = target.partition(":")
    obj = importlib.import_module(module)
    return getattr(obj, attr) if attr else obj


