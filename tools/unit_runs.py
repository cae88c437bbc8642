"""What the RT-unit tools share (tools/replay_vs_unit.py, tools/unit_pipelines.py): one frame
through the RT unit in RTL (``--backend rtunit``, the replay run on the same parameters), and the
run of the named frames: one progress line each on stderr before and after, their Markdown table
on stdout, the rows as JSON written all or nothing. tools/ is not part of the installed package;
these scripts need a checkout."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Callable

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from driver.backends.rtunit import RtUnitBackend  # noqa: E402
from driver.core import outputs  # noqa: E402
from driver.design import DesignPoint  # noqa: E402
from driver.render import RenderResult, render  # noqa: E402

FIXED = 20            # the fixed-latency memory's cycles


def render_unit(scene: str, workload: str, size: int, rays_in_flight: int, stack_depth: int,
                memory: str, point: dict | None = None, check_embree: bool = False,
                **unit) -> tuple[RenderResult, float]:
    """Render a size² frame of ``scene`` and ``workload`` through the RT unit in RTL with
    ``rays_in_flight`` slots, stacks of ``stack_depth`` and ``memory`` ("hierarchy": the design
    point's; "fixed": FIXED cycles); ``point``: DesignPoint options of the frame and its
    datapath; ``unit``: further RtUnitBackend options (dividers, pipelines). Returns the result
    and its wall seconds."""
    dp = DesignPoint(workload=workload, **(point or {}))
    be = RtUnitBackend(rays_in_flight=rays_in_flight, stack_depth=stack_depth, mem_latency=FIXED,
                       memory=dp.memory().config() if memory == "hierarchy" else None,
                       **unit, **dp.backend_options())
    t0 = time.perf_counter()
    res = render(scene, size, size, backend=be, progress=False, point=dp,
                 check_embree=check_embree)
    return res, time.perf_counter() - t0


def unknown(prog: str, what: str, names: list[str], known) -> bool:
    """Whether a name is not one of ``known``; if so, say which (one line on stderr)."""
    bad = [n for n in names if n not in known]
    if bad:
        print(f"{prog}: unknown {what} {bad[0]!r}; choose from {', '.join(known)}",
              file=sys.stderr)
    return bool(bad)


def run_all(jobs: list[tuple[str, Callable[[], dict]]], done: Callable[[dict], str],
            table: Callable[[list[dict]], str], json_path: str | None) -> int:
    """Run each (label, run) in turn, a progress line before and after (``done``: what the
    second says of the row, before its wall seconds ``wall_s``); print ``table`` of the rows and
    write them to ``json_path`` as {"runs": rows}."""
    rows = []
    for label, run in jobs:
        print(f"  {label} ...", file=sys.stderr, flush=True)
        rows.append(run())
        print(f"  {label}: {done(rows[-1])} ({rows[-1]['wall_s']:.1f} s)", file=sys.stderr,
              flush=True)
    print(table(rows))
    if json_path:
        outputs.write_json({"runs": rows}, json_path)
    return 0
