"""LumiBench's three ray-generation shaders as workloads (docs/lumibench.md): ``lumibench-pt``,
``lumibench-sh``, ``lumibench-ao``, on any scene.

What each pixel sample does, as the benchmark's shaders do it (one thread per pixel runs its
samples in order; every sample at a sub-pixel offset that is the same in every pixel, as the
benchmark draws it from one seed shared by all pixels):

- ``lumibench-pt`` (path tracing): a path traces at most ``PT_RAYS`` rays (the benchmark's 16
  bounces, the camera ray counting as the first), each a closest-hit ray of extent
  [``TMIN``, ``TMAX``]; at a hit the material scatters: a Lambertian surface hit on its front
  face continues in the direction ``n + s`` (``n`` the unit face normal, ``s`` uniform in the
  unit ball; not normalised, as the shader leaves it) from the hit point, multiplying the
  path's colour by its albedo; a back face (as wound) ends the path, as the shader's
  ``dot(direction, normal) < 0`` test does with the model's normals; an emitter ends it with its
  emission. A miss ends it with the sky colour (sky scenes, and scenes in which no triangle
  emits, which would otherwise be black) or black; a path still going after ``PT_RAYS`` rays
  is black. No light sampling. Ray types ``primary``, ``bounce1`` ...
  ``bounce15``.
- ``lumibench-sh`` (shadows): the camera ray, then at a hit ``SH_RAYS`` any-hit rays from the hit
  point moved ``SH_OFFSET`` along the face normal: towards the sky direction with extent
  ``TMAX`` (both rays the same ray, as in the benchmark), or towards a point drawn in the point
  light's sphere with the distance to it as extent; a shadow ray is traced only when its
  direction is on the normal's side (``dot > 0``); one that is not traced counts as shadowed,
  as in the shader. Colour: the albedo x 0.3 per shadowed ray. Ray types ``primary``, ``shadow``.
- ``lumibench-ao`` (ambient occlusion): the camera ray, then at a hit ``ao_rays`` (4) any-hit
  rays, each direction uniform on the sphere and flipped into the normal's hemisphere, from the
  hit point moved ``AO_OFFSET`` along the direction, extent [``TMIN``, ``AO_EXTENT``]. Colour:
  the albedo x 0.9 per occluded ray. Ray types ``primary``, ``ao``.

The datapath has no minimum t: a ray of extent [``TMIN``, ``tmax``] is traced from
``o + TMIN d`` with extent ``tmax - TMIN`` (the same segment). Every triangle is double-sided
in LumiBench scenes (``driver.scenes.lumibench``); the face normal of the shaders is the
geometric normal of the triangle as wound (the benchmark interpolates the model's vertex
normals). Random numbers are ``driver.scenes.sampling``'s counter-based hash (the benchmark
uses its own generator): the rays differ, their distribution does not. The light of a scene
is its first light: a ``SkyLight`` (LumiBench's sky), a ``SphereLight`` or ``PointLight`` (a
point light of radius 0), or a ``QuadLight`` (a point drawn on the quad); a scene without a
light is lit from the camera's up direction as a sky.

Every random number is a pure function of (seed, pixel, sample, bounce, purpose): a tile traced
alone gives exactly that tile of the frame. Ray types and their statistics as every workload's
(``by_type``).
"""

from __future__ import annotations

import numpy as np

from .scenes import sampling
from .scenes.camera import camera_rays
from .scenes.lumibench import SkyLight, SphereLight

PT, SH, AO = "lumibench-pt", "lumibench-sh", "lumibench-ao"
WORKLOADS = (PT, SH, AO)
TMIN = 0.001                    # every ray's extent starts here (the shaders' tMin)
TMAX = 10000.0
PT_RAYS = 16                    # the path tracer's rays per path at most (its 16 bounces)
SH_RAYS = 2                     # shadow rays per hit (--shadowrays 2)
SH_OFFSET = 0.001               # the shadow rays' origin, off the surface along the normal
SH_SCALE = 0.3                  # colour factor per shadowed ray
AO_OFFSET = 0.01                # the AO rays' origin, moved along the ray
AO_EXTENT = 10.0
AO_SCALE = 0.9                  # colour factor per occluded AO ray
SKY_TOP = np.array([0.5, 0.7, 1.0])          # the sky colour: white at the horizon, blue above
SKY_DIRECTION = (0.0, 1.0, 0.0)


def sky_colour(dirs: np.ndarray) -> np.ndarray:
    """The sky scenes' background: white to (0.5, 0.7, 1.0) with the direction's height."""
    d = np.asarray(dirs, np.float64)
    t = 0.5 * (d[:, 1] / np.maximum(np.linalg.norm(d, axis=1), 1e-300) + 1.0)
    return (1.0 - t)[:, None] + t[:, None] * SKY_TOP


