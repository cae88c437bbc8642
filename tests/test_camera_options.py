"""Cameras and scenes for your own data: ``--camera/--look-at/--up/--fov`` override the scene's
camera, ``--up-axis`` frames mesh files, glTF ``baseColorFactor`` is the albedo, every mesh type
listed loads, ``render --help`` and docs/scenes.md name every built-in, mesh type and TOML key."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from trimesh.visual.material import PBRMaterial

from driver.cli import main
from driver.design import DesignPoint
from driver.render import render
from driver.scenes import scene as sc
from driver.scenes.camera import Camera
from driver.scenes.materials import DEFAULT_ALBEDO
from driver.workloads import setup_for

DOCS = Path(__file__).resolve().parent.parent / "docs" / "scenes.md"


def test_camera_flags_render_the_same_frame_as_a_toml_camera(in_tmp):
    (in_tmp / "cam.toml").write_text('mesh = "sphere"\n[camera]\nposition = [-3.0, 1.5, 2.0]\n'
                                     'look_at = [0.2, 0.0, 0.1]\nup = [0.0, 1.0, 0.0]\n'
                                     'fov_deg = 55.0\n')
    assert main(["render", "cam.toml", "--size", "20", "--backend", "golden", "--no-progress",
                 "--out", "toml.png"]) == 0
    assert main(["render", "sphere", "--size", "20", "--backend", "golden", "--no-progress",
                 "--camera=-3,1.5,2", "--look-at", "0.2,0,0.1", "--up", "0,1,0", "--fov", "55",
                 "--out", "flags.png"]) == 0
    assert main(["render", "sphere", "--size", "20", "--backend", "golden", "--no-progress",
                 "--out", "plain.png"]) == 0
    from PIL import Image
    img = {k: np.asarray(Image.open(in_tmp / f"{k}.png")) for k in ("toml", "flags", "plain")}
    assert np.array_equal(img["toml"], img["flags"])
    assert not np.array_equal(img["flags"], img["plain"])


def test_with_camera_replaces_only_the_parts_given():
    s = sc.load_scene("sphere")
    t = sc.with_camera(s, fov_deg=25.0)
    assert t.camera == Camera(s.camera.position, s.camera.look_at, s.camera.up, 25.0)
    u = sc.with_camera(s, position=(0.0, -9.0, 0.0))
    assert u.camera.position == (0.0, -9.0, 0.0) and u.camera.look_at == s.camera.look_at
    assert s.camera.fov_deg == 40.0                                  # the scene is not changed
    with pytest.raises(ValueError, match="same point"):
        sc.with_camera(s, position=s.camera.look_at)


@pytest.mark.parametrize("args, words", [
    (["--camera", "1,2"], "--camera must be three finite numbers"),
    (["--camera", "a,b,c"], "--camera must be three finite numbers"),
    (["--look-at", "1,2,inf"], "--look-at must be three finite numbers"),
    (["--up", "1,,2"], "--up must be three finite numbers"),
    (["--fov", "0"], "fov_deg must be in (0, 180)"),
    (["--fov", "180"], "fov_deg must be in (0, 180)"),
    (["--fov", "nan"], "--fov must be a finite number"),
    (["--camera", "1,1,1", "--look-at", "1,1,1", "--up", "0,0,1"], "same point"),
    (["--camera", "0,0,5", "--look-at", "0,0,0", "--up", "0,0,1"], "parallel"),
    (["--up-axis", "z"], "--up-axis applies to mesh files"),
])
def test_bad_camera_flags_fail_before_any_work(error_line, in_tmp, monkeypatch, args, words):
    import driver.render

    def no_work(*a, **k):
        raise AssertionError("loaded or rendered before checking the camera flags")
    monkeypatch.setattr(driver.render, "render", no_work)
    monkeypatch.setattr(sc, "load_scene", no_work)
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", *args]) == 2
    assert words in error_line()
    assert list(in_tmp.iterdir()) == []


def test_camera_checked_against_the_scene_once_loaded(error_line, in_tmp):
    # the sphere's own up is +z: looking straight down it is parallel
    assert main(["render", "sphere", "--size", "8", "--backend", "golden", "--no-progress",
                 "--camera", "0,0,5", "--look-at", "0,0,0"]) == 2
    assert "parallel" in error_line()
    assert list(in_tmp.iterdir()) == []


def test_up_axis_frames_mesh_files(in_tmp):
    box = trimesh.creation.box((1.0, 2.0, 4.0))
    box.export(in_tmp / "box.ply")
    y = sc.load_scene(str(in_tmp / "box.ply"))
    z = sc.load_scene(str(in_tmp / "box.ply"), up_axis="z")
    assert y.camera.up == sc.UP_AXES["y"] and z.camera.up == sc.UP_AXES["z"]
    assert y.camera.position != z.camera.position
    with pytest.raises(ValueError, match="--up-axis must be"):
        sc.load_scene(str(in_tmp / "box.ply"), up_axis="x")
    res = render(z, 12, 12, backend="golden", progress=False)
    assert res.stats["hits"] > 0
    assert main(["render", "box.ply", "--up-axis", "z", "--size", "8", "--backend", "golden",
                 "--no-progress"]) == 0


def _two_part_gltf():
    a = trimesh.creation.box()
    a.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(
        baseColorFactor=[0.9, 0.1, 0.1, 1.0]))
    b = trimesh.creation.icosphere(1)
    b.apply_translation([3.0, 0.0, 0.0])
    b.visual = trimesh.visual.TextureVisuals(material=PBRMaterial(
        baseColorFactor=[0.2, 0.4, 0.8, 1.0], doubleSided=True))
    c = trimesh.creation.box()
    c.apply_translation([-3.0, 0.0, 0.0])                      # no material: the default grey
    return trimesh.Scene({"red": a, "blue": b, "plain": c})


@pytest.mark.parametrize("ext", [".glb", ".gltf"])
def test_gltf_base_colour_is_the_albedo(in_tmp, ext):
    scene = _two_part_gltf()
    if ext == ".glb":
        scene.export(in_tmp / "m.glb")
    else:
        for name, data in scene.export(file_type="gltf").items():
            (in_tmp / ("m.gltf" if name.endswith(".gltf") else name)).write_bytes(data)
    s = sc.load_scene(str(in_tmp / f"m{ext}"))
    assert s.double_sided
    tri = s.triangles
    centre_x = tri.mean(axis=1)[:, 0]
    alb = s.materials.albedo
    assert alb.shape == (len(tri), 3)
    # each face's albedo is its part's factor (trimesh keeps it as uint8)
    np.testing.assert_allclose(alb[centre_x > 1.5], np.broadcast_to(
        np.round(np.array([0.2, 0.4, 0.8]) * 255) / 255, (int((centre_x > 1.5).sum()), 3)))
    np.testing.assert_allclose(alb[abs(centre_x) < 1], np.broadcast_to(
        np.round(np.array([0.9, 0.1, 0.1]) * 255) / 255, (int((abs(centre_x) < 1).sum()), 3)))
    assert (alb[centre_x < -1.5] == DEFAULT_ALBEDO).all()
    assert setup_for(s).materials is s.materials                 # what the workloads shade with
    res = render(s, 24, 16, backend="golden", progress=False,
                 point=DesignPoint(workload="shadow"))
    assert res.stats["hits"] > 0


def test_mesh_without_base_colour_stays_grey(in_tmp):
    trimesh.creation.box().export(in_tmp / "b.glb")
    assert sc.load_scene(str(in_tmp / "b.glb")).materials is None


@pytest.mark.parametrize("ext", sc.MESH_TYPES)
def test_every_listed_mesh_type_loads(in_tmp, ext):
    mesh = trimesh.creation.icosphere(1)
    data = mesh.export(file_type=ext)
    files = data if isinstance(data, dict) else {f"m.{ext}": data}
    for name, blob in files.items():
        name = f"m.{ext}" if name.endswith(f".{ext}") else name
        (in_tmp / name).write_bytes(blob if isinstance(blob, bytes) else blob.encode())
    s = sc.load_scene(str(in_tmp / f"m.{ext}"))
    assert len(s.mesh.faces) == len(mesh.faces)


def test_help_lists_every_scene_and_mesh_type(capsys):
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name in sc.available():
        assert re.search(rf"\b{name}\b", text), name
    for ext in sc.MESH_TYPES:
        assert f".{ext}" in text, ext
    for flag in ("--camera", "--look-at", "--up X,Y,Z", "--fov", "--up-axis"):
        assert flag in text


def test_docs_name_every_key_builtin_and_mesh_type():
    text = DOCS.read_text()
    keys = sc._TOP_KEYS | sc._CAMERA_KEYS | set().union(*sc._LIGHT_KEYS.values())
    for key in keys:
        assert f"`{key}`" in text or f"{key} =" in text, key
    for name in sc.available():
        assert f"`{name}`" in text, name
    for ext in sc.MESH_TYPES:
        assert f"`.{ext}`" in text, ext
    for kind in sc._LIGHT_KEYS:
        assert f'type = "{kind}"' in text
