"""LumiBench's scene definitions (docs/lumibench.md): what the benchmark says each scene is,
and where its repository is.

LumiBench (Liu et al., IISWC 2023) defines 16 scenes in the code of its application (a fork of
RayTracingInVulkan): a folder of OBJ files (each model its own bottom-level acceleration
structure, placed once in the top level) or a single model with a model matrix, a camera (a
``.camera`` file of eye and centre, or fixed in code), a vertical field of view, and a light
(a sky from the direction (0, 1, 0), or a point light with a radius). ``DEFINITIONS`` holds
those definitions, ``root()`` the repository's clone (``--lumibench-root DIR`` or
``LUMIBENCH_ROOT``), laid out as the repository is (``Scenes/...``, ``assets/models/...``), and
``check``/``available`` what a root can trace without reading a mesh. ``driver.scenes.lumibench``
loads a scene.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import SceneError

PREFIX = "lumibench:"
ROOT_ENV = "LUMIBENCH_ROOT"
CACHE_ENV = "RAYFLEX_SCENE_CACHE"
CACHE_VERSION = 1             # bump when what a cached scene holds or how it is made changes
SIZE = 128                    # the benchmark's frames: 128 x 128, 2 samples per pixel
SPP = 2
SKY = (0.0, 1.0, 0.0)         # the sky scenes' light direction
UP = (0.0, 1.0, 0.0)
AO_EXTENT = 10.0              # the AO shader's ray extent
SHADERS = ("pt", "sh", "ao")
EMPTY = "no triangles"        # why an OBJ file without triangles is left out


@dataclass(frozen=True)
class SkyLight:
    """Light from a fixed ``direction`` (unit), as the benchmark's sky scenes' shadow rays see
    it. For the tool's own workloads (``shadow``, ``path``) it is a point light ``distance``
    away from ``centre`` in that direction, bright enough for an irradiance of about 1 there."""

    direction: tuple = SKY
    centre: tuple = (0.0, 0.0, 0.0)
    distance: float = 1.0

    def sample(self, u1, u2):
        k = len(u1)
        p = (np.asarray(self.centre, np.float64)
             + self.distance * np.asarray(self.direction, np.float64))
        return (np.broadcast_to(p, (k, 3)), None,
                np.full((k, 3), self.distance ** 2))


@dataclass(frozen=True)
class SphereLight:
    """A point light of ``radius`` at ``position`` (the benchmark's BUNNY): shadow rays aim at
    a uniform point inside the sphere. ``intensity``: radiant intensity for the tool's own
    workloads, which sample the same points."""

    position: tuple
    radius: float = 0.0
    intensity: tuple = (1.0, 1.0, 1.0)

    def sample(self, u1, u2, u3=None):
        """Points uniform in the ball (``u3`` the radial number; 0.5 without it)."""
        k = len(u1)
        z = 1.0 - 2.0 * np.asarray(u1, np.float64)
        phi = 2.0 * np.pi * np.asarray(u2, np.float64)
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        r = self.radius * np.cbrt(np.full(k, 0.5) if u3 is None else np.asarray(u3, np.float64))
        p = (np.asarray(self.position, np.float64)
             + r[:, None] * np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1))
        return p, None, np.broadcast_to(np.asarray(self.intensity, np.float64), (k, 3))


def _rot_y(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], np.float64)


def _rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], np.float64)


def _model_matrix(translate=(0.0, 0.0, 0.0), scale=1.0, rotate=np.eye(3)) -> np.ndarray:
    """(3, 4) float64: translate · scale · rotate (applied to a vertex right to left)."""
    m = np.zeros((3, 4))
    m[:, :3] = scale * np.asarray(rotate, np.float64)
    m[:, 3] = translate
    return m


@dataclass(frozen=True)
class Definition:
    """One LumiBench scene. ``kind``: "folder" (every OBJ in ``path`` a model, the camera from
    its ``.camera`` file) or "model" (the OBJ at ``path`` through ``matrix``, the camera
    ``eye``/``centre``). ``light``: None for the sky, else (position, radius) of a point light.
    ``skip``: OBJ files the benchmark's scene list leaves out (name substrings).
    ``cornell``: the application's Cornell box of that size is part of the scene.
    ``unsupported``: why the tool cannot trace it (None: it can)."""

    id: str
    name: str
    kind: str
    path: str
    fov: float
    eye: tuple | None = None
    centre: tuple | None = None
    matrix: tuple | None = None
    light: tuple | None = None
    skip: tuple = ()
    cornell: float = 0.0
    shaders: tuple = SHADERS
    unsupported: str | None = None

    @property
    def runs(self) -> tuple:
        return tuple(f"{self.id}_{s.upper()}" for s in self.shaders)


def _folder(id, name, path, fov, **kw) -> Definition:
    return Definition(id, name, "folder", path, fov, **kw)


def _model(id, name, path, fov, eye, centre, matrix, **kw) -> Definition:
    return Definition(id, name, "model", path, fov, eye, centre,
                      tuple(map(tuple, np.asarray(matrix).tolist())), **kw)


# the 16 scenes of LumiBench's run list, as its application defines them (docs/lumibench.md)
DEFINITIONS = {d.id: d for d in (
    _model("BUNNY", "Bunny", "assets/models/bunny.obj", 40, (278, 278, 800), (278, 278, 0),
           _model_matrix((555 - 300 - 82, 5, -225 - 82), 200, _rot_y(75)),
           light=((280.0, 500.0, 400.0), 10.0), cornell=555.0),
    _model("SHIP", "Ship", "assets/models/karimSchooner.obj", 50, (378, 278, 500), (178, 278, 0),
           _model_matrix((555 - 300 - 82, -9, -295 - 82), 100, _rot_y(75))),
    _model("CRNVL", "Carnival", "assets/models/TheCarnival.obj", 50, (275, 60, -700),
           (225, 120, -1000), _model_matrix((400, 20, 150), 0.2)),
    _model("SPNZA", "Sponza", "Scenes/Sponza/sponza.obj", 70, (0, 115, 2), (0, 115, 1),
           _model_matrix(rotate=_rot_y(270))),
    _model("CHSNT", "Chestnut", "assets/models/chestnut.obj", 50, (20, 0, 100), (20, 100, 0),
           _model_matrix(rotate=_rot_x(-75)), shaders=("pt",),
           unsupported="its leaves are alpha-tested textures (an any-hit shader decides each "
                       "hit), which the datapath's triangle test cannot do"),
    _model("REF", "Reflective Cornell Box & Lucy", "assets/models/lucy.obj", 78,
           (278, 278, 350), (278, 278, 0), _model_matrix(),
           unsupported="its glass ball is a procedural sphere (an intersection shader), and the "
                       "datapath tests triangles only"),
    _model("WKND", "Ray Tracing in One Weekend", "", 20, (13, 2, 3), (0, 0, 0), _model_matrix(),
           unsupported="its spheres are procedural primitives (intersection shaders), and the "
                       "datapath tests triangles only"),
    _folder("PARK", "Trees and Grass", "Scenes/TreesAndGrass", 30,
            unsupported="its ground is a procedural sphere (an intersection shader), and the "
                        "datapath tests triangles only"),
    _folder("CAR", "Racing Car", "Scenes/Blender_2.77", 30),
    _folder("ROBOT", "Procedural", "Scenes/Blender_2.78", 30),
    _folder("SPRNG", "Spring", "Scenes/Blender_2.80", 20, skip=("Dirt_grass",)),
    _folder("PARTY", "Party Tug", "Scenes/Blender_2.83", 20),
    _folder("FOX", "Splash Fox", "Scenes/Blender_2.90", 30),
    _folder("FRST", "Red Autumn Forest", "Scenes/Blender_2.91", 30),
    _folder("LANDS", "White Lands", "Scenes/Blender_3.2", 25),
    _folder("BATH", "Bathroom", "Scenes/Bathroom", 36),
)}


def is_lumibench(name) -> bool:
    return isinstance(name, str) and name.startswith(PREFIX)


_ROOT: list = []        # roots set by ``using_root`` (the command line's --lumibench-root)


class using_root:
    """``with using_root(DIR):`` LumiBench scenes are read from DIR (None: no change)."""

    def __init__(self, path):
        self.path = path

    def __enter__(self):
        if self.path is not None:
            root(self.path)                     # a bad directory fails here, in one line
            _ROOT.append(self.path)
        return self

    def __exit__(self, *exc):
        if self.path is not None:
            _ROOT.pop()
        return False


def root(explicit=None) -> Path:
    """The repository's directory: ``explicit``, else the innermost ``using_root``, else
    ``$LUMIBENCH_ROOT``; SceneError (one line) when none names a directory."""
    given = explicit if explicit is not None else (_ROOT[-1] if _ROOT else
                                                   os.environ.get(ROOT_ENV))
    if not given:
        raise SceneError(f"LumiBench scenes are read from a clone of the benchmark's repository: "
                         f"give --lumibench-root DIR or set {ROOT_ENV}")
    path = Path(given).expanduser()
    if not path.is_dir():
        raise SceneError(f"LumiBench root {given} is not a directory")
    return path


def definition(name: str) -> Definition:
    """The definition of ``lumibench:ID`` (or of ``ID``); SceneError for an unknown ID or one
    the tool cannot trace."""
    sid = name[len(PREFIX):] if is_lumibench(name) else name
    d = DEFINITIONS.get(sid.upper())
    if d is None:
        raise SceneError(f"unknown LumiBench scene {sid!r}; scenes: {', '.join(DEFINITIONS)}")
    if d.unsupported:
        raise SceneError(f"{PREFIX}{d.id} ({d.name}) cannot be traced: {d.unsupported}")
    return d


def check(name: str, root_dir=None) -> Definition:
    """Everything about ``lumibench:ID`` that is known without reading a mesh: the ID, the
    root, and that what the scene needs first exists (one-line SceneError otherwise)."""
    d = definition(name)
    base = root(root_dir) / d.path
    if d.kind == "folder" and not base.is_dir():
        raise SceneError(f"{PREFIX}{d.id}: the folder {d.path} is not in {root(root_dir)}")
    if d.kind == "model" and not base.is_file():
        raise SceneError(f"{PREFIX}{d.id}: its model {d.path} is not in {root(root_dir)}")
    return d



# the application's Cornell box (BUNNY, REF): walls of 0..s in x and y, 0..-s in z, the front
# open; reflectances and the light's radiance as the application sets them
_RED, _GREEN, _WHITE = (0.65, 0.05, 0.05), (0.12, 0.45, 0.15), (0.73, 0.73, 0.73)
_CORNELL_LIGHT = 15.0


def cornell_box(s: float):
    """(triangles (12, 3, 3), albedo, emission) float32 of the application's Cornell box of
    size ``s``: green wall x = 0, red wall x = s, white back (z = -s), floor and ceiling, each
    facing the inside, and the light quad (x 213..343, z -328..-223 in units of s / 555) just
    under the ceiling, facing down."""
    def quad(a, b, c, e):
        return [[a, b, c], [a, c, e]]
    l0, l1, l2, l3 = (0, 0, 0), (0, 0, -s), (0, s, -s), (0, s, 0)
    r0, r1, r2, r3 = (s, 0, 0), (s, 0, -s), (s, s, -s), (s, s, 0)
    x0, x1 = s * 213 / 555, s * 343 / 555
    z0, z1 = s * (-555 + 332) / 555, s * (-555 + 227) / 555
    y1 = s * 0.998
    walls = [(quad(l0, l1, l2, l3), _GREEN, 0.0), ([[r2, r1, r0], [r3, r2, r0]], _RED, 0.0),
             (quad(l1, r1, r2, l2), _WHITE, 0.0), (quad(l0, r0, r1, l1), _WHITE, 0.0),
             (quad(l2, r2, r3, l3), _WHITE, 0.0),
             (quad((x0, y1, z1), (x1, y1, z1), (x1, y1, z0), (x0, y1, z0)), (0.0, 0.0, 0.0),
              _CORNELL_LIGHT)]
    tris, alb, emi = [], [], []
    for t, colour, e in walls:
        tris += t
        alb += [colour] * len(t)
        emi += [(e, e, e)] * len(t)
    return (np.array(tris, np.float32), np.array(alb, np.float32), np.array(emi, np.float32))


def available(root_dir=None) -> dict:
    """For every definition: None when this root can trace it, else why not (one line)."""
    out = {}
    for sid in DEFINITIONS:
        try:
            check(PREFIX + sid, root_dir)
            out[sid] = None
        except SceneError as e:
            out[sid] = str(e)
    return out
