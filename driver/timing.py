"""Timing in the open: Fmax and the critical path of each pipeline stage with OpenSTA.

A configuration's generic gate netlist (the area flow's native synthesis, ``driver.area``: the
wheel's slang frontend, the system's Yosys, cached and shared with ``rayflex area``) is mapped to
a standard-cell liberty (default: the OSU 0.18 um cells of Debian's ``qflow-tech-osu018``)::

    read_rtlil generic.il
    dfflibmap -liberty LIB
    abc -D DELAY_PS -constr constr.txt -liberty LIB     # delay-driven map, buffering, sizing
    opt_clean; stat -liberty LIB; write_verilog netlist.v

and OpenSTA (Debian's ``opensta``, the ``sta`` binary) times the netlist under one ideal clock.
Every flip-flop is named by the register bit it holds (its Q net: ``g_reg[3].u_reg.main_q``...),
so the paths can be grouped by the pipeline register they end at: the paths ending at stage
register R(k) are stage Sk's logic (R(k-1) -> Sk -> R(k)). Per stage the report gives the worst
register-to-register path (arrival + the flip-flop's setup time: the least clock period that
stage allows), and Fmax = 1 / the largest of them; the worst path's cells are listed.

Results are cached (``$RAYFLEX_CACHE/timing``), keyed by the generic netlist, this recipe, the
liberty file, ABC's required delay and the tools' versions.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from . import area
from .backends.cache import cache_root as tool_cache
from .core.configs import BASELINE, CONFIGS
from .plotting import wrap
from .power.liberty import DEBIAN_OSU018

RECIPE = 1                 # bump when the mapping script or the STA script changes meaning
INSTALL = "apt-get install opensta yosys qflow-tech-osu018"
# the configurations ``rayflex timing`` reports by default: the paper's four, the q8 decode and
# TRANSFORM on the baseline
DEFAULT_CONFIGS = (*CONFIGS, "baseline-unified-q8", "baseline-unified-xf")
# ABC's required delay (ps, abc -D): the paper's 1 GHz, out of reach in 0.18 um, so ABC maps each cone for
# its least delay
DEFAULT_DELAY_PS = 1000
# the constraint OpenSTA times against (ns): loose, so that every path has a positive slack and
# the least period of a path is this minus its slack
PERIOD_NS = 1000.0
# ABC's view of the boundary: inputs driven by a small inverter, each output a small load (pF)
CONSTRAINTS = "set_driving_cell INVX1\nset_load 0.02\n"
CLOCK_PORT = "clk_i"
# ABC's mapping scripts (``abc -D``'s required delay in each): "default" is Yosys's own for a
# liberty with a delay target (equivalence sweeping, choices, then delay mapping, buffering and
# sizing); "fast" maps the structurally hashed logic directly (no sweeping, no choices), for a
# design whose sweep does not finish (exact wide multipliers): compare like with like, not against
# the default script's figures
ABC_SCRIPTS = {
    "default": None,
    "fast": "strash\n&get -n\n&st\n&nf -D {D}\n&put\nbuffer\nupsize -D {D}\ndnsize -D {D}\n"
            "stime -p\n",
}


class TimingError(RuntimeError):
    """A tool missing or failing (one-line message)."""


# ------------------------------------------------------------------------------------------------
# tools

def sta_binary() -> str | None:
    return shutil.which("sta")


def check_tools(liberty: str | None = None) -> Path:
    """The liberty file to map to; one line naming the packages when a tool is missing."""
    missing = [name for name, ok in (("sta (OpenSTA)", sta_binary()),
                                     ("yosys", area.native_yosys())) if not ok]
    lib = Path(liberty) if liberty else DEBIAN_OSU018
    if not lib.is_file():
        missing.append(f"liberty {lib}" if liberty else "the OSU 0.18 um liberty")
    if missing:
        if liberty and missing == [f"liberty {lib}"]:
            raise TimingError(f"--liberty: {lib} not found")
        raise TimingError(f"timing needs {', '.join(missing)}: {INSTALL}")
    try:
        area.yosys_command()
    except area.AreaError as e:
        raise TimingError(str(e)) from None
    return lib


_STA_VERSION: list[str] = []


def sta_version() -> str:
    if not _STA_VERSION:
        r = subprocess.run([sta_binary(), "-version"], capture_output=True, text=True, timeout=60)
        _STA_VERSION.append("OpenSTA " + (r.stdout.strip() or "?"))
    return _STA_VERSION[0]


def cache_root() -> Path:
    return tool_cache() / "timing"


def _file_sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


# ------------------------------------------------------------------------------------------------
# stages

# register bit (the Q net of a flip-flop, without its bit index) -> the stage whose logic feeds it
_STAGE_RULES = (
    (re.compile(r"g_reg\[(\d+)\]\.u_reg\.(main|skid)_q$"), lambda m: _reg_stage(int(m[1]))),
    (re.compile(r"g_decode\.u_dec_reg\.(main|skid)_q$"), lambda m: "S0"),
    (re.compile(r"u_in_reg\.(main|skid)_q$"), lambda m: "in"),
    (re.compile(r"u_out_reg\.(main|skid)_q$"), lambda m: "out"),
    (re.compile(r"(main|skid)_valid_q$"), lambda m: "control"),
    (re.compile(r"^(?:g_\w+\.)?u_s(\d+)\."), lambda m: f"S{int(m[1])}"),
)
NUM_STAGES = 9            # compute stages S1..S9 (rtl/rayflex.sv); later registers pad the latency
# the order a report lists stages in
STAGE_ORDER = ("in", *(f"S{k}" for k in range(NUM_STAGES + 1)), "pass", "out", "control",
               "outputs", "other")
STAGE_MEANING = {
    "in": "request ports -> input register", "S0": "q8 decode", "S1": "origin subtract",
    "S2": "scale multiply", "S3": "near/far x, y", "S4": "near/far z", "S5": "clamp, u v w",
    "S6": "slab hit", "S7": "sort: accumulate", "S8": "sort: t, count", "S9": "sort: tri hit",
    "pass": "pass-through registers", "out": "response format", "control": "valid/ready",
    "outputs": "registers -> output ports", "other": "other registers",
}


def _reg_stage(k: int) -> str:
    return f"S{k + 1}" if k < NUM_STAGES else "pass"


def stage_of(net: str) -> str:
    """The stage whose logic ends at the register holding ``net`` (``\\g_reg[2].u_reg.main_q
    [17]`` -> "S3")."""
    name = re.sub(r"\s*\[\d+\]$", "", net.strip().lstrip("\\"))
    for pattern, stage in _STAGE_RULES:
        m = pattern.search(name)
        if m:
            return stage(m)
    return "other"


_CELL = re.compile(r"^\s*(\w+)\s+(\S+)\s*\((.*?)\);", re.S | re.M)
_PIN = re.compile(r"\.(\w+)\(([^()]*)\)")


def sequential_cells(liberty: Path) -> set[str]:
    """Names of the liberty's flip-flop and latch cells."""
    text = liberty.read_text(errors="replace")
    out = set()
    starts = [(m.start(), m[1]) for m in re.finditer(r'\bcell\s*\(\s*"?([\w$]+)"?\s*\)', text)]
    for (a, name), (b, _) in zip(starts, starts[1:] + [(len(text), "")]):
        if re.search(r"\b(ff|latch)\s*\(", text[a:b]):
            out.add(name)
    return out


