"""Tables and plots of the one-kernel studies (docs/compressed.md, docs/rayorder.md,
docs/rtunit.md) from ``rayflex sweep --json`` documents:

    rayflex study gpu compressed docs/compressed_gpu.json [--plot PNG]
    rayflex study gpu schedules docs/compressed_schedules.json
    rayflex study gpu order docs/rayorder_gpu.json [--plot PNG]
    rayflex study gpu units docs/rtunit_units.json

In a one-kernel frame the ray types share the pipelines, so a frame is compared by its cycles and
utilization, and each ray type by its ops, the node bytes each memory level supplied per ray and
its latency (trace call to last response, mean and 95th percentile).
"""

from __future__ import annotations

import numpy as np
from ..core.layout import DEFAULT_FORMAT

LEVELS = ("l1", "l2", "dram")


def _points(doc: dict, **match) -> list[dict]:
    return [p for p in doc["points"]
            if all(p["design_point"][k] == v for k, v in match.items())]


def _one(doc: dict, **match) -> dict:
    pts = _points(doc, **match)
    if not pts:
        raise ValueError(f"no point with {match} in the sweep")
    return pts[0]


def _kinds(doc: dict) -> list[str]:
    return list(doc["points"][0]["by_type"])


def _type_row(t: dict) -> dict:
    m = t["rtunit_memory"]
    served = m["bytes_served_per_ray"]
    return {"rays": t["rays"], "ops_per_ray": t["ops"] / t["rays"] if t["rays"] else 0.0,
            **{f"{lvl}_bytes_per_ray": served[lvl] for lvl in LEVELS},
            "latency_mean": m["latency_mean"], "latency_p95": m["latency_p95"]}


def frame_row(p: dict, ref: dict | None = None) -> dict:
    """A point's frame figures (``rtunit_memory``), and its cycles over ``ref``'s."""
    m = p["rtunit_memory"]
    row = {"cycles": m["cycles"], "utilization": m["utilization"],
           "cycles_per_ray": m["cycles_per_ray"], "dram_bytes_per_ray": m["bytes_per_ray"],
           "l1_hit_rate": m["hit_rate"], "simt_efficiency": m["simt"]["simt_efficiency"],
           "latency_mean": m["latency_mean"], "latency_p95": m["latency_p95"],
           "memory_pj_per_ray": m["memory_energy"]["per_ray"]}
    if ref is not None:
        row["cycles_vs_ref"] = m["cycles"] / ref["rtunit_memory"]["cycles"]
    return row


def _group(p: dict) -> str:
    """A point's preset and frame size: the heading its rows go under."""
    dp = p["design_point"]
    return f"{dp['rt_preset']}, {dp['size']} x {dp['size']}"


def compressed(doc: dict) -> dict:
    """Per preset and frame size, per node format: the frame's figures (cycles over box32's)
    and each ray type's."""
    out: dict = {}
    for p in doc["points"]:
        dp = p["design_point"]
        ref = _one(doc, rt_preset=dp["rt_preset"], size=dp["size"], bvh_format=DEFAULT_FORMAT)
        out.setdefault(_group(p), {})[dp["bvh_format"]] = {
            "frame": frame_row(p, ref),
            "by_type": {k: _type_row(t) for k, t in p["by_type"].items()}}
    return out


