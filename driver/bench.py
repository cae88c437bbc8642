"""``rayflex bench``: datapath throughput of a real frame, and how fast the simulation runs.

Runs a design point's frame (``driver.design``; default: the bunny, 256 x 256, primary rays,
baseline-unified) through the "rtl" backend. Every statistic is in the schema of
docs/statistics.md; the primary workload with one sample per pixel also measures the simulation:

- ``frame``: the frame's statistics: op counts, ``wavefront`` (the functional run: every ray in
  flight, one pipeline), ``rtunit`` (the RT-unit replay of the design point: ray pool,
  pipelines, node fetches free) and ``rtunit_memory`` (the same with its node cache and memory),
  ``embree`` (the Embree cross-check of every ray), ``wall_s`` with its parts (BVH build,
  traversal on the RTL, RT-unit replays), and ``by_type`` (the same per ray type).
- ``rtl_cycles_per_s``: datapath clock cycles per wall second of the "rtl" backend while it
  streams the frame (time inside the harness calls), the best of ``--repeat`` (3) timed passes:
  the wavefront traversal itself, then re-streams of its recorded requests in the same batches
  (responses checked equal to the traversal's). Every pass is listed in
  ``rtl_cycles_per_s_runs``. Best-of-N, as ``timeit`` does: on a shared machine other load only
  ever slows a pass down.
- ``pyverilator``: cycles per second of the cycle-by-cycle backend on a short stream of the same
  requests (the frame's first ``--pyverilator-requests``, 2,000), best of ``--repeat`` passes
  (all in ``cycles_per_s_runs``), with "rtl" timed on that same stream for reference and both
  checked against the frame's responses bit for bit; ``rtl_vs_pyverilator_speedup`` =
  rtl_cycles_per_s / pyverilator cycles per second (best against best).
- ``golden_rays_per_s``: the whole frame's traversal on the golden numpy model (rays per wall
  second; hits checked equal to the RTL's); ``embree_rays_per_s``: Embree's closest hit
  for the same rays (one cast each, Embree's own BVH build excluded and reported as
  ``embree_build_s``); ``bvh_build_s``.
- ``rtunit_sweep``: RT-unit cycles per frame, utilization and frame time at 1 GHz for every
  (pipelines, rays in flight) pair on a smaller frame of the same view (``--sweep-size``, 64),
  and one PNG plot (``--plot``): cycles per frame vs rays in flight, log x, one line per
  pipeline count. The sweep's replays run in parallel threads, one per usable core (at most 4).

Any other workload (``bench_workload``) reports the frame and per ray type the same
statistics, any-hit against closest-hit ops, and utilization over rays in flight per ray type
(``sweep``, plotted). Every document carries ``provenance`` (version, commit, design point,
machine). A short table goes to stdout, progress bars to stderr, the JSON to ``--json PATH``
(the command line is ``driver.cli.bench``).
"""

from __future__ import annotations

import time

import numpy as np

from . import backends, rtunit, tiles, workloads
from .backends import build as rtl_build
from .bench_plots import plot_rays_held, plot_workload_sweep
from .bvh4 import warm_up
from .check import compare, embree_closest, embree_json, summary
from .core.progress import bar as _bar
from .core.provenance import machine, provenance
from .core.wire import pack_responses
from .core.words import plural
from .design import DesignPoint, clock_figures
from .plotting import describe
from .rtunit.gpu import replay_point, waves_of
from .rtunit.plan import Wave
from .scenes.camera import check_size, primary_rays
from .stats import order_cost_line, public
from .tracer import trace

PYVERILATOR_REQUESTS = 2000
REPEAT = 3
SWEEP_SIZE = 64


