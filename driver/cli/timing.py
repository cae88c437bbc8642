"""``rayflex timing``: Fmax and the critical path of each pipeline stage (``driver.timing``),
with the command line of ``rayflex area``."""

from __future__ import annotations

from .. import area, timing
from ..core import outputs
from ..core.outputs import JSON, MARKDOWN, PNG, Outputs
from ..core.provenance import provenance
from . import options
from .area import check_synthesis, progress_of
from .common import wrote


def add_parser(subparsers):
    p = subparsers.add_parser(
        "timing", help="Fmax and the critical path per pipeline stage (Yosys, OpenSTA; cached)",
        description="Map each configuration to a standard-cell liberty (Yosys and ABC with a "
                    "delay target; default the OSU 0.18 um cells) and time it with OpenSTA: the "
                    "worst register-to-register path of each pipeline stage, the stage that "
                    "sets the clock, its cells and Fmax. Needs Debian's packages: "
                    f"{timing.INSTALL}. A configuration takes minutes the first time (the "
                    "generic synthesis is shared with rayflex area) and answers at once from "
                    "the cache afterwards. See docs/timing.md.")
    options.add(p, "timing")
    return p


def run(args) -> int:
    try:
        names, jobs = check_synthesis(args)
        lib = timing.check_tools(args.liberty)
        if names is None and not args.top:
            names = list(timing.DEFAULT_CONFIGS)
        if not args.delay_target > 0:
            raise ValueError(f"--delay-target must be > 0 ps, got {args.delay_target:g}")
    except (area.AreaError, timing.TimingError) as e:
        raise ValueError(str(e)) from None
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    md = outs.add("--markdown", args.markdown, MARKDOWN) if args.markdown else None
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    log = progress_of(args)
    try:
        if args.top:
            src = area.snapshot(args.rev)
            r = timing.time_config(args.top, src, lib, args.delay_target, not args.no_cache,
                                   args.timeout, log, top=args.top)
            rep = timing.report({args.top: r}, src, area.rev_label(args.rev))
        else:
            rep = timing.time_all(names, lib, args.delay_target, jobs, not args.no_cache,
                                  args.timeout, log, rev=args.rev)
    except (area.AreaError, timing.TimingError) as e:
        raise ValueError(str(e)) from None
    rep["provenance"] = provenance()
    table = timing.markdown(rep)
    print(table)
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
        if md:
            outs.temp(md).write_text(table + "\n")
        if png:
            timing.plot(rep, outs.temp(png))
    wrote(outs.paths())
    return 0