def registers(netlist: str, seq: set[str]) -> dict[str, tuple[str, str]]:
    """Flip-flop instance -> (its D pin as OpenSTA names it, the Q net), from a netlist written
    by ``write_verilog -noattr -noexpr``."""
    out = {}
    for m in _CELL.finditer(netlist):
        if m[1] not in seq:
            continue
        pins = dict(_PIN.findall(m[3]))
        inst = m[2]
        if "D" in pins and "Q" in pins:
            out[inst] = (pins["Q"].strip(), pins["D"].strip())
    return out


# ------------------------------------------------------------------------------------------------
# mapping and STA

def map_script(top: str, liberty: Path, delay_ps: float, script: str = "default") -> str:
    """The Yosys script that maps ``generic.il``; with an ABC ``script`` other than "default"
    its ``abc`` reads ``map.abc`` (``abc_script``)."""
    lib = liberty.name
    abc = (f"abc -D {delay_ps:g}" if ABC_SCRIPTS[script] is None else "abc -script map.abc")
    return ("read_rtlil generic.il\n"
            f"hierarchy -top {top}\n"
            f"dfflibmap -liberty {lib}\n"
            f"{abc} -constr constr.txt -liberty {lib}\n"
            "opt_clean\n"
            f"tee -q -o stat.txt stat -liberty {lib}\n"
            "write_verilog -noattr -noexpr netlist.v\n")


