#!/usr/bin/env python3
"""The FUSED datapath's effect on hits (docs/tradeoffs.md#forgoing-rounding): every ray of each
run's frame, as today's datapath traces it, traced again on the FUSED datapath (the box slab value
and the triangle's edge functions rounded once); each ray whose answer changes (closest-hit rays:
the primitive; any-hit rays: occluded or not) is adjudicated with exact arithmetic
(``driver.adjudicate``: the fused answer as ours, today's as the other). A ``datapath_wrong`` ray
means the fused datapath misses a hit it must report or reports one it must not (watertightness).

    python tools/fused_study.py --lumibench-root DIR --json fused.json   # the table on stdout
    python tools/fused_study.py --lumibench-root DIR --scenes BATH --workloads ao --size 32

Runs: LumiBench's runs that the root can make (``rayflex suite lumibench``'s), each at its size
and samples unless ``--size``/``--spp`` say otherwise. Both datapaths are the golden model
(``--backend golden``, bit-exact with the RTL of each build) or the RTL (``--backend rtl``).
Rays of later bounces are today's (a changed hit would change the rays after it): each ray is
compared on its own. Progress on stderr; the outputs are written all or nothing. tools/ is not
part of the installed package; this script needs a checkout.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from driver import backend as make_backend  # noqa: E402
from driver.scenes import lumibench as lb  # noqa: E402
from driver.adjudicate import adjudicate  # noqa: E402
from driver.check import _scale  # noqa: E402
from driver.core import outputs  # noqa: E402
from driver.core.provenance import provenance  # noqa: E402
from driver.design import DesignPoint  # noqa: E402
from driver.scenes.scene import load_scene  # noqa: E402
from driver.suite import SuiteError, check_runs, lumibench_runs  # noqa: E402
from driver.tracer import trace  # noqa: E402
from driver.workloads import run as run_workload, setup_for  # noqa: E402

CLASSES = ("agree", "edge_tie", "embree_wrong", "datapath_wrong")


def compare_batch(bvh, batch, fused_be, tri, double_sided: bool) -> dict:
    """One wavefront traced again on the fused datapath: rays, changed, and the verdicts."""
    r = batch.result
    f = trace(bvh, batch.origins, batch.dirs, backend=fused_be, extent=batch.extent,
              any_hit=batch.any_hit, double_sided=double_sided)
    changed = np.flatnonzero((f.hit != r.hit) if batch.any_hit else (f.prim != r.prim))
    counts = dict.fromkeys(CLASSES, 0)
    records = []
    if len(changed):
        v = adjudicate(tri, batch.origins, batch.dirs, batch.extent, (f.t, f.prim), (r.t, r.prim),
                       batch.any_hit, double_sided, _scale(tri, batch.origins), rays=changed,
                       emb_occluded=r.hit if batch.any_hit else None)
        counts = v.counts()
        counts["agree"] -= len(batch.origins) - len(changed)      # only the changed rays
        records = [{k: (float(x) if isinstance(x, (np.floating, float)) else
                        int(x) if isinstance(x, (np.integer, int)) else x)
                    for k, x in rec.items()} for rec in v.records]
    return {"rays": int(len(batch.origins)), "changed": int(len(changed)),
            "hit_changed": int((f.hit != r.hit).sum()),
            "t_changed": int((f.hit & r.hit & (f.t != r.t)).sum()), "classes": counts,
            "records": records[:8]}


def study_run(run, point, root, backend: str, say) -> dict:
    t0 = time.perf_counter()
    with lb.using_root(root):
        scene = load_scene(point.scene)
    bvh = point.build(scene)
    setup = setup_for(scene)
    tri = setup.triangles
    if hasattr(tri, "instances"):
        raise SuiteError(f"run {run.name}: an instanced scene (the study adjudicates flat "
                         "triangle lists)")
    today = make_backend(backend, **point.backend_options())
    fused = make_backend(backend, **point.backend_options(), fused=True)
    tracer = partial(trace, backend=today)
    fr = run_workload(setup, bvh, point.size, point.size, tracer, point.workload,
                      **point.workload_options())
    out = {"rays": 0, "changed": 0, "hit_changed": 0, "t_changed": 0,
           "classes": dict.fromkeys(CLASSES, 0), "by_type": {}, "records": []}
    for b in fr.batches:
        part = compare_batch(bvh, b, fused, tri, setup.double_sided)
        kind = out["by_type"].setdefault(b.kind, {"rays": 0, "changed": 0, "hit_changed": 0})
        for k in ("rays", "changed", "hit_changed"):
            kind[k] += part[k]
        for k in ("rays", "changed", "hit_changed", "t_changed"):
            out[k] += part[k]
        for c in CLASSES:
            out["classes"][c] += part["classes"][c]
        out["records"] += [{"ray_type": b.kind, **rec} for rec in part["records"]]
    out["records"] = out["records"][:16]
    out["seconds"] = round(time.perf_counter() - t0, 1)
    say(f"{run.name}: {out['rays']:,} rays, {out['changed']} changed "
        f"({out['classes']['datapath_wrong']} datapath_wrong) in {out['seconds']} s")
    return out


def markdown(doc: dict) -> str:
    rows = ["| run | rays | hits changed | of them hit/miss | edge ties | today's wrong | "
            "fused wrong |", "|---|---:|---:|---:|---:|---:|---:|"]
    for name, r in doc["runs"].items():
        c = r["classes"]
        rows.append(f"| {name} | {r['rays']:,} | {r['changed']:,} | {r['hit_changed']:,} | "
                    f"{c['edge_tie']:,} | {c['embree_wrong']:,} | {c['datapath_wrong']:,} |")
    t = doc["total"]
    c = t["classes"]
    rows.append(f"| **all** | {t['rays']:,} | {t['changed']:,} | {t['hit_changed']:,} | "
                f"{c['edge_tie']:,} | {c['embree_wrong']:,} | {c['datapath_wrong']:,} |")
    return "\n".join(rows) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="tools/fused_study.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--lumibench-root", help="a clone of LumiBench (default: $LUMIBENCH_ROOT)")
    p.add_argument("--scenes", help="these scene IDs only (e.g. BATH,SHIP)")
    p.add_argument("--workloads", help="these shaders only (pt, sh, ao)")
    p.add_argument("--size", type=int, help="every run's frame N x N (default: the suite's)")
    p.add_argument("--spp", type=int, help="every run's samples per pixel (default: the suite's)")
    p.add_argument("--config", default="baseline-unified",
                   help="today's configuration (the study adds -fused); default baseline-unified")
    p.add_argument("--backend", default="golden", choices=("golden", "rtl"))
    p.add_argument("--json", metavar="PATH", help="write the per-run counts as JSON")
    args = p.parse_args(argv)
    try:
        runs, skipped = lumibench_runs(args.lumibench_root,
                                       args.scenes.split(",") if args.scenes else None,
                                       args.workloads.split(",") if args.workloads else None)
        if not runs:
            raise SuiteError("no LumiBench run can be made: "
                             + "; ".join(f"{k}: {v}" for k, v in skipped.items()))
        base = DesignPoint(config=args.config)
        if base.fused:
            raise SuiteError(f"--config {args.config}: give today's configuration, not a fused "
                             "one (the study compares it with its -fused build)")
        runs = [replace(r, size=args.size or r.size, spp=args.spp or r.spp) for r in runs]
        with lb.using_root(args.lumibench_root):
            points = check_runs(runs, base)
        outs = outputs.Outputs()
        js = outs.add("--json", args.json, outputs.JSON) if args.json else None
    except (SuiteError, ValueError, outputs.OutputError) as e:
        print(f"fused_study: {e}", file=sys.stderr)
        return 2

    def say(msg):
        print(msg, file=sys.stderr, flush=True)

    done = {}
    try:
        for i, (run, point) in enumerate(zip(runs, points)):
            say(f"[{i + 1}/{len(runs)}] {run.name} {point.size}x{point.size} spp {point.spp}")
            done[run.name] = study_run(run, point, args.lumibench_root, args.backend, say)
    except KeyboardInterrupt:
        say("fused_study: interrupted (nothing written)")
        return 130
    total = {k: sum(r[k] for r in done.values()) for k in ("rays", "changed", "hit_changed",
                                                          "t_changed")}
    total["classes"] = {c: sum(r["classes"][c] for r in done.values()) for c in CLASSES}
    doc = {"provenance": provenance(points[0]), "config": args.config,
           "fused": args.config + "-fused", "backend": args.backend, "runs": done,
           "skipped": skipped, "total": total}
    if js is not None:
        with outs.commit():
            outputs.write_json(doc, outs.temp(js))
    print(markdown(doc), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
