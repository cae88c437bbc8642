"""Area of the whole RT unit (``rtl/rf_rtunit.sv``) per module: ``rayflex area --top rf_rtunit``.

The unit is synthesized with Yosys keeping its hierarchy one level deep: the slang frontend reads
it with ``--keep-hierarchy``, the datapath instance becomes a black box, and every module the top
instantiates directly (ray buffer, stacks, fetch and node buffer, scheduler, response processing,
dividers, hit update) keeps its boundary (``keep_hierarchy``) while everything below it is
flattened into it; the top's own logic (slot control, arbiters, result register) is the
``control`` row. ``stat`` then counts each module's cells, categorized and weighted in gate
equivalents as the datapath's area flow does (``driver.area.categorize``). The datapath's row is
that flow's result for the configuration (``driver.area.synthesize``: from its cache when the
configuration has been synthesized, else synthesized now), so a unit report never synthesizes
the datapath twice; inside the unit the datapath keeps its boundary, so its cells are the same.

Storage is reported twice per module: ``sequential`` (the flip-flops the synthesis keeps) and
``memory_bits``: the bits of the arrays Yosys infers as memories at word level (after ``proc``),
i.e. what SRAM macros would hold (the ray records, the stack RAM, the node buffer; arrays with a
reset, such as the per-ray nearest t and counters, are registers and are not counted there).

The whole flow runs in the wheel's Yosys (Debian's Yosys 0.23 cannot read the elaborated
Verilog: it lacks the ``$bwmux`` cell). Results are cached beside the datapath's
(``$RAYFLEX_CACHE/area``), keyed by the script, the RTL and the Yosys version.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from . import area
from .backends import build as rtl_build
from .backends import rtunit
from .core.configs import BASELINE
from .design import BY_NAME

TOP = rtunit.UNIT_TOP
RECIPE = 1             # bump when the script below changes meaning
# the top's instances, in the order of the report: instance -> (row name, what it is), and the
# top's own logic (one table with the unit's energy per module, driver/backends/rtunit.py)
INSTANCES = rtunit.UNIT_INSTANCES
CONTROL = rtunit.UNIT_CONTROL
unit_params = rtunit.unit_params
NUMBERS = ("cells", "sequential", "inverter", "buffer", "logic", "ge", "memory_bits")


def sources(rev: str | None = None) -> list[tuple[str, bytes]]:
    """The unit's RTL snapshot: the datapath's files, the divider's and the unit's, in compile
    order, a file once (as ``driver.backends.rtunit.unit_sources`` lists them)."""
    out, seen = [], set()
    for lst in (rtl_build.SOURCE_LIST, rtl_build.DIV_SOURCE_LIST, rtunit.UNIT_SOURCE_LIST):
        for name, blob in area.snapshot(rev, lst):
            if name not in seen:
                seen.add(name)
                out.append((name, blob))
    return out


def script(params: dict[str, int], files: list[str]) -> str:
    """The Yosys script: the unit elaborated with its hierarchy, the datapath a black box, word-
    level statistics (memories), then the area flow's generic synthesis with the top's
    instances kept, and the per-module statistics."""
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    return (f"read_slang -j 1 --keep-hierarchy --top {TOP} {g} {' '.join(files)}\n"
            f"hierarchy -top {TOP}\n"
            f"blackbox {area.TOP}$*\n"
            f"hierarchy -top {TOP}\n"
            "proc\nopt_clean\n"
            "tee -q -o words.json stat -json\n"
            "setattr -mod -set keep_hierarchy 1 rf_rtu_*\n"
            f"synth -top {TOP} -flatten -noshare\n"
            "tee -q -o stat.json stat -json\n")


def instance_of(module: str) -> str | None:
    """The top's instance a module of the hierarchy-keeping synthesis stands for
    (``rf_rtu_stack$rf_rtunit.u_stack`` -> ``u_stack``), None for the top."""
    module = module.lstrip("\\")
    if module == TOP:
        return None
    return module.rsplit(".", 1)[-1]


def _gates(by_type: dict[str, int]) -> dict[str, int]:
    """Yosys' gate cells only (``$_..._``): not the kept instances nor ``$scopeinfo``."""
    return {t: n for t, n in by_type.items() if t.startswith("$_")}


def synthesize_unit(params: dict[str, int], srcs=None, cache: bool = True,
                    timeout: float | None = None, progress=None) -> dict:
    """Cells per module of the unit's own modules (the datapath a black box) for its build
    parameters (``driver.backends.rtunit.unit_params``); cached."""
    srcs = srcs if srcs is not None else sources()
    text = script(params, [n for n, _ in srcs])
    key = area.cache_key(f"unit{RECIPE}\n{text}", srcs, "wheel")
    entry = area.cache_root() / f"{TOP}-{key}.json"
    if cache and entry.is_file():
        res = json.loads(entry.read_text())
        res["cached"] = True
        return res
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rayflex-area-") as tmp:
        work = Path(tmp)
        area.materialize(work, srcs)
        area.run_yosys(work, text, timeout, progress=progress, label=TOP)
        words = json.loads((work / "words.json").read_text())["modules"]
        stat_doc = json.loads((work / "stat.json").read_text())
    stat = stat_doc["modules"]
    design = area.categorize(_gates(stat_doc["design"]["num_cells_by_type"]))["cells"]
    modules = {}
    for name, st in stat.items():
        inst = instance_of(name)
        row = area.categorize(_gates(st["num_cells_by_type"]))
        row["memory_bits"] = int(words.get(name, {}).get("num_memory_bits", 0))
        row["module"] = name.lstrip("\\").split("$", 1)[0]
        modules[inst or "top"] = row
    res = {"modules": modules, "design_cells": design,
           "synth_s": round(time.perf_counter() - t0, 1),
           "yosys": area.yosys_version("wheel"), "script": text.splitlines()[1:], "key": key,
           "rtl_sha": area.rtl_sha(srcs)}
    area.write_atomic(entry, json.dumps(res, indent=1) + "\n")
    res["cached"] = False
    return res


