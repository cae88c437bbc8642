"""``rayflex study NAME``: the studies behind the figures of the docs, as commands.

- ``rayorder``: every ray-order policy of the RT unit at every window, per scene and ray type
  (docs/rayorder.md; ``driver.studies.rayorder``);
- ``bvh``: BVH build times (CPU and wall) of each image format, each build in a fresh process
  (docs/compressed.md; ``driver.studies.bvh``);
- ``compressed``: box32 vs q8 (and q8g) from ``rayflex bench --workload ... --bvh-format``
  documents of the same frame: the table and the utilization plot (docs/compressed.md;
  ``driver.studies.compressed``);
- ``instances hits|images|table|transform``: instanced vs flattened (docs/instances.md;
  ``driver.studies.instances``);
- ``gpu compressed|schedules|order|units SWEEP.json``: the one-kernel studies' tables and plots
  from ``rayflex sweep --json`` documents: node formats, frame schedules, ray orders and RT
  units in a GPU's frame (docs/compressed.md, docs/rayorder.md, docs/rtunit.md;
  ``driver.studies.gpu``).

Each checks its arguments before any work, writes its outputs all or nothing, shows progress
on stderr and puts the ``provenance`` object into its JSON, as every command does.
"""

from __future__ import annotations

import json

from ..core import outputs
from ..core.layout import IMAGE_FORMATS
from ..core.outputs import JSON, PNG, Outputs
from ..core.provenance import provenance
from ..design import DesignPoint
from ..plotting import describe
from ..rtunit.order import POLICIES, check_window
from ..studies import bvh, compressed, gpu, instances, rayorder
from . import options

STUDIES = {
    "rayorder": "ray-order policies of the RT unit per scene and ray type; docs/rayorder.md",
    "bvh": "BVH build times per image format, each build in a fresh process; docs/compressed.md",
    "compressed": "box32 vs q8 (and q8g) from bench documents of one frame: table and plot; "
                  "docs/compressed.md",
    "instances": "instanced vs flattened scenes; docs/instances.md",
    "gpu": "one-kernel frames in a GPU from rayflex sweep documents: node formats, frame "
           "schedules, ray orders, RT units (table, plot); docs/rtunit.md",
}
INSTANCE_STUDIES = {
    "hits": "image bytes and hits, instanced vs flattened",
    "images": "two-level image bytes per format (TLAS, instance nodes, BLASes)",
    "table": "Markdown table of bench --workload documents",
    "transform": "the instance transform in the driver vs on the datapath: ops, RT-unit cycles, "
                 "utilization",
}


def add_parser(subparsers):
    p = subparsers.add_parser(
        "study", help="the studies behind the docs' figures: ray order, BVH builds, compressed "
                      "images, instances",
        description="Run one of the studies whose tables and plots the docs show: " + "; ".join(
            f"{name}: {what}" for name, what in STUDIES.items()) + ".")
    sub = p.add_subparsers(dest="study", metavar="STUDY", required=True)
    for name, what in STUDIES.items():
        s = sub.add_parser(name, help=what, description=what[:1].upper() + what[1:] + ".")
        if name == "instances":
            inner = s.add_subparsers(dest="instances_study", metavar="WHAT", required=True)
            for kind, text in INSTANCE_STUDIES.items():
                k = inner.add_parser(kind, help=text, description=text[:1].upper() + text[1:]
                                     + ".")
                options.add(k, f"study instances {kind}")
                k.set_defaults(study_run=_INSTANCES[kind])
            continue
        options.add(s, f"study {name}")
        s.set_defaults(study_run=_RUN[name])
    return p


def run(args) -> int:
    return args.study_run(args)


def _command(args) -> str:
    return "rayflex " + " ".join(getattr(args, "argv", None) or [])


def _window(text: str, option: str) -> int:
    try:
        return check_window(rayorder.ALL_RAYS if text == "all" else int(text))
    except ValueError:
        raise ValueError(f"{option}: a window is an integer >= 1 or \"all\", got {text!r}") \
            from None


def _rayorder(args) -> int:
    windows = [_window(x, "--windows") for x in args.windows.split(",")]
    variants_window = _window(args.variants_window, "--variants-window")
    policies = args.policies.split(",")
    for name in policies:
        if name not in POLICIES:
            raise ValueError(f"--policies: unknown ray order {name!r} (choose from "
                             f"{', '.join(POLICIES)})")
    formats = args.bvh_formats.split(",")
    bad = [f for f in formats if f not in IMAGE_FORMATS]
    if bad:
        raise ValueError(f"--bvh-formats: unknown format {bad[0]!r} (choose from "
                         f"{', '.join(IMAGE_FORMATS)})")
    outs = Outputs()
    js = outs.add("--json", args.json, JSON)
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    with outs.commit():
        doc = {"provenance": provenance(None),
               **rayorder.study(args.scenes.split(","), args.size, windows=windows,
                                progress=not args.no_progress, formats=formats,
                                policies=policies, variants=not args.no_variants,
                                variants_window=variants_window)}
        doc["machine"] = doc["provenance"]["machine"]
        doc["command"] = _command(args)
        if png:
            rayorder.plot_study(doc, outs.temp(png))
            doc["plot"] = str(png)
        outputs.write_json(doc, outs.temp(js))
    print(rayorder.study_tables(doc))
    return 0


