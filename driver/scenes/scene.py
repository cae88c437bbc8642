"""Scenes: a triangle mesh, a camera, a default image size, and for rendering workloads
(docs/workloads.md) materials, lights, double-sidedness and an AO radius.

``load(name_or_path)`` returns a ``trimesh.Trimesh``; ``load_scene(name_or_path)`` a ``Scene``;
``resolve`` says where a name or path comes from without reading any mesh, ``scene_name`` gives
its name (the command line names its outputs before any work), ``with_camera`` replaces parts of
its camera. How names resolve, the built-in scenes, the mesh file types (``MESH_TYPES``), glTF
materials and the TOML scene format are documented in docs/scenes.md (tests check that it names
every built-in, mesh type and TOML key accepted here).
A scene may hold instances (``Scene.instances``: glTF mesh reuse, ``bunny_grid``, ``city``),
traced through a two-level BVH (docs/instances.md).

Meshes are loaded with ``process=False``: no vertex merging, no face removal, so primitive ids are
face indices in the file. Degenerate (zero-area) triangles are kept. Invalid input raises
``SceneError`` (a ``ValueError``) with a one-line message.
"""

from __future__ import annotations

import importlib.resources
import sys
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import trimesh

if sys.version_info >= (3, 11):
    import tomllib
else:                                               # pragma: no cover
    try:
        import tomli as tomllib
    except ImportError:
        tomllib = None

from .camera import Camera, check_size, fmt_vec, frame
from ..core.resources import data_dir
from ..core.errors import CameraError, SceneError
from ..instances import Instances
from . import meshes
from .builtins import BUILT
from . import lumibench
from .materials import DEFAULT_ALBEDO, Materials, PointLight, QuadLight
from .model import DEFAULT_SIZE, Scene, triangles

SCENES_DIR = data_dir("scenes")
BUILTINS = ("bunny", "room", "soup", "sphere")
RENDER_BUILTINS = ("cornell", "bunny_floor", "bunny_grid", "city")   # with materials and lights
_UP = {"bunny": (0.0, 0.0, 1.0), "sphere": (0.0, 0.0, 1.0), "room": (0.0, 0.0, 1.0),
       "soup": (0.0, 0.0, 1.0)}