def bench(point: DesignPoint = DesignPoint(), sweep_size=SWEEP_SIZE,
          sweep_rays=rtunit.SWEEP_RAYS_IN_FLIGHT, sweep_pipelines=rtunit.SWEEP_PIPELINES,
          plot=None, pyverilator_requests=PYVERILATOR_REQUESTS, repeat=REPEAT,
          progress=True, scene=None, ideal: bool = False) -> dict:
    """Run the benchmark of design point ``point`` (its primary frame); returns the JSON
    document (see the module docstring). ``scene``: a loaded scene instead of
    ``point.scene``."""
    from .scenes.scene import load_scene

    scene = point.scene_of(load_scene(point.scene if scene is None else scene))
    if scene.mesh is None:
        raise ValueError(f"the frame benchmark measures Embree on every triangle; scene "
                         f"{scene.name!r} is too large to flatten (bench it with --workload)")
    w, h = scene.size if point.size is None else (point.size, point.size)
    w, h = check_size(w, h)
    origins, dirs = primary_rays(scene.camera, w, h)
    n = len(origins)
    rtl = backends.backend("rtl", **point.backend_options())  # build (or load) first: fail early

    frame, res, bvh = _frame(scene, origins, dirs, rtl, point, f"{w}x{h}", progress, w, ideal)
    sided = scene.double_sided
    rec = res.record
    rtl_runs = [res.stats["sim_cycles_per_s"]]
    for _ in range(int(repeat) - 1):
        rtl_runs.append(_restream(rtl, rec, res.step_requests))
    rtl_cps = max(rtl_runs)

    # ---- Embree: rays per second and the cross-check of every hit ---------------------------
    tri = scene.triangles
    t_emb_build, t_emb = _embree_rate(tri, origins, dirs)
    emb_t, emb_prim = embree_closest(tri, origins, dirs, sided)
    frame["embree"] = embree_json(compare(res.t, res.prim, emb_t, emb_prim, tri, origins, dirs))
    frame["by_type"]["primary"]["embree"] = frame["embree"]

    t_gold, golden_same = _golden(bvh, origins, dirs, res, f"{w}x{h}", progress, point, sided)

    # ---- pyverilator on a short stream of the frame's requests --------------------------------
    pyv = None
    k = min(int(pyverilator_requests), rec.ops)
    if k:
        pyv = _pyverilator_stream(rec, k, progress, repeat, point)
    speedup = rtl_cps / pyv["cycles_per_s"] if pyv and pyv["cycles_per_s"] else None

    sweep = None
    if sweep_size:
        sweep = _sweep(scene, bvh, rtl, min(int(sweep_size), w, h), sweep_rays, sweep_pipelines,
                       plot, progress, point)

    frame["clock"] = clock_figures(point, frame)
    return {
        "provenance": provenance(point),
        "scene": scene.name,
        "width": w,
        "height": h,
        "frame": frame,
        "rtl_cycles_per_s": rtl_cps,
        "rtl_cycles_per_s_runs": rtl_runs,
        "repeat": int(repeat),
        "pyverilator": pyv,
        "rtl_vs_pyverilator_speedup": speedup,
        "golden_rays_per_s": n / t_gold if t_gold > 0 else None,
        "golden_matches_rtl": golden_same,
        "embree_rays_per_s": n / t_emb if t_emb > 0 else None,
        "embree_build_s": t_emb_build,
        "bvh_build_s": frame["wall_parts_s"]["bvh_build"],
        "rtunit_sweep": sweep,
    }


