"""Rendering workloads (docs/workloads.md): which rays a frame shoots, and the image they make.

An integrator never sees node layouts (pbrt's split): it makes rays, hands each batch to
``driver.tracer.trace`` (every box and triangle test on the datapath), and shades the hits. Each
batch is one wavefront through the datapath with all its rays in flight; a frame is a sequence of
them:

- ``primary``: one camera ray per pixel and sample (pixel centre for one sample, stratified jitter
  for more), closest hit; the image is head-light shading (``headlight``).
- ``shadow``: primary rays, then from every hit one shadow ray to a point sampled on the light
  (any hit, extent just short of the light); the image is direct diffuse lighting.
- ``ao``: primary rays, then ``ao_rays`` cosine-distributed rays per hit on the hemisphere of the
  geometric normal facing the incoming ray (any hit, extent = the scene's AO radius); the image is
  the unoccluded fraction.
- ``path``: diffuse (Lambertian) path tracing with next-event estimation: at every vertex one
  shadow ray to the light and, up to ``bounces`` deep, one cosine-distributed closest-hit
  continuation ray (ray types ``bounce1``, ``bounce2``, ...). Emission is counted where a camera
  ray sees a light directly; after that light arrives only through the shadow rays (no double
  counting).

Every random decision is ``driver.scenes.sampling.uniform`` of (seed, pixel, sample, bounce,
purpose), so any subset of pixels (a tile) traced alone gives exactly its part of the whole frame.
Ray types and their statistics: ``by_type`` (``driver.stats.merge``; docs/statistics.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import lumibench_shaders
from .check import check_rays, embree_sample, merge_checks
from .scenes import sampling
from .scenes.camera import camera_rays
from .scenes.materials import Materials, PointLight
from .stats import merge

WORKLOADS = ("primary", "shadow", "ao", "path") + lumibench_shaders.WORKLOADS
LINEAR = ("primary", "ao") + lumibench_shaders.WORKLOADS   # images shown linear (no exposure)
SHADOW_EXTENT = 1.0 - 1e-4     # shadow rays aim at the light sample with d = y - x: t in [0, 1)
TONE_ROWS = 256                                # tone mapping works on this many rows at a time
BASE_COLOUR = np.array([0.92, 0.86, 0.76])     # the primary workload's surface colour
AMBIENT = 0.08
BG_TOP = np.array([0.42, 0.52, 0.66])          # its background gradient
BG_BOTTOM = np.array([0.10, 0.11, 0.14])
AO_RADIUS_REL = 0.1            # default AO radius: 10 % of the scene's bounding-box diagonal


@dataclass
class Setup:
    """What a workload needs of a scene: triangles (m, 3, 3), camera, materials, lights,
    whether triangles are double-sided, the AO radius, the background radiance. ``triangles``
    and the materials' arrays may be computed on indexing (``driver.instances``:
    ``InstancedTriangles``, ``PerInstance``): workloads only index them by primitive id."""

    triangles: np.ndarray
    camera: object
    materials: Materials
    lights: list
    double_sided: bool = False
    ao_radius: float | None = None
    background: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if hasattr(self.triangles, "bounds"):       # driver.instances.InstancedTriangles
            lo, hi = self.triangles.bounds()
        else:
            lo, hi = self.triangles.reshape(-1, 3).min(0), self.triangles.reshape(-1, 3).max(0)
        diag = float(np.linalg.norm(hi.astype(np.float64) - lo))
        if self.ao_radius is None:
            self.ao_radius = AO_RADIUS_REL * diag
        if not self.lights:
            self.lights = [default_light(self.camera, lo, hi)]


def default_light(camera, lo, hi) -> PointLight:
    """A point light above and behind the camera, bright enough to light the scene's centre with
    irradiance about 1."""
    _, _, up = camera.basis()
    centre = (np.asarray(lo, np.float64) + hi) / 2
    diag = float(np.linalg.norm(np.asarray(hi, np.float64) - lo))
    pos = np.asarray(camera.position, np.float64) + up * 0.5 * diag
    r2 = float(np.sum((pos - centre) ** 2))
    return PointLight(tuple(pos), (r2,) * 3)


@dataclass
class Batch:
    """One wavefront of one ray type: which pixel and sample each ray belongs to, its rays, and
    (after tracing) its hits. For the RT-unit replay (docs/rtunit.md) every ray also names its
    ``thread`` (the pixel: one thread per pixel runs its samples in order; default ``pixel``)
    and its ``slot``: the trace call site in the thread's program, a number that grows along
    the program (``Frame.slot``; two rays of one thread never share a slot, rays of several
    threads at one slot are one trace call of their warp)."""

    kind: str                      # ray type (its by_type name, docs/statistics.md)
    pixel: np.ndarray              # (k,) pixel index of each ray
    sample: np.ndarray             # (k,) sample index
    origins: np.ndarray
    dirs: np.ndarray
    extent: np.ndarray
    any_hit: bool
    result: object = None
    slot: np.ndarray | None = None     # (k,) int64 program slot of each ray
    thread: np.ndarray | None = None   # (k,) int64 thread of each ray (None: ``pixel``)

    def __post_init__(self):
        if self.thread is None:
            self.thread = np.asarray(self.pixel, np.int64)
        if self.slot is None:
            raise ValueError(f"batch {self.kind!r}: every ray needs its program slot")
        self.slot = np.broadcast_to(np.asarray(self.slot, np.int64), (len(self.pixel),))


@dataclass
class FrameResult:
    """radiance (npix, 3) float64 (linear; AO: the unoccluded fraction); ops[type] (npix,) int64
    datapath ops per pixel; stats: totals + ``by_type``; batches: every traced batch; timings:
    the wall-time phases of a frame traced on Dask (``driver.tiles.render_tiles``), in seconds."""

    radiance: np.ndarray
    ops: dict
    stats: dict
    batches: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)


class Frame:
    """Trace one workload over ``pixels`` (indices into the width x height image)."""

    def __init__(self, setup: Setup, bvh, width: int, height: int, tracer, spp: int = 1,
                 bounces: int = 1, ao_rays: int = 4, seed: int = 0, pixels=None,
                 calls: int = 1):
        check_arguments(spp, bounces, ao_rays, seed)
        self.setup, self.bvh, self.w, self.h = setup, bvh, width, height
        self.trace = tracer   # trace(bvh, origins, dirs, extent=, any_hit=, double_sided=)
        self.spp, self.bounces, self.ao_rays, self.seed = spp, bounces, ao_rays, seed
        self.pixels = (np.arange(width * height) if pixels is None
                       else np.asarray(pixels, np.int64))
        self.calls = calls    # trace calls per sample in the thread's program (``slot``)
        self.batches: list[Batch] = []

    def slot(self, sample, call) -> np.ndarray:
        """Program slot of trace call ``call`` (0: the camera ray; a number or one per ray) of
        ``sample``: one thread per pixel runs its samples in order, each sample ``calls`` trace
        call sites."""
        call = np.asarray(call, np.int64)
        if call.size and (int(call.min()) < 0 or int(call.max()) >= self.calls):
            raise ValueError(f"trace call {int(call.max())} outside the program's {self.calls} "
                             "per sample")
        return np.asarray(sample, np.int64) * self.calls + call

    def trace_rays(self, kind, pixel, sample, origins, dirs, extent, any_hit, call) -> Batch:
        """Trace one wavefront of ray type ``kind`` (a ``Batch``'s fields) and keep it.
        ``call``: each ray's trace call in its pixel sample's program (``slot``; the thread is
        the pixel), its place in its thread's program (the RT unit's one-kernel replay)."""
        return self._run(Batch(kind, pixel, sample, origins, dirs, extent, any_hit,
                               slot=self.slot(sample, call)))

    def _run(self, batch: Batch) -> Batch:
        batch.result = self.trace(self.bvh, batch.origins, batch.dirs, extent=batch.extent,
                                  any_hit=batch.any_hit, double_sided=self.setup.double_sided)
        self.batches.append(batch)
        return batch

    def primary(self) -> Batch:
        pix = np.repeat(self.pixels, self.spp)
        smp = np.tile(np.arange(self.spp), len(self.pixels))
        jx, jy = sampling.jitter(self.seed, pix, smp, self.spp)
        o, d = camera_rays(self.setup.camera, self.w, self.h, pix, jx, jy)
        return self._run(Batch("primary", pix, smp, o, d, np.full(len(pix), np.inf), False,
                               slot=self.slot(smp, 0)))

    def surface(self, b: Batch):
        """Hit rows, hit points (float64), unit geometric normals facing the incoming ray, prim."""
        res = b.result
        rows = np.flatnonzero(res.hit)
        prim = res.prim[rows]
        tri = self.setup.triangles[prim].astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        d = b.dirs[rows].astype(np.float64)
        n = np.where((np.einsum("ij,ij->i", n, d) > 0)[:, None], -n, n)
        p = b.origins[rows].astype(np.float64) + res.t[rows, None].astype(np.float64) * d
        p -= np.einsum("ij,ij->i", p - tri[:, 0], n)[:, None] * n      # back onto the plane
        return rows, p, n, prim

    def shadow(self, b: Batch, depth: int, rows, p, n, call: int = 1):
        """Shadow rays to light samples from the hits ``rows`` of batch ``b``: only where the
        sample faces the surface and the light faces the point (elsewhere the light adds nothing
        and no ray is traced). Returns (batch, the rows it serves (index into ``rows``), their
        unshadowed light (radiance x geometry / pi, without the albedo) (k, 3))."""
        lights = self.setup.lights
        pix, smp = b.pixel[rows], b.sample[rows]
        u1, u2 = sampling.uniform2(self.seed, pix, smp, depth, sampling.LIGHT)
        which = np.minimum((sampling.uniform(self.seed, pix, smp, depth, sampling.LIGHT, 2)
                            * len(lights)).astype(np.int64), len(lights) - 1)
        y, ny, le = np.zeros((len(rows), 3)), np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
        is_point = np.zeros(len(rows), bool)
        for i, light in enumerate(lights):
            sel = which == i
            py, nl, e = light.sample(u1[sel], u2[sel])
            y[sel], le[sel] = py, e
            if nl is None:
                is_point[sel] = True
            else:
                ny[sel] = nl
        o = sampling.offset_origin(p, n)
        d = y - o.astype(np.float64)
        r2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        w = d / np.sqrt(r2)[:, None]
        cos_x = np.einsum("ij,ij->i", n, w)
        cos_y = np.where(is_point, 1.0, -np.einsum("ij,ij->i", ny, w))
        go = np.flatnonzero((cos_x > 0) & (cos_y > 0))
        factor = le[go] * (len(lights) * cos_x[go] * cos_y[go] / r2[go] / np.pi)[:, None]
        batch = Batch("shadow", pix[go], smp[go], o[go], d[go].astype(np.float32),
                      np.full(len(go), SHADOW_EXTENT, np.float32), True,
                      slot=self.slot(smp[go], call))
        return self._run(batch), go, factor

    def hemisphere(self, kind, b, rows, n, p, depth, purpose, count, call: int = 1):
        """``count`` cosine-distributed rays per hit (pixel-major), from the offset hit points;
        ray j of a hit is trace call ``call + j`` of its sample."""
        pix = np.repeat(b.pixel[rows], count)
        smp = np.repeat(b.sample[rows], count)
        j = np.tile(np.arange(count), len(rows))
        key = smp * max(count, 1) + j
        u1, u2 = sampling.uniform2(self.seed, pix, key, depth, purpose)
        nn = np.repeat(n, count, axis=0)
        d = sampling.cosine_hemisphere(nn, u1, u2)
        o = sampling.offset_origin(np.repeat(p, count, axis=0), nn)
        ext = self.setup.ao_radius if kind == "ao" else np.inf
        return self._run(Batch(kind, pix, smp, o, d.astype(np.float32),
                               np.full(len(pix), ext, np.float32), kind == "ao",
                               slot=self.slot(smp, call) + j))


def check_arguments(spp, bounces, ao_rays, seed) -> None:
    """One-line ValueErrors for bad workload arguments."""
    for name, v, lo in (("spp", spp, 1), ("bounces", bounces, 0), ("ao-rays", ao_rays, 1),
                        ("seed", seed, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise ValueError(f"--{name} must be an integer >= {lo}, got {v!r}")
    if spp > 4096 or ao_rays > 1024 or bounces > 64:
        raise ValueError("--spp is at most 4096, --ao-rays 1024 and --bounces 64")


def run(setup: Setup, bvh, width: int, height: int, tracer, workload: str = "primary",
        **options) -> FrameResult:
    """Trace ``workload`` (``WORKLOADS``) on ``pixels`` (default: all) of a width x height frame.
    ``tracer(bvh, origins, dirs, extent=, any_hit=, double_sided=)`` runs each batch
    (``driver.tracer.trace`` with the backend bound). Options: spp, bounces, ao_rays, seed,
    pixels."""
    if workload not in WORKLOADS:
        raise ValueError(f"unknown workload {workload!r}; available: {', '.join(WORKLOADS)}")
    fr = Frame(setup, bvh, width, height, tracer, calls=calls_per_sample(workload, **{
        k: options[k] for k in ("bounces", "ao_rays") if k in options}), **options)
    if workload in lumibench_shaders.WORKLOADS:             # docs/lumibench.md
        return _finish(fr, lumibench_shaders.run(fr, workload))
    npix = len(fr.pixels)
    radiance = np.zeros((npix * fr.spp, 3))
    prim = fr.primary()
    if workload == "primary":
        radiance[:] = headlight(prim.result.prim, setup.triangles, prim.dirs, prim.pixel, width,
                                height)
    elif workload == "ao":
        rows, p, n, _ = fr.surface(prim)
        ao = fr.hemisphere("ao", prim, rows, n, p, 0, sampling.AO, fr.ao_rays)
        free = (~ao.result.hit).reshape(len(rows), fr.ao_rays).mean(axis=1)
        radiance[rows] = free[:, None]
    else:
        _paths(fr, prim, radiance, fr.bounces if workload == "path" else 0)
    return _finish(fr, radiance)


def calls_per_sample(workload: str, bounces: int = 1, ao_rays: int = 4) -> int:
    """Trace call sites per sample of a workload's thread program (docs/rtunit.md): the camera
    ray; shadow: one shadow ray; ao: ``ao_rays`` AO rays, one call each; path: per vertex a
    shadow ray and (but the last) a continuation ray; LumiBench's shaders: docs/lumibench.md."""
    if workload in lumibench_shaders.WORKLOADS:
        return lumibench_shaders.calls(workload, ao_rays)
    return {"primary": 1, "shadow": 2, "ao": 1 + ao_rays, "path": 2 + 2 * bounces}[workload]