def abc_script(script: str, delay_ps: float) -> str | None:
    """The text of ABC script ``script`` at required delay ``delay_ps`` (None: Yosys's own)."""
    if script not in ABC_SCRIPTS:
        raise TimingError(f"ABC script {script!r}: choose from {', '.join(ABC_SCRIPTS)}")
    text = ABC_SCRIPTS[script]
    return None if text is None else text.replace("{D}", f"{delay_ps:g}")


def _sta_tcl(top: str, liberty: Path, groups: dict[str, list[str]], clocked: bool) -> str:
    lines = [f"read_liberty {liberty.name}", "read_verilog netlist.v", f"link_design {top}"]
    if clocked:
        lines += [f"create_clock -name clk -period {PERIOD_NS:g} [get_ports {CLOCK_PORT}]",
                  "set_input_delay 0 -clock clk [delete_from_list [all_inputs] "
                  f"[get_ports {CLOCK_PORT}]]"]
    else:
        lines += [f"create_clock -name clk -period {PERIOD_NS:g}",
                  "set_input_delay 0 -clock clk [all_inputs]"]
    lines.append("set_output_delay 0 -clock clk [all_outputs]")
    for stage, pins in groups.items():
        lines.append(f'puts "@@GROUP {stage}"')
        to = "[all_outputs]" if stage == "outputs" else \
            "[get_pins {" + " ".join(_tcl_name(p) for p in pins) + "}]"
        lines.append(f"report_checks -path_delay max -format full -digits 3 -to {to}")
    lines.append('puts "@@END"')
    return "\n".join(lines) + "\n"


def _tcl_name(pin: str) -> str:
    return pin.replace("\\", "\\\\").replace("[", "\\[").replace("]", "\\]")


_STEP = re.compile(r"^\s*(-?[\d.]+)\s+(-?[\d.]+)\s+([\^v])\s+(\S+?)/(\w+)\s+\((\w+)\)\s*$")


def parse_report(text: str) -> dict | None:
    """One ``report_checks -format full`` path: start, end, the cells on it, arrival, setup,
    slack; None when the group has no path."""
    if "No paths" in text or "Startpoint" not in text:
        return None
    start = re.search(r"Startpoint:\s*(\S+)", text)[1]
    end = re.search(r"Endpoint:\s*(\S+)", text)[1]
    arrival = float(re.search(r"(-?[\d.]+)\s+data arrival time", text)[1])
    slack = float(re.search(r"(-?[\d.]+)\s+slack", text)[1])
    setup = re.search(r"(-?[\d.]+)\s+(-?[\d.]+)\s+library setup time", text)
    steps = []
    data = text.split("data arrival time")[0]
    for line in data.splitlines():
        m = _STEP.match(line)
        if m:
            steps.append({"instance": m[4], "pin": m[5], "cell": m[6],
                          "incr_ns": float(m[1]), "at_ns": float(m[2])})
    # a flip-flop's clock pin is a line of its own before its Q: keep one line per cell
    steps = [st for i, st in enumerate(steps)
             if not (i + 1 < len(steps) and steps[i + 1]["instance"] == st["instance"])]
    return {"start": start, "end": end, "arrival_ns": arrival,
            "setup_ns": -float(setup[1]) if setup else 0.0,
            "min_period_ns": round(PERIOD_NS - slack, 3), "steps": steps}


