"""The power report: the paper's ratios side by side, markdown tables, the plot, energy per ray.

``PAPER`` holds the paper's power-vs-operation results (section "Power Consumption"): the
extended datapath costs +18 % (box) / +20 % (triangle) over the baseline; disjoint vs unified is
within +-2.5 % for box/triangle, -9 % Euclidean, -3 % cosine; all at 60-85 mW at 1 GHz, i.e.
60-85 pJ per operation at one operation per cycle.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..area import config_params
from ..core.configs import Q8_SUFFIX, XF_SUFFIX
from ..core.provenance import provenance
from . import stimulus
from .netlist import STAGE_LABELS
from ..core.layout import FORMATS

PAPER = {
    "source": "RayFlex paper, Power Consumption (Genus, VCD of 100 random tests, 1 GHz)",
    "extended_vs_baseline": {"box": 0.18, "triangle": 0.20},
    "disjoint_vs_unified": {"box": [-0.025, 0.025], "triangle": [-0.025, 0.025],
                            "euclidean": -0.09, "cosine": -0.03},
    "power_mW_at_1GHz": [60, 85],
}
UNITS = {"signals": "bit toggles", "gates": "fan-out-weighted toggles", "liberty": "pJ"}


def _e(cfgs, cfg, op):
    r = cfgs.get(cfg, {}).get(op, {})
    return r.get("energy_per_op")


def _rel(a, b):
    return None if a is None or b in (None, 0) else round(a / b - 1, 4)


def base_of(cfg: str) -> str:
    """The base configuration of ``cfg`` (without the q8 decode and TRANSFORM suffixes)."""
    return cfg.removesuffix(XF_SUFFIX).removesuffix(Q8_SUFFIX)


def _share(cfgs, cfg, op, stage):
    st = cfgs.get(cfg, {}).get(op, {}).get("stages") or {}
    return st.get(stage)


def ratios(cfgs: dict) -> dict:
    """The paper's comparisons on our numbers (relative change, 0.18 = +18 %), and for the
    configurations with the q8 decode or TRANSFORM what those cost: ``q8_decode`` (per -q8
    configuration: box_q8 vs box_q8_host, the same nodes decoded on the host, on it and on its
    base configuration; box on it vs box on the base; the decode stage S0's share of a box_q8
    op and its energy) and
    ``transform_op`` (per -xf configuration: transform vs box and triangle on it, box and
    triangle vs the base)."""
    out = {"extended_vs_baseline": {}, "disjoint_vs_unified": {}, "triangle_vs_box": {},
           "q8_decode": {}, "transform_op": {}}
    for kind in ("unified", "disjoint"):
        out["extended_vs_baseline"][kind] = {
            op: _rel(_e(cfgs, f"extended-{kind}", op), _e(cfgs, f"baseline-{kind}", op))
            for op in ("box", "triangle")}
    for kind in ("baseline", "extended"):
        ops = stimulus.measurable({"EXTENDED": kind == "extended"})
        out["disjoint_vs_unified"][kind] = {
            op: _rel(_e(cfgs, f"{kind}-disjoint", op), _e(cfgs, f"{kind}-unified", op))
            for op in ops}
    for cfg in cfgs:
        t, b = _e(cfgs, cfg, "triangle"), _e(cfgs, cfg, "box")
        out["triangle_vs_box"][cfg] = None if t is None or not b else round(t / b, 4)
        base = base_of(cfg)
        q8 = _e(cfgs, cfg, "box_q8")
        if q8 is not None:
            s0 = _share(cfgs, cfg, "box_q8", "S0")
            out["q8_decode"][cfg] = {
                "base": base, "box_q8_vs_host": _rel(q8, _e(cfgs, cfg, "box_q8_host")),
                "box_q8_vs_base_host": _rel(q8, _e(cfgs, base, "box_q8_host")),
                "box_vs_base_box": _rel(b, _e(cfgs, base, "box")),
                "decode_share": s0, "decode_energy": None if s0 is None else q8 * s0,
                "decode_share_of_box": _share(cfgs, cfg, "box", "S0")}
        x = _e(cfgs, cfg, "transform")
        if x is not None:
            out["transform_op"][cfg] = {
                "base": base, "transform_vs_box": _rel(x, b), "transform_vs_triangle": _rel(x, t),
                "box_vs_base_box": _rel(b, _e(cfgs, base, "box")),
                "triangle_vs_base_triangle": _rel(t, _e(cfgs, base, "triangle"))}
    return out


def frame_mix(point, progress: bool = False) -> dict:
    """The operation mix per ray type of design point ``point``'s workload frame (golden
    traversal, its BVH options): {type: {box_ops, tri_ops, rays}}."""
    from ..render import render
    stats = render(point.scene, point.size, point.size, backend="golden", progress=progress,
                   point=point).stats
    return mix_of(stats)


def mix_of(stats: dict) -> dict:
    if stats.get("by_type"):
        return {t: {k: int(v[k]) for k in ("box_ops", "tri_ops", "rays")}
                for t, v in stats["by_type"].items()}
    return {"primary": {k: int(stats[k]) for k in ("box_ops", "tri_ops", "rays")}}


def per_ray(mix: dict, cfgs: dict, q8_image: bool = False) -> dict:
    """Energy per ray and per frame for each ray type and configuration (box/triangle energy;
    ``q8_image``: the frame's BVH is a q8 image, its box ops are ``stimulus.box_op``'s)."""
    out = {}
    for rtype, m in mix.items():
        row = {"rays": m["rays"], "box_ops_per_ray": m["box_ops"] / m["rays"] if m["rays"] else 0,
               "tri_ops_per_ray": m["tri_ops"] / m["rays"] if m["rays"] else 0, "configs": {}}
        for cfg in cfgs:
            bop = stimulus.box_op(config_params(cfg), q8_image)
            eb, et = _e(cfgs, cfg, bop), _e(cfgs, cfg, "triangle")
            if eb is None or et is None:
                continue
            frame = m["box_ops"] * eb + m["tri_ops"] * et
            row["configs"][cfg] = {"energy_per_ray": frame / m["rays"] if m["rays"] else 0.0,
                                   "energy_per_frame": frame, "box_op": bop}
            tb = cfgs[cfg].get(bop, {}).get("energy_per_op_total")
            tt = cfgs[cfg].get("triangle", {}).get("energy_per_op_total")
            if tb is not None and tt is not None:      # liberty: with clock pins and leakage
                total = m["box_ops"] * tb + m["tri_ops"] * tt
                row["configs"][cfg]["energy_per_ray_total"] = total / m["rays"] if m["rays"] \
                    else 0.0
                row["configs"][cfg]["energy_per_frame_total"] = total
        out[rtype] = row
    return out


def build(level: str, res: dict, n: int, seed: int, mix: dict, point, cfgs,
          liberty=None) -> dict:
    """The report: energy per op of every configuration, the paper's ratios, and the energy per
    ray of every ray type of ``point``'s workload (``mix``, ``frame_mix``)."""
    cfg_results = res["configs"]
    prov = provenance(point)
    prov["design_point"]["config"] = list(cfgs)        # power measures every one listed
    rep = {"provenance": prov, "level": level, "unit": UNITS[level], "ops_per_type": n,
           "stimulus_seed": seed, "configs": cfg_results, "ratios": ratios(cfg_results),
           "paper": PAPER, "pending": stimulus.pending(),
           "per_ray": per_ray(mix, cfg_results, FORMATS[point.bvh_format].compressed)}
    if "synth_s" in res:
        rep["synthesis"] = res["synth_s"]
    if liberty:
        rep["liberty"] = str(liberty)
    return rep


