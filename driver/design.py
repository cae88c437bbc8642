"""A design point: the datapath, BVH, RT-unit and workload choices of one measurement.

Every option of a design point is defined once here (``OPTIONS``: flag, type, default, help,
check, and whether ``rayflex sweep`` takes a list of values for it). ``render``, ``bench``,
``power`` and ``sweep`` add them with ``add_options`` and read them back with ``from_args``
(one ``DesignPoint``) or ``grid_from_args`` (``sweep``: every combination of the listed values),
so that a name, its default and its meaning are the same in every command. A ``DesignPoint`` is
what the code passes around: ``backend_options()`` for ``driver.backends.backend``,
``memory()`` for the RT-unit replay, ``as_dict()`` for a JSON's provenance.

The groups (docs/datapath.md for the datapath, docs/workloads.md for the workloads,
docs/statistics.md for what is measured):

- datapath: ``--config`` (a configuration of driver/area.py's table: EXTENDED x DISJOINT),
  ``--latency`` (pipeline stages), ``--transform`` (an instanced scene's ray transform in the
  driver, or on the datapath: build parameter TRANSFORM), ``--clock-mhz`` (the clock that turns
  cycles into time: ``DesignPoint.clock`` and ``clock_figures``);
- bvh: ``--bvh-fill``, ``--cull-stack``;
- rtunit (docs/rtunit.md): ``--rt-preset`` (a whole RT-unit configuration; options given with
  it override its fields), the frame schedule ``--frame``, ``--shader-cycles``,
  ``--flush-between``, warps ``--warp-size``, ``--warps-per-unit``, ``--rt-units``, each unit's
  ``--rays-in-flight``, ``--pipelines``, the RT unit in RTL's ``--stack-depth`` and
  ``--unit-check`` (``--backend rtunit``, docs/rtunit_rtl.md), node cache ``--cache-kib`` (0: none), ``--cache-ways``,
  ``--cache-latency``, ``--mshrs``, the shared ``--l2-kib``, ``--l2-ways``, ``--l2-latency``,
  ``--line-bytes``, ``--sector-bytes``, DRAM ``--mem-latency``, ``--mem-bytes-per-cycle``, and
  the ray order ``--ray-order``, ``--ray-window``;
- workload: ``--scene`` (``render``: also the positional SCENE), ``--workload``, ``--size``,
  ``--spp``, ``--bounces``, ``--ao-rays``, ``--seed``.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, fields, replace
from typing import Callable

from . import timing
from .core.configs import (ALL_CONFIGS, DESIGN_CONFIGS, FUSED_SUFFIX, Q8_SUFFIX, SHARED_SUFFIX,
                           config_name, parse_config)
from .backends.build import MIN_LATENCY, rtl_params
from .backends.rtunit import (DEFAULT_STACK_DEPTH, MAX_STACK_DEPTH, MAX_UNIT_PIPELINES,
                              MIN_STACK_DEPTH, UNIT_BACKEND, UNIT_CHECKS, UNIT_OPTIONS,
                              check_format, unit_params)
from .bvh4 import build_scene
from .core.datapath import LATENCY, MAX_LATENCY, default_latency, least_latency
from .instances import DATAPATH, TRANSFORMS
from .core.layout import DEFAULT_FORMAT, IMAGE_FORMATS
from .rtunit import MemoryModel
from .rtunit.order import DEFAULT_POLICY, DEFAULT_WINDOW, POLICIES
from .rtunit.gpu import DEFAULT_REPLAY_DATAPATH, DEFAULT_UNIT_COSTS, REPLAY_DATAPATHS, UNIT_COSTS
from .rtunit.plan import FRAMES, MAX_RT_UNITS, MAX_WARP_SIZE, Schedule
from .rtunit.presets import DEFAULT_PRESET, PRESETS
from .scenes.camera import MAX_SIZE
from .scenes.lumibench import PREFIX as LUMIBENCH_PREFIX
from .workloads import WORKLOADS

GROUPS = {
    "datapath": "datapath (docs/datapath.md)",
    "bvh": "BVH and traversal (docs/bvh.md)",
    "rtunit": "RT units in a GPU: frame schedule, warps, ray pool, pipelines, memory hierarchy "
              "(docs/rtunit.md)",
    "workload": "workload (docs/workloads.md)",
}
MAX_PIPELINES = 64
MAX_CLOCK_MHZ = 100_000.0
# the clock when neither --clock-mhz nor the timing cache gives one: the paper's 1 GHz
DEFAULT_CLOCK_MHZ = 1000.0
DEFAULT_SCENE = "bunny"


def _resolve_scene(name) -> None:
    """An unknown scene or a missing file fails here, before any work (one-line SceneError)."""
    from .scenes.scene import resolve
    if isinstance(name, str):
        resolve(name)


def _scene_help() -> str:
    """The scene option's help, listing the scenes and mesh types that exist."""
    from .scenes.scene import MESH_TYPES, available
    return (f"a scene name ({', '.join(available())}; a bare name is the scene even if a file "
            "of that name exists here: write ./NAME for the file), a .toml scene file or a mesh "
            f"file ({', '.join('.' + t for t in MESH_TYPES)}); docs/scenes.md")


