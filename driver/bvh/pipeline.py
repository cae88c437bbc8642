"""The BVH build, one pipeline: binary build -> collapse to 4-wide -> the format's image writer
(box32, q8 or q8g); the two-level image of instanced scenes (``driver.bvh.instances``)
runs it for every BLAS and the TLAS. ``driver.bvh4`` is the entry point.

Build pipeline (madmann91/bvh and tinybvh style):

1. Primitive boxes and centroids only (``_prim_boxes``): the binary builder never sees triangles.
2. Binary BVH by SAH, C_trav = C_int = 1, split until every leaf holds one triangle (RDNA-style
   leaves): nodes of more than ``SWEEP_MAX`` (8) primitives are binned, ``bins`` (16) bins per
   axis over the node's centroid bounds on all three axes; nodes of 3..8 primitives try every
   split of the centroid order on all three axes (the exact SAH, which no binning beats);
   2 primitives split 1 + 1; a node whose centroids all coincide is split in the middle of its
   primitive list. Two implementations of these same rules (they build the same tree):
   ``builder="fast"`` (default), numba kernels in ``driver.bvh.build`` (depth first, with a
   progress bar), and ``builder="numpy"``, the vectorised reference (``driver.bvh.reference``:
   all nodes of a tree level binned, scored and partitioned together; the whole build is
   about 10x slower with it: docs/bvh.md). ``fill`` > 0 (fast builder only) constrains the
   split counts of small nodes so that their subtrees can become full 4-wide nodes
   (``driver.bvh.build``).
3. Collapse to 4-wide: ``collapse="sah"`` (default) picks the binary nodes that become box nodes
   by the dynamic programme of Ylitie et al. 2017 that minimises the wide tree's SAH cost
   (``driver.bvh.collapse``); ``collapse="greedy"`` (``_collapse``) starts each 4-wide
   node with the binary node's two children and twice replaces the interior child of largest
   surface area by its two children (triangle children are never opened).
4. Memory image: box32 (``driver.bvh.box32``; docs/datapath.md#bvh4-image, the layout in
   ``driver.bvh.image``), q8 and q8g (``driver.bvh.q8_image``; docs/compressed.md), over the
   triangle pairs of ``driver.bvh.q8`` and the group leaves of ``driver.bvh.q8g``.

Conservative boxes. The datapath's slab test is strict (``tmin < tmax``) and rounds ``box - o``
and ``* inv`` to float32, so an exact box would lose flat (axis-aligned) triangles entirely and
could lose grazing hits on box faces by an ulp. Every stored bound is therefore grown outward:

    stored_min = nextafter(float32(min - pad), -inf)
    stored_max = nextafter(float32(max + pad), +inf)
    pad = PAD_REL * S,   S = largest |coordinate| in the mesh,   PAD_REL = 2**-16

i.e. at least one float32 ulp of the bound (so every box, flat ones included, has positive
thickness) plus a scene-relative margin of about 256 float32 ulps of S (1.5e-5 S, far below a
triangle's size in any practical mesh, so traversal cost is unchanged). Why a margin: the slab
test rounds ``box - o`` and then ``* inv``, an error of about one ulp of ``|box - o|``, and the
watertight triangle test rounds ``P - o`` the same way; when the ray origin is far from the box
these ulps are much larger than the box's own ulps, and a box grown by one ulp only would be
flattened back to zero thickness (a miss) for e.g. a flat wall seen from a camera 20 S away.
The margin keeps every triangle that the TRIANGLE op hits inside a box that the QUADBOX op hits
for ray origins up to about 100 S from the world origin (tests/test_bvh4.py checks it on the
golden model up to 64 S; measured on the test meshes, PAD_REL = 2**-18 first lost hits at 64 S
and 2**-16 at 256 S). Growth is monotone, so a child's stored box lies inside its parent's.
"""

from __future__ import annotations

import time

import numpy as np

from ..core.layout import IMAGE_FORMATS
from ..core.progress import bar as progress_bar
from .image import BVH4, _half_area
from .phases import Phases
from .reference import _build_binary, _prim_boxes

PAD_REL = 2.0 ** -16