def _frame(scene, origins, dirs, rtl, point, label, progress, width, ideal=False):
    """The frame on "rtl": BVH build, wavefront traversal (recorded), the RT-unit replay (and
    with ``ideal`` the one with free node fetches). Returns (frame statistics, trace result,
    BVH)."""

    t_kernels = warm_up()                           # the builder's JIT, like the model's build
    t0 = time.perf_counter()
    bvh = point.build(scene)
    t_bvh = time.perf_counter() - t0
    bar = _bar(len(origins), f"frame {label} rtl", "ray", progress)
    t1 = time.perf_counter()
    res = trace(bvh, origins, dirs, backend=rtl, record=True, progress=bar.hook,
                cull_stack=point.cull_stack, double_sided=scene.double_sided)
    t_trace = time.perf_counter() - t1
    bar.close()
    bar = _bar(1, f"RT-unit replay R={point.rays_in_flight} P={point.pipelines}", "run",
               progress)
    t2 = time.perf_counter()
    frame = public(res.stats)
    n = res.record.rays
    rp = replay_point([Wave(res.record, "primary", np.arange(n), np.zeros(n, np.int64))], point,
                      width, ideal)
    frame["rtunit"], frame["rtunit_memory"] = rp["rtunit"], rp["rtunit_memory"]
    t_replay = time.perf_counter() - t2
    bar.hook(1, 1)
    bar.close()
    frame["by_type"] = {"primary": {**frame, **rp["by_type"]["primary"]}}
    frame["wall_s"] = time.perf_counter() - t0
    frame["wall_parts_s"] = {"bvh_build": t_bvh, "traversal": t_trace, "replay": t_replay}
    frame["bvh_kernels_s"] = t_kernels              # not in wall_s (see bvh4.warm_up)
    frame["bvh"] = dict(bvh.stats)
    frame.update(scene.counts())
    return frame, res, bvh


def _golden(bvh, origins, dirs, res, label, progress, point, double_sided):
    """The whole frame on the numpy model: (wall seconds, hits equal to the RTL's)."""
    bar = _bar(len(origins), f"frame {label} golden", "ray", progress)
    t0 = time.perf_counter()
    gold = trace(bvh, origins, dirs, backend=backends.backend("golden", **point.backend_options()),
                 progress=bar.hook, cull_stack=point.cull_stack,
                 double_sided=double_sided)
    t_gold = time.perf_counter() - t0
    bar.close()
    same = bool(np.array_equal(gold.t.view(np.uint32), res.t.view(np.uint32))
                and np.array_equal(gold.prim, res.prim))
    return t_gold, same


def _sweep(scene, bvh, rtl, ss, sweep_rays, sweep_pipelines, plot, progress, point) -> dict:
    """The RT-unit sweep (node fetches free) on a smaller frame (ss x ss) of the same view, and
    its plot."""
    so, sd = primary_rays(scene.camera, ss, ss)
    srec = trace(bvh, so, sd, backend=rtl, record=True, cull_stack=point.cull_stack,
                 double_sided=scene.double_sided).record
    pairs = len(sweep_rays) * len(sweep_pipelines)
    bar = _bar(pairs, f"RT-unit sweep {ss}x{ss}", "point", progress)
    t0 = time.perf_counter()
    points = rtunit.sweep(srec, sweep_rays, sweep_pipelines,
                          progress=lambda done, total, pt: bar.hook(done, total),
                          workers=min(4, machine()["cores_usable"] or 1))
    t_sweep = time.perf_counter() - t0
    bar.close()
    keep = ("pipelines", "rays_in_flight", "cycles", "utilization", "frame_us_at_1ghz",
            "starved_cycles", "replay_datapath", "responses_verified")
    if plot:
        rtunit.plot_sweep(points, plot, "RT-unit cycles vs rays in flight and pipelines, free "
                          "node fetches: " + describe(
                              {**point.as_dict(), "size": ss, "scene": scene.name},
                              omit=("rays_in_flight", "pipelines", "cache_kib", "mem_latency"))
                          + f"\n{srec.ops:,} datapath ops, turnaround "
                          f"{rtunit.DEFAULT_TURNAROUND} cycle")
    return {"width": ss, "height": ss, "rays": srec.rays, "ops": srec.ops,
            "latency_cycles": point.latency, "turnaround_cycles": rtunit.DEFAULT_TURNAROUND,
            "wall_s": t_sweep, "plot": str(plot) if plot else None,
            "points": [{kk: pt[kk] for kk in keep} for pt in points]}