def _int_range(lo: int, hi: int | None = None) -> Callable:
    def check(flag, v):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
            rng = f"in {lo}..{hi}" if hi is not None else f">= {lo}"
            raise ValueError(f"{flag} must be an integer {rng}, got {v!r}")
    return check


def _latency(flag, v):
    if v is not None:
        _int_range(MIN_LATENCY, MAX_LATENCY)(flag, v)


def _positive_float(flag, v):
    if not v > 0:
        raise ValueError(f"{flag} must be > 0, got {v!r}")


def _power_of_two(flag, v):
    if isinstance(v, bool) or not isinstance(v, int) or v < 4 or v & (v - 1):
        raise ValueError(f"{flag} must be a power of two >= 4, got {v!r}")


def _warp_size(flag, v):
    if isinstance(v, bool) or not isinstance(v, int) or v < 1 or v > MAX_WARP_SIZE or v & (v - 1):
        raise ValueError(f"{flag} must be a power of two in 1..{MAX_WARP_SIZE}, got {v!r}")


def _sector(flag, v):
    if v != 0:
        _power_of_two(flag, v)


def _clock(flag, v):
    if v is not None and not (isinstance(v, (int, float)) and 0 < v <= MAX_CLOCK_MHZ):
        raise ValueError(f"{flag} must be a clock in MHz in (0, {MAX_CLOCK_MHZ:g}], got {v!r}")


def _choice(choices) -> Callable:
    def check(flag, v):
        if v not in choices:
            raise ValueError(f"{flag}: unknown value {v!r}; choose from {', '.join(choices)}")
    return check


def _size(flag, v):
    if v is not None:
        _int_range(1, MAX_SIZE)(flag, v)


def _bool(text: str) -> bool:
    t = str(text).strip().lower()
    if t in ("1", "yes", "on", "true"):
        return True
    if t in ("0", "no", "off", "false"):
        return False
    raise ValueError(f"not a yes/no value: {text!r}")


@dataclass(frozen=True)
class Option:
    """One design-point option: ``name`` (the DesignPoint field and argparse dest), ``flag``,
    ``type`` (parses one value from text), ``default``, ``help``, ``check(flag, value)``
    (one-line ValueError), ``group``, and ``listable``: ``rayflex sweep`` takes a comma-separated
    list of values (and ``all`` when ``choices`` name them)."""

    name: str
    flag: str
    type: Callable
    default: object
    help: str
    check: Callable
    group: str
    metavar: str = "N"
    choices: tuple | None = None
    listable: bool = True

    def describe_default(self) -> str:
        if self.name == "latency":
            return (f"the paper's {LATENCY}, {default_latency(True)} with the q8 decode; "
                    f"{least_latency()} puts S9 beside the output format, docs/timing.md")
        if self.name == "size":
            return "the scene's size, 256 for the built-in scenes"
        if self.name == "clock_mhz":
            return ("the configuration's Fmax where rayflex timing has timed it (its cache, "
                    f"docs/timing.md), else {DEFAULT_CLOCK_MHZ:g}")
        if self.type is _bool:
            return "no"
        return str(self.default)


