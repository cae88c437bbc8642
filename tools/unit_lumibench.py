#!/usr/bin/env python3
"""LumiBench's runs through the RT unit in RTL with their instances (docs/rtunit_rtl.md,
"LumiBench's 12 runs, with their instances"): the suite at stack depth 32 and again at 8, both
with the traversal's check, and one Markdown table of the two.

    LUMIBENCH_ROOT=... python tools/unit_lumibench.py --json docs/rtunit_lumibench.json
    python tools/unit_lumibench.py --from DIR32 DIR8 --json docs/rtunit_lumibench.json

Each suite is ``rayflex suite lumibench --backend rtunit --transform datapath --workers 2
[--stack-depth 8]`` (its progress on stderr); ``--from`` reads two suites' folders made so
instead. The JSON (written all or nothing) has every run's figures at both depths and each
suite's command, commit, wall time and the load before and after. tools/ is not part of the
installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from driver.core import outputs  # noqa: E402

DEPTHS = (32, 8)
COMMAND = ("rayflex", "suite", "lumibench", "--backend", "rtunit", "--transform", "datapath",
           "--workers", "2")


def command(depth: int) -> list[str]:
    """The suite's command at stack depth ``depth`` (32: the default)."""
    return [*COMMAND, *(["--stack-depth", str(depth)] if depth != 32 else [])]


def run_suite(depth: int, out: Path) -> dict:
    """The suite at ``depth`` into ``out``: the load before and after it."""
    load0 = os.getloadavg()[0]
    subprocess.run([sys.executable, "-m", "driver.cli", *command(depth)[1:], "--out", str(out)],
                   check=True)
    return {"load": [round(load0, 2), round(os.getloadavg()[0], 2)]}


def runs_of(folder: Path) -> dict:
    """name -> the figures of each run in a suite's folder."""
    rows = {}
    for f in sorted(folder.glob("*_*.json")):
        d = json.loads(f.read_text())
        u, c = d["unit_rtl"], d["embree"]["adjudicated"]["classes"]
        rows[f.stem] = {"rays": d["rays"], "box_ops": d["box_ops"], "tri_ops": d["tri_ops"],
                        "transform_ops": d["transform_ops"], "cycles": u["cycles"],
                        "max_stack_depth": u["max_stack_depth"],
                        "stack_overflows": u["stack_overflows"],
                        "rays_overflowed": u["rays_overflowed"], "refills": u["stack_refills"],
                        "replay_cycles_ratio": u["replay_cycles_ratio"],
                        "traversal_mismatches": u["traversal_mismatches"],
                        "datapath_wrong": c["datapath_wrong"], "edge_tie": c["edge_tie"],
                        "reused_batches": u["reused_batches"]}
    return rows


def suite_of(folder: Path) -> dict:
    """A suite folder's provenance: commit and wall seconds (summary.json)."""
    s = json.loads((folder / "summary.json").read_text())
    return {"commit": s["provenance"]["git_commit"], "machine": s["provenance"]["machine"],
            "wall_s": round(s["wall_s"], 1)}


def table(doc: dict) -> str:
    """The two depths' runs side by side, as docs/rtunit_rtl.md shows them."""
    lines = ["| run | rays | box / triangle / TRANSFORM ops (both depths) | unit cycles, depth 32 "
             "| max stack depth | replay, unit costs | unit cycles, depth 8 (against 32) | stack "
             "overflows (rays), depth 8 | refills | replay, unit costs | rays ≠ traversal "
             "(32 / 8) | Embree `datapath_wrong` (32 / 8; edge ties) |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---|"]
    for name, a in doc["depth_32"].items():
        b = doc["depth_8"][name]
        lines.append(
            f"| {name} | {a['rays']:,} | {a['box_ops']:,} / {a['tri_ops']:,} / "
            f"{a['transform_ops']:,} | {a['cycles']:,} | {a['max_stack_depth']} | "
            f"{a['replay_cycles_ratio']:.4f} | {b['cycles']:,} ({b['cycles'] / a['cycles']:.4f})"
            f" | {b['stack_overflows']:,} ({b['rays_overflowed']:,}) | {b['refills']:,} | "
            f"{b['replay_cycles_ratio']:.4f} | {a['traversal_mismatches']} / "
            f"{b['traversal_mismatches']} | {a['datapath_wrong']} / {b['datapath_wrong']} "
            f"({a['edge_tie']}) |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--from", dest="folders", nargs=2, metavar=("DIR32", "DIR8"),
                    help="read the two suites' folders instead of running them")
    ap.add_argument("--json", help="write the figures here (all or nothing)")
    args = ap.parse_args(argv)
    doc, runs = {}, {}
    with tempfile.TemporaryDirectory(prefix="unit-lumibench-") as tmp:
        for depth, given in zip(DEPTHS, args.folders or (None, None)):
            folder = Path(given) if given else Path(tmp) / f"depth{depth}"
            made = None if given else run_suite(depth, folder)
            doc[f"depth_{depth}"] = runs_of(folder)
            runs[f"depth_{depth}"] = {"command": " ".join(command(depth)), **suite_of(folder),
                                      **(made or {})}
    if doc["depth_32"].keys() != doc["depth_8"].keys():
        print("unit_lumibench: the two suites made different runs", file=sys.stderr)
        return 2
    print(table(doc))
    if args.json:
        outputs.write_json({"suites": runs, **doc}, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