def _embree_rate(triangles, origins, dirs):
    """(scene build seconds, trace seconds) of one Embree closest-hit cast of every ray (any
    face; the cross-check's back-face re-casts are not timed)."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    tri = np.ascontiguousarray(triangles, np.float32)
    o = np.ascontiguousarray(origins, np.float32)
    d = np.ascontiguousarray(dirs, np.float32)
    t0 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tri)
    scene.run(o[:1], d[:1], output=1)              # Embree commits (builds) on the first query
    t1 = time.perf_counter()
    scene.run(o, d, output=1)
    return t1 - t0, time.perf_counter() - t1


def _restream(rtl, rec, steps) -> float:
    """Stream the frame's recorded wavefront requests through the "rtl" harness again, in the
    traversal's batches (one ``run_nodes`` call per step, as the traversal makes them); returns
    cycles per second of harness time. The responses must equal the traversal's."""
    c0, wall, off = rtl.cycles, 0.0, 0
    for n in np.asarray(steps, np.int64).tolist():
        sl = slice(off, off + n)
        t0 = time.perf_counter()
        out = rtl.run_nodes(rec.ray_words, rec.image, rec.ray[sl], rec.ptr[sl], rec.extent[sl])
        wall += time.perf_counter() - t0
        if not np.array_equal(out, rec.responses[sl]):
            raise RuntimeError("re-streamed frame requests gave different responses")
        off = n + off
    return (rtl.cycles - c0) / wall if wall > 0 else 0.0


def _pyverilator_stream(rec, k: int, progress, repeat: int, point) -> dict:
    """Stream the record's first k requests through pyverilator and through "rtl" (``run()``
    calls of ``chunk`` requests each, so that the progress bar moves; both backends get the same
    calls and count the same cycles), ``repeat`` times each; every pass checked against the
    frame's responses bit for bit. Rates: the best pass (all passes in ``*_runs``)."""
    req = rec.requests(np.arange(k))
    expect = rec.responses[:k]
    pv = backends.backend("pyverilator", **point.backend_options())
    be = backends.backend("rtl", **point.backend_options())
    chunk = max(1, min(250, k))

    def timed(dp, bar=None):
        out, wall, c0 = [], 0.0, dp.cycles
        for i in range(0, k, chunk):
            t0 = time.perf_counter()
            out.append(dp.run(req[i:i + chunk]))
            wall += time.perf_counter() - t0
            if bar:
                bar.hook(min(i + chunk, k), k)
        same = bool(np.array_equal(pack_responses(np.concatenate(out)), expect))
        return dp.cycles - c0, wall, same

    pv_runs, rtl_runs = [], []
    for r in range(int(repeat)):
        bar = _bar(k, f"pyverilator stream {r + 1}/{repeat}", "req", progress)
        pv_runs.append(timed(pv, bar))
        bar.close()
        rtl_runs.append(timed(be))
    rate = lambda run: run[0] / run[1] if run[1] > 0 else 0.0  # noqa: E731
    best, best_rtl = max(pv_runs, key=rate), max(rtl_runs, key=rate)
    return {
        "requests": k,
        "chunk": chunk,
        "cycles": int(best[0]),
        "wall_s": best[1],
        "cycles_per_s": rate(best),
        "cycles_per_s_runs": [rate(run) for run in pv_runs],
        "responses_match_frame": all(run[2] for run in pv_runs),
        "rtl_same_stream_cycles": int(best_rtl[0]),
        "rtl_same_stream_wall_s": best_rtl[1],
        "rtl_same_stream_cycles_per_s": rate(best_rtl),
        "rtl_same_stream_match": all(run[2] for run in rtl_runs),
        "cycles_equal_every_run": len({run[0] for run in pv_runs + rtl_runs}) == 1,
    }


