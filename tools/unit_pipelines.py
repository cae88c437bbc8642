#!/usr/bin/env python3
"""The RT unit in RTL with 1, 2 and 4 datapath pipelines (docs/rtunit_rtl.md#several-pipelines):
each frame traced through ``--backend rtunit`` with ``--pipelines`` P, every ray checked against
the Python traversal and the replay with the unit's costs run on the same parameters; printed as
a Markdown table (cycles, utilization per pipeline, the node fetches per cycle,
the replay's ratio).

    python tools/unit_pipelines.py                          # every frame, P = 1, 2, 4
    python tools/unit_pipelines.py --frames bunny-64 --pipelines 1,2 --json pipes.json

Each frame names its scene, workload and size; 64 rays in flight, stack depth 32, 2 dividers,
and the memory: the default design point's hierarchy (32 KiB 4-way L1, DRAM latency 200 at
32 B/cycle) or a fixed latency of 20 cycles. Progress on stderr; the JSON is written all or
nothing. tools/ is not part of the installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from unit_runs import render_unit, run_all, unknown  # noqa: E402

from driver.core.markdown import table as md_table  # noqa: E402

RAYS_IN_FLIGHT, STACK_DEPTH = 64, 32
# name: scene, workload, size, memory
FRAMES = {
    "bunny-64": ("bunny", "primary", 64, "hierarchy"),
    "cornell-ao-32": ("cornell", "ao", 32, "hierarchy"),
    "bunny-64-fixed": ("bunny", "primary", 64, "fixed"),
    "cornell-ao-32-fixed": ("cornell", "ao", 32, "fixed"),
}


def run(name: str, pipelines: int) -> dict:
    scene, workload, size, mem = FRAMES[name]
    res, wall = render_unit(scene, workload, size, RAYS_IN_FLIGHT, STACK_DEPTH, mem,
                            pipelines=pipelines)
    u = res.stats["unit_rtl"]
    return {"frame": name, "scene": scene, "workload": workload, "size": size, "memory": mem,
            "pipelines": pipelines, "rays": res.stats["rays"], "ops": res.stats["ops"],
            "cycles": u["cycles"], "utilization": u["utilization"],
            "pipeline_utilization": u["pipeline_utilization"],
            "ops_per_cycle": res.stats["ops"] / u["cycles"],
            "mem_requests": u["mem_requests"], "divider_full_cycles": u["divider_full_cycles"],
            "mismatches": u["traversal_mismatches"], "replay_cycles": u["replay_cycles"],
            "ratio": u["replay_cycles_ratio"], "wall_s": wall}


def table(rows: list[dict]) -> str:
    head = ["frame", "memory", "pipelines", "ops", "cycles", "vs 1 pipeline", "ops per cycle",
            "utilization per pipeline", "node fetches per cycle", "both dividers busy",
            "rays ≠ traversal", "replay, unit costs", "ratio"]
    lines = []
    base = {}
    for r in rows:
        base.setdefault((r["frame"]), r["cycles"] if r["pipelines"] == 1 else None)
        one = base.get(r["frame"])
        util = ", ".join(f"{u:.3f}" for u in r["pipeline_utilization"])
        fetches = r["mem_requests"] / r["cycles"]
        lines.append([f"{r['scene']} {r['size']}², {r['workload']}", r["memory"],
                      str(r["pipelines"]), f"{r['ops']:,}", f"{r['cycles']:,}",
                      "—" if not one else format(r["cycles"] / one, ".3f"),
                      f"{r['ops_per_cycle']:.3f}", util, f"{fetches:.3f}",
                      f"{r['divider_full_cycles']:,}", str(r["mismatches"]),
                      f"{r['replay_cycles']:,}", f"{r['ratio']:.3f}"])
    return md_table(head, lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", default=",".join(FRAMES),
                    help="comma-separated frame names: " + ", ".join(FRAMES))
    ap.add_argument("--pipelines", default="1,2,4", help="comma-separated pipeline counts")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    names = [n for n in a.frames.split(",") if n]
    if unknown("unit_pipelines", "frame", names, FRAMES):
        return 2
    try:
        counts = [int(p) for p in a.pipelines.split(",") if p]
    except ValueError:
        print(f"unit_pipelines: --pipelines {a.pipelines!r}: give whole numbers",
              file=sys.stderr)
        return 2
    return run_all([(f"{n}, {p} pipelines", lambda n=n, p=p: run(n, p))
                    for n in names for p in counts],
                   lambda r: f"{r['cycles']:,} cycles, ratio {r['ratio']:.4f}", table, a.json)


if __name__ == "__main__":
    sys.exit(main())
