"""Scenes and camera: built-ins, mesh files, TOML scenes, validation with one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from driver.scenes.camera import Camera, check_size, primary_rays
from driver.core.errors import CameraError, SceneError
from driver.scenes.scene import (BUILTINS, SCENES_DIR, Scene, available, load, load_scene, resolve,
                          scene_name)


def one_line(excinfo):
    msg = str(excinfo.value)
    assert msg and "\n" not in msg
    return msg


# ---------------------------------------------------------------------------------------------
# built-ins and scenes/

@pytest.mark.parametrize("name", ["sphere", "room", "soup"])
def test_procedural_builtins(name):
    mesh = load(name)
    assert isinstance(mesh, trimesh.Trimesh) and len(mesh.faces) > 0
    assert np.isfinite(mesh.vertices).all()
    assert load(name).faces.tolist() == mesh.faces.tolist()          # deterministic


def test_bunny_builtin_keeps_every_face():
    mesh = load("bunny")
    assert len(mesh.faces) == 99785 and len(mesh.vertices) == 50000
    assert mesh.volume > 0                                  # outward normals = front faces


def test_room_walls_face_inward_and_camera_sees_them():
    scene = load_scene("room")
    tri = scene.triangles.astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = tri.mean(axis=1)
    walls = slice(0, 6 * 16 * 2)                      # the room's shell comes first
    on_shell = (np.abs(centre[walls, :2]) == 4).any(1) | np.isin(centre[walls, 2], [0, 3])
    assert on_shell.all()
    # every wall triangle faces the room's interior
    assert (np.einsum("ij,ij->i", n[walls], np.array([0, 0, 1.5]) - centre[walls]) > 0).all()
    cam = np.array(scene.camera.position)
    assert (np.abs(cam[:2]) < 4).all() and 0 < cam[2] < 3


def test_scene_names_resolve_to_tomls():
    for name in ("bunny", "sphere", "room"):
        s = load_scene(name)
        assert isinstance(s, Scene) and s.name == name and s.size == (256, 256)
        s.camera.validate()
    assert load_scene("sphere.toml").camera == load_scene("sphere").camera
    assert load_scene(SCENES_DIR / "room.toml").name == "room"
    assert {"bunny", "room", "soup", "sphere"} <= set(available())
    assert set(BUILTINS) <= set(available())


def test_builtin_without_toml_is_framed_automatically():
    s = load_scene("soup")
    o, d = primary_rays(s.camera, 8, 8)
    centre = s.triangles.reshape(-1, 3).mean(0)
    # the middle pixel looks roughly at the mesh
    to_centre = centre - o[0]
    mid = d[4 * 8 + 4]
    assert np.dot(mid, to_centre / np.linalg.norm(to_centre)) > 0.95


def test_unknown_scene():
    with pytest.raises(SceneError) as e:
        load_scene("no_such_scene")
    assert "unknown scene" in one_line(e) and "bunny" in str(e.value)


def test_missing_file():
    with pytest.raises(SceneError) as e:
        load_scene("missing/mesh.ply")
    assert "no such file" in one_line(e)


# ---------------------------------------------------------------------------------------------
# mesh files

def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
    return p


PLY = """ply
format ascii 1.0
element vertex {nv}
property float x
property float y
property float z
element face {nf}
property list uchar int vertex_indices
end_header
{body}
"""


def ply(verts, faces):
    body = "\n".join(" ".join(map(str, v)) for v in verts)
    body += "\n" + "\n".join(f"3 {a} {b} {c}" for a, b, c in faces)
    return PLY.format(nv=len(verts), nf=len(faces), body=body)


def test_ply_keeps_duplicates_and_degenerates(tmp_path):
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 0)]          # vertex 3 duplicates vertex 0
    faces = [(0, 1, 2), (0, 1, 2), (3, 1, 2), (0, 0, 1)]           # duplicate face, degenerate
    mesh = load(write(tmp_path, "m.ply", ply(verts, faces)))
    assert mesh.faces.tolist() == [list(f) for f in faces]
    assert len(mesh.vertices) == 4


def test_obj_stl_off_glb_round_trip(tmp_path):
    src = trimesh.creation.box()
    for ext in ("obj", "stl", "off", "glb"):
        p = tmp_path / f"box.{ext}"
        src.export(str(p))
        mesh = load(p)
        assert len(mesh.faces) == 12, ext
        s = load_scene(p)
        assert s.name == "box" and s.size == (256, 256)


def test_multi_part_file_is_concatenated(tmp_path):
    sc = trimesh.Scene([trimesh.creation.box(), trimesh.creation.icosphere(subdivisions=1)])
    p = tmp_path / "two.glb"
    sc.export(str(p))
    assert len(load(p).faces) == 12 + 80


@pytest.mark.parametrize("text, words", [
    (ply([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 9)]), "indexes outside"),
    (ply([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, -1)]), "indexes outside"),
    (ply([(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)], [(0, 1, 2)]), "not finite"),
    (ply([(0, 0, 0), (1e39, 0, 0), (0, 1, 0)], [(0, 1, 2)]), "not finite"),
    (ply([(0, 0, 0), (1, 0, 0), (0, 1, 0)], []), "no triangles"),
    ("garbage\x00\x01", "cannot read"),
])
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_invalid_ply(tmp_path, text, words):
    with pytest.raises(SceneError) as e:
        load(write(tmp_path, "bad.ply", text))
    assert words in one_line(e)


def test_invalid_obj(tmp_path):
    with pytest.raises(SceneError) as e:
        load(write(tmp_path, "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"))
    one_line(e)
    with pytest.raises(SceneError) as e:
        load(write(tmp_path, "empty.obj", ""))
    assert "no triangles" in one_line(e)


def test_unsupported_and_directory(tmp_path):
    with pytest.raises(SceneError) as e:
        load(write(tmp_path, "mesh.xyzw", "1 2 3"))
    assert "unsupported" in one_line(e)
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path)
    assert "directory" in one_line(e)


def test_scene_errors_are_value_errors():
    assert issubclass(SceneError, ValueError) and issubclass(CameraError, ValueError)


# ---------------------------------------------------------------------------------------------
# scene TOML

def test_toml_with_relative_mesh_and_camera(tmp_path):
    trimesh.creation.box().export(str(tmp_path / "b.stl"))
    p = write(tmp_path, "s.toml", 'mesh = "b.stl"\nname = "boxy"\nwidth = 40\nheight = 30\n'
                                  '[camera]\nposition = [3, 3, 3]\nlook_at = [0, 0, 0]\n'
                                  'fov_deg = 30\n')
    s = load_scene(p)
    assert s.name == "boxy" and s.size == (40, 30) and len(s.mesh.faces) == 12
    assert s.camera.position == (3, 3, 3) and s.camera.fov_deg == 30
    assert s.camera.up == (0.0, 1.0, 0.0)              # mesh files default to +y up


def test_toml_without_camera_is_framed(tmp_path):
    s = load_scene(write(tmp_path, "s.toml", 'mesh = "sphere"\nsize = 20\n'))
    assert s.size == (20, 20) and s.name == "s"
    s.camera.validate()


@pytest.mark.parametrize("text, words", [
    ('mesh = "sphere"\nsize = 0\n', "1..8192"),
    ('mesh = "sphere"\nsize = 100000\n', "1..8192"),
    ('mesh = "sphere"\nsize = 1.5\n', "integer"),
    ('mesh = "sphere"\n[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 0]\n', "same point"),
    ('mesh = "sphere"\n[camera]\nposition = [0,0,5]\nlook_at = [0,0,0]\nup = [0,0,1]\n',
     "parallel"),
    ('mesh = "sphere"\n[camera]\nposition = [0,5,0]\nlook_at = [0,0,0]\nfov_deg = 180\n',
     "fov"),
    ('mesh = "sphere"\n[camera]\nposition = [0,5]\nlook_at = [0,0,0]\n', "3 numbers"),
    ('mesh = "sphere"\n[camera]\nposition = [0,5,0]\n', "look_at"),
    ('mesh = "sphere"\nzoom = 2\n', "unknown key"),
    ('mesh = "nothing.ply"\n', "neither a file"),
    ('name = "x"\n', "needs mesh"),
    ('mesh = = \n', "invalid TOML"),
])
def test_bad_toml(tmp_path, text, words):
    with pytest.raises(SceneError) as e:
        load_scene(write(tmp_path, "bad.toml", text))
    assert words in one_line(e)


# ---------------------------------------------------------------------------------------------
# camera

def test_primary_rays_layout():
    cam = Camera((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0)
    o, d = primary_rays(cam, 4, 2)
    assert o.shape == d.shape == (8, 3) and o.dtype == d.dtype == np.float32
    assert np.allclose(np.linalg.norm(d, axis=1), 1, atol=1e-6)
    assert (d[:4, 1] > 0).all() and (d[4:, 1] < 0).all()            # top row first
    assert (np.diff(d[:4, 0]) > 0).all()                             # left to right
    # 90 degree vertical fov: the top/bottom image edge is at 45 degrees
    o, d = primary_rays(cam, 1, 1)
    assert np.allclose(d[0], [0, 0, -1])


@pytest.mark.parametrize("cam, words", [
    (Camera((0, 0, 0), (0, 0, -1), (0, 1, 0), 0.0), "fov"),
    (Camera((0, 0, 0), (0, 0, -1), (0, 1, 0), -10), "fov"),
    (Camera((0, 0, 0), (0, 0, -1), (0, 1, 0), float("nan")), "finite"),
    (Camera((1, 2, 3), (1, 2, 3), (0, 1, 0), 40), "same point"),
    (Camera((0, 0, 0), (0, 0, -1), (0, 0, 2), 40), "parallel"),
    (Camera((0, 0, 0), (0, 0, -1), (0, 0, 0), 40), "zero"),
    (Camera((0, float("inf"), 0), (0, 0, -1), (0, 1, 0), 40), "finite"),
    (Camera("abc", (0, 0, -1), (0, 1, 0), 40), "3 numbers"),
])
def test_bad_camera(cam, words):
    with pytest.raises(CameraError) as e:
        primary_rays(cam, 4, 4)
    assert words in one_line(e)


@pytest.mark.parametrize("w, h", [(0, 4), (4, -1), (8193, 1), (2.5, 4), ("8", 8), (True, 4)])
def test_bad_size(w, h):
    with pytest.raises(CameraError) as e:
        check_size(w, h)
    one_line(e)


def test_size_accepts_numpy_and_integral_floats():
    assert check_size(np.int64(3), 4.0) == (3, 4)


# ---------------------------------------------------------------------------------------------
# issue 11 #6: bad meshes say what is wrong, in one line, with plain numbers and no warning

def test_truncated_stl_and_garbage_obj_say_what_is_wrong(tmp_path):
    trimesh.creation.box().export(str(tmp_path / "b.stl"))
    (tmp_path / "t.stl").write_bytes((tmp_path / "b.stl").read_bytes()[:300])
    (tmp_path / "g.obj").write_bytes(b"garbage\nnot an obj\n\x01\x02")
    for name in ("t.stl", "g.obj"):
        with pytest.raises(SceneError) as e:
            load_scene(tmp_path / name)
        assert "No module named" not in str(e.value) and name in str(e.value)


def test_mesh_at_one_point_is_degenerate(tmp_path):
    (tmp_path / "d.obj").write_text("v 5 5 5\nv 5 5 5\nv 5 5 5\nf 1 2 3\n")
    with pytest.raises(SceneError, match=r"degenerate: all 3 vertices are at one point \(5, 5, 5\)"):
        load_scene(tmp_path / "d.obj")


def test_camera_errors_print_plain_numbers():
    with pytest.raises(CameraError) as e:
        Camera((1.5, 2, 3), (1.5, 2, 3)).validate()
    assert "(1.5, 2, 3)" in str(e.value) and "np." not in str(e.value)


def test_coordinates_near_float32_max_fail_without_a_warning(tmp_path):
    import warnings
    (tmp_path / "big.obj").write_text("v 3e38 0 0\nv 0 3e38 0\nv 0 0 3e38\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SceneError, match="float32 range"):
            load_scene(tmp_path / "big.obj")


def test_bare_name_is_the_scene_even_with_a_local_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    trimesh.creation.box().export(str(tmp_path / "bunny"), file_type="stl")
    assert resolve("bunny").kind == "toml" and scene_name("bunny") == "bunny"
    assert "./bunny" in capsys.readouterr().err
    assert resolve("./bunny") == ("mesh", Path("./bunny"))
    assert resolve("soup") == ("builtin", "soup")                  # no scenes/soup.toml
