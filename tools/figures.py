#!/usr/bin/env python3
"""Rebuild every image and JSON file the README and docs/ show, from the tool itself.

    python tools/figures.py --list               # the figures: name, cost, outputs, last run
    python tools/figures.py --only power_signals  # rebuild one (repeatable)
    python tools/figures.py --light               # rebuild the ones that take about a minute
    python tools/figures.py                       # rebuild all (tens of minutes on 2 cores)
    python tools/figures.py --numbers             # the numbers the README quotes, from the JSON

Each figure is one command of the tool (``rayflex render|bench|sweep|power|study`` or
``python -m driver.area``) run from the checkout on its own code (``PYTHONPATH`` = the
checkout). After a
figure is rebuilt, ``docs/figures.json`` records its command, the commit it ran on and the
machine (CPU model, cores), which is what the docs cite for a measurement.

``README_NUMBERS`` is the one table of the numbers the README quotes: quoted name -> (JSON file,
key path, format). ``tests/test_docs.py`` checks that each appears in the README exactly as the
JSON it comes from says, so the README cannot drift from its data.

tools/ is not part of the installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from driver.core.layout import IMAGE_FORMATS  # noqa: E402  (the checkout's, not an installed one)

MANIFEST = ROOT / "docs" / "figures.json"
RAYFLEX = [sys.executable, "-m", "driver.cli"]
TMP = "{tmp}"                       # an output nobody shows (e.g. a heat map), in a temp directory


@dataclass(frozen=True)
class Figure:
    name: str
    argv: tuple                      # the command; "{tmp}" stands for a scratch directory
    outputs: tuple                   # files it writes that the README or docs show
    minutes: float                   # rough cost on the reference machine (2 cores, warm caches)
    about: str

    def command(self, tmp: str = "TMP") -> list[str]:
        return [a.replace(TMP, tmp) for a in self.argv]

    def shown(self) -> str:
        """The command as a user types it."""
        words = self.command()
        if words[:3] == RAYFLEX:
            words = ["rayflex", *words[3:]]
        elif words[:1] == [sys.executable]:
            words = ["python", *words[1:]]
        return " ".join(words)


def _render(name, scene, *extra, heatmap=True, json_out=None, minutes=5.0, about=""):
    out = f"images/{name}.png"
    heat = f"images/{name}_heatmap.png" if heatmap else f"{TMP}/{name}_heatmap.png"
    argv = (*RAYFLEX, "render", scene, "--size", "256", "--backend", "rtl", "--check-embree",
            *extra, "--out", out, "--heatmap", heat, "--no-progress")
    outputs = (out, *([heat] if heatmap else []))
    if json_out:
        argv += ("--json", json_out)
        outputs += (json_out,)
    return Figure(name, argv, outputs, minutes, about)


def _bench_workload(scene, workload):
    stem = f"images/bench_{scene}_{workload}64"
    return Figure(f"bench_{scene}_{workload}64",
                  (*RAYFLEX, "bench", "--scene", scene, "--workload", workload, "--size", "64",
                   "--spp", "2", "--bounces", "2", "--sweep-rays", "1,4,16,64,256,1024",
                   "--json", f"{stem}.json", "--plot", f"{stem}_sweep.png", "--no-progress"),
                  (f"{stem}.json", f"{stem}_sweep.png"), 4.0,
                  f"datapath mix per ray type and the rays-in-flight sweep, {scene} {workload}")


def _power(level, minutes, workloads=True):
    return Figure(f"power_{level}",
                  (*RAYFLEX, "power", "--level", level,
                   *(("--scene", "bunny", "--size", "32") if workloads else ()),
                   "--json", f"docs/power_{level}.json", "--plot", f"images/power_{level}.png",
                   "--no-progress"),
                  (f"docs/power_{level}.json", f"images/power_{level}.png"), minutes,
                  f"energy per operation (and per ray) of the four configurations, {level} level")


# the two trade-offs beside the configurations they change (docs/tradeoffs.md)
TRADEOFF_CONFIGS = ("baseline-unified,baseline-unified-fused,extended-unified,"
                    "extended-unified-shared")

# the q8 decode and TRANSFORM beside the configuration they extend (docs/power.md)
POWER_Q8_XF = "baseline-unified,baseline-unified-q8,baseline-unified-xf"
# the configurations rayflex timing has timed for docs/timing.md (its default six: the paper's
# four, the q8 decode and TRANSFORM), and the area study's required delays (ps)
TIMED = ("baseline-unified,extended-unified,baseline-unified-q8,baseline-unified-xf,"
         "baseline-disjoint,extended-disjoint")
ABC_DELAYS = "2000,5000,10000,14000,20000,30000,50000"


def _power_q8_xf(level, minutes):
    stem = f"power_q8_xf_{level}"
    return Figure(stem,
                  (*RAYFLEX, "power", "--level", level, "--config", POWER_Q8_XF,
                   "--scene", "bunny", "--size", "32", "--bvh-format", "q8",
                   "--json", f"docs/{stem}.json", "--plot", f"images/{stem}.png", "--no-progress"),
                  (f"docs/{stem}.json", f"images/{stem}.png"), minutes,
                  f"energy per op of box_q8 (the q8 decode) and TRANSFORM beside box and "
                  f"triangle, and per ray of a q8 image, {level} level")


FORMATS = IMAGE_FORMATS                   # node images (docs/compressed.md)
# the compressed-node study as it was before one-kernel frames: each ray type on its own, cold
# caches, both replays, utilization over rays in flight (docs/compressed.md's first table)
WAVEFRONT_STUDY = ("--frame", "wavefront", "--flush-between", "--ideal-replay", "--sweep-rays",
                   "1,2,4,8,16,32,64,128,256,1024")


def _compressed(fmt):
    out = f"images/compressed_path64_{fmt}.json"
    return Figure(f"compressed_path64_{fmt}",
                  (*RAYFLEX, "bench", "--scene", "bunny_floor", "--workload", "path", "--size",
                   "64", "--spp", "2", "--bounces", "2", "--bvh-format", fmt, *WAVEFRONT_STUDY,
                   "--json", out, "--plot", f"{TMP}/compressed_path64_{fmt}_sweep.png",
                   "--no-progress"),
                  (out,), 4.0, f"the bunny on a floor, path traced, on the {fmt} node image")


PATH = ("--scene", "bunny_floor", "--workload", "path", "--spp", "2", "--bounces", "2")

FIGURES = [
    _render("bunny", "bunny", json_out="images/bunny_stats.json", minutes=1.0,
            about="the 256 x 256 bunny on the RTL with its heat map and frame statistics"),
    _render("cornell_path", "cornell", "--workload", "path", "--spp", "16", minutes=15.0,
            about="Cornell box, path traced, 16 samples per pixel"),
    _render("cornell_ao", "cornell", "--workload", "ao", "--spp", "4", "--ao-rays", "4",
            heatmap=False, minutes=8.0, about="Cornell box, ambient occlusion, 4 x 4 rays"),
    _render("bunny_floor_path", "bunny_floor", "--workload", "path", "--spp", "16",
            minutes=15.0, about="the bunny on a floor, path traced, 16 samples per pixel"),
    _render("bunny_floor_ao", "bunny_floor", "--workload", "ao", "--spp", "4", "--ao-rays", "4",
            heatmap=False, minutes=8.0, about="the bunny on a floor, ambient occlusion"),
    Figure("bench_bunny256",
           (*RAYFLEX, "bench", "--ideal-replay", "--json", "images/bench_bunny256.json",
            "--plot", "images/bench_bunny256_rtunit.png", "--no-progress"),
           ("images/bench_bunny256.json", "images/bench_bunny256_rtunit.png"), 3.0,
           "the default bench frame: RT-unit replay, memory, simulation speeds, sweep"),
    *(_bench_workload(s, w) for s in ("cornell", "bunny_floor") for w in ("path", "ao")),
    Figure("bvh_bench",
           (*RAYFLEX, "bench", "--bvh", "--json", "docs/bvh_bench.json", "--plot",
            "docs/bvh_bench_bvh.png", "--no-progress"),
           ("docs/bvh_bench.json", "docs/bvh_bench_bvh.png"), 10.0,
           "BVH build times (1, 20 and 50 bunnies) and the --bvh-fill x --cull-stack trade-off"),
    *(_compressed(fmt) for fmt in FORMATS),
    Figure("compressed_path64_sweep",
           (*RAYFLEX, "study", "compressed",
            *(f"images/compressed_path64_{fmt}.json" for fmt in FORMATS),
            "--plot", "images/compressed_path64_sweep.png"),
           ("images/compressed_path64_sweep.png",), 0.1,
           "box32 vs q8 vs q8g: utilization with the node memory over rays in flight"),
    Figure("compressed_latency",
           (*RAYFLEX, "sweep", "--scene", "bunny_floor", "--workload", "path", "--size", "64",
            "--spp", "2", "--bounces", "2", "--bvh-format", "box32,q8g", "--mem-latency",
            "0,200", "--cache-ways", "4,512", "--frame", "wavefront", "--flush-between", "yes",
            "--json", "docs/compressed_latency.json",
            "--results", f"{TMP}/compressed_latency.points.jsonl", "--no-progress"),
           ("docs/compressed_latency.json",), 1.0,
           "box32 vs q8g with the memory's latency on and off and a fully associative cache: "
           "per ray type and wavefront"),
    Figure("compressed_build",
           (*RAYFLEX, "study", "bvh", "--counts", "0", "50", "--json",
            "docs/compressed_build.json", "--no-progress"),
           ("docs/compressed_build.json",), 4.0,
           "build times of box32, q8 and q8g on the bunny and 5 M triangles (CPU and wall)"),
    Figure("rayorder",
           (*RAYFLEX, "study", "rayorder", "--json", "docs/rayorder.json",
            "--plot", "images/rayorder.png", "--no-progress"),
           ("docs/rayorder.json", "images/rayorder.png"), 20.0,
           "ray-order policies of the RT unit per scene and ray type, with their state cost"),
    Figure("compressed_gpu",
           (*RAYFLEX, "sweep", *PATH, "--size", "64,128", "--bvh-format", "box32,q8,q8g",
            "--rt-preset", "default,rtx2060-vulkan-sim", "--json", "docs/compressed_gpu.json",
            "--results", f"{TMP}/compressed_gpu.points.jsonl", "--no-progress"),
           ("docs/compressed_gpu.json",), 8.0,
           "box32 vs q8 vs q8g in a one-kernel frame (64 x 64 and 128 x 128) on the default and "
           "rtx2060-vulkan-sim presets: frame cycles, bytes per level and latency per ray type"),
    Figure("compressed_gpu_plot",
           (*RAYFLEX, "study", "gpu", "compressed",
            "docs/compressed_gpu.json", "--plot", "images/compressed_gpu.png"),
           ("images/compressed_gpu.png",), 0.1,
           "latency per ray type and node format on both presets (from compressed_gpu)"),
    Figure("compressed_schedules",
           (*RAYFLEX, "sweep", *PATH, "--size", "64", "--bvh-format", "box32,q8g", "--frame",
            "wavefront,one-kernel", "--flush-between", "yes,no", "--json",
            "docs/compressed_schedules.json", "--results",
            f"{TMP}/compressed_schedules.points.jsonl", "--no-progress"),
           ("docs/compressed_schedules.json",), 2.0,
           "box32 and q8g under the wavefront schedule with cold and warm caches and in one "
           "kernel (default preset): what the cold wavefronts hid"),
    Figure("rayorder_gpu",
           (*RAYFLEX, "sweep", *PATH, "--size", "64,128", "--bvh-format", "box32,q8",
            "--rt-preset", "default,rtx2060-vulkan-sim", "--ray-order", "index,affinity,treelet",
            "--ray-window", "256,1024", "--json", "docs/rayorder_gpu.json", "--results",
            f"{TMP}/rayorder_gpu.points.jsonl", "--no-progress"),
           ("docs/rayorder_gpu.json",), 25.0,
           "ray-order policies in a one-kernel frame (64 x 64 and 128 x 128) on both presets, "
           "box32 and q8"),
    Figure("rayorder_gpu_pool",
           (*RAYFLEX, "sweep", *PATH, "--size", "128", "--bvh-format", "box32,q8",
            "--rt-preset", "default,rtx2060-vulkan-sim", "--rays-in-flight", "256,1024",
            "--json", "docs/rayorder_gpu_pool.json", "--results",
            f"{TMP}/rayorder_gpu_pool.points.jsonl", "--no-progress"),
           ("docs/rayorder_gpu_pool.json",), 6.0,
           "index order with the ray pool as large as the schedulers' windows (128 x 128, both "
           "presets): the rays held without the scheduler"),
    Figure("rayorder_gpu_plot",
           (*RAYFLEX, "study", "gpu", "order",
            "docs/rayorder_gpu.json", "--plot", "images/rayorder_gpu.png"),
           ("images/rayorder_gpu.png",), 0.1,
           "frame cycles per ray-order policy relative to index order (from rayorder_gpu)"),
    Figure("rtunit_units",
           (*RAYFLEX, "sweep", "--scene", "bunny_floor", "--workload", "ao", "--size", "128",
            "--spp", "2", "--rt-preset", "rtx2060-vulkan-sim", "--rt-units", "1,30", "--json",
            "docs/rtunit_units.json", "--results", f"{TMP}/rtunit_units.points.jsonl",
            "--no-progress"),
           ("docs/rtunit_units.json",), 3.0,
           "a GPU-sized frame (128 x 128 AO, 2 spp) on one and on 30 RT units of the "
           "rtx2060-vulkan-sim preset: cycles and the replay's wall time"),
    Figure("bench_bunny_floor_ao128_rtx2060",
           (*RAYFLEX, "bench", "--scene", "bunny_floor", "--workload", "ao", "--size", "128",
            "--spp", "2", "--rt-preset", "rtx2060-vulkan-sim", "--json",
            "images/bench_bunny_floor_ao128_rtx2060.json", "--plot",
            "images/bench_bunny_floor_ao128_rtx2060_held.png", "--no-progress"),
           ("images/bench_bunny_floor_ao128_rtx2060.json",
            "images/bench_bunny_floor_ao128_rtx2060_held.png"), 2.0,
           "the GPU-sized AO frame on the rtx2060-vulkan-sim preset: rays held per RT unit over "
           "the frame, SIMT efficiency, memory levels"),
    Figure("sweep_bunny_floor_ao32",
           (*RAYFLEX, "sweep", "--scene", "bunny_floor", "--workload", "ao", "--size", "32",
            "--config", "baseline-unified,baseline-disjoint", "--rays-in-flight", "16,64",
            "--cache-kib", "0,16", "--json", "images/sweep_bunny_floor_ao32.json",
            "--plot", "images/sweep_bunny_floor_ao32.png",
            "--results", f"{TMP}/sweep.points.jsonl", "--no-progress"),
           ("images/sweep_bunny_floor_ao32.json", "images/sweep_bunny_floor_ao32.png"), 3.0,
           "a design-point sweep: 2 configurations x 2 ray pools x with/without a node cache"),
    Figure("power_bunny_floor_path32",
           (*RAYFLEX, "power", "--scene", "bunny_floor", "--workload", "path", "--size", "32",
            "--json", "images/power_bunny_floor_path32.json", "--no-progress"),
           ("images/power_bunny_floor_path32.json",), 4.0,
           "energy per op and per ray of each ray type (signals level), bunny on a floor, path"),
    *(Figure(f"unit_energy_{stem}",
             (*RAYFLEX, "power", "--backend", "rtunit", "--scene", scene, "--workload", workload,
              "--size", size, "--json", f"docs/unit_energy_{stem}.json", "--no-progress"),
             (f"docs/unit_energy_{stem}.json",), 1.0,
             f"the whole RT unit's energy per ray and module, {scene} {workload} {size}x{size}")
      for stem, scene, workload, size in (("bunny64", "bunny", "primary", "64"),
                                          ("cornell_ao32", "cornell", "ao", "32"),
                                          ("bunny_floor_path32", "bunny_floor", "path", "32"))),
    _power("signals", 1.0, workloads=False),
    _power("gates", 12.0),
    _power("liberty", 12.0),
    *(_power_q8_xf(level, minutes) for level, minutes in
      (("signals", 1.0), ("gates", 12.0), ("liberty", 12.0))),
    Figure("instances_hits",
           (*RAYFLEX, "study", "instances", "hits", "--scene", "bunny_grid",
            "--size", "256", "--json", "docs/instances_hits.json"),
           ("docs/instances_hits.json",), 6.0,
           "bunny_grid instanced vs flattened: image bytes (every format) and the hits of both"),
    Figure("instances_images",
           (*RAYFLEX, "study", "instances", "images", "--scene", "bunny_grid",
            "--scene", "city", "--json", "docs/instances_images.json"),
           ("docs/instances_images.json",), 1.0,
           "two-level image bytes of bunny_grid and the city per format: TLAS, instances, BLASes"),
    Figure("instances_transform",
           (*RAYFLEX, "study", "instances", "transform", "--scene",
            "bunny_grid", "--workload", "path", "--size", "64", "--spp", "2", "--bounces", "2",
            "--json", "docs/instances_transform.json", "--no-progress"),
           ("docs/instances_transform.json",), 5.0,
           "the instance transform in the driver vs on the datapath: ops, RT-unit cycles"),
    # LumiBench: these read a clone of the benchmark's repository at $LUMIBENCH_ROOT
    Figure("lumibench",
           (*RAYFLEX, "suite", "lumibench", "--out", "images/lumibench", "--workers", "2",
            "--no-progress"),
           tuple(f"images/lumibench/{f}" for f in ("summary.json", "summary.csv", "summary.png",
                                                   "images.png")), 3.0,
           "every LumiBench run the clone at LUMIBENCH_ROOT allows, 128 x 128, 2 spp, on the RTL, "
           "checked and replayed"),
    Figure("lumibench_bath_ao512",
           (*RAYFLEX, "suite", "lumibench", "--scenes", "BATH", "--workloads", "ao", "--size",
            "512", "--out", "images/lumibench_512", "--workers", "2", "--no-progress"),
           ("images/lumibench_512/summary.json", "images/lumibench_512/BATH_AO.json",
            "images/lumibench_512/BATH_AO.png"), 4.0,
           "the bathroom's AO frame at 512 x 512 (16 x the benchmark's pixels) on 2 Dask workers"),
    Figure("lumibench_load_bath",
           (*RAYFLEX, "bench", "--scene-load", "--scene", "lumibench:BATH", "--json",
            "docs/lumibench_load_bath.json", "--no-progress"),
           ("docs/lumibench_load_bath.json",), 0.3,
           "the bathroom's load and BVH build, first and from the scene cache"),
    Figure("lumibench_bath_ao_e2e",
           (*RAYFLEX, "bench", "--end-to-end", "--scene", "lumibench:BATH", "--workload",
            "lumibench-ao", "--size", "128", "--spp", "2", "--repeat", "9", "--json",
            "docs/lumibench_bath_ao_e2e.json", "--no-progress"),
           ("docs/lumibench_bath_ao_e2e.json",), 1.5,
           "the bathroom's AO frame as a render runs it, 9 fresh processes: rays per second "
           "outside loading and the BVH"),
    Figure("lumibench_load_1000",
           (*RAYFLEX, "bench", "--scene-load", "--synthetic", "1000,3000000", "--json",
            "docs/lumibench_load_1000.json", "--no-progress"),
           ("docs/lumibench_load_1000.json",), 2.0,
           "a LumiBench-format folder of 1,000 OBJ files, 3 M triangles: load and build"),
    Figure("area", (sys.executable, "-m", "driver.area", "--yosys", "wheel", "--jobs", "2",
                    "--json", "docs/area.json"),
           ("docs/area.json",), 60.0, "Yosys cell counts of the four configurations"),
    Figure("area_q8_xf", (sys.executable, "-m", "driver.area", "--yosys", "wheel", "--configs",
                          POWER_Q8_XF, "--jobs", "2", "--json", "docs/area_q8_xf.json"),
           ("docs/area_q8_xf.json",), 45.0,
           "Yosys cell counts of the q8 decode and TRANSFORM beside baseline-unified"),
    Figure("tradeoffs_power_signals",
           (*RAYFLEX, "power", "--level", "signals", "--config", TRADEOFF_CONFIGS, "--op",
            "box,triangle", "--json", "docs/tradeoffs_power_signals.json"),
           ("docs/tradeoffs_power_signals.json",), 10.0,
           "energy per box and triangle op (RTL toggles) of the FUSED and SHARED builds beside "
           "today's (docs/tradeoffs.md)"),
    Figure("tradeoffs_fused_lumibench",
           (sys.executable, "tools/fused_study.py", "--json",
            "docs/tradeoffs_fused_lumibench.json"),
           ("docs/tradeoffs_fused_lumibench.json",), 7.0,
           "the hits the FUSED datapath changes on every ray of the LumiBench runs, adjudicated "
           "(docs/tradeoffs.md)"),
    Figure("timing",
           (*RAYFLEX, "timing", "--configs", TIMED, "--jobs", "2", "--rev", "HEAD",
            "--json", "docs/timing.json",
            "--plot", "images/timing_stages.png", "--power-json", "docs/power_liberty.json",
            "--power-plot", "images/timing_power.png", "--no-progress"),
           ("docs/timing.json", "images/timing_stages.png", "images/timing_power.png"), 120.0,
           "Fmax and each pipeline stage's least period (OSU 0.18 um, OpenSTA); power against "
           "the clock"),
    Figure("rtunit_replay_full",
           (sys.executable, "tools/replay_vs_unit.py", "--runs", "full", "--json",
            "docs/rtunit_replay_full.json"),
           ("docs/rtunit_replay_full.json",), 1.5,
           "the full-size frames through the RT unit in RTL, every ray checked against the "
           "traversal and Embree, the replay's cycles against the unit's (docs/rtunit_rtl.md)"),
    Figure("rtunit_lumibench",
           (sys.executable, "tools/unit_lumibench.py", "--json", "docs/rtunit_lumibench.json"),
           ("docs/rtunit_lumibench.json",), 3.5,
           "LumiBench's runs through the RT unit in RTL with their instances, every ray checked, "
           "at stack depths 32 and 8 (needs LUMIBENCH_ROOT; docs/rtunit_rtl.md)"),
    Figure("rtunit_pipelines",
           (sys.executable, "tools/unit_pipelines.py", "--json", "docs/rtunit_pipelines.json"),
           ("docs/rtunit_pipelines.json",), 2.0,
           "the RT unit in RTL with 1, 2 and 4 datapath pipelines: cycles, utilization per "
           "pipeline, the replay's cycles against the unit's (docs/rtunit_rtl.md)"),
    Figure("timing_balanced",
           (*RAYFLEX, "timing", "--configs", "baseline-unified,baseline-unified@10", "--jobs",
            "2", "--rev", "HEAD", "--json", "docs/timing_balanced.json", "--no-progress"),
           ("docs/timing_balanced.json",), 40.0,
           "the balanced pipeline (10 stages: S9 beside the output format) against the paper's 11"),
    Figure("timing_fused",
           (*RAYFLEX, "timing", "--configs", "baseline-unified,baseline-unified-fused",
            "--abc-script", "fast", "--jobs", "2", "--rev", "ae4b17a", "--json",
            "docs/timing_fused.json", "--no-progress"),
           ("docs/timing_fused.json",), 10.0,
           "Fmax, area and flip-flops of the fused build beside the baseline, both mapped by "
           "ABC's fast script (docs/tradeoffs.md)"),
    Figure("timing_tradeoffs",
           (*RAYFLEX, "timing", "--configs", "extended-unified,extended-unified-shared",
            "--jobs", "2", "--rev", "ae4b17a", "--json", "docs/timing_tradeoffs.json",
            "--no-progress"),
           ("docs/timing_tradeoffs.json",), 40.0,
           "Fmax, area and flip-flops of the shared-register build beside the one it changes "
           "(docs/tradeoffs.md)"),
    Figure("timing_sweep_fp_add",
           (*RAYFLEX, "timing", "--top", "rf_fp_add", "--abc-delays", ABC_DELAYS,
            "--json", "docs/timing_sweep_fp_add.json", "--plot",
            "images/timing_sweep_fp_add.png", "--no-progress"),
           ("docs/timing_sweep_fp_add.json", "images/timing_sweep_fp_add.png"), 1.0,
           "the FP adder's area and Fmax against ABC's required delay"),
]
BY_NAME = {f.name: f for f in FIGURES}
LIGHT_MINUTES = 1.5        # --light: the figures at most this long


# --------------------------------------------------------------------------------------------
# Quoted numbers: name -> (JSON file, key path, format)

MIB = 2 ** 20
# The bathroom's AO frame end to end (docs/lumibench_bath_ao_e2e.json): quoted by the README and
# by docs/lumibench.md
E2E_FILE = "docs/lumibench_bath_ao_e2e.json"
E2E_NUMBERS = {
    **{f"e2e_{key}_{stat}": (E2E_FILE, f"summary.{key}.{stat}", fmt_)
       for key, fmt_ in (("rays_per_s", "{:,.0f}"), ("trace_s", "{:.2f}"),
                         ("functional_s", "{:.2f}"), ("replay_s", "{:.2f}"),
                         ("process_s", "{:.1f}"))
       for stat in ("min", "median", "max")},
    "e2e_runs": (E2E_FILE, "runs", lambda v: f"{len(v):d}"),
    "e2e_rays": (E2E_FILE, "runs.0.rays", "{:,}"),
    "e2e_peak": (E2E_FILE, "runs", lambda v: f"{max(r['peak_rss_bytes'] for r in v) / MIB:,.0f}"),
}

# The numbers the README quotes
README_NUMBERS = {
    "bunny_rays": ("images/bunny_stats.json", "rays", "{:,}"),
    "bunny_hits": ("images/bunny_stats.json", "hits", "{:,}"),
    "bunny_ops": ("images/bunny_stats.json", "ops", "{:,}"),
    "bunny_box_per_ray": ("images/bunny_stats.json", "box_ops_per_ray", "{:.2f}"),
    "bunny_tri_per_ray": ("images/bunny_stats.json", "tri_ops_per_ray", "{:.2f}"),
    "bunny_wavefront_cycles": ("images/bunny_stats.json", "wavefront.cycles", "{:,}"),
    "bunny_embree_mismatch": ("images/bunny_stats.json", "embree.prim_mismatch", "{:d}"),
    "bunny_edge_ties": ("images/bunny_stats.json", "embree.edge_ties", "{:d}"),
    "bench_replay_cycles": ("images/bench_bunny256.json", "frame.rtunit.cycles", "{:,}"),
    "bench_replay_utilization": ("images/bench_bunny256.json", "frame.rtunit.utilization", "{:.3f}"),
    "bench_memory_cycles": ("images/bench_bunny256.json", "frame.rtunit_memory.cycles", "{:,}"),
    "bench_memory_utilization": ("images/bench_bunny256.json", "frame.rtunit_memory.utilization", "{:.2f}"),
    "bench_memory_hit_rate": ("images/bench_bunny256.json", "frame.rtunit_memory.hit_rate", "{:.2f}"),
    "bench_memory_bytes_per_ray": ("images/bench_bunny256.json", "frame.rtunit_memory.bytes_per_ray",
                                   "{:.0f}"),
    "bench_rtl_cycles_per_s": ("images/bench_bunny256.json", "rtl_cycles_per_s", "{:,.0f}"),
    "bench_speedup": ("images/bench_bunny256.json", "rtl_vs_pyverilator_speedup", "{:.0f}"),
    "floor_path_util": ("images/bench_bunny_floor_path64.json", "frame.rtunit_memory.utilization",
                        "{:.3f}"),
    **{f"floor_path_{t}_latency": ("images/bench_bunny_floor_path64.json",
                                   f"frame.by_type.{t}.rtunit_memory.latency_mean", "{:,.0f}")
       for t in ("primary", "bounce1")},
    "floor_path_bounce1_bytes": ("images/bench_bunny_floor_path64.json",
                                 "frame.by_type.bounce1.rtunit_memory.bytes_per_ray", "{:.0f}"),
    "cornell_path_util": ("images/bench_cornell_path64.json", "frame.rtunit_memory.utilization",
                          "{:.3f}"),
    **{f"sweep_{name}_{key}": ("images/sweep_bunny_floor_ao32.json", f"points.{i}.{path}", fmt_)
       for name, i in (("nocache", 2), ("cache", 3))
       for key, path, fmt_ in (("util", "rtunit_memory.utilization", "{:.3f}"),
                               ("bytes", "rtunit_memory.bytes_per_ray", "{:.0f}"),
                               ("memory_pj", "energy_per_ray.memory_pj", "{:,.0f}"))},
    "sweep_energy_ao_unified": ("images/sweep_bunny_floor_ao32.json",
                                "points.3.by_type.ao.energy_per_ray.signals", "{:,.0f}"),
    "sweep_energy_ao_disjoint": ("images/sweep_bunny_floor_ao32.json",
                                 "points.7.by_type.ao.energy_per_ray.signals", "{:,.0f}"),
    **{f"power_ray_{t}": ("images/power_bunny_floor_path32.json",
                          f"per_ray.{t}.configs.baseline-unified.energy_per_ray", "{:,.0f}")
       for t in ("primary", "shadow", "bounce1")},
    **{f"order_{t}_{policy}": ("docs/rayorder.json",
                               f"formats.box32.scenes.bunny_floor.{t}.policies.{policy}.{window}"
                               ".utilization", "{:.2f}")
       for t in ("ao", "primary") for policy, window in (("index", 0), ("affinity", 256))},
    "order_state_bytes": ("docs/rayorder.json", "formats.box32.scenes.bunny_floor.ao.policies"
                          ".affinity.256.ray_order_cost.extra_state_bytes", "{:,}"),
    "order_extra_rays": ("docs/rayorder.json", "formats.box32.scenes.bunny_floor.ao.policies"
                         ".affinity.256.ray_order_cost.extra_rays_held", "{:d}"),
    **{f"compressed_{fmt}_bytes_per_triangle": (f"images/compressed_path64_{fmt}.json",
                                                "frame.bvh.bytes_per_triangle", "{:.1f}")
       for fmt in ("box32", "q8", "q8g")},
    # one-kernel frames (docs/compressed.md, docs/rayorder.md, docs/rtunit.md)
    **{f"gpu_{fmt}_util": ("docs/compressed_gpu.json", f"points.{i}.rtunit_memory.utilization",
                           "{:.3f}")
       for fmt, i in (("box32", 0), ("q8", 4), ("q8g", 8))},
    **{f"gpu_{fmt}_dram": ("docs/compressed_gpu.json", f"points.{i}.rtunit_memory.bytes_per_ray",
                           "{:.0f}")
       for fmt, i in (("box32", 0), ("q8", 4), ("q8g", 8))},
    "gpu_rtx_box32_cycles": ("docs/compressed_gpu.json", "points.3.rtunit_memory.cycles", "{:,}"),
    "gpu_rtx_q8g_cycles": ("docs/compressed_gpu.json", "points.11.rtunit_memory.cycles", "{:,}"),
    "gpu_order_q8_index": ("docs/rayorder_gpu.json", "points.25.rtunit_memory.utilization",
                           "{:.3f}"),
    "gpu_order_q8_affinity": ("docs/rayorder_gpu.json", "points.29.rtunit_memory.utilization",
                              "{:.3f}"),
    "gpu_order_q8_pool": ("docs/rayorder_gpu_pool.json", "points.4.rtunit_memory.utilization",
                          "{:.3f}"),
    **{f"gpu_units{u}_{key}": ("docs/rtunit_units.json", f"points.{i}.{path}", fmt_)
       for u, i in ((1, 0), (30, 1))
       for key, path, fmt_ in (("cycles", "rtunit_memory.cycles", "{:,}"),
                               ("util", "rtunit_memory.utilization", "{:.3f}"),
                               ("wall", "wall_s", "{:.1f}"))},
    "compressed_q8g_shadow_wavefront": ("images/compressed_path64_q8g.json",
                                        "frame.by_type.shadow.rtunit_memory.utilization",
                                        "{:.2f}"),
    "gpu_units30_held": ("docs/rtunit_units.json", "points.1.rtunit_memory.simt.rays_held_mean",
                         "{:.0f}"),
    "power_gates_ext_box": ("docs/power_gates.json",
                            "ratios.extended_vs_baseline.unified.box", "{:+.1%}"),
    "power_gates_ext_tri": ("docs/power_gates.json",
                            "ratios.extended_vs_baseline.unified.triangle", "{:+.1%}"),
    "power_gates_tri_vs_box": ("docs/power_gates.json",
                               "ratios.triangle_vs_box.baseline-unified", "{:.2f}"),
    "power_q8_decode": ("docs/power_q8_xf_gates.json",
                        "ratios.q8_decode.baseline-unified-q8.box_q8_vs_base_host", "{:+.1%}"),
    "power_q8_decode_share": ("docs/power_q8_xf_gates.json",
                              "ratios.q8_decode.baseline-unified-q8.decode_share", "{:.1%}"),
    "power_transform_vs_box": ("docs/power_q8_xf_gates.json",
                               "ratios.transform_op.baseline-unified-xf.transform_vs_box",
                               "{:+.1%}"),
    "timing_fmax": ("docs/timing.json", "configs.baseline-unified.fmax_mhz", "{:.1f}"),
    "timing_period": ("docs/timing.json", "configs.baseline-unified.min_period_ns", "{:.2f}"),
    "timing_s8": ("docs/timing.json", "configs.baseline-unified.stages.S8.min_period_ns",
                  "{:.2f}"),
    "paper_power_ext_box": ("docs/power_gates.json", "paper.extended_vs_baseline.box", "{:+.0%}"),
    "paper_power_ext_tri": ("docs/power_gates.json", "paper.extended_vs_baseline.triangle",
                            "{:+.0%}"),
    "paper_area_disjoint": ("docs/area.json", "configs.baseline-disjoint.paper_ratio", "{:.2f}"),
    "paper_area_extended": ("docs/area.json", "configs.extended-unified.paper_ratio", "{:.2f}"),
    "paper_area_both": ("docs/area.json", "configs.extended-disjoint.paper_ratio", "{:.2f}"),
    "area_disjoint": ("docs/area.json", "configs.baseline-disjoint.ratio.cells", "{:.2f}"),
    "area_extended": ("docs/area.json", "configs.extended-unified.ratio.cells", "{:.2f}"),
    "area_both": ("docs/area.json", "configs.extended-disjoint.ratio.cells", "{:.2f}"),
    **{f"area_{suffix}": ("docs/area_q8_xf.json", f"configs.baseline-unified-{suffix}.ratio.cells",
                          "{:.2f}") for suffix in ("q8", "xf")},
    "instances_bytes_ratio": ("docs/instances_hits.json",
                              "images.box32.flattened_over_instanced", "{:.1f}"),
    "transform_ops_per_ray": ("docs/instances_transform.json",
                              "transforms.datapath.frame.transform_ops_per_ray", "{:.2f}"),
    **{f"transform_{key}_change": ("docs/instances_transform.json",
                                   f"datapath_vs_driver.frame.{key}", "{:+.1%}")
       for key in ("ops", "rtunit_cycles", "rtunit_memory_cycles")},
    **{f"transform_{where}_util_mem": ("docs/instances_transform.json",
                                       f"transforms.{where}.frame.rtunit_memory.utilization",
                                       "{:.2f}")
       for where in ("driver", "datapath")},
    "lumibench_runs": ("images/lumibench/summary.json", "totals.runs", "{:d}"),
    "lumibench_size": ("images/lumibench/summary.json", "runs.0.size", "{:d}"),
    "lumibench_rays": ("images/lumibench/summary.json", "totals.rays", "{:,}"),
    "lumibench_datapath_wrong": ("images/lumibench/summary.json", "totals.datapath_wrong",
                                 "{:d}"),
    "lumibench_edge_ties": ("images/lumibench/summary.json", "totals.edge_tie", "{:,}"),
    "lumibench_bath_pt_util": ("images/lumibench/summary.json", "runs.9.utilization_memory",
                               "{:.2f}"),
    "lumibench_bath_pt_bytes": ("images/lumibench/summary.json", "runs.9.bytes_per_ray",
                                "{:.0f}"),
    "lumibench_lands_ao_util": ("images/lumibench/summary.json", "runs.8.utilization_memory",
                                "{:.2f}"),
    "lumibench_wall": ("images/lumibench/summary.json", "wall_s", "{:.0f}"),
    "lumibench_load": ("docs/figures.json", "lumibench.load.median", "{:.1f}"),
    "lumibench_bath_ao_rays_per_s": E2E_NUMBERS["e2e_rays_per_s_median"],
    "lumibench_bath_ao_runs": E2E_NUMBERS["e2e_runs"],
    "bvh_build_bunny": ("docs/bvh_bench.json", "builds.0.build_s", "{:.2f}"),
    "bvh_build_5m": ("docs/bvh_bench.json", "builds.2.build_s", "{:.1f}"),
}


# The numbers docs/lumibench.md quotes (the same form; tests/test_suite.py checks the page)
LUMIBENCH_NUMBERS = {
    "lb_runs": ("images/lumibench/summary.json", "totals.runs", "{:d}"),
    "lb_rays": ("images/lumibench/summary.json", "totals.rays", "{:,}"),
    "lb_edge_ties": ("images/lumibench/summary.json", "totals.edge_tie", "{:,}"),
    "lb_wall": ("images/lumibench/summary.json", "wall_s", "{:.0f}"),
    "lb_bath_ao_rays_per_s": ("images/lumibench/BATH_AO.json", "timing.rays_per_s", "{:,.0f}"),
    "lb_bath_ao_trace": ("images/lumibench/BATH_AO.json", "timing.trace_s", "{:.1f}"),
    "lb_bath_ao_functional": ("images/lumibench/BATH_AO.json", "wavefront.sim_wall_s",
                              "{:.1f}"),
    "lb_bath_ao_replay": ("images/lumibench/BATH_AO.json", "rtunit_memory.sim_wall_s",
                          "{:.1f}"),
    **E2E_NUMBERS,
    "lb512_rays": ("images/lumibench_512/BATH_AO.json", "rays", "{:,}"),
    "lb512_wall": ("images/lumibench_512/BATH_AO.json", "timing.wall_s", "{:.0f}"),
    "lb512_rays_per_s": ("images/lumibench_512/BATH_AO.json", "timing.rays_per_s", "{:,.0f}"),
    **{f"lb512_peak{i}": ("images/lumibench_512/BATH_AO.json", f"workers_peak_rss_bytes.{i}",
                          lambda v: f"{v / MIB:,.0f}") for i in (0, 1)},
    **{f"load_bath_{p}": ("docs/lumibench_load_bath.json", f"{p}.to_tracing_s", "{:.1f}")
       for p in ("cold", "warm")},
    **{f"load_1000_{p}": ("docs/lumibench_load_1000.json", f"{p}.to_tracing_s", "{:.1f}")
       for p in ("cold", "warm")},
    "load_1000_cold_peak": ("docs/lumibench_load_1000.json", "cold.peak_rss_bytes",
                            lambda v: f"{v / MIB:,.0f}"),
    "load_1000_triangles": ("docs/lumibench_load_1000.json", "cold.triangles", "{:,}"),
    **{f"lb_bath_{t}_latency": ("images/lumibench/BATH_PT.json",
                                f"by_type.{t}.rtunit_memory.latency_mean", "{:,.0f}")
       for t in ("primary", "bounce2")},
    **{f"lb_bath_{t}_bytes": ("images/lumibench/BATH_PT.json",
                              f"by_type.{t}.rtunit_memory.bytes_per_ray", "{:,.0f}")
       for t in ("primary", "bounce2")},
    "lb_sprng_bounce2_bytes": ("images/lumibench/SPRNG_PT.json",
                               "by_type.bounce2.rtunit_memory.bytes_per_ray", "{:,.0f}"),
    "lb_sprng_bounce2_latency": ("images/lumibench/SPRNG_PT.json",
                                 "by_type.bounce2.rtunit_memory.latency_mean", "{:,.0f}"),
    **{f"lb_{n}_util": ("images/lumibench/summary.json", f"runs.{i}.utilization_memory",
                        "{:.2f}") for n, i in (("ship_sh", 1), ("ship_ao", 2), ("sprng_pt", 3),
                                               ("lands_ao", 8), ("bath_pt", 9),
                                               ("bath_ao", 11))},
    **{f"lb_{n}_ops": ("images/lumibench/summary.json", f"runs.{i}.ops_per_ray", "{:.1f}")
       for n, i in (("ship_sh", 1), ("ship_ao", 2), ("lands_sh", 7), ("lands_ao", 8))},
    "lb_ship_ao_ties": ("images/lumibench/summary.json", "runs.2.edge_tie", "{:,}"),
}


LUMIBENCH_PAGE = ROOT / "docs" / "lumibench.md"
LUMIBENCH_FIGURES = ("lumibench", "lumibench_bath_ao512", "lumibench_load_bath",
                     "lumibench_load_1000", "lumibench_bath_ao_e2e")


def lumibench_sections(root: Path = ROOT) -> dict[str, str]:
    """The generated sections of docs/lumibench.md (between ``<!-- generated: NAME -->`` and
    ``<!-- end: NAME -->``): the table of runs and the text that quotes the JSON."""
    from driver.suite_report import markdown_table
    n = readme_numbers(root, LUMIBENCH_NUMBERS)
    summary = json.loads((root / "images" / "lumibench" / "summary.json").read_text())
    table = markdown_table(summary) + f"""