def _fmt(x, digits=3):
    if x is None:
        return "–"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{digits}g}"


def _pct(x):
    if x is None:
        return "–"
    if isinstance(x, list):
        return f"{x[0] * 100:+.1f} … {x[1] * 100:+.1f} %"
    return f"{x * 100:+.1f} %"


def markdown(rep: dict) -> str:
    """Energy per operation per configuration, the ratios next to the paper's, stage shares."""
    cfgs = rep["configs"]
    ops = [op for op in stimulus.OPS if any(op in r for r in cfgs.values())]
    lines = [f"Energy per operation ({rep['unit']}; level {rep['level']}, "
             f"{rep['ops_per_type']} ops per type, stimulus seed {rep['stimulus_seed']})", "",
             *(["(in parentheses: with every flip-flop's clock pin and the leakage of the "
                "cycle, i.e. the power at 1 GHz in mW)", ""] if rep["level"] == "liberty"
               else []),
             "| configuration | " + " | ".join(ops) + " | idle per cycle |",
             "|---|" + "---:|" * (len(ops) + 1)]
    for cfg, r in cfgs.items():
        cells = []
        for op in ops:
            v = r.get(op, {})
            cell = "pending" if "pending" in v else _fmt(v.get("energy_per_op"))
            if "energy_per_op_total" in v:
                cell += f" ({_fmt(v['energy_per_op_total'])})"
            cells.append(cell)
        idle = r["idle_per_cycle"]
        cells.append(_fmt(idle["energy"]) + (f" ({_fmt(idle['energy_total'])})"
                                             if "energy_total" in idle else ""))
        lines.append(f"| {cfg} | " + " | ".join(cells) + " |")
    rt, paper = rep["ratios"], rep["paper"]
    lines += ["", "| comparison | op | ours | paper |", "|---|---|---:|---:|"]
    for kind, row in rt["extended_vs_baseline"].items():
        for op, v in row.items():
            if v is not None:
                lines.append(f"| extended vs baseline ({kind}) | {op} | {_pct(v)} | "
                             f"{_pct(paper['extended_vs_baseline'].get(op))} |")
    for kind, row in rt["disjoint_vs_unified"].items():
        for op, v in row.items():
            if v is not None:
                lines.append(f"| disjoint vs unified ({kind}) | {op} | {_pct(v)} | "
                             f"{_pct(paper['disjoint_vs_unified'].get(op))} |")
    for cfg, v in rt["triangle_vs_box"].items():
        if v is not None:
            lines.append(f"| triangle / box ({cfg}) | – | {v:.3f} | – |")
    for cfg, q in rt.get("q8_decode", {}).items():
        lines += [f"| box_q8 vs box_q8_host ({cfg}) | box_q8 | {_pct(q['box_q8_vs_host'])} "
                  "| – |",
                  f"| {cfg} vs {q['base']} | box_q8 vs box_q8_host | "
                  f"{_pct(q['box_q8_vs_base_host'])} | – |",
                  f"| {cfg} vs {q['base']} | box | {_pct(q['box_vs_base_box'])} | – |",
                  f"| decode stage S0, share of box_q8 ({cfg}) | box_q8 | "
                  f"{_pct(q['decode_share']).lstrip('+')} | – |"]
    for cfg, x in rt.get("transform_op", {}).items():
        lines += [f"| transform vs box ({cfg}) | transform | {_pct(x['transform_vs_box'])} | – |",
                  f"| transform vs triangle ({cfg}) | transform | "
                  f"{_pct(x['transform_vs_triangle'])} | – |",
                  f"| {cfg} vs {x['base']} | box | {_pct(x['box_vs_base_box'])} | – |",
                  f"| {cfg} vs {x['base']} | triangle | {_pct(x['triangle_vs_base_triangle'])} "
                  "| – |"]
    rows = [(cfg, op, r[op]["stages"]) for cfg, r in cfgs.items() for op in ops
            if r.get(op, {}).get("stages")]
    labels = stage_columns([st for _, _, st in rows])
    lines += ["", "Share of each operation's energy by stage (%):", "",
              "| configuration | op | " + " | ".join(labels) + " |",
              "|---|---|" + "---:|" * len(labels)]
    for cfg, op, st in rows:
        lines.append(f"| {cfg} | {op} | " + " | ".join(
            f"{st.get(s, 0) * 100:.1f}" for s in labels) + " |")
    if rep.get("per_ray"):
        dp = rep["provenance"]["design_point"]
        lines += ["", f"Energy per ray ({rep['unit']}) of {dp['scene']} {dp['workload']} "
                      f"(size {dp['size'] or 'of the scene'}, spp {dp['spp']}):", "",
                  "| ray type | box ops/ray | tri ops/ray | " + " | ".join(cfgs) + " |",
                  "|---|---:|---:|" + "---:|" * len(cfgs)]
        for rtype, row in rep["per_ray"].items():
            lines.append(f"| {rtype} | {row['box_ops_per_ray']:.2f} | "
                         f"{row['tri_ops_per_ray']:.2f} | " + " | ".join(
                             _fmt(row["configs"].get(c, {}).get("energy_per_ray"))
                             for c in cfgs) + " |")
    if rep.get("pending"):
        lines += [""] + [f"{op}: {why}" for op, why in rep["pending"].items()]
    return "\n".join(lines)