def as_triangles(mesh_or_triangles) -> np.ndarray:
    """(n, 3, 3) float32 C-contiguous triangles from a trimesh mesh or an array-like.

    Raises ValueError (one line) for no triangles, a wrong shape or non-finite coordinates."""
    with np.errstate(over="ignore"):                        # > float32 max -> inf -> rejected
        if hasattr(mesh_or_triangles, "vertices") and hasattr(mesh_or_triangles, "faces"):
            v = np.asarray(mesh_or_triangles.vertices, np.float32).reshape(-1, 3)
            f = np.asarray(mesh_or_triangles.faces, np.int64)
            if f.ndim != 2 or f.shape[1] != 3:
                raise ValueError(f"mesh faces must be (n, 3), got {f.shape}")
            if f.size and (f.min() < 0 or f.max() >= len(v)):
                raise ValueError("mesh faces index vertices that do not exist")
            tris = v[f]
        else:
            try:
                tris = np.asarray(mesh_or_triangles, np.float32)
            except (TypeError, ValueError) as e:
                raise ValueError(f"triangles must be an (n, 3, 3) float array: {e}") from None
    if tris.ndim != 3 or tris.shape[1:] != (3, 3):
        raise ValueError(f"triangles must have shape (n, 3, 3), got {tris.shape}")
    if len(tris) == 0:
        raise ValueError("no triangles: cannot build a BVH of an empty mesh")
    if not np.isfinite(tris).all():
        raise ValueError("triangle coordinates must be finite (in float32)")
    return np.ascontiguousarray(tris)


BUILDERS = ("fast", "numpy")


COLLAPSES = ("sah", "greedy")


PROGRESS_MIN = 1_000_000        # progress=None shows a bar from this many triangles (~0.5 s)


def build(triangles_or_trimesh, bins: int = 16, *, builder: str = "fast", collapse: str = "sah",
          fill: int = 0, progress=None, format: str = "box32", pair: bool = True,
          on_phase=None) -> BVH4:
    """Build a BVH4 (binned SAH, one triangle per leaf) and its memory image
    (docs/datapath.md#bvh4-image, docs/compressed.md).

    triangles_or_trimesh : (n, 3, 3) array-like (converted to float32) or a trimesh.Trimesh
    bins : SAH bins per axis (>= 2; default 16)
    builder : "fast" (numba, default) or "numpy" (the reference; same tree, ~10x slower)
    collapse : "sah" (SAH-optimal, default) or "greedy" (the earlier collapse, for comparisons)
    fill : subtrees of at most ``fill`` triangles are split so that their 4-wide nodes can all
        be full (``driver.bvh.build``; fast builder only): fewer box nodes and bytes for a
        little more SAH; 0 (default) = plain SAH splits
    progress : True/False, or None = a bar on stderr (terminal only) from PROGRESS_MIN triangles
    format : "box32" (default: 128-byte float32 box nodes, one 64-byte node per triangle, the
        module docstring's layout), "q8" (docs/compressed.md: triangles sharing an edge are
        paired first and each pair is one leaf primitive of the build; 64-byte quantized box
        nodes whose decoded child boxes contain the box32 stored boxes; 64-byte pair leaves) or
        "q8g" (q8 where the subtrees of 3 to 6 triangles that the SAH trade-off of
        ``driver.bvh.q8g.group_leaves`` picks become 128-byte group leaves sharing up to 8
        vertices)
    pair : q8 formats: pair triangles that share an edge (default); False: one triangle per
        pair leaf, e.g. the instance boxes of a q8 TLAS (``driver.bvh.instances``)
    on_phase : called with each phase's name as it starts (``driver.bvh.phases``); the
        phases' wall and CPU times are ``stats["phase_s"]`` and ``stats["phase_cpu_s"]``
    Degenerate (zero-area) triangles are kept (the datapath never hits them).
    Raises ValueError for an empty input, a wrong shape, non-finite coordinates or a bad option."""
    # the stages' numba kernels: loaded (compiled once per machine) when a BVH is first built,
    # so that importing the package does not load numba
    from . import build as bvh_build
    from .box32 import _write_image
    from .collapse import _collapse, collapse_sah
    from .q8_image import _write_q8_image
    from .q8g import group_leaves
    t0 = time.perf_counter()
    _check_options(bins, builder, collapse, fill, format)
    tris = as_triangles(triangles_or_trimesh)
    phases = Phases(on_phase)
    pairs, prims = None, tris
    if format != "box32":
        pairs = _leaf_pairs(tris, getattr(triangles_or_trimesh, "faces", None), pair, phases)
        prims = pairs[4]                # one box-shaped triangle per leaf: the builder's input

    show = None if progress is None and len(tris) >= PROGRESS_MIN else bool(progress)
    with progress_bar(len(tris), "BVH build", "tri", show, leave=False) as bar:
        with phases("binary build"):
            left, right, prim, node_lo, node_hi = _binary(prims, bins, builder, fill, bar)
        bar.set_postfix_str("collapse")
        with phases("stored boxes"):
            pad = PAD_REL * float(max(-tris.min(), tris.max()))
            if collapse == "greedy":                            # from the exact boxes
                greedy_area = _half_area(node_lo.astype(np.float64), node_hi)
            node_area = bvh_build.grow_boxes(node_lo, node_hi, pad)   # in place: stored boxes
        groups = None
        if format != "box32":
            with phases("group leaves"):
                groups = group_leaves(left, right, prim, node_area, pairs, format == "q8g")
        with phases("collapse"):
            if collapse == "sah":
                levels = collapse_sah(left, right, node_area)
            else:
                levels = _collapse(left, right, greedy_area)
        bar.set_postfix_str("image")
        with phases("image"):
            if pairs is None:
                image, depth, sah, hist = _write_image(levels, left, prim, node_lo, node_hi,
                                                       node_area, tris)
            else:
                image, depth, sah, hist = _write_q8_image(levels, left, prim, node_lo, node_hi,
                                                          pairs, groups, tris)
    paired = 0 if pairs is None else 2 * int((pairs[1] >= 0).sum())
    stats = {"format": format, **_shape_stats(levels, tris, prims, groups),
             "depth": depth, "sah_cost": sah, "fill": int(fill),
             "build_s": time.perf_counter() - t0, "bytes": int(image.nbytes),
             "bytes_per_triangle": image.nbytes / len(tris), "pair_ratio": paired / len(tris),
             "avg_children": float((hist * np.arange(1, 5)).sum()
                                   / sum(len(s) for s in levels)),
             "child_histogram": hist.tolist(), "phase_s": phases.seconds,
             "phase_cpu_s": phases.cpu_seconds}
    return BVH4(image, tris, stats, format)


