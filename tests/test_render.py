"""Rendering: primary rays -> BVH4 -> traversal on the golden datapath -> shading, heat map,
progress hook, Embree check wiring."""

from __future__ import annotations

import types

import numpy as np
import pytest
from PIL import Image

from driver.scenes.camera import primary_rays
from driver.core.outputs import save_image
from driver.workloads import BG_BOTTOM, BG_TOP
from driver.render import (PEAK_BYTES_PER_RAY, RenderResult, check_memory, check_memory_tiled,
                           estimate_bytes, heatmap, render, shade)
from driver.scenes.scene import load_scene

COUNTS = ("rays", "hits", "box_ops", "tri_ops", "ops", "latency_cycles", "box_ops_per_ray",
          "tri_ops_per_ray", "node_bytes_fetched", "backend")
WAVEFRONT = ("cycles", "utilization", "sim_wall_s", "sim_cycles_per_s", "frame_us_at_1ghz")


def test_shade_lambert_headlight_and_background():
    # one triangle facing the camera head-on, one at 60 degrees; rays straight down -z
    tri = np.array([[[1, -1, -1], [0, 1, -1], [-1, -1, -1]],
                    [[0, 0, -1], [1, 0, -1 + np.sqrt(3)], [0, 1, -1]]], np.float32)
    dirs = np.array([[0, 0, -1]] * 4, np.float32)
    res = types.SimpleNamespace(prim=np.array([0, 1, -1, -1]))
    img = shade(res, tri, dirs, 2, 2)
    assert img.shape == (2, 2, 3) and img.dtype == np.uint8
    assert (img[0, 0] > img[0, 1]).all()                     # head-on brighter than 60 degrees
    assert (img[1, 0] == img[1, 1]).all()                     # background: same row, same colour
    top = shade(types.SimpleNamespace(prim=np.full(4, -1)), tri, dirs, 1, 4)
    assert (top[0, 0].astype(int).sum() > top[3, 0].astype(int).sum())   # gradient
    assert np.allclose(top[0, 0] / 255, BG_TOP ** (1 / 2.2), atol=1 / 255)
    assert np.allclose(top[3, 0] / 255, BG_BOTTOM ** (1 / 2.2), atol=1 / 255)


def test_shade_degenerate_triangle_and_size_mismatch():
    tri = np.zeros((1, 3, 3), np.float32)
    img = shade(types.SimpleNamespace(prim=np.array([0])), tri, np.array([[0, 0, 1]], np.float32),
                1, 1)
    assert img.shape == (1, 1, 3)
    with pytest.raises(ValueError):
        shade(types.SimpleNamespace(prim=np.array([0, 0])), tri, np.zeros((2, 3)), 3, 3)


def test_heatmap_and_images_by_extension(tmp_path):
    ops = np.arange(12 * 8).reshape(8, 12)
    heatmap(ops, 12, 8, tmp_path / "h.png", title="test")
    with Image.open(tmp_path / "h.png") as im:
        assert im.format == "PNG" and im.size[0] > 100
    heatmap(ops, 12, 8, tmp_path / "h.jpg", title="test")
    for ext, fmt in ((".png", "PNG"), (".jpg", "JPEG"), (".jpeg", "JPEG"), (".tif", "TIFF"),
                     (".webp", "WEBP")):
        save_image(np.zeros((5, 7, 3), np.uint8), tmp_path / f"i{ext}")
        with Image.open(tmp_path / f"i{ext}") as im:
            assert im.size == (7, 5) and im.mode == "RGB" and im.format == fmt, ext
    with Image.open(tmp_path / "h.jpg") as im:
        assert im.format == "JPEG"


