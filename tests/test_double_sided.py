"""Double-sided scenes take NO_CULL on every path: the whole-frame wavefront, tiles, Dask workers,
``rayflex bench``'s frame and ``driver.trace`` given a scene, with the Embree check under the same
rule. An open bowl seen from above shows its inside, which is made of back faces: a path that
culls them loses part of the bowl (and a culled Embree check would agree with it)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import driver
from driver.design import DesignPoint
from driver.bench import bench
from driver.scenes.camera import Camera, primary_rays
from driver.check import embree_closest
from driver.render import render
from driver.scenes.scene import Scene

SIZE = 24


@pytest.fixture(scope="module")
def bowl() -> Scene:
    """The lower half of a sphere (open at the top), looked into from above and to the side."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    keep = sphere.triangles_center[:, 2] < 0.0
    mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=False)
    cam = Camera(position=(0.0, -1.6, 2.2), look_at=(0.0, 0.0, -0.2), up=(0.0, 0.0, 1.0),
                 fov_deg=45.0)
    return Scene(mesh, cam, (SIZE, SIZE), "bowl", double_sided=True)


@pytest.fixture(scope="module")
def embree_hits(bowl):
    o, d = primary_rays(bowl.camera, SIZE, SIZE)
    both_t, both_prim = embree_closest(bowl.triangles, o, d, double_sided=True)
    front_t, _ = embree_closest(bowl.triangles, o, d, double_sided=False)
    # the scene is a real test: culling would lose most of the inside of the bowl
    assert (both_prim >= 0).sum() > 1.5 * np.isfinite(front_t).sum()
    return both_t, both_prim


@pytest.fixture(scope="module")
def whole(bowl):
    return render(bowl, backend="golden", progress=False, check_embree=True)


def test_whole_frame_traces_both_faces(bowl, whole, embree_hits):
    _, emb_prim = embree_hits
    assert whole.trace is not None                     # the one-wavefront path
    assert np.array_equal(whole.trace.prim >= 0, emb_prim >= 0)
    assert whole.stats["hits"] == int((emb_prim >= 0).sum())
    e = whole.stats["embree"]
    assert (e["hit_mismatch"], e["prim_mismatch"]) == (0, 0)


@pytest.mark.parametrize("options", [dict(tile=8), dict(tile=8, workers=2)],
                         ids=["tiled", "2-workers"])
def test_tiles_and_workers_give_the_whole_frame(bowl, whole, options):
    part = render(bowl, backend="golden", progress=False, check_embree=True, **options)
    assert part.trace is None                          # the tiled path
    assert part.stats["hits"] == whole.stats["hits"]
    assert np.array_equal(part.image, whole.image)
    assert np.array_equal(part.ops, whole.ops)
    assert part.stats["embree"]["hit_mismatch"] == 0


def test_bench_frame_traces_both_faces(bowl, whole):
    doc = bench(DesignPoint(size=SIZE, cache_kib=0), sweep_size=0, pyverilator_requests=0,
                repeat=1, progress=False, scene=bowl)
    assert doc["frame"]["hits"] == whole.stats["hits"]
    assert doc["golden_matches_rtl"]
    assert (doc["frame"]["embree"]["hit_mismatch"], doc["frame"]["embree"]["prim_mismatch"]) \
        == (0, 0)


def test_trace_of_a_scene_takes_its_sidedness(bowl, whole):
    o, d = primary_rays(bowl.camera, SIZE, SIZE)
    res = driver.trace(bowl, o, d, backend="golden")
    assert np.array_equal(res.prim, whole.trace.prim)
    culled = driver.trace(bowl, o, d, backend="golden", double_sided=False)
    assert culled.hit.sum() < res.hit.sum()
