"""BVH build benchmark: build time, peak memory and tree quality (``bvh_bench()`` -> JSON dict).

Big meshes are instanced bunnies (``instanced_bunnies``). Each build runs in a fresh process
(multiprocessing "spawn") so that its peak resident memory (``ru_maxrss``) is its own; the
figure includes the interpreter, numpy and numba (~150 MB). ``build_s`` is wall time,
``build_cpu_s`` the process CPU time (all threads; on a shared machine the steadier figure), and
``load_average`` the machine's 1-minute load when the build ended. Tree quality before/after compares
the greedy collapse with the SAH collapse on the bunny, by SAH cost and by the ops per ray of the
bunny's 256 x 256 primary frame traced on the golden model, and checks that both trees find the
same closest hits; then the shape trade-off: box nodes and ops per ray for each ``--bvh-fill``
in ``FILLS``, with the docs/datapath.md#traversal traversal and with the distance-culled stack
(``cull_stack``), against the reference point ``REFERENCE`` (box nodes, ops per ray), optionally
plotted.

    rayflex study bvh --counts 0 50 --json builds.json

times the builds only (no tree quality) and prints them as the Markdown table of
docs/compressed.md: process CPU and wall seconds per format, their ratios to box32, and the
machine's load average while they ran.
"""

from __future__ import annotations

import os
import multiprocessing
import resource
import time
from pathlib import Path

import numpy as np

from ..bvh4 import build
from ..core.errors import SceneError
from ..core.markdown import table as markdown_table
from ..core.progress import iterate
from ..scenes.builtins import instanced_bunnies as grid
from ..scenes.camera import primary_rays
from ..tracer import trace
from ..core.layout import DEFAULT_FORMAT, IMAGE_FORMATS

BUNNY_TRIANGLES = 99_785
FORMATS = IMAGE_FORMATS            # image formats whose builds are timed
FILLS = (0, 8, 16, 32, 40, 64, 256, 1 << 30)     # --bvh-fill values of the shape trade-off
# a reference point on the bunny frame: box nodes, and 0.95 x the 6.29 ops per ray of plain SAH
REFERENCE = {"box_nodes": 36_000, "ops_per_ray": 0.95 * 6.29}


def instanced_bunnies(count: int, seed: int = 0) -> np.ndarray:
    """``count`` copies of the Stanford bunny (``driver.scenes.builtins.instanced_bunnies``),
    flattened: (count * bunny triangles, 3, 3) float32 world-space triangles."""
    from ..scenes.scene import load
    return grid(load("bunny").triangles, count, seed).flatten()


def _build_child(count, fmt, conn):
    """In a fresh process: build ``count`` bunnies (0 = the bunny itself) in image format
    ``fmt`` and send the numbers."""
    from ..scenes.scene import load
    tris = instanced_bunnies(count) if count else load("bunny")
    build(load("bunny"), progress=False, format=fmt)    # load the compiled kernels before timing
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    cpu0 = time.process_time()
    bvh = build(tris, progress=None, format=fmt)
    cpu = time.process_time() - cpu0
    s = bvh.stats
    conn.send({"format": fmt, "triangles": s["tri_nodes"], "build_s": round(s["build_s"], 3),
               "bytes": s["bytes"], "bytes_per_triangle": round(s["bytes_per_triangle"], 2),
               "pair_ratio": round(s["pair_ratio"], 4),
               "build_cpu_s": round(cpu, 3), "load_average": round(os.getloadavg()[0], 2),
               "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
               "rss_before_mb": round(rss0 / 1024, 1), "box_nodes": s["box_nodes"],
               "sah_cost": round(s["sah_cost"], 4)})
    conn.close()


def _timed_build(count: int, fmt: str = DEFAULT_FORMAT) -> dict:
    ctx = multiprocessing.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_build_child, args=(count, fmt, send))
    proc.start()
    send.close()
    try:
        result = recv.recv()
    except EOFError:
        raise OSError(f"BVH build of {count} bunnies died (exit code {proc.join() or proc.exitcode})")
    proc.join()
    return result


