"""LumiBench scenes (driver/scenes/lumibench.py, driver/scenes/objfile.py) from a tiny folder in
the benchmark's layout that the test writes: two OBJ files with their MTL files, a camera file,
and an MTL whose OBJ is missing, as in the public repository."""

from __future__ import annotations

import json

import numpy as np
import pytest

from driver.cli import main
from driver.core.errors import SceneError
from driver.scenes import lumibench as lb
from driver.scenes.objfile import DEFAULT_DIFFUSE, read_obj, scan
from driver.scenes.scene import load_scene, resolve, scene_name

BOX_OBJ = """# a unit cube's bottom and top, as quads, two materials
mtllib box.mtl
v 0 0 0
v 1 0 0
v 1 0 1
v 0 0 1
v 0 1 0
v 1 1 0
v 1 1 1
v 0 1 1
f 1 2 3 4
usemtl red
f 5/1/1 8/2/1 7/3/1 6/4/1
"""
BOX_MTL = """newmtl white
Kd 0.8 0.8 0.8
newmtl red
Kd 0.9 0.1 0.1
"""
# a triangle and a thin quad (split along its shorter diagonal 1-3), negative indices
FLAG_OBJ = """mtllib flag.mtl
o flag
v 2 0 -1
v 3 0 -1
v 3 2 -1
f -3 -2 -1
v 0 0 -3
v 4 0 -3
v 4 0.1 -3
v 0 0.1 -3
usemtl unknown_material
f -4 -3 -2 -1
l 1 2
"""
FLAG_MTL = "newmtl only\nKd 0.2 0.4 0.6\n"


def suite_root(path) -> object:
    """A LumiBench root at ``path`` that two scenes can be run from: BATH (box and flag, a
    camera file) and SHIP (one triangle); returns ``path``."""
    folder = path / "Scenes" / "Bathroom"
    folder.mkdir(parents=True)
    for name, text in (("box.obj", BOX_OBJ), ("box.mtl", BOX_MTL), ("flag.obj", FLAG_OBJ),
                       ("flag.mtl", FLAG_MTL), ("Camera.camera", "0.5 0.5 6 0.5 0.5 0")):
        (folder / name).write_text(text)
    (path / "assets" / "models").mkdir(parents=True)
    (path / "assets" / "models" / "karimSchooner.obj").write_text(
        "v 0 0 -1\nv 1 0 -1\nv 0 1 -1\nf 1 2 3\n")
    return path