def table(doc: dict) -> str:
    """The short human-readable summary printed by ``rayflex bench``."""
    f, pv = doc["frame"], doc.get("pyverilator")
    rows = [
        ("frame", f"{doc['scene']} {doc['width']}x{doc['height']}: {f['rays']} rays, "
                  f"{f['hits']} hits"),
        ("Embree", summary(f["embree"]).removeprefix("embree: ") if f.get("embree")
         else "not checked"),
        ("datapath ops", f"{f['ops']} ({f['box_ops']} box + {f['tri_ops']} tri"
                         + (f" + {f['transform_ops']} transform" if f.get("transform_ops")
                            else "")
                         + f"; {f['box_ops_per_ray']:.2f} + {f['tri_ops_per_ray']:.2f}"
                         + (f" + {f['transform_ops_per_ray']:.2f}" if f.get("transform_ops")
                            else "") + " per ray)"),
        *timing_rows(f),
        ("frame wall", f"{f['wall_s']:.2f} s (BVH {f['wall_parts_s']['bvh_build']:.2f} + "
                       f"traversal {f['wall_parts_s']['traversal']:.2f} + replays "
                       f"{f['wall_parts_s']['replay']:.2f})"),
        ("rtl", f"{doc['rtl_cycles_per_s']:.3g} cycles/s (best of "
                f"{', '.join(f'{x:.3g}' for x in doc['rtl_cycles_per_s_runs'])})"),
    ]
    if pv:
        rows.append(("pyverilator", f"{pv['cycles_per_s']:.3g} cycles/s on {pv['requests']} "
                                    f"requests (best of {len(pv['cycles_per_s_runs'])}); "
                                    f"rtl/pyverilator {doc['rtl_vs_pyverilator_speedup']:.0f}x"))
    rows += [
        ("golden", f"{doc['golden_rays_per_s']:.3g} rays/s"),
        ("embree", f"{doc['embree_rays_per_s']:.3g} rays/s"),
        ("BVH build", f"{doc['bvh_build_s']:.2f} s"),
    ]
    sw = doc.get("rtunit_sweep")
    if sw:
        pts = sw["points"]
        for p in sorted({pt["pipelines"] for pt in pts}):
            line = "  ".join(f"R={pt['rays_in_flight']}:{pt['utilization']:.2f}"
                             for pt in pts if pt["pipelines"] == p)
            rows.append((f"sweep P={p} util", line))
    width = max(len(r[0]) for r in rows)
    return "\n".join(f"{a:<{width}}  {b}" for a, b in rows)


def timing_rows(f: dict) -> list[tuple[str, str]]:
    """(label, text) rows of a frame's wavefront and RT-unit figures (docs/statistics.md)."""
    wf = f["wavefront"]
    rows = [("wavefront", f"{wf['cycles']} cycles, utilization {wf['utilization']:.4f} (every "
                          "ray in flight, one pipeline)")]
    for key, what in (("rtunit", "node fetches free"), ("rtunit_memory", "memory hierarchy")):
        r = f.get(key)
        if r:
            rows.append((f"RT units {r['rt_units']} x R={r['rays_in_flight']} "
                         f"P={r['pipelines']} warp {r['warp_size']}, {r['frame_schedule']}",
                         f"{r['cycles']} cycles, utilization {r['utilization']:.4f}, "
                         f"{r['frame_us_at_1ghz']:.1f} us at 1 GHz, latency "
                         f"{r['latency_mean']:.0f} (p95 {r['latency_p95']:.0f}) cycles per ray "
                         f"({what}"
                         + (f"; L1 hit rate {r['hit_rate']:.3f}, {r['bytes_per_ray']:.0f} B/ray "
                            "from DRAM)" if "hit_rate" in r else ")")))
    m = f.get("rtunit_memory") or {}
    w = m.get("simt")
    if w and m.get("warp_size", 1) > 1:
        rows.append(("warps", f"{w['warps']} warps, {w['trace_calls']} trace calls, SIMT "
                              f"efficiency {w['simt_efficiency']:.3f}; a call waits "
                              f"{w['slowest_ray_wait_per_call']:.0f} cycles for its slowest ray "
                              f"after its first; {w['rays_held_mean']:.1f} rays held per RT unit "
                              f"on average (at most {w['max_rays_held']})"))
    if m.get("levels"):
        lv = m["levels"]
        text = "; ".join(
            f"{name} {lv[k]['line_accesses']:,} accesses, {lv[k]['line_hits']:,} hits "
            f"({lv[k]['merged_misses']:,} merged misses), {lv[k]['fill_bytes']:,} bytes filled, "
            f"{lv[k]['wait_cycles']:,} cycles waited" for k, name in (("l1", "L1"), ("l2", "L2"))
            if lv[k]["line_accesses"])
        d = lv["dram"]
        rows.append(("memory", (text + "; " if text else "")
                     + f"DRAM {d['transfer_bytes']:,} bytes in {d['transfers']:,} transfers, "
                     f"{d['wait_cycles']:,} cycles waited; {m['mshr_stalls']:,} MSHR stalls"))
    cost = (f.get("rtunit_memory") or f.get("rtunit") or {}).get("ray_order_cost")
    if cost:
        rows.append(("ray order", order_cost_line(cost)))
    return rows