UP_AXES = {"y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}     # --up-axis of mesh files
_FILE_UP = UP_AXES["y"]        # auto-framing of mesh files: +y up (OBJ / glTF convention)
# what trimesh reads as triangle meshes, by file extension: its mesh loaders, without type names
# that are no extension (stl_ascii: trimesh tells ASCII STL by content) and point clouds
_NOT_MESH_FILES = {"stl_ascii", "xyz"}
MESH_TYPES = tuple(sorted(set(trimesh.exchange.load.mesh_formats()) - _NOT_MESH_FILES))


def load(name_or_path) -> trimesh.Trimesh:
    """The mesh of a scene name, built-in, scene TOML or mesh file (see module docstring)."""
    if isinstance(name_or_path, trimesh.Trimesh):
        return _validated(name_or_path, "mesh")
    return load_scene(name_or_path).mesh


class Source(NamedTuple):
    """Where a scene comes from: kind "toml" or "mesh" with a Path, "builtin" with a name, or
    "lumibench" with ``lumibench:ID`` (``driver.scenes.lumibench``)."""

    kind: str
    ref: object


def load_scene(name_or_path, up_axis: str | None = None) -> Scene:
    """Resolve ``name_or_path`` (or a ``Source`` from ``resolve``) to a ``Scene`` (see
    docs/scenes.md). ``up_axis`` ("y" or "z", ``UP_AXES``): the up direction of a mesh file's
    automatic camera (default y); SceneError for any other scene."""
    if isinstance(name_or_path, Scene):
        return name_or_path
    kind, ref = name_or_path if isinstance(name_or_path, Source) else resolve(name_or_path)
    check_up_axis(up_axis, kind)
    if kind == "lumibench":
        return lumibench.load(ref, progress=True)
    if kind == "toml":
        return _from_toml(ref)
    if kind == "mesh":
        return _from_mesh_file(ref, UP_AXES[up_axis or "y"])
    if ref in RENDER_BUILTINS:
        return _rendering_builtin(ref)
    mesh = builtin(ref)
    return Scene(mesh, _frame(mesh, _UP[ref], ref), (DEFAULT_SIZE, DEFAULT_SIZE), ref)


def _rendering_builtin(name: str) -> Scene:
    b = BUILT[name](lambda: triangles(builtin("bunny")))
    mesh = None if b.triangles is None else _mesh(
        b.triangles.reshape(-1, 3), np.arange(3 * len(b.triangles)).reshape(-1, 3), name)
    return Scene(mesh, Camera(**b.camera).validate(), (DEFAULT_SIZE, DEFAULT_SIZE), name,
                 Materials(b.albedo, b.emission), list(b.lights), b.double_sided,
                 instances=b.instances)


def check_up_axis(up_axis: str | None, kind: str) -> None:
    """SceneError unless ``up_axis`` is None, or one of ``UP_AXES`` for a mesh file."""
    if up_axis is None:
        return
    if up_axis not in UP_AXES:
        raise SceneError(f"--up-axis must be {' or '.join(UP_AXES)}, got {up_axis!r}")
    if kind != "mesh":
        raise SceneError("--up-axis applies to mesh files (their automatic camera); a built-in "
                         "scene has its own camera and a TOML scene sets [camera] up")


def with_camera(scene: Scene, position=None, look_at=None, up=None, fov_deg=None) -> Scene:
    """``scene`` with the given parts of its camera replaced (None keeps the scene's); the new
    camera is validated (one-line CameraError)."""
    cam = scene.camera
    keep = lambda v, old: old if v is None else v  # noqa: E731
    new = Camera(keep(position, cam.position), keep(look_at, cam.look_at), keep(up, cam.up),
                 keep(fov_deg, cam.fov_deg))
    return replace(scene, camera=new.validate())


def resolve(name_or_path) -> Source:
    """Where a scene comes from, without reading any mesh: ``Source("toml", Path)``,
    ``Source("mesh", Path)`` or ``Source("builtin", name)``; SceneError (one line) if it names
    nothing."""
    if not isinstance(name_or_path, (str, Path)):
        raise SceneError(f"a scene is a name or a path, got {type(name_or_path).__name__}")
    text = str(name_or_path)
    if not text.strip():
        raise SceneError("empty scene name")
    if lumibench.is_lumibench(text):           # lumibench:ID (docs/lumibench.md)
        return Source("lumibench", f"{lumibench.PREFIX}{lumibench.check(text).id}")
    path = Path(text).expanduser()
    bare = isinstance(name_or_path, str) and path.name == text and not path.suffix
    named = SCENES_DIR / f"{text}.toml"
    if bare and (named.is_file() or text in BUILTINS or text in RENDER_BUILTINS):
        if path.exists():
            used = f"scene {named}" if named.is_file() else "built-in scene"
            print(f"rayflex: note: {text!r} is the {used}; the "
                  f"{'folder' if path.is_dir() else 'file'} {text} in the current directory is "
                  f"not used (write ./{text} for it)", file=sys.stderr)
        return Source("toml", named) if named.is_file() else Source("builtin", text)
    if path.is_file():
        return Source("toml" if path.suffix.lower() == ".toml" else "mesh", path)
    if path.exists():
        raise SceneError(f"scene {text!r} is a directory, not a mesh or .toml file")
    if path.name == text and path.suffix == ".toml" and (SCENES_DIR / text).is_file():
        return Source("toml", SCENES_DIR / text)
    if path.suffix or len(path.parts) > 1:
        raise SceneError(f"no such file: {text}")
    raise SceneError(f"unknown scene {text!r}: not a file; scenes: {', '.join(available())}")


def scene_name(name_or_path) -> str:
    """The name ``load_scene`` would give the scene, without reading its mesh."""
    if isinstance(name_or_path, Scene):
        return name_or_path.name
    kind, ref = name_or_path if isinstance(name_or_path, Source) else resolve(name_or_path)
    if kind == "toml":
        name = _read_toml(ref).get("name", ref.stem)
        return name if isinstance(name, str) and name else ref.stem
    if kind == "lumibench":
        return ref.split(":", 1)[1]
    return ref.stem if kind == "mesh" else ref


def available() -> list[str]:
    """Names accepted besides paths: TOML scenes in scenes/ and built-in meshes."""
    tomls = sorted(p.stem for p in SCENES_DIR.glob("*.toml")) if SCENES_DIR.is_dir() else []
    return sorted(set(tomls) | set(BUILTINS) | set(RENDER_BUILTINS))


# ---------------------------------------------------------------------------------------------
# built-in meshes

def builtin(name: str) -> trimesh.Trimesh:
    """A built-in mesh by name (see ``BUILTINS``)."""
    if name == "bunny":
        res = importlib.resources.files("pymeshfix") / "examples" / "StanfordBunny.ply"
        with importlib.resources.as_file(res) as p:
            if not p.is_file():
                raise SceneError(f"built-in bunny not found at {p} (is pymeshfix installed?)")
            return _read_mesh_file(p)
    if name == "sphere":
        m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        return _mesh(m.vertices, m.faces, "sphere")
    if name == "room":
        return _mesh(*meshes.room(), "room")
    if name == "soup":
        return _mesh(*meshes.soup(), "soup")
    raise SceneError(f"unknown built-in mesh {name!r}; built-ins: {', '.join(BUILTINS)}")


def _frame(mesh, up, what) -> Camera:
    """Automatic camera for a mesh: its used vertices fill about 60 % of the image height.
    A mesh whose used vertices all lie at one point has no view: SceneError."""
    pts = np.asarray(mesh.vertices)[np.unique(mesh.faces)]
    lo, hi = pts.min(0), pts.max(0)
    if not (hi - lo).any():
        raise SceneError(f"{what}: mesh is degenerate: all {len(pts)} vertices are at one point "
                         f"{fmt_vec(lo)}")
    try:
        return frame(pts, up=up).validate()
    except CameraError as e:
        raise SceneError(f"{what}: no automatic camera for this mesh: {e}") from None


def _mesh(vertices, faces, what) -> trimesh.Trimesh:
    return _validated(trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                                      process=False, validate=False), what)


