"""Level ``liberty``: the gate-level toggles priced with a liberty library's power tables.

The reader is hand-written (~80 lines): the format is a simple nesting of ``name (args) { ... }``
groups, ``name : value ;`` and ``name (args) ;`` attributes, and the project needs only the units,
each cell's leakage, pin capacitances, ``function``/``ff`` and the ``internal_power`` and
transition tables. The one PyPI package for it (``liberty-parser``) is GPL-licensed (this project
is MIT) and is not among the project's dependencies.

Mapping (no ABC run): every generic gate of the ``gates`` netlist is taken as the smallest cell of
the library with the same logic function (up to output inversion: the toggles are the same); a
flip-flop with enable as a D flip-flop plus a 2:1 mux in its feedback path; one with an
asynchronous reset as the library's flip-flop with a clear pin. So the cell-level netlist has the
gate netlist's structure and its simulated toggles apply unchanged (docs/power.md discusses
what a real technology mapping would change).

Energy per toggle of a net = the driving cell's internal energy (mean of rise_power and
fall_power over its related pins, bilinearly interpolated, linearly extrapolated beyond the table
as STA tools do, at the net's load and its input slew) + ½·C·V² of the load C (the input pin
capacitances the net drives; no wire load). The input slew of a cell is the output transition
of the cell driving its first input, from that cell's transition tables at its own load with the
library's smallest slew as its input (one pass, not a full timing propagation). Per cycle: the
clock pins of every flip-flop (no clock gating, no clock tree) and the leakage of every cell over
one 1 ns cycle (the paper's 1 GHz).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DEBIAN_OSU018 = Path("/usr/share/qflow/tech/osu018/osu018_stdcells.lib")
CYCLE_NS = 1.0            # the paper's clock, 1 GHz


# ------------------------------------------------------------------------------------------------
# reader

@dataclass
class Group:
    kind: str
    args: list[str]
    attrs: dict = field(default_factory=dict)
    groups: list["Group"] = field(default_factory=list)

    def sub(self, kind: str) -> list["Group"]:
        return [g for g in self.groups if g.kind == kind]


_TOKEN = re.compile(r'\s*(?:(/\*.*?\*/)|("(?:[^"\\]|\\.)*")|([{}();:,])|([^\s{}();:,"]+))', re.S)


def parse(text: str) -> Group:
    """Parse liberty text into a tree of groups (the top one is the ``library``)."""
    text = text.replace("\\\n", " ")
    toks = []
    for m in _TOKEN.finditer(text):
        if m.group(1):
            continue
        toks.append(m.group(2) if m.group(2) else m.group(3) or m.group(4))
    toks = [t for t in toks if t]
    pos = 0

    def args_list():
        nonlocal pos
        out = []
        pos += 1                                     # "("
        while toks[pos] != ")":
            if toks[pos] != ",":
                out.append(toks[pos].strip('"'))
            pos += 1
        pos += 1
        return out

    def body(g: Group):
        nonlocal pos
        while pos < len(toks) and toks[pos] != "}":
            name = toks[pos]
            pos += 1
            if toks[pos] == ":":
                pos += 1
                val = []
                while toks[pos] not in (";", "}"):
                    val.append(toks[pos].strip('"'))
                    pos += 1
                if toks[pos] == ";":
                    pos += 1
                g.attrs[name] = " ".join(val)
            elif toks[pos] == "(":
                a = args_list()
                if pos < len(toks) and toks[pos] == "{":
                    pos += 1
                    child = Group(name, a)
                    body(child)
                    if pos >= len(toks):
                        raise IndexError
                    pos += 1                         # "}"
                    g.groups.append(child)
                else:
                    if pos < len(toks) and toks[pos] == ";":
                        pos += 1
                    g.attrs[name] = a
            else:
                raise ValueError(f"liberty: unexpected {toks[pos]!r} after {name!r}")

    try:
        root = Group("", [])
        body(root)
    except IndexError:
        raise ValueError("liberty: unexpected end of file") from None
    libs = root.sub("library")
    if not libs:
        raise ValueError("liberty: no library group")
    return libs[0]


def _floats(s) -> np.ndarray:
    if isinstance(s, list):
        s = ",".join(s)
    return np.array([float(x) for x in re.split(r"[,\s]+", s.strip()) if x])


@dataclass
class Table:
    """A lookup table over (load, slew); 1-D tables (passive energy) over slew only."""
    load: np.ndarray | None
    slew: np.ndarray
    values: np.ndarray         # (len(load), len(slew)) or (len(slew),)

    def __call__(self, load, slew):
        load = np.asarray(load, float)
        slew = np.asarray(slew, float)
        if self.load is None:
            return _interp1(self.slew, self.values, slew)
        # interpolate along slew for every load row, then along load
        rows = np.stack([_interp1(self.slew, r, slew) for r in self.values])   # (L, ...)
        return _interp_rows(self.load, rows, load)


def _interp1(x, y, q):
    """Piecewise-linear in x, linear extrapolation beyond both ends."""
    q = np.asarray(q, float)
    if len(x) == 1:
        return np.full(q.shape, y[0])
    i = np.clip(np.searchsorted(x, q) - 1, 0, len(x) - 2)
    x0, x1, y0, y1 = x[i], x[i + 1], y[i], y[i + 1]
    return y0 + (y1 - y0) * (q - x0) / (x1 - x0)


def _interp_rows(x, rows, q):
    if len(x) == 1:
        return rows[0]
    i = np.clip(np.searchsorted(x, q) - 1, 0, len(x) - 2)
    x0, x1 = x[i], x[i + 1]
    y0 = np.take_along_axis(rows, i[None], 0)[0] if rows.ndim > 1 else rows[i]
    y1 = np.take_along_axis(rows, (i + 1)[None], 0)[0] if rows.ndim > 1 else rows[i + 1]
    return y0 + (y1 - y0) * (q - x0) / (x1 - x0)


def _table(g: Group, templates: dict) -> Table:
    tpl = templates.get(g.args[0] if g.args else "", {})
    idx1 = _floats(g.attrs["index_1"]) if "index_1" in g.attrs else tpl.get("index_1")
    idx2 = _floats(g.attrs["index_2"]) if "index_2" in g.attrs else tpl.get("index_2")
    vals = _floats(g.attrs["values"])
    v1 = tpl.get("variable_1", "")
    if idx2 is None:
        return Table(None, idx1, vals)
    vals = vals.reshape(len(idx1), len(idx2))
    if "transition" in v1:                           # (slew, load): store as (load, slew)
        return Table(idx2, idx1, vals.T.copy())
    return Table(idx1, idx2, vals)


@dataclass
class Cell:
    name: str
    area: float
    leakage: float                       # in the library's leakage unit
    inputs: dict[str, float]             # pin -> capacitance
    output: str | None
    function: str | None
    ff: dict | None                      # next_state, clocked_on, clear, preset
    energy: list[tuple[Table, Table]]    # internal (rise, fall) tables of the output pin
    transition: list[tuple[Table, Table]]
    clock_energy: list[tuple[Table, Table]]   # passive tables of the clock pin


@dataclass
class Library:
    name: str
    voltage: float
    cap_unit_pf: float
    leak_unit_nw: float
    energy_unit_pj: float
    cells: dict[str, Cell]
    min_slew: float


_UNIT = {"f": 1e-15, "p": 1e-12, "n": 1e-9, "u": 1e-6, "m": 1e-3, "": 1.0}


def _unit(text: str, base: str) -> float:
    m = re.fullmatch(r"\s*([\d.]*)\s*([fpnum]?)" + base + r"\s*", text.strip('"'), re.I)
    if not m:
        raise ValueError(f"liberty: cannot read the unit {text!r}")
    return float(m.group(1) or 1) * _UNIT[m.group(2).lower()]


def load(path) -> Library:
    """Read a liberty file (ValueError with one line if it is not usable)."""
    try:
        text = Path(path).read_text(errors="replace")
    except OSError as e:
        raise OSError(f"cannot read liberty file {path}: {e.strerror}") from None
    lib = parse(text)
    a = lib.attrs
    templates = {}
    for g in lib.groups:
        if g.kind.endswith("template") and g.args:
            templates[g.args[0]] = {k: (_floats(v) if k.startswith("index") else v)
                                    for k, v in g.attrs.items()}
    volt = float(a.get("nom_voltage", 0) or 0)
    for oc in lib.sub("operating_conditions"):
        volt = float(oc.attrs.get("voltage", volt))
    if not volt:
        raise ValueError("liberty: no nom_voltage or operating_conditions voltage")
    cap = a.get("capacitive_load_unit", ["1", "pf"])
    cap_pf = float(cap[0]) * _unit(cap[1], "f") / 1e-12
    leak_nw = _unit(a.get("leakage_power_unit", "1nW"), "w") / 1e-9
    # internal energy unit = voltage unit x capacitance unit (V x pF = pJ)
    volt_unit = _unit(a.get("voltage_unit", "1V"), "v")
    energy_pj = volt_unit * cap_pf
    cells = {}
    slews = []
    for c in lib.sub("cell"):
        inputs, out, func, en, tr, clk = {}, None, None, [], [], []
        for p in c.sub("pin"):
            d = p.attrs.get("direction")
            if d == "input":
                inputs[p.args[0]] = float(p.attrs.get("capacitance", 0))
                if p.attrs.get("clock") == "true":
                    for ip in p.sub("internal_power"):
                        rp, fp = ip.sub("rise_power"), ip.sub("fall_power")
                        if rp and fp:
                            clk.append((_table(rp[0], templates), _table(fp[0], templates)))
            elif d == "output" and out is None:
                out, func = p.args[0], p.attrs.get("function")
                for ip in p.sub("internal_power"):
                    rp, fp = ip.sub("rise_power"), ip.sub("fall_power")
                    if rp and fp:
                        en.append((_table(rp[0], templates), _table(fp[0], templates)))
                for t in p.sub("timing"):
                    rt, ft = t.sub("rise_transition"), t.sub("fall_transition")
                    if rt and ft:
                        tr.append((_table(rt[0], templates), _table(ft[0], templates)))
                        slews.append(tr[-1][0].slew.min())
        ffs = c.sub("ff")
        ff = dict(ffs[0].attrs) if ffs else None
        cells[c.args[0]] = Cell(c.args[0], float(c.attrs.get("area", 0)),
                                float(c.attrs.get("cell_leakage_power", 0)), inputs, out, func,
                                ff, en, tr, clk)
    if not cells:
        raise ValueError("liberty: no cells")
    return Library(lib.args[0] if lib.args else "?", volt, cap_pf, leak_nw, energy_pj, cells,
                   min(slews) if slews else 0.0)


# ------------------------------------------------------------------------------------------------
# mapping generic gates to library cells

# generic gate -> truth table over its inputs in order (A, B, S), as a function of a tuple
_GENERIC = {
    "$_BUF_": (1, lambda v: v[0]), "$_NOT_": (1, lambda v: 1 - v[0]),
    "$_AND_": (2, lambda v: v[0] & v[1]), "$_OR_": (2, lambda v: v[0] | v[1]),
    "$_XOR_": (2, lambda v: v[0] ^ v[1]), "$_NAND_": (2, lambda v: 1 - (v[0] & v[1])),
    "$_NOR_": (2, lambda v: 1 - (v[0] | v[1])), "$_XNOR_": (2, lambda v: 1 - (v[0] ^ v[1])),
    "$_ANDNOT_": (2, lambda v: v[0] & (1 - v[1])), "$_ORNOT_": (2, lambda v: v[0] | (1 - v[1])),
    "$_MUX_": (3, lambda v: v[1] if v[2] else v[0]),
    "$_NMUX_": (3, lambda v: 1 - (v[1] if v[2] else v[0])),
}
# a gate no cell implements -> the closest one that exists (an inverter on one input omitted)
_NEAREST = {"$_ANDNOT_": "$_AND_", "$_ORNOT_": "$_OR_", "$_NMUX_": "$_MUX_", "$_BUF_": "$_NOT_"}


def _eval_function(expr: str, pins: list[str], values) -> int:
    """Evaluate a liberty boolean function (! ' for not, space * & for and, + | for or, ^)."""
    py = expr
    for i, p in sorted(enumerate(pins), key=lambda x: -len(x[1])):
        py = re.sub(rf"\b{re.escape(p)}\b", f"_v[{i}]", py)
    py = re.sub(r"(\w+\[\d+\]|\))\s*'", r"(1-\1)", py)
    py = py.replace("!", " 1- ").replace("+", "|").replace("*", "&")
    py = re.sub(r"(\]|\))\s+(?=[_(1])", r"\1 & ", py)
    return int(eval(py, {"__builtins__": {}}, {"_v": values})) & 1   # noqa: S307 (own grammar)


def _truth(n_in, fn):
    return tuple(fn(v) for v in itertools.product((0, 1), repeat=n_in))


def map_gate(lib: Library, gate: str) -> list[Cell]:
    """The library cells that implement generic gate ``gate`` (smallest area first by function,
    up to output inversion); flip-flops: [flip-flop] or [flip-flop, mux] for an enable."""
    if gate in _GENERIC:
        n_in, fn = _GENERIC[gate]
        want = _truth(n_in, fn)
        inv = tuple(1 - x for x in want)
        best = {want: None, inv: None}
        for c in lib.cells.values():
            if c.ff is not None or not c.function or len(c.inputs) != n_in or not c.energy:
                continue
            pins = list(c.inputs)
            for perm in itertools.permutations(range(n_in)):
                try:
                    tt = tuple(_eval_function(c.function, [pins[i] for i in perm], v)
                               for v in itertools.product((0, 1), repeat=n_in))
                except Exception:              # noqa: BLE001  (a function we cannot read)
                    break
                if tt in best:
                    if best[tt] is None or c.area < best[tt].area:
                        best[tt] = c
                    break
        best = best[want] or best[inv]         # the exact function, else its complement
        if best is None and gate in _NEAREST:
            return map_gate(lib, _NEAREST[gate])
        if best is None:
            raise ValueError(f"liberty {lib.name}: no cell implements {gate}")
        return [best]
    m = re.fullmatch(r"\$_(S?DFFE?)_([PN])([PN][01])?([PN])?_", gate)
    if m:
        reset = m.group(1).startswith("DFF") and m.group(3) is not None    # asynchronous
        pos_edge = [c for c in lib.cells.values() if c.ff and c.clock_energy
                    and not re.search(r"[!']", c.ff.get("clocked_on", ""))]
        cands = [c for c in pos_edge if ("clear" in c.ff or "preset" in c.ff) == reset] \
            or pos_edge
        if not cands:
            raise ValueError(f"liberty {lib.name}: no flip-flop with clock power tables")
        ff = min(cands, key=lambda c: c.area)
        out = [ff]
        if "E" in m.group(1):
            out += map_gate(lib, "$_MUX_")
        return out
    raise ValueError(f"liberty: no mapping for {gate}")


# ------------------------------------------------------------------------------------------------
# per-net energies

def find(path: str | None) -> tuple[Path | None, str]:
    """The liberty file to use: ``path``, else Debian's qflow-tech-osu018; (None, why) if absent."""
    if path:
        p = Path(path)
        return (p, "") if p.is_file() else (None, f"liberty file {path} not found")
    if DEBIAN_OSU018.is_file():
        return DEBIAN_OSU018, ""
    return None, (f"no liberty file ({DEBIAN_OSU018} missing: apt-get install qflow-tech-osu018, "
                  "or pass --liberty PATH)")


def _mean_tables(pairs, load, slew):
    if not pairs:
        return np.zeros(np.shape(load))
    return np.mean([0.5 * (r(load, slew) + f(load, slew)) for r, f in pairs], axis=0)


def net_energies(lib: Library, cell_types: list[str], driver, sinks, in0) -> dict:
    """Energy per toggle (pJ) of every net, clock energy per cycle and leakage per cycle (pJ).

    driver: (n,) index into ``cell_types`` or -1; sinks: (n, len(cell_types)) input pins per
    cell type; in0: (n,) the first input net of each net's driver."""
    maps = [map_gate(lib, t) for t in cell_types]
    pin_cap = np.array([np.mean(list(m[-1 if len(m) > 1 else 0].inputs.values()))
                        for m in maps]) * lib.cap_unit_pf        # pF per sink pin
    load = sinks @ pin_cap                                       # pF per net
    n = len(driver)
    slew = np.full(n, lib.min_slew)
    out_slew = np.full(n, lib.min_slew)
    energy = np.zeros(n)
    for t, m in enumerate(maps):
        idx = np.flatnonzero(driver == t)
        if not len(idx):
            continue
        main = m[0]
        out_slew[idx] = _mean_tables(main.transition, load[idx], slew[idx]) \
            if main.transition else lib.min_slew
    src = np.where(in0 >= 0, in0, 0)
    slew = np.where(in0 >= 0, out_slew[src], lib.min_slew)
    for t, m in enumerate(maps):
        idx = np.flatnonzero(driver == t)
        if not len(idx):
            continue
        e = sum(_mean_tables(c.energy, load[idx], slew[idx]) for c in m) * lib.energy_unit_pj
        energy[idx] = e + 0.5 * load[idx] * lib.voltage ** 2          # pF x V^2 = pJ
    counts = np.bincount(driver[driver >= 0], minlength=len(cell_types))
    clock = sum(counts[t] * float(np.mean([0.5 * (r(0, lib.min_slew) + f(0, lib.min_slew))
                                           for r, f in m[0].clock_energy]))
                for t, m in enumerate(maps) if m[0].ff) * lib.energy_unit_pj
    leak_nw = sum(counts[t] * sum(c.leakage for c in m) for t, m in enumerate(maps)) \
        * lib.leak_unit_nw
    return {"energy_per_toggle": energy, "clock_per_cycle_pj": float(clock),
            "leakage_per_cycle_pj": float(leak_nw * 1e-9 * CYCLE_NS * 1e-9 / 1e-12),
            "leakage_mW": float(leak_nw * 1e-6),
            "cells": {t: [c.name for c in m] for t, m in zip(cell_types, maps)},
            "library": lib.name, "voltage": lib.voltage}


class Priced:
    """A gate model whose net weights are liberty energies per toggle (pJ); ``per_cycle`` is the
    energy every cycle costs regardless of data (flip-flop clock pins, leakage)."""

    unit = "pJ"
    level = "liberty"

    def __init__(self, model, info: dict):
        self.model = model
        self.weight = info["energy_per_toggle"]
        self.stage = model.stage
        self.streams = model.streams
        self.leakage = {k: v for k, v in info.items() if k != "energy_per_toggle"}
        self.per_cycle = info["clock_per_cycle_pj"] + info["leakage_per_cycle_pj"]

    def pair(self, streams):
        return self.model.pair(streams)

    def idle(self, words, cycles):
        return self.model.idle(words, cycles)


def price(model, net, path) -> Priced:
    lib = load(path)
    info = net_energies(lib, net.cell_types, net.driver, net.sinks, net.in0)
    info["energy_per_toggle"] = np.where(model.weight > 0, info["energy_per_toggle"], 0.0)
    return Priced(model, info)

