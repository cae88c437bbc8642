"""Switching activity of one configuration: models that count the toggles of every net while
request streams run through them.

* ``SignalModel`` (level ``signals``): the RTL built by Verilator with ``--trace``
  (sim/power_harness.cpp); a run writes a VCD and the harness counts bit toggles per VCD
  identifier, in C++ (sim/rf_toggles.h, the counter the RT unit's harness uses too) (a 300-request run: ~25 MB, ~0.1 s). Verilator gives each net one
  identifier however many scopes it appears in (ports, continuous assignments), so each net
  counts once. Built once per configuration and cached by ``driver.backends.verilate``.
* ``GateModel`` (level ``gates``): the generic-gate netlist (``netlist.py``) on the 64-lane
  simulator ``gatesim``; toggles counted per net with ``np.bitwise_count``.

Both give the steady state of a list of streams (``pair``: each stream's first half, and the
whole stream, run from reset; their difference is the second half's operations with the
pipeline full) and the toggles of idle cycles after a drained stream (``idle``). Every run
starts from reset, so a run's toggles depend only on its requests: same seed, same numbers.
"""

from __future__ import annotations

import ctypes
import re
import tempfile
from pathlib import Path

import numpy as np

from ..backends import toggles, verilate
from ..backends.build import LINT_WAIVERS, RTL_DIR, SIM_DIR, rtl_sources
from ..core.wire import REQ_WORDS
from . import gatesim
from .netlist import STAGE_LABELS, Netlist

HARNESS = SIM_DIR / "power_harness.cpp"
# inputs driven by the test bench (their toggles are the driver's, and the clock has no tree here)
TB_INPUTS = ("clk_i", "rst_ni", "in_valid_i", "req_i", "out_ready_i")


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    vp, i64 = ctypes.c_void_p, ctypes.c_int64
    lib.pw_new.restype = vp
    lib.pw_free.argtypes = [vp]
    lib.pw_stream.restype = i64
    lib.pw_stream.argtypes = [vp, vp, i64, i64]
    if lib.pw_req_words() != REQ_WORDS:
        raise OSError("power harness and driver disagree on the request width; rebuild")
    lib.pw_trace_open.argtypes = [vp, ctypes.c_char_p]
    lib.pw_trace_close.argtypes = [vp]
    lib.pw_vcd_count.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
    lib.pw_vcd_count.restype = i64
    return lib


def _build(sv, params, name, vargs) -> Path:
    try:
        return verilate.build_library("rayflex", sv, [HARNESS], params=params, name=name,
                                      verilator_args=vargs)
    except verilate.BuildError as e:
        raise OSError(f"cannot build the power model: {e}") from None


