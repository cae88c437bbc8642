"""Running the measurements of ``driver.power`` (its docstring tells the method): the
configurations, one model's steady-state energy per operation (``measure``), a level over
configurations on every core (``run_level``), the netlists, and which models a command builds
first.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, ThreadPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from queue import Empty

import numpy as np
from tqdm import tqdm

from ..backends import build as rtl_build
from ..backends import verilate
from ..core.datapath import default_latency
from ..core.wire import pack_requests
from . import activity, liberty, netlist, stimulus
from .netlist import STAGE_LABELS, _area

LEVELS = ("signals", "gates", "liberty")
IDLE_CYCLES = 200
DEFAULT_OPS = 100


def configs() -> dict[str, tuple[int, int]]:
    """The four base configurations (what ``--config all`` measures): name -> (EXTENDED,
    DISJOINT), the table of driver/area.py."""
    return dict(_area().CONFIGS)


def all_configs() -> list[str]:
    """Every configuration power measures: the four, each with the q8 decode (``-q8``,
    COMPRESSED) and each of those with TRANSFORM (``-xf``), the extended ones with shared request
    registers (``-shared``, SHARED), and each of those rounded once in the box slab and the edge
    functions (``-fused``, FUSED), as driver/area.py names them."""
    area = _area()
    names = [*area.ALL_CONFIGS, *area.XF_CONFIGS]
    names += [n + area.SHARED_SUFFIX for n in names if n.startswith("extended")]
    return names + [n + area.FUSED_SUFFIX for n in names]


def build_params(cfg: str) -> dict[str, int]:
    """The build parameters of configuration ``cfg`` without the latency (EXTENDED, DISJOINT,
    and COMPRESSED / TRANSFORM when set): what its gate netlist is synthesized with."""
    return _area().config_params(cfg)


def own_latency(cfg: str) -> int:
    """The configuration's own pipeline depth (11, 12 with the q8 decode): its gate netlist's."""
    return default_latency(bool(build_params(cfg).get("COMPRESSED")))


def params_of(cfg: str, latency: int | None = None) -> dict[str, int]:
    """The build parameters of the traced model of ``cfg`` (``latency`` None: its own)."""
    return {**build_params(cfg), "LATENCY": own_latency(cfg) if latency is None else latency}


def netlist_cached(cfg: str) -> bool:
    """Whether the gate netlist of configuration ``cfg`` is in the cache (no synthesis)."""
    return netlist.is_cached(build_params(cfg))


def check_ops(ops, cfgs) -> None:
    """A one-line ValueError if an operation of ``ops`` is unknown or cannot run on a
    configuration of ``cfgs`` (e.g. box_q8 without the q8 decode)."""
    why = {"EXTENDED": "the extended operations (an extended-* configuration)",
           "COMPRESSED": "the q8 decode (a -q8 configuration)",
           "TRANSFORM": "TRANSFORM (a -xf configuration)"}
    for op in ops:
        if op not in stimulus.OPS:
            raise ValueError(f"--op {op}: unknown operation; choose from "
                             f"{', '.join(stimulus.OPS)}")
        for cfg in cfgs:
            if op not in stimulus.measurable(build_params(cfg)):
                raise ValueError(f"--op {op}: configuration {cfg} cannot run it; it needs "
                                 f"{why[stimulus.needs(op)]}")


def measure(model, params: dict, n: int = DEFAULT_OPS, seed: int = 0,
            idle_cycles: int = IDLE_CYCLES, ops=None, progress=None) -> dict:
    """Energy per operation of one model (``activity.SignalModel``/``GateModel``, or a liberty
    pricing of a gate model: anything with ``run``, ``weight``, ``stage``, ``unit``) of a
    configuration with build parameters ``params`` (``ops``: the operation types to measure,
    default every one it runs).

    Returns {op: {toggles_per_op, energy_per_op, unit, cycles_per_op, stages}, "idle_per_cycle":
    {...}} plus {op: {"pending": reason}} for operations the RTL cannot run yet."""
    if n < 1:
        raise ValueError(f"--ops must be >= 1, got {n}")
    runs = stimulus.measurable(params)
    names = list(ops or runs)
    bad = [o for o in names if o not in runs]
    if bad:
        raise ValueError(f"operation {bad[0]} needs the build parameter "
                         f"{stimulus.needs(bad[0])}")
    w = model.weight
    counted = w > 0
    out: dict = {}
    first = pack_requests(stimulus.requests(names[0], n, seed))
    c, t = model.idle(first, idle_cycles)
    idle = t / c
    out["idle_per_cycle"] = {"toggles": float(idle[counted].sum()),
                             "energy": float(w @ idle), "unit": model.unit,
                             "cycles": int(c)}
    if hasattr(model, "per_cycle"):
        out["idle_per_cycle"]["energy_total"] = out["idle_per_cycle"]["energy"] + model.per_cycle
    for op in names:
        if progress:
            progress(op)
        streams = [pack_requests(stimulus.requests(op, 2 * n, [seed, k]))
                   for k in range(model.streams)]
        ops_done, cycles, dt = model.pair(streams)
        d = dt - idle * cycles
        e = d * w
        total = float(e.sum())
        shares = np.bincount(model.stage, weights=e, minlength=len(STAGE_LABELS))
        out[op] = {"toggles_per_op": float(d[counted].sum() / ops_done),
                   "energy_per_op": total / ops_done, "unit": model.unit,
                   "cycles_per_op": cycles / ops_done, "ops": ops_done,
                   "streams": len(streams),
                   "stages": {s: round(float(v / total), 4) if total else 0.0
                              for s, v in zip(STAGE_LABELS, shares)}}
        if hasattr(model, "per_cycle"):      # liberty: + clock pins and leakage of its cycles
            out[op]["energy_per_op_total"] = out[op]["energy_per_op"] \
                + model.per_cycle * cycles / ops_done
    for op, why in stimulus.pending().items():
        out[op] = {"pending": why}
    return out


def run_level(level: str, cfgs: list[str], n: int = DEFAULT_OPS, seed: int = 0,
              liberty_path: str | None = None, progress=None, latency: int | None = None,
              ops=None) -> dict:
    """Measure ``cfgs`` at ``level``; returns the report's ``configs`` part and notes.
    ``latency``: the pipeline depth of the signals level's models (None: each configuration's
    own; the gate netlists have their own); ``ops``: the operation types to measure (default:
    every one the configuration runs)."""
    if level == "signals":
        out = {}
        for cfg in cfgs:
            t0 = time.perf_counter()
            p = params_of(cfg, latency)
            names = ops or stimulus.measurable(p)
            model = activity.SignalModel(p)   # a first build reports its steps: before the bar
            bar = _bar(progress, {cfg: len(names)})
            out[cfg] = measure(model, p, n, seed, ops=ops,
                               progress=(lambda op, c=cfg: bar.step(c, op)) if bar else None)
            if bar:
                bar.close()
            out[cfg]["latency"] = p["LATENCY"]
            out[cfg]["seconds"] = round(time.perf_counter() - t0, 1)
        return {"configs": out}
    nets = _netlists(cfgs, progress)
    notes = {cfg: {"seconds": nets[cfg].synth_s, "cached": nets[cfg].cached,
                   "cells": sum(nets[cfg].cells.values())} for cfg in cfgs}
    return {"configs": _measure_nets(level, nets, n, seed, liberty_path, progress, ops),
            "synth_s": notes}


def _measure_net(level, cfg, net, n, seed, liberty_path, step=None, ops=None) -> dict:
    """One configuration at level ``gates`` or ``liberty`` (``step(cfg, op)``: progress)."""
    t0 = time.perf_counter()
    model = activity.GateModel(net)
    if level == "liberty":
        model = liberty.price(model, net, liberty_path)
    out = measure(model, params_of(cfg), n, seed, ops=ops,
                  progress=(lambda op: step(cfg, op)) if step else None)
    out["latency"] = own_latency(cfg)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    if level == "liberty":
        out["leakage"] = model.leakage
    return out


_steps = None                         # a child process's progress queue


def _child_init(queue):
    global _steps
    _steps = queue


def _child_measure(*args, ops=None) -> dict:
    return _measure_net(*args, step=lambda cfg, op: _steps.put((cfg, op)), ops=ops)


def _measure_nets(level, nets: dict, n, seed, liberty_path, progress=None, ops=None) -> dict:
    """Measure every configuration's netlist, side by side in one process per core (the gate
    simulation is numpy on one thread; the biggest netlist starts first), so a warm run takes
    about its longest configuration, not their sum. The numbers do not depend on where a
    configuration ran: each is a deterministic function of its netlist, ``n`` and ``seed``."""
    cfgs = list(nets)
    bar = _bar(progress, {c: len(ops or stimulus.measurable(params_of(c))) for c in cfgs})
    step = bar.step if bar else None
    lanes = _lanes(len(cfgs))
    try:
        if lanes == 1:
            return {c: _measure_net(level, c, nets[c], n, seed, liberty_path, step, ops)
                    for c in cfgs}
        ctx = mp.get_context("spawn")          # the parent may hold threads: never fork it
        queue = ctx.Queue()
        order = sorted(cfgs, key=lambda c: -sum(nets[c].cells.values()))
        pending: set = set()
        pool = ProcessPoolExecutor(lanes, mp_context=ctx, initializer=_child_init,
                                   initargs=(queue,))
        try:
            jobs = {c: pool.submit(_child_measure, level, c, nets[c], n, seed, liberty_path,
                                   ops=ops)
                    for c in order}
            pending = set(jobs.values())
            while pending:
                done, pending = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                for f in done:
                    try:
                        f.result()             # an error stops the run now
                    except BrokenProcessPool:
                        raise OSError("a gate-level measurement process died (out of memory? "
                                      "--config NAME measures one configuration at a time)"
                                      ) from None
                while True:
                    try:
                        msg = queue.get_nowait()
                    except Empty:
                        break
                    if step:
                        step(*msg)
            return {c: jobs[c].result() for c in cfgs}
        finally:
            pool.shutdown(wait=not pending, cancel_futures=True)
    finally:
        if bar:
            bar.close()


def _netlists(cfgs: list[str], progress=None) -> dict:
    """The gate netlists of ``cfgs``: cache misses are synthesized side by side, one Yosys
    process per core (Yosys is single-threaded; the longest synthesis, by the last recorded
    times, starts first), so a cold run takes about its longest synthesis, not their sum."""
    wanted = {c: build_params(c) for c in cfgs}
    order = sorted(cfgs, key=lambda c: -netlist.estimate(wanted[c]))
    pool = ThreadPoolExecutor(_lanes(len(cfgs)), thread_name_prefix="rayflex-synth")
    try:
        jobs = {c: pool.submit(netlist.synthesize, wanted[c], progress=progress) for c in order}
        return {c: jobs[c].result() for c in cfgs}
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


class _WouldBuild(Exception):
    pass


def uncached_models(models) -> list[str]:
    """Which of ``models`` ((kind, params): kind "rtl" for the harness of the rtl backend and
    the RT-unit replay, "signals" for the traced model of ``power --level signals``) are not in
    the build cache: their descriptions, to say before building how many builds will run."""
    def refuse(*a, **k):
        raise _WouldBuild()

    missing = []
    real = verilate.cached_build
    verilate.cached_build = refuse
    try:
        for kind, params in models:
            try:
                (rtl_build.build_harness if kind == "rtl"
                 else activity.SignalModel.library)(params)
            except _WouldBuild:
                missing.append(" ".join([kind, *(f"{k}={v}" for k, v in params.items()
                                                 if v or k in ("EXTENDED", "DISJOINT"))]))
    finally:
        verilate.cached_build = real
    return missing


def announce_builds(command: str, models, log=None) -> list[str]:
    """Say on stderr how many of ``models`` (see ``uncached_models``) will be built first."""
    missing = uncached_models(models)
    if missing:
        msg = (f"{command}: {len(missing)} of {len(models)} models to build first (a first "
               f"build takes about a minute each): {', '.join(missing)}")
        (log or (lambda m: print(f"rayflex: {m}", file=sys.stderr, flush=True)))(msg)
    return missing


def _lanes(jobs: int) -> int:
    """Side-by-side lanes for ``jobs`` single-threaded jobs: one per core, at most one per job."""
    return max(1, min(jobs, os.cpu_count() or 1))


def _have_yosys() -> bool:
    try:
        _area().yosys_command()
    except Exception:          # noqa: BLE001  (AreaError: not installed)
        return False
    return True


class _Bar:
    """One bar over the operation types of every configuration being measured."""

    def __init__(self, per_cfg: dict[str, int]):
        self.bar = tqdm(total=sum(per_cfg.values()), desc="measuring", unit="op type",
                        leave=False, file=sys.stderr)
        self.current: dict[str, str] = {}

    def step(self, cfg, op):
        if cfg in self.current:       # called before each operation type
            self.bar.update(1)
        self.current[cfg] = op
        self.bar.set_postfix_str(", ".join(f"{c} {o}" for c, o in self.current.items()))

    def close(self):
        self.bar.update(self.bar.total - self.bar.n)
        self.bar.close()


def _bar(progress, per_cfg):
    return _Bar(per_cfg) if progress else None


def parse_configs(text: str) -> list[str]:
    """The configurations of ``--config``: a comma-separated list of ``all_configs()`` names,
    or ``all``: the four base configurations."""
    items = list(dict.fromkeys(x.strip() for x in str(text).split(",") if x.strip()))
    if items == ["all"]:
        return list(configs())
    if not items:
        raise ValueError("--config: give at least one configuration")
    for c in items:
        if c not in all_configs():
            raise ValueError(f"--config: unknown value {c!r}; choose from all, "
                             f"{', '.join(all_configs())}")
    return items

