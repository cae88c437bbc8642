"""``rayflex timing``: Fmax and the critical path of each pipeline stage (``driver.timing``),
with the command line of ``rayflex area``."""

from __future__ import annotations

import json
from pathlib import Path

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
                    "required delay; default the OSU 0.18 um cells) and time it with OpenSTA: the "
                    "worst register-to-register path of each pipeline stage, the stage that "
                    "sets the clock, its cells and Fmax. Needs Debian's packages: "
                    f"{timing.INSTALL}. A configuration takes about ten minutes of one core "
                    "the first time (longer on a busy machine; the generic synthesis is shared "
                    "with rayflex area) and answers at once from the cache afterwards. See "
                    "docs/timing.md.")
    options.add(p, "timing")
    return p


def run(args) -> int:
    try:
        names, jobs = check_synthesis(args)
        lib = timing.check_tools(args.liberty)
        if names is None and not args.top:
            names = list(timing.DEFAULT_CONFIGS)
        if not args.abc_delay > 0:
            raise ValueError(f"--abc-delay must be > 0 ps, got {args.abc_delay:g}")
    except (area.AreaError, timing.TimingError) as e:
        raise ValueError(str(e)) from None
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    md = outs.add("--markdown", args.markdown, MARKDOWN) if args.markdown else None
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    power_doc = None
    if args.power_json:
        try:
            power_doc = json.loads(Path(args.power_json).read_text())
        except (OSError, ValueError) as e:
            raise ValueError(f"--power-json {args.power_json}: {e}") from None
        if power_doc.get("level") != "liberty" or not isinstance(power_doc.get("configs"), dict):
            raise ValueError(f"--power-json {args.power_json}: not a rayflex power --level "
                             "liberty document")
    ppng = outs.add("--power-plot", args.power_plot, PNG) if args.power_plot else None
    if ppng and not power_doc:
        raise ValueError("--power-plot needs --power-json")
    log = progress_of(args)
    if args.abc_delays is not None:
        return sweep(args, names, lib, outs, js, md, png, log)
    try:
        if args.top:
            src = area.snapshot(args.rev, area.source_list_for(args.top))
            r = timing.time_config(args.top, src, lib, args.abc_delay, not args.no_cache,
                                   args.timeout, log, top=args.top, script=args.abc_script)
            rep = timing.report({args.top: r}, src, area.rev_label(args.rev))
        else:
            rep = timing.time_all(names, lib, args.abc_delay, jobs, not args.no_cache,
                                  args.timeout, log, rev=args.rev, script=args.abc_script)
    except (area.AreaError, timing.TimingError) as e:
        raise ValueError(str(e)) from None
    rep["provenance"] = provenance()
    if power_doc:
        rep["power_vs_frequency"] = timing.power_vs_frequency(
            power_doc, {n: r["fmax_mhz"] for n, r in rep["configs"].items()})
        rep["paper_frequency"] = timing.PAPER_FREQUENCY
    table = timing.markdown(rep)
    print(table)
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
        if md:
            outs.temp(md).write_text(table + "\n")
        if png:
            timing.plot(rep, outs.temp(png))
        if ppng:
            timing.plot_power(rep["power_vs_frequency"], outs.temp(ppng),
                              "Power against clock on the open flow: energy per triangle op "
                              f"({Path(args.power_json).name}) x clock, up to each "
                              "configuration's Fmax; one netlist at every clock (the paper "
                              "synthesizes again per clock: 60-85 mW at 1 GHz, 15 nm)")
    wrote(outs.paths())
    return 0


def sweep(args, names, lib, outs, js, md, png, log) -> int:
    """``--abc-delays``: the area-against-clock study."""
    try:
        delays = [float(x) for x in args.abc_delays.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"--abc-delays: not a list of numbers: {args.abc_delays!r}") \
            from None
    if not delays or any(t <= 0 for t in delays):
        raise ValueError("--abc-delays: give delays > 0 ps")
    src = area.snapshot(args.rev, area.source_list_for(args.top) if args.top else None)
    try:
        res = timing.sweep_delays([args.top] if args.top else names, src, lib, delays,
                                   top=args.top or area.TOP, timeout=args.timeout,
                                   progress=log)
    except (area.AreaError, timing.TimingError) as e:
        raise ValueError(str(e)) from None
    doc = {"provenance": provenance(), "rtl_sha": area.rtl_sha(src),
           "rtl_rev": area.rev_label(args.rev), "liberty": str(lib), "delay_sweep": res,
           "paper": timing.PAPER_FREQUENCY}
    rows = ["| configuration | abc -D (ps) | 1 / -D (MHz) | 1 / -D / Fmax | Fmax (MHz) | "
            "area (mm²) | area vs first | cells |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for n, rs in res.items():
        for r in rs:
            rows.append(f"| {n} | {r['abc_delay_ps']:g} | {r['goal_mhz']:g} | "
                        f"{r['goal_vs_fmax']:.2f} | {r['fmax_mhz']:.1f} | "
                        f"{r['area_um2'] / 1e6:.4f} | {r['area_vs_first']:.4f} | {r['cells']:,} |")
    table = "\n".join(rows)
    print(table)
    with outs.commit():
        if js:
            outputs.write_json(doc, outs.temp(js))
        if md:
            outs.temp(md).write_text(table + "\n")
        if png:
            timing.plot_delays(res, outs.temp(png),
                                f"Area against ABC's required delay, {lib.stem} (0.18 um clocks "
                                "are not the paper's 15 nm clocks: x is relative to the Fmax "
                                "reached)")
    wrote(outs.paths())
    return 0