def check_program(batches) -> None:
    """One-line ValueError when a thread has two rays at one slot of its program (the replay
    needs every ray's place in its thread's program; ``Batch``)."""
    if not batches:
        return
    t = np.concatenate([b.thread for b in batches])
    s = np.concatenate([b.slot for b in batches])
    key = np.unique(np.stack([t, s]), axis=1) if len(t) else np.zeros((2, 0))
    if key.shape[1] != len(t):
        raise ValueError("a thread has two rays at one slot of its program: each trace call "
                         "site of a thread needs its own slot (driver.workloads.Batch)")


def headlight(prim, triangles, dirs, pixels, width: int, height: int) -> np.ndarray:
    """The primary workload's look, linear RGB (k, 3): flat face normals, Lambert with a head
    light (the light at the camera), a little ambient; misses show a vertical background gradient
    (the pixel's row picks it). Gamma is applied by ``tone_map(..., linear=True)``."""
    prim = np.asarray(prim, np.int64).reshape(-1)
    rows = np.linspace(0.0, 1.0, height)[np.asarray(pixels, np.int64) // width][:, None]
    rgb = BG_TOP * (1 - rows) + BG_BOTTOM * rows
    hit = prim >= 0
    if hit.any():
        tri = np.asarray(triangles[prim[hit]], np.float64)
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(nrm, axis=1)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)[hit]
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            lam = np.abs(np.einsum("ij,ij->i", nrm, d)) / length
        lam = np.nan_to_num(lam, nan=0.0)                            # degenerate triangles
        rgb[hit] = BASE_COLOUR * (AMBIENT + (1 - AMBIENT) * lam[:, None])
    return rgb


