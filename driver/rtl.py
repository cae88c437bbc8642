"""RTL backends: the SystemVerilog RayFlex datapath simulated by Verilator.

``HarnessBackend`` ("rtl") streams a whole request batch through the Verilated model in one C++
call (sim/rayflex_harness.cpp). ``PyverilatorBackend`` ("pyverilator") drives the same model cycle
by cycle from Python (single steps, optional VCD waveform). Given the same requests and the same
input-gap / output-stall patterns, both return identical responses and identical cycle counts.

``HarnessBackend.run_nodes`` is the traversal fast path: the harness assembles QUADBOX/TRIANGLE
requests from a packed ray table (``ray_words``) and the BVH4 image, so the host sends three
numbers per request instead of 320 bytes. The same harness library runs the RT-unit replay
(``driver.rtunit``); ``harness_library(params)`` loads it once per process.

Both build on first use (cached, keyed by the RTL sources and parameters; see driver.verilate).
"""

from __future__ import annotations

import ctypes
import json
import os
from pathlib import Path

import numpy as np

from . import verilate
from .backends import BackendError
from .datapath import LATENCY, REQUEST_DTYPE, check_requests
from .wire import REQ_WORDS, RSP_WORDS, pack_requests, unpack_responses

ROOT = Path(__file__).resolve().parent.parent
RTL_DIR = ROOT / "rtl"
SIM_DIR = ROOT / "sim"
TOP = "rayflex"

