"""Rendering workloads (docs/datapath.md#traversal, docs/workloads.md#ray-types): counter-based
sampling, self-intersection offsets, any-hit traversal, per-type statistics, tiles equal to the
whole frame, golden == rtl, Embree per type."""

import numpy as np
import pytest

from driver import workloads
from driver.scenes import sampling
from driver.backends import backend
from driver.bvh4 import build
from driver.scenes.scene import load_scene
from driver.tracer import trace
from support.recording import RecordingBackend


@pytest.fixture(scope="module")
def floor_scene():
    b = load_scene("bunny_floor")
    return workloads.setup_for(b), build(b.triangles)


def tracer_on(be):
    return lambda bvh, o, d, **kw: trace(bvh, o, d, backend=be, **kw)


# ---- sampling ---------------------------------------------------------------------------------

def test_random_numbers_are_pure_functions_of_their_key():
    pix = np.arange(1000)
    a = sampling.uniform(5, pix, 3, 1, sampling.BOUNCE, 0)
    b = sampling.uniform(5, pix[::-1], 3, 1, sampling.BOUNCE, 0)[::-1]
    assert np.array_equal(a, b)                                   # order does not matter
    assert not np.array_equal(a, sampling.uniform(6, pix, 3, 1, sampling.BOUNCE, 0))
    assert not np.array_equal(a, sampling.uniform(5, pix, 3, 1, sampling.LIGHT, 0))
    assert not np.array_equal(a, sampling.uniform(5, pix, 3, 1, sampling.BOUNCE, 1))
    big = sampling.uniform(0, np.arange(200_000), 0, 0, 0, 0)
    assert 0 <= big.min() and big.max() < 1
    counts = np.histogram(big, bins=20, range=(0, 1))[0]
    assert np.abs(counts - 10_000).max() < 500                    # ~5 sigma
    u, v = sampling.uniform2(0, np.arange(200_000), 0, 0, 0)
    assert abs(np.corrcoef(u, v)[0, 1]) < 0.01


def test_stratified_jitter_covers_the_pixel():
    jx, jy = sampling.jitter(1, np.zeros(16, int), np.arange(16), 16)
    cells = set(zip((jx * 4).astype(int).tolist(), (jy * 4).astype(int).tolist()))
    assert len(cells) == 16                                       # one sample per stratum
    cx, cy = sampling.jitter(1, np.arange(5), np.zeros(5, int), 1)
    assert (cx == 0.5).all() and (cy == 0.5).all()                # one sample: the centre