Each run's wall time is its own, in one Dask worker process while the other worker made other
runs; the last line's is the whole suite's. `edge tie`: mostly the ship's, whose sails are
duplicated coplanar triangles (two triangles at the same t on every ray that meets them; the
ship's AO run alone has {n['lb_ship_ao_ties']})."""
    reading = f"""What the runs say about an RT unit of this design point:

- **Frames of short shadow and AO rays keep the datapath busy** where the scene is small or the
  rays coherent: the ship's shadow and AO frames issue an op in {n['lb_ship_sh_util']} and
  {n['lb_ship_ao_util']} of their cycles, the landscape's AO frame in {n['lb_lands_ao_util']}; the
  bathroom's camera rays fetch {n['lb_bath_primary_bytes']} bytes of nodes per ray from memory
  and are done {n['lb_bath_primary_latency']} cycles after their trace call on average: the
  32 KiB node cache holds most of what neighbouring rays share.
- **Path-traced frames on the large scenes are memory-bound**: the bathroom's keeps the datapath
  busy in {n['lb_bath_pt_util']} of its cycles, Spring's in {n['lb_sprng_pt_util']}; from the
  second bounce on, the bathroom's rays fetch {n['lb_bath_bounce2_bytes']} bytes per ray and take
  {n['lb_bath_bounce2_latency']} cycles each, Spring's {n['lb_sprng_bounce2_bytes']} bytes and
  {n['lb_sprng_bounce2_latency']} cycles. On these frames the memory side (node cache,
  bandwidth, latency, ray order, compressed nodes) decides what path tracing costs, which the
  bunny frames could not show.
- **Ops per ray depend on the scene more than on the shader**: the ship costs
  {n['lb_ship_ao_ops']} (AO) to {n['lb_ship_sh_ops']} (SH) ops per ray (duplicated sails, long
  thin rigging in overlapping boxes), the landscape {n['lb_lands_ao_ops']} to
  {n['lb_lands_sh_ops']} (most rays see the sky). Energy per ray follows ops per ray: a
  configuration's energy per op does not depend on the scene.
- **The bathroom's shadows are all dark**: it is lit by the sky from (0, 1, 0) and the room is
  closed, so every shadow ray that faces the sky meets the ceiling, as it does in the benchmark.
- Each frame is replayed as a GPU runs the benchmark's shaders (`rtunit_memory`,
  docs/rtunit.md): one kernel, each pixel's thread tracing its camera ray and then its shadow,
  AO or bounce rays in program order, no barrier between ray types. The ray types share the
  pipeline, so each has a latency and bytes per ray, not a utilization of its own."""
    manifest = load_manifest()

    def load(name: str) -> str:
        got = (manifest.get(name) or {}).get("load")
        return ("load not recorded" if not got else
                f"load {got['min']:.1f} to {got['max']:.1f}, median {got['median']:.1f}")

    ao = json.loads((root / "images" / "lumibench" / "BATH_AO.json").read_text())
    ratio = ao["timing"]["trace_s"] / ao["wavefront"]["sim_wall_s"]
    times = f"""Measured on the reference machine (AMD EPYC, 2 cores); each figure gives the machine's load
while it ran (runnable processes, sampled every 10 s by `tools/figures.py`; the suite's own two
workers make 2; above that, other jobs shared the cores and every wall time grows). The parts of
one run share the same conditions, so their ratios hold.

- **The suite**: the {n['lb_runs']} runs, {n['lb_rays']} rays, in {n['lb_wall']} s on 2 Dask
  workers ({load('lumibench')}; `images/lumibench/summary.json`), every ray traced on the RTL,
  checked against Embree and replayed on the RT unit with its node memory: each request is
  simulated once on the RTL by the functional trace, and the timing replay moves it through the
  pipelines' handshake timing (docs/rtunit.md). Each worker is one process on one core.
- **The bathroom's AO frame, one process** (128 × 128, 2 spp, {n['e2e_rays']} rays; `rayflex
  bench --end-to-end --scene lumibench:BATH --workload lumibench-ao --size 128 --spp 2 --repeat
  {n['e2e_runs']}`, `docs/lumibench_bath_ao_e2e.json`; {load('lumibench_bath_ao_e2e')}): each run a fresh
  `rayflex render lumibench:BATH --workload lumibench-ao --size 128 --spp 2 --check-embree
  --rtunit` process, every ray on the RTL, checked against Embree and replayed: median
  {n['e2e_rays_per_s_median']} rays per second outside loading and the BVH (from
  {n['e2e_rays_per_s_min']} to {n['e2e_rays_per_s_max']} over {n['e2e_runs']} runs;
  {n['e2e_trace_s_median']} s, of which the functional RTL pass {n['e2e_functional_s_median']} s
  and the RT-unit replay {n['e2e_replay_s_median']} s, summed over tiles that overlap); the
  whole process {n['e2e_process_s_median']} s, peak memory {n['e2e_peak']} MiB. The process
  uses both cores: its tiles run on two threads, each with its own Verilated model
  (`RAYFLEX_THREADS`; docs/workloads.md).
- **The same frame inside the suite** (one worker, one core, beside the other worker's run):
  {n['lb_bath_ao_rays_per_s']} rays per second outside loading and BVH build
  ({n['lb_bath_ao_trace']} s, of which the functional RTL pass {n['lb_bath_ao_functional']} s
  and the RT-unit replay {n['lb_bath_ao_replay']} s; the rest is the traversal's own work
  between the datapath's steps, the Embree check, shading): {ratio:.2f} × the time of the
  functional RTL pass alone.
- **The bathroom's AO frame at 512 × 512** (16 × the benchmark's pixels, {n['lb512_rays']} rays;
  `rayflex suite lumibench --scenes BATH --workloads ao --size 512 --workers 2`: a suite of one
  run spreads its tiles over the workers; {load('lumibench_bath_ao512')}): {n['lb512_wall']} s,
  {n['lb512_rays_per_s']} rays per second; the two workers' peak memory {n['lb512_peak0']} MiB
  and {n['lb512_peak1']} MiB (`images/lumibench_512/BATH_AO.json`).
- **Loading** (`rayflex bench --scene-load`, each phase a fresh process,
  `docs/lumibench_load_bath.json`; {load('lumibench_load_bath')}): the bathroom starts tracing
  {n['load_bath_cold']} s after
  its process starts the first time (reading its 46 OBJ files, building its two-level BVH) and
  {n['load_bath_warm']} s the second time (the scene and its BVH from the cache; most of it is
  importing the tool).
- **A large folder**: 1,000 OBJ files of {n['load_1000_triangles']} triangles
  (`rayflex bench --scene-load --synthetic 1000,3000000`, `docs/lumibench_load_1000.json`;
  {load('lumibench_load_1000')}) load and build in {n['load_1000_cold']} s the first time, peak memory
  {n['load_1000_cold_peak']} MiB, and start tracing {n['load_1000_warm']} s after the start the
  second time."""
    return {"table": table, "reading": reading, "times": times}


def lumibench_page(root: Path = ROOT) -> str:
    """docs/lumibench.md with its generated sections made from the JSON files."""
    return _fill(root / "docs" / "lumibench.md", lumibench_sections(root))


def _fill(page: Path, sections: dict[str, str]) -> str:
    """``page``'s text with each section between ``<!-- generated: NAME ... -->`` and
    ``<!-- end: NAME -->`` replaced by ``sections[NAME]``."""
    import re
    text = page.read_text()
    for name, body in sections.items():
        pattern = re.compile(rf"(<!-- generated: {name}\b[^>]*-->\n).*?(<!-- end: {name} -->)",
                             re.S)
        if not pattern.search(text):
            raise SystemExit(f"figures: error: {page.name} has no section {name!r}")
        text = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)
    return text


