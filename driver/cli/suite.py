"""``rayflex suite lumibench`` (or ``--suite FILE``): a benchmark's runs on the RTL, each checked
and replayed (``driver.suite``, docs/lumibench.md)."""

from __future__ import annotations

from pathlib import Path

from ..backends.rtunit import UNIT_BACKEND
from ..design import check_unit_reads, unit_flags
from ..scenes.camera import MAX_SIZE
from ..core.words import cell, plural
from ..scenes.lumibench import root
from ..suite import (SUITES, SUMMARY, Run, SuiteError, check_runs, lumibench_runs, read_suite,
                     run_suite)
from . import options
from .common import EXIT_CHECK, check_backend, check_positive, check_workers, wrote


def add_parser(subparsers):
    p = subparsers.add_parser(
        "suite", help="a benchmark's runs (LumiBench's scenes x shaders, or a TOML list): each "
                      "on the RTL, every ray checked against Embree, replayed on the RT unit",
        description="Make every run of a suite: trace the frame on the datapath, check every "
                    "ray against Embree (adjudicated with exact arithmetic), replay every "
                    "wavefront on the RT unit of the design point, and write NAME.json and "
                    "NAME.png per run into --out, then summary.json, summary.csv and "
                    "summary.png. Runs already in --out from the same source tree and design "
                    "point are kept, so an interrupted suite resumes. Exits 1 when any ray is "
                    "classified datapath-wrong.")
    options.add(p, "suite", groups=("datapath", "bvh", "rtunit"))
    return p


def run(args) -> int:
    if args.suite_name is None and args.suite is None:
        raise SuiteError(f"which suite? give a built-in suite's name ({', '.join(SUITES)}: "
                         f"rayflex suite {SUITES[0]}) or a TOML list of runs (--suite FILE)")
    if args.suite_name is not None and args.suite is not None:
        raise SuiteError(f"give the suite once: {args.suite_name} or --suite {args.suite}, "
                         "not both")
    if args.suite and (args.scenes or args.workloads):
        raise SuiteError("--scenes and --workloads choose LumiBench's runs; a --suite file "
                         "lists its own")
    check_backend(args.backend)
    unit_flags(args, args.backend)
    if args.backend == UNIT_BACKEND and args.ideal_replay:
        raise SuiteError(f"--backend {UNIT_BACKEND}: the RT unit in RTL times every frame "
                         "itself; --ideal-replay replays the rtl backend's frames")
    check_workers(args)
    for flag in ("size", "spp"):
        v = getattr(args, flag)
        if v is not None:
            check_positive(f"--{flag}", v, 1, MAX_SIZE if flag == "size" else 4096)
    base = options.from_args(args)
    skipped = {}
    if args.suite:
        name, runs = read_suite(args.suite)
        lroot = None
    else:
        name = args.suite_name
        lroot = root()
        split = lambda v: None if v is None else [x for x in v.split(",") if x.strip()]  # noqa
        runs, skipped = lumibench_runs(lroot, split(args.scenes), split(args.workloads))
        if not runs:
            raise SuiteError(f"no LumiBench run can be made from {lroot}: "
                             + "; ".join(f"{k}: {v}" for k, v in list(skipped.items())[:3]))
    runs = [Run(r.name, r.scene, r.workload, args.size or r.size, args.spp or r.spp,
                r.bounces, r.ao_rays, r.seed) for r in runs]
    points = check_runs(runs, base)
    if args.backend == UNIT_BACKEND:    # what the unit cannot be built with or read, at once
        base.backend_options(UNIT_BACKEND)
    for p in points:                    # a LumiBench scene (instanced) the unit cannot enter
        check_unit_reads(args.backend, p)
    from ..scenes.scene import resolve
    for r in runs:                          # every scene exists before any work
        try:
            resolve(r.scene)
        except ValueError as e:
            raise SuiteError(f"run {r.name}: {e}") from None
    out = Path(args.out or f"suite-{name}").expanduser()
    if out.exists() and not out.is_dir():
        raise SuiteError(f"--out {out} is a file, not a folder")
    summary = run_suite(name, runs, base, out, args.backend, lroot, args.workers, args.scheduler,
                        args.ideal_replay, skipped, not args.no_progress)
    print(table(summary))
    wrote([out / f for f in SUMMARY if (out / f).exists()])
    return EXIT_CHECK if summary["datapath_wrong"] else 0


def table(summary: dict) -> str:
    """The summary as text: one line per run, each column headed by one word (its JSON key's
    name where it has one), then what the columns are."""
    head = (f"{'run':<12} {'rays':>9} {'ops/ray':>8} {'util_mem':>8} {'B/ray':>7} "
            f"{'hit_rate':>8} {'energy/ray':>10} {'agree':>9} {'edge_tie':>8} "
            f"{'embree_wrong':>12} {'datapath_wrong':>14}")
    lines = [f"suite {summary['suite']}: {plural(len(summary['runs']), 'run')} in "
             f"{summary['wall_s']:.1f} s ({summary['runs_made']} made now)", head]
    for r in summary["runs"]:
        lines.append(f"{r['name']:<12} {r['rays']:>9,} {cell(r['ops_per_ray'], '.2f'):>8} "
                     f"{cell(r['utilization_memory'], '.3f'):>8} "
                     f"{cell(r['bytes_per_ray'], '.0f'):>7} {cell(r['hit_rate'], '.3f'):>8} "
                     f"{cell(r['energy_per_ray_signals'], '.3g'):>10} "
                     f"{cell(r['agree'], ','):>9} {cell(r['edge_tie'], ','):>8} "
                     f"{cell(r['embree_wrong'], ','):>12} {cell(r['datapath_wrong'], ','):>14}"
                     + ("  (partial scene)" if r["partial"] else ""))
    lines.append("(util_mem: the RT unit's utilization with the node memory; B/ray: bytes from "
                 "memory per ray; hit_rate: the node cache's; energy/ray: bit toggles per ray; "
                 "agree ... datapath_wrong: the rays of each class of the Embree check, "
                 "docs/lumibench.md; -: none)")
    for k, missing in summary.get("partial", {}).items():
        lines.append(f"partial: {k} without {plural(len(missing), 'missing file')}: "
                     + ", ".join(missing[:4]) + (", ..." if len(missing) > 4 else ""))
    for k, why in summary.get("skipped", {}).items():
        lines.append(f"not run: {k}: {why}")
    return "\n".join(lines)
