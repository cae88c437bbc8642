"""Switching activity of one configuration: a Verilated model that counts the toggles of every
net while request streams run through it (sim/power_harness.cpp).

Two models share one interface, ``run(words, idle=0, only_idle=False) -> (cycles, toggles)``,
where ``toggles`` is a float64 vector over the model's nets:

* ``SignalModel`` (level ``signals``): the RTL built with ``--trace``; a run writes a VCD and the
  harness counts bit toggles per VCD identifier (one per net: aliases share it). The VCD is
  written to a temporary file and counted in C++ (a 300-request run: ~25 MB, ~0.1 s).
* ``GateModel`` (level ``gates``): the generic-gate netlist (``netlist.py``) built with
  ``--coverage-toggle``; a run zeroes Verilator's toggle counters and writes them afterwards.

Both are built once per configuration and cached by ``driver.verilate`` (hash of the sources,
parameters and recipe). Each run uses a fresh model instance (reset, all registers zero), so a
run's toggles depend only on its requests: the same seed gives the same numbers.
"""

from __future__ import annotations

import ctypes
import re
import tempfile
from pathlib import Path

import numpy as np

from .. import verilate
from ..rtl import RTL_DIR, LINT_WAIVERS, SIM_DIR, rtl_sources
from ..wire import REQ_WORDS
from .netlist import STAGE_LABELS, Netlist

HARNESS = SIM_DIR / "power_harness.cpp"
# inputs driven by the test bench (their toggles are the driver's, and the clock has no tree here)
TB_INPUTS = ("clk_i", "rst_ni", "in_valid_i", "req_i", "out_ready_i")
# the netlist is ~5 x 10^5 single-bit assigns: split the C++ into files and functions so that
# the compiler sees many small functions (one huge one is slow to optimise)
_GATE_VARGS = ["--coverage-toggle", "--output-split", "20000", "--output-split-cfuncs", "2000",
               "-Wno-fatal", "-Wno-lint", "-Wno-style"]


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    vp, i64 = ctypes.c_void_p, ctypes.c_int64
    lib.pw_new.restype = vp
    lib.pw_free.argtypes = [vp]
    lib.pw_stream.restype = i64
    lib.pw_stream.argtypes = [vp, vp, i64, i64]
    if lib.pw_req_words() != REQ_WORDS:
        raise OSError("power harness and driver disagree on the request width; rebuild")
    if lib.pw_mode() == 1:
        lib.pw_trace_open.argtypes = [vp, ctypes.c_char_p]
        lib.pw_trace_close.argtypes = [vp]
        lib.pw_vcd_count.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
        lib.pw_vcd_count.restype = i64
    else:
        lib.pw_zero.argtypes = [vp]
        lib.pw_write.argtypes = [vp, ctypes.c_char_p]
    return lib


def _build(sv, params, name, vargs) -> Path:
    try:
        return verilate.build_library("rayflex", sv, [HARNESS], params=params, name=name,
                                      verilator_args=vargs)
    except verilate.BuildError as e:
        raise OSError(f"cannot build the power model: {e}") from None


class _Model:
    level = ""
    unit = ""

    def __init__(self):
        self._tmp = tempfile.TemporaryDirectory(prefix="rayflex-power-")
        self.tmp = Path(self._tmp.name)

    def run(self, words: np.ndarray, idle: int = 0, only_idle: bool = False):
        """Stream ``words`` ((n, REQ_WORDS) uint32) back to back in a fresh model, then ``idle``
        cycles. Returns (cycles counted, toggles per net); with ``only_idle`` only the idle
        cycles after the stream has drained are counted."""
        words = np.ascontiguousarray(words, np.uint32)
        s = self.lib.pw_new()
        try:
            if only_idle:
                self._check(self.lib.pw_stream(s, words.ctypes.data, len(words), 0))
                self._start(s)
                cycles = self._check(self.lib.pw_stream(s, None, 0, idle))
            else:
                self._start(s)
                cycles = self._check(self.lib.pw_stream(s, words.ctypes.data, len(words), idle))
            return cycles, self._stop(s)
        finally:
            self.lib.pw_free(s)

    @staticmethod
    def _check(cycles: int) -> int:
        if cycles < 0:
            raise RuntimeError("power model deadlocked: no handshake for 1000 cycles")
        return int(cycles)


