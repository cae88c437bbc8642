"""What every plot the tool draws shares: a title naming the frame and the design point it was
measured on (``describe``), wrapped between words (``wrap``), and legends placed outside the
data, under the axes (``legend_under``, ``legend_below``), so that no series hides behind one
and the axes keep the figure's width."""

from __future__ import annotations

from .core.words import plural, wrap  # noqa: F401  (wrap: every plot's titles)


def describe(point: dict, omit=(), parts=("frame", "datapath", "bvh", "rtunit")) -> str:
    """The design point ``point`` (``DesignPoint.as_dict()``, or a JSON's
    ``provenance.design_point``) in words, the options named in ``omit`` left out (e.g. those a
    plot varies): e.g. "bunny_floor 64x64 path (spp 2, bounces 2); baseline-unified, latency 11;
    box32 BVH; one-kernel frame, R=64, 1 pipeline, 32 KiB 4-way node cache, 200-cycle 32 B/cycle
    memory"."""
    p, skip, out = point, set(omit), []
    if "frame" in parts:
        size = "" if p.get("size") is None or "size" in skip else f" {p['size']}x{p['size']}"
        extra = [f"{k} {p[k]}" for k in ("spp", "bounces") if k not in skip
                 and (k == "spp" or p.get("workload") == "path")]
        if p.get("workload") == "ao" and "ao_rays" not in skip:
            extra.append(f"{p['ao_rays']} AO rays")
        out.append(f"{p['scene']}{size} {p['workload']}"
                   + (f" ({', '.join(extra)})" if extra else ""))
    if "datapath" in parts:
        d = [p["config"]] if "config" not in skip else []
        if "latency" not in skip and p.get("latency") is not None:
            d.append(f"latency {p['latency']}")
        if p.get("transform") == "datapath" and "transform" not in skip:
            d.append("TRANSFORM on the datapath")
        if d:
            out.append(", ".join(d))
    if "bvh" in parts:
        b = [] if "bvh_format" in skip else [f"{p['bvh_format']} BVH"]
        if p.get("bvh_fill") and "bvh_fill" not in skip:
            b.append(f"fill {p['bvh_fill']}")
        if p.get("cull_stack") and "cull_stack" not in skip:
            b.append("culled stack")
        if p.get("flatten") and "flatten" not in skip:
            b.append("flattened")
        if b:
            out.append(", ".join(b))
    if "rtunit" in parts:
        r = []
        if p.get("rt_preset", "default") != "default" and "rt_preset" not in skip:
            r.append(f"{p['rt_preset']} preset")
        if p.get("frame_schedule") and "frame_schedule" not in skip:
            r.append(f"{p['frame_schedule']} frame")
        if p.get("rt_units", 1) != 1 and "rt_units" not in skip:
            r.append(f"{p['rt_units']} RT units")
        if p.get("warp_size", 1) != 1 and "warp_size" not in skip:
            r.append(f"warps of {p['warp_size']}")
        if "rays_in_flight" not in skip:
            r.append(f"R={p['rays_in_flight']}")
        if "pipelines" not in skip:
            r.append(plural(p["pipelines"], "pipeline"))
        if not {"cache_kib", "cache_ways", "line_bytes"} & skip:
            r.append(f"{p['cache_kib']} KiB {p['cache_ways']}-way node cache"
                     if p["cache_kib"] else "no node cache")
        if p.get("l2_kib") and "l2_kib" not in skip:
            r.append(f"{p['l2_kib']} KiB L2")
        if not {"mem_latency", "mem_bytes_per_cycle"} & skip:
            r.append(f"{p['mem_latency']}-cycle {p['mem_bytes_per_cycle']:g} B/cycle memory")
        if p.get("ray_order", "index") != "index" and "ray_order" not in skip:
            r.append(f"ray order {p['ray_order']} W={p['ray_window']}")
        if r:
            out.append(", ".join(r))
    return "; ".join(out)


def legend_under(ax, handles=None, labels=None, ncol: int = 2, **kw):
    """The axes' legend under them, below the axis label (``fig.tight_layout`` makes room), so
    the axes keep the figure's width."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    return ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.13),
                     ncol=ncol, frameon=False, borderaxespad=0.0, **kw)


def legend_below(fig, handles, labels, ncol: int, **kw):
    """One legend for a figure, below its axes (``fig.tight_layout`` leaves it room when given
    ``rect=(0, legend_height, 1, 1)``)."""
    return fig.legend(handles, labels, loc="lower center", ncol=ncol, frameon=False, **kw)