OPTIONS: tuple[Option, ...] = (
    Option("config", "--config", str, "baseline-unified",
           "datapath configuration: " + ", ".join(ALL_CONFIGS) + " (EXTENDED x DISJOINT build "
           f"parameters; {Q8_SUFFIX}: with the q8 node decode in the datapath, build parameter "
           "COMPRESSED, docs/compressed.md; every one gives the same box/triangle results, bit "
           f"for bit; an extended one also as NAME{SHARED_SUFFIX}: its vectors on the request "
           "registers' box and triangle bits, build parameter SHARED, the same results), each "
           f"also as NAME{FUSED_SUFFIX}: the box slab values and the triangle's edge functions "
           "rounded once, build parameter FUSED (other results); docs/tradeoffs.md",
           _choice(tuple(DESIGN_CONFIGS)), "datapath", "NAME", tuple(DESIGN_CONFIGS)),
    Option("latency", "--latency", int, None,
           f"pipeline stages of the datapath, {MIN_LATENCY} to {MAX_LATENCY} (one more with "
           "the q8 decode)", _latency, "datapath"),
    Option("transform", "--transform", str, "driver",
           "where an instanced scene's ray transform runs: "
           + "; ".join(f"{k}: {v}" for k, v in TRANSFORMS.items())
           + "; the same hits, bit for bit (docs/instances.md)", _choice(tuple(TRANSFORMS)),
           "datapath", "WHERE", tuple(TRANSFORMS)),
    Option("clock_mhz", "--clock-mhz", float, None,
           "the datapath's clock in MHz, for the frame's time, rays per second and power in "
           "real units", _clock, "datapath", "MHZ", listable=False),
    Option("bvh_fill", "--bvh-fill", int, 0,
           "split subtrees of at most N triangles so that their 4-wide nodes can all be full: "
           "fewer box nodes and bytes, slightly more ops per ray (0: plain SAH; docs/bvh.md)",
           _int_range(0), "bvh"),
    Option("flatten", "--flatten", _bool, False,
           "trace an instanced scene (glTF mesh reuse, bunny_grid) as one mesh: its flattened "
           "world-space triangles in one BVH instead of a two-level BVH of instances "
           "(docs/instances.md)", lambda flag, v: None, "bvh"),
    Option("cull_stack", "--cull-stack", _bool, False,
           "keep each stack entry's entry distance and drop box nodes beyond the nearest hit "
           "without a request: the same hits, fewer box ops (the RT unit keeps a float per "
           "stack entry; docs/bvh.md)", lambda flag, v: None, "bvh", "yes|no"),
    Option("bvh_format", "--bvh-format", str, DEFAULT_FORMAT,
           "node image: box32 (128-byte float32 box nodes, a 64-byte node per triangle), q8 "
           "(64-byte quantized box nodes, 64-byte triangle-pair leaves) or q8g (q8 with 128-byte "
           "leaves of 3 to 6 triangles sharing vertices where they cost few ops) "
           "(docs/compressed.md)", _choice(IMAGE_FORMATS), "bvh", "FORMAT",
           IMAGE_FORMATS),
    Option("rt_preset", "--rt-preset", str, DEFAULT_PRESET,
           "a whole RT-unit configuration at once (" + "; ".join(
               f"{k}: {v.help}" for k, v in PRESETS.items()) + "); every RT-unit option given "
           "with it overrides its value (docs/rtunit.md)", _choice(tuple(PRESETS)), "rtunit",
           "NAME", tuple(PRESETS)),
    Option("frame_schedule", "--frame", str, "one-kernel",
           "frame schedule: one-kernel (every thread's rays in program order in one kernel, as "
           "a DXR/Vulkan dispatch) or wavefront (one ray type at a time, a barrier between)",
           _choice(FRAMES), "rtunit", "SCHEDULE", FRAMES),
    Option("shader_cycles", "--shader-cycles", int, 0,
           "cycles of shader work between a trace call's last response and the warp's next "
           "trace call", _int_range(0), "rtunit"),
    Option("flush_between", "--flush-between", _bool, False,
           "wavefront frames: drop every cache at each barrier (the replay before one-kernel "
           "frames did)", lambda flag, v: None, "rtunit", "yes|no"),
    Option("warp_size", "--warp-size", int, 1,
           f"threads per warp, a power of two up to {MAX_WARP_SIZE} (1: every ray issued on "
           "its own); warps are screen tiles (8 x 4 pixels for 32)", _warp_size, "rtunit"),
    Option("warps_per_unit", "--warps-per-unit", int, 0,
           "warps resident per RT unit (0: twice the warps its ray pool holds)", _int_range(0),
           "rtunit", "W"),
    Option("rt_units", "--rt-units", int, 1,
           f"RT units (one per SM), 1..{MAX_RT_UNITS}: warps assigned round robin over screen "
           "tiles, all units in front of the shared L2 and DRAM", _int_range(1, MAX_RT_UNITS),
           "rtunit"),
    Option("rays_in_flight", "--rays-in-flight", int, 64,
           "ray pool of each RT unit: rays with a request chain in progress (whole warps: a "
           "multiple of --warp-size)", _int_range(1), "rtunit"),
    Option("stack_depth", "--stack-depth", int, DEFAULT_STACK_DEPTH,
           f"traversal stack entries per ray of the RT unit in RTL (--backend rtunit), "
           f"{MIN_STACK_DEPTH}..{MAX_STACK_DEPTH}: a push onto a full stack spills its oldest "
           "entry to memory, read back when the stack empties (the same hits and ops, more "
           "cycles; docs/rtunit_rtl.md)", _int_range(MIN_STACK_DEPTH, MAX_STACK_DEPTH), "rtunit"),
    Option("unit_check", "--unit-check", str, UNIT_CHECKS[0],
           "what checks every ray of the RT unit in RTL (--backend rtunit) besides "
           "--check-embree: traversal (the Python traversal on the unit's datapath, each ray "
           "compared, and the RT-unit replay of its requests: unit_rtl's "
           "traversal_mismatches and replay ratios) or none (the unit alone, faster; those "
           "figures null)", _choice(UNIT_CHECKS), "rtunit", "CHECK", UNIT_CHECKS,
           listable=False),
    Option("pipelines", "--pipelines", int, 1,
           f"datapath pipelines of the RT unit, 1..{MAX_PIPELINES} (the RT unit in RTL, "
           f"--backend rtunit: 1..{MAX_UNIT_PIPELINES}, each with its response stage)",
           _int_range(1, MAX_PIPELINES), "rtunit"),
    Option("cache_kib", "--cache-kib", int, 32,
           "node cache (L1) of each RT unit in KiB, set-associative LRU (0: none, every node "
           "fetch goes to the L2 or DRAM)", _int_range(0), "rtunit"),
    Option("cache_ways", "--cache-ways", int, 4, "ways of the node cache", _int_range(1),
           "rtunit"),
    Option("cache_latency", "--cache-latency", int, 0,
           "cycles from a node cache hit to the node being present", _int_range(0), "rtunit"),
    Option("mshrs", "--mshrs", int, 0,
           "miss registers per RT unit (0: unlimited); misses to a line or sector already in "
           "flight merge, a full file holds further misses", _int_range(0), "rtunit"),
    Option("l2_kib", "--l2-kib", int, 0,
           "L2 in KiB shared by all RT units, set-associative LRU (0: no L2)", _int_range(0),
           "rtunit"),
    Option("l2_ways", "--l2-ways", int, 16, "ways of the L2", _int_range(1), "rtunit"),
    Option("l2_latency", "--l2-latency", int, 0,
           "cycles an L1 miss takes to the L2 and back on an L2 hit", _int_range(0), "rtunit"),
    Option("line_bytes", "--line-bytes", int, 64, "cache line size in bytes (L1 and L2)",
           _power_of_two, "rtunit"),
    Option("sector_bytes", "--sector-bytes", int, 0,
           "bytes per memory transaction: sectors of a line (a power of two >= 4 dividing "
           "the line), or 0: whole lines", _sector, "rtunit"),
    Option("mem_latency", "--mem-latency", int, 200,
           "cycles from a transaction's DRAM transfer to its arrival", _int_range(0),
           "rtunit"),
    Option("mem_bytes_per_cycle", "--mem-bytes-per-cycle", float, 32.0,
           "DRAM bandwidth shared by all RT units: bytes transferred per cycle (transfers are "
           "serialised)", _positive_float, "rtunit", "B"),
    Option("ray_order", "--ray-order", str, DEFAULT_POLICY,
           "order in which rays enter the RT unit's ray pool: "
           + "; ".join(f"{k}: {v.help}" for k, v in POLICIES.items()) + " (docs/rayorder.md)",
           _choice(tuple(POLICIES)), "rtunit", "POLICY", tuple(POLICIES)),
    Option("ray_window", "--ray-window", int, DEFAULT_WINDOW,
           "rays a sorting policy sorts together, or the affinity scheduler holds (at least "
           "--rays-in-flight); index order has no window", _int_range(1), "rtunit", "W"),
    Option("replay_datapath", "--replay-datapath", str, DEFAULT_REPLAY_DATAPATH,
           "how the RT-unit replay runs the datapath pipelines: timing (each pipeline as the "
           "handshake timing of its RTL model: a request per cycle, its response the model's "
           "latency later, the responses the functional pass's) or rtl (every request "
           "evaluated again on the Verilated model and its response compared with the "
           "functional pass's, bit for bit: slower); counts and cycles are the same "
           "(docs/rtunit.md)", _choice(REPLAY_DATAPATHS), "rtunit", "HOW", REPLAY_DATAPATHS,
           listable=False),
    Option("unit_costs", "--unit-costs", str, DEFAULT_UNIT_COSTS,
           "what the RT-unit replay charges per request: replay (one turnaround cycle from a "
           "response to the ray's next request, no divider) or rtl (the RT unit in RTL's ray, "
           "pop, memory and result ports, fetch register, scheduler cycle, response stage and "
           f"dividers, the cycles --backend rtunit counts; 1..{MAX_UNIT_PIPELINES} pipelines, "
           "index ray order; "
           "docs/rtunit_rtl.md)", _choice(UNIT_COSTS), "rtunit",
           "COSTS", UNIT_COSTS),
    Option("scene", "--scene", str, DEFAULT_SCENE, _scene_help(),
           lambda flag, v: _resolve_scene(v), "workload", "SCENE", listable=False),
    Option("workload", "--workload", str, "primary",
           "rays of the frame: primary (camera rays), shadow (+ one shadow ray per hit), ao "
           "(+ --ao-rays ambient-occlusion rays per hit), path (diffuse path tracing with "
           "next-event estimation and --bounces bounces); lumibench-pt, lumibench-sh, "
           "lumibench-ao: LumiBench's path tracing (16 bounces), shadow (2 rays per hit) and "
           "AO (--ao-rays per hit) shaders (docs/lumibench.md)", _choice(WORKLOADS), "workload",
           "NAME", WORKLOADS, listable=False),
    Option("size", "--size", int, None, "square frame N x N", _size, "workload"),
    Option("spp", "--spp", int, 1, "samples per pixel, 1..4096", _int_range(1, 4096),
           "workload"),
    Option("bounces", "--bounces", int, 1,
           "path: diffuse bounces after the camera ray, 0..64 (0: direct light)",
           _int_range(0, 64), "workload"),
    Option("ao_rays", "--ao-rays", int, 4, "ao: rays per hit, 1..1024", _int_range(1, 1024),
           "workload"),
    Option("seed", "--seed", int, 0, "seed of the counter-based random numbers",
           _int_range(0), "workload"),
)
BY_NAME = {o.name: o for o in OPTIONS}
assert set(UNIT_OPTIONS) <= set(BY_NAME)