def test_cosine_directions_lie_on_the_hemisphere():
    rng = np.random.default_rng(2)
    n = rng.normal(size=(5000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = sampling.cosine_hemisphere(n, rng.random(5000), rng.random(5000))
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    cos = np.einsum("ij,ij->i", d, n)
    assert (cos >= 0).all()
    assert abs(cos.mean() - 2 / 3) < 0.02                         # E[cos] of a cosine lobe


def test_offset_origins_leave_their_surface_on_the_normal_side():
    rng = np.random.default_rng(3)
    for scale in (1e-3, 1.0, 1e4):
        tri = (rng.normal(size=(3000, 3, 3)) * scale).astype(np.float32)
        w = rng.dirichlet((1, 1, 1), 3000)
        p = np.einsum("ij,ijk->ik", w, tri.astype(np.float64))
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        o = sampling.offset_origin(p, n)
        assert o.dtype == np.float32
        side = np.einsum("ij,ij->i", o.astype(np.float64) - tri[:, 0], n)
        assert (side > 0).all()
        # a ray leaving along the hemisphere never meets its own triangle
        d = sampling.cosine_hemisphere(n, rng.random(3000), rng.random(3000))
        for k in range(0, 3000, 1000):
            sl = slice(k, k + 1)
            res = trace(tri[sl], o[sl], d[sl], backend="golden")
            assert not res.hit.any()


# ---- any-hit traversal --------------------------------------------------------------------------

def test_any_hit_stops_at_its_first_hit_and_returns_a_real_one():
    b = load_scene("bunny_floor")
    bvh = build(b.triangles)
    rng = np.random.default_rng(4)
    o = np.tile(np.asarray(b.camera.position, np.float32), (400, 1))
    target = b.triangles[rng.integers(0, len(b.triangles), 400)].mean(axis=1)
    d = (target - o).astype(np.float32)
    rec = RecordingBackend(backend("golden"))
    res = trace(bvh, o, d, backend=rec, extent=np.float32(2.0), any_hit=True)
    closest = trace(bvh, o, d, backend="golden", extent=np.float32(2.0))
    assert res.hit.sum() > 300
    assert np.array_equal(res.hit, closest.hit)                  # occluded iff something within
    assert (res.t[res.hit] < 2.0).all()
    from driver.check import point_triangle_distance
    p = o[res.hit].astype(np.float64) + res.t[res.hit, None] * d[res.hit]
    dist = point_triangle_distance(p, b.triangles[res.prim[res.hit]].astype(np.float64))
    assert (dist < 1e-4).all()                                    # on the triangle it names
    # no request of a ray after the TRIANGLE response that ended it
    last_call = {}
    for k, req in enumerate(rec.calls):
        for r in req["tag"].tolist():
            last_call[r] = k
    ended = {}
    for k, req in enumerate(rec.calls):
        rsp = backend("golden").run(req)
        with np.errstate(all="ignore"):
            t = rsp["t_num"] / rsp["t_den"]
        for i in np.flatnonzero((req["opcode"] == 0) & (rsp["tri_hit"] == 1) & (t < 2.0)):
            ended.setdefault(int(req["tag"][i]), k)
    assert ended and all(last_call[r] == k for r, k in ended.items())
    assert res.stats["ops"] < closest.stats["ops"]


# ---- frames -------------------------------------------------------------------------------------

@pytest.mark.parametrize("workload", workloads.WORKLOADS)
def test_each_workload_makes_an_image_and_per_type_stats(floor_scene, workload):
    setup, bvh = floor_scene
    res = workloads.run(setup, bvh, 40, 40, tracer_on("golden"), workload, spp=2, bounces=2,
                        ao_rays=2)
    assert res.radiance.shape == (1600, 3) and res.radiance.std() > 0   # not flat
    kinds = {"primary": {"primary"}, "shadow": {"primary", "shadow"}, "ao": {"primary", "ao"},
             "path": {"primary", "shadow", "bounce1", "bounce2"},
             "lumibench-sh": {"primary", "shadow"}, "lumibench-ao": {"primary", "ao"},
             "lumibench-pt": {"primary"} | {f"bounce{k}" for k in range(1, 16)}}[workload]
    if workload == "lumibench-pt":      # paths end where they miss: as many bounces as they take
        assert {"primary", "bounce1"} <= set(res.stats["by_type"]) <= kinds
        kinds = set(res.stats["by_type"])
    assert set(res.stats["by_type"]) == kinds == set(res.ops)
    total = res.stats
    for k in ("rays", "hits", "box_ops", "tri_ops", "ops", "cycles"):
        assert total[k] == sum(s[k] for s in total["by_type"].values())
    assert total["ops"] == sum(int(o.sum()) for o in res.ops.values())
    emb = workloads.embree_check(res, setup)
    assert emb["rays_compared"] == total["rays"]
    assert emb["hit_mismatch"] <= 0.001 * total["rays"]
    assert emb["prim_mismatch"] <= 0.001 * total["rays"]
    assert emb["max_t_rel_err_exact"] < 1e-4


def test_a_tile_alone_equals_that_tile_of_the_frame(floor_scene):
    setup, bvh = floor_scene
    whole = workloads.run(setup, bvh, 32, 24, tracer_on("golden"), "path", spp=2, bounces=2,
                          seed=9)
    tile = np.arange(32 * 24).reshape(24, 32)[5:17, 8:24].reshape(-1)
    part = workloads.run(setup, bvh, 32, 24, tracer_on("golden"), "path", spp=2, bounces=2,
                         seed=9, pixels=tile)
    assert np.array_equal(part.radiance, whole.radiance[tile])
    for kind, ops in part.ops.items():
        assert np.array_equal(ops, whole.ops[kind][tile])


def test_same_seed_same_frame_on_golden_and_rtl(floor_scene):
    setup, bvh = floor_scene
    a = workloads.run(setup, bvh, 24, 24, tracer_on("golden"), "path", spp=2, bounces=2, seed=3)
    b = workloads.run(setup, bvh, 24, 24, tracer_on("rtl"), "path", spp=2, bounces=2, seed=3)
    c = workloads.run(setup, bvh, 24, 24, tracer_on("golden"), "path", spp=2, bounces=2, seed=4)
    assert np.array_equal(a.radiance, b.radiance)
    for kind in a.ops:
        assert np.array_equal(a.ops[kind], b.ops[kind])
        sa, sb = a.stats["by_type"][kind], b.stats["by_type"][kind]
        assert {k: sa[k] for k in ("rays", "hits", "box_ops", "tri_ops")} == \
               {k: sb[k] for k in ("rays", "hits", "box_ops", "tri_ops")}
    assert not np.array_equal(a.radiance, c.radiance)


@pytest.mark.parametrize("bad", [dict(spp=0), dict(bounces=-1), dict(ao_rays=0), dict(seed=-2),
                                 dict(spp=1.5), dict(spp=5000)])
def test_bad_workload_arguments_are_one_line_errors(floor_scene, bad):
    setup, bvh = floor_scene
    with pytest.raises(ValueError, match="^--"):
        workloads.run(setup, bvh, 8, 8, tracer_on("golden"), "path", **bad)
    with pytest.raises(ValueError, match="unknown workload"):
        workloads.run(setup, bvh, 8, 8, tracer_on("golden"), "photon")


def test_a_scene_without_a_light_gets_the_default_one(floor_scene):
    setup, bvh = floor_scene
    bare = workloads.Setup(setup.triangles, setup.camera, setup.materials, [])
    assert len(bare.lights) == 1 and isinstance(bare.lights[0], workloads.PointLight)
    res = workloads.run(bare, bvh, 24, 24, tracer_on("golden"), "shadow")
    assert res.radiance.max() > 0


def test_culled_hits_are_all_front_faces(floor_scene):
    """Without NO_CULL every hit of every ray type is a front face (d . n < 0)."""
    setup, bvh = floor_scene
    assert not setup.double_sided
    res = workloads.run(setup, bvh, 24, 24, tracer_on("golden"), "path", spp=2, bounces=2)
    for b in res.batches:
        hit = b.result.hit
        tri = setup.triangles[b.result.prim[hit]].astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert (np.einsum("ij,ij->i", b.dirs[hit].astype(np.float64), n) < 0).all(), b.kind


def test_double_sided_scenes_hit_back_faces():
    """The Cornell box is double-sided: rays from behind its back wall (z = 559.2) stop there, at
    faces wound the other way; without NO_CULL the same rays pass through that wall."""
    scene = load_scene("cornell")
    setup, bvh = workloads.setup_for(scene), build(scene.triangles)
    assert setup.double_sided
    rng = np.random.default_rng(1)
    o = np.column_stack([rng.uniform(100, 450, 64), rng.uniform(100, 450, 64), np.full(64, 700.0)])
    d = np.tile([0.0, 0.0, -1.0], (64, 1))
    both = trace(bvh, o, d, backend="golden", double_sided=True)
    culled = trace(bvh, o, d, backend="golden")
    assert both.hit.all() and np.allclose(both.t, 700 - 559.2, rtol=1e-5)
    tri = setup.triangles[both.prim].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (np.einsum("ij,ij->i", d, n) > 0).all()              # back faces, seen from the ray
    assert (culled.t[culled.hit] > 700 - 559.2 + 1).all()        # culled: through the wall


def test_gltf_double_sided_material_and_toml_lights(tmp_path):
    """A glTF written here: its material's doubleSided makes the scene double-sided; a TOML scene
    names point and quad lights; bad lights are one-line errors."""
    import trimesh
    from trimesh.visual.material import PBRMaterial
    quad = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]],
                           process=False)
    for double in (True, False):
        quad.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(doubleSided=double))
        path = tmp_path / f"quad_{double}.glb"
        path.write_bytes(trimesh.exchange.gltf.export_glb(trimesh.Scene(quad)))
        assert load_scene(str(path)).double_sided is double
    (tmp_path / "lit.toml").write_text(
        'mesh = "quad_True.glb"\nao_radius = 0.5\n[[lights]]\ntype = "point"\n'
        'position = [0.5, 0.5, 2.0]\nintensity = [4.0, 4.0, 4.0]\n[[lights]]\ntype = "quad"\n'
        'corner = [0.0, 0.0, 3.0]\nu = [0.0, 1.0, 0.0]\nv = [1.0, 0.0, 0.0]\n'
        'emission = [1.0, 1.0, 1.0]\n')
    s = load_scene(str(tmp_path / "lit.toml"))
    assert s.double_sided and s.ao_radius == 0.5
    assert [type(x).__name__ for x in s.lights] == ["PointLight", "QuadLight"]
    (tmp_path / "bad.toml").write_text('mesh = "quad_True.glb"\n[[lights]]\ntype = "spot"\n')
    with pytest.raises(ValueError, match=r"lights\[0\]: type must be"):
        load_scene(str(tmp_path / "bad.toml"))