def unit_sphere(u1, u2) -> np.ndarray:
    """Uniform unit directions (k, 3) from two uniform numbers each."""
    z = 1.0 - 2.0 * np.asarray(u1, np.float64)
    phi = 2.0 * np.pi * np.asarray(u2, np.float64)
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def in_ball(seed, pixel, sample, bounce, purpose) -> np.ndarray:
    """Uniform points (k, 3) in the unit ball (the shaders' ``RandomInUnitSphere``)."""
    u1, u2 = sampling.uniform2(seed, pixel, sample, bounce, purpose)
    u3 = sampling.uniform(seed, pixel, sample, bounce, purpose, 2)
    return unit_sphere(u1, u2) * np.cbrt(u3)[:, None]


def shader_light(setup):
    """("sky", direction) or ("point", sampler(u1, u2, u3) -> points (k, 3)) of a scene's
    first light (module docstring)."""
    lights = list(getattr(setup, "lights", []) or [])
    light = lights[0] if lights else None
    if isinstance(light, SkyLight):
        return "sky", np.asarray(light.direction, np.float64)
    if isinstance(light, SphereLight):
        return "point", lambda u1, u2, u3: light.sample(u1, u2, u3)[0]
    if light is not None and hasattr(light, "position"):               # PointLight
        pos = np.asarray(light.position, np.float64)
        return "point", lambda u1, u2, u3: np.broadcast_to(pos, (len(u1), 3))
    if light is not None:                                              # QuadLight
        return "point", lambda u1, u2, u3: light.sample(u1, u2)[0]
    _, _, up = setup.camera.basis()
    return "sky", up


def _with_tmin(o: np.ndarray, d: np.ndarray, tmax):
    """A ray of extent [TMIN, tmax] as the datapath's [0, extent): origin moved TMIN along d."""
    o2 = (np.asarray(o, np.float64) + TMIN * np.asarray(d, np.float64)).astype(np.float32)
    ext = np.broadcast_to(np.asarray(tmax, np.float64) - TMIN, (len(o2),)).astype(np.float32)
    return o2, np.asarray(d, np.float32), ext


def _camera(fr):
    """The camera rays of every (pixel, sample): the sample's offset shared by all pixels."""
    pix = np.repeat(fr.pixels, fr.spp)
    smp = np.tile(np.arange(fr.spp), len(fr.pixels))
    jx, jy = sampling.uniform2(fr.seed, 0, smp, 0, sampling.CAMERA)
    o, d = camera_rays(fr.setup.camera, fr.w, fr.h, pix, jx, jy)
    o, d, ext = _with_tmin(o, d, TMAX)
    return fr.trace_rays("primary", pix, smp, o, d, ext, False, np.zeros(len(pix), np.int64))


