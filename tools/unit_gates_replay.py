#!/usr/bin/env python3
"""The RT unit's gate netlist driven by its RTL runs (docs/rtunit_rtl.md#energy): a frame of
random rays over a random triangle soup, split into runs of ``--per-run`` rays, each run through
the RTL unit with its ports recorded, then the runs replayed on the unit's generic-gate netlist,
``--lanes`` at a time (one per gatesim lane). Prints the netlist's size, each replay's cycles,
seconds, milliseconds per simulated cycle and output mismatches (0: the netlist showed every
recorded output every cycle).

    python tools/unit_gates_replay.py                        # 4 lanes, then 64, of 16 rays each
    python tools/unit_gates_replay.py --lanes 64 --per-run 32

The netlist of the unit (RAYS 4, STACK_DEPTH 8 by default) is synthesized on first use (about
15 minutes) and cached. tools/ is not part of the installed package; this script needs a
checkout.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from driver.backends.rtunit import RtUnitBackend
from driver.core.datapath import prepare_rays
from driver.power import gatesim, unit_gates
from driver.tracer import as_bvh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.corpus import rays as corpus_rays  # noqa: E402
from support.meshes import soup  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, action="append",
                    help=f"runs replayed together, 1..{gatesim.LANES} (repeatable; default 4 "
                         "and 64)")
    ap.add_argument("--per-run", type=int, default=16, help="rays per run (default 16)")
    ap.add_argument("--rays-in-flight", type=int, default=4)
    ap.add_argument("--stack-depth", type=int, default=8)
    ap.add_argument("--triangles", type=int, default=200)
    args = ap.parse_args()
    lanes = args.lanes or [4, 64]
    if not all(1 <= n <= gatesim.LANES for n in lanes) or args.per_run < 1:
        print(f"--lanes 1..{gatesim.LANES} and --per-run >= 1", file=sys.stderr)
        return 2
    unit = RtUnitBackend(rays_in_flight=args.rays_in_flight, stack_depth=args.stack_depth,
                         mem_latency=20, compare=False)
    tris = soup(args.triangles, 1)
    o, d = corpus_rays(tris, max(lanes) * args.per_run, 3)
    bvh, rays = as_bvh(tris), prepare_rays(o, d)
    net = unit_gates.unit_netlist(unit.unit_params, progress=lambda m: print(m, file=sys.stderr))
    flops = sum(v for k, v in net.cells.items() if "DFF" in k)
    print(f"netlist: {sum(net.cells.values()):,} cells ({flops:,} flip-flops), logic depth "
          f"{net.levels}, {unit.unit_params}")
    for n in lanes:
        runs = [unit.trace_unit(bvh, rays[k * args.per_run:(k + 1) * args.per_run],
                                record=True).stimulus for k in range(n)]
        rep = unit_gates.replay(net, runs)
        longest = int(rep.cycles.max())
        print(f"{n} lanes: {n * args.per_run:,} rays, {int(np.sum(rep.cycles)):,} cycles "
              f"({longest:,} in the longest run), replay {rep.seconds:.1f} s, "
              f"{rep.seconds / (longest + unit_gates.RESET_CYCLES) * 1e3:.1f} ms per cycle, "
              f"{rep.mismatches} mismatches")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
