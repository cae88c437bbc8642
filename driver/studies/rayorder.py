"""The ray-order study of docs/rayorder.md: per scene and ray type, every ray-order policy of the
RT unit (``driver.rtunit.order``) at every window, on the RT-unit model with the node memory;
with the treelet variants, its tables and its plot.
"""

from __future__ import annotations

from dataclasses import replace

from .. import backends, rtunit, workloads
from ..bvh4 import build
from ..core.progress import bar
from ..design import DesignPoint
from ..rtunit.gpu import derived
from ..rtunit.order import DEFAULT_TREELETS, POLICIES, floor_bytes, merge_costs
from ..stats import WAVEFRONTS
from ..tracer import trace
from ..core.layout import DEFAULT_FORMAT

ALL_RAYS = 1 << 16     # a window that holds every ray of the study's batches ("all")
STUDY_WINDOWS = (64, 256, 1024, 4096, ALL_RAYS)
STUDY_SCENES = ("bunny_floor", "cornell")
STUDY_TYPES = ("primary", "shadow", "bounce1", "bounce2", "ao")
_MEM_SUMMED = ("line_accesses", "line_hits", "line_misses", "bytes_from_memory",
               "node_wait_cycles")


def study_stats(replays: list) -> dict:
    """The study's ``rtunit_memory`` object of replays (``driver.rtunit.ReplayResult``) of a
    ray type's batches, each on its own (an empty ray pool and a cold node cache, the wavefront
    schedule of docs/rtunit.md), one after another: cycles add up."""
    if not replays:
        raise ValueError("no replay")
    first = replays[0]
    out = {"rays_in_flight": first.rays_in_flight, "pipelines": first.pipelines,
           "turnaround_cycles": first.turnaround, "rays": sum(r.rays for r in replays),
           "ops": sum(r.ops for r in replays), "cycles": sum(r.cycles for r in replays),
           "starved_cycles": sum(r.starved_cycles for r in replays),
           "sim_wall_s": sum(r.wall_s for r in replays),
           "responses_verified": (None if any(r.verified is None for r in replays)
                                  else all(r.verified for r in replays))}
    if first.memory:
        for k in _MEM_SUMMED:
            out[k] = sum(r.memory[k] for r in replays)
    out[WAVEFRONTS] = [_wavefront_row(r) for r in replays]
    costs = [r.order for r in replays if getattr(r, "order", None)]
    if costs:
        out["ray_order_cost"] = merge_costs(costs)
    return derived(out)


def _wavefront_row(r) -> dict:
    """One replayed wavefront of an RT-unit object's ``wavefronts``: its size and timing, and
    with a node memory its bytes from memory (each wavefront starts with an empty ray pool and
    a cold node cache, so a small one is bound by the memory's latency)."""
    row = {"rays": r.rays, "ops": r.ops, "cycles": r.cycles, "utilization": r.utilization}
    if r.memory:
        row["bytes_from_memory"] = r.memory["bytes_from_memory"]
    return row


def frame_records(scene_name: str, size: int, spp: int, bounces: int, ao_rays: int,
                  seed: int = 0, bvh_format: str = DEFAULT_FORMAT) -> dict:
    """{ray type: [Record, ...]}: the path frame's batches and the ao frame's ao rays, traced on
    "rtl" with every request recorded, on the scene's BVH in ``bvh_format``."""
    from ..scenes.scene import load_scene

    scene = load_scene(scene_name)
    setup = workloads.setup_for(scene)
    rtl = backends.backend("rtl")
    bvh = build(scene.triangles, format=bvh_format)

    def tracer(bvh_, o, d, **kw):
        return trace(bvh_, o, d, backend=rtl, record=True, **kw)

    out: dict = {}
    for workload, kinds in (("path", None), ("ao", ("ao",))):
        res = workloads.run(setup, bvh, size, size, tracer, workload, spp=spp, bounces=bounces,
                            ao_rays=ao_rays, seed=seed)
        for b in res.batches:
            if kinds is None or b.kind in kinds:
                out.setdefault(b.kind, []).append(b.result.record)
    return out


