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
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from driver.backends.rtunit import RtUnitBackend  # noqa: E402
from driver.core import outputs  # noqa: E402
from driver.design import DesignPoint  # noqa: E402
from driver.render import render  # noqa: E402

FIXED = 20            # the fixed-latency memory's cycles
# name: (scene, workload, size, point options, rays in flight, stack depth, memory)
RUNS = {
    "bunny-primary": ("bunny", "primary", 64, {}, 64, 32, "hierarchy"),
    "bunny-primary-stack8": ("bunny", "primary", 64, {}, 64, 8, "hierarchy"),
    "bunny-primary-rif8": ("bunny", "primary", 64, {}, 8, 32, "hierarchy"),
    "bunny-primary-fixed": ("bunny", "primary", 64, {}, 64, 32, "fixed"),
    "cornell-ao-16": ("cornell", "ao", 16, {}, 8, 32, "hierarchy"),
    "cornell-ao-16-fixed": ("cornell", "ao", 16, {}, 8, 32, "fixed"),
    "cornell-ao-32": ("cornell", "ao", 32, {}, 64, 32, "hierarchy"),
    "cornell-ao-32-stack8": ("cornell", "ao", 32, {}, 64, 8, "hierarchy"),
    "bunny_floor-path-32": ("bunny_floor", "path", 32, {"spp": 1, "bounces": 2}, 64, 32,
                            "hierarchy"),
}


def run(name: str) -> dict:
    scene, workload, size, opts, rif, depth, mem = RUNS[name]
    point = DesignPoint(workload=workload, **opts)
    be = RtUnitBackend(rays_in_flight=rif, stack_depth=depth, mem_latency=FIXED,
                       memory=point.memory().config() if mem == "hierarchy" else None)
    t0 = time.perf_counter()
    res = render(scene, size, size, backend=be, progress=False, point=point)
    u = res.stats["unit_rtl"]
    return {"run": name, "scene": scene, "workload": workload, "size": size,
            "rays_in_flight": rif, "stack_depth": depth, "memory": mem,
            "ops": res.stats["ops"], "unit_cycles": u["cycles"],
            "replay_cycles": u["replay_cycles"], "ratio": u["replay_cycles_ratio"],
            "default_cycles": u["replay_default_cycles"],
            "default_ratio": u["replay_default_cycles_ratio"],
            "mismatches": u["traversal_mismatches"], "divider_full_cycles":
            u["divider_full_cycles"], "stack_overflows": u["stack_overflows"],
            "wall_s": time.perf_counter() - t0}


def table(rows: list[dict]) -> str:
    head = ("| run | rays in flight | stack | memory | ops | unit cycles | replay, default "
            "costs | ratio | replay, unit costs | ratio |\n|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]

    def num(v, fmt):
        return "—" if v is None else format(v, fmt)
    for r in rows:
        lines.append(f"| {r['run']} | {r['rays_in_flight']} | {r['stack_depth']} | "
                     f"{r['memory']} | {r['ops']:,} | {r['unit_cycles']:,} | "
                     f"{num(r['default_cycles'], ',')} | {num(r['default_ratio'], '.3f')} | "
                     f"{num(r['replay_cycles'], ',')} | {num(r['ratio'], '.3f')} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", default=",".join(RUNS), help="comma-separated run names: "
                    + ", ".join(RUNS))
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    names = [n for n in a.runs.split(",") if n]
    bad = [n for n in names if n not in RUNS]
    if bad:
        print(f"replay_vs_unit: unknown run {bad[0]!r}; choose from {', '.join(RUNS)}",
              file=sys.stderr)
        return 2
    rows = []
    for n in names:
        print(f"  {n} ...", file=sys.stderr, flush=True)
        rows.append(run(n))
        r = rows[-1]
        print(f"  {n}: ratio {r['ratio']} ({r['wall_s']:.1f} s)", file=sys.stderr, flush=True)
    print(table(rows))
    if a.json:
        outputs.write_json({"runs": rows}, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