def test_memory_estimate_refuses_a_frame_that_cannot_fit(monkeypatch):
    """Issue 11 #5: --size 8192 was killed by the kernel after allocating > 15 GB."""
    rays = 8192 * 8192
    assert estimate_bytes(rays) > rays * PEAK_BYTES_PER_RAY
    with pytest.raises(ValueError, match=r"GiB.*smaller --size \(at most about \d+ x \d+"):
        check_memory(rays, available=16 * 2**30)
    check_memory(256 * 256, available=16 * 2**30)           # the default frame fits easily
    import driver.render
    # too big as one wavefront: tiled (issue 16), and refused only if even the tiled frame's
    # buffers cannot fit
    assert not driver.render.fits_in(rays, 16 * 2**30)
    check_memory_tiled(rays, 64 * 64, available=16 * 2**30)
    monkeypatch.setattr(driver.render, "available_memory", lambda: 1 * 2**30)
    with pytest.raises(ValueError, match="tiled frame.*GiB"):   # render() checks before any work
        render("sphere", 8192, 8192, backend="golden", progress=False)


def test_render_sphere_golden(tmp_path):
    res = render("sphere", 24, 16, backend="golden", progress=False, check_embree=True)
    assert isinstance(res, RenderResult)
    assert res.image.shape == (16, 24, 3) and res.ops.shape == (16, 24)
    assert set(COUNTS) <= set(res.stats) and set(WAVEFRONT) == set(res.stats["wavefront"])
    assert res.stats["rays"] == 24 * 16 and res.stats["backend"] == "golden"
    assert res.stats["hits"] == int((res.trace.prim >= 0).sum()) > 0
    assert (res.ops.reshape(-1) == res.trace.box_ops + res.trace.tri_ops).all()
    emb = res.stats["embree"]
    assert emb["rays_compared"] == 24 * 16
    assert emb["hit_mismatch"] == 0 and emb["prim_mismatch"] == 0
    assert {"box_nodes", "tri_nodes", "depth", "build_s", "bytes"} <= set(res.stats["bvh"])
    # the middle of the image is the sphere, the corners background
    assert res.trace.prim.reshape(16, 24)[8, 12] >= 0
    assert res.trace.prim.reshape(16, 24)[0, 0] == -1
    res.save(tmp_path / "s.png")
    res.save_heatmap(tmp_path / "h.png")
    with Image.open(tmp_path / "s.png") as im:
        assert im.size == (24, 16)


def test_render_room_from_inside_hits_every_pixel():
    res = render("room", 16, 16, backend="golden", progress=False, check_embree=True)
    assert (res.trace.prim >= 0).all()
    assert res.stats["embree"]["hit_mismatch"] == 0
    assert res.stats["embree"]["prim_mismatch"] == 0


def test_render_progress_bar_on_stderr(capsys):
    render("sphere", 8, 8, backend="golden", progress=True)
    err = capsys.readouterr().err
    assert "64/64" in err


def test_render_matches_primary_rays_and_scene_default_size():
    scene = load_scene("soup")
    res = render(scene, 10, 6, backend="golden", progress=False)
    o, d = primary_rays(scene.camera, 10, 6)
    assert res.trace.t.shape == (60,)
    hit = res.trace.prim >= 0
    # hit points lie on the triangles they report
    p = o[hit] + res.trace.t[hit, None] * d[hit]
    from driver.check import point_triangle_distance
    dist = point_triangle_distance(p.astype(float), scene.triangles[res.trace.prim[hit]]
                                   .astype(float))
    assert dist.max() < 1e-4


def test_render_bad_backend():
    import driver
    with pytest.raises(driver.BackendError):
        render("sphere", 4, 4, backend="nope", progress=False)


def test_long_silent_phases_show_progress(capsys, monkeypatch):
    """Issue 11 #4: a 30 s BVH build (2 M triangles) and the Embree check printed nothing. A
    phase longer than a second now shows a ticking line that ends with its duration."""
    import time

    import driver.bvh4
    real = driver.bvh4.build

    def slow_build(mesh, *a, **k):
        time.sleep(1.6)
        return real(mesh, *a, **k)
    monkeypatch.setattr(driver.bvh4, "build", slow_build)
    render("sphere", 8, 8, backend="golden", progress=True)
    err = capsys.readouterr().err
    assert "building the BVH4 of 1,280 triangles" in err and "done in 1." in err
    render("sphere", 8, 8, backend="golden", progress=False)
    assert capsys.readouterr().err == ""
