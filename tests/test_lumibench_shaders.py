"""LumiBench's shaders (driver/lumibench_shaders.py) on hand-checked scenes: how many rays each
pixel sample traces, where they start, where they go and how far."""

from __future__ import annotations

import numpy as np
import pytest

from driver import lumibench_shaders as ls
from driver import workloads
from driver.bvh4 import build
from driver.scenes.camera import Camera, camera_rays
from driver.scenes.lumibench import SkyLight, SphereLight
from driver.scenes.materials import Materials
from driver.tracer import trace

SIZE, SPP = 8, 2
F32 = np.float32


def floor(y=0.0, half=50.0, up=True):
    """A square floor at height y facing +y (up) or -y, two triangles."""
    a, b, c, d = (-half, y, -half), (half, y, -half), (half, y, half), (-half, y, half)
    tri = [[a, d, c], [a, c, b]] if up else [[a, c, d], [a, b, c]]
    return np.array(tri, F32)


def setup(tri, light=None, albedo=0.5):
    cam = Camera((0.0, 4.0, 0.0), (0.0, 0.0, 0.01), (0.0, 1.0, 0.0), 40.0)   # looking down
    mats = Materials(np.full((len(tri), 3), albedo), np.zeros((len(tri), 3)))
    return workloads.Setup(tri, cam, mats, [light or SkyLight()], True, 10.0)


def frame(s, workload, **kw):
    bvh = build(s.triangles)
    tracer = lambda b, o, d, **k: trace(b, o, d, backend="golden", **k)  # noqa: E731
    return workloads.run(s, bvh, SIZE, SIZE, tracer, workload, spp=SPP, **kw)


def batch(res, kind):
    (b,) = [b for b in res.batches if b.kind == kind]
    return b


def test_camera_rays_share_each_samples_offset_and_start_at_tmin():
    s = setup(floor())
    res = frame(s, ls.AO)
    cam = batch(res, "primary")
    assert len(cam.pixel) == SIZE * SIZE * SPP
    # every pixel's sample k is at the same sub-pixel offset: the rays equal camera rays through
    # one (jx, jy) per sample
    for k in range(SPP):
        sel = cam.sample == k
        pix = cam.pixel[sel]
        best = None
        for jx in np.linspace(0.0, 1.0, 101):
            for jy in np.linspace(0.0, 1.0, 101):
                _, d = camera_rays(s.camera, SIZE, SIZE, pix[:1], jx, jy)
                err = float(np.abs(d[0] - cam.dirs[sel][0]).max())
                if best is None or err < best[0]:
                    best = (err, jx, jy)
        _, d = camera_rays(s.camera, SIZE, SIZE, pix, best[1], best[2])
        assert np.abs(d - cam.dirs[sel]).max() < 0.02            # one offset for all pixels
    o = cam.origins.astype(np.float64) - np.asarray(s.camera.position)
    assert np.allclose(o, ls.TMIN * cam.dirs, atol=1e-6)         # moved TMIN along the ray
    assert np.allclose(cam.extent, ls.TMAX - ls.TMIN)


def test_sh_traces_two_sky_rays_per_hit_on_the_lit_side_only():
    lit = frame(setup(floor(up=True)), ls.SH)
    cam, sh = batch(lit, "primary"), batch(lit, "shadow")
    assert cam.result.hit.all()
    assert len(sh.pixel) == ls.SH_RAYS * len(cam.pixel)           # two per hit
    assert np.allclose(sh.dirs, [0.0, 1.0, 0.0])                   # towards the sky
    # origin: the hit moved SH_OFFSET along the normal, then TMIN along the ray
    assert np.allclose(sh.origins[:, 1], ls.SH_OFFSET + ls.TMIN, atol=1e-6)
    assert sh.any_hit and not sh.result.hit.any()
    assert np.allclose(lit.radiance, 0.5)                          # nothing shadows: the albedo
    # the same floor facing down: every hit is on its back, no shadow ray faces the sky
    dark = frame(setup(floor(up=False)), ls.SH)
    assert batch(dark, "primary").result.hit.all()
    assert not [b for b in dark.batches if b.kind == "shadow" and len(b.pixel)]
    assert np.allclose(dark.radiance, 0.5 * ls.SH_SCALE ** 2)      # untraced rays are shadowed


def test_sh_point_light_rays_end_at_a_point_of_the_light():
    light = SphereLight((3.0, 20.0, 1.0), 2.0)
    res = frame(setup(floor(), light), ls.SH)
    sh = batch(res, "shadow")
    assert len(sh.pixel) == ls.SH_RAYS * SIZE * SIZE * SPP
    d = sh.dirs.astype(np.float64)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    end = sh.origins + (sh.extent[:, None].astype(np.float64)) * d   # the sampled light point
    assert (np.linalg.norm(end - light.position, axis=1) <= light.radius + 1e-3).all()
    # a light below the floor: no shadow ray is on the lit side
    below = frame(setup(floor(), SphereLight((0.0, -5.0, 0.0), 1.0)), ls.SH)
    assert not [b for b in below.batches if b.kind == "shadow" and len(b.pixel)]