class SignalModel:
    """Level ``signals``: every traced RTL net (one per VCD identifier), weight 1 per bit toggle."""

    level = "signals"
    unit = "bit toggles"
    streams = 1

    def __init__(self, params: dict[str, int], every_net: bool = False):
        self._tmp = tempfile.TemporaryDirectory(prefix="rayflex-power-")
        self.tmp = Path(self._tmp.name)
        self.lib = _load(self.library(params, every_net))
        self.codes: dict[str, int] | None = None
        self.names: list[list[str]] = []
        self.run(np.zeros((0, REQ_WORDS), np.uint32), idle=1)    # reads the net declarations

    @staticmethod
    def library(params: dict[str, int], every_net: bool = False) -> Path:
        """The traced model of ``params`` (built on a cache miss); ``every_net``: with every
        array and vector traced (``toggles.trace_args``), as the RT unit's measurement traces
        its datapath."""
        name = "rayflex_power_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
        return _build([RTL_DIR / LINT_WAIVERS, *rtl_sources()], params,
                      name + ("_all" if every_net else ""), toggles.trace_args(every_net))

    def run(self, words: np.ndarray, idle: int = 0, only_idle: bool = False):
        """Stream ``words`` ((n, REQ_WORDS) uint32) back to back in a fresh model, then ``idle``
        cycles. Returns (cycles counted, toggles per net); with ``only_idle`` only the idle
        cycles after the stream has drained are counted."""
        words = np.ascontiguousarray(words, np.uint32)
        s = self.lib.pw_new()
        try:
            if only_idle:
                _check(self.lib.pw_stream(s, words.ctypes.data, len(words), 0))
                self._start(s)
                cycles = _check(self.lib.pw_stream(s, None, 0, idle))
            else:
                self._start(s)
                cycles = _check(self.lib.pw_stream(s, words.ctypes.data, len(words), idle))
            return cycles, self._stop(s)
        finally:
            self.lib.pw_free(s)

    def pair(self, streams: list[np.ndarray]):
        """Steady state: (ops, cycles, toggles per net) of each stream's second half."""
        ops, cycles, t = 0, 0, 0.0
        for w in streams:
            c1, t1 = self.run(w[:len(w) // 2])
            c2, t2 = self.run(w)
            ops, cycles, t = ops + len(w) - len(w) // 2, cycles + c2 - c1, t + (t2 - t1)
        return ops, cycles, t

    def idle(self, words: np.ndarray, cycles: int):
        return self.run(words, idle=cycles, only_idle=True)

    def _start(self, s):
        self.lib.pw_trace_open(s, str(self.tmp / "run.vcd").encode())

    def _stop(self, s) -> np.ndarray:
        self.lib.pw_trace_close(s)
        vcd, cnt = self.tmp / "run.vcd", self.tmp / "run.cnt"
        if self.codes is None:
            self._header(vcd)
        if self.lib.pw_vcd_count(str(vcd).encode(), str(cnt).encode()) < 0:
            raise OSError(f"cannot read the waveform {vcd}")
        out = toggles.read_counts(cnt, self.codes)
        vcd.unlink()
        return out

    def _header(self, vcd: Path) -> None:
        """Net index, names, weights and stages from the VCD's declarations."""
        with open(vcd) as f:
            self.codes, self.names = toggles.declarations(f)
        self.weight = np.array([0.0 if any(_is_tb_input(p) for p in ps) else 1.0
                                for ps in self.names])
        self.stage = np.array([_signal_stage(ps) for ps in self.names], np.int8)


def _check(cycles: int) -> int:
    if cycles < 0:
        raise RuntimeError("power model deadlocked: no handshake for 1000 cycles")
    return int(cycles)


def _is_tb_input(path: str) -> bool:
    parts = path.split(".")
    return len(parts) == 2 and parts[1] in TB_INPUTS        # TOP.<port>


_SKID_REG = re.compile(r"\.(g_reg\[\d+\]\.u_reg|u_in_reg|u_dec_reg|u_out_reg)\.\w+_q$")
_STAGE = re.compile(r"\.u_s(\d)\.")          # u_s0: the q8 decode stage (COMPRESSED)


def _signal_stage(paths: list[str]) -> int:
    """Stage label of an RTL net from all its names (STAGE_LABELS index)."""
    if any(_SKID_REG.search(p) for p in paths):
        return STAGE_LABELS.index("registers")
    for p in paths:
        m = _STAGE.search(p)
        if m:
            return STAGE_LABELS.index(f"S{m.group(1)}")
    if any(".u_out." in p for p in paths):
        return STAGE_LABELS.index("out")
    return STAGE_LABELS.index("control")


class GateModel:
    """Level ``gates``: every gate output of the generic-gate netlist, weight = its fan-out,
    simulated by ``gatesim`` on 64 lanes: up to 32 stream pairs per pass."""

    level = "gates"
    unit = "fan-out-weighted toggles"
    streams = gatesim.LANES // 2

    def __init__(self, net: Netlist):
        self.net = net
        driven = net.driver >= 0
        self.weight = np.where(driven, net.fanout, 0).astype(np.float64)
        self.stage = np.where(driven, net.stage, STAGE_LABELS.index("control")).astype(np.int8)

    def _simulate(self, streams: list[np.ndarray], idle: int, count_from_idle: bool):
        """Stream ``streams[k]`` (n_k x REQ_WORDS) back to back in lane k, then ``idle`` cycles.
        Returns (cycles per lane, toggles per net in lanes 0..31, in lanes 32..63); the counts
        cover each lane's run or, with ``count_from_idle``, only the transitions between two idle
        cycles (the last response leaving is the stream's activity, not idle activity)."""
        L = gatesim.LANES
        if len(streams) > L:
            raise ValueError(f"at most {L} streams per pass")
        sim = gatesim.GateSim(self.net)
        length = np.array([len(w) for w in streams] + [0] * (L - len(streams)))
        words = np.zeros((L, max(1, length.max()) + 1, REQ_WORDS), np.uint32)
        for k, w in enumerate(streams):
            words[k, :len(w)] = w
            words[k, len(w):] = w[-1] if len(w) else 0      # inputs keep their last value
        sent = np.zeros(L, np.int64)
        taken = np.zeros(L, np.int64)
        done_at = np.zeros(L, np.int64)
        lo = np.uint64((1 << (L // 2)) - 1)
        hi = ~lo
        count = [np.zeros(sim.n), np.zeros(sim.n)]
        prev = None
        prev_busy = np.zeros(L, bool)
        bit = np.uint64(1) << np.arange(L, dtype=np.uint64)
        sim.set_input("rst_ni", np.ones((L, 1)))
        sim.set_input("out_ready_i", np.ones((L, 1)))
        sim.set_input("clk_i", np.zeros((L, 1)))
        cycle = 0
        idle_left = idle
        while True:
            busy = taken < length
            if not busy.any() and not prev_busy.any():
                if idle_left == 0:
                    break
                idle_left -= 1
            valid = sent < length
            sim.set_input("in_valid_i", valid[:, None])
            req = words[np.arange(L), np.minimum(sent, words.shape[1] - 1)]
            sim.set_input("req_i", np.unpackbits(req.view(np.uint8), axis=1,
                                                 bitorder="little"))
            sim.settle()
            # a lane counts the transition into this cycle's state if it was busy in the
            # previous cycle (as the VCD of the RTL harness ends with the state after the last
            # response's clock); an idle run counts transitions between two idle cycles only
            if count_from_idle:
                mask = ~np.uint64(0) if not busy.any() and not prev_busy.any() else np.uint64(0)
            else:
                mask = np.bitwise_or.reduce(bit[prev_busy]) if prev_busy.any() else np.uint64(0)
            if prev is not None and mask:
                x = (sim.v ^ prev) & mask
                count[0] += np.bitwise_count(x & lo)
                count[1] += np.bitwise_count(x & hi)
            prev = sim.v.copy()
            prev_busy = busy
            in_fire = valid & sim.output("in_ready_o")[:, 0]
            out_fire = sim.output("out_valid_o")[:, 0] & busy
            sim.clock()
            cycle += 1
            sent += in_fire
            taken += out_fire
            done_at[busy & (taken == length)] = cycle
            if cycle > 4 * (length.max() + 50) + idle:
                raise RuntimeError("gate-level model deadlocked")
        return done_at, count[0], count[1]

    def pair(self, streams: list[np.ndarray]):
        """Steady state of ``streams`` (each 2n requests): the first halves in lanes 0..31 and the
        whole streams in lanes 32..63. Returns (ops, cycles, toggles per net) of the difference."""
        out_ops, out_cycles, out_t = 0, 0, 0.0
        half = self.streams
        for i in range(0, len(streams), half):
            chunk = streams[i:i + half]
            firsts = [w[:len(w) // 2] for w in chunk]
            lanes = firsts + [np.zeros((0, REQ_WORDS), np.uint32)] * (half - len(chunk)) + chunk
            done, t_first, t_full = self._simulate(lanes, 0, False)
            out_ops += sum(len(w) - len(w) // 2 for w in chunk)
            out_cycles += int(done[half:half + len(chunk)].sum() - done[:len(chunk)].sum())
            out_t = out_t + (t_full - t_first)
        return out_ops, out_cycles, out_t

    def idle(self, words: np.ndarray, cycles: int):
        """Toggles of ``cycles`` idle cycles after ``words`` drained (summed over 64 lanes)."""
        _, a, b = self._simulate([words] * gatesim.LANES, cycles, True)
        return cycles * gatesim.LANES, a + b