def _tree_row(bvh, r) -> dict:
    s = bvh.stats
    return {"box_nodes": s["box_nodes"], "avg_children": round(s["avg_children"], 4),
            "child_histogram": s["child_histogram"], "depth": s["depth"],
            "sah_cost": round(s["sah_cost"], 4), "bytes": s["bytes"],
            "box_ops_per_ray": round(float(r.box_ops.mean()), 4),
            "tri_ops_per_ray": round(float(r.tri_ops.mean()), 4),
            "ops_per_ray": round(float((r.box_ops + r.tri_ops).mean()), 4)}


def _same(a, b) -> bool:
    """Bit-identical hits (t and primitive) of two traces of the same rays."""
    return bool(np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32))
                and np.array_equal(a.prim, b.prim))


def _fills(scene, o, d, ref, fills, progress) -> dict:
    """The BVH shape trade-off: for each ``--bvh-fill``, the tree, the ops per ray of the
    docs/datapath.md#traversal traversal and of the distance-culled stack, and whether the hits
    equal ``ref``'s."""
    rows = []
    for fill in iterate(fills, "BVH fills", "fill", progress):
        bvh = build(scene.mesh, fill=fill)
        plain = trace(bvh, o, d, backend="golden")
        culled = trace(bvh, o, d, backend="golden", cull_stack=True)
        row = {"fill": fill, **_tree_row(bvh, plain)}
        row["culled_ops_per_ray"] = round(culled.stats["ops"] / len(o), 4)
        row["culled_box_ops_per_ray"] = round(culled.stats["box_ops_per_ray"], 4)
        row["stack_culls_per_ray"] = round(culled.stats["stack_culls"] / len(o), 4)
        row["same_hits"] = _same(plain, ref) and _same(culled, ref)
        rows.append(row)
    within = [{"fill": r["fill"], "cull_stack": cull}
           for r in rows for cull, key in ((False, "ops_per_ray"), (True, "culled_ops_per_ray"))
           if r["box_nodes"] <= REFERENCE["box_nodes"] and r[key] <= REFERENCE["ops_per_ray"]
           and r["same_hits"]]
    return {"rows": rows, "reference": {**{k: round(v, 4) for k, v in REFERENCE.items()},
                                        "within": within}}