def test_ao_rays_in_the_hemisphere_within_their_extent():
    ceiling = floor(y=6.0, up=False)                               # above the camera (y = 4)
    res = frame(setup(np.concatenate([floor(), ceiling])), ls.AO, ao_rays=4)
    cam, ao = batch(res, "primary"), batch(res, "ao")
    hits = int(cam.result.hit.sum())
    assert len(ao.pixel) == 4 * hits
    d = ao.dirs.astype(np.float64)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    assert (d[:, 1] > 0).all()                                     # the floor's hemisphere
    assert abs(d[:, 1].mean() - 0.5) < 0.05                        # uniform, not cosine (2/3)
    assert np.allclose(ao.extent, ls.AO_EXTENT - ls.TMIN)
    assert np.allclose(ao.origins[:, 1], (ls.AO_OFFSET + ls.TMIN) * d[:, 1], atol=1e-5)
    # occluded exactly when the ceiling is within the extent along the ray
    reach = ao.origins[:, 1] + ao.extent * d[:, 1]
    assert 0 < ao.result.hit.sum() < len(ao.pixel)
    assert np.array_equal(ao.result.hit, reach > 6.0)
    # colour: the albedo x 0.9 per occluded ray, averaged over the pixel's two samples
    count = ao.result.hit.reshape(-1, 4).sum(axis=1)
    per_sample = 0.5 * ls.AO_SCALE ** count
    assert np.allclose(res.radiance[:, 0], per_sample.reshape(-1, SPP).mean(axis=1))


def test_pt_bounces_until_a_miss_and_at_most_sixteen_rays():
    open_res = frame(setup(floor()), ls.PT)
    kinds = {b.kind for b in open_res.batches}
    assert kinds == {"primary", "bounce1"}                         # up, then into the sky
    b1 = batch(open_res, "bounce1")
    cam = batch(open_res, "primary")
    assert len(b1.pixel) == int(cam.result.hit.sum())
    # direction = n + a point in the unit ball (not normalised)
    assert (np.linalg.norm(b1.dirs - np.array([0.0, 1.0, 0.0], F32), axis=1) <= 1 + 1e-6).all()
    assert not b1.result.hit.any()
    # the floor seen from below: a back face ends every path at once
    back = frame(setup(floor(up=False)), ls.PT)
    assert {b.kind for b in back.batches} == {"primary"}
    # a closed box: every path runs its 16 rays and ends black
    box = np.concatenate([floor(y=-1.0), floor(y=6.0, up=False)] + [
        np.array(w, F32) for w in _walls(-1.0, 6.0, 50.0)])
    closed = frame(setup(box), ls.PT)
    per_kind = {b.kind: len(b.pixel) for b in closed.batches}
    assert list(per_kind) == ["primary"] + [f"bounce{k}" for k in range(1, ls.PT_RAYS)]
    assert set(per_kind.values()) == {SIZE * SIZE * SPP}
    assert np.allclose(closed.radiance, 0.0)


def _walls(y0, y1, h):
    """Four walls of the box |x|, |z| <= h between heights y0 and y1, facing inward."""
    out = []
    for axis in (0, 2):
        for sgn in (-1, 1):
            q = np.array([(-h, y0), (h, y0), (h, y1), (-h, y1)], np.float64)
            pts = np.zeros((4, 3))
            pts[:, axis] = sgn * h
            pts[:, 2 - axis] = q[:, 0]
            pts[:, 1] = q[:, 1]
            tri = np.array([[pts[0], pts[1], pts[2]], [pts[0], pts[2], pts[3]]], F32)
            n = np.cross(tri[0, 1] - tri[0, 0], tri[0, 2] - tri[0, 0])
            if n[axis] * sgn > 0:                   # facing out: turn it inward
                tri = tri[:, [0, 2, 1]]
            out.append(tri)
    return out


@pytest.mark.parametrize("workload", ls.WORKLOADS)
def test_a_tile_traced_alone_is_that_tile_of_the_frame(workload):
    s = setup(np.concatenate([floor(), floor(y=6.0, up=False)]))
    bvh = build(s.triangles)
    tracer = lambda b, o, d, **k: trace(b, o, d, backend="golden", **k)  # noqa: E731
    whole = workloads.run(s, bvh, SIZE, SIZE, tracer, workload, spp=SPP)
    tile = np.arange(SIZE * SIZE)[10:30]
    part = workloads.run(s, bvh, SIZE, SIZE, tracer, workload, spp=SPP, pixels=tile)
    assert np.array_equal(part.radiance, whole.radiance[tile])


@pytest.mark.parametrize("workload", ls.WORKLOADS)
def test_every_ray_has_its_place_in_its_threads_program(workload):
    """thread = pixel, slot = sample * calls + call, growing along each thread's program, never
    two rays of a thread at one slot (what the RT unit's one-kernel replay follows)."""
    box = np.concatenate([floor(), floor(y=6.0, up=False)])
    res = frame(setup(box), workload, ao_rays=4)
    calls = ls.calls(workload, 4)
    seen = {}
    for b in res.batches:
        assert np.array_equal(b.thread, b.pixel)
        call = b.slot - b.sample * calls
        assert ((0 <= call) & (call < calls)).all()
        for t, s in zip(b.thread.tolist(), b.slot.tolist()):
            assert (t, s) not in seen
            seen[(t, s)] = b.kind
    # a thread's camera ray of sample 1 comes after every ray of its sample 0
    by_thread = {}
    for (t, s), kind in seen.items():
        by_thread.setdefault(t, []).append((s, kind))
    for rays in by_thread.values():
        rays.sort()
        assert rays[0][1] == "primary" and [k for _, k in rays].count("primary") == SPP