def _run(cmd, cwd: Path, timeout: float | None, what: str) -> str:
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, text=True, start_new_session=True)
    with area._LIVE_LOCK:
        area._LIVE.add(proc)
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        raise TimingError(f"{what} took longer than {timeout} s") from None
    finally:
        area.kill(proc)
        proc.wait()
        with area._LIVE_LOCK:
            area._LIVE.discard(proc)
    if proc.returncode:
        errs = [ln for ln in out.splitlines() if "rror" in ln]
        raise TimingError(f"{what} failed: " + (errs[0].strip() if errs else
                                                f"exit status {proc.returncode}"))
    return out


def time_generic(generic: Path, top: str, liberty: Path, delay_ps: float,
                 timeout: float | None = None, progress=None, label: str = "timing",
                 keep: Path | None = None, script: str = "default") -> dict:
    """Map the generic netlist ``generic`` (RTLIL) to ``liberty`` with ABC's required delay
    ``delay_ps`` and time it with OpenSTA: the report of one configuration (uncached).
    ``keep``: where to keep the mapped netlist (``keep``) and OpenSTA's script and report (the
    same name with ``.tcl`` and ``.sta.txt``)."""
    with tempfile.TemporaryDirectory(prefix="rayflex-timing-") as tmp:
        work = Path(tmp)
        shutil.copyfile(generic, work / "generic.il")
        shutil.copyfile(liberty, work / liberty.name)
        (work / "constr.txt").write_text(CONSTRAINTS)
        text = abc_script(script, delay_ps)
        if text is not None:
            (work / "map.abc").write_text(text)
        t0 = time.monotonic()
        area._run_yosys(work, map_script(top, liberty, delay_ps, script), timeout,
                        cmd=[area.native_yosys()], progress=progress, label=label)
        map_s = time.monotonic() - t0
        stat = (work / "stat.txt").read_text()
        netlist = (work / "netlist.v").read_text()
        regs = registers(netlist, sequential_cells(liberty))
        groups = groups_of(regs)
        if progress:
            progress(f"{label}: OpenSTA on {len(regs):,} flip-flops in {len(groups)} groups")
        (work / "sta.tcl").write_text(_sta_tcl(top, liberty, groups, clocked=bool(regs)))
        t1 = time.monotonic()
        out = _run([sta_binary(), "-no_splash", "-exit", "sta.tcl"], work, timeout, "OpenSTA")
        sta_s = time.monotonic() - t1
        if keep is not None:
            area._write_atomic(keep, (work / "netlist.v").read_bytes())
            area._write_atomic(keep.with_suffix(".tcl"), (work / "sta.tcl").read_bytes())
            area._write_atomic(keep.with_suffix(".sta.txt"), out)
            area._write_atomic(keep.with_suffix(".map.log"), (work / "yosys.log").read_bytes())
    stages = stages_of(out, regs, groups)
    limiting = max(stages, key=lambda s: stages[s]["min_period_ns"])
    worst = stages[limiting]["min_period_ns"]
    area_um2 = re.search(r"Chip area for module .*?:\s*([\d.]+)", stat)
    cells = re.search(r"Number of cells:\s*(\d+)", stat)
    return {"abc_delay_ps": delay_ps, "abc_script": script,
            "liberty": str(liberty), "liberty_sha": _file_sha(liberty),
            "min_period_ns": worst, "fmax_mhz": round(1000.0 / worst, 1),
            "limiting_stage": limiting, "stages": stages,
            "area_um2": float(area_um2[1]) if area_um2 else None,
            "cells": int(cells[1]) if cells else None, "flip_flops": len(regs),
            "cells_by_type": _cells_by_type(stat), "map_s": round(map_s, 1),
            "sta_s": round(sta_s, 1), "sta": sta_version(), "yosys_map": area.native_version()}