def report(config: str = BASELINE, rays: int = BY_NAME["rays_in_flight"].default,
           stack_depth: int = BY_NAME["stack_depth"].default,
           dividers: int = rtunit.DEFAULT_DIVIDERS, datapath: bool = True, rev: str | None = None,
           cache: bool = True, timeout: float | None = None, tool: str = "wheel",
           progress=None) -> dict:
    """The unit's area per module for one parameter set: its own modules synthesized here, the
    datapath's row from the area flow (``datapath`` False: left out, and out of the total).
    ``tool``: the Yosys of the datapath's synthesis when it is not cached (``area.resolve_yosys``;
    the unit's modules always go through the wheel)."""
    dp_params = area.config_params(config)
    params = rtunit.unit_params(dp_params, rays, stack_depth, dividers)   # one line if bad
    label = area.rev_label(rev)
    srcs = sources(None if rev is None else label)
    unit = synthesize_unit(params, srcs, cache, timeout, progress)
    if progress:
        progress(f"{TOP}: {sum(m['cells'] for m in unit['modules'].values()):,} cells outside "
                 f"the datapath in {unit['synth_s']} s{' (cached)' if unit['cached'] else ''}")
    rows: dict[str, dict] = {}
    dp_source = "left out"
    if datapath:
        dp_srcs = area.snapshot(None if rev is None else label)
        cached = area.is_cached(config, dp_srcs, tool)
        if not cached:
            area.announce("area of the datapath", [config], tool, 1, progress)
        r = area.synthesize(dp_params, cache=cache, timeout=timeout, name=config,
                            sources=dp_srcs, tool=tool, progress=progress)
        dp_source = "area cache" if r["cached"] else "synthesized"
        rows["datapath"] = {**{k: r[k] for k in NUMBERS if k != "memory_bits"},
                            "memory_bits": 0, "instance": "u_datapath", "module": area.TOP,
                            "source": f"rayflex area --configs {config} ({dp_source}, "
                                      f"{r['yosys']})"}
        if progress:
            progress(f"datapath {config}: {r['cells']:,} cells "
                     f"({'from the area cache' if r['cached'] else 'synthesized'})")
    mods = unit["modules"]
    for inst, (name, _) in INSTANCES.items():
        if inst in mods:
            rows[name] = {**mods[inst], "instance": inst, "source": "synthesized"}
    for inst in mods:                              # an instance this table does not name yet
        if inst not in INSTANCES and inst != "top":
            rows[inst] = {**mods[inst], "instance": inst, "source": "synthesized"}
    rows[CONTROL[0]] = {**mods["top"], "instance": TOP, "source": "synthesized"}
    total = {k: sum(r[k] for r in rows.values()) for k in NUMBERS}
    total["ge"] = round(total["ge"], 1)
    for r in rows.values():
        r["ge_share"] = round(r["ge"] / total["ge"], 4) if total["ge"] else None
    return {"top": TOP, "config": config, "rays_in_flight": rays, "stack_depth": stack_depth,
            "dividers": dividers, "datapath_source": dp_source,
            "yosys": unit["yosys"], "flow": "read_slang --keep-hierarchy; blackbox rayflex; "
            "proc; stat (memories); synth -flatten -noshare, the top's instances kept; stat",
            "rtl_sha": unit["rtl_sha"], "rtl_rev": label, "unit_synth_s": unit["synth_s"],
            "unit_cached": unit["cached"],
            "design_cells": unit["design_cells"], "modules": rows, "total": total}


def markdown(rep: dict) -> str:
    """The report as a markdown table, a row per module and the total."""
    what = {name: text for name, text in INSTANCES.values()} | {CONTROL[0]: CONTROL[1]}
    head = (f"RT unit {rep['config']}, RAYS {rep['rays_in_flight']}, "
            f"STACK_DEPTH {rep['stack_depth']}, DIVIDERS {rep['dividers']}; datapath: {rep['datapath_source']}\n\n")
    rows = ["| module | instance | cells | flip-flops | logic | est. GE | GE share | "
            "RAM bits (SRAM) | what |", "|---|---|---:|---:|---:|---:|---:|---:|---|"]
    for name, r in [*rep["modules"].items(), ("total", {**rep["total"], "instance": "",
                                                        "ge_share": 1.0})]:
        share = "–" if r.get("ge_share") is None else f"{r['ge_share']:.1%}"
        rows.append(f"| {name} | {r['instance']} | {r['cells']:,} | {r['sequential']:,} | "
                    f"{r['logic']:,} | {r['ge']:,.0f} | {share} | {r['memory_bits']:,} | "
                    f"{what.get(name, '')} |")
    return head + "\n".join(rows)