TIMING_PAGE = ROOT / "docs" / "timing.md"


def timing_sections(root: Path = ROOT) -> dict[str, str]:
    """The generated sections of docs/timing.md, from docs/timing.json (the ``timing`` figure):
    the command and RTL, the tables, what they say, the flow's time, and power at Fmax."""
    from driver import timing
    from driver.area import PAPER_OVERHEAD
    rep = json.loads((root / "docs" / "timing.json").read_text())
    cfgs = rep["configs"]
    base = cfgs.get("baseline-unified")
    made = load_manifest().get("timing", {})
    import textwrap
    head = (textwrap.fill(
        f"RTL of commit `{rep['rtl_rev']}` (`rtl_sha` {rep['rtl_sha']}), {rep['yosys']}, "
        f"{rep['sta']}, `{Path(next(iter(cfgs.values()))['liberty']).name}`; made by `python "
        f"tools/figures.py --only timing` (tool commit {made.get('commit', '?')}, "
        "[figures.json](figures.json)), which runs", 100, break_on_hyphens=False,
        break_long_words=False)
        + f"\n\n    {BY_NAME['timing'].shown()}\n\n" + timing.markdown(rep))

    def stage_text(r, s):
        st = r["stages"][s]
        return f"{s} ({timing.STAGE_MEANING.get(s, s)}, {st['min_period_ns']:.2f} ns)"

    reading = []
    if base:
        lim = base["limiting_stage"]
        st = base["stages"][lim]
        cells = [c["cell"] for c in st["path"][1:]]
        bufs = sum(c.startswith("BUF") for c in cells)
        reading.append(
            f"* **The stage that sets the clock** of baseline-unified is {lim}, the "
            f"{timing.STAGE_MEANING.get(lim, lim)}: from `{st['start']}` to `{st['end']}`, "
            f"{st['cells_on_path']} cells after the flip-flop ({bufs} of them buffers), "
            f"{st['arrival_ns']:.2f} ns plus {st['setup_ns']:.2f} ns setup.")
        fu = [f"S{k}" for k in range(1, 9) if f"S{k}" in base["stages"]]
        per = [base["stages"][s]["min_period_ns"] for s in fu]
        if per:
            lo, hi, mean = min(per), max(per), sum(per) / len(per)
            clk_q = base["stages"][lim]["path"][0]["incr_ns"]
            split = mean / 2 + clk_q + st["setup_ns"]
            reading.append(
                f"* **The pipeline is balanced:** {fu[0]} to {fu[-1]} each hold one "
                f"floating-point unit between registers and lie within {lo:.2f} to {hi:.2f} ns "
                f"({(hi / lo - 1) * 100:.0f} %). Moving logic between them gains at most "
                f"{(1 - mean / hi) * 100:.0f} % (eight even stages would each take their mean, "
                f"{mean:.2f} ns), and no two of them merge without doubling the period; a faster "
                f"clock needs every one of them split in two, each half about {mean / 2:.2f} ns "
                f"plus a flip-flop's {clk_q:.2f} ns clock-to-Q and {st['setup_ns']:.2f} ns "
                f"setup: up to {hi / split:.1f} × the Fmax (an estimate from these per-stage "
                "delays, not a synthesized design).")
        if "S9" in base["stages"] and "out" in base["stages"]:
            s9, out = (base["stages"][k]["min_period_ns"] for k in ("S9", "out"))
            reading.append(
                f"* **The other way,** S9 (the sort's last layer, {s9:.2f} ns) cannot join S8 "
                f"without lengthening the clock, but S9 and the response format (`out`, "
                f"{out:.2f} ns) together take {s9 + out:.2f} ns, far below {hi:.2f}: by the "
                "paper's rule (merge where the critical path does not grow) one stage and its "
                "register go at no cost in Fmax: the balanced pipeline below.")
    lims = {r["limiting_stage"] for r in cfgs.values()}
    if len(cfgs) > 1 and len(lims) == 1:
        f = sorted(r["fmax_mhz"] for r in cfgs.values())
        reading.append(
            f"* **One stage sets every configuration's clock,** {next(iter(lims))}: Fmax from "
            f"{f[0]:.1f} to {f[-1]:.1f} MHz, a spread of {(f[-1] / f[0] - 1) * 100:.1f} %"
            + ("" if not {"baseline-unified", "baseline-unified-q8"} <= set(cfgs) else
               "; the same stage's period moves by "
               + _moved(*(cfgs[n]["stages"][next(iter(lims))]["min_period_ns"]
                          for n in ("baseline-unified", "baseline-unified-q8")))
               + " between two builds where its RTL is the same (baseline-unified and "
               "baseline-unified-q8, which adds a stage before S1): ABC maps the whole design at "
               "once, and a configuration with more logic is not always the slower one") + ".")
    for n, r in cfgs.items():
        if n == "baseline-unified" or not base:
            continue
        paper = PAPER_OVERHEAD.get(n)
        reading.append(
            f"* **{n}**: {r['fmax_mhz']:.1f} MHz ({(r['fmax_ratio'] - 1) * 100:+.1f} % against "
            f"baseline-unified), set by {stage_text(r, r['limiting_stage'])}; cell area "
            f"{(r['area_ratio'] - 1) * 100:+.0f} %"
            + (f" (the paper's: {paper * 100:+.0f} %)" if paper is not None else "") + ".")
    left = [n for n in timing.DEFAULT_CONFIGS if n not in cfgs]
    if left:
        reading.append(f"* Not timed in this run: {', '.join(left)} (`rayflex timing` times "
                       "all six by default).")

    rows = ["| configuration | whole flow (s) | generic synthesis (s) | mapping (s) | "
            "OpenSTA (s) |", "|---|---:|---:|---:|---:|"]
    for n, r in cfgs.items():
        flow = "cached" if r.get("flow_s") is None else f"{r['flow_s']:,.0f}"
        rows.append(f"| {n} | {flow} | {r['synth_s']:,.0f} | {r['map_s']:,.0f} | "
                    f"{r['sta_s']:,.0f} |")
    flow_time = "\n".join(rows)

    power = rep.get("power_vs_frequency") or {}
    prow = ["| configuration | Fmax (MHz) | pJ per triangle op | mW at 1 GHz | mW at its Fmax | "
            "pJ per box op | mW at 1 GHz | mW at its Fmax |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for n, c in power.items():
        if not c.get("fmax_mhz"):
            continue
        t, b = c["ops"]["triangle"], c["ops"]["box"]
        prow.append(f"| {n} | {c['fmax_mhz']:.1f} | {t['pj_per_op']:,.0f} | "
                    f"{t['mw_at_1ghz']:,.0f} | {t['mw_at_fmax']:,.0f} | {b['pj_per_op']:,.0f} | "
                    f"{b['mw_at_1ghz']:,.0f} | {b['mw_at_fmax']:,.0f} |")
    reading = [textwrap.fill(b, 100, subsequent_indent="  ", break_on_hyphens=False,
                             break_long_words=False) for b in reading]
    return {"results": head, "reading": "\n".join(reading), "flow_time": flow_time,
            "power": "\n".join(prow), "balanced": balanced_section(root)}


def balanced_section(root: Path = ROOT) -> str:
    """The balanced pipeline's table (docs/timing_balanced.json, the ``timing_balanced`` figure):
    each build's stages, Fmax, area, flip-flops and Fmax per area against the paper's 11."""
    import textwrap
    path = root / "docs" / "timing_balanced.json"
    if not path.is_file():
        return "Not measured yet: `python tools/figures.py --only timing_balanced`."
    from driver import timing
    cfgs = json.loads(path.read_text())["configs"]
    base = cfgs[timing.BASELINE]
    rows = ["| build | stages | Fmax (MHz) | limiting stage | area (mm²) | flip-flops | "
            "Fmax per area (MHz/mm²) | against 11 stages |", "|---|---:|---:|---|---:|---:|---:|---:|"]
    for n, r in cfgs.items():
        stages = int(n.partition("@")[2] or 11)
        per = r["fmax_mhz"] / (r["area_um2"] / 1e6)
        rel = per / (base["fmax_mhz"] / (base["area_um2"] / 1e6))
        rows.append(f"| {n} | {stages} | {r['fmax_mhz']:.1f} | {r['limiting_stage']} "
                    f"({timing.STAGE_MEANING.get(r['limiting_stage'], '')}, "
                    f"{r['min_period_ns']:.2f} ns) | {r['area_um2'] / 1e6:.3f} | "
                    f"{r['flip_flops']:,} | {per:.2f} | {(rel - 1) * 100:+.1f} % |")
    merged = next((r for n, r in cfgs.items() if n.endswith("@10")), None)
    if merged is None:
        return "\n".join(rows)
    st, mt = base["stages"], merged["stages"]
    lim = merged["limiting_stage"]
    fmax = merged["fmax_mhz"] / base["fmax_mhz"] - 1
    rel = (merged["fmax_mhz"] / merged["area_um2"]) / (base["fmax_mhz"] / base["area_um2"]) - 1
    text = (
        f"The merged stage (`out`: S9 and the response format) takes {mt['out']['min_period_ns']:.2f}"
        f" ns, where the 11-stage build's S9 took {st['S9']['min_period_ns']:.2f} and its `out` "
        f"{st['out']['min_period_ns']:.2f}: R9 goes ({base['flip_flops'] - merged['flip_flops']:,} "
        f"flip-flops), the area falls by {(1 - merged['area_um2'] / base['area_um2']) * 100:.1f} % "
        f"and the latency by a cycle. The clock moves by {fmax * 100:+.1f} %, at {lim} "
        f"({timing.STAGE_MEANING.get(lim, lim)}: {st[lim]['min_period_ns']:.2f} and "
        f"{mt[lim]['min_period_ns']:.2f} ns), whose RTL the two builds share: that is ABC mapping "
        "the whole design at once, the same variation as between the configurations above. "
        f"Fmax per area moves by {rel * 100:+.1f} %, within that variation: on this flow no "
        "rebalancing measurably raises Fmax per area. Merging buys a cycle of latency and about a "
        "percent of area; a faster clock needs every one of S1 to S8 split (above).")
    return "\n".join(rows) + "\n\n" + textwrap.fill(text, 100, break_on_hyphens=False,
                                                     break_long_words=False)


def _moved(a: float, b: float) -> str:
    return f"{abs(b / a - 1) * 100:.1f} % ({a:.2f} and {b:.2f} ns)"


def timing_page(root: Path = ROOT) -> str:
    """docs/timing.md with its generated sections made from docs/timing.json."""
    return _fill(root / "docs" / "timing.md", timing_sections(root))


def lookup(data, path: str):
    """``data`` at a dotted key path (list indices are integers)."""
    for key in path.split("."):
        data = data[int(key)] if isinstance(data, list) else data[key]
    return data


def readme_numbers(root: Path = ROOT, table: dict | None = None) -> dict[str, str]:
    """Every quoted README number (or of ``table``, e.g. ``LUMIBENCH_NUMBERS``), formatted
    from its JSON file."""
    cache: dict[str, object] = {}
    out = {}
    for name, (file, path, fmt) in (README_NUMBERS if table is None else table).items():
        if file not in cache:
            cache[file] = json.loads((root / file).read_text())
        value = lookup(cache[file], path)
        text = fmt(value) if callable(fmt) else fmt.format(value)
        out[name] = text.replace("%", " %")
    return out


# --------------------------------------------------------------------------------------------
# the manifest: which command, commit and machine made each figure


def machine() -> dict:
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count()}