def groups_of(regs: dict) -> dict[str, list[str]]:
    """Stage -> the D pins of its flip-flops (``registers``), in report order, and "outputs"."""
    groups: dict[str, list[str]] = {}
    for inst, (q, _) in regs.items():
        groups.setdefault(stage_of(q), []).append(f"{inst}/D")
    groups = {s: groups[s] for s in STAGE_ORDER if s in groups}
    groups["outputs"] = []
    return groups


def stages_of(out: str, regs: dict, groups: dict) -> dict:
    """Each group's worst path from OpenSTA's output ``out`` (``@@GROUP`` sections), with the
    register bits it starts and ends at (``regs``: ``registers``)."""
    stages = {}
    for chunk in out.split("@@GROUP ")[1:]:
        name, _, body = chunk.partition("\n")
        path = parse_report(body.split("@@END")[0])
        if path is None:
            continue
        steps = path["steps"]
        if steps and steps[-1]["instance"] == path["end"]:      # the end flip-flop's D pin
            steps = steps[:-1]
        path["steps"] = steps
        first = steps[0] if steps else None
        stages[name.strip()] = {
            "min_period_ns": path["min_period_ns"], "arrival_ns": path["arrival_ns"],
            "setup_ns": path["setup_ns"], "flip_flops": len(groups.get(name.strip(), [])),
            "start": _reg_name(path["start"], regs), "end": _reg_name(path["end"], regs),
            "cells_on_path": len(path["steps"]) - (1 if first and first["instance"] in regs
                                                   else 0),
            "path": path["steps"]}
    if not stages:
        raise TimingError("OpenSTA reported no path (see the netlist)")
    return stages


def _reg_name(inst: str, regs: dict) -> str:
    """A path end as the register bit it is (``g_reg[2].u_reg.main_q[17]``), or the port."""
    if inst in regs:
        return regs[inst][0].lstrip("\\").replace(" [", "[")
    return inst


def _cells_by_type(stat: str) -> dict[str, int]:
    body = stat.split("Number of cells:")[-1]
    out = {}
    for m in re.finditer(r"^\s+(\w+)\s+(\d+)\s*$", body, re.M):
        out[m[1]] = int(m[2])
    return dict(sorted(out.items()))


# ------------------------------------------------------------------------------------------------
# configurations

def time_config(name: str, sources, liberty: Path, delay_ps: float = DEFAULT_DELAY_PS,
                cache: bool = True, timeout: float | None = None, progress=None,
                top: str = area.TOP, script: str = "default") -> dict:
    """The timing report of configuration ``name`` (or, with ``top``, of one module without
    parameters) of the RTL ``sources``: generic synthesis (the area flow's, cached), the mapped
    netlist and OpenSTA (cached). ``script``: ABC's mapping script (``ABC_SCRIPTS``)."""
    abc_script(script, delay_ps)                 # an unknown script: refused before any work
    t0 = time.monotonic()
    kw = {"params": area.config_params(name)} if top == area.TOP else {}
    gen = area.synthesize(top=top, cache=True, timeout=timeout, name=name, sources=sources,
                          tool="native", progress=progress, **kw)
    generic = area.generic_netlist(gen)
    if generic is None:               # the cached netlist was removed: synthesize again
        (area.cache_root() / f"{top}-{gen['key']}.json").unlink(missing_ok=True)
        gen = area.synthesize(top=top, cache=True, timeout=timeout, name=name, sources=sources,
                              tool="native", progress=progress, **kw)
        generic = area.generic_netlist(gen)
    h = hashlib.sha256(f"{RECIPE}\n{gen['key']}\n{_file_sha(liberty)}\n{delay_ps:g}\n"
                       f"{CONSTRAINTS}\n{area.native_version()}\n{sta_version()}".encode())
    if script != "default":                      # the default script's keys stay as they were
        h.update(f"\n{abc_script(script, delay_ps)}".encode())
    key = h.hexdigest()[:24]
    entry = cache_root() / f"{top}-{name}-{key}.json"
    if cache and entry.is_file():
        res = json.loads(entry.read_text())
        res["cached"] = True
        return res
    if progress:
        progress(f"{name}: mapping to {liberty.name} (abc -D {delay_ps:g}, {script} script) "
                 "and timing")
    res = time_generic(generic, top, liberty, delay_ps, timeout, progress, name,
                       keep=entry.with_suffix(".v"), script=script)
    res = {"config": name, "top": top, "rtl_sha": area.rtl_sha(sources),
           "generic_cells": gen["cells"], "synth_s": gen["synth_s"],
           "synth_cached": gen["cached"], **res,
           "flow_s": round(time.monotonic() - t0, 1) if not gen["cached"] else None,
           "netlist": str(entry.with_suffix(".v")), "key": key}
    area._write_atomic(entry, json.dumps(res, indent=1) + "\n")   # a forced run refreshes it
    res["cached"] = False
    return res


