"""box32 vs q8 on one workload frame: the table and the plot of docs/compressed.md, from two
``rayflex bench --workload ... --bvh-format box32|q8 --json`` documents of the same frame.

    python -m driver.bvh.study BOX32.json Q8.json [--plot PNG]

prints the per-ray-type comparison as a Markdown table and draws utilization with the node
memory vs rays in flight, one colour per ray type, solid q8 and dashed box32.
"""

from __future__ import annotations

import argparse
import json
import sys

FORMATS = ("box32", "q8")


def rows(docs: dict) -> list[dict]:
    """Per ray type: both formats' bytes per triangle, ops, node bytes and bytes from memory
    per ray, cache hit rate and utilization with the node memory, and the q8 / box32 ratios."""
    out = []
    a, b = docs["box32"], docs["q8"]
    for kind in a["by_type"]:
        row = {"type": kind, "rays": a["by_type"][kind]["rays"]}
        for fmt, doc in docs.items():
            t = doc["by_type"][kind]
            n = t["rays"]
            row[fmt] = {"bytes_per_triangle": doc["bvh"]["bytes_per_triangle"],
                        "box_ops_per_ray": t["box_ops"] / n, "tri_ops_per_ray": t["tri_ops"] / n,
                        "ops_per_ray": t["ops"] / n, "node_bytes_per_ray": t["node_bytes_fetched"] / n,
                        "memory_bytes_per_ray": t["memory"]["bytes_per_ray"],
                        "hit_rate": t["memory"]["hit_rate"],
                        "utilization_memory": t["memory"]["replay_utilization"],
                        "utilization_free": t["replay_utilization"]}
        row["ops_ratio"] = row["q8"]["ops_per_ray"] / row["box32"]["ops_per_ray"]
        row["memory_bytes_ratio"] = (row["q8"]["memory_bytes_per_ray"]
                                     / row["box32"]["memory_bytes_per_ray"])
        out.append(row)
    if a["by_type"].keys() != b["by_type"].keys():
        raise ValueError("the two documents hold different ray types")
    return out


def markdown(table: list[dict]) -> str:
    head = ("| ray type | rays | ops/ray box32 → q8 | box+tri ops ratio | node B/ray box32 → q8 "
            "| B from memory/ray box32 → q8 | ratio | cache hit rate | utilization with memory |")
    lines = [head, "|" + "---|" * 9]
    for r in table:
        a, b = r["box32"], r["q8"]
        lines.append(
            f"| {r['type']} | {r['rays']:,} | {a['ops_per_ray']:.2f} "
            f"({a['box_ops_per_ray']:.2f} + {a['tri_ops_per_ray']:.2f}) → {b['ops_per_ray']:.2f} "
            f"({b['box_ops_per_ray']:.2f} + {b['tri_ops_per_ray']:.2f}) | {r['ops_ratio']:.3f} "
            f"| {a['node_bytes_per_ray']:.0f} → {b['node_bytes_per_ray']:.0f} "
            f"| {a['memory_bytes_per_ray']:.0f} → {b['memory_bytes_per_ray']:.0f} "
            f"| {r['memory_bytes_ratio']:.3f} | {a['hit_rate']:.3f} → {b['hit_rate']:.3f} "
            f"| {a['utilization_memory']:.3f} → {b['utilization_memory']:.3f} |")
    return "\n".join(lines)


def plot(docs: dict, path, title: str) -> None:
    """PNG: utilization with the node memory vs rays in flight (log x), per ray type, both
    formats (solid q8, dashed box32)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    for i, kind in enumerate(docs["q8"]["sweep"]):
        c = colours[i % len(colours)]
        for fmt, style in (("q8", "o-"), ("box32", "s--")):
            pts = docs[fmt]["sweep"][kind]
            ax.plot([p["rays_in_flight"] for p in pts],
                    [p["memory"]["replay_utilization"] for p in pts], style, color=c,
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
    """{"box32": doc, "q8": doc} from two bench JSON files of the same frame (ValueError)."""
    docs = {}
    for p in paths:
        try:
            with open(p) as f:
                doc = json.load(f)
        except (OSError, ValueError) as e:
            raise ValueError(f"{p}: not a readable bench JSON ({e})") from None
        fmt = doc.get("bvh_format")
        if fmt not in FORMATS or "by_type" not in doc or "memory" not in next(
                iter(doc["by_type"].values()), {}):
            raise ValueError(f"{p}: not a rayflex bench --workload JSON with the node memory")
        docs[fmt] = doc
    if set(docs) != set(FORMATS):
        raise ValueError("give one box32 and one q8 document")
    keys = ("scene", "workload", "width", "height", "spp", "bounces", "seed")
    if any(docs["box32"][k] != docs["q8"][k] for k in keys):
        raise ValueError("the two documents are not the same frame")
    return docs


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m driver.bvh.study", description=__doc__.split(
        "\n\n")[0])
    p.add_argument("json", nargs=2, help="the box32 and the q8 bench JSON")
    p.add_argument("--plot", metavar="PNG", help="draw the utilization sweep here")
    args = p.parse_args(argv)
    try:
        docs = load(args.json)
        table = rows(docs)
        if args.plot:
            from ..outputs import Outputs, PNG
            outs = Outputs()
            png = outs.add("--plot", args.plot, PNG)
            d = docs["q8"]
            with outs.commit():
                plot(docs, outs.temp(png), f"{d['scene']} {d['width']}x{d['height']} "
                     f"{d['workload']}, {d['spp']} spp: box32 vs q8 node images")
    except (ValueError, OSError) as e:
        print(f"rayflex: error: {e}", file=sys.stderr)
        return 2
    print(markdown(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