def window_label(w) -> str:
    return "all" if int(w) >= ALL_RAYS else str(w)


STUDY_FORMATS = (DEFAULT_FORMAT, "q8")
# the study's frames (path: 2 samples per pixel, 2 bounces; ao: 4 rays per hit) and RT unit (64
# rays in flight, the default node cache and memory)
STUDY_POINT = DesignPoint(spp=2, bounces=2, ao_rays=4, rays_in_flight=64)


def study(scenes=STUDY_SCENES, size: int = 64, windows=STUDY_WINDOWS, policies=None,
          point: DesignPoint = STUDY_POINT, progress: bool = True, formats=(DEFAULT_FORMAT,),
          variants: bool = False, variants_window: int = None) -> dict:
    """Every policy at every window on the path (and ao) frames of ``scenes`` at ``size`` x
    ``size``, for the BVH in each of ``formats``, on the RT unit of design point ``point`` (its
    samples per pixel, bounces, AO rays and seed make the frames; its rays in flight and node
    memory replay them; the default ``STUDY_POINT``): per ray type the node cache's hit rate,
    bytes from memory per ray,
    utilization with the node memory, cycles per frame and the policy's cost; index order once
    (it has no window), and the cold-cache floor of the bytes per ray. The document:
    ``formats.<format>.scenes.<scene>.<ray type>``; with ``variants``, ``treelet_variants``
    (``treelet_variants`` on the first scene and format, at ``variants_window``, default
    ``VARIANT_WINDOW``)."""

    def replay_all(records, r, order="index", window=None):
        """The RT-unit replays (with ``memory``) of a ray type's batches, one after another:
        the published ``rtunit_memory`` object (docs/statistics.md)."""
        return study_stats([rtunit.replay(rec, r, 1, memory=memory, ray_order=order,
                                          ray_window=window) for rec in records])

    spp, bounces, ao_rays, seed = point.spp, point.bounces, point.ao_rays, point.seed
    rays_in_flight, memory = point.rays_in_flight, point.memory()
    policies = list(policies or POLICIES)
    doc = {"size": size, "spp": spp, "bounces": bounces, "ao_rays": ao_rays,
           "rays_in_flight": rays_in_flight, "pipelines": 1, "memory": memory.describe(),
           "treelets": DEFAULT_TREELETS.describe(), "windows": list(windows),
           "policies": policies, "formats": {}}
    for fmt in formats:
        doc["formats"][fmt] = {"scenes": {}}
        for scene in scenes:
            recs = frame_records(scene, size, spp, bounces, ao_rays, seed, fmt)
            kinds = ([k for k in STUDY_TYPES if k in recs]
                     + [k for k in recs if k not in STUDY_TYPES])
            # "pool": index order with all W rays in the pool (R = W), the scheduler's rays
            # without the scheduler
            runs = [(k, p, w) for k in kinds for p in policies + ["pool"]
                    for w in ([None] if p == "index" else windows)]
            pb = bar(len(runs), f"{scene} ({fmt}): ray-order replays", "replay", progress)
            types = {}
            for n, (kind, pol, w) in enumerate(runs):
                t = types.setdefault(kind, {
                    "rays": sum(r.rays for r in recs[kind]),
                    "ops": sum(r.ops for r in recs[kind]), "batches": len(recs[kind]),
                    "floor_bytes_per_ray": floor_bytes(recs[kind], memory.line_bytes)
                    / max(1, sum(r.rays for r in recs[kind])), "policies": {}})
                if pol == "pool":
                    t.setdefault("pool", {})[str(w)] = replay_all(recs[kind], w)
                elif not (POLICIES[pol].schedule and w is not None and w < rays_in_flight):
                    point = replay_all(recs[kind], rays_in_flight, pol, w)
                    t["policies"].setdefault(pol, {})[str(w or 0)] = point
                pb.hook(n + 1, len(runs))
            pb.close()
            doc["formats"][fmt]["scenes"][scene] = types
            if variants and fmt == formats[0] and scene == scenes[0]:
                doc["treelet_variants"] = treelet_variants(
                    {k: recs[k] for k in VARIANT_TYPES if k in recs}, rays_in_flight, memory,
                    progress, variants_window or VARIANT_WINDOW)
    return doc