def stage_columns(stages: list[dict]) -> list[str]:
    """The stage labels (``netlist.STAGE_LABELS`` order) with a share in some of ``stages``
    (the decode stage S0 only when a configuration has it)."""
    return [s for s in STAGE_LABELS if any(st.get(s) for st in stages)]


def plot(rep: dict, path) -> None:
    """Grouped bars of energy per operation, one group per operation, one bar per configuration
    (the layout of the paper's power-vs-operation figure)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cfgs = rep["configs"]
    ops = [op for op in stimulus.OPS if any("energy_per_op" in r.get(op, {})
                                           for r in cfgs.values())]
    fig, ax = plt.subplots(figsize=(max(7.0, 1.1 * len(ops) + 1.5), 3.8), dpi=120)
    width = 0.8 / max(1, len(cfgs))
    x = np.arange(len(ops))
    for i, (cfg, r) in enumerate(cfgs.items()):
        vals = [r.get(op, {}).get("energy_per_op", np.nan) for op in ops]
        bars = ax.bar(x + (i - (len(cfgs) - 1) / 2) * width, vals, width, label=cfg)
        ax.bar_label(bars, labels=["" if np.isnan(v) else _fmt(v) for v in vals], fontsize=6,
                     rotation=90, padding=2)
    ax.set_xticks(x, ops, rotation=20, ha="right", fontsize=8)
    unit = rep["unit"] + (f", {Path(rep['liberty']).stem}" if rep.get("liberty") else "")
    ax.set_ylabel(f"energy per operation ({unit})", fontsize=8)
    ax.set_title(f"RayFlex energy per operation, level {rep['level']} "
                 f"({rep['ops_per_type']} random back-to-back ops per stream)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.margins(y=0.2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
