"""Render a scene through the datapath: camera -> BVH4 -> traversal on a backend -> shading.

``render(scene, width, height, backend)`` returns a ``RenderResult`` with the image, the
per-pixel datapath operation counts, the trace result and the frame statistics (SPEC section 10
names, plus ``bvh`` build statistics and, when checked, the ``embree`` object).

Shading: flat face normals, Lambert with a head light (the light sits at the camera), a little
ambient, sRGB-ish gamma; misses show a vertical background gradient.

Memory: a frame holds every primary ray and its traversal state at once (tiles are a later
issue), so ``check_memory`` refuses a frame whose estimated peak (``PEAK_BYTES_PER_RAY`` per ray
plus ``BASE_BYTES``) exceeds the memory available, before anything is allocated.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .backends import BackendError
from .camera import check_size, primary_rays
from .errors import RayflexError
from .outputs import save_image
from .progress import bar as progress_bar
from .progress import phase
from .scene import Scene, load_scene

BASE_COLOUR = np.array([0.92, 0.86, 0.76])           # surface albedo
AMBIENT = 0.08
BG_TOP = np.array([0.42, 0.52, 0.66])
BG_BOTTOM = np.array([0.10, 0.11, 0.14])
# Peak resident memory of a frame, measured with /usr/bin/time -v (maximum RSS) on the sphere
# scene at 256², 512² and 1024² (--check-embree makes no difference): golden 167 / 403 / 1,294 MB,
# rtl 144 / 282 / 853 MB. The slope between 512² and 1024² is 1,160 bytes per ray on golden and
# 743 on rtl; the intercept about 100 MB (Python, numpy, the model). A mesh adds its BVH.
PEAK_BYTES_PER_RAY = 1200
BASE_BYTES = 150 * 2**20


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
        """Write the image (PNG, JPEG, ... by the extension of ``path``)."""
        save_image(self.image, path)

    def heatmap_image(self, title: str | None = None) -> np.ndarray:
        """The operations-per-pixel heat map as an RGB image."""
        return heatmap_image(self.ops, self.width, self.height,
                             title=title or f"{self.scene.name} {self.width}x{self.height}: "
                                            f"datapath ops per pixel "
                                            f"({self.stats.get('backend', '?')})")

    def save_heatmap(self, path, title: str | None = None) -> None:
        """Write the operations-per-pixel heat map (format by the extension of ``path``)."""
        save_image(self.heatmap_image(title), path)


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
    check_memory(w * h)
    origins, dirs = primary_rays(scene.camera, w, h)
    be = open_backend(backend)              # fail early, before a long BVH build
    with phase(f"building the BVH4 of {len(scene.mesh.faces):,} triangles", progress):
        bvh = build(scene.mesh)
    bvh_stats = dict(getattr(bvh, "stats", {}) or {})

    name = backend if isinstance(backend, str) else getattr(backend, "name", "backend")
    bar = progress_bar(len(origins), f"{scene.name} {w}x{h} {name}", "ray", progress)
    try:
        result = trace(bvh, origins, dirs, backend=be, progress=bar.hook)
    finally:
        bar.close()

    tri = scene.triangles
    image = shade(result, tri, dirs, w, h)
    ops = (np.asarray(result.box_ops, np.int64) + np.asarray(result.tri_ops, np.int64))
    stats = dict(result.stats)
    stats["bvh"] = bvh_stats
    emb = None
    if check_embree:
        from .check import check, embree_json
        with phase(f"Embree check of {len(origins):,} rays", progress):
            emb = check(tri, origins, dirs, result.t, result.prim)
        stats["embree"] = embree_json(emb)
    return RenderResult(scene, w, h, image, ops.reshape(h, w), result, stats, emb, bvh_stats)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (MemAvailable in /proc/meminfo; else the
    free physical pages), or None if the system does not say."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def estimate_bytes(rays: int) -> int:
    """Estimated peak memory of a frame of ``rays`` primary rays (see PEAK_BYTES_PER_RAY)."""
    return BASE_BYTES + PEAK_BYTES_PER_RAY * int(rays)


def check_memory(rays: int, available: int | None = None) -> None:
    """Refuse (one-line RayflexError) a frame whose estimated peak exceeds available memory."""
    avail = available_memory() if available is None else available
    need = estimate_bytes(rays)
    if avail is None or need <= avail:
        return
    fit = max(1, int(((avail - BASE_BYTES) / PEAK_BYTES_PER_RAY) ** 0.5)) if avail > BASE_BYTES \
        else 1
    raise RayflexError(f"a frame of {rays:,} rays needs about {need / 2**30:.1f} GiB, more than "
                       f"the {avail / 2**30:.1f} GiB of memory available: use a smaller --size "
                       f"(at most about {fit} x {fit} here; frames are not tiled yet)")


def open_backend(name):
    """Build the backend once up front so a missing or broken one fails before any work.
    Returns the backend object (passed to trace) or the name if it is already an object."""
    if not isinstance(name, str):
        return name
    from .backends import backend
    try:
        return backend(name)
    except ImportError as e:
        raise BackendError(f"backend {name!r} is not available: {e}") from None


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


def heatmap_image(ops_per_pixel, width: int, height: int, title: str | None = None) -> np.ndarray:
    """The heat map of datapath operations per pixel (box_ops + tri_ops) with a colour bar, as an
    (H, W, 3) uint8 image (written like any image, in the format its file extension names).

    ops_per_pixel : (width * height,) or (height, width), row 0 at the top.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ops = np.asarray(ops_per_pixel).reshape(height, width)
    aspect = width / height
    fig = Figure(figsize=(min(4.8 * aspect, 12) + 1.4, 4.8), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(ops, cmap="inferno", interpolation="nearest", vmin=0,
                   vmax=max(1, int(ops.max())) if ops.size else 1)
    ax.set_axis_off()
    ax.set_title(title or "datapath operations per pixel", fontsize=10)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    cb.set_label("box + triangle ops per pixel")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def heatmap(ops_per_pixel, width: int, height: int, path, title: str | None = None) -> None:
    """Write the heat map (``heatmap_image``) to ``path`` (format by extension)."""
    save_image(heatmap_image(ops_per_pixel, width, height, title), path)
