"""``rayflex bench --end-to-end``: a design point's frame as ``rayflex render --check-embree
--rtunit`` runs it (``--backend rtunit``: as ``rayflex render --check-embree --backend rtunit``
runs it), timed run by run (docs/lumibench.md, docs/rtunit_rtl.md).

Each run is a fresh Python process (``python -m driver.frame_bench POINT_JSON BACKEND``), as a
user's render is: it imports the tool, loads the scene (from the scene cache once a first run
has filled it), builds or loads the BVH, traces every ray on the RTL, checks every ray against
Embree and replays the frame on the design point's RT units (on the RT unit in RTL: the unit
traces and times the frame, and ``--unit-check`` says what checks it besides Embree); it reports
the render's wall time (``wall_s``: BVH, tracing, replay, check) split into the BVH and the rest,
the functional pass (the unit's simulation) and the replay as the statistics give them, the
verdicts of the check, and the process's peak memory. A first run that is not counted fills the caches (scene, BVH, Verilated model), so the
counted runs measure what every later run of the frame costs. ``rays_per_s`` is the frame's rays
over its wall time outside loading and the BVH (``trace_s``); the summary gives the minimum,
median and maximum over the counted runs.
"""

from __future__ import annotations

import time

_T_MODULE = time.time()         # before this module's imports: the tool's import time

import json  # noqa: E402
import os  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402

from .backends.rtunit import UNIT_BACKEND  # noqa: E402
from .core.progress import phase as show  # noqa: E402
from .design import DesignPoint  # noqa: E402
from .load_bench import fresh_process  # noqa: E402
from .render import render  # noqa: E402
from .scenes.scene import load_scene  # noqa: E402

# the figures of a run that the summary gives as minimum, median and maximum
SUMMARISED = ("rays_per_s", "trace_s", "wall_s", "functional_s", "replay_s", "process_s")


def run_frame(point_json: str, backend: str = "rtl") -> dict:
    """One run in this process (module docstring) on ``backend``: "rtl" (the Python traversal on
    the RTL datapath, replayed) or "rtunit" (the RT unit in RTL)."""
    t_start = float(os.environ.get("RAYFLEX_T0", time.time()))
    point = DesignPoint(**json.loads(point_json))
    t_imp = time.time()
    scene = load_scene(point.scene)
    t_load = time.time()
    unit = backend == UNIT_BACKEND
    res = render(scene, point.size, point.size, backend=backend, progress=False,
                 check_embree=True, point=point, rtunit=not unit)
    t_end = time.time()
    s = res.stats
    bvh_s = float(s["bvh"].get("build_s", 0.0))
    trace_s = s["wall_s"] - bvh_s
    verdicts = s["embree"]["adjudicated"]["classes"]
    return {"rays": int(s["rays"]), "ops": int(s["ops"]), "wall_s": s["wall_s"],
            "bvh_s": bvh_s, "trace_s": trace_s, "rays_per_s": s["rays"] / trace_s,
            "functional_s": s["wavefront"]["sim_wall_s"],
            "replay_s": None if unit else s["rtunit_memory"]["sim_wall_s"],
            "replay_datapath": None if unit else s["rtunit_memory"]["replay_datapath"],
            "unit_cycles": s["unit_rtl"]["cycles"] if unit else None,
            "traversal_mismatches": s["unit_rtl"]["traversal_mismatches"] if unit else None,
            "import_s": t_imp - min(_T_MODULE, t_start), "load_s": t_load - t_imp,
            "process_s": t_end - t_start, "verdicts": verdicts,
            "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}


def end_to_end(point, repeat: int, progress: bool = True, backend: str = "rtl") -> dict:
    """``repeat`` counted runs of ``point``'s frame on ``backend`` ("rtl" or "rtunit") after one
    that fills the caches, each in a fresh process; returns every run and the ``SUMMARISED``
    figures' minimum, median and maximum (None for a figure the backend has not: the replay's
    on the RT unit in RTL)."""
    text = json.dumps(point.as_dict())
    with show(f"first run of {point.scene} {point.workload} (fills the caches)", progress):
        first = fresh_process("driver.frame_bench", [text, backend], "end-to-end run")
    runs = []
    for k in range(repeat):
        with show(f"run {k + 1} of {repeat}", progress):
            runs.append(fresh_process("driver.frame_bench", [text, backend], "end-to-end run"))
    summary = {}
    for key in SUMMARISED:
        vals = [r[key] for r in runs if r[key] is not None]
        summary[key] = ({"min": min(vals), "median": statistics.median(vals), "max": max(vals)}
                        if vals else None)
    how = (f"--backend {UNIT_BACKEND} --unit-check {point.unit_check}"
           if backend == UNIT_BACKEND else "--rtunit")
    return {"command": (f"rayflex render {point.scene} --workload {point.workload} --size "
                        f"{point.size} --spp {point.spp} --check-embree {how}"
                        + (" --cull-stack" if point.cull_stack else "")),
            "backend": backend, "first_run": first, "runs": runs, "summary": summary}


if __name__ == "__main__":
    print(json.dumps(run_frame(*sys.argv[1:3])))
