"""Instanced vs flattened: the figures of docs/instances.md.

    rayflex study instances hits [--scene bunny_grid] [--size 256] [--json OUT]
    rayflex study instances images [--scene NAME ...] [--json OUT]
    rayflex study instances table DOC.json [DOC.json ...]
    rayflex study instances transform [--scene bunny_grid] [--workload path]
        [--size 64] [--spp 2] [--bounces 2] [--json OUT]

``hits`` builds a scene's image both ways (two-level and flattened, in every image format),
reports their bytes (the two-level image's TLAS, instance nodes and BLASes apart), and traces
the same rays through both (box32) on the golden model: the scene's primary rays (closest hit)
and, from every primary hit, an occlusion ray to the centre of its first light (any-hit): hit
and primitive mismatches, and the rays whose ``t`` differs (by the transform's rounding) with
the largest relative difference; it also traces the primary rays through the two-level image
of every other format and compares them with box32's (``formats_vs_box32``: ``t`` bit for
bit). ``images`` builds the two-level image of each scene in every format and reports its
bytes (TLAS, instance nodes, BLASes). ``table`` prints, per document and ray type
(``rayflex bench --workload ... --json`` documents, with or without ``--flatten``), the ops per
ray (box, triangle, instance), node bytes and bytes from memory per ray, the node cache's hit
rate and the utilization with the node memory, as a Markdown table. ``transform`` runs the
same ``rayflex bench --workload`` frame with the instance transform in the driver and on the
datapath (``--transform driver|datapath``) and reports, per ray type and for the frame, the ops
per ray (box, triangle, transform), the RT-unit cycles and utilization without and with the
node memory (the design point's defaults), the datapath's latency, and the datapath
transform's relative change in ops and cycles (``datapath_vs_driver``: datapath / driver - 1);
a JSON document and a Markdown table.
"""

from __future__ import annotations

import numpy as np

from ..bench import bench_workload
from ..bvh4 import build, build_two_level
from ..core.layout import DEFAULT_FORMAT, IMAGE_FORMATS
from ..core.markdown import table as markdown_table
from ..core.provenance import provenance
from ..design import DesignPoint
from ..instances import DATAPATH, TRANSFORMS
from ..scenes.camera import primary_rays
from ..tracer import trace
from ..workloads import setup_for


def hits(scene_name: str = "bunny_grid", size: int = 256, backend: str = "golden") -> dict:
    """The image sizes and the hit comparison of the module docstring, as a JSON-ready dict."""
    from ..scenes.scene import load_scene

    scene = load_scene(scene_name)
    if scene.instances is None:
        raise ValueError(f"scene {scene_name!r} has no instances")
    images, two_level = {}, {}
    for fmt in IMAGE_FORMATS:
        inst, flat = build_two_level(scene.instances, format=fmt), build(scene.mesh, format=fmt)
        images[fmt] = {"instanced_bytes": inst.stats["bytes"],
                       **_parts(inst.stats),
                       "flattened_bytes": flat.stats["bytes"],
                       "ratio": inst.stats["bytes"] / flat.stats["bytes"],
                       "flattened_over_instanced": flat.stats["bytes"] / inst.stats["bytes"],
                       "instanced_build_s": inst.stats["build_s"],
                       "flattened_build_s": flat.stats["build_s"]}
        two_level[fmt] = inst
        if fmt == DEFAULT_FORMAT:
            bvh_f = flat
    bvh_i = two_level[DEFAULT_FORMAT]
    o, d = primary_rays(scene.camera, size, size)
    out = {"scene": scene.name, **scene.counts(), "size": size, "backend": backend,
           "images": images, "rays": {}}
    a, b = trace(bvh_i, o, d, backend=backend), trace(bvh_f, o, d, backend=backend)
    out["rays"]["primary"] = _compare(a, b, scene.triangles)
    out["formats_vs_box32"] = {fmt: _same_image_hits(trace(two_level[fmt], o, d,
                                                           backend=backend), a)
                               for fmt in IMAGE_FORMATS if fmt != DEFAULT_FORMAT}
    rows = np.flatnonzero(a.hit & b.hit)
    p = o[rows].astype(np.float64) + b.t[rows, None].astype(np.float64) * d[rows]
    light = setup_for(scene).lights[0]                  # the scene's first (or default) light
    centre = (np.asarray(light.corner) + 0.5 * np.asarray(light.u) + 0.5 * np.asarray(light.v)
              if hasattr(light, "corner") else np.asarray(light.position))
    tri = scene.triangles[b.prim[rows]].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n *= -np.sign(np.einsum("ij,ij->i", n, d[rows]))[:, None]         # towards the camera
    so = (p + 1e-4 * float(np.abs(tri).max()) * n).astype(np.float32)
    sd = (centre - so).astype(np.float32)
    a2 = trace(bvh_i, so, sd, backend=backend, extent=1.0, any_hit=True)
    b2 = trace(bvh_f, so, sd, backend=backend, extent=1.0, any_hit=True)
    out["rays"]["shadow"] = _compare(a2, b2, None)
    for kind, (x, y) in (("primary", (a, b)), ("shadow", (a2, b2))):
        out["rays"][kind].update(
            {f"{k}_per_ray_{lab}": r.stats[f"{k}_per_ray"] for lab, r in (("instanced", x),
                                                                         ("flattened", y))
             for k in ("box_ops", "tri_ops")},
            instance_ops_per_ray=x.stats["instance_ops_per_ray"],
            node_bytes_per_ray_instanced=x.stats["node_bytes_fetched"] / max(len(x.t), 1),
            node_bytes_per_ray_flattened=y.stats["node_bytes_fetched"] / max(len(y.t), 1))
    return out