def unit_flags(args, backend: str) -> None:
    """Refuse (ValueError, one line) ``--stack-depth`` or ``--unit-check`` without ``--backend
    rtunit``, and an
    RT-unit option the RT unit in RTL does not model with it."""
    if backend == UNIT_BACKEND:
        other = [o.flag for o in OPTIONS if o.group == "rtunit" and o.name not in UNIT_OPTIONS
                 and getattr(args, o.name, None) is not None]
        if other:
            raise ValueError(f"{other[0]} is a setting of the RT-unit replay, which --backend "
                             f"{UNIT_BACKEND} does not run (docs/rtunit_rtl.md)")
    else:
        for name in ("stack_depth", "unit_check"):
            if getattr(args, name, None) is not None:
                raise ValueError(f"{BY_NAME[name].flag} sets the RT unit in RTL: give --backend "
                                 f"{UNIT_BACKEND}")


def check_unit_reads(backend: str, point, scene=None) -> None:
    """What the RT unit in RTL cannot read, refused in one line (``check_format``): without
    ``scene``, a LumiBench scene (instanced, every one) before it is loaded; with it, the loaded
    scene's instances and the node format, before the BVH build."""
    if backend != UNIT_BACKEND:
        return
    if scene is None and not str(point.scene).startswith(LUMIBENCH_PREFIX):
        return
    instanced = scene is None or getattr(scene, "instances", None) is not None
    check_format(point.bvh_format, point.compressed, point.transform_op,
                 instanced and not point.flatten)