@pytest.fixture
def root(tmp_path, monkeypatch):
    """A LumiBench root whose Bathroom folder holds box, flag and the MTL of a missing OBJ."""
    folder = tmp_path / "Scenes" / "Bathroom"
    folder.mkdir(parents=True)
    (folder / "box.obj").write_text(BOX_OBJ)
    (folder / "box.mtl").write_text(BOX_MTL)
    (folder / "flag.obj").write_text(FLAG_OBJ)
    (folder / "flag.mtl").write_text(FLAG_MTL)
    (folder / "tub.mtl").write_text("newmtl tub\nKd 1 1 1\n")   # its tub.obj is missing
    (folder / "Camera.camera").write_text("0.5 0.5 6\n0.5 0.5 0\n")
    monkeypatch.setenv("RAYFLEX_SCENE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(lb.ROOT_ENV, str(tmp_path))
    return tmp_path


def test_obj_reader_follows_tinyobjloader(root):
    box = read_obj(root / "Scenes/Bathroom/box.obj")
    assert box.triangles.shape == (4, 3, 3) and box.triangles.dtype == np.float32
    assert box.material.tolist() == [0, 0, 1, 1]          # before usemtl: the first material
    assert np.allclose(box.albedo[0], 0.8) and np.allclose(box.albedo[2], [0.9, 0.1, 0.1])
    # the quad 1 2 3 4: diagonals equal, so [0, 1, 3], [1, 2, 3] (sqr02 < sqr13 fails)
    assert box.triangles[0].tolist() == [[0, 0, 0], [1, 0, 0], [0, 0, 1]]
    assert box.triangles[1].tolist() == [[1, 0, 0], [1, 0, 1], [0, 0, 1]]
    flag = read_obj(root / "Scenes/Bathroom/flag.obj")
    assert len(flag.triangles) == 3                        # the line is no triangle
    assert flag.triangles[0].tolist() == [[2, 0, -1], [3, 0, -1], [3, 2, -1]]
    # corners 0 1 2 3 of the thin quad: |v2 - v0|^2 = 16.01 > |v3 - v1|^2 = 16.01? equal again;
    # either way the split keeps every vertex and covers the quad
    quad = flag.triangles[1:].reshape(-1, 3)
    assert {tuple(v) for v in quad.tolist()} == {(0, 0, -3), (4, 0, -3), (4, np.float32(0.1),
                                                                          -3), (0, np.float32(0.1), -3)}
    assert flag.material.tolist() == [0, 0, 0]             # unknown usemtl: the first material
    assert np.allclose(flag.albedo, [0.2, 0.4, 0.6])


def test_quads_split_along_the_shorter_diagonal(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text("v 0 0 0\nv 4 0 0\nv 5 1 0\nv 0 1 0\nf 1 2 3 4\n")   # 0-2 longer than 1-3
    t = read_obj(p).triangles.tolist()
    assert t == [[[0, 0, 0], [4, 0, 0], [0, 1, 0]], [[4, 0, 0], [5, 1, 0], [0, 1, 0]]]
    p.write_text("v 0 0 0\nv 4 0 0\nv 1 1 0\nv -3 1 0\nf 1 2 3 4\n")  # 0-2 shorter
    t = read_obj(p).triangles.tolist()
    assert t == [[[0, 0, 0], [4, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [-3, 1, 0]]]


def test_obj_without_materials_is_grey_and_numbers_parse_exactly(tmp_path):
    p = tmp_path / "n.obj"
    xs = ["0.1", "1e-3", "-2.5E+2", "123456789.123456789", "3.4028235e38", "7"]
    p.write_text(f"v {xs[0]} {xs[1]} {xs[2]}\nv {xs[3]} {xs[4]} {xs[5]}\nv 0 0 0\nf 1 2 3\n")
    m = read_obj(p)
    assert m.triangles[0, :2].reshape(-1).tolist() == [float(np.float32(float(x))) for x in xs]
    assert np.allclose(m.albedo, DEFAULT_DIFFUSE)


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
BROKEN_OBJ = [   # (file, what the one line says after "bad.obj:")
    ("v 0 0\nf 1 1 1\n", "1: vertex 1 has 2 coordinates; a vertex needs 3 (x y z)"),
    ("v 0\n", "1: vertex 1 has 1 coordinate; a vertex needs 3 (x y z)"),
    ("v 0 0 0\nv 1 0 1,5\n", "2: vertex 2: coordinate '1,5' is not a number"),
    (TRI + "f 1 0 1\n", "4: face 1: vertex index 0 (OBJ indices start at 1)"),
    (TRI + "f 1 2 3\nf 1 2 7\n", "5: face 2: vertex index 7 is beyond the file's 3 vertices"),
    ("v 0 0 0\nf 1 1 2\n", "2: face 1: vertex index 2 is beyond the file's 1 vertex"),
    (TRI + "f 1 2 -4\n",
     "4: face 1: vertex index -4 counts back past the first vertex (3 vertices read before it)"),
    (TRI + "f 1 2 x3\n", "4: face 1: 'x3' is not a vertex index"),
    (TRI + "f 1/1 2/1 3.0/1\n", "4: face 1: '3.0/1' is not a vertex index"),
]


@pytest.mark.parametrize("text, what", BROKEN_OBJ)
def test_a_malformed_obj_is_one_line_naming_the_file_line_and_fault(tmp_path, text, what):
    p = tmp_path / "bad.obj"
    p.write_text(text)
    with pytest.raises(SceneError) as e:
        read_obj(p)
    assert str(e.value) == f"{p}:{what}"


def test_a_face_of_two_corners_is_skipped_or_refused_when_strict(tmp_path):
    """tinyobjloader (and so a LumiBench scene) skips a face of fewer than 3 corners; a mesh
    file given on its own (``strict``) is refused there."""
    p = tmp_path / "two.obj"
    p.write_text(TRI + "f 1 2 3\n\nf 2 3\n")
    assert len(read_obj(p).triangles) == 1
    with pytest.raises(SceneError) as e:
        scan(p, strict=True)
    assert str(e.value) == f"{p}:6: face 2 has 2 corners; a face needs at least 3"


def test_folder_scene_as_the_benchmark_defines_it(root):
    assert resolve("lumibench:BATH").kind == "lumibench"
    assert scene_name("lumibench:bath") == "BATH"
    s = load_scene("lumibench:BATH")
    assert isinstance(s, lb.LumiBenchScene)
    assert s.models == ["Scenes/Bathroom/box.obj", "Scenes/Bathroom/flag.obj"]
    assert len(s.instances) == 2 and s.instances.meshes[0].shape == (4, 3, 3)
    assert np.allclose(s.instances.object_to_world, np.eye(3, 4))
    assert s.triangles.shape == (7, 3, 3)                  # model after model
    assert s.missing == ["Scenes/Bathroom/tub.obj"] and s.partial
    assert s.camera.position == (0.5, 0.5, 6.0) and s.camera.look_at == (0.5, 0.5, 0.0)
    assert s.camera.up == lb.UP and s.camera.fov_deg == 36.0
    assert s.size == (128, 128) and s.double_sided and s.ao_radius == 10.0
    assert isinstance(s.lights[0], lb.SkyLight) and s.lights[0].direction == (0.0, 1.0, 0.0)
    assert np.allclose(s.materials.albedo[2], [0.9, 0.1, 0.1])
    info = s.info()
    assert info["partial"] and info["missing"] == ["Scenes/Bathroom/tub.obj"]


def test_second_load_comes_from_the_cache_and_a_changed_file_is_read_again(root):
    first = lb.load("lumibench:BATH")
    assert not first.cached
    again = lb.load("lumibench:BATH")
    assert again.cached and np.array_equal(again.triangles, first.triangles)
    assert again.missing == first.missing and again.camera == first.camera
    (root / "Scenes/Bathroom/box.mtl").write_text(BOX_MTL.replace("0.9 0.1 0.1", "0 0 1"))
    changed = lb.load("lumibench:BATH")
    assert not changed.cached and np.allclose(changed.materials.albedo[2], [0, 0, 1])


def test_model_scene_with_its_transform_and_a_missing_camera_file(root):
    models = root / "assets" / "models"
    models.mkdir(parents=True)
    (models / "karimSchooner.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    ship = lb.load("lumibench:SHIP")
    # translate(173, -9, -377) . scale(100) . rotate(75 deg about y), applied to (1, 0, 0)
    c, s = np.cos(np.radians(75)), np.sin(np.radians(75))
    assert np.allclose(ship.triangles[0, 1], [173 + 100 * c, -9, -377 - 100 * s], atol=1e-3)
    assert ship.camera.position == (378, 278, 500) and ship.camera.fov_deg == 50
    (root / "Scenes/Bathroom/Camera.camera").unlink()
    bath = lb.load("lumibench:BATH")
    assert "Scenes/Bathroom/Camera.camera" in bath.missing and bath.camera.fov_deg == 36.0


def test_what_cannot_be_loaded_says_so_in_one_line(root, monkeypatch):
    for sid, words in (("WKND", "procedural"), ("CHSNT", "alpha-tested"), ("PARK", "procedural"),
                       ("NOPE", "unknown LumiBench scene"), ("SHIP", "karimSchooner.obj is not"),
                       ("CAR", "Blender_2.77 is not")):
        with pytest.raises(SceneError, match=words) as e:
            resolve(f"lumibench:{sid}")
        assert "\n" not in str(e.value)
    monkeypatch.delenv(lb.ROOT_ENV)
    with pytest.raises(SceneError, match="--lumibench-root"):
        resolve("lumibench:BATH")


def test_render_a_lumibench_scene_from_the_command_line(root, in_tmp):
    code = main(["render", "lumibench:BATH", "--lumibench-root", str(root), "--backend",
                 "golden", "--workload", "lumibench-ao", "--size", "16", "--check-embree",
                 "--json", "bath.json", "--no-progress"])
    assert code == 0
    out = json.loads((in_tmp / "bath.json").read_text())
    assert out["lumibench"]["partial"] and out["lumibench"]["missing"] == [
        "Scenes/Bathroom/tub.obj"]
    assert set(out["by_type"]) == {"primary", "ao"}
    assert out["embree"]["adjudicated"]["classes"]["datapath_wrong"] == 0
    assert (in_tmp / "BATH.png").is_file()


def test_bench_scene_load_cold_then_from_the_cache(root, in_tmp):
    assert main(["bench", "--scene-load", "--scene", "lumibench:BATH", "--json", "l.json",
                 "--no-progress"]) == 0
    doc = json.loads((in_tmp / "l.json").read_text())
    assert not doc["cold"]["cached"] and doc["warm"]["cached"]
    assert not doc["cold"]["bvh_cached"] and doc["warm"]["bvh_cached"]
    for name in ("cold", "warm"):
        r = doc[name]
        assert r["triangles"] == 7 and r["models"] == 2 and r["peak_rss_bytes"] > 0
        assert r["to_tracing_s"] >= r["import_s"] + r["load_s"] + r["build_s"]
    assert main(["bench", "--scene-load", "--synthetic", "3,60", "--json", "s.json",
                 "--no-progress"]) == 0
    doc = json.loads((in_tmp / "s.json").read_text())
    assert doc["synthetic"] == {"files": 3, "triangles": 60}
    assert doc["warm"]["models"] == 3 and 30 <= doc["warm"]["triangles"] <= 90


def test_bench_scene_load_needs_a_lumibench_scene(in_tmp, error_line):
    assert main(["bench", "--scene-load", "--scene", "bunny"]) == 2
    assert "lumibench:ID" in error_line()
    assert main(["bench", "--synthetic", "3,60"]) == 2
    assert "--scene-load" in error_line()


def test_lumibench_scenes_anywhere_a_scene_is_accepted(root, in_tmp):
    import driver
    o = np.array([[0.5, 5.0, 0.5], [2.5, 0.5, 6.0]], np.float32)
    d = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]], np.float32)
    hits = driver.trace("lumibench:BATH", o, d, backend="golden")   # the box's top, the flag
    assert hits.prim.tolist() == [2, 4] and np.allclose(hits.t, [4.0, 7.0])
    common = ["--scene", "lumibench:BATH", "--workload", "lumibench-sh", "--size", "8"]
    assert main(["bench", *common, "--sweep-rays", "1,4", "--json", "b.json",
                 "--no-progress"]) == 0
    assert json.loads((in_tmp / "b.json").read_text())["frame"]["rays"] > 0
    assert main(["sweep", *common, "--rays-in-flight", "2,8", "--json", "s.json",
                 "--no-progress"]) == 0
    assert len(json.loads((in_tmp / "s.json").read_text())["points"]) == 2
    assert main(["power", "--config", "baseline-unified", "--ops", "10", *common, "--json",
                 "p.json", "--no-progress"]) == 0


def test_the_bvh_of_a_second_run_comes_from_the_cache(root):
    from driver.bvh4 import build_scene
    from driver.design import DesignPoint
    scene = lb.load("lumibench:BATH")
    first = DesignPoint().build(scene)
    assert not first.stats.get("from_cache")
    again = DesignPoint().build(lb.load("lumibench:BATH"))
    assert again.stats["from_cache"] and type(again) is type(first)
    assert np.array_equal(again.image, first.image) and again.blas == first.blas
    assert np.array_equal(again.blas_root, first.blas_root)
    fresh = build_scene(scene)
    assert np.array_equal(fresh.image, again.image)
    # other options, the flattened scene: other entries, each the same as a build
    q8 = DesignPoint(bvh_format="q8").build(scene)
    assert not q8.stats.get("from_cache") and q8.format == "q8"
    flat_point = DesignPoint(flatten=True)
    flat = flat_point.build(flat_point.scene_of(scene))
    flat2 = flat_point.build(flat_point.scene_of(lb.load("lumibench:BATH")))
    assert flat2.stats["from_cache"] and np.array_equal(flat.image, flat2.image)
    assert not hasattr(flat2, "instances") or flat2.instances is None
    # a changed file is another scene: built again
    (root / "Scenes/Bathroom/flag.obj").write_text(FLAG_OBJ.replace("v 2 0 -1", "v 2 0 -1.5"))
    changed = DesignPoint().build(lb.load("lumibench:BATH"))
    assert not changed.stats.get("from_cache")


def test_two_processes_building_one_scene_build_its_bvh_once(root, monkeypatch):
    """The second build of a scene's BVH waits for the first and reads its image (two Dask
    workers starting runs of the same scene): threads with files of their own lock like
    processes."""
    import threading
    import time

    from driver.design import DesignPoint
    from driver.scenes import lumibench as loader
    built, real = [], loader.build_scene

    def slow_build(*args, **kw):
        built.append(1)
        time.sleep(0.5)                         # long enough for the other to reach the lock
        return real(*args, **kw)
    monkeypatch.setattr(loader, "build_scene", slow_build)
    out = []
    threads = [threading.Thread(target=lambda: out.append(
        DesignPoint().build(lb.load("lumibench:BATH")))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert len(out) == 2 and len(built) == 1
    assert sorted(bool(b.stats.get("from_cache")) for b in out) == [False, True]
    assert np.array_equal(out[0].image, out[1].image)
