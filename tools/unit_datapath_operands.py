#!/usr/bin/env python3
"""Why the RT unit's datapath switches less than the datapath alone predicts
(docs/rtunit_rtl.md#energy): a frame's own datapath requests streamed through the datapath alone
at level signals, with the nets the traced unit counts, in three samples of 3,000 requests each:
consecutive requests in the traversal's (wavefront) order, requests drawn at random in frame
order, and requests drawn at random in random order. Prints the energy per op of each (bit
toggles, the pipeline's fill and drain included: 11 of 3,011 cycles).

    python tools/unit_datapath_operands.py                  # the bunny, 64 x 64 primary rays
    python tools/unit_datapath_operands.py --scene cornell --size 32

tools/ is not part of the installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse

import numpy as np

from driver.core.layout import NodeRef
from driver.core.wire import pack_requests
from driver.design import DesignPoint
from driver.power import activity
from driver.scenes.camera import primary_rays
from driver.scenes.scene import load_scene
from driver.tracer import trace

SAMPLE = 3000


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="bunny")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    point = DesignPoint(scene=args.scene, size=args.size)
    scene = point.scene_of(load_scene(args.scene))
    o, d = primary_rays(scene.camera, args.size, args.size)
    rec = trace(scene, o, d, backend="rtl", record=True).record
    words = pack_requests(rec.requests())
    is_box = NodeRef.is_box(np.asarray(rec.ptr))
    model = activity.SignalModel(point.rtl_params(), every_net=True)
    rng = np.random.default_rng(args.seed)
    n = min(SAMPLE, len(words))
    start = max(0, len(words) // 4 - n // 2)
    print(f"{args.scene} {args.size}x{args.size} primary: {len(words):,} requests "
          f"({int(is_box.sum()):,} box)")
    for name, idx in (("consecutive, traversal order", np.arange(start, start + n)),
                      ("random, frame order", np.sort(rng.choice(len(words), n, replace=False))),
                      ("random, random order", rng.choice(len(words), n, replace=False))):
        cycles, toggles = model.run(words[idx])
        energy = float(toggles @ model.weight)
        print(f"{name}: {n:,} ops ({int(is_box[idx].sum()):,} box), {cycles:,} cycles, "
              f"{energy / n:,.0f} bit toggles per op")


if __name__ == "__main__":
    main()