@dataclass(frozen=True)
class DesignPoint:
    """One design point (the fields are ``OPTIONS``' names, with their defaults)."""

    config: str = BY_NAME["config"].default
    latency: int = BY_NAME["latency"].default
    transform: str = BY_NAME["transform"].default
    clock_mhz: float | None = BY_NAME["clock_mhz"].default
    bvh_fill: int = BY_NAME["bvh_fill"].default
    flatten: bool = BY_NAME["flatten"].default
    cull_stack: bool = BY_NAME["cull_stack"].default
    bvh_format: str = BY_NAME["bvh_format"].default
    rt_preset: str = BY_NAME["rt_preset"].default
    frame_schedule: str = BY_NAME["frame_schedule"].default
    shader_cycles: int = BY_NAME["shader_cycles"].default
    flush_between: bool = BY_NAME["flush_between"].default
    warp_size: int = BY_NAME["warp_size"].default
    warps_per_unit: int = BY_NAME["warps_per_unit"].default
    rt_units: int = BY_NAME["rt_units"].default
    rays_in_flight: int = BY_NAME["rays_in_flight"].default
    stack_depth: int = BY_NAME["stack_depth"].default
    unit_check: str = BY_NAME["unit_check"].default
    pipelines: int = BY_NAME["pipelines"].default
    cache_kib: int = BY_NAME["cache_kib"].default
    cache_ways: int = BY_NAME["cache_ways"].default
    cache_latency: int = BY_NAME["cache_latency"].default
    mshrs: int = BY_NAME["mshrs"].default
    l2_kib: int = BY_NAME["l2_kib"].default
    l2_ways: int = BY_NAME["l2_ways"].default
    l2_latency: int = BY_NAME["l2_latency"].default
    line_bytes: int = BY_NAME["line_bytes"].default
    sector_bytes: int = BY_NAME["sector_bytes"].default
    mem_latency: int = BY_NAME["mem_latency"].default
    mem_bytes_per_cycle: float = BY_NAME["mem_bytes_per_cycle"].default
    ray_order: str = BY_NAME["ray_order"].default
    ray_window: int = BY_NAME["ray_window"].default
    replay_datapath: str = BY_NAME["replay_datapath"].default
    unit_costs: str = BY_NAME["unit_costs"].default
    scene: str = BY_NAME["scene"].default
    workload: str = BY_NAME["workload"].default
    size: int | None = BY_NAME["size"].default
    spp: int = BY_NAME["spp"].default
    bounces: int = BY_NAME["bounces"].default
    ao_rays: int = BY_NAME["ao_rays"].default
    seed: int = BY_NAME["seed"].default

    def __post_init__(self):
        for o in OPTIONS:
            o.check(o.flag, getattr(self, o.name))
        least = least_latency(self.compressed)
        if self.latency is None:                            # the configuration's own
            object.__setattr__(self, "latency", default_latency(self.compressed))
        elif self.latency < least:
            raise ValueError(f"--latency must be at least {least} for --config {self.config}, "
                             f"got {self.latency}")
        if POLICIES[self.ray_order].schedule and self.ray_window < self.rays_in_flight:
            raise ValueError(f"--ray-order {self.ray_order}: --ray-window ({self.ray_window}) "
                             f"must be at least --rays-in-flight ({self.rays_in_flight})")
        if self.flatten and self.transform_op:
            raise ValueError(f"--transform {DATAPATH} with --flatten: a flattened scene is one "
                             "mesh, with no instance transform to run")
        if self.cache_kib and (self.cache_kib * 1024) % (self.cache_ways * self.line_bytes):
            raise ValueError(f"--cache-kib {self.cache_kib} is not a whole number of sets of "
                             f"--cache-ways {self.cache_ways} x --line-bytes {self.line_bytes}")
        if self.l2_kib and (self.l2_kib * 1024) % (self.l2_ways * self.line_bytes):
            raise ValueError(f"--l2-kib {self.l2_kib} is not a whole number of sets of "
                             f"--l2-ways {self.l2_ways} x --line-bytes {self.line_bytes}")
        if self.sector_bytes > self.line_bytes:
            raise ValueError(f"--sector-bytes {self.sector_bytes} is larger than --line-bytes "
                             f"{self.line_bytes}")
        if self.rays_in_flight % self.warp_size:
            raise ValueError(f"--rays-in-flight {self.rays_in_flight} must be a multiple of "
                             f"--warp-size {self.warp_size}: the RT unit holds whole warps")
        if POLICIES[self.ray_order].schedule and self.ray_window % self.warp_size:
            raise ValueError(f"--ray-window {self.ray_window} must be a multiple of "
                             f"--warp-size {self.warp_size}")
        if self.unit_costs == "rtl" and (self.pipelines > MAX_UNIT_PIPELINES
                                         or self.ray_order != DEFAULT_POLICY):
            raise ValueError("--unit-costs rtl charges the RT unit in RTL's costs: it has "
                             f"1..{MAX_UNIT_PIPELINES} pipelines and takes rays in index order "
                             f"(give --pipelines 1..{MAX_UNIT_PIPELINES} --ray-order index)")
        if POLICIES[self.ray_order].key is not None and self.frame_schedule == "one-kernel":
            raise ValueError(f"--ray-order {self.ray_order} sorts a wavefront's ray queue: use "
                             "it with --frame wavefront (in a one-kernel frame threads issue "
                             "their rays; affinity and treelet scheduling work there)")

    # what the parts of the driver take
    @property
    def extended(self) -> bool:
        return bool(parse_config(self.config)["EXTENDED"])

    @property
    def disjoint(self) -> bool:
        return bool(parse_config(self.config)["DISJOINT"])

    @property
    def compressed(self) -> bool:
        """The q8 node decode is in the datapath (build parameter COMPRESSED)."""
        return bool(parse_config(self.config).get("COMPRESSED"))

    @property
    def shared(self) -> bool:
        """The vectors travel on the request registers' box and triangle bits (build parameter
        SHARED)."""
        return bool(parse_config(self.config).get("SHARED"))

    @property
    def fused(self) -> bool:
        """The box slab values and the edge functions are rounded once (build parameter
        FUSED)."""
        return bool(parse_config(self.config).get("FUSED"))

    @property
    def transform_op(self) -> bool:
        """The instance transform runs on the datapath (build parameter TRANSFORM)."""
        return self.transform == DATAPATH

    def clock(self) -> tuple[float, str]:
        """The datapath's clock (MHz) and where it comes from: ``--clock-mhz``, the
        configuration's Fmax in ``rayflex timing``'s cache ("timing": its RTL as it is now, the
        default delay target and liberty), or the default 1 GHz ("default")."""
        if self.clock_mhz is not None:
            return float(self.clock_mhz), "--clock-mhz"
        fmax = _cached_fmax(config_name({**parse_config(self.config),
                                         **({"TRANSFORM": 1} if self.transform_op else {})}))
        if fmax is not None:
            return fmax, "timing"
        return DEFAULT_CLOCK_MHZ, "default"

    def backend_options(self, name: str | None = None) -> dict:
        """Keyword options of ``driver.backends.backend`` for this datapath; for the RT unit in
        RTL (``name`` "rtunit") also its ray slots, stack depth, pipelines, memory hierarchy and
        culling stack (``cull_stack``), after refusing (ValueError, one line) a ray count, stack
        depth, pipeline count or node format it cannot take."""
        out = {"extended": self.extended, "disjoint": self.disjoint, "latency": self.latency,
               "compressed": self.compressed, "transform": self.transform_op,
               **({"fused": True} if self.fused else {}),
               **({"shared": True} if self.shared else {})}
        if name == UNIT_BACKEND:
            # what the unit cannot be built with or read: one line, before any work
            unit_params({}, self.rays_in_flight, self.stack_depth, pipelines=self.pipelines)
            check_format(self.bvh_format, self.compressed, self.transform_op, False)
            out.update(rays_in_flight=self.rays_in_flight, stack_depth=self.stack_depth,
                       pipelines=self.pipelines, memory=self.memory().config(),
                       compare=self.unit_check == UNIT_CHECKS[0],
                       **({"cull": True} if self.cull_stack else {}))
        return out

    def rtl_params(self) -> dict:
        """RTL build parameters (EXTENDED, DISJOINT, LATENCY, COMPRESSED, TRANSFORM, FUSED,
        SHARED) of this datapath."""
        return rtl_params(self.extended, self.disjoint, self.latency, self.compressed,
                          self.transform_op, self.fused, self.shared)

    def memory(self):
        """The RT units' ``driver.rtunit.MemoryModel`` (``cache_kib`` 0: no node cache;
        ``l2_kib`` 0: no L2)."""
        return MemoryModel(self.cache_kib * 1024, self.cache_ways, self.line_bytes,
                           self.mem_latency, float(self.mem_bytes_per_cycle),
                           hit_latency=self.cache_latency, sector_bytes=self.sector_bytes,
                           mshrs=self.mshrs, l2_bytes=self.l2_kib * 1024, l2_ways=self.l2_ways,
                           l2_latency=self.l2_latency)

    def schedule(self):
        """The frame schedule of the replay (``driver.rtunit.gpu.Schedule``)."""
        return Schedule(self.frame_schedule, self.warp_size, self.warps_per_unit,
                        self.shader_cycles,
                        self.flush_between, self.rt_units)

    @classmethod
    def preset(cls, name: str = DEFAULT_PRESET, **changes) -> "DesignPoint":
        """The design point of RT-unit preset ``name`` (``driver.rtunit.presets``) with
        ``changes`` (any option) over it."""
        if name not in PRESETS:
            raise ValueError(f"--rt-preset: unknown value {name!r}; choose from "
                             f"{', '.join(PRESETS)}")
        return cls(**{**PRESETS[name].values, **changes, "rt_preset": name})

    def order_options(self) -> dict:
        """``driver.rtunit.replay``'s ``ray_order`` and ``ray_window`` (index order: no window)."""
        return {"ray_order": self.ray_order,
                "ray_window": None if self.ray_order == DEFAULT_POLICY else self.ray_window}

    def workload_options(self) -> dict:
        """``driver.workloads.run`` options."""
        return {"spp": self.spp, "bounces": self.bounces, "ao_rays": self.ao_rays,
                "seed": self.seed}

    def tree_options(self) -> dict:
        """``fill`` and ``bvh_format`` (BVH build) and ``cull_stack`` (traversal)."""
        return {"fill": self.bvh_fill, "cull_stack": self.cull_stack,
                "bvh_format": self.bvh_format}

    def scene_of(self, scene):
        """The scene as this point traces it: flattened with ``flatten``. With the transform on
        the datapath the scene must have instances (one-line ValueError otherwise)."""
        if self.transform_op and getattr(scene, "instances", None) is None:
            raise ValueError(f"--transform {DATAPATH}: scene {scene.name!r} has no instances "
                             "(one mesh), so there is no instance transform to run")
        return scene.flattened() if self.flatten else scene

    def build(self, scene):
        """The BVH of ``scene`` for this point (``driver.bvh4.build_scene``: a two-level
        image for an instanced scene; a scene with its own ``build_bvh``, a LumiBench scene,
        may take it from its cache)."""
        own = getattr(scene, "build_bvh", None)
        if own is not None:
            return own(fill=self.bvh_fill, format=self.bvh_format, transform=self.transform)
        return build_scene(scene, fill=self.bvh_fill, format=self.bvh_format,
                           transform=self.transform)

    def group(self, name: str) -> dict:
        return {o.name: getattr(self, o.name) for o in OPTIONS if o.group == name}

    def as_dict(self) -> dict:
        return asdict(self)

    def key(self) -> str:
        """A stable text key of the point (``sweep``'s resume file)."""
        return ",".join(f"{f.name}={getattr(self, f.name)}" for f in fields(self))

    def replace(self, **changes) -> "DesignPoint":
        return replace(self, **changes)



