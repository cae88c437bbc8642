#!/usr/bin/env python3
"""The RT-unit replay's frame cycles against the RT unit in RTL's (docs/rtunit_rtl.md#the-replay-
against-the-unit): a set of small frames, each traced through ``--backend rtunit`` with the replay
run on the same parameters (``unit_rtl.replay_cycles_ratio``, replay cycles over the unit's),
printed as a Markdown table.

    python tools/replay_vs_unit.py                       # every run, the table on stdout
    python tools/replay_vs_unit.py --runs bunny-primary,cornell-ao-16 --json runs.json

Each run names its scene, workload, size, rays in flight, stack depth and memory (the default
design point's hierarchy, or a fixed latency of 20 cycles). Progress on stderr; the JSON is
written all or nothing. tools/ is not part of the installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from unit_runs import render_unit, run_all, unknown  # noqa: E402

from driver.core.markdown import table as md_table  # noqa: E402

BASE = {"scene": "bunny", "workload": "primary", "size": 64, "point": {}, "rays_in_flight": 64,
        "stack_depth": 32, "memory": "hierarchy", "dividers": 2}
# name: what differs from BASE (point: DesignPoint options of the frame and its datapath)
RUNS = {
    "bunny-primary": {},
    "bunny-primary-stack8": {"stack_depth": 8},
    "bunny-primary-stack4": {"stack_depth": 4},
    "bunny-primary-rif1-stack2": {"stack_depth": 2, "rays_in_flight": 1, "size": 16},
    "bunny-primary-rif8": {"rays_in_flight": 8},
    "bunny-primary-fixed": {"memory": "fixed"},
    "bunny-primary-q8": {"point": {"config": "baseline-unified-q8", "bvh_format": "q8"}},
    "cornell-ao-16": {"scene": "cornell", "workload": "ao", "size": 16, "rays_in_flight": 8},
    "cornell-ao-16-fixed": {"scene": "cornell", "workload": "ao", "size": 16,
                            "rays_in_flight": 8, "memory": "fixed"},
    "cornell-ao-16-div1": {"scene": "cornell", "workload": "ao", "size": 16,
                           "rays_in_flight": 8, "dividers": 1},
    "cornell-ao-32": {"scene": "cornell", "workload": "ao", "size": 32},
    "cornell-ao-32-rif1": {"scene": "cornell", "workload": "ao", "size": 32,
                           "rays_in_flight": 1},
    "bunny_floor-path-32": {"scene": "bunny_floor", "workload": "path", "size": 32,
                            "point": {"spp": 1, "bounces": 2}},
    # the full-size frames: every ray checked against Embree too (--runs full)
    "bunny-primary-256": {"size": 256},
    "bunny-primary-256-stack8": {"size": 256, "stack_depth": 8},
    "bunny_floor-path-64": {"scene": "bunny_floor", "workload": "path",
                            "point": {"spp": 2, "bounces": 2}},
    "bunny_floor-path-64-stack8": {"scene": "bunny_floor", "workload": "path", "stack_depth": 8,
                                   "point": {"spp": 2, "bounces": 2}},
    "cornell-ao-64": {"scene": "cornell", "workload": "ao"},
    "cornell-ao-64-stack8": {"scene": "cornell", "workload": "ao", "stack_depth": 8},
}
FULL = ["bunny-primary-256", "bunny-primary-256-stack8", "bunny_floor-path-64",
        "bunny_floor-path-64-stack8", "cornell-ao-64", "cornell-ao-64-stack8"]


def run(name: str) -> dict:
    spec = {**BASE, **RUNS[name]}
    scene, workload, size = spec["scene"], spec["workload"], spec["size"]
    rif, depth, mem = spec["rays_in_flight"], spec["stack_depth"], spec["memory"]
    res, wall = render_unit(scene, workload, size, rif, depth, mem, point=spec["point"],
                            check_embree=name in FULL, dividers=spec["dividers"])
    u = res.stats["unit_rtl"]
    emb = res.stats.get("embree")
    return {"run": name, "scene": scene, "workload": workload, "size": size,
            "rays_in_flight": rif, "stack_depth": depth, "memory": mem,
            "dividers": spec["dividers"], "point": spec["point"],
            "ops": res.stats["ops"], "unit_cycles": u["cycles"],
            "replay_cycles": u["replay_cycles"], "ratio": u["replay_cycles_ratio"],
            "default_cycles": u["replay_default_cycles"],
            "default_ratio": u["replay_default_cycles_ratio"],
            "rays": res.stats["rays"],
            "mismatches": u["traversal_mismatches"], "divider_full_cycles":
            u["divider_full_cycles"], "stack_overflows": u["stack_overflows"],
            "max_stack_depth": u["max_stack_depth"], "stack_refills": u["stack_refills"],
            "rays_overflowed": u["rays_overflowed"],
            "embree_datapath_wrong": (None if emb is None else
                                      emb["adjudicated"]["classes"]["datapath_wrong"]
                                      if "adjudicated" in emb else
                                      emb["hit_mismatch"] + emb["prim_mismatch"]),
            "wall_s": wall}


def table(rows: list[dict]) -> str:
    head = ["run", "rays", "rays in flight", "stack", "memory", "ops", "unit cycles",
            "max stack depth", "refills", "rays ≠ traversal", "Embree `datapath_wrong`",
            "replay, default costs", "ratio", "replay, unit costs", "ratio"]

    def num(v, fmt):
        return "—" if v is None else format(v, fmt)
    return md_table(head, [
        [r["run"], f"{r['rays']:,}", str(r["rays_in_flight"]), str(r["stack_depth"]),
         r["memory"], f"{r['ops']:,}", f"{r['unit_cycles']:,}", str(r["max_stack_depth"]),
         f"{r['stack_refills']:,}", str(r["mismatches"]), num(r["embree_datapath_wrong"], ","),
         num(r["default_cycles"], ","), num(r["default_ratio"], ".3f"),
         num(r["replay_cycles"], ","), num(r["ratio"], ".3f")] for r in rows])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", default=",".join(n for n in RUNS if n not in FULL),
                    help="comma-separated run names, or 'full' (the full-size frames, each "
                    "checked against Embree): " + ", ".join(RUNS))
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    names = FULL if a.runs == "full" else [n for n in a.runs.split(",") if n]
    if unknown("replay_vs_unit", "run", names, RUNS):
        return 2
    return run_all([(n, lambda n=n: run(n)) for n in names], lambda r: f"ratio {r['ratio']}",
                   table, a.json)


if __name__ == "__main__":
    sys.exit(main())
