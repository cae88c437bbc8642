"""The "rtunit" backend: the RT unit in RTL (``rtl/rf_rtunit.sv``: ray buffer, stacks, node fetch,
scheduler, response processing and divider around the unchanged datapath) traversing whole
batches of rays by itself, driven by ``sim/rtunit_rtl_harness.cpp`` (docs/rtunit_rtl.md).

``RtUnitBackend`` is the "rtl" backend (``run``/``run_nodes`` on its datapath, for everything that
issues single requests) plus ``trace_unit``: a frame's prepared rays in, hits, per-ray op counts
and the unit's cycles out, with no host work per traversal step. ``driver.tracer.trace`` calls it
in place of the Python traversal. The unit reads box32 images (box nodes and triangle nodes) and,
built with the datapath's q8 decode stage (a ``-q8`` configuration), q8 images (q8 box nodes and
triangle-pair leaves); built with the datapath's TRANSFORM (``--transform datapath``), two-level
images (instance nodes: each ray entering an instance sends a TRANSFORM request); built with CULL
(``cull=True``, ``--cull-stack``) its stack keeps each entry's distance and culls as
``driver.traversal``'s ``cull`` does (docs/rtunit_rtl.md#the-culling-stack); q8g images and
instances without TRANSFORM are refused with one line before any work.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.layout import (BOX_NODE, BOX_TYPE, INSTANCE_NODE, INSTANCE_TYPE, NO_CHILD, NODE_BYTES,
                           PAIR_TYPE, Q8_NODE, Q8_TYPE, TRI_TYPE, NodeRef, node_word)
from ..core.wire import RAY_WORDS, ray_words
from . import toggles, unit_memo, verilate
from .base import BackendError
from .build import (DIV_SOURCE_LIST, RTL_DIR, SIM_DIR, layout_header_dir, parse_source_list,
                    rtl_sources)
from .harness import HarnessBackend, MemoryConfig, memory_config

UNIT_TOP = "rf_rtunit"
UNIT_SOURCE_LIST = RTL_DIR / "rtunit_sources.txt"
UNIT_LINT_WAIVERS = "rtunit_lint.vlt"
UNIT_HARNESS = "rtunit_rtl_harness.cpp"
MAX_RAYS = 256                      # ray slots the unit can be built with (RAYS)
MIN_STACK_DEPTH, MAX_STACK_DEPTH = 2, 4096
DEFAULT_STACK_DEPTH = 32
DEFAULT_DIVIDERS, MAX_DIVIDERS = 2, 16   # binary32 dividers (rf_fp_div: one division at a time)
DEFAULT_SETUPS, MAX_SETUPS = 2, 16       # ray setups (rf_rtu_setup: one ray entering an instance)
MAX_UNIT_PIPELINES = 4              # datapath pipelines the unit can be built with (PIPELINES)
DEFAULT_MEM_LATENCY = 20            # the fixed-latency memory behind the port, cycles
FORMATS = ("box32", "q8")           # node images the unit reads (q8: with the decode stage)
# what checks the unit's rays besides Embree (``--unit-check``): the Python traversal on the unit's
# datapath and the replay of its requests (the backend's ``compare``), or nothing
UNIT_CHECKS = ("traversal", "none")
UNIT_BACKEND = "rtunit"
# the design options (driver/design.py) the unit reads: its ray slots, stack, pipelines, check
# and memory hierarchy
UNIT_OPTIONS = ("rays_in_flight", "stack_depth", "pipelines", "unit_check", "cache_kib",
                "cache_ways", "cache_latency", "mshrs", "l2_kib", "l2_ways", "l2_latency",
                "line_bytes", "sector_bytes", "mem_latency", "mem_bytes_per_cycle")
# the unit's statistics, in the order of rf_rtunit_stats::RtuStats (generated from this tuple);
# UNIT_STAT_ARRAYS: those with one entry per pipeline (MAX_UNIT_PIPELINES entries)
UNIT_STATS = (
    "cycles",                   # first ray offered to the last result taken
    "cycles_simulated",         # clock cycles the model ran
    "dp_requests",              # requests that entered the datapath
    "mem_requests",             # node fetches on the memory port
    "mem_bytes",                # bytes those fetches read
    "mem_outstanding_cycles",   # cycles with at least one fetch outstanding
    "busy_cycles",              # cycles with at least one ray in the unit
    "overflows",                # pushes onto a full stack: its oldest entry spilled to memory
    "refill_reads",             # spilled entries read back
    "max_stack_depth",          # most entries any ray's stack held
    "divider_busy_cycles",      # sum over cycles of the dividers holding a division
    "divider_full_cycles",      # cycles with every divider holding one
    "setup_busy_cycles",        # sum over cycles of the ray setups holding a ray
    "pipeline_requests",        # per pipeline: requests that entered it (cycles its input took one)
    "skipped_cycles",           # cycles counted without clocking the model (every ray waited)
)
UNIT_STAT_ARRAYS = ("pipeline_requests",)
# the top's instances, one row each in the unit's area and energy tables: instance -> (row name,
# what it is); the top's own logic (slot states, arbiters, result register) is the row CONTROL
UNIT_INSTANCES = {
    "u_datapath": ("datapath", "rayflex, the configuration's datapath (the area flow's count)"),
    "u_rays": ("ray buffer", "prepared rays, ids, nearest t, hit records, op counters"),
    "u_stack": ("stack", "RAYS x STACK_DEPTH pointers, per-slot counts and spill counts"),
    "u_fetch": ("fetch", "node requests and the node buffer (RAYS x 128 B)"),
    "u_sched": ("scheduler", "picks a ready slot, assembles its request"),
    "u_resp": ("response", "pushes hit children, hands triangle hits to the dividers"),
    "u_div": ("dividers", "DIVIDERS binary32 dividers for t = t_num / t_den"),
    "u_hit": ("hit", "nearest-t compare, any-hit termination"),
    "u_setup": ("ray setups", "SETUPS ray setups of the rays entering instances (TRANSFORM)"),
}
UNIT_CONTROL = ("control", "the top: slot states, arbiters, result register")
UNIT_ROWS = tuple(name for name, _ in UNIT_INSTANCES.values()) + (UNIT_CONTROL[0],)
_OK, _BUDGET, _BAD_ADDRESS, _BAD_ARGS, _BAD_GEOMETRY, _RAY_ERROR = 0, -1, -2, -3, -4, -5
# the per-ray counters the harness writes (kUnitOps in rf_rtunit_stats.h): QUADBOX, TRIANGLE,
# overflows, refills, TRANSFORM, culled
UNIT_OPS = 6
ADVANCE_CYCLES = 1 << 16            # cycles per harness call (progress and Ctrl-C between calls)
# a run's cycle budget: BUDGET_BASE + BUDGET_PER_RAY per ray + BUDGET_PER_REQUEST per datapath
# request made so far (so a correct frame of rays with thousands of nodes each never meets it,
# and a unit that stops making requests does), with the requests bounded by the image: a ray
# fetches each node at most once per instance it enters, so more requests than that mean a loop
BUDGET_BASE, BUDGET_PER_RAY, BUDGET_PER_REQUEST = 10_000, 20_000, 2_000
_LIBS: dict = {}


class RtuStats(ctypes.Structure):
    _fields_ = [(name, ctypes.c_int64 * MAX_UNIT_PIPELINES if name in UNIT_STAT_ARRAYS
                 else ctypes.c_int64) for name in UNIT_STATS]


def stats_header() -> str:
    """``rf_rtunit_stats.h``: the ``RtuStats`` struct the harness fills, from ``UNIT_STATS``."""
    body = "\n".join(f"  int64_t {name}[kMaxPipelines];" if name in UNIT_STAT_ARRAYS
                     else f"  int64_t {name};" for name in UNIT_STATS)
    return ("// Generated by driver/backends/rtunit.py at build time. Do not edit.\n#pragma once\n"
            "#include <cstdint>\nnamespace rf_rtunit_stats {\n"
            f"constexpr int kMaxPipelines = {MAX_UNIT_PIPELINES};\n"
            f"constexpr int kUnitOps = {UNIT_OPS};\n"
            f"struct RtuStats {{\n{body}\n}};\n}}  // namespace rf_rtunit_stats\n")


def div_cycles() -> int:
    """rf_fp_div_pkg::DIV_CYCLES, the divider's latency, read from the RTL package (its
    quotient bits over its bits per cycle, plus the input and the rounding cycle)."""
    text = (RTL_DIR / "rf_fp_div_pkg.sv").read_text()
    value = {m[1]: int(m[2]) for m in re.finditer(r"(DIV_\w+)\s*=\s*(\d+);", text)}
    if not (re.search(r"DIV_CYCLES\s*=\s*DIV_ITER_CYCLES \+ 2;", text) and
            re.search(r"DIV_ITER_CYCLES\s*=\s*DIV_QUOTIENT_BITS / DIV_DIGIT_BITS;", text)):
        raise BackendError("rtl/rf_fp_div_pkg.sv: DIV_CYCLES is no longer "
                           "DIV_QUOTIENT_BITS / DIV_DIGIT_BITS + 2")
    return value["DIV_QUOTIENT_BITS"] // value["DIV_DIGIT_BITS"] + 2


def unit_sources() -> list:
    """The datapath's RTL files, the divider's and the unit's, in compile order (a file
    once)."""
    out = []
    for path in [*rtl_sources(), *rtl_sources(DIV_SOURCE_LIST), *rtl_sources(UNIT_SOURCE_LIST)]:
        if path not in out:
            out.append(path)
    return out


def unit_params(datapath: dict, rays: int, stack_depth: int,
                dividers: int = DEFAULT_DIVIDERS, setups: int = DEFAULT_SETUPS,
                pipelines: int = 1, cull: bool = False) -> dict:
    """The unit's build parameters: RAYS, STACK_DEPTH, DIVIDERS, SETUPS, PIPELINES (given only
    when more than one: the one-pipeline unit keeps its build), CULL (the distance-culled stack,
    given only when on: the unit without it keeps its build) and the datapath's
    (``rtl_params``). BackendError (one line) for a value the RTL cannot be built with."""
    for name, v, lo, hi in (("--rays-in-flight", rays, 1, MAX_RAYS),
                            ("--stack-depth", stack_depth, MIN_STACK_DEPTH, MAX_STACK_DEPTH),
                            ("dividers", dividers, 1, MAX_DIVIDERS),
                            ("setups", setups, 1, MAX_SETUPS),
                            ("--pipelines", pipelines, 1, MAX_UNIT_PIPELINES)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
            raise BackendError(f"{name} {v!r}: the RT unit in RTL is built with {lo}..{hi}")
    return {"RAYS": int(rays), "STACK_DEPTH": int(stack_depth), "DIVIDERS": int(dividers),
            "SETUPS": int(setups), **({"PIPELINES": int(pipelines)} if pipelines > 1 else {}),
            **({"CULL": 1} if cull else {}), **datapath}


def _header_dir() -> str:
    text = stats_header()
    out = verilate.cache_dir() / "gen" / f"rtunit-{hashlib.sha256(text.encode()).hexdigest()[:16]}"
    header = out / "rf_rtunit_stats.h"
    if not header.is_file():
        try:
            out.mkdir(parents=True, exist_ok=True)
            tmp = out / f".h.{os.getpid()}"
            tmp.write_text(text)
            os.replace(tmp, header)
        except OSError as e:
            raise BackendError(f"cannot write the build cache {out}: {e.strerror}") from None
    return str(out)


def unit_library(params: dict, activity: bool = False) -> ctypes.CDLL:
    """The harness over the Verilated RT unit with these parameters (built on first use, cached;
    loaded once per process); ``activity``: the traced build that counts switching activity
    (``toggles.trace_args``; built only for ``rayflex power``)."""
    key = (tuple(sorted(params.items())), bool(activity))
    if key in _LIBS:
        return _LIBS[key]
    name = ("rtunit_" + ("act_" if activity else "")
            + "_".join(f"{k[0].lower()}{v}" for k, v in params.items()))
    try:
        path = verilate.build_library(
            UNIT_TOP, unit_sources(), [SIM_DIR / UNIT_HARNESS], params=params, name=name,
            verilator_args=["-CFLAGS", f"-I{layout_header_dir()}", "-CFLAGS",
                            f"-I{_header_dir()}", "-CFLAGS", f"-I{SIM_DIR}",
                            *(toggles.trace_args() if activity else [])])
    except verilate.BuildError as e:
        raise BackendError(f"cannot build the RT unit: {e}") from None
    lib = ctypes.CDLL(str(path))
    i64, vp, u32p = ctypes.c_int64, ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint32)
    i64p, u8p = ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_uint8)
    lib.rtu_new.restype = vp
    lib.rtu_new.argtypes = [u32p, u8p, i64, u32p, i64, ctypes.c_uint32, i64, i64, i64,
                            ctypes.POINTER(MemoryConfig), u32p, u32p, u32p, u8p, i64p, i64p]
    lib.rtu_free.argtypes = [vp]
    lib.rtu_advance.restype = i64
    lib.rtu_advance.argtypes = [vp, i64, i64p]
    lib.rtu_stats.argtypes = [vp, ctypes.POINTER(RtuStats)]
    lib.rtu_idle.argtypes = [vp, i64]
    lib.rtu_can_count.restype = i64
    lib.rtu_toggles_start.restype = i64
    lib.rtu_toggles_start.argtypes = [vp]
    lib.rtu_toggles_write.restype = i64
    lib.rtu_toggles_write.argtypes = [vp, ctypes.c_char_p, ctypes.c_char_p]
    _LIBS[key] = lib
    return lib


def net_rows(names: list[list[str]]) -> tuple[np.ndarray, np.ndarray]:
    """(row index in ``UNIT_ROWS`` per net, weight per net) of the traced unit's nets (every
    name of each, ``toggles.declarations``). A net belongs to the module that drives it: by the
    RTL's port names, a name ending in ``_i`` is a module's input (driven elsewhere), one ending
    in ``_o`` its output; a net seen only as inputs of the unit's modules is the top's logic
    (``control``); the unit's own inputs (``TOP.<port>_i``: what the harness drives) weigh 0,
    as the test bench's inputs do in the datapath's measurement."""
    rows = np.zeros(len(names), np.int64)
    weight = np.ones(len(names))
    control = UNIT_ROWS.index(UNIT_CONTROL[0])
    for k, paths in enumerate(names):
        driven = []                      # (row, name) of the names that are not inputs
        tb_input = False
        for p in paths:
            parts = p.split(".")
            if len(parts) == 2:          # TOP.<port> of the harness's model
                tb_input |= parts[1].endswith("_i")
                continue
            row = next((UNIT_ROWS.index(UNIT_INSTANCES[q][0]) for q in parts[2:-1]
                        if q in UNIT_INSTANCES), control)
            if not parts[-1].endswith("_i"):
                driven.append((row, parts[-1]))
        if tb_input:
            weight[k] = 0.0
        outputs = [r for r, leaf in driven if leaf.endswith("_o") and r != control]
        internal = [r for r, _ in driven if r != control]
        rows[k] = outputs[0] if outputs else internal[0] if internal else control
    return rows, weight


@dataclass
class UnitResult:
    """Per-ray results of a batch through the RT unit.

    prim : (n,) int64 (-1: no hit; in a two-level image the primitive id in the hit's BLAS);
    instance : (n,) int64, the hit's instance (-1: none, or a one-level image);
    t : (n,) float32 (the ray's extent without a hit); hit (n,)
    box_ops, tri_ops, xf_ops, overflows, refills : (n,) int64 (xf_ops: TRANSFORM requests);
    culled : (n,) int64, box nodes the distance-culled stack dropped (0 without CULL);
    stats : {``UNIT_STATS``} of the run
    """

    prim: np.ndarray
    t: np.ndarray
    hit: np.ndarray
    box_ops: np.ndarray
    tri_ops: np.ndarray
    overflows: np.ndarray
    refills: np.ndarray
    stats: dict
    instance: np.ndarray
    xf_ops: np.ndarray
    culled: np.ndarray
    activity: dict | None = None       # a traced backend's: ``RtUnitBackend.activity_of``
    reused: bool = False               # the results of an equal batch (``unit_memo``)


def check_format(fmt: str, compressed: bool, transform: bool, instanced: bool) -> None:
    """Refuse (ValueError, one line) a node format or an instanced scene the unit cannot read,
    before an image is built (``check_image`` checks the image itself): instances need the
    datapath's TRANSFORM (``transform``)."""
    if instanced and not transform:
        raise ValueError("the RT unit in RTL enters instances with the datapath's TRANSFORM: "
                         "give --transform datapath (or --flatten)")
    if fmt not in FORMATS:
        raise ValueError(f"the RT unit in RTL reads {', '.join(FORMATS)} images, not {fmt} "
                         f"(--bvh-format {fmt}): use --backend rtl for it")
    if fmt == "q8" and not compressed:
        raise ValueError("the RT unit in RTL reads q8 nodes with the datapath's decode stage: "
                         "give a -q8 configuration (--config baseline-unified-q8)")


def check_image(bvh, compressed: bool = False, transform: bool = False) -> None:
    """Refuse (ValueError, one line) what the unit cannot read: a node format other than
    ``FORMATS`` (q8 only with ``compressed``, the datapath's decode stage), instances without
    ``transform`` (the datapath's TRANSFORM), or a node pointer that leaves the image, names a
    node type the unit does not read (an instance node inside a BLAS among them), or loops."""
    fmt = getattr(bvh, "format", "box32")
    instanced = getattr(bvh, "instances", None) is not None
    check_format(fmt, compressed, transform, instanced)
    img = np.asarray(bvh.image).reshape(-1).view(np.uint8)
    words = img.view("<u4")
    readable = {BOX_TYPE, TRI_TYPE} | ({Q8_TYPE, PAIR_TYPE} if fmt == "q8" else set())
    child_word = np.zeros(8, np.int64)
    child_word[BOX_TYPE], child_word[Q8_TYPE] = node_word(BOX_NODE, "child"), node_word(
        Q8_NODE, "child")
    nbytes = np.array([NODE_BYTES.get(t, 0) for t in range(8)], np.int64)
    # the TLAS (instance nodes allowed), then each BLAS once (however many instances name it)
    levels = [(np.array([bvh.root], np.uint32), readable | ({INSTANCE_TYPE} if instanced
                                                             else set()))]
    seen, limit = 0, len(img) // 64 + 1          # every node takes 64 bytes or more
    while levels:
        frontier, types = levels.pop(0)
        blas = []
        while len(frontier):                      # breadth first over the box nodes' children
            seen += len(frontier)
            if seen > limit:
                raise ValueError("the BVH image's pointers form a loop")
            typ = NodeRef.type(frontier)
            if not np.isin(typ, list(types)).all():
                raise ValueError("a BVH pointer names a node type the RT unit cannot read")
            off = NodeRef.offset(frontier)
            if ((off + nbytes[typ]) > len(img)).any():
                raise ValueError("a BVH pointer leaves the image")
            box = np.isin(typ, [BOX_TYPE, Q8_TYPE])
            inst = typ == INSTANCE_TYPE
            blas.append(words[NodeRef.word(frontier[inst]) + node_word(INSTANCE_NODE, "blas")])
            child = words[(NodeRef.word(frontier[box]) + child_word[typ[box]])[:, None]
                          + np.arange(4)].reshape(-1)
            frontier = child[child != NO_CHILD]
        roots = np.unique(np.concatenate(blas))
        if len(roots):
            levels.append((roots, readable))


class RtUnitBackend(HarnessBackend):
    """The RT unit in RTL (see the module docstring). Options beyond the "rtl" backend's:
    ``rays_in_flight`` (RAYS, ray slots), ``stack_depth`` (STACK_DEPTH), ``mem_latency`` (the
    fixed-latency memory's cycles; used when ``memory`` is None), ``memory`` (a
    ``MEMORY_CONFIG`` dict, ``driver.rtunit.MemoryModel.config()``: the replay's hierarchy behind
    the port), ``max_outstanding`` (fetches the fixed-latency memory holds, 0: no limit),
    ``dividers`` (DIVIDERS: binary32 dividers for the triangle hits' t), ``setups`` (SETUPS:
    ray setups for the rays entering instances), ``pipelines`` (PIPELINES: datapaths, each with
    its response stage), ``cull`` (CULL: the distance-culled stack, ``--cull-stack``),
    ``activity`` (the traced build: every batch's switching activity per
    module, ``UnitResult.activity``; for ``rayflex power``), ``compare`` (``trace``
    also runs the Python traversal on this backend's datapath, checks every ray of the unit
    against it and replays its requests for the replay's cycles: ``driver.tracer``)."""

    name = UNIT_BACKEND

    def __init__(self, rays_in_flight: int = 64, stack_depth: int = DEFAULT_STACK_DEPTH,
                 mem_latency: int = DEFAULT_MEM_LATENCY, memory: dict | None = None,
                 max_outstanding: int = 0, dividers: int = DEFAULT_DIVIDERS,
                 setups: int = DEFAULT_SETUPS, pipelines: int = 1, compare: bool = True,
                 activity: bool = False, cull: bool = False,
                 **options):
        # what the RTL cannot be built with is refused before the datapath's harness is built
        unit_params({}, rays_in_flight, stack_depth, dividers, setups, pipelines)
        if not isinstance(mem_latency, int) or mem_latency < 1:
            raise BackendError(f"memory latency {mem_latency!r}: give a whole number of cycles "
                               ">= 1")
        super().__init__(**options)
        self.unit_params = unit_params(self.params, rays_in_flight, stack_depth, dividers,
                                       setups, pipelines, bool(cull))
        self.cull = bool(cull)
        self.pipelines = int(pipelines)
        self.dividers = int(dividers)
        self.setups = int(setups)
        self.compare = bool(compare)
        self.rays_in_flight = int(rays_in_flight)
        self.stack_depth = int(stack_depth)
        self.mem_latency = int(mem_latency)
        self.memory = memory
        self.max_outstanding = int(max_outstanding)
        self.activity = bool(activity)
        self._checked = None        # the last image check_image passed: (image, root)
        self._image_digest = None   # its bytes' digest, once a memo needs it (unit_memo)
        self._nets = None                               # (codes, rows, weight) once read
        self.net_names: list[list[str]] = []            # the traced nets' names, once read
        self._unit = unit_library(self.unit_params, self.activity)   # build now: fail early

    def _count(self, h) -> dict:
        """The bit toggles counted since ``rtu_toggles_start`` per row of ``UNIT_ROWS`` (each
        net's toggles times its weight, ``net_rows``) and the nets counted."""
        with tempfile.TemporaryDirectory(prefix="rayflex-unit-") as tmp:
            decl, cnt = Path(tmp) / "decl.vcd", Path(tmp) / "counts.txt"
            if self._unit.rtu_toggles_write(h, str(decl).encode(), str(cnt).encode()) < 0:
                raise OSError(f"cannot write the RT unit's toggle counts in {tmp}")
            if self._nets is None:
                with open(decl) as f:
                    codes, names = toggles.declarations(f)
                self._nets = (codes, *net_rows(names))
                self.net_names = names
            codes, rows, weight = self._nets
            per_net = toggles.read_counts(cnt, codes) * weight
        by_row = np.bincount(rows, weights=per_net, minlength=len(UNIT_ROWS))
        return {"toggles": {r: float(v) for r, v in zip(UNIT_ROWS, by_row)},
                "nets": len(codes)}

    def idle_activity(self, cycles: int) -> dict:
        """The switching activity of the unit (traced: ``activity``) clocked ``cycles`` cycles
        after reset with no ray: ``_count``'s dict and ``cycles``."""
        if not self.activity:
            raise ValueError("idle_activity needs the traced unit (activity=True)")
        none = np.zeros(0, np.uint32)
        h = self._new(np.zeros((0, RAY_WORDS), np.uint32), np.zeros(0, np.uint8),
                      np.zeros(1, np.uint8), 0, none, none, none, np.zeros(0, np.uint8),
                      np.zeros((0, UNIT_OPS), np.int64))
        try:
            self._unit.rtu_toggles_start(h)
            self._unit.rtu_idle(h, int(cycles))
            return {**self._count(h), "cycles": int(cycles)}
        finally:
            self._unit.rtu_free(h)

    def _new(self, rw, ah, img, root, prim, inst, t, hit, ops):
        """A harness run (``rtu_new``) over these arrays (which must outlive it)."""
        err = ctypes.c_int64(0)
        mc = memory_config(self.memory)
        u32 = ctypes.POINTER(ctypes.c_uint32)
        u8 = ctypes.POINTER(ctypes.c_uint8)
        i64 = ctypes.POINTER(ctypes.c_int64)
        h = self._unit.rtu_new(rw.ctypes.data_as(u32), ah.ctypes.data_as(u8), len(rw),
                               img.ctypes.data_as(u32), img.size, int(root), self.mem_latency,
                               self.max_outstanding, self.dividers, ctypes.byref(mc),
                               prim.ctypes.data_as(u32), inst.ctypes.data_as(u32),
                               t.ctypes.data_as(u32), hit.ctypes.data_as(u8),
                               ops.ctypes.data_as(i64), ctypes.byref(err))
        if not h:
            raise ValueError("memory geometry cannot be modelled" if err.value == _BAD_GEOMETRY
                             else "RT unit: inconsistent arguments")
        return h

    def trace_unit(self, bvh, rays: np.ndarray, any_hit=False, progress=None,
                   max_cycles: int | None = None) -> UnitResult:
        """Run prepared rays (``driver.core.datapath.prepare_rays``) through the unit over
        ``bvh`` (checked by ``check_image``, once for the batches of a frame: again when the
        image object or the root changes). ``any_hit``: a bool or one per ray.
        ``progress(done, total)`` is called between harness calls. ``max_cycles``: the budget
        (default: ``BUDGET_BASE`` + ``BUDGET_PER_RAY`` per ray + ``BUDGET_PER_REQUEST`` per
        datapath request made); RuntimeError when it runs out; ValueError when the rays make
        more requests than the image has nodes for (``request_bound``: a loop). Within
        ``unit_memo.memo`` a batch traced before is reused (``UnitResult.reused``)."""
        if self._checked is None or self._checked[0] is not bvh.image or \
                self._checked[1] != int(bvh.root):
            check_image(bvh, self.compressed, self.transform)
            self._checked = (bvh.image, int(bvh.root))
            self._image_digest = None
        n = len(rays)
        rw = np.ascontiguousarray(ray_words(rays), np.uint32)
        assert rw.shape == (n, RAY_WORDS)
        ah = np.ascontiguousarray(np.broadcast_to(np.asarray(any_hit, bool), (n,)), np.uint8)
        name = (self._memo_name(bvh, rw, ah) if unit_memo.directory() is not None
                and not self.activity and max_cycles is None else None)
        found = unit_memo.load(name) if name is not None else None
        activity = None
        if found is not None:
            arrays, stats = found
        else:
            arrays, stats, activity = self._simulate(bvh, rw, ah, progress, max_cycles)
            if name is not None:
                unit_memo.store(name, arrays, stats)
        self.cycles += stats["cycles"]
        self.requests += stats["dp_requests"]
        return UnitResult(**arrays, stats=stats, activity=activity, reused=found is not None)

    def _memo_name(self, bvh, rw: np.ndarray, ah: np.ndarray) -> str:
        """The batch's name in ``unit_memo``: its rays, flags, image and root, the unit's library
        (its RTL, harness and parameters) and the memory behind its port."""
        if self._image_digest is None:
            self._image_digest = unit_memo.key([], [np.asarray(bvh.image)])
        return unit_memo.key([self._unit._name, self._image_digest, int(bvh.root),
                              self.mem_latency, self.max_outstanding, self.memory], [rw, ah])

    def _simulate(self, bvh, rw: np.ndarray, ah: np.ndarray, progress, max_cycles):
        """``trace_unit``'s simulation: ``({UnitResult array: ndarray}, stats, activity)``."""
        n = len(rw)
        img = np.ascontiguousarray(np.asarray(bvh.image).reshape(-1).view(np.uint8))
        prim = np.full(n, NO_CHILD, np.uint32)
        inst = np.full(n, NO_CHILD, np.uint32)
        t = np.zeros(n, np.uint32)
        hit = np.zeros(n, np.uint8)
        ops = np.zeros((n, UNIT_OPS), np.int64)
        lib = self._unit
        h = self._new(rw, ah, img, bvh.root, prim, inst, t, hit, ops)
        if self.activity:
            lib.rtu_toggles_start(h)
        activity = None
        try:
            st = self._advance(h, bvh, n, ops, progress, max_cycles)
            if self.activity:
                activity = {**self._count(h), "cycles": int(st.cycles_simulated)}
        finally:
            lib.rtu_free(h)
        stats = {name: ([int(v) for v in getattr(st, name)][:self.pipelines]
                        if name in UNIT_STAT_ARRAYS else int(getattr(st, name)))
                 for name in UNIT_STATS}
        prim64 = prim.astype(np.int64)
        prim64[prim == NO_CHILD] = -1
        inst64 = inst.astype(np.int64)
        inst64[inst == NO_CHILD] = -1
        arrays = dict(prim=prim64, t=t.view(np.float32), hit=hit.astype(bool),
                      box_ops=ops[:, 0].copy(), tri_ops=ops[:, 1].copy(),
                      overflows=ops[:, 2].copy(), refills=ops[:, 3].copy(), instance=inst64,
                      xf_ops=ops[:, 4].copy(), culled=ops[:, 5].copy())
        return arrays, stats, activity

    def _advance(self, h, bvh, n: int, ops: np.ndarray, progress, max_cycles) -> RtuStats:
        """Clock the harness run ``h`` until every ray's result is in; its final statistics."""
        lib = self._unit
        budget = BUDGET_BASE + BUDGET_PER_RAY * n if max_cycles is None else int(max_cycles)
        most = request_bound(bvh, n)
        st = RtuStats()
        bad = ctypes.c_int64(-1)
        ran, grown = 0, budget
        while True:
            step = min(ADVANCE_CYCLES, max(1, grown - ran))
            rc = lib.rtu_advance(h, step, ctypes.byref(bad))
            lib.rtu_stats(h, ctypes.byref(st))
            ran = st.cycles_simulated
            if progress is not None:
                progress(int(np.count_nonzero(ops[:, 0] + ops[:, 1])), n)
            if rc == 1:
                return st
            if rc == _BAD_ADDRESS:
                raise ValueError("a BVH pointer leaves the image (the unit fetched past it)")
            if rc == _RAY_ERROR:
                raise ValueError(f"ray {bad.value} met a node pointer the RT unit cannot "
                                 "read (a corrupt image)")
            if rc < 0:
                raise RuntimeError(f"RT unit harness failed ({rc})")
            if st.dp_requests > most:
                raise ValueError(f"the RT unit made {st.dp_requests:,} requests for {n} rays, "
                                 f"more than this image has nodes for ({most:,}): its "
                                 "pointers loop")
            if max_cycles is None:
                grown = budget + BUDGET_PER_REQUEST * st.dp_requests
            if ran >= grown:
                raise RuntimeError(f"the RT unit did not finish {n} rays within its budget "
                                   f"of {grown:,} cycles (a corrupt image?)")


def request_bound(bvh, rays: int) -> int:
    """The most datapath requests ``rays`` rays can make over ``bvh`` without a loop: each node
    (64 bytes or more) once per ray, once more per instance (a ray enters each at most once)."""
    nodes = np.asarray(bvh.image).nbytes // 64 + 1
    instances = getattr(bvh, "instances", None)
    return rays * nodes * (1 + (len(instances) if instances is not None else 0))


def lint_unit(params: dict | None = None) -> str:
    """``verilator --lint-only -Wall`` of the RT unit (datapath included) with both waiver
    files."""
    return verilate.lint(UNIT_TOP, [RTL_DIR / "lint.vlt", RTL_DIR / UNIT_LINT_WAIVERS,
                                    *unit_sources()], params or {})
