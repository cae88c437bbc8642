"""Render a scene through the datapath: camera -> BVH4 -> traversal on a backend -> shading.

``render(scene, width, height, backend)`` returns a ``RenderResult`` with the image, the
per-pixel datapath operation counts, the trace result and the frame statistics (SPEC section 10
names, plus ``bvh`` build statistics and, when checked, the ``embree`` object).

Shading: flat face normals, Lambert with a head light (the light sits at the camera), a little
ambient, sRGB-ish gamma; misses show a vertical background gradient.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from .backends import BACKENDS, BackendError
from .camera import check_size, primary_rays
from .scene import Scene, load_scene

BASE_COLOUR = np.array([0.92, 0.86, 0.76])           # surface albedo
AMBIENT = 0.08
BG_TOP = np.array([0.42, 0.52, 0.66])
BG_BOTTOM = np.array([0.10, 0.11, 0.14])


@dataclass
class RenderResult:
    """image (h, w, 3) uint8; ops (h, w) int64 box + tri ops per pixel; trace: the TraceResult;
    stats: SPEC section 10 dict (+ ``bvh``, + ``embree`` when checked); embree: the full
    ``driver.check.compare`` result (with ray index lists) or None."""

    scene: Scene
    width: int
    height: int
    image: np.ndarray
    ops: np.ndarray
    trace: object
    stats: dict
    embree: dict | None = None
    bvh_stats: dict = field(default_factory=dict)

    def save(self, path) -> None:
        """Write the image as PNG."""
        save_png(self.image, path)

    def save_heatmap(self, path, title: str | None = None) -> None:
        """Write the operations-per-pixel heat map as PNG."""
        heatmap(self.ops, self.width, self.height, path,
                title=title or f"{self.scene.name} {self.width}x{self.height}: "
                               f"datapath ops per pixel ({self.stats.get('backend', '?')})")


def render(scene, width=None, height=None, backend: str = "rtl", progress: bool = True,
           check_embree: bool = False) -> RenderResult:
    """Render ``scene`` (a Scene, or anything ``load_scene`` takes) at width x height (default:
    the scene's size) with every box/triangle test on ``backend``; optionally cross-check every
    primary ray against Embree."""
    from .bvh4 import build
    from .tracer import trace

    scene = load_scene(scene)
    w, h = check_size(width if width is not None else scene.size[0],
                      height if height is not None else scene.size[1])
    origins, dirs = primary_rays(scene.camera, w, h)
    be = _backend(backend)                  # fail early, before a long BVH build
    bvh = build(scene.mesh)
    bvh_stats = dict(getattr(bvh, "stats", {}) or {})

    bar = _progress_bar(len(origins), progress, f"{scene.name} {w}x{h} {backend}")
    try:
        result = trace(bvh, origins, dirs, backend=be, progress=bar.hook if bar else None)
    finally:
        if bar:
            bar.close()

    tri = scene.triangles
    image = shade(result, tri, dirs, w, h)
    ops = (np.asarray(result.box_ops, np.int64) + np.asarray(result.tri_ops, np.int64))
    stats = dict(result.stats)
    stats["bvh"] = bvh_stats
    emb = None
    if check_embree:
        from .check import check, embree_json
        emb = check(tri, origins, dirs, result.t, result.prim)
        stats["embree"] = embree_json(emb)
    return RenderResult(scene, w, h, image, ops.reshape(h, w), result, stats, emb, bvh_stats)


def _backend(name):
    """Build the backend once up front so a missing or broken one fails before any work.
    Returns the backend object (passed to trace) or the name if it is already an object."""
    if not isinstance(name, str):
        return name
    if name not in BACKENDS:
        raise BackendError(f"unknown backend {name!r}; available: {', '.join(BACKENDS)}")
    from .backends import backend
    try:
        return backend(name)
    except ImportError as e:
        raise BackendError(f"backend {name!r} is not available: {e}") from None


class _Bar:
    """tqdm bar on stderr fed by trace's progress(done_rays, total_rays) callback."""

    def __init__(self, total, desc):
        from tqdm import tqdm
        self.bar = tqdm(total=total, desc=desc, unit="ray", file=sys.stderr, leave=True,
                        dynamic_ncols=True, mininterval=0.2)

    def hook(self, done, total):
        if total != self.bar.total:
            self.bar.total = total
        self.bar.update(max(0, int(done) - self.bar.n))

    def close(self):
        self.bar.close()


def _progress_bar(total, enabled, desc):
    return _Bar(total, desc) if enabled else None


def shade(trace_result, triangles, dirs, width: int, height: int) -> np.ndarray:
    """Lambert with a head light and flat face normals; misses get the background gradient.

    trace_result : has ``prim`` (n,) int (-1 = miss); triangles : (m, 3, 3); dirs : (n, 3)
    Returns an (height, width, 3) uint8 image, row 0 at the top.
    """
    n = width * height
    prim = np.asarray(trace_result.prim, np.int64).reshape(-1)
    if len(prim) != n:
        raise ValueError(f"shade: {len(prim)} rays for a {width}x{height} image")
    rows = np.repeat(np.linspace(0.0, 1.0, height), width)[:, None]
    rgb = BG_TOP * (1 - rows) + BG_BOTTOM * rows                     # (n, 3) linear-ish
    hit = prim >= 0
    if hit.any():
        tri = np.asarray(triangles, np.float64)[prim[hit]]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(nrm, axis=1)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)[hit]
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            lam = np.abs(np.einsum("ij,ij->i", nrm, d)) / length
        lam = np.nan_to_num(lam, nan=0.0)                            # degenerate triangles
        rgb[hit] = BASE_COLOUR * (AMBIENT + (1 - AMBIENT) * lam[:, None])
    rgb = np.clip(rgb, 0.0, 1.0) ** (1 / 2.2)
    return (rgb * 255 + 0.5).astype(np.uint8).reshape(height, width, 3)


def save_png(image: np.ndarray, path) -> None:
    """Write an (h, w, 3) uint8 image as PNG."""
    from PIL import Image
    Image.fromarray(np.asarray(image, np.uint8), "RGB").save(str(path), format="PNG")


def heatmap(ops_per_pixel, width: int, height: int, path, title: str | None = None) -> None:
    """PNG heat map of datapath operations per pixel (box_ops + tri_ops) with a colour bar.

    ops_per_pixel : (width * height,) or (height, width), row 0 at the top.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ops = np.asarray(ops_per_pixel).reshape(height, width)
    aspect = width / height
    fig = Figure(figsize=(min(4.8 * aspect, 12) + 1.4, 4.8), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(ops, cmap="inferno", interpolation="nearest", vmin=0,
                   vmax=max(1, int(ops.max())) if ops.size else 1)
    ax.set_axis_off()
    ax.set_title(title or "datapath operations per pixel", fontsize=10)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    cb.set_label("box + triangle ops per pixel")
    fig.tight_layout()
    fig.savefig(str(path), format="png")