# Compile order: the packages first, then the leaf units, then the stages and the top.
# (rf_fp_round.sv and rf_fp_normalize.sv wrap rf_fp_pkg's functions as modules for the FP unit
# tests; the datapath calls the functions.)
RTL_FILES = [
    "rf_pkg.sv", "rf_fp_pkg.sv", "rf_fp_add.sv", "rf_fp_mul.sv", "rf_fp_cmp.sv",
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
    if int(latency) < 11:
        raise BackendError(f"latency {latency}: the RTL needs at least 11 stages (input register, "
                           "9 compute stages, output register)")
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
        check_requests(req, self.extended)

    def _max_idle(self) -> int:
        return 64 * PATTERN_LEN + 100 * self.latency


class HarnessBackend(_RtlBase):
    """The fast path: one C++ call streams a batch through the Verilated model.

    ``run(requests)`` takes a ``REQUEST_DTYPE`` array; ``run_nodes(...)`` takes traversal requests
    as (ray, node pointer, extent) triples and lets the harness assemble the request words from the
    packed rays and the BVH4 image (no per-request Python work; see ``driver.traversal``)."""

    name = "rtl"

    def __init__(self, **options):
        super().__init__(**options)
        self._lib = harness_library(self.params)
        self._sim = self._lib.rf_new()

    def __del__(self):
        sim, self._sim = getattr(self, "_sim", None), None
        if sim:
            self._lib.rf_free(sim)

    def _patterns(self):
        gap = self.gap.ctypes.data_as(_U8P) if self.gap is not None else None
        stall = self.stall.ctypes.data_as(_U8P) if self.stall is not None else None
        return gap, PATTERN_LEN, stall, PATTERN_LEN, self._max_idle()

    def _account(self, cycles: int, n: int) -> None:
        if cycles == -2:
            raise ValueError("a traversal request names a node pointer outside the BVH image")
        if cycles < 0:
            raise RuntimeError("RTL pipeline deadlocked: no handshake for too many cycles")
        self.cycles += int(cycles)
        self.requests += n

    def run(self, req: np.ndarray) -> np.ndarray:
        self._check(req)
        words = pack_requests(req)
        out = np.zeros((len(req), RSP_WORDS), np.uint32)
        cycles = self._lib.rf_run(self._sim, _u32p(words), _u32p(out), len(req),
                                  *self._patterns())
        self._account(cycles, len(req))
        return unpack_responses(out)

    def run_nodes(self, ray_words: np.ndarray, image_words: np.ndarray, ray: np.ndarray,
                  ptr: np.ndarray, extent: np.ndarray) -> np.ndarray:
        """Stream traversal requests: request i is ray ``ray[i]`` (a row of ``ray_words``, see
        ``ray_words()``; tag = the ray index) against the node at pointer ``ptr[i]`` of the BVH4
        image ``image_words`` (QUADBOX for a box node, TRIANGLE for a triangle node), with extent
        ``extent[i]``. Returns the (n, RSP_WORDS) uint32 response words, in request order.
        Bit-identical to ``run()`` on the same requests built in Python (tests check)."""
        rw, img, r, p, e = node_arrays(ray_words, image_words, ray, ptr, extent)
        n = len(r)
        out = np.empty((n, RSP_WORDS), np.uint32)
        cycles = self._lib.rf_run_nodes(self._sim, _u32p(rw), _u32p(img), img.size, _u32p(r),
                                        _u32p(p), _u32p(e), _u32p(out), n, *self._patterns())
        self._account(cycles, n)
        return out


_U8P = ctypes.POINTER(ctypes.c_uint8)
_U32P = ctypes.POINTER(ctypes.c_uint32)
_I64P = ctypes.POINTER(ctypes.c_int64)
_LIBS: dict = {}


def _u32p(a: np.ndarray):
    return a.ctypes.data_as(_U32P)


def harness_library(params: dict[str, int]) -> ctypes.CDLL:
    """The C++ harness (sim/rayflex_harness.cpp) over the Verilated model with these parameters,
    built on first use and loaded once per process."""
    key = tuple(sorted(params.items()))
    lib = _LIBS.get(key)
    if lib is None:
        lib = use_library(params, _build_harness(params))
    return lib


def use_library(params: dict[str, int], path) -> ctypes.CDLL:
    """Load the harness library at ``path`` and make it this process's library for ``params``
    (``harness_library``, the "rtl" backend and the RT-unit replay then use it). The build's
    profile-guided-optimisation training (``driver.pgo``) runs the instrumented library this way."""
    lib = ctypes.CDLL(str(path))
    i64, vp = ctypes.c_int64, ctypes.c_void_p
    lib.rf_new.restype = vp
    lib.rf_free.argtypes = [vp]
    lib.rf_run.restype = i64
    lib.rf_run.argtypes = [vp, _U32P, _U32P, i64, _U8P, i64, _U8P, i64, i64]
    lib.rf_run_nodes.restype = i64
    lib.rf_run_nodes.argtypes = [vp, _U32P, _U32P, i64, _U32P, _U32P, _U32P, _U32P, i64,
                                 _U8P, i64, _U8P, i64, i64]
    lib.rf_build_requests.restype = i64
    lib.rf_build_requests.argtypes = [_U32P, _U32P, i64, _U32P, _U32P, _U32P, _U32P, i64]
    lib.rf_replay.restype = i64
    lib.rf_replay.argtypes = [i64, i64, i64, i64, _U32P, i64, _U32P, i64, _U32P, _U32P, _U32P,
                              i64, _I64P, _I64P, _U32P, _I64P, _I64P, i64]
    if (lib.rf_req_words() != REQ_WORDS or lib.rf_rsp_words() != RSP_WORDS
            or lib.rf_ray_words() != RAY_WORDS):
        raise BackendError("harness and driver disagree on the wire format; rebuild")
    _LIBS[tuple(sorted(params.items()))] = lib
    return lib


RAY_WORDS = 15            # wire words 0..14 of a request: tag, control, origin, dir, inv, extent,
#                           shear; the rest of a traversal request is its box or triangle


def ray_words(rays: np.ndarray) -> np.ndarray:
    """The ray table of ``run_nodes``/``replay``: (n, RAY_WORDS) uint32, wire words 0..14 of the
    prepared rays (``prepare_rays``): tag, control (kx, ky, kz; opcode as given), origin, dir,
    inv, extent, shear. Box, triangle and vector fields are not part of it (a traversal request
    carries zero vector fields; the harness fills the box or the triangle)."""
    if rays.dtype != REQUEST_DTYPE:
        raise TypeError("rays must be a REQUEST_DTYPE array")
    n = len(rays)
    w = np.empty((n, RAY_WORDS), np.uint32)
    w[:, 0] = rays["tag"]
    u = lambda f: rays[f].astype(np.uint32)  # noqa: E731
    w[:, 1] = ((u("opcode") & 3) | (u("kx") & 3) << 2 | (u("ky") & 3) << 4 | (u("kz") & 3) << 6
               | (u("reset_accumulator") & 1) << 8 | u("vec_mask") << 16)
    for name, first, count in (("origin", 2, 3), ("dir", 5, 3), ("inv", 8, 3), ("extent", 11, 1),
                               ("shear", 12, 3)):
        w[:, first:first + count] = rays[name].reshape(n, count).view(np.uint32)
    return w


def node_arrays(ray_words_, image_words, ray, ptr, extent):
    """Checked contiguous arrays (ray table, image words, ray, ptr, extent bits: uint32) for the
    harness calls that assemble traversal requests."""
    rw = np.ascontiguousarray(ray_words_, np.uint32)
    if rw.ndim != 2 or rw.shape[1] != RAY_WORDS:
        raise ValueError(f"ray words must be (n, {RAY_WORDS}) uint32")
    img = np.ascontiguousarray(image_words).reshape(-1).view(np.uint32)
    r = np.ascontiguousarray(ray, np.uint32).reshape(-1)
    p = np.ascontiguousarray(ptr, np.uint32).reshape(-1)
    e = np.ascontiguousarray(extent, np.float32).reshape(-1).view(np.uint32)
    if not len(r) == len(p) == len(e):
        raise ValueError("ray, ptr and extent must have the same length")
    if len(r) and int(r.max()) >= len(rw):
        raise ValueError("a ray index is out of range of the ray table")
    return rw, img, r, p, e


def build_requests(params: dict[str, int], ray_words_: np.ndarray, image_words: np.ndarray,
                   ray, ptr, extent) -> np.ndarray:
    """The (n, REQ_WORDS) request words ``run_nodes``/``replay`` assemble for these triples."""
    lib = harness_library(params)
    rw, img, r, p, e = node_arrays(ray_words_, image_words, ray, ptr, extent)
    out = np.zeros((len(r), REQ_WORDS), np.uint32)
    if lib.rf_build_requests(_u32p(rw), _u32p(img), img.size, _u32p(r), _u32p(p), _u32p(e),
                             _u32p(out), len(r)) < 0:
        raise ValueError("a traversal request names a node pointer outside the BVH image")
    return out


def pgo_enabled() -> bool:
    """Whether the harness is built with profile-guided optimisation (``driver.pgo``): yes unless
    the environment sets ``RAYFLEX_PGO=0`` (a faster first build, a slower simulation)."""
    value = os.environ.get("RAYFLEX_PGO", "1").strip().lower()
    if value not in ("0", "1", "no", "yes", "off", "on", "false", "true", ""):
        raise BackendError(f"RAYFLEX_PGO={value!r}: use 1 (profile-guided build, the default) or 0")
    return value not in ("0", "no", "off", "false")


def _build_harness(params: dict[str, int]) -> Path:
    name = "rayflex_" + "_".join(f"{k[0].lower()}{v}" for k, v in params.items())
    train = train_env = None
    if pgo_enabled():
        train = [verilate.PYTHON, "-m", "driver.pgo", json.dumps(params, sort_keys=True)]
        train_env = {"PYTHONPATH": os.pathsep.join(
            [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    try:
        return verilate.build_library(TOP, rtl_sources(), [SIM_DIR / "rayflex_harness.cpp"],
                                      params=params, name=name, train=train,
                                      train_env=train_env)
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
    except ImportError:
        raise BackendError("the pyverilator backend needs the pyverilator-mm package") from None
    so = _build_pyverilator(params)
    # pyverilator's wrapper keeps one global time counter per loaded library, and Verilator refuses
    # to add a model while time is non-zero: reset it so a process can create several models.
    ctypes.c_double.in_dll(ctypes.CDLL(str(so)), "main_time").value = 0.0
    return pyverilator.PyVerilator(str(so))


def _build_pyverilator(params: dict[str, int]) -> Path:
    """The cached pyverilator shared object (driver.verilate.build_pyverilator)."""
    try:
        return verilate.build_pyverilator(
            TOP, RTL_DIR / f"{TOP}.sv", rtl_sources(), [RTL_DIR / "rf_pkg.sv"], [RTL_DIR], params,
            defines=["RF_ASSERTIONS"],            # the skid buffers' protocol assertions
            verilator_args=["--assert"])
    except verilate.BuildError as e:
        raise BackendError(f"cannot build the pyverilator backend: {e}") from None
