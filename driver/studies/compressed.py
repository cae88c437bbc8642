"""box32 vs q8 (and q8g) on one workload frame: the table and the plot of docs/compressed.md,
from ``rayflex bench --workload ... --bvh-format FORMAT --json`` documents of the same frame.

    rayflex study compressed BOX32.json Q8.json [Q8G.json] [--plot PNG]

prints the per-ray-type comparison as a Markdown table and draws utilization with the node
memory vs rays in flight, one panel per ray type, one line per format. The documents are
``rayflex bench --frame wavefront --flush-between --ideal-replay --sweep-rays LIST`` runs:
each ray type replayed on its own with cold caches, so that it has its own cycles (the study of
a GPU's one-kernel frame is ``rayflex study gpu``, ``driver.studies.gpu``).
"""

from __future__ import annotations

import json

from ..core.markdown import table as markdown_table
from ..plotting import wrap
from ..core.layout import DEFAULT_FORMAT, IMAGE_FORMATS

FORMATS = IMAGE_FORMATS


def rows(docs: dict) -> list[dict]:
    """Per ray type and format: bytes per triangle, ops, node bytes and bytes from memory per
    ray, cache hit rate, utilization and cycles per ray with the node memory, and the ratios to
    box32."""
    out = []
    base = docs[DEFAULT_FORMAT]["frame"]
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
    """PNG: utilization with the node memory vs rays in flight (log x), one panel per ray type,
    one line per image format (box32 dashed, q8 solid, q8g dotted, each its own marker), the
    legend below the panels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if any(not d.get("sweep") for d in docs.values()):
        raise ValueError("the documents hold no rays-in-flight sweep (bench --sweep-rays)")
    kinds = list(docs[DEFAULT_FORMAT]["sweep"][0]["by_type"])
    cols = min(len(kinds), 4)
    rows_ = -(-len(kinds) // cols)
    fig = Figure(figsize=(3.2 * cols + 0.6, 3.0 * rows_ + 1.3), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows_, cols, sharex=True, sharey=True, squeeze=False).ravel()
    style = {"box32": ("s", "--"), "q8": ("o", "-"), "q8g": ("^", ":")}
    for ax, kind in zip(axes, kinds):
        for i, (fmt, doc) in enumerate(docs.items()):
            pts = doc["sweep"]
            ys = [p["by_type"][kind]["rtunit_memory"]["utilization"] for p in pts]
            if None in ys:
                raise ValueError("a ray type's utilization needs the wavefront schedule "
                                 "(bench --frame wavefront)")
            ax.plot([p["rays_in_flight"] for p in pts], ys, marker=style[fmt][0],
                    ls=style[fmt][1], color=f"C{i}", ms=4, lw=1.3, label=fmt)
        ax.set_title(kind, fontsize=9)
        ax.set_xscale("log", base=2)
        ax.set_ylim(0, 1.05)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[len(kinds):]:
        ax.set_visible(False)
    for ax in axes[-cols:]:
        ax.set_xlabel("rays in flight (R)")
    for ax in axes[::cols]:
        ax.set_ylabel("utilization with the\nnode cache + memory")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), frameon=False,
               fontsize=8)
    fig.suptitle(wrap(title, 150), fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
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
    if len(docs) != len(paths) or not {DEFAULT_FORMAT, "q8"} <= set(docs):
        raise ValueError("give one document per format, box32 and q8 among them")
    keys = ("scene", "workload", "width", "height", "spp", "bounces", "seed")
    if any(doc[k] != docs[DEFAULT_FORMAT][k] for doc in docs.values() for k in keys):
        raise ValueError("the documents are not the same frame")
    if any(doc["frame"]["by_type"].keys() != docs[DEFAULT_FORMAT]["frame"]["by_type"].keys()
           for doc in docs.values()):
        raise ValueError("the documents hold different ray types")
    return {f: docs[f] for f in FORMATS if f in docs}