class SignalModel(_Model):
    """Level ``signals``: every traced RTL net (one per VCD identifier), weight 1 per bit toggle."""

    level = "signals"
    unit = "bit toggles"

    def __init__(self, params: dict[str, int]):
        super().__init__()
        name = "rayflex_power_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
        self.lib = _load(_build([RTL_DIR / LINT_WAIVERS, *rtl_sources()], params, name,
                                ["--trace"]))
        self.codes: dict[str, int] | None = None
        self.names: list[list[str]] = []
        self.run(np.zeros((0, REQ_WORDS), np.uint32), idle=1)    # reads the net declarations

    def _start(self, s):
        self.lib.pw_trace_open(s, str(self.tmp / "run.vcd").encode())

    def _stop(self, s) -> np.ndarray:
        self.lib.pw_trace_close(s)
        vcd, cnt = self.tmp / "run.vcd", self.tmp / "run.cnt"
        if self.codes is None:
            self._header(vcd)
        if self.lib.pw_vcd_count(str(vcd).encode(), str(cnt).encode()) < 0:
            raise OSError(f"cannot read the waveform {vcd}")
        out = np.zeros(len(self.codes))
        for line in cnt.read_text().splitlines():
            code, n = line.rsplit(" ", 1)
            out[self.codes[code]] = float(n)
        vcd.unlink()
        return out

    def _header(self, vcd: Path) -> None:
        """Net index, names, weights and stages from the VCD's declarations."""
        codes: dict[str, int] = {}
        names: list[list[str]] = []
        scope: list[str] = []
        with open(vcd) as f:
            for line in f:
                w = line.split()
                if not w:
                    continue
                if w[0] == "$scope":
                    scope.append(w[2])
                elif w[0] == "$upscope":
                    scope.pop()
                elif w[0] == "$var":
                    code, name = w[3], w[4]
                    if code not in codes:
                        codes[code] = len(codes)
                        names.append([])
                    names[codes[code]].append(".".join([*scope, name]))
                elif w[0] == "$enddefinitions":
                    break
        self.codes, self.names = codes, names
        self.weight = np.array([0.0 if any(_is_tb_input(p) for p in ps) else 1.0
                                for ps in names])
        self.stage = np.array([_signal_stage(ps) for ps in names], np.int8)


def _is_tb_input(path: str) -> bool:
    parts = path.split(".")
    return len(parts) == 2 and parts[1] in TB_INPUTS        # TOP.<port>


_SKID_REG = re.compile(r"\.(g_reg\[\d+\]\.u_reg|u_in_reg|u_out_reg)\.\w+_q$")
_STAGE = re.compile(r"\.u_s(\d)\.")


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


class GateModel(_Model):
    """Level ``gates``: every gate output of the generic-gate netlist, weight = its fan-out."""

    level = "gates"
    unit = "fan-out-weighted toggles"

    def __init__(self, net: Netlist, params: dict[str, int]):
        super().__init__()
        name = "rayflex_gates_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
        self.lib = _load(_build([net.verilog_path], {}, name, _GATE_VARGS))
        self.net = net
        n = len(net.fanout)
        driven = net.driver >= 0
        self.weight = np.where(driven, net.fanout, 0).astype(np.float64)
        self.stage = np.where(driven, net.stage, STAGE_LABELS.index("control")).astype(np.int8)
        self.n = n

    def _start(self, s):
        self.lib.pw_zero(s)

    def _stop(self, s) -> np.ndarray:
        path = self.tmp / "cov.dat"
        self.lib.pw_write(s, str(path).encode())
        return parse_coverage(path, self.n)


_COV = re.compile(rb"\x01o\x02n(\d+)(?:\[\d+\])?:[01]->[01]\x01.*' (\d+)$")


def parse_coverage(path: Path, n: int) -> np.ndarray:
    """Toggles per net ``n<id>`` from a Verilator coverage file (both directions summed)."""
    out = np.zeros(n)
    with open(path, "rb") as f:
        for line in f:
            m = _COV.search(line.rstrip(b"\n"))
            if m:
                out[int(m.group(1))] += int(m.group(2))
    return out