def _parts(stats: dict) -> dict:
    """The parts of a two-level image's bytes (``build_two_level`` statistics)."""
    return {k: stats[k] for k in ("tlas_format", "tlas_box_nodes", "tlas_bytes",
                                  "instance_bytes", "blas_bytes")}


def _same_image_hits(a, b) -> dict:
    """Closest hits of two two-level images of one scene (another format ``a`` vs box32 ``b``):
    the same instance transforms and BLAS triangles, so the same hits with ``t`` bit for bit;
    ``prim_mismatch``/``instance_mismatch``: another triangle or instance at that same ``t``."""
    both = a.hit & b.hit
    return {"rays": int(len(a.t)), "hits": int(a.hit.sum()),
            "hit_mismatch": int((a.hit != b.hit).sum()),
            "t_bits_differ": int((a.t[both].view(np.uint32) != b.t[both].view(np.uint32)).sum()),
            "prim_mismatch": int((a.prim[both] != b.prim[both]).sum()),
            "instance_mismatch": int((a.instance[both] != b.instance[both]).sum()),
            "box_ops_per_ray": a.stats["box_ops_per_ray"],
            "box_ops_per_ray_box32": b.stats["box_ops_per_ray"],
            "node_bytes_per_ray": a.stats["node_bytes_fetched"] / max(len(a.t), 1),
            "node_bytes_per_ray_box32": b.stats["node_bytes_fetched"] / max(len(b.t), 1)}


def images(scene_names=("bunny_grid", "city")) -> dict:
    """The two-level image of each scene in every format (``IMAGE_FORMATS``): its bytes (TLAS,
    instance nodes, BLASes, total), bytes per instanced triangle and build time."""
    from ..scenes.scene import load_scene
    out = {"scenes": {}}
    for name in scene_names:
        scene = load_scene(name)
        if scene.instances is None:
            raise ValueError(f"scene {name!r} has no instances")
        counts = scene.counts()
        rows = {}
        for fmt in IMAGE_FORMATS:
            s = build_two_level(scene.instances, format=fmt).stats
            rows[fmt] = {"bytes": s["bytes"], **_parts(s),
                         "bytes_per_instanced_triangle": s["bytes_per_triangle"],
                         "build_s": s["build_s"]}
        out["scenes"][scene.name] = {**counts, "blas": len(scene.instances.meshes),
                                     "images": rows}
    return out