def compressed_markdown(doc: dict) -> str:
    tab = compressed(doc)
    lines = []
    for preset, fmts in tab.items():
        lines += [f"**{preset}**: the frame", "",
                  "| image | cycles | vs box32 | utilization | DRAM B/ray | L1 hit rate "
                  "| latency mean / p95 | memory pJ/ray |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for fmt, r in fmts.items():
            f = r["frame"]
            lines.append(f"| {fmt} | {f['cycles']:,} | {f['cycles_vs_ref']:.3f} "
                         f"| {f['utilization']:.3f} | {f['dram_bytes_per_ray']:.0f} "
                         f"| {f['l1_hit_rate']:.3f} | {f['latency_mean']:,.0f} / "
                         f"{f['latency_p95']:,.0f} | {f['memory_pj_per_ray']:,.0f} |")
        lines += ["", f"**{preset}**: per ray type (bytes per ray supplied by each level)", "",
                  "| ray type | image | ops/ray | L1 B/ray | L2 B/ray | DRAM B/ray "
                  "| latency mean | latency p95 |", "|---|---|---:|---:|---:|---:|---:|---:|"]
        for kind in next(iter(fmts.values()))["by_type"]:
            for fmt, r in fmts.items():
                t = r["by_type"][kind]
                lines.append(f"| {kind} | {fmt} | {t['ops_per_ray']:.2f} "
                             f"| {t['l1_bytes_per_ray']:.0f} | {t['l2_bytes_per_ray']:.0f} "
                             f"| {t['dram_bytes_per_ray']:.0f} | {t['latency_mean']:,.0f} "
                             f"| {t['latency_p95']:,.0f} |")
        lines.append("")
    return "\n".join(lines)


SCHEDULES = (("wavefront", True, "wavefront, cold caches"),
             ("wavefront", False, "wavefront, warm caches"),
             ("one-kernel", False, "one kernel"))


def schedules_markdown(doc: dict) -> str:
    """Per node format: the frame under each schedule; each ray type's utilization where the
    schedule gives it one, and its latency and DRAM bytes per ray."""
    kinds = _kinds(doc)
    head = ("| image | schedule | frame cycles | utilization | DRAM B/ray | "
            + " | ".join(f"{k}: util / lat / DRAM B" for k in kinds) + " |")
    lines = [head, "|---|---|---:|---:|---:|" + "---:|" * len(kinds)]
    for fmt in dict.fromkeys(p["design_point"]["bvh_format"] for p in doc["points"]):
        for frame, flush, label in SCHEDULES:
            p = _one(doc, bvh_format=fmt, frame_schedule=frame, flush_between=flush)
            m = p["rtunit_memory"]
            cells = []
            for k in kinds:
                t = p["by_type"][k]["rtunit_memory"]
                u = "—" if t["utilization"] is None else f"{t['utilization']:.3f}"
                cells.append(f"{u} / {t['latency_mean']:,.0f} / {t['bytes_per_ray']:.0f}")
            lines.append(f"| {fmt} | {label} | {m['cycles']:,} | {m['utilization']:.3f} "
                         f"| {m['bytes_per_ray']:.0f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def order(doc: dict) -> dict:
    """Per preset and frame size, format, policy and window: the frame's figures and the
    policy's cost (index order once: it has no window)."""
    out: dict = {}
    for p in doc["points"]:
        dp = p["design_point"]
        key = "index" if dp["ray_order"] == "index" else f"{dp['ray_order']} W={dp['ray_window']}"
        ref = _one(doc, rt_preset=dp["rt_preset"], size=dp["size"], bvh_format=dp["bvh_format"],
                   ray_order="index")
        row = frame_row(p, ref)
        cost = p["rtunit_memory"].get("ray_order_cost") or {}
        row["extra_state_bytes"] = cost.get("extra_state_bytes", 0)
        row["by_type"] = {k: _type_row(t) for k, t in p["by_type"].items()}
        out.setdefault(_group(p), {}).setdefault(dp["bvh_format"], {}).setdefault(key, row)
    return out


def order_markdown(doc: dict) -> str:
    tab = order(doc)
    kinds = _kinds(doc)
    lines = []
    for preset, fmts in tab.items():
        for fmt, rows in fmts.items():
            lines += [f"**{preset}, {fmt}**", "",
                      "| policy | frame cycles | vs index | utilization | DRAM B/ray "
                      "| extra state B | " + " | ".join(f"{k} latency" for k in kinds) + " |",
                      "|---|---:|---:|---:|---:|---:|" + "---:|" * len(kinds)]
            for key, r in rows.items():
                lines.append(f"| {key} | {r['cycles']:,} | {r['cycles_vs_ref']:.3f} "
                             f"| {r['utilization']:.3f} | {r['dram_bytes_per_ray']:.0f} "
                             f"| {r['extra_state_bytes']:,} | "
                             + " | ".join(f"{r['by_type'][k]['latency_mean']:,.0f}"
                                          for k in kinds) + " |")
            lines.append("")
    return "\n".join(lines)


def units_markdown(doc: dict) -> str:
    lines = ["| RT units | frame cycles | utilization | DRAM B/ray | L2 hit rate | latency mean "
             "/ p95 | replay wall s |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for p in doc["points"]:
        m = p["rtunit_memory"]
        l2 = m["levels"]["l2"]["hit_rate"]
        lines.append(f"| {m['rt_units']} | {m['cycles']:,} | {m['utilization']:.3f} "
                     f"| {m['bytes_per_ray']:.0f} | {l2:.3f} | {m['latency_mean']:,.0f} / "
                     f"{m['latency_p95']:,.0f} | {p['wall_s']:.1f} |")
    return "\n".join(lines)


def plot_compressed(doc: dict, path) -> None:
    """PNG: one panel per preset and frame size: each ray type's mean latency (trace call to its
    last response) per node format, the frame's cycles and utilization in the legend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    tab = compressed(doc)
    presets = list(tab)
    cols = min(2, len(presets))
    rows = -(-len(presets) // cols)
    fig = Figure(figsize=(6.0 * cols, 4.2 * rows), dpi=110)
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(rows, cols, i + 1) for i in range(len(presets))]
    for ax, preset in zip(axes, presets):
        fmts = list(tab[preset])
        kinds = list(tab[preset][fmts[0]]["by_type"])
        x = np.arange(len(kinds))
        w = 0.8 / len(fmts)
        top = max(tab[preset][f]["by_type"][k]["latency_mean"] for f in fmts for k in kinds)
        ax.set_ylim(0, top * 1.35)                    # room for the legend above the bars
        for j, fmt in enumerate(fmts):
            lat = [tab[preset][fmt]["by_type"][k]["latency_mean"] for k in kinds]
            f = tab[preset][fmt]["frame"]
            ax.bar(x + (j - (len(fmts) - 1) / 2) * w, lat, w, color=f"C{j}",
                   label=f"{fmt}: frame {f['cycles']:,} cycles, utilization "
                         f"{f['utilization']:.2f}")
        ax.set_xticks(x)
        ax.set_xticklabels(kinds)
        ax.set_ylabel("mean latency per ray (cycles)", fontsize=8)
        ax.set_title(f"{preset}, one-kernel frame", fontsize=9)
        ax.tick_params(axis="x", labelsize=8)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{doc['scene']} {doc['workload']}: node formats on a GPU's RT units",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(str(path), format="png")


def plot_order(doc: dict, path) -> None:
    """PNG: per preset and format, the frame's cycles relative to index order per policy."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    tab = order(doc)
    fig = Figure(figsize=(12.0, 4.8), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    groups = [(pr, fmt) for pr in tab for fmt in tab[pr]]
    keys = list(dict.fromkeys(k for pr, fmt in groups for k in tab[pr][fmt]))
    x = np.arange(len(groups))
    w = 0.8 / len(keys)
    for j, key in enumerate(keys):
        ys = [tab[pr][fmt].get(key, {}).get("cycles_vs_ref", np.nan) for pr, fmt in groups]
        ax.bar(x + (j - (len(keys) - 1) / 2) * w, ys, w, color=f"C{j}", label=key)
    ax.axhline(1.0, color="grey", lw=1, ls=":")
    ax.set_xticks(x)
    ax.set_xticklabels([pr.replace(", ", "\n") + f"\n{fmt}" for pr, fmt in groups],
                       fontsize=7)
    ax.set_ylabel("frame cycles / index order's (axis from 0.5)")
    ax.set_ylim(0.5, 1.15)
    ax.set_title(f"{doc['scene']} {doc['workload']}, one-kernel frame: ray order in the RT "
                 "units", fontsize=9)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7, title="policy (W: rays held per unit)", title_fontsize=7,
              loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(str(path), format="png")


TABLES = {"compressed": (compressed_markdown, plot_compressed),
          "schedules": (schedules_markdown, None),
          "order": (order_markdown, plot_order),
          "units": (units_markdown, None)}