def cached_fmax(name: str, sources=None) -> float | None:
    """Fmax (MHz) of configuration ``name`` from the timing cache at the default required delay,
    for the RTL ``sources`` (default: the working tree's); None when it has not been timed."""
    try:
        sources = sources if sources is not None else area.snapshot()
    except area.AreaError:
        return None
    sha = area.rtl_sha(sources)
    best = None
    for entry in cache_root().glob(f"{area.TOP}-{name}-*.json"):
        try:
            r = json.loads(entry.read_text())
        except (OSError, ValueError):
            continue
        if (r.get("rtl_sha") == sha and r.get("abc_delay_ps") == DEFAULT_DELAY_PS
                and r.get("abc_script", "default") == "default"
                and r.get("liberty") == str(DEBIAN_OSU018)):
            m = entry.stat().st_mtime
            if best is None or m > best[0]:
                best = (m, r["fmax_mhz"])
    return best[1] if best else None


def time_all(names, liberty: Path, delay_ps: float = DEFAULT_DELAY_PS, jobs: int = 1,
             cache: bool = True, timeout=None, progress=None, rev: str | None = None,
             script: str = "default") -> dict:
    """Time the named configurations of one RTL snapshot, ``jobs`` at a time: the report."""
    names = list(names)
    label = area.rev_label(rev)
    sources = area.snapshot(None if rev is None else label)
    todo = [n for n in names if not area.is_cached(n, sources, "native")]
    area.announce("timing", todo, "native", jobs, progress)
    done = []

    def one(n):
        r = time_config(n, sources, liberty, delay_ps, cache, timeout, progress, script=script)
        done.append(n)
        if progress:
            progress(f"{n}: Fmax {r['fmax_mhz']:.1f} MHz, limited by {r['limiting_stage']}"
                     f"{' (cached)' if r['cached'] else ''} [{len(done)}/{len(names)}]")
        return r

    return report(area.run_each(names, one, jobs, "native"), sources, label)


def report(results: dict, sources, label: str) -> dict:
    base = results.get(BASELINE)
    out = {"flow": "read_slang | synth -flatten -noshare | dfflibmap; abc -D -constr -liberty | "
                   "OpenSTA report_checks per stage register",
           "yosys": area.yosys_version("native"), "sta": sta_version(),
           "rtl_sha": area.rtl_sha(sources), "rtl_rev": label,
           "period_constraint_ns": PERIOD_NS, "baseline": BASELINE if base else None,
           "configs": {}}
    for n, r in results.items():
        r = dict(r)
        if base:
            r["fmax_ratio"] = round(r["fmax_mhz"] / base["fmax_mhz"], 4)
            r["area_ratio"] = round(r["area_um2"] / base["area_um2"], 4) \
                if r.get("area_um2") and base.get("area_um2") else None
        out["configs"][n] = r
    return out


