"""A suite's summary (``driver.suite``): one row per run, ``summary.json`` and ``summary.csv``,
the figure a paper would show (``summary.png``: per run ops per ray, RT-unit utilization with
the node memory, bytes per ray, node cache hit rate and energy per ray, runs grouped by shader),
every run's image on one sheet (``images.png``) and the Markdown table of docs/lumibench.md."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from PIL import Image

from .core.outputs import jsonable
from .core.provenance import provenance
from .core.words import plural
from .plotting import describe, wrap


ROW_KEYS = ("name", "scene", "workload", "size", "spp", "partial", "rays", "hits",
            "ops_per_ray", "box_ops_per_ray", "tri_ops_per_ray", "utilization_memory",
            "utilization", "hit_rate", "bytes_per_ray", "energy_per_ray_signals",
            "replay_cycles_ratio", "agree",
            "edge_tie",
            "embree_wrong", "datapath_wrong", "wall_s")


def row(name: str, doc: dict) -> dict:
    """One run's summary row (``ROW_KEYS``). A run on the RT unit in RTL (``unit_rtl``) gives
    the unit's utilization and its replay's cycles over the unit's."""
    unit = doc.get("unit_rtl") or {}
    mem = doc.get("rtunit_memory") or {"utilization": unit.get("utilization")}
    plain = doc.get("rtunit") or {}
    cls = ((doc.get("embree") or {}).get("adjudicated") or {}).get("classes", {})
    rays = doc.get("rays", 0)
    return {"name": name, "scene": doc["run"]["scene"], "workload": doc["run"]["workload"],
            "size": doc["width"], "spp": doc["run"]["spp"],
            "partial": bool((doc.get("lumibench") or {}).get("partial", False)),
            "rays": rays, "hits": doc.get("hits"),
            "ops_per_ray": doc.get("ops", 0) / rays if rays else 0.0,
            "box_ops_per_ray": doc.get("box_ops_per_ray"),
            "tri_ops_per_ray": doc.get("tri_ops_per_ray"),
            "utilization_memory": mem.get("utilization"), "utilization": plain.get("utilization"),
            "hit_rate": mem.get("hit_rate"), "bytes_per_ray": mem.get("bytes_per_ray"),
            "energy_per_ray_signals": (doc.get("energy_per_ray") or {}).get("signals"),
            "replay_cycles_ratio": unit.get("replay_cycles_ratio"),
            **{c: cls.get(c) for c in ("agree", "edge_tie", "embree_wrong", "datapath_wrong")},
            "wall_s": doc.get("timing", {}).get("wall_s")}


def summary(name, runs, done, skipped, base, backend, root, wall, made, workers,
            scheduler) -> dict:
    """The suite's summary: one ``row`` per run made, the runs skipped, the partial scenes, the
    totals of the check's classes, the wall time."""
    rows = [row(r.name, done[r.name]) for r in runs if r.name in done]
    wrong = sum(r["datapath_wrong"] or 0 for r in rows)
    partial = {}
    for r in runs:
        info = done.get(r.name, {}).get("lumibench") or {}
        if info.get("partial"):
            partial[info["id"]] = info["missing"]
    return {"provenance": provenance(base), "suite": name, "backend": backend,
            "root": str(root) if root else None, "runs": rows,
            "skipped": skipped, "partial": partial, "datapath_wrong": wrong,
            "totals": {"runs": len(rows), "rays": sum(r["rays"] for r in rows),
                       **{c: sum(r[c] or 0 for r in rows)
                          for c in ("agree", "edge_tie", "embree_wrong", "datapath_wrong")}},
            "wall_s": wall, "runs_made": made, "workers": workers, "scheduler": scheduler}


def write_summary(out: Path, summary: dict) -> None:
    """summary.json, summary.csv and, with any run, summary.png and images.png, each
    atomically."""
    tmp = out / ".summary.json.tmp"
    tmp.write_text(json.dumps(jsonable(summary), indent=1) + "\n")
    tmp.replace(out / "summary.json")
    tmp = out / ".summary.csv.tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ROW_KEYS)
        w.writeheader()
        for r in summary["runs"]:
            w.writerow(r)
    tmp.replace(out / "summary.csv")
    if summary["runs"]:
        for name, data in (("summary.png", figure(summary)), ("images.png", sheet(out, summary))):
            tmp = out / f".{name}.tmp"
            tmp.write_bytes(data)
            tmp.replace(out / name)