def images_markdown(doc: dict) -> str:
    """The ``images`` document as a Markdown table."""
    return markdown_table(
        ["scene", "format", "TLAS", "TLAS bytes", "instance node bytes", "BLAS bytes",
         "image bytes", "bytes / instanced triangle", "image / box32"],
        ([name, fmt, f"{r['tlas_format']} ({r['tlas_box_nodes']:,} nodes)",
          f"{r['tlas_bytes']:,}", f"{r['instance_bytes']:,}", f"{r['blas_bytes']:,}",
          f"{r['bytes']:,}", f"{r['bytes_per_instanced_triangle']:.3f}",
          f"{r['bytes'] / sc['images']['box32']['bytes']:.3f}"]
         for name, sc in doc["scenes"].items() for fmt, r in sc["images"].items()))


def _compare(a, b, triangles) -> dict:
    """Instanced ``a`` vs flattened ``b`` on the same rays. Closest hits (``triangles``: the
    flattened triangles): the triangles hit, and the ``t`` of the same triangle; a different
    triangle that shares a vertex with the other at a ``t`` within 1e-5 is an edge tie (the
    two roundings put the hit point on either side of a shared edge). Any-hit rays (None): only
    whether they are occluded compares (the first triangle accepted depends on the tree)."""
    both = a.hit & b.hit
    out = {"rays": int(len(a.t)), "hits": int(a.hit.sum()),
           "hit_mismatch": int((a.hit != b.hit).sum())}
    if triangles is None:
        return out
    same = both & (a.prim == b.prim)
    rel = np.abs(a.t[same].astype(np.float64) - b.t[same]) / np.abs(b.t[same])
    other = np.flatnonzero(both & (a.prim != b.prim))
    ta, tb = triangles[a.prim[other]], triangles[b.prim[other]]
    shared = (ta[:, :, None, :] == tb[:, None, :, :]).all(-1).any((1, 2))
    close = np.abs(a.t[other].astype(np.float64) - b.t[other]) <= 1e-5 * np.abs(b.t[other])
    out.update({"prim_mismatch": int(len(other)), "edge_ties": int((shared & close).sum()),
                "t_differs": int((a.t[same] != b.t[same]).sum()),
                "max_t_rel_diff": float(rel.max()) if len(rel) else 0.0})
    return out


def rows(doc: dict) -> list[dict]:
    """Per ray type of a ``bench --workload`` document: the study's columns."""
    out = []
    for kind, t in doc["by_type"].items():
        n = t["rays"]
        mem = t.get("memory") or {}
        out.append({"type": kind, "rays": n, "box": t["box_ops"] / n, "tri": t["tri_ops"] / n,
                    "instance": t.get("instance_ops", 0) / n,
                    "node_bytes": t["node_bytes_fetched"] / n,
                    "memory_bytes": mem.get("bytes_per_ray"), "hit_rate": mem.get("hit_rate"),
                    "utilization": mem.get("replay_utilization")})
    return out


def markdown(docs: list[dict]) -> str:
    def f(v, fmt):
        return "—" if v is None else format(v, fmt)

    def image(doc):
        kind = ("instanced" if doc.get("instances", 1) > 1 and "tlas_bytes" in doc["bvh"]
                else "flattened")
        return f"{kind} {doc['bvh']['format']}"
    return markdown_table(
        ["scene", "image", "image bytes", "ray type", "rays", "box ops/ray", "tri ops/ray",
         "instance ops/ray", "node B/ray", "B from memory/ray", "cache hit rate",
         "utilization with memory"],
        ([doc["scene"], image(doc), f"{doc['bvh']['bytes']:,}", r["type"], f"{r['rays']:,}",
          f"{r['box']:.2f}", f"{r['tri']:.2f}", f"{r['instance']:.2f}", f"{r['node_bytes']:.0f}",
          f(r["memory_bytes"], ".0f"), f(r["hit_rate"], ".3f"), f(r["utilization"], ".3f")]
         for doc in docs for r in rows(doc)))