def markdown(rep: dict) -> str:
    rows = ["| configuration | Fmax (MHz) | least period (ns) | limiting stage | cells on its "
            "path | area (mm²) | flip-flops | cells |",
            "|---|---:|---:|---|---:|---:|---:|---:|"]
    for n, r in rep["configs"].items():
        s = r["stages"][r["limiting_stage"]]
        rows.append(f"| {n} | {r['fmax_mhz']:.1f} | {r['min_period_ns']:.2f} | "
                    f"{r['limiting_stage']} ({STAGE_MEANING.get(r['limiting_stage'], '')}) | "
                    f"{s['cells_on_path']} | "
                    f"{(r['area_um2'] or 0) / 1e6:.2f} | {r['flip_flops']:,} | {r['cells']:,} |")
    stages = [s for s in STAGE_ORDER if any(s in r["stages"] for r in rep["configs"].values())]
    rows += ["", "Least clock period per stage (ns; the stage's worst register-to-register "
                 "path plus setup):", "",
             "| configuration | " + " | ".join(stages) + " |",
             "|---|" + "---:|" * len(stages)]
    for n, r in rep["configs"].items():
        cells = []
        for s in stages:
            v = r["stages"].get(s)
            txt = "" if v is None else f"{v['min_period_ns']:.2f}"
            cells.append(f"**{txt}**" if s == r["limiting_stage"] else txt)
        rows.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def plot(rep: dict, path) -> None:
    """Bars of each stage's least clock period per configuration; the stage that sets the clock
    is marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfgs = list(rep["configs"])
    stages = [s for s in STAGE_ORDER if s not in ("other",)
              and any(s in r["stages"] for r in rep["configs"].values())]
    fig, ax = plt.subplots(figsize=(11, 4.8))
    width = 0.8 / max(1, len(cfgs))
    x = np.arange(len(stages))
    for i, n in enumerate(cfgs):
        r = rep["configs"][n]
        vals = [r["stages"].get(s, {}).get("min_period_ns", np.nan) for s in stages]
        bars = ax.bar(x + (i - (len(cfgs) - 1) / 2) * width, vals, width,
                      label=f"{n}: {r['fmax_mhz']:.1f} MHz")
        lim = stages.index(r["limiting_stage"]) if r["limiting_stage"] in stages else None
        if lim is not None:
            bars[lim].set_edgecolor("black")
            bars[lim].set_linewidth(1.5)
    ax.set_xticks(x, stages)
    ax.set_ylabel("least clock period (ns)")
    ax.set_xlabel("pipeline stage (paths ending at its register); black edge: the stage that "
                  "sets the clock")
    lib = Path(next(iter(rep["configs"].values()))["liberty"]).stem
    ax.set_title(wrap(f"Delay per pipeline stage, {lib} (OpenSTA), RTL {rep['rtl_rev']}", 100))
    ax.legend(fontsize=8, ncol=1, loc="upper right")  # over the short stages on the right
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def sweep_delays(names, sources, liberty: Path, delays, top: str = area.TOP,
                  timeout=None, progress=None) -> dict:
    """Area and Fmax of each configuration (or module ``top``) mapped at each of ABC's delay
    ``delays`` (ps): the paper's area-against-clock study on the open flow. The generic
    netlist is shared; each delay is one mapping and one OpenSTA run (cached)."""
    out = {}
    for n in names:
        rows = []
        for d in delays:
            r = time_config(n, sources, liberty, d, True, timeout, progress, top=top)
            rows.append({"abc_delay_ps": d, "goal_mhz": round(1e6 / d, 1),
                         "fmax_mhz": r["fmax_mhz"], "area_um2": r["area_um2"],
                         "cells": r["cells"], "limiting_stage": r["limiting_stage"]})
        best = max(x["fmax_mhz"] for x in rows)
        for x in rows:
            x["goal_vs_fmax"] = round(x["goal_mhz"] / best, 3)
            x["area_vs_first"] = round(x["area_um2"] / rows[0]["area_um2"], 4)
        out[n] = rows
    return out


# The paper's synthesis results at clocks of 500 to 1500 MHz (its 15 nm library and Genus)
PAPER_FREQUENCY = {
    "source": "RayFlex paper, Synthesis Results (Genus, a 15 nm open cell library, synthesized for "
              "clocks of 500-1500 MHz)",
    "area": "the circuit area barely changes with the clock it is synthesized for, "
            "500-1500 MHz",
    "power": "the power consumption follows a nearly linear trend in the evaluated frequency "
             "range; unified vs disjoint within +/-4 %, baseline vs extended 14 % to 22 %",
    "clocks_mhz": [500, 1500], "power_mW_at_1GHz": [60, 85],
}


def plot_delays(sweep: dict, path, title: str) -> None:
    """Area against the clock ABC maps for (1 / its required delay) as a fraction of the
    achieved Fmax, with the paper's range (its clocks as a fraction of its 1 GHz)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker  # noqa: F401

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for n, rows in sweep.items():
        ax.plot([r["goal_vs_fmax"] for r in rows], [r["area_vs_first"] for r in rows], "o-",
                label=f"{n} (Fmax {max(r['fmax_mhz'] for r in rows):.0f} MHz)")
    ax.axvspan(0.5, 1.5, color="grey", alpha=0.12,
               label="the paper's clocks, 500-1500 MHz around its 1 GHz (area flat)")
    ax.axhline(1.0, color="grey", lw=0.8)
    vals = [r["area_vs_first"] for rows in sweep.values() for r in rows]
    ax.set_ylim(min(0.9, min(vals) - 0.02), max(1.1, max(vals) + 0.02))   # +-10 % at least
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xticks([0.25, 0.5, 1, 2, 4, 8])
    ax.set_xlabel("clock ABC maps for (1 / -D) / the best Fmax reached (log)")
    ax.set_ylabel("cell area / area at the first -D")
    ax.set_title(wrap(title, 90), fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def power_vs_frequency(power_doc: dict, fmax: dict[str, float]) -> dict:
    """The paper's power-against-frequency study on the open flow: a ``rayflex power --level
    liberty`` document's energy per operation (with clock pins; leakage as power) times the
    clock, from 100 MHz to each configuration's Fmax (``fmax``: configuration -> MHz, where
    timed). One netlist at every clock: the line is straight by construction (the paper
    synthesizes again per clock)."""
    out = {}
    for n, c in power_doc["configs"].items():
        leak = (c.get("leakage") or {}).get("leakage_mW", 0.0)
        clock_pj = (c.get("leakage") or {}).get("clock_per_cycle_pj", 0.0)
        rows = {}
        for op in ("box", "triangle"):
            if op not in c:
                continue
            dyn = c[op]["energy_per_op"] + clock_pj           # pJ per op, one op per cycle
            rows[op] = {"pj_per_op": round(dyn, 1),
                        "mw_at_1ghz": round(dyn + leak, 1),
                        "mw_at_fmax": (round(dyn * fmax[n] / 1000 + leak, 1)
                                       if n in fmax else None)}
        out[n] = {"fmax_mhz": fmax.get(n), "leakage_mW": leak, "ops": rows}
    return out


def plot_power(study: dict, path, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for n, c in study.items():
        tri = c["ops"].get("triangle")
        if not tri:
            continue
        f = np.linspace(0, 1000.0, 101)
        line, = ax.plot(f, tri["pj_per_op"] * f / 1000 + c["leakage_mW"], ":",
                        label=n + (f" (solid to its Fmax, {c['fmax_mhz']:.0f} MHz)"
                                   if c["fmax_mhz"] else " (not timed)"))
        if c["fmax_mhz"]:
            g = np.linspace(0, c["fmax_mhz"], 20)
            ax.plot(g, tri["pj_per_op"] * g / 1000 + c["leakage_mW"], "-", color=line.get_color())
            ax.plot([c["fmax_mhz"]], [tri["pj_per_op"] * c["fmax_mhz"] / 1000 + c["leakage_mW"]],
                    "o", color=line.get_color())
    ax.set_xlabel("clock (MHz)")
    ax.set_ylabel("power, a triangle op every cycle (mW)")
    ax.set_title(wrap(title, 90), fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

