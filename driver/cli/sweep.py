"""``rayflex sweep``: a grid of design points on one workload (``driver.sweep``)."""

from __future__ import annotations

import os
from pathlib import Path

from .. import design
from ..core import outputs
from ..core.outputs import JSON, PNG, TABLE, Outputs
from ..power import announce_builds
from ..sweep import check_unit_points, models, plot, sweep, table, write_csv
from . import options
from .common import check_workers, note, wrote


def add_parser(subparsers):
    p = subparsers.add_parser(
        "sweep", help="a grid of design points on one workload: cycles, utilization, cache, "
                      "energy per ray",
        description="Measure every combination of the design-point options given as "
                    "comma-separated lists (--config all: every configuration) on one "
                    "workload: the frame's RT-unit cycles and utilization with the memory "
                    "hierarchy, per ray type the datapath ops, latency, bytes from each memory "
                    "level and energy per ray (docs/statistics.md, docs/rtunit.md). The workload "
                    "is traced once per BVH/workload option and replayed per RT-unit point; "
                    "every configuration's "
                    "responses are checked bit for bit against the trace's. Finished points are "
                    "kept in a results file, so an interrupted sweep resumes where it stopped.")
    options.add(p, "sweep", sweep=True)
    return p


def results_path(args) -> Path:
    if args.results:
        return Path(args.results).expanduser()
    for given in (args.json, args.csv, args.plot):
        if given:
            g = Path(given).expanduser()
            return g.with_name(f"{g.stem}.points.jsonl")
    return Path("rayflex_sweep.points.jsonl")


def run(args) -> int:
    from ..render import check_memory

    points = options.grid_from_args(args)
    unit = args.backend == "rtunit"
    if unit:
        check_unit_points(points)
    elif getattr(args, "unit_check", None) is not None:
        raise ValueError("--unit-check sets the RT unit in RTL: give --backend rtunit")
    check_workers(args)
    for size in {p.size for p in points if p.size}:
        check_memory(size * size)
    outs = Outputs()
    csv_path = outs.add("--csv", args.csv, TABLE) if args.csv else None
    if csv_path and csv_path.suffix.lower() != ".csv":
        raise ValueError(f"--csv {args.csv}: use a .csv file name")
    js = outs.add("--json", args.json, JSON) if args.json else None
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    res = results_path(args)
    parent = res.parent if str(res.parent) else Path(".")
    if res.is_dir() or not parent.is_dir() or not os.access(parent, os.W_OK) \
            or (res.exists() and not os.access(res, os.W_OK)):
        raise ValueError(f"--results {res}: cannot write there")
    if res.suffix.lower() != ".jsonl":
        raise ValueError(f"--results {res}: use a .jsonl file name")
    if res in outs.paths():
        raise ValueError(f"--results {res} names another output")
    progress = not args.no_progress
    if progress:
        note(f"sweep: {len(points)} design points "
             f"({', '.join(design.varied(points)) or 'one point'} varied) on "
             f"{points[0].scene} {points[0].workload}")
    announce_builds("sweep", models(points))
    doc = sweep(points, args.workers, args.scheduler, res, progress, args.ideal_replay, unit)
    with outs.commit():
        if csv_path:
            write_csv(doc, outs.temp(csv_path))
        if png:
            plot(doc, outs.temp(png))
            doc["plot"] = str(png)
        if js:
            outputs.write_json(doc, outs.temp(js))
    print(table(doc))
    wrote(outs.paths() + [res])
    return 0 if all(doc["bit_exact"].values()) else 1