# ----------------------------------------------------------------------------------------------
# rayflex bench --workload: the datapath mix and the RT-unit timing per ray type

def bench_workload(point: DesignPoint, sweep_rays=(), plot=None, progress=True,
                   ideal: bool = False) -> dict:
    """One workload frame of design point ``point`` on "rtl" (every batch recorded), checked
    against Embree; the frame's RT-unit replay (``rtunit_memory``; with ``ideal`` also
    ``rtunit``, free node fetches), per ray type its op mix, latency and bytes from each memory
    level, any-hit vs closest-hit ops of the same rays; with ``sweep_rays`` (rays in flight per
    unit, multiples of the warp size) the replay again at each, plotted (``plot``; without a
    sweep the plot shows the rays each RT unit holds over the frame)."""
    from .scenes.scene import load_scene

    scene = point.scene_of(load_scene(point.scene))
    size = point.size or scene.size[0]
    setup = workloads.setup_for(scene)
    rtl = backends.backend("rtl", **point.backend_options())
    golden = backends.backend("golden", **point.backend_options())
    bad = [r for r in sweep_rays if r % point.warp_size]
    if bad:
        raise ValueError(f"--sweep-rays {bad[0]} is not a multiple of --warp-size "
                         f"{point.warp_size}")
    t0 = time.perf_counter()
    bvh = point.build(scene)
    t_bvh = time.perf_counter() - t0

    def tracer(bvh_, o, d, **kw):
        return trace(bvh_, o, d, backend=rtl, record=True, cull_stack=point.cull_stack, **kw)

    t1 = time.perf_counter()
    res = workloads.run(setup, bvh, size, size, tracer, point.workload,
                        **point.workload_options())
    t_trace = time.perf_counter() - t1
    workloads.embree_check(res, setup)
    frame = public(res.stats)
    kinds = list(frame["by_type"])
    waves = waves_of(res.batches)
    steps = 1 + len(sweep_rays)
    bar = _bar(steps, f"{point.workload}: RT-unit replay", "replay", progress)
    t2 = time.perf_counter()
    rp = replay_point(waves, point, size, ideal)
    for key in ("rtunit", "rtunit_memory"):
        frame[key] = rp[key]
    for kind in kinds:
        entry = frame["by_type"][kind]
        entry.update(rp["by_type"][kind])
        batches = [b for b in res.batches if b.kind == kind]
        if batches[0].any_hit:
            closest = sum(trace(bvh, b.origins, b.dirs, backend=golden, extent=b.extent,
                                double_sided=setup.double_sided).stats["ops"] for b in batches)
            entry["closest_hit_ops"] = closest
            entry["any_hit_vs_closest_ops"] = entry["ops"] / closest if closest else None
    t_replay = time.perf_counter() - t2
    bar.hook(1, steps)
    sweep = []
    for i, r in enumerate(sweep_rays):
        sp = replay_point(waves, point.replace(rays_in_flight=r,
                                               ray_window=max(point.ray_window, r)), size)
        sweep.append({"rays_in_flight": r, "rtunit_memory": sp["rtunit_memory"],
                      "by_type": {k: {"rtunit_memory": v["rtunit_memory"]}
                                  for k, v in sp["by_type"].items()}})
        bar.hook(i + 2, steps)
    bar.close()
    if plot and sweep:
        plot_workload_sweep(sweep, plot, "utilization vs rays in flight: " + describe(
            {**point.as_dict(), "size": size, "scene": scene.name},
            omit=("rays_in_flight", "ray_window")))
    elif plot:
        plot_rays_held(frame, plot, "rays held per RT unit over the frame: " + describe(
            {**point.as_dict(), "size": size, "scene": scene.name}))
    frame["wall_parts_s"] = {"bvh_build": t_bvh, "traversal": t_trace, "replay": t_replay}
    frame["bvh"] = dict(bvh.stats)
    frame.update(scene.counts())
    frame["clock"] = clock_figures(point, frame)
    return {"provenance": provenance(point), "scene": scene.name, "workload": point.workload,
            "width": size, "height": size, "frame": frame, "sweep": sweep or None,
            "plot": str(plot) if plot else None}