def markdown_table(summary: dict) -> str:
    """The summary's runs as a Markdown table (docs/lumibench.md shows it; a test checks the
    page against the JSON)."""
    lines = ["| run | rays | ops / ray | RT-unit utilization | bytes / ray | node cache hit rate "
             "| energy / ray (M toggles) | agree | edge tie | Embree wrong | datapath wrong "
             "| wall |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    fmt = lambda v, f: "–" if v is None else format(v, f)  # noqa: E731
    for r in summary["runs"]:
        e = r["energy_per_ray_signals"]
        lines.append(
            f"| {r['name']}{' (partial)' if r['partial'] else ''} | {r['rays']:,} | "
            f"{fmt(r['ops_per_ray'], '.1f')} | {fmt(r['utilization_memory'], '.2f')} | "
            f"{fmt(r['bytes_per_ray'], ',.0f')} | {fmt(r['hit_rate'], '.3f')} | "
            f"{fmt(None if e is None else e / 1e6, '.2f')} | {r['agree']:,} | "
            f"{r['edge_tie']:,} | {r['embree_wrong']:,} | {r['datapath_wrong']:,} | "
            f"{fmt(r['wall_s'], '.1f')} s |")
    t = summary["totals"]
    lines.append(f"| all {plural(t['runs'], 'run')} | {t['rays']:,} | | | | | | {t['agree']:,} | "
                 f"{t['edge_tie']:,} | {t['embree_wrong']:,} | {t['datapath_wrong']:,} | "
                 f"{summary['wall_s']:.0f} s |")
    return "\n".join(lines)


PANELS = (("ops_per_ray", "datapath ops per ray", None, 1.0),
          ("utilization_memory", "RT-unit utilization\n(node cache + memory)", (0.0, 1.0), 1.0),
          ("bytes_per_ray", "bytes from memory per ray", None, 1.0),
          ("hit_rate", "node cache hit rate", (0.0, 1.0), 1.0),
          ("energy_per_ray_signals", "energy per ray\n(million bit toggles)", None, 1e-6))


def figure(summary: dict) -> bytes:
    """PNG bytes: one panel per figure of ``PANELS``, one bar per run, runs grouped by shader
    (workload), scenes in the same order in every group."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    rows = summary["runs"]
    groups = list(dict.fromkeys(r["workload"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    colours = {s: c for s, c in zip(scenes, ["#4C72B0", "#DD8452", "#55A868", "#C44E52",
                                             "#8172B3", "#937860", "#DA8BC3", "#8C8C8C",
                                             "#CCB974", "#64B5CD"] * 4)}
    fig = Figure(figsize=(2.5 * len(PANELS) + 1.1, 3.3), dpi=110)
    FigureCanvasAgg(fig)
    width = 0.8 / max(len(scenes), 1)
    for i, (k, label, ylim, scale) in enumerate(PANELS):
        ax = fig.add_subplot(1, len(PANELS), i + 1)
        for j, s in enumerate(scenes):
            xs, ys = [], []
            for g, wl in enumerate(groups):
                v = [r[k] for r in rows if r["scene"] == s and r["workload"] == wl]
                if v and v[0] is not None:
                    xs.append(g - 0.4 + width * (j + 0.5))
                    ys.append(v[0] * scale)
            ax.bar(xs, ys, width * 0.92, color=colours[s], label=_short(s))
        ax.set_xticks(range(len(groups)))
        ax.set_xticklabels([_short(g).upper() for g in groups], fontsize=8)
        ax.set_title(label, fontsize=9)
        ax.tick_params(axis="y", labelsize=7)
        if ylim:
            ax.set_ylim(*ylim)
        else:
            ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False,
               title="scene", title_fontsize=8)
    dp = (summary.get("provenance") or {}).get("design_point") or {}
    fig.suptitle(wrap(f"suite {summary['suite']}: {plural(len(rows), 'run')} on the RTL; "
                      + describe(dp, parts=("datapath", "bvh", "rtunit")), 150), fontsize=9)
    fig.tight_layout(rect=(0, 0, 1 - 0.9 / fig.get_figwidth(), 0.93))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def sheet(out: Path, summary: dict) -> bytes:
    """PNG bytes: every run's image, one row per scene, one column per workload."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    rows = summary["runs"]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    groups = list(dict.fromkeys(r["workload"] for r in rows))
    fig = Figure(figsize=(1.9 * len(groups) + 0.2, 1.9 * len(scenes) + 0.4), dpi=110)
    FigureCanvasAgg(fig)
    for i, sc in enumerate(scenes):
        for j, wl in enumerate(groups):
            ax = fig.add_subplot(len(scenes), len(groups), i * len(groups) + j + 1)
            ax.set_axis_off()
            run = [r for r in rows if r["scene"] == sc and r["workload"] == wl]
            if run and (out / f"{run[0]['name']}.png").is_file():
                with Image.open(out / f"{run[0]['name']}.png") as im:
                    ax.imshow(im.convert("RGB"), interpolation="nearest")
                ax.set_title(run[0]["name"] + (" (partial)" if run[0]["partial"] else ""),
                             fontsize=7)
    fig.suptitle(f"suite {summary['suite']}: every run's image", fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _short(text: str) -> str:
    return text.split(":", 1)[-1].removeprefix("lumibench-")
