"""The "pyverilator" backend: the same Verilated RTL driven cycle by cycle from Python.

``step()`` runs single cycles, ``vcd=`` writes a waveform of every run. It applies the same
handshake sequence per cycle as the C++ harness, so given the same requests and gap/stall
patterns it returns identical responses and cycle counts (tests check). It is ~100x slower than
the "rtl" harness: for waveforms and cross-checks, not frames.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import numpy as np

from . import verilate
from ..core.wire import RSP_WORDS, pack_requests, unpack_responses
from .base import BackendError
from .build import RTL_DIR, TOP, rtl_sources
from .rtlbase import PATTERN_LEN, RtlBackendBase


class PyverilatorBackend(RtlBackendBase):
    """Cycle-by-cycle path through pyverilator: ``step()`` for single cycles, ``vcd=`` for a
    waveform of every run. Same handshake sequence per cycle as the C++ harness."""

    name = "pyverilator"

    def __init__(self, vcd: str | os.PathLike | None = None, **options):
        super().__init__(**options)
        self.sim = _pyverilator_model(self.params)
        self.vcd = str(vcd) if vcd else None
        if self.vcd:
            self.sim.start_vcd_trace(self.vcd)
        io = self.sim.io
        io.clk_i = 0
        io.rst_ni = 0
        io.in_valid_i = 0
        io.out_ready_i = 0
        for _ in range(2):
            self._tick()
        io.rst_ni = 1

    def _tick(self):
        self.sim.io.clk_i = 1
        self.sim.io.clk_i = 0

    def step(self, in_valid: bool, req_word: int, out_ready: bool):
        """One clock cycle: drive the inputs, sample the handshakes, clock. Returns
        (in_fire, out_fire, response wire value or None)."""
        io = self.sim.io
        io.in_valid_i = int(in_valid)
        if in_valid:
            io.req_i = req_word
        io.out_ready_i = int(out_ready)
        in_fire = bool(in_valid and io.in_ready_o)
        out_fire = bool(io.out_valid_o and out_ready)
        rsp = int(io.rsp_o) if out_fire else None
        self._tick()
        return in_fire, out_fire, rsp

    def run(self, req: np.ndarray) -> np.ndarray:
        self._check(req)
        n = len(req)
        words = pack_requests(req)
        as_int = [int.from_bytes(w.tobytes(), "little") for w in words]
        out = np.zeros((n, RSP_WORDS), np.uint32)
        sent = taken = k = idle = 0
        first = last = -1
        while taken < n:
            hold = self.gap is not None and self.gap[k % PATTERN_LEN]
            stall = self.stall is not None and self.stall[k % PATTERN_LEN]
            valid = sent < n and not hold
            in_fire, out_fire, rsp = self.step(valid, as_int[sent] if valid else 0, not stall)
            if out_fire:
                out[taken] = np.frombuffer(rsp.to_bytes(RSP_WORDS * 4, "little"), np.uint32)
                taken += 1
                last = k
            if in_fire:
                first = k if first < 0 else first
                sent += 1
            idle = 0 if (in_fire or out_fire) else idle + 1
            if idle > self._max_idle():
                raise RuntimeError("RTL pipeline deadlocked: no handshake for too many cycles")
            k += 1
        self.sim.io.in_valid_i = 0
        self.sim.io.out_ready_i = 0
        if self.vcd:
            self.sim.flush_vcd_trace()
        cycles = last - first + 1 if n else 0
        self.cycles += cycles
        self.requests += n
        return unpack_responses(out)


def _pyverilator_model(params: dict[str, int]):
    """Build (or reuse) the pyverilator model of the datapath with these parameters."""
    try:
        import pyverilator
    except ImportError:
        raise BackendError("the pyverilator backend needs the pyverilator-mm package") from None
    so = _build_pyverilator(params)
    # pyverilator's wrapper keeps one global time counter per loaded library, and Verilator refuses
    # to add a model while time is non-zero: reset it so a process can create several models.
    ctypes.c_double.in_dll(ctypes.CDLL(str(so)), "main_time").value = 0.0
    return pyverilator.PyVerilator(str(so))


def _build_pyverilator(params: dict[str, int]) -> Path:
    """The cached pyverilator shared object (driver.backends.verilate.build_pyverilator)."""
    try:
        return verilate.build_pyverilator(
            TOP, RTL_DIR / f"{TOP}.sv", rtl_sources(),
            [f for f in rtl_sources() if f.stem.endswith("_pkg")], [RTL_DIR], params,
            defines=["RF_ASSERTIONS"],            # the skid buffers' protocol assertions
            verilator_args=["--assert"])
    except verilate.BuildError as e:
        raise BackendError(f"cannot build the pyverilator backend: {e}") from None