def plot_fills(fills: dict, path, title: str) -> None:
    """PNG: primary-ray ops per ray vs box nodes, one point per ``--bvh-fill``, for the
    docs/datapath.md#traversal traversal and the distance-culled stack, with the reference point."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.4, 4.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    rows = fills["rows"]
    x = [r["box_nodes"] for r in rows]
    for key, label, mark in (("ops_per_ray", "stack of pointers", "o-"),
                             ("culled_ops_per_ray", "distance-culled stack", "s-")):
        ax.plot(x, [r[key] for r in rows], mark, label=label)
        for r in rows:
            ax.annotate("inf" if r["fill"] >= 1 << 30 else str(r["fill"]), (r["box_nodes"], r[key]),
                        textcoords="offset points", xytext=(4, 4), fontsize=7)
    t = fills["reference"]
    ax.axvline(t["box_nodes"], color="grey", ls=":", lw=1,
               label=f"reference: {t['box_nodes']:,} box nodes")
    ax.axhline(t["ops_per_ray"], color="grey", ls="-.", lw=1,
               label=f"reference: {t['ops_per_ray']:.2f} ops per ray")
    ax.set_xlabel("box nodes (labels: --bvh-fill)")
    ax.set_ylabel("datapath ops per primary ray\n(zoomed: the axis does not start at 0)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, format="png")


def _quality(size: int = 256, fills=FILLS, plot=None, progress: bool = False) -> dict:
    """Greedy vs SAH collapse on the bunny frame (golden model): tree and ops per ray; then the
    ``fills`` trade-off (``_fills``), plotted to ``plot`` (a PNG path) if given."""
    from ..scenes.scene import load_scene
    scene = load_scene("bunny")
    o, d = primary_rays(scene.camera, size, size)
    out, traces = {}, {}
    for collapse in ("greedy", "sah"):
        bvh = build(scene.mesh, collapse=collapse)
        r = trace(bvh, o, d, backend="golden")
        s = bvh.stats
        traces[collapse] = r
        out[collapse] = _tree_row(bvh, r)
    a, b = traces["greedy"], traces["sah"]
    both = a.hit & b.hit
    out["same_hits"] = {
        "rays": int(len(a.hit)), "hits": int(a.hit.sum()),
        "hit_mismatch": int((a.hit != b.hit).sum()),
        "prim_mismatch": int((a.prim[both] != b.prim[both]).sum()),
        "prim_mismatch_same_t": int(((a.prim != b.prim) & both & (a.t == b.t)).sum())}
    out["ops_ratio"] = round(out["sah"]["ops_per_ray"] / out["greedy"]["ops_per_ray"], 4)
    if fills:
        out["fills"] = _fills(scene, o, d, b, fills, progress)
        if plot:
            plot_fills(out["fills"], plot, f"bunny {size}x{size} primary rays, box32 BVH "
                                           "(fill varied), golden model: BVH4 size vs "
                                           "datapath ops")
    return out


def bvh_bench(counts=(0, 20, 50), quality: bool = True, size: int = 256,
              progress: bool = True, fills=FILLS, plot=None, formats=FORMATS) -> dict:
    """The benchmark as a dict: ``builds`` (one entry per mesh and image format in ``formats``:
    0 = the bunny, k = k instanced bunnies, i.e. ~2 M for 20 and ~5 M for 50; each format's
    build time also as a ratio to box32's, ``vs_box32_build_s``) and ``quality`` (``_quality`` on the bunny's
    size x size primary frame, with the ``fills`` trade-off plotted to ``plot``)."""
    result = {"machine_cpus": multiprocessing.cpu_count(), "builds": []}
    runs = [(count, fmt) for count in counts for fmt in formats]
    for count, fmt in iterate(runs, "BVH bench", "build", progress):
        t0 = time.perf_counter()
        entry = {"bunnies": count or 1, **_timed_build(count, fmt)}
        entry["process_wall_s"] = round(time.perf_counter() - t0, 2)
        base = [b for b in result["builds"] if b["bunnies"] == entry["bunnies"]
                and b["format"] == DEFAULT_FORMAT]
        if fmt != DEFAULT_FORMAT and base:
            entry["vs_box32_build_s"] = round(entry["build_s"] / base[0]["build_s"], 3)
        result["builds"].append(entry)
    if quality:
        result["quality"] = _quality(size, fills, plot, progress)
    return result


PAIRING = ("vertex ids", "adjacency", "matching", "pairs")    # build phases of the q8 pairing
WORST_MIN = 1000      # triangles: below, a build's fixed costs (calls, allocations) dominate


def mesh_items(paths) -> list[tuple[str, list]]:
    """(name, mesh files) to build: each mesh file alone, and each folder's files (not its
    subfolders') alone and then together as one mesh (``folder/*``)."""

    from ..scenes.scene import MESH_TYPES
    items = []
    for path in map(Path, paths):
        if path.is_dir():
            files = sorted(p for p in path.iterdir()
                           if p.is_file() and p.suffix.lower().lstrip(".") in MESH_TYPES)
            if not files:
                raise ValueError(f"{path}: no mesh files in this folder")
            items += [(str(f), [f]) for f in files]
            items.append((f"{path}/*", files))
        elif path.is_file():
            items.append((str(path), [path]))
        else:
            raise ValueError(f"{path}: no such file or folder")
    return items