def _paths(fr: Frame, b: Batch, radiance: np.ndarray, bounces: int) -> None:
    """Direct light at the primary hits (bounces = 0) or full diffuse paths with NEE."""
    mats = fr.setup.materials
    ray = np.arange(len(b.pixel))                # the sample (row of radiance) of each ray
    throughput = np.ones((len(ray), 3))
    for depth in range(bounces + 1):
        miss = ~b.result.hit
        radiance[ray[miss]] += throughput[miss] * np.asarray(fr.setup.background, np.float64)
        rows, p, n, prim = fr.surface(b)
        if depth == 0:
            radiance[ray[rows]] += mats.emission[prim]
        if not len(rows):
            break
        alb = mats.albedo[prim] * throughput[rows]
        sh, go, factor = fr.shadow(b, depth, rows, p, n, call=1 + 2 * depth)
        lit = ~sh.result.hit
        np.add.at(radiance, ray[rows[go[lit]]], alb[go[lit]] * factor[lit])
        if depth == bounces:
            break
        b = fr.hemisphere(f"bounce{depth + 1}", b, rows, n, p, depth + 1, sampling.BOUNCE, 1,
                          call=2 + 2 * depth)
        ray, throughput = ray[rows], alb


def _finish(fr: Frame, radiance: np.ndarray) -> FrameResult:
    """Average samples per pixel, ops per pixel per ray type, statistics per ray type."""
    npix = len(fr.pixels)
    per_pixel = radiance.reshape(npix, fr.spp, 3).mean(axis=1)
    order = np.argsort(fr.pixels, kind="stable")      # pixel index -> row of this frame's arrays
    ops, stats = {}, {}
    for b in fr.batches:
        k = b.result.ops                     # box, triangle and transform requests
        idx = order[np.searchsorted(fr.pixels, b.pixel, sorter=order)]
        ops.setdefault(b.kind, np.zeros(npix, np.int64))
        np.add.at(ops[b.kind], idx, k)
        stats.setdefault(b.kind, []).append(b.result.stats)
    by_type = {kind: merge(parts) for kind, parts in stats.items()}
    total = merge([s for parts in stats.values() for s in parts])
    total["by_type"] = by_type
    return FrameResult(per_pixel, ops, total, fr.batches)