def bench_workers(point: DesignPoint, workers=2, tile=64, progress=True) -> dict:
    """The same tiled frame of design point ``point`` on "rtl" in this process and on a
    LocalCluster of ``workers`` processes: wall times (scheduler start-up and the once-per-worker
    set-up included), the speed-up, and whether the two frames are identical (image, per-pixel
    ops, statistics but wall times). ``phases_n_workers``: where the distributed frame's wall
    time went (``tiles.render_tiles``); ``speedup_tiles`` compares the tiles after the first
    result with the same share of the one-process frame, i.e. the scaling the machine gives once
    every fixed cost is paid."""
    from .scenes.scene import load_scene

    scene = point.scene_of(load_scene(point.scene))
    size = point.size or scene.size[0]
    setup, bvh = workloads.setup_for(scene), point.build(scene)
    n_tiles = len(tiles.plan(size, size, tile))
    # a first use on this machine builds the Verilated model (minutes): build it before either
    # clock starts, so that both runs pay only what every run pays, loading it from the cache
    rtl_build.build_harness(point.rtl_params())
    options = point.workload_options() | {"cull_stack": point.cull_stack}
    spec = ("rtl", point.backend_options())
    runs = {}
    for n in (1, int(workers)):
        bar = _bar(n_tiles, f"{point.workload} {size}x{size} on {plural(n, 'worker')}", "tile",
                   progress)
        t0 = time.perf_counter()
        runs[n] = (tiles.render_tiles(setup, bvh, size, size, point.workload, options, spec,
                                      tile, n, progress=bar.hook),
                   time.perf_counter() - t0)
        bar.close()
    (a, ta), (b, tb) = runs[1], runs[int(workers)]
    phases = b.timings
    keep = ("rays", "hits", "box_ops", "tri_ops", "ops", "cycles")
    same = (np.array_equal(a.radiance, b.radiance)
            and all(np.array_equal(a.ops[k], b.ops[k]) for k in a.ops)
            and {k: a.stats[k] for k in keep} == {k: b.stats[k] for k in keep})
    return {"provenance": provenance(point), "scene": scene.name, "workload": point.workload,
            "width": size, "height": size, "tile": tile, "tiles": n_tiles,
            "workers": int(workers), "wall_s_1_worker": ta, "wall_s_n_workers": tb,
            "speedup": ta / tb if tb > 0 else None, "identical": bool(same),
            "phases_n_workers": {k: round(v, 3) for k, v in phases.items()},
            "speedup_tiles": (ta * (n_tiles - 1) / n_tiles / phases["tiles_s"]
                              if n_tiles > 1 and phases.get("tiles_s") else None),
            "rays": a.stats["rays"], "ops": a.stats["ops"]}