def _mesh_child(conn, phase, formats) -> None:
    """In a fresh process: load and build each item the parent sends, in every format; send
    per format the build time, its phases and the pairing's microseconds per triangle."""
    from ..scenes.scene import load_scene

    def on_phase(name):
        phase.value = name.encode()[:99]

    on_phase("loading the kernels")
    warm = np.random.default_rng(0).random((64, 3, 3)).astype(np.float32)
    for fmt in formats:                      # each kernel's first call loads it: not timed
        build(warm, format=fmt, progress=False)
    while True:
        try:
            name, files = conn.recv()
        except (EOFError, OSError):
            return
        try:
            on_phase("load")
            meshes = []
            for f in files:
                try:
                    meshes.append(load_scene(f).mesh)
                except SceneError as e:
                    if "no triangles" not in str(e):
                        raise
            if not meshes:                  # e.g. an OBJ of a rig's empty helper object
                conn.send({"mesh": name, "files": len(files), "triangles": 0})
                continue
            tris = np.concatenate([np.asarray(m.triangles, np.float32) for m in meshes])
            mesh = meshes[0] if len(files) == 1 else tris
            row = {"mesh": name, "files": len(files), "triangles": len(tris)}
            for fmt in formats:
                on_phase(f"{fmt}: start")
                bvh = build(mesh, format=fmt, progress=False,
                            on_phase=lambda p, fmt=fmt: on_phase(f"{fmt}: {p}"))
                st = bvh.stats
                r = {"build_s": round(st["build_s"], 4),
                     "phase_s": {k: round(v, 5) for k, v in st["phase_s"].items()},
                     "bytes_per_triangle": round(st["bytes_per_triangle"], 2),
                     "pair_ratio": round(st["pair_ratio"], 4)}
                if fmt != DEFAULT_FORMAT:
                    n = len(tris)
                    for what, keys in (("matching", ("matching",)), ("pairing", PAIRING)):
                        for clock, key in (("", "phase_s"), ("_cpu", "phase_cpu_s")):
                            r[f"{what}{clock}_us_per_triangle"] = round(
                                1e6 * sum(st[key][k] for k in keys) / n, 4)
                row[fmt] = r
            row["load_average"] = round(os.getloadavg()[0], 2)
            conn.send(row)
        except Exception as e:  # noqa: BLE001  (a file that does not load is a row, not a stop)
            conn.send({"mesh": name, "files": len(files), "error": f"{type(e).__name__}: {e}"})


def mesh_bench(paths, formats=FORMATS, bound_s: float = 60.0, bound_per_tri_s: float = 1e-4,
               progress: bool = True) -> dict:
    """Build every mesh of ``paths`` (``mesh_items``: files alone, folders' files alone and
    whole) in ``formats``, in a worker process that is killed and replaced when an item runs
    longer than ``bound_s + bound_per_tri_s`` per triangle (a ``hang`` row naming the phase).
    Returns {"meshes": rows, "worst": the largest pairing and matching microseconds per
    triangle of q8 and q8g, "hangs", "errors"}."""
    items = mesh_items(paths)
    ctx = multiprocessing.get_context("spawn")

    def start():
        phase = ctx.Array("c", 100, lock=False)
        conn, child = ctx.Pipe()
        proc = ctx.Process(target=_mesh_child, args=(child, phase, tuple(formats)), daemon=True)
        proc.start()
        child.close()
        return proc, conn, phase

    proc, conn, phase = start()
    rows = []
    try:
        for name, files in iterate(items, "BVH mesh bench", "mesh", progress):
            size = sum(f.stat().st_size for f in files)           # ~40 bytes a triangle (OBJ)
            limit = bound_s + 2 * bound_per_tri_s * size / 40 * len(formats)
            conn.send((name, files))
            if conn.poll(limit + (120 if not rows else 0)):          # + loading the kernels
                try:
                    rows.append(conn.recv())
                    continue
                except EOFError:
                    rows.append({"mesh": name, "error": f"the worker died in "
                                 f"{phase.value.decode()!r} (exit {proc.exitcode})"})
            else:
                rows.append({"mesh": name, "hang": phase.value.decode(),
                             "bound_s": round(limit, 1)})
            proc.kill()
            proc.join()
            proc, conn, phase = start()
    finally:
        conn.close()
        proc.kill()
        proc.join()
    worst = {}
    for fmt in formats:
        for key in ("pairing_us_per_triangle", "matching_us_per_triangle",
                    "pairing_cpu_us_per_triangle", "matching_cpu_us_per_triangle"):
            for big, what in ((True, f"{fmt} {key}"),
                              (False, f"{fmt} {key} below {WORST_MIN:,} triangles")):
                done = [r for r in rows if fmt in r and key in r[fmt]
                        and (r["triangles"] >= WORST_MIN) == big]
                if done:
                    top = max(done, key=lambda r: r[fmt][key])
                    worst[what] = {"value": top[fmt][key], "mesh": top["mesh"],
                                   "triangles": top["triangles"]}
    return {"meshes": rows, "worst": worst, "hangs": sum("hang" in r for r in rows),
            "errors": sum("error" in r for r in rows),
            "empty": sum(r.get("triangles") == 0 for r in rows),
            "machine_cpus": multiprocessing.cpu_count()}


