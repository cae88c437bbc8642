"""The whole RT unit at the power flow's gate level: its generic-gate netlist driven by the
stimulus its RTL run recorded (docs/rtunit_rtl.md#energy).

The unit's netlist (``netlist.synthesize`` with the unit's top, ``rf_rtunit``: elaborated,
flattened, its arrays mapped to flip-flops and multiplexers, generic gates) is cycle-equivalent
to its RTL: zero delay, the same registers, the same ports. So the RTL harness records the
values of the unit's ports every clock cycle of a run (``RtUnitBackend.trace_unit(record=True)``,
a ``Stimulus``: rays in, memory responses, ready signals, and the outputs) and ``replay`` drives
the netlist's inputs with them from reset, cycle by cycle, each run in its own ``gatesim`` lane
(up to 64 independent runs per pass), comparing the netlist's outputs with the recorded ones
every cycle and counting every net's toggles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import unit_area
from ..backends.rtunit import UNIT_TOP
from . import gatesim, netlist

RESET_CYCLES = 2           # the harness's (rtu_new): rst_ni low for two clock edges


def unit_netlist(params: dict[str, int], progress=None) -> netlist.Netlist:
    """The generic-gate netlist of the unit built with ``params`` (``rtunit.unit_params``),
    synthesized on a cache miss (minutes: the datapath's gates are most of it)."""
    return netlist.synthesize(params, unit_area.sources(), progress, top=UNIT_TOP)


@dataclass
class Replay:
    """What ``replay`` found: per lane the cycles replayed after reset (``cycles``), every net's
    toggles between two consecutive replayed cycles summed over the lanes (``toggles``), the
    number of (lane, cycle, output bit) whose netlist value differed from the recording
    (``mismatches``) and the first of them (``first_mismatch``: lane, cycle, port), and the
    seconds the simulation took."""

    cycles: np.ndarray
    toggles: np.ndarray
    mismatches: int
    first_mismatch: tuple | None
    seconds: float


def _frames(stim, ports: list[tuple[str, int]], reset: dict[str, int] | None) -> np.ndarray:
    """(cycles, bytes) uint8: the run's values of ``ports`` per cycle, after ``RESET_CYCLES``
    reset frames when ``reset`` (port -> its value in reset; every other port 0) is given."""
    values = {**stim.inputs, **stim.outputs}
    rows = np.concatenate([values[name] for name, _ in ports], axis=1)
    if reset is None:
        return rows
    pre = np.zeros((RESET_CYCLES, rows.shape[1]), np.uint8)
    at = 0
    for name, b in ports:
        if name in reset:
            pre[:, at:at + b] = np.frombuffer(int(reset[name]).to_bytes(b, "little"), np.uint8)
        at += b
    return np.concatenate([pre, rows])


def _stack(stims, ports, reset: bool) -> np.ndarray:
    """(lanes, cycles, bytes): ``_frames`` of each run in its own lane (``reset``: after the reset
    frames, the run's BVH root on ``root_i``), a shorter run keeping its last frame."""
    one = [_frames(s, ports, {"root_i": s.root} if reset else None) for s in stims]
    out = np.zeros((len(stims), max(len(f) for f in one), one[0].shape[1]), np.uint8)
    for k, f in enumerate(one):
        out[k, :len(f)] = f
        out[k, len(f):] = f[-1]
    return out


def _bit_map(net, ports: list[tuple[str, int]]) -> tuple[np.ndarray, np.ndarray, list]:
    """(net per port bit, the bit's position in a frame's unpacked bits, port per bit) of the
    ports as the netlist has them (its width: the recording may hold more bits)."""
    nets, pos, names = [], [], []
    at = 0
    for name, b in ports:
        bits = net.ports.get(name)
        if bits is None:
            raise ValueError(f"the unit's netlist has no port {name}")
        if len(bits) > 8 * b:
            raise ValueError(f"port {name}: {len(bits)} bits in the netlist, {8 * b} recorded")
        nets.append(np.asarray(bits, np.int64))
        pos.append(at * 8 + np.arange(len(bits)))
        names += [name] * len(bits)
        at += b
    return np.concatenate(nets), np.concatenate(pos), names


def _lane_words(frame: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(lanes, bytes) frames -> one uint64 per bit: bit k of word j is lane k's bit ``pos[j]``."""
    bits = np.unpackbits(frame, axis=1, bitorder="little")[:, pos]
    packed = np.packbits(bits, axis=0, bitorder="little")           # (ceil(lanes/8), bits)
    word = np.zeros((8, bits.shape[1]), np.uint8)
    word[:packed.shape[0]] = packed
    return word.T.copy().view(np.uint64).reshape(-1)


def replay(net, stims: list, check: bool = True, progress=None) -> Replay:
    """Drive ``net`` (the unit's ``unit_netlist``) with ``stims`` (``rtunit.Stimulus``, at most
    ``gatesim.LANES``, one lane each): ``RESET_CYCLES`` cycles in reset (the recorded BVH root on
    ``root_i``), then every recorded cycle's inputs; with ``check`` the netlist's outputs are
    compared with the recorded ones every cycle of every lane. ``progress(done, total)`` every
    256 cycles."""
    L = gatesim.LANES
    if not 1 <= len(stims) <= L:
        raise ValueError(f"1..{L} recorded runs per replay, got {len(stims)}")
    t0 = time.perf_counter()
    first = stims[0]
    ins = [(n, v.shape[1]) for n, v in first.inputs.items()]
    outs = [(n, v.shape[1]) for n, v in first.outputs.items()]
    in_nets, in_pos, _ = _bit_map(net, ins)
    out_nets, out_pos, out_names = _bit_map(net, outs)
    fin = _stack(stims, ins, True)
    fout = _stack(stims, outs, False) if check else None
    length = np.array([s.cycles for s in stims]) + RESET_CYCLES
    sim = gatesim.GateSim(net)
    clk = net.ports.get("clk_i")
    if clk is not None:
        sim.v[clk] = 0
    toggles = np.zeros(sim.n, np.int64)
    lane_bit = np.uint64(1) << np.arange(L, dtype=np.uint64)
    mismatches, first_bad = 0, None
    prev = None
    total = int(length.max())
    for c in range(total):
        sim.v[in_nets] = _lane_words(fin[:, c], in_pos)
        sim.settle()
        live = (c < length)
        if not sim.loops_held(np.bitwise_or.reduce(lane_bit[:len(stims)][live])):
            raise RuntimeError(f"cycle {c}: a multiplexer cut out of a loop selects it "
                               "(the netlist's cut is not exact for this run)")
        counted = live & (c > RESET_CYCLES)
        if prev is not None and counted.any():
            mask = np.bitwise_or.reduce(lane_bit[:len(stims)][counted])
            toggles += np.bitwise_count((sim.v ^ prev) & mask)
        prev = sim.v.copy()
        if check and c >= RESET_CYCLES:
            mask = np.bitwise_or.reduce(lane_bit[:len(stims)][live])
            want = _lane_words(fout[:, c - RESET_CYCLES], out_pos)
            bad = np.flatnonzero((sim.v[out_nets] ^ want) & mask)
            if len(bad):
                lanes = ((sim.v[out_nets[bad]] ^ want[bad]) & mask)
                for j, w in zip(bad, lanes):
                    lane_bad = [k for k in range(len(stims)) if int(w) >> k & 1]
                    mismatches += len(lane_bad)
                    if first_bad is None:
                        first_bad = (lane_bad[0], c - RESET_CYCLES, out_names[j])
        sim.clock()
        if progress is not None and c % 256 == 255:
            progress(c + 1, total)
    return Replay(length - RESET_CYCLES, toggles, mismatches, first_bad,
                  time.perf_counter() - t0)

