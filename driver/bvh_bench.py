"""BVH build benchmark: build time, peak memory and tree quality (``bvh_bench()`` -> JSON dict).

Big meshes are instanced bunnies (``instanced_bunnies``). Each build runs in a fresh process
(multiprocessing "spawn") so that its peak resident memory (``ru_maxrss``) is its own; the
figure includes the interpreter, numpy and numba (~150 MB). ``build_s`` is wall time,
``build_cpu_s`` the process CPU time (all threads; on a shared machine the steadier figure), and
``load_average`` the machine's 1-minute load when the build ended. Tree quality before/after compares
the greedy collapse with the SAH collapse on the bunny, by SAH cost and by the ops per ray of the
bunny's 256 x 256 primary frame traced on the golden model, and checks that both trees find the
same closest hits.
"""

from __future__ import annotations

import os
import multiprocessing
import resource
import sys
import time

import numpy as np

BUNNY_TRIANGLES = 99_785


def instanced_bunnies(count: int, seed: int = 0) -> np.ndarray:
    """``count`` copies of the Stanford bunny (``driver.builtins.instanced_bunnies``)."""
    from .builtins import instanced_bunnies as grid
    from .scene import load
    return grid(load("bunny").triangles, count, seed)


def _build_child(count, conn):
    """In a fresh process: build ``count`` bunnies (0 = the bunny itself) and send the numbers."""
    from .bvh4 import build
    from .scene import load
    tris = instanced_bunnies(count) if count else load("bunny")
    build(load("bunny"), progress=False)        # load the compiled kernels before timing
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    cpu0 = time.process_time()
    bvh = build(tris, progress=None)
    cpu = time.process_time() - cpu0
    s = bvh.stats
    conn.send({"triangles": s["tri_nodes"], "build_s": round(s["build_s"], 3),
               "build_cpu_s": round(cpu, 3), "load_average": round(os.getloadavg()[0], 2),
               "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
               "rss_before_mb": round(rss0 / 1024, 1), "box_nodes": s["box_nodes"],
               "sah_cost": round(s["sah_cost"], 4)})
    conn.close()


def _timed_build(count: int) -> dict:
    ctx = multiprocessing.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_build_child, args=(count, send))
    proc.start()
    send.close()
    try:
        result = recv.recv()
    except EOFError:
        raise OSError(f"BVH build of {count} bunnies died (exit code {proc.join() or proc.exitcode})")
    proc.join()
    return result


def _quality(size: int = 256) -> dict:
    """Greedy vs SAH collapse on the bunny frame (golden model): tree and ops per ray."""
    from .bvh4 import build
    from .camera import primary_rays
    from .scene import load_scene
    from .tracer import trace
    scene = load_scene("bunny")
    o, d = primary_rays(scene.camera, size, size)
    out, traces = {}, {}
    for collapse in ("greedy", "sah"):
        bvh = build(scene.mesh, collapse=collapse)
        r = trace(bvh, o, d, backend="golden")
        s = bvh.stats
        traces[collapse] = r
        out[collapse] = {"box_nodes": s["box_nodes"], "avg_children": round(s["avg_children"], 4),
                         "child_histogram": s["child_histogram"], "depth": s["depth"],
                         "sah_cost": round(s["sah_cost"], 4), "bytes": s["bytes"],
                         "box_ops_per_ray": round(float(r.box_ops.mean()), 4),
                         "tri_ops_per_ray": round(float(r.tri_ops.mean()), 4),
                         "ops_per_ray": round(float((r.box_ops + r.tri_ops).mean()), 4)}
    a, b = traces["greedy"], traces["sah"]
    both = a.hit & b.hit
    out["same_hits"] = {
        "rays": int(len(a.hit)), "hits": int(a.hit.sum()),
        "hit_mismatch": int((a.hit != b.hit).sum()),
        "prim_mismatch": int((a.prim[both] != b.prim[both]).sum()),
        "prim_mismatch_same_t": int(((a.prim != b.prim) & both & (a.t == b.t)).sum())}
    out["ops_ratio"] = round(out["sah"]["ops_per_ray"] / out["greedy"]["ops_per_ray"], 4)
    return out


def bvh_bench(counts=(0, 20, 50), quality: bool = True, size: int = 256,
              progress: bool = True) -> dict:
    """The benchmark as a dict: ``builds`` (one entry per mesh: 0 = the bunny, k = k instanced
    bunnies, i.e. ~2 M for 20 and ~5 M for 50) and ``quality`` (``_quality`` on the bunny's
    size x size primary frame)."""
    from tqdm import tqdm
    result = {"machine_cpus": multiprocessing.cpu_count(), "builds": []}
    for count in tqdm(counts, desc="BVH bench", disable=not progress, file=sys.stderr):
        t0 = time.perf_counter()
        entry = {"bunnies": count or 1, **_timed_build(count)}
        entry["process_wall_s"] = round(time.perf_counter() - t0, 2)
        result["builds"].append(entry)
    if quality:
        result["quality"] = _quality(size)
    return result