def build_table(doc: dict) -> str:
    """Markdown: per mesh, each format's build CPU seconds (wall seconds), the ratios of q8 and
    q8g to box32 (CPU and wall), q8g's bytes per triangle and the load averages seen."""
    by = {}
    for b in doc["builds"]:
        by.setdefault(b["bunnies"], {})[b["format"]] = b
    fmts = [f for f in FORMATS if any(f in row for row in by.values())]
    head = ["mesh", *(f"{f} CPU s (wall)" for f in fmts),
            *(f"{f} / {DEFAULT_FORMAT} CPU (wall)" for f in fmts if f != DEFAULT_FORMAT),
            "q8g bytes / triangle", "load average"]
    rows = []
    for count, row in by.items():
        any_row = next(iter(row.values()))
        mesh = (f"bunny, {any_row['triangles']:,} triangles" if count == 1
                else f"{count} bunnies, {any_row['triangles']:,} triangles")
        cells = [mesh, *(f"{row[f]['build_cpu_s']:.2f} ({row[f]['build_s']:.2f})"
                         if f in row else "–" for f in fmts)]
        base = row.get(DEFAULT_FORMAT)
        for f in fmts:
            if f != DEFAULT_FORMAT:
                cells.append(f"{row[f]['build_cpu_s'] / base['build_cpu_s']:.2f} "
                             f"({row[f]['build_s'] / base['build_s']:.2f})"
                             if base and f in row else "–")
        cells.append(f"{row['q8g']['bytes_per_triangle']:.1f}" if "q8g" in row else "–")
        loads = [b["load_average"] for b in row.values()]
        cells.append(f"{min(loads):.1f}–{max(loads):.1f}")
        rows.append(cells)
    return markdown_table(head, rows)


def mesh_table(doc: dict) -> str:
    """Plain lines: meshes, triangles, hangs and errors, then the worst pairing and matching
    microseconds per triangle per format."""
    rows = doc["meshes"]
    tri = sum(r.get("triangles", 0) for r in rows)
    lines = [f"{len(rows)} meshes, {tri:,} triangles: {doc['hangs']} hangs, "
             f"{doc['errors']} errors, {doc['empty']} without triangles"]
    for key, w in doc["worst"].items():
        lines.append(f"worst {key}: {w['value']:.3f} ({w['mesh']}, {w['triangles']:,} "
                     "triangles)")
    lines += [f"hang: {r['mesh']} in {r['hang']!r}" for r in rows if "hang" in r]
    lines += [f"error: {r['mesh']}: {r['error']}" for r in rows if "error" in r]
    return "\n".join(lines)