@functools.lru_cache(maxsize=64)
def _cached_fmax(config: str) -> float | None:
    return timing.cached_fmax(config)


def clock_figures(point: DesignPoint, stats: dict) -> dict:
    """The frame in real units at the point's clock (``DesignPoint.clock``): the ``clock`` object
    of a frame's JSON: ``clock_mhz``, ``clock_source``, ``frame_us`` (the frame's cycles: the
    RT-unit replay with its memory, else with free node fetches, else the wavefront's) and
    ``rays_per_s_per_rt_unit``."""
    mhz, source = point.clock()
    cycles = None
    for key in ("rtunit_memory", "rtunit", "wavefront"):
        obj = stats.get(key)
        if isinstance(obj, dict) and obj.get("cycles"):
            cycles = obj["cycles"]
            break
    frame_us = cycles / mhz if cycles else None
    rays = stats.get("rays")
    rate = (rays / (frame_us * 1e-6) / point.rt_units) if frame_us and rays else None
    return {"clock_mhz": mhz, "clock_source": source,
            "frame_us": round(frame_us, 3) if frame_us is not None else None,
            "rays_per_s_per_rt_unit": round(rate) if rate is not None else None}


def varied(points: list[DesignPoint]) -> list[str]:
    """The option names whose value differs between ``points``."""
    return [o.name for o in OPTIONS if len({getattr(p, o.name) for p in points}) > 1]
