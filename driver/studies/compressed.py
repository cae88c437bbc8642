"""box32 vs q8 (and q8g) on one workload frame: the table and the plot of docs/compressed.md,
from ``rayflex bench --workload ... --bvh-format FORMAT --json`` documents of the same frame.

    rayflex study compressed BOX32.json Q8.json [Q8G.json] [--plot PNG]

prints the per-ray-type comparison as a Markdown table and draws utilization with the node
memory vs rays in flight, one colour per ray type, solid q8 and dashed box32. The documents are
``rayflex bench --frame wavefront --flush-between --ideal-replay --sweep-rays LIST`` runs: each ray
type replayed on its own with cold caches, so that it has its own cycles (the study as it was
before one-kernel frames; the one-kernel study is ``rayflex study gpu``, ``driver.studies.gpu``).
"""

from __future__ import annotations

import json

from ..core.markdown import table as markdown_table

FORMATS = ("box32", "q8", "q8g")


def rows(docs: dict) -> list[dict]:
    """Per ray type and format: bytes per triangle, ops, node bytes and bytes from memory per
    ray, cache hit rate, utilization and cycles per ray with the node memory, and the ratios to
    box32."""
    out = []
    base = docs["box32"]["frame"]
    for kind in base["by_type"]:
        ref = base["by_type"][kind]
        for fmt, doc in docs.items():
            t = doc["frame"]["by_type"][kind]
            n = t["rays"]
            m = t["rtunit_memory"]
            row = {"type": kind, "format": fmt, "rays": n,
                   "bytes_per_triangle": doc["frame"]["bvh"]["bytes_per_triangle"],
                   "box_ops_per_ray": t["box_ops"] / n, "tri_ops_per_ray": t["tri_ops"] / n,
                   "ops_per_ray": t["ops"] / n, "node_bytes_per_ray": t["node_bytes_fetched"] / n,
                   "memory_bytes_per_ray": m["bytes_per_ray"], "hit_rate": m["hit_rate"],
                   "utilization_memory": m["utilization"],
                   "cycles_per_ray_memory": m["cycles"] / n,
                   "utilization_free": t["rtunit"]["utilization"],
                   "ops_ratio": t["ops"] / ref["ops"],
                   "memory_bytes_ratio": m["bytes_per_ray"] / ref["rtunit_memory"]["bytes_per_ray"],
                   "cycles_ratio": m["cycles"] / ref["rtunit_memory"]["cycles"]}
            out.append(row)
    return out


def markdown(table: list[dict]) -> str:
    return markdown_table(
        ["ray type", "image", "B/triangle", "ops/ray (box + tri)", "ops vs box32", "node B/ray",
         "B from memory/ray", "vs box32", "cache hit rate", "utilization with memory",
         "cycles/ray with memory", "vs box32"],
        ([r["type"], r["format"], f"{r['bytes_per_triangle']:.1f}",
          f"{r['ops_per_ray']:.2f} ({r['box_ops_per_ray']:.2f} + {r['tri_ops_per_ray']:.2f})",
          f"{r['ops_ratio']:.3f}", f"{r['node_bytes_per_ray']:.0f}",
          f"{r['memory_bytes_per_ray']:.0f}", f"{r['memory_bytes_ratio']:.3f}",
          f"{r['hit_rate']:.3f}", f"{r['utilization_memory']:.3f}",
          f"{r['cycles_per_ray_memory']:.1f}", f"{r['cycles_ratio']:.3f}"] for r in table))


def plot(docs: dict, path, title: str) -> None:
    """PNG: utilization with the node memory vs rays in flight (log x), per ray type, box32
    (dashed) and q8 (solid)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    sweeps = {fmt: docs[fmt]["sweep"] for fmt in ("q8", "box32")}
    if any(not sw for sw in sweeps.values()):
        raise ValueError("the documents hold no rays-in-flight sweep (bench --sweep-rays)")
    for i, kind in enumerate(sweeps["q8"][0]["by_type"]):
        c = colours[i % len(colours)]
        for fmt, style in (("q8", "o-"), ("box32", "s--")):
            pts = sweeps[fmt]
            ys = [p["by_type"][kind]["rtunit_memory"]["utilization"] for p in pts]
            if None in ys:
                raise ValueError("a ray type's utilization needs the wavefront schedule "
                                 "(--frame wavefront)")
            ax.plot([p["rays_in_flight"] for p in pts], ys, style, color=c,
                    ms=4, lw=1.5 if fmt == "q8" else 1, label=f"{kind} {fmt}")
    ax.set_xscale("log", base=2)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("rays in flight (ray pool size R)")
    ax.set_ylabel("datapath utilization with node cache + memory")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(str(path), format="png")


def load(paths) -> dict:
    """{format: doc} from bench JSON files of the same frame, one per format, box32 and q8
    among them (ValueError)."""
    docs = {}
    for p in paths:
        try:
            with open(p) as f:
                doc = json.load(f)
        except (OSError, ValueError) as e:
            raise ValueError(f"{p}: not a readable bench JSON ({e})") from None
        point = (doc.get("provenance") or {}).get("design_point") or {}
        fmt = point.get("bvh_format")
        types = (doc.get("frame") or {}).get("by_type") or {}
        if fmt not in FORMATS or not types or not next(iter(types.values())).get("rtunit_memory"):
            raise ValueError(f"{p}: not a rayflex bench --workload JSON with the node memory")
        doc = {**doc, **{k: point[k] for k in ("spp", "bounces", "seed")}}
        docs[fmt] = doc
    if len(docs) != len(paths) or not {"box32", "q8"} <= set(docs):
        raise ValueError("give one document per format, box32 and q8 among them")
    keys = ("scene", "workload", "width", "height", "spp", "bounces", "seed")
    if any(doc[k] != docs["box32"][k] for doc in docs.values() for k in keys):
        raise ValueError("the documents are not the same frame")
    if any(doc["frame"]["by_type"].keys() != docs["box32"]["frame"]["by_type"].keys()
           for doc in docs.values()):
        raise ValueError("the documents hold different ray types")
    return {f: docs[f] for f in FORMATS if f in docs}