# ---------------------------------------------------------------------------------------------
# files

def _from_mesh_file(path: Path, up=_FILE_UP) -> Scene:
    mesh = _read_mesh_file(path)
    inst = _gltf_instances(path)
    if inst is not None:
        flat = inst.flatten().reshape(-1, 3)
        mesh = _mesh(flat, np.arange(len(flat)).reshape(-1, 3), str(path))
    double, materials = _gltf_materials(path, len(mesh.faces))
    return Scene(mesh, _frame(mesh, up, str(path)), (DEFAULT_SIZE, DEFAULT_SIZE), path.stem,
                 None if inst is not None else materials,
                 double_sided=double, instances=inst)


def _gltf_instances(path: Path):
    """The instances of a glTF/GLB scene graph in which some mesh is used by more than one node
    (``driver.instances.Instances``: its meshes, one instance per node with that node's world
    transform, nested nodes composed), or None (no reuse, or not a glTF file)."""
    loaded = _load_gltf(path)
    if not isinstance(loaded, trimesh.Scene):
        return None
    nodes = [(node, loaded.graph[node]) for node in loaded.graph.nodes_geometry]
    nodes = [(node, m, g) for node, (m, g) in nodes
             if isinstance(loaded.geometry.get(g), trimesh.Trimesh)]
    used = [g for _, _, g in nodes]
    if len(set(used)) == len(used):
        return None
    names = sorted(set(used), key=used.index)
    meshes = [triangles(_validated(loaded.geometry[g], f"{path}: mesh {g!r}")) for g in names]
    try:
        return Instances(meshes, [names.index(g) for g in used],
                         np.stack([np.asarray(m, np.float64)[:3] for _, m, _ in nodes]))
    except ValueError as e:
        raise SceneError(f"{path}: {e}") from None


def _load_gltf(path: Path):
    """The trimesh object (a Scene or a mesh) of a glTF/GLB file, or None (another file type)."""
    if path.suffix.lower() not in (".gltf", ".glb"):
        return None
    try:
        return trimesh.load(str(path), process=False)
    except Exception:  # noqa: BLE001  (already read once by _read_mesh_file)
        return None