class LoadSampler:
    """The machine's load (the 1-minute load average: runnable processes) sampled every
    ``every`` seconds while a figure is made: a time taken on a busy machine says so."""

    def __init__(self, every: float = 10.0):
        self.every, self.samples = every, []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while True:
            self.samples.append(os.getloadavg()[0])
            if self._stop.wait(self.every):
                return

    def __enter__(self) -> "LoadSampler":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def summary(self) -> dict | None:
        """min, median and max of the samples, with the cores they share (None: no sample)."""
        if not self.samples:
            return None
        v = sorted(self.samples)
        return {"min": round(v[0], 2), "median": round(v[len(v) // 2], 2),
                "max": round(v[-1], 2), "samples": len(v), "cores": os.cpu_count()}


def _git(*args) -> str:
    r = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else ""


def head_commit() -> str:
    commit = _git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = _git("status", "--porcelain", "--untracked-files=no", "driver")
    return commit + ("-dirty" if dirty else "")


def load_manifest() -> dict:
    try:
        return json.loads(MANIFEST.read_text())
    except (OSError, ValueError):
        return {}


def _write_manifest(data: dict) -> None:
    tmp = MANIFEST.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, MANIFEST)


def record_existing() -> None:
    """Manifest entries for figures never rebuilt by this script: the commit that last wrote
    their first output (from git) and the reference machine."""
    data = load_manifest()
    for fig in FIGURES:
        if fig.name in data:
            continue
        commit = _git("log", "-1", "--format=%h", "--", fig.outputs[0]) or "unknown"
        data[fig.name] = {"command": fig.shown(), "outputs": list(fig.outputs),
                          "commit": commit, "machine": {"cpu": "AMD EPYC", "cores": 2},
                          "date": _git("log", "-1", "--format=%cs", commit) or None}
    _write_manifest(data)


def rebuild(fig: Figure) -> None:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    print(f"[{fig.name}] {fig.shown()}", file=sys.stderr, flush=True)
    commit = head_commit()                        # the code it runs on (before any later commit)
    with tempfile.TemporaryDirectory(prefix="figures-") as tmp, LoadSampler() as load:
        r = subprocess.run(fig.command(tmp), cwd=ROOT, env=env)
    if r.returncode != 0:
        raise SystemExit(f"figures: error: {fig.name} failed (exit {r.returncode})")
    data = load_manifest()
    data[fig.name] = {"command": fig.shown(), "outputs": list(fig.outputs),
                      "commit": commit, "machine": machine(),
                      "date": datetime.date.today().isoformat(), "load": load.summary()}
    _write_manifest(data)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python tools/figures.py",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--list", action="store_true", help="list the figures and exit")
    p.add_argument("--only", action="append", metavar="NAME", choices=sorted(BY_NAME),
                   help="rebuild only this figure (repeatable)")
    p.add_argument("--light", action="store_true",
                   help=f"rebuild the figures of at most {LIGHT_MINUTES} min")
    p.add_argument("--lumibench-page", action="store_true",
                   help="rewrite docs/lumibench.md's generated sections from the JSON files "
                        "(done after any LumiBench figure is rebuilt)")
    p.add_argument("--timing-page", action="store_true",
                   help="rewrite docs/timing.md's generated sections from docs/timing.json "
                        "(done after the timing figure is rebuilt)")
    p.add_argument("--numbers", action="store_true",
                   help="print the README's numbers as their JSON files give them")
    p.add_argument("--record-existing", action="store_true",
                   help="add manifest entries (from git) for figures never rebuilt here")
    args = p.parse_args(argv)
    if args.list:
        data = load_manifest()
        for fig in FIGURES:
            made = data.get(fig.name, {})
            print(f"{fig.name:24} ~{fig.minutes:g} min  {fig.about}\n"
                  f"{'':24} {fig.shown()}\n{'':24} -> {', '.join(fig.outputs)}"
                  f"  (last: commit {made.get('commit', '?')})")
        return 0
    if args.lumibench_page:
        LUMIBENCH_PAGE.write_text(lumibench_page())
        return 0
    if args.timing_page:
        TIMING_PAGE.write_text(timing_page())
        return 0
    if args.numbers:
        quoted = {**readme_numbers(), **readme_numbers(table=LUMIBENCH_NUMBERS)}
        for name, value in quoted.items():
            print(f"{name:32} {value}")
        return 0
    if args.record_existing:
        record_existing()
        return 0
    chosen = ([BY_NAME[n] for n in args.only] if args.only else
              [f for f in FIGURES if f.minutes <= LIGHT_MINUTES] if args.light else FIGURES)
    for fig in chosen:
        rebuild(fig)
    if any(f.name in LUMIBENCH_FIGURES for f in chosen):
        LUMIBENCH_PAGE.write_text(lumibench_page())
    if any(f.name == "timing" for f in chosen):
        TIMING_PAGE.write_text(timing_page())
    return 0


if __name__ == "__main__":
    sys.exit(main())