VARIANT_TYPES = ("shadow", "bounce1")
VARIANT_WINDOW = 256
# the treelet variants the study compares (changes from DEFAULT_TREELETS)
TREELET_VARIANTS = {
    "default": {},
    "no borrow": {"borrow": False},
    "no borrow, 64 active": {"borrow": False, "active": 64},
    "no borrow, any number active": {"borrow": False, "active": ALL_RAYS},
    "2 KiB treelets": {"treelet_bytes": 2048},
    "32 KiB treelets, 1 active": {"treelet_bytes": 32768, "active": 1},
    "no parking": {"park": False},
    "prefetch": {"prefetch": True},
}


def treelet_variants(recs: dict, rays_in_flight: int, memory, progress: bool = True,
                     window: int = VARIANT_WINDOW) -> dict:
    """The ``treelet`` policy under each of ``TREELET_VARIANTS`` at one window: per ray type of
    ``recs`` the published ``rtunit_memory`` object with the variant's configuration."""
    out = {"window": window, "variants": {}}
    runs = [(v, k) for v in TREELET_VARIANTS for k in recs]
    pb = bar(len(runs), "treelet variants", "replay", progress)
    for n, (name, kind) in enumerate(runs):
        cfg = replace(DEFAULT_TREELETS, **TREELET_VARIANTS[name])
        point = study_stats([rtunit.replay(r, rays_in_flight, 1, memory=memory,
                                           ray_order="treelet", ray_window=window, treelets=cfg)
                             for r in recs[kind]])
        out["variants"].setdefault(name, {"config": cfg.describe()})[kind] = point
        pb.hook(n + 1, len(runs))
    pb.close()
    return out