def _bvh(args) -> int:
    if any(c < 0 for c in args.counts):
        raise ValueError(f"--counts must be >= 0, got {args.counts}")
    outs = Outputs()
    js = outs.add("--json", args.json, JSON) if args.json else None
    if args.meshes:
        bvh.mesh_items(args.meshes)                         # bad paths: before any work
        doc = {"provenance": provenance(None),
               **bvh.mesh_bench(args.meshes, formats=tuple(args.formats),
                                progress=not args.no_progress)}
    else:
        doc = {"provenance": provenance(None),
               **bvh.bvh_bench(counts=tuple(args.counts), quality=False,
                               progress=not args.no_progress, formats=tuple(args.formats))}
    with outs.commit():
        if js:
            outputs.write_json(doc, outs.temp(js))
    print(bvh.mesh_table(doc) if args.meshes else bvh.build_table(doc))
    return 0


def _compressed(args) -> int:
    outs = Outputs(inputs=args.json)
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    docs = compressed.load(args.json)
    table = compressed.rows(docs)
    with outs.commit():
        if png:
            d = docs["q8"]
            point = {**d["provenance"]["design_point"], "size": d["width"]}
            compressed.plot(docs, outs.temp(png), f"{' vs '.join(docs)} node images: " + describe(
                point, omit=("bvh_format", "rays_in_flight", "pipelines")))
    print(compressed.markdown(table))
    return 0


def _gpu(args) -> int:
    text, draw = gpu.TABLES[args.table]
    if args.plot and draw is None:
        raise ValueError(f"--plot: the {args.table} table has no plot")
    outs = Outputs(inputs=[args.sweep])
    png = outs.add("--plot", args.plot, PNG) if args.plot else None
    try:
        with open(args.sweep) as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        raise ValueError(f"{args.sweep}: not a readable JSON document ({e})") from None
    try:
        table = text(doc)
        with outs.commit():
            if png:
                draw(doc, outs.temp(png))
    except (KeyError, IndexError, TypeError) as e:
        raise ValueError(f"{args.sweep}: not a rayflex sweep --json document of this study "
                         f"(no {e})") from None
    print(table)
    return 0


def _json_out(args):
    """The instance studies' ``--json`` output, checked before any work: (outputs, target)."""
    outs = Outputs()
    return outs, outs.add("--json", args.json, JSON) if args.json else None


def _commit(outs, js, doc) -> None:
    with outs.commit():
        if js:
            outputs.write_json(doc, outs.temp(js))


def _instances_hits(args) -> int:
    outs, js = _json_out(args)
    doc = {"provenance": provenance(None), **instances.hits(args.scene, args.size)}
    print(json.dumps(doc, indent=1))
    _commit(outs, js, doc)
    return 0


def _instances_images(args) -> int:
    outs, js = _json_out(args)
    doc = {"provenance": provenance(None),
           **instances.images(tuple(args.scene or ("bunny_grid", "city")))}
    _commit(outs, js, doc)
    print(instances.images_markdown(doc))
    return 0


def _instances_table(args) -> int:
    docs = []
    for path in args.docs:
        with open(path) as f:
            docs.append(json.load(f))
    try:
        print(instances.markdown(docs))
    except KeyError as e:
        raise ValueError(f"not a rayflex bench --workload JSON document (no {e})") from None
    return 0


def _instances_transform(args) -> int:
    DesignPoint(scene=args.scene, workload=args.workload, size=args.size, spp=args.spp,
                bounces=args.bounces)                                 # bad values fail now
    outs, js = _json_out(args)
    doc = instances.transform_cost(args.scene, args.workload, args.size, args.spp, args.bounces,
                                   progress=not args.no_progress)
    _commit(outs, js, doc)
    print(instances.transform_markdown(doc))
    return 0


_RUN = {"rayorder": _rayorder, "bvh": _bvh, "compressed": _compressed, "gpu": _gpu}
_INSTANCES = {"hits": _instances_hits, "images": _instances_images, "table": _instances_table,
              "transform": _instances_transform}