def transform_cost(scene: str = "bunny_grid", workload: str = "path", size: int = 64,
                   spp: int = 2, bounces: int = 2, progress: bool = False) -> dict:
    """The ``transform`` study of the module docstring: ``driver.bench.bench_workload`` of the
    same design point with each ``--transform`` (no rays-in-flight sweep), as a JSON-ready
    dict."""
    out: dict = {}
    # datapath first: a scene without instances is refused before any work
    for where in sorted(TRANSFORMS, key=lambda w: w != DATAPATH):
        # each ray type replayed on its own (the wavefront schedule with cold caches), so that
        # every ray type has its own cycles
        point = DesignPoint(scene=scene, workload=workload, size=size, spp=spp,
                            bounces=bounces, transform=where, frame_schedule="wavefront",
                            flush_between=True)
        doc = bench_workload(point, sweep_rays=(), progress=progress, ideal=True)
        f = doc["frame"]
        if not out:
            out = {"provenance": provenance(point), "scene": doc["scene"], "workload": workload,
                   "width": doc["width"], "height": doc["height"], "spp": spp,
                   "bounces": bounces, "latency_cycles": f["latency_cycles"],
                   "instances": f["instances"], "transforms": {}}
            out["provenance"]["design_point"]["transform"] = list(TRANSFORMS)
        out["transforms"][where] = {"frame": _cost(f),
                                    "by_type": {k: _cost(t) for k, t in f["by_type"].items()},
                                    "wall_s": sum(f["wall_parts_s"].values())}
    out["transforms"] = {w: out["transforms"][w] for w in TRANSFORMS}
    a, b = (out["transforms"][w] for w in TRANSFORMS)
    out["datapath_vs_driver"] = {
        kind: _relative(a["frame"] if kind == "frame" else a["by_type"][kind],
                        b["frame"] if kind == "frame" else b["by_type"][kind])
        for kind in ["frame", *a["by_type"]]}
    return out


def _cost(t: dict) -> dict:
    """One frame's or ray type's figures of the ``transform`` study."""
    n = t["rays"]
    out = {"rays": n, "hits": t["hits"], "ops": t["ops"],
           **{k: t[k] for k in ("box_ops_per_ray", "tri_ops_per_ray", "instance_ops_per_ray",
                                "transform_ops_per_ray")},
           "ops_per_ray": t["ops"] / n if n else 0.0,
           "embree_hit_mismatch": (t.get("embree") or {}).get("hit_mismatch")}
    for key in ("rtunit", "rtunit_memory"):
        r = t.get(key) or {}
        out[key] = {k: r.get(k) for k in ("cycles", "utilization", "cycles_per_ray",
                                          "hit_rate", "bytes_per_ray") if k in r}
    return out


def _relative(a: dict, b: dict) -> dict:
    """Datapath (``b``) against driver (``a``): the relative change (b / a - 1) of the ops and
    of the RT-unit cycles."""
    def change(x, y):
        return y / x - 1 if x else None
    out = {"ops": change(a["ops"], b["ops"])}
    for key in ("rtunit", "rtunit_memory"):
        out[f"{key}_cycles"] = change(a[key].get("cycles"), b[key].get("cycles"))
    return out


def transform_markdown(doc: dict) -> str:
    """The ``transform`` study as a Markdown table: one row per ray type (and the frame) and
    transform placement."""
    lines = ["| ray type | transform | rays | box ops/ray | tri ops/ray | transform ops/ray "
             "| RT-unit cycles | utilization | cycles with memory | utilization with memory "
             "| cycles vs driver (with memory) |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"
             "---:|---:|"]
    pct = lambda x: "—" if x is None else f"{100 * x:+.1f} %"     # noqa: E731
    kinds = [*next(iter(doc["transforms"].values()))["by_type"], "frame"]
    for kind in kinds:
        for where, m in doc["transforms"].items():
            c = m["frame"] if kind == "frame" else m["by_type"][kind]
            rel = doc["datapath_vs_driver"][kind]["rtunit_memory_cycles"]
            lines.append(
                f"| {kind} | {where} | {c['rays']:,} | {c['box_ops_per_ray']:.2f} "
                f"| {c['tri_ops_per_ray']:.2f} | {c['transform_ops_per_ray']:.2f} "
                f"| {c['rtunit']['cycles']:,} | {c['rtunit']['utilization']:.3f} "
                f"| {c['rtunit_memory']['cycles']:,} | {c['rtunit_memory']['utilization']:.3f} "
                f"| {'' if where == 'driver' else pct(rel)} |")
    return "\n".join(lines)