def plot_study(doc: dict, path) -> None:
    """PNG: utilization with the node memory vs window, one panel per format, scene and ray type,
    one line per policy (index order dashed; grey dotted: index order with all W rays in the
    pool); the window that holds every ray is drawn at ``ALL_RAYS``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = [(fmt, scene, types) for fmt, f in doc["formats"].items()
            for scene, types in f["scenes"].items()]
    kinds = [k for k in STUDY_TYPES if any(k in types for _, _, types in rows)]
    fig = Figure(figsize=(3.0 * len(kinds), 2.6 * len(rows)), dpi=90)
    FigureCanvasAgg(fig)
    colours = dict(zip(POLICIES, ["black", "tab:blue", "tab:orange", "tab:green", "tab:red",
                                  "tab:purple"]))
    ticks = [int(w) for w in doc["windows"]]
    for i, (fmt, scene, types) in enumerate(rows):
        for j, kind in enumerate(kinds):
            ax = fig.add_subplot(len(rows), len(kinds), i * len(kinds) + j + 1)
            t = types.get(kind)
            if t is None:
                ax.set_axis_off()
                continue
            for pol, pts in t["policies"].items():
                if pol == "index":
                    ax.axhline(pts["0"]["utilization"], color=colours.get(pol, "grey"),
                               ls="--", lw=1, label="index")
                    continue
                ws = sorted(int(w) for w in pts)
                ax.plot(ws, [pts[str(w)]["utilization"] for w in ws], "o-", ms=3,
                        color=colours.get(pol), label=pol)
            if "pool" in t:
                ws = sorted(int(w) for w in t["pool"])
                ax.plot(ws, [t["pool"][str(w)]["utilization"] for w in ws], ":",
                        color="grey", label="index, R = W")
            ax.set_xscale("log", base=2)
            ax.set_xticks(ticks)
            ax.set_xticklabels([window_label(w) for w in ticks])
            ax.minorticks_off()
            ax.set_ylim(0, 1.05)
            ax.grid(True, alpha=0.3)
            ax.set_title(f"{scene} {kind} ({fmt})", fontsize=9)
            if i == len(rows) - 1:
                ax.set_xlabel("window W (rays)", fontsize=8)
            if j == 0:
                ax.set_ylabel("utilization with memory", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"ray order: {doc['size']}x{doc['size']} path (spp {doc['spp']}, bounces "
                 f"{doc['bounces']}) and ao, R={doc['rays_in_flight']}, "
                 f"{doc['memory']['cache_bytes'] // 1024} KiB node cache", fontsize=10)
    fig.tight_layout()
    fig.savefig(str(path), format="png")


def summary_table(doc: dict, fmt: str, scene: str) -> str:
    """Markdown: per ray type of ``scene`` in ``fmt``, each policy at its window of highest
    utilization (utilization with memory / bytes per ray, the window), index order with W rays in
    the pool at its best W, and the cold-cache floor of bytes per ray."""
    types = doc["formats"][fmt]["scenes"][scene]
    pols = [p for p in doc["policies"]]
    out = ["| ray type | " + " | ".join(f"`{p}`" if p != "index" else p for p in pols)
           + " | index, R = W | floor B/ray |", "|---|" + "---|" * (len(pols) + 2)]
    for kind, t in types.items():
        cells = []
        for pts in [t["policies"].get(p, {}) for p in pols] + [t.get("pool", {})]:
            if not pts:
                cells.append("")
                continue
            w, v = max(pts.items(), key=lambda kv: (kv[1]["utilization"], -int(kv[0])))
            cells.append(f"{v['utilization']:.3f} / {v['bytes_per_ray']:.0f}"
                         + ("" if w == "0" else f" (W = {window_label(w)})"))
        out.append(f"| {kind} | " + " | ".join(cells) + f" | {t['floor_bytes_per_ray']:.0f} |")
    return "\n".join(out)


def study_tables(doc: dict) -> str:
    """Markdown tables of a ``study`` document: per format, scene and ray type, one row per
    policy, one column per window; each cell: utilization with memory / hit rate / bytes per ray
    / cycles; then the treelet variants."""
    ws = [str(w) for w in doc["windows"]]
    out = []
    for fmt, f in doc["formats"].items():
        for scene in f["scenes"]:
            out += [f"**Summary: {scene} ({fmt})**, each policy at its best window "
                    "(utilization with memory / bytes per ray)", "",
                    summary_table(doc, fmt, scene), ""]
    for fmt, f in doc["formats"].items():
        for scene, types in f["scenes"].items():
            for kind, t in types.items():
                out += [f"**{scene} {kind}** ({fmt}): {t['rays']} rays, {t['ops']} ops, "
                        f"cold-cache floor {t['floor_bytes_per_ray']:.0f} B/ray", "",
                        "| policy | " + " | ".join(f"W = {window_label(w)}" for w in ws) + " |",
                        "|---|" + "---|" * len(ws)]
                rows = dict(t["policies"])
                rows["index, R = W"] = t.get("pool", {})
                for pol, pts in rows.items():
                    cells = []
                    for w in ws:
                        v = pts.get("0" if pol == "index" else w)
                        cells.append("" if v is None else
                                     f"{v['utilization']:.3f} / {v['hit_rate']:.3f} / "
                                     f"{v['bytes_per_ray']:.0f} / {v['cycles']}")
                    out.append(f"| {pol} | " + " | ".join(cells) + " |")
                out.append("")
    var = doc.get("treelet_variants")
    if var:
        kinds = [k for k in VARIANT_TYPES if any(k in v for v in var["variants"].values())]
        out += [f"**treelet variants** (W = {window_label(var['window'])}; utilization / "
                "bytes per ray / "
                "picks)", "", "| variant | " + " | ".join(kinds) + " |",
                "|---|" + "---|" * len(kinds)]
        for name, v in var["variants"].items():
            out.append(f"| {name} | " + " | ".join(
                f"{v[k]['utilization']:.3f} / {v[k]['bytes_per_ray']:.0f} / "
                f"{v[k]['ray_order_cost']['picks']}" for k in kinds) + " |")
        out.append("")
    return "\n".join(out)
