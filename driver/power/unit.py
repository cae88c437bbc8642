"""Energy per ray of the whole RT unit in RTL from its switching activity (``rayflex power
--backend rtunit``; docs/rtunit_rtl.md#energy), at the power flow's level ``signals``.

The design point's frame is rendered through the RT unit built with ``--trace``
(``driver.backends.rtunit``, ``activity=True``): each batch the unit traverses (one ray type: the
primary rays, a bounce's shadow rays, ...) is counted from reset until its last result, every
cycle, as the datapath's ``signals`` level counts a stream (``sim/rf_toggles.h``: bit toggles per
net, each net once). The nets are mapped to the area table's module rows (``net_rows``: the
module that drives a net), so the energy of a batch is the sum of its modules', and its energy
per ray that sum over its rays. The unit's inputs, driven by the harness, weigh 0.

The check: the datapath's row against the datapath alone, the ``signals`` energy per operation
(``run.measure``: random back-to-back streams, the same traced nets) times the batch's
operations. They differ by what the streams cannot have: the traversal's operands (a box node's
children lie close together, the ray is the same for every request of the ray) and the
pipeline's bubbles (a request's values stay in the registers until the next).
"""

from __future__ import annotations

import time

from ..backends import backend
from ..backends.rtunit import UNIT_BACKEND, UNIT_ROWS
from ..core.layout import FORMATS
from ..core.provenance import provenance
from ..render import render
from . import activity, stimulus
from .run import DEFAULT_OPS, IDLE_CYCLES, measure

LEVEL, UNIT = "signals", "bit toggles"


def datapath_ops(point, n: int = DEFAULT_OPS, seed: int = 0) -> dict:
    """Energy per operation of the point's datapath alone at level signals with every net traced
    as the unit's model traces it: {op: energy_per_op} for its box, triangle and transform."""
    params = point.rtl_params()
    q8 = FORMATS[point.bvh_format].compressed
    ops = [stimulus.box_op(params, q8), "triangle"] + (["transform"] if point.transform_op
                                                         else [])
    res = measure(activity.SignalModel(params, every_net=True), params, n, seed, ops=ops)
    return {"box": res[ops[0]]["energy_per_op"], "box_op": ops[0],
            "triangle": res["triangle"]["energy_per_op"],
            "transform": res["transform"]["energy_per_op"] if point.transform_op else None}


def _row(stats: dict, per_op: dict) -> dict:
    """One ray type's (or the frame's) figures from its statistics (``unit_rtl.activity``)."""
    unit = stats["unit_rtl"]
    act = unit["activity"]
    rays = int(stats["rays"])
    xf = int(stats.get("transform_ops") or 0)
    energy = sum(act["toggles"].values())
    modules = {m: {"energy_per_ray": v / rays if rays else 0.0,
                   "share": v / energy if energy else 0.0}
               for m, v in act["toggles"].items()}
    alone = (stats["box_ops"] * per_op["box"] + stats["tri_ops"] * per_op["triangle"]
             + (xf * per_op["transform"] if per_op["transform"] else 0.0))
    dp = act["toggles"]["datapath"]
    return {"rays": rays, "cycles": int(unit["cycles"]), "box_ops": int(stats["box_ops"]),
            "tri_ops": int(stats["tri_ops"]), "transform_ops": xf,
            "energy": energy, "energy_per_ray": energy / rays if rays else 0.0,
            "modules": modules,
            "datapath_check": {"in_unit": dp, "alone": alone,
                               "ratio": dp / alone if alone else None}}


def measure_unit(point, n: int = DEFAULT_OPS, seed: int = 0, progress: bool = False) -> dict:
    """The report of ``rayflex power --backend rtunit`` for design point ``point``: energy per
    ray of every ray type of its frame through the unit (``per_ray``), the frame's
    (``frame``), per module, the unit's idle energy per cycle, the datapath alone's energy per
    op (``datapath_ops``) and the check of the unit's datapath row against it."""
    t0 = time.perf_counter()
    be = backend(UNIT_BACKEND, **{**point.backend_options(UNIT_BACKEND), "compare": False},
                 activity=True)
    idle = be.idle_activity(IDLE_CYCLES)
    per_op = datapath_ops(point, n, seed)
    res = render(point.scene, point.size, point.size, backend=be, progress=progress,
                 point=point)
    stats = res.stats
    types = stats.get("by_type") or {"primary": stats}
    idle_total = sum(idle["toggles"].values())
    return {
        "provenance": provenance(point), "level": LEVEL, "unit": UNIT, "backend": UNIT_BACKEND,
        "unit_params": be.unit_params, "nets": idle["nets"],
        "ops_per_type": n, "stimulus_seed": seed,
        "idle_per_cycle": {"energy": idle_total / idle["cycles"], "cycles": idle["cycles"],
                           "modules": {m: v / idle["cycles"]
                                       for m, v in idle["toggles"].items()}},
        "datapath_ops": per_op,
        "per_ray": {kind: _row(s, per_op) for kind, s in types.items()},
        "frame": _row(stats, per_op),
        "seconds": round(time.perf_counter() - t0, 1),
    }


def markdown(rep: dict) -> str:
    """The energy per ray of each ray type per module, and the datapath check."""
    dp = rep["provenance"]["design_point"]
    u = rep["unit_params"]
    kinds = list(rep["per_ray"]) + (["frame"] if len(rep["per_ray"]) > 1 else [])
    rows = {**rep["per_ray"], "frame": rep["frame"]}
    lines = [f"Energy per ray of the RT unit ({rep['unit']}, level {rep['level']}) of "
             f"{dp['scene']} {dp['workload']} (size {dp['size'] or 'of the scene'}, spp "
             f"{dp['spp']}); RAYS {u['RAYS']}, STACK_DEPTH {u['STACK_DEPTH']}, DIVIDERS "
             f"{u['DIVIDERS']}, {dp['config']}:", "",
             "| module | " + " | ".join(kinds) + " |", "|---|" + "---:|" * len(kinds)]
    for m in UNIT_ROWS:
        if not any(rows[k]["modules"][m]["energy_per_ray"] for k in kinds):
            continue
        lines.append(f"| {m} | " + " | ".join(
            f"{rows[k]['modules'][m]['energy_per_ray']:,.0f} "
            f"({rows[k]['modules'][m]['share']:.1%})" for k in kinds) + " |")
    lines += ["| total | " + " | ".join(f"{rows[k]['energy_per_ray']:,.0f}" for k in kinds)
              + " |",
              "| rays | " + " | ".join(f"{rows[k]['rays']:,}" for k in kinds) + " |",
              "| cycles per ray | " + " | ".join(
                  f"{rows[k]['cycles'] / rows[k]['rays']:.2f}" if rows[k]["rays"] else "–"
                  for k in kinds) + " |",
              "| datapath in the unit / alone | " + " | ".join(
                  f"{rows[k]['datapath_check']['ratio']:.3f}"
                  if rows[k]["datapath_check"]["ratio"] else "–" for k in kinds) + " |",
              "", f"idle: {rep['idle_per_cycle']['energy']:,.1f} {rep['unit']} per cycle; "
              f"datapath alone per op: {rep['datapath_ops']['box_op']} "
              f"{rep['datapath_ops']['box']:,.0f}, triangle {rep['datapath_ops']['triangle']:,.0f}"]
    return "\n".join(lines)