def tone_map(radiance: np.ndarray, width: int, height: int, exposure: float | None = None,
             linear: bool = False):
    """(h, w, 3) uint8: exposure (default: the 99th percentile of luminance maps to 1), Reinhard
    on luminance, gamma 2.2; ``linear``: values in [0, 1] as they are (AO), gamma 2.2 only."""
    rgb = np.asarray(radiance).reshape(height, width, 3)
    weights = np.array([0.2126, 0.7152, 0.0722])
    if not linear and exposure is None:
        lum = np.concatenate([(rgb[r:r + TONE_ROWS].astype(np.float64) @ weights).ravel()
                              for r in range(0, height, TONE_ROWS)]) if rgb.size else np.ones(1)
        top = float(np.percentile(lum, 99))
        exposure = 1.0 / top if top > 0 else 1.0
    out = np.empty((height, width, 3), np.uint8)
    for r in range(0, height, TONE_ROWS):            # in row blocks: bounded float64 copies
        x = rgb[r:r + TONE_ROWS].astype(np.float64)
        if not linear:
            x = x * exposure
            x = x / (1.0 + (x @ weights)[..., None]) * 2.0
        out[r:r + TONE_ROWS] = (np.clip(x, 0.0, 1.0) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)
    return out


def embree_check(result: FrameResult, setup: Setup) -> dict:
    """Check every traced batch against Embree (``driver.check.check_rays``); puts the
    ``embree`` object into the frame's statistics and into each ray type's; returns the total."""
    per_kind: dict = {}
    for b in result.batches:
        r = b.result
        tri, rows, prim = setup.triangles, slice(None), r.prim
        if hasattr(tri, "instances"):       # too large to flatten: a sample (driver.instances)
            rows, tri, prim = embree_sample(tri.instances, b.origins, b.dirs, b.extent, r.t,
                                            r.prim)
        ext = np.broadcast_to(np.asarray(b.extent, np.float64), (len(r.t),))
        part = check_rays(tri, b.origins[rows], b.dirs[rows], ext[rows], r.t[rows], prim,
                          b.any_hit, setup.double_sided)
        for rec in part["adjudicated"]["rays"]:         # which ray: its type, pixel, sample
            at = np.arange(len(r.t))[rows][rec.pop("ray")]
            rec.update(ray_type=b.kind, pixel=int(b.pixel[at]), sample=int(b.sample[at]))
        per_kind.setdefault(b.kind, []).append(part)
    for kind, parts in per_kind.items():
        result.stats["by_type"][kind]["embree"] = merge_checks(parts)
    total = merge_checks([p for parts in per_kind.values() for p in parts])
    result.stats["embree"] = total
    return total


def setup_for(scene) -> Setup:
    """The ``Setup`` of a loaded scene (``driver.scenes.scene.Scene``): its triangles and camera,
    and its materials, lights, double-sidedness and AO radius where the scene defines them."""
    tri = scene.triangles
    mats = getattr(scene, "materials", None) or Materials.plain(len(tri))
    return Setup(tri, scene.camera, mats, list(getattr(scene, "lights", None) or []),
                 bool(getattr(scene, "double_sided", False)), getattr(scene, "ao_radius", None))