def _gltf_materials(path: Path, faces: int):
    """(double_sided, materials) of a glTF/GLB file: double-sided when any material says
    ``doubleSided``; a part's ``baseColorFactor`` (RGB, linear as glTF defines it) is the albedo
    of its triangles, ``DEFAULT_ALBEDO`` where a part has none; materials None (the default grey
    everywhere) when no part has one, or for any other file type."""
    if path.suffix.lower() not in (".gltf", ".glb"):
        return False, None
    try:
        loaded = trimesh.load_scene(str(path), process=False)
    except Exception:  # noqa: BLE001  (already read once by _read_mesh_file)
        return False, None
    # the parts in the order trimesh concatenates them into the mesh (Scene.to_mesh)
    parts = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
    mats = [getattr(getattr(g, "visual", None), "material", None) for g in parts]
    double = any(bool(getattr(m, "doubleSided", False)) for m in mats)
    colours = [getattr(m, "baseColorFactor", None) for m in mats]
    if all(c is None for c in colours) or sum(len(g.faces) for g in parts) != faces:
        return double, None
    albedo = np.concatenate([np.broadcast_to(
        DEFAULT_ALBEDO if c is None else _unit_rgb(c), (len(g.faces), 3))
        for g, c in zip(parts, colours)])
    return double, Materials(albedo.astype(np.float64), np.zeros((faces, 3)))


def _unit_rgb(colour) -> np.ndarray:
    """RGB in [0, 1] of a colour trimesh keeps as uint8 RGBA (or as floats in [0, 1])."""
    c = np.asarray(colour)
    return c[:3] / 255.0 if c.dtype.kind in "ui" else c[:3].astype(np.float64)


def _read_mesh_file(path: Path) -> trimesh.Trimesh:
    """Read a mesh file with process=False, concatenating multi-part files; validate it."""
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in MESH_TYPES:
        raise SceneError(f"unsupported mesh file type {path.suffix or '(none)'!r}: {path} "
                         f"(use {', '.join(t.upper() for t in MESH_TYPES)} or a .toml scene)")
    if suffix == "obj":                 # trimesh answers a broken OBJ in numpy's words
        from .objfile import scan
        scan(path, strict=True)
    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # noqa: BLE001  (trimesh raises anything on a broken file)
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise SceneError(f"cannot read mesh file {path}: {msg}") from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise SceneError(f"{path} holds no triangle mesh (got {type(mesh).__name__})")
    return _validated(mesh, str(path))


