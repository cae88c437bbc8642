"""Plots of a frame's RT-unit replays (``driver.rtunit.gpu``; ``rayflex bench --workload``):
the rays each RT unit holds over the frame, and utilization over rays in flight."""

from __future__ import annotations

from .plotting import legend_under, wrap

MARKERS = ("o", "s", "^", "D", "v", "P")     # one per ray type: coinciding curves stay apart


def plot_rays_held(frame: dict, path, title: str) -> None:
    """PNG: rays held per RT unit (admitted, not done) over the frame's cycles, for each replay
    of the frame (``rtunit_memory``, and ``rtunit`` when there is one), with the unit's ray pool
    as a dotted line."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.4, 4.8), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    pool = frame["rtunit_memory"]["rays_in_flight"]
    for key, style, label in (("rtunit_memory", "-", "with the memory hierarchy"),
                              ("rtunit", "--", "node fetches free")):
        r = frame.get(key)
        series = (r or {}).get("simt", {}).get("rays_held_series")
        if not series:
            continue
        b = series["bin_cycles"]
        pts = series["per_unit"]
        ax.plot([b * (i + 0.5) for i in range(len(pts))], pts, style, lw=1.5,
                label=f"{label} ({r['cycles']:,} cycles, utilization {r['utilization']:.2f})")
    ax.axhline(pool, color="grey", ls=":", lw=1, label=f"ray pool ({pool} rays)")
    ax.set_ylim(0, pool * 1.1)
    ax.set_xlim(left=0)
    ax.set_xlabel("cycle")
    ax.set_ylabel("rays held per RT unit (mean over the units)")
    ax.grid(True, alpha=0.3)
    legend_under(ax, ncol=2, fontsize=7)
    ax.set_title(wrap(title, 90), fontsize=8)
    fig.tight_layout()
    fig.savefig(str(path), format="png")


def plot_workload_sweep(sweep: list, path, title: str) -> None:
    """PNG: datapath utilization with the memory hierarchy vs rays in flight (log x): the
    frame's, and with the wavefront schedule each ray type's (one-kernel frames share the
    pipelines between ray types: their mean latency per ray is drawn instead, right axis)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 5.2), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    x = [p["rays_in_flight"] for p in sweep]
    ax.plot(x, [p["rtunit_memory"]["utilization"] for p in sweep], "o-", color="black", lw=2,
            label="frame")
    kinds = list(sweep[0]["by_type"])
    typed = sweep[0]["by_type"][kinds[0]]["rtunit_memory"]["utilization"] is not None
    ax2 = None if typed else ax.twinx()
    for i, kind in enumerate(kinds):
        style = {"marker": MARKERS[i % len(MARKERS)], "ms": 7 - i % 4, "color": f"C{i}",
                 "mfc": "none" if i % 2 else f"C{i}"}
        ys = [p["by_type"][kind]["rtunit_memory"] for p in sweep]
        if typed:
            ax.plot(x, [y["utilization"] for y in ys], ls="--", label=kind, **style)
        else:
            ax2.plot(x, [y["latency_mean"] for y in ys], ls=":", label=f"{kind}: latency",
                     **style)
    ax.set_xscale("log", base=2)
    ax.set_xticks(x)
    ax.set_xticklabels([str(v) for v in x])
    ax.minorticks_off()
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("rays in flight per RT unit (ray pool size R)")
    ax.set_ylabel("datapath utilization with the memory hierarchy")
    ax.grid(True, which="both", alpha=0.3)
    if ax2 is not None:
        ax2.set_ylabel("mean latency per ray, issue to done (cycles)")
        ax2.set_ylim(bottom=0)
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        legend_under(ax, h1 + h2, l1 + l2, ncol=min(len(l1 + l2), 6), fontsize=7)
    else:
        legend_under(ax, ncol=min(len(kinds) + 1, 6), title="utilization", fontsize=7)
    ax.set_title(wrap(title, 90), fontsize=8)
    fig.tight_layout()
    fig.savefig(str(path), format="png")