def _binary(prims, bins, builder, fill, bar) -> tuple:
    """The binary tree (left, right, prim, node_lo, node_hi) of the builder, checked."""
    from . import build as bvh_build                        # numba: loaded by a build
    if builder == "fast":
        tree = bvh_build.build_binary(prims, int(bins), bar, int(fill))
    else:
        tree = _build_binary(*_prim_boxes(prims), int(bins))
        bar.update(len(prims))
    bvh_build.check_tree(*tree[:2])
    return tree


def _check_options(bins, builder, collapse, fill, format) -> None:
    """``build``'s options, each a one-line ValueError when wrong."""
    if int(bins) < 2:
        raise ValueError(f"bins must be >= 2, got {bins}")
    if builder not in BUILDERS:
        raise ValueError(f"builder must be one of {BUILDERS}, got {builder!r}")
    if collapse not in COLLAPSES:
        raise ValueError(f"collapse must be one of {COLLAPSES}, got {collapse!r}")
    if isinstance(fill, bool) or not isinstance(fill, (int, np.integer)) or fill < 0:
        raise ValueError(f"fill must be an integer >= 0, got {fill!r}")
    if format not in IMAGE_FORMATS:
        raise ValueError(f"format must be one of {IMAGE_FORMATS}, got {format!r}")
    if fill and builder != "fast":
        raise ValueError("fill needs the fast builder (the numpy reference has plain SAH splits)")


def _leaf_pairs(tris, faces, pair: bool, phases) -> tuple:
    """The triangle pairs of a q8 format's leaves (``driver.bvh.q8.pair_triangles``'s tuple):
    triangles sharing an edge paired when ``pair``, else every leaf one triangle."""
    from .q8 import _pairs, pair_triangles, vertex_ids      # numba: loaded by a build
    if pair:
        return pair_triangles(tris, None if faces is None else np.asarray(faces), phases)
    with phases("pairs"):               # no partner: every leaf holds one triangle
        ids = vertex_ids(tris)
        return (*_pairs(ids, np.full(len(tris), -1, np.int64), tris), ids)


def _shape_stats(levels, tris, prims, groups) -> dict:
    """The image's node and leaf counts of ``build``'s statistics, in their order."""
    n_groups = 0 if groups is None else len(groups[0])
    return {"box_nodes": sum(len(s) for s in levels), "tri_nodes": len(tris),
            "leaf_nodes": (len(prims) if groups is None
                           else len(prims) - int((groups[0] >= 0).sum()) + n_groups),
            "group_leaves": n_groups,
            "grouped_triangles": 0 if groups is None else int((groups[1] >= 0).sum())}


def warm_up() -> float:
    """Compile (first use on a machine: ~20 s, then cached on disk by numba) or load (~1 s per
    process) the fast builder's kernels by building a tiny mesh; returns the seconds it took.
    Benchmarks call it so that a build time is the build's, as they build the Verilated model
    before timing the simulation."""
    from . import build as bvh_build
    t0 = time.perf_counter()
    tris = np.random.default_rng(0).random((64, 3, 3)).astype(np.float32)
    build(tris, progress=False)
    bvh_build.build_binary(tris, 16, threads=2)     # the threaded path's kernel (_node) too
    return time.perf_counter() - t0