def _validated(mesh: trimesh.Trimesh, what: str) -> trimesh.Trimesh:
    """Check the raw arrays (before anything touches them): faces present, (n, 3) integer faces
    inside the vertex array, finite float32 vertices."""
    faces = np.asarray(mesh.faces)
    verts = np.asarray(mesh.vertices)
    if faces.size == 0:
        raise SceneError(f"{what}: mesh has no triangles")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise SceneError(f"{what}: faces must be triangles, got shape {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(verts):
        bad = int(np.flatnonzero((faces < 0).any(1) | (faces >= len(verts)).any(1))[0])
        raise SceneError(f"{what}: face {bad} {faces[bad].tolist()} indexes outside the "
                         f"{len(verts)} vertices")
    with np.errstate(over="ignore"):
        finite = np.isfinite(verts.astype(np.float32)).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise SceneError(f"{what}: vertex {bad} is not finite in float32: {fmt_vec(verts[bad])}")
    return mesh


# ---------------------------------------------------------------------------------------------
# scene TOML

_TOP_KEYS = {"mesh", "name", "size", "width", "height", "camera", "double_sided", "ao_radius",
             "lights"}
_LIGHT_KEYS = {"point": {"type", "position", "intensity"},
               "quad": {"type", "corner", "u", "v", "emission"}}
_CAMERA_KEYS = {"position", "look_at", "up", "fov_deg"}


def _from_toml(path: Path) -> Scene:
    data = _read_toml(path)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise SceneError(f"{path}: unknown key(s) {', '.join(sorted(unknown))}; "
                         f"allowed: {', '.join(sorted(_TOP_KEYS))}")
    if not isinstance(data.get("mesh"), str):
        raise SceneError(f"{path}: needs mesh = \"<built-in name or mesh file>\"")
    mesh_ref = data["mesh"]
    mesh_path = (path.parent / mesh_ref).expanduser()
    double, materials = False, None
    if mesh_path.is_file():
        if mesh_path.suffix.lower() == ".toml":
            raise SceneError(f"{path}: mesh must be a mesh file or built-in, not a .toml")
        mesh, up = _read_mesh_file(mesh_path), _FILE_UP
        double, materials = _gltf_materials(mesh_path, len(mesh.faces))
    elif mesh_ref in BUILTINS:
        mesh, up = builtin(mesh_ref), _UP[mesh_ref]
    else:
        raise SceneError(f"{path}: mesh {mesh_ref!r} is neither a file (relative to the TOML) "
                         f"nor a built-in ({', '.join(BUILTINS)})")
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise SceneError(f"{path}: name must be a non-empty string")
    try:
        size = _size(data)
        camera = _camera(data.get("camera"), mesh, up)
    except CameraError as e:
        raise SceneError(f"{path}: {e}") from None
    double = data.get("double_sided", double)
    if not isinstance(double, bool):
        raise SceneError(f"{path}: double_sided must be true or false")
    ao = data.get("ao_radius")
    if ao is not None and (isinstance(ao, bool) or not isinstance(ao, (int, float))
                           or not 0 < ao < float("inf")):
        raise SceneError(f"{path}: ao_radius must be a positive number, got {ao!r}")
    return Scene(mesh, camera, size, name, materials, _lights(path, data.get("lights", [])), double,
                 None if ao is None else float(ao))


def _lights(path: Path, specs) -> list:
    """Workload lights from the TOML's [[lights]] tables."""
    if not isinstance(specs, list):
        raise SceneError(f"{path}: lights must be an array of tables ([[lights]])")
    out = []
    for i, spec in enumerate(specs):
        what = f"{path}: lights[{i}]"
        kind = spec.get("type") if isinstance(spec, dict) else None
        if kind not in _LIGHT_KEYS:
            raise SceneError(f"{what}: type must be \"point\" or \"quad\"")
        if set(spec) != _LIGHT_KEYS[kind]:
            raise SceneError(f"{what}: a {kind} light has exactly the keys "
                             f"{', '.join(sorted(_LIGHT_KEYS[kind]))}")
        vec = {k: _vec3(v, f"{what}.{k}") for k, v in spec.items() if k != "type"}
        for k in ("intensity", "emission"):
            if k in vec and min(vec[k]) < 0:
                raise SceneError(f"{what}: {k} must not be negative")
        if kind == "point":
            out.append(PointLight(vec["position"], vec["intensity"]))
        elif np.linalg.norm(np.cross(vec["u"], vec["v"])) == 0:
            raise SceneError(f"{what}: u and v span no area")
        else:
            out.append(QuadLight(vec["corner"], vec["u"], vec["v"], vec["emission"]))
    return out


def _vec3(v, what) -> tuple:
    ok = isinstance(v, list) and len(v) == 3 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v)
    if not ok:
        raise SceneError(f"{what} must be 3 finite numbers, got {v!r}")
    return tuple(float(x) for x in v)


def _read_toml(path: Path) -> dict:
    if tomllib is None:                                 # pragma: no cover
        raise SceneError(f"{path}: reading .toml scenes needs Python >= 3.11 or the tomli "
                         "package")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: invalid TOML: {e}") from None
    except OSError as e:
        raise SceneError(f"cannot read {path}: {e.strerror}") from None


def _size(data: dict) -> tuple[int, int]:
    if "size" in data and ("width" in data or "height" in data):
        raise CameraError("give either size or width/height, not both")
    if "size" in data:
        return check_size(data["size"], data["size"])
    return check_size(data.get("width", DEFAULT_SIZE), data.get("height", DEFAULT_SIZE))


def _camera(spec, mesh, up) -> Camera:
    if spec is None:
        return _frame(mesh, up, "mesh")
    if not isinstance(spec, dict):
        raise CameraError("[camera] must be a table")
    unknown = set(spec) - _CAMERA_KEYS
    if unknown:
        raise CameraError(f"unknown camera key(s) {', '.join(sorted(unknown))}; "
                          f"allowed: {', '.join(sorted(_CAMERA_KEYS))}")
    missing = {"position", "look_at"} - set(spec)
    if missing:
        raise CameraError(f"camera needs {' and '.join(sorted(missing))}")
    tup = lambda v: tuple(v) if isinstance(v, list) else v  # noqa: E731  (TOML arrays)
    cam = Camera(tup(spec["position"]), tup(spec["look_at"]), tup(spec.get("up", up)),
                 spec.get("fov_deg", 40.0))
    return cam.validate()