def _hits(fr, b):
    """Hit rows of batch ``b``, their hit points (float64, on the triangle's plane), unit face
    normals as wound (not turned towards the ray), primitives."""
    res = b.result
    rows = np.flatnonzero(res.hit)
    prim = res.prim[rows]
    tri = np.asarray(fr.setup.triangles[prim], np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    d = b.dirs[rows].astype(np.float64)
    p = b.origins[rows].astype(np.float64) + res.t[rows, None].astype(np.float64) * d
    p -= np.einsum("ij,ij->i", p - tri[:, 0], n)[:, None] * n          # back onto the plane
    return rows, p, n, prim


def _miss_colour(fr, dirs, sky: bool) -> np.ndarray:
    return sky_colour(dirs) if sky else np.zeros((len(dirs), 3))


def calls(workload: str, ao_rays: int) -> int:
    """Trace calls per pixel sample of a shader's program (at most): its rays' slots are
    ``sample * calls + call``, call 0 the camera ray (a ray's place in its thread's program,
    which the RT unit's one-kernel replay follows)."""
    return {PT: PT_RAYS + 1, SH: 1 + SH_RAYS, AO: 1 + ao_rays}[workload]


def run(fr, workload: str) -> np.ndarray:
    """Trace ``workload`` on frame ``fr`` (``driver.workloads.Frame``); the radiance of every
    (pixel, sample) row (npix * spp, 3), linear."""
    fr.calls = calls(workload, fr.ao_rays)
    if workload == PT:
        return _pt(fr)
    if workload == SH:
        return _sh(fr)
    if workload == AO:
        return _ao(fr)
    raise ValueError(f"unknown LumiBench workload {workload!r}")


def _albedo(fr, prim) -> np.ndarray:
    return np.asarray(fr.setup.materials.albedo[prim], np.float64)


def _emits(mats) -> bool:
    """Whether any triangle of the scene emits light."""
    e = getattr(mats.emission, "values", mats.emission)       # driver.instances.PerInstance
    return bool(np.asarray(e).any())


def _pt(fr) -> np.ndarray:
    kind, _ = shader_light(fr.setup)
    sky = kind == "sky" or not _emits(fr.setup.materials)   # else nothing would light a path
    b = _camera(fr)
    colour = np.zeros((len(b.pixel), 3))
    ray = np.arange(len(b.pixel))               # the (pixel, sample) row of each path
    through = np.ones((len(ray), 3))
    mats = fr.setup.materials
    for depth in range(PT_RAYS):
        miss = ~b.result.hit
        colour[ray[miss]] = through[miss] * _miss_colour(fr, b.dirs[miss], sky)
        rows, p, n, prim = _hits(fr, b)
        if not len(rows):
            break
        emit = np.asarray(mats.emission[prim], np.float64)
        emitter = emit.any(axis=1)
        colour[ray[rows[emitter]]] = through[rows[emitter]] * emit[emitter]
        front = np.einsum("ij,ij->i", b.dirs[rows].astype(np.float64), n) < 0
        alb = _albedo(fr, prim)
        stop = ~emitter & ~front                # a back face ends the path with its albedo
        colour[ray[rows[stop]]] = through[rows[stop]] * alb[stop]
        go = np.flatnonzero(~emitter & front)
        if depth == PT_RAYS - 1 or not len(go):
            break                               # a path still going after PT_RAYS rays: black
        r = rows[go]
        pix, smp = b.pixel[r], b.sample[r]
        d = n[go] + in_ball(fr.seed, pix, smp, depth + 1, sampling.BOUNCE)
        small = np.linalg.norm(d, axis=1) < 1e-8 * np.linalg.norm(n[go], axis=1)
        d[small] = n[go][small]
        o, d, ext = _with_tmin(p[go], d, TMAX)
        through = through[r] * alb[go]
        ray = ray[r]
        b = fr.trace_rays(f"bounce{depth + 1}", pix, smp, o, d, ext, False,
                          np.full(len(pix), depth + 1, np.int64))
    return colour


def _per_hit(fr, count: int):
    """The camera rays, the colour of every (pixel, sample) so far (the sky's where they
    miss), and ``count`` secondary rays' keys per hit: (light kind, light, rows, hit points,
    normals, primitives, pixel, sample, j (0..count-1) of each, the normal repeated)."""
    kind, light = shader_light(fr.setup)
    b = _camera(fr)
    colour = _miss_colour(fr, b.dirs, kind == "sky")
    rows, p, n, prim = _hits(fr, b)
    pix = np.repeat(b.pixel[rows], count)
    smp = np.repeat(b.sample[rows], count)
    j = np.tile(np.arange(count), len(rows))
    return kind, light, colour, rows, p, n, prim, pix, smp, j, np.repeat(n, count, axis=0)


def _sh(fr) -> np.ndarray:
    kind, light, colour, rows, p, n, prim, pix, smp, j, nn = _per_hit(fr, SH_RAYS)
    k = len(rows)
    o = np.repeat(p + SH_OFFSET * n, SH_RAYS, axis=0)
    if kind == "sky":
        d = np.broadcast_to(light / np.linalg.norm(light), (len(pix), 3)).copy()
        tmax = np.full(len(pix), TMAX)
    else:
        key = smp * SH_RAYS + j
        u1, u2 = sampling.uniform2(fr.seed, pix, key, 0, sampling.LIGHT)
        u3 = sampling.uniform(fr.seed, pix, key, 0, sampling.LIGHT, 2)
        to = light(u1, u2, u3) - o
        tmax = np.linalg.norm(to, axis=1)
        d = to / np.maximum(tmax, 1e-300)[:, None]
    go = np.flatnonzero(np.einsum("ij,ij->i", d, nn) > 0)
    o2, d2, ext = _with_tmin(o[go], d[go], tmax[go])
    sh = fr.trace_rays("shadow", pix[go], smp[go], o2, d2, ext, True, 1 + j[go])
    shadowed = np.ones(len(pix), bool)          # a ray not traced counts as shadowed
    shadowed[go] = sh.result.hit
    count = shadowed.reshape(k, SH_RAYS).sum(axis=1)
    colour[rows] = _albedo(fr, prim) * (SH_SCALE ** count)[:, None]
    return colour


def _ao(fr) -> np.ndarray:
    m = fr.ao_rays
    _, _, colour, rows, p, n, prim, pix, smp, j, nn = _per_hit(fr, m)
    u1, u2 = sampling.uniform2(fr.seed, pix, smp * m + j, 0, sampling.AO)
    d = unit_sphere(u1, u2)
    d = np.where((np.einsum("ij,ij->i", d, nn) <= 0)[:, None], -d, d)
    o = np.repeat(p, m, axis=0) + AO_OFFSET * d
    o2, d2, ext = _with_tmin(o, d, AO_EXTENT)
    ao = fr.trace_rays("ao", pix, smp, o2, d2, ext, True, 1 + j)
    count = ao.result.hit.reshape(len(rows), m).sum(axis=1)
    colour[rows] = _albedo(fr, prim) * (AO_SCALE ** count)[:, None]
    return colour
