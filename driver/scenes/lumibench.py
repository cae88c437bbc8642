"""LumiBench's scenes, read from a clone of the benchmark's repository (docs/lumibench.md).

LumiBench (Liu et al., IISWC 2023) defines 16 scenes in the code of its application (a fork of
RayTracingInVulkan): a folder of OBJ files (each model its own bottom-level acceleration
structure, placed once in the top level) or a single model with a model matrix, a camera (a
``.camera`` file of eye and centre, or fixed in code), a vertical field of view, and a light
(a sky from the direction (0, 1, 0), or a point light with a radius). ``DEFINITIONS`` holds
those definitions; ``load(id)`` reproduces one from the repository at ``root()``
(``--lumibench-root DIR`` or ``LUMIBENCH_ROOT``), laid out as the repository is
(``Scenes/...``, ``assets/models/...``):

- every model is one mesh of ``driver.instances.Instances`` with an identity transform (the
  application transforms a model's vertices, in float64 here and rounded once to float32), so
  the scene traces through the two-level BVH, one BLAS per model, as the benchmark's does;
- triangles, materials and their order come from ``driver.scenes.objfile`` (tinyobjloader's
  rules); models are taken in name order (the application walks the folder in the file
  system's order); a model with no triangles is left out, as the application leaves it out;
- every triangle is double-sided: the benchmark's rays carry no culling flag;
- a file the definition needs that is not there (the public repository lacks some large
  models) is reported by name (``LumiBenchScene.missing``): the scene is loaded from what
  exists and is ``partial``; a missing camera file leaves the automatic camera with the
  scene's field of view. A scene that needs what the datapath cannot do (procedural spheres,
  alpha-tested textures) is refused in one line (``SceneError``), as is a scene whose only
  model is missing.

Loaded scenes are cached (``CACHE_VERSION``) as an ``.npz`` in ``cache_dir()/scenes``, keyed by
the definition and the contents (BLAKE2b) of every file it reads, so a second run of a scene
reads one file instead of its OBJ files (``RAYFLEX_SCENE_CACHE``: 0 bypasses the cache, a
folder puts it there).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .camera import Camera
from .scene import Scene

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


@dataclass
class LumiBenchScene(Scene):
    """A ``Scene`` loaded from LumiBench: ``mesh`` is the (n, 3, 3) float32 array of every
    model's triangles (model after model: the flattened instances), ``instances`` one mesh per
    model, identity transforms. Beyond ``Scene``: ``lumibench`` (the definition's ID),
    ``models`` (names, in instance order), ``missing`` (files the definition needs that are not
    in the root, relative to it), ``skipped`` (files left out, with why), ``root``."""

    lumibench: str = ""
    models: list = field(default_factory=list)
    missing: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    root: str = ""
    load_s: float = 0.0
    cached: bool = False
    cache_key: str = ""          # the scene cache's key ("" without the cache)

    @property
    def triangles(self) -> np.ndarray:
        return self.mesh

    @property
    def partial(self) -> bool:
        return bool(self.missing)

    def counts(self) -> dict:
        n = len(self.mesh)
        return {"instances": len(self.instances) if self.instances is not None else 1,
                "instanced_triangles": n, "blas_triangles": n}

    def flattened(self) -> "LumiBenchScene":
        return replace(self, instances=None)

    def build_bvh(self, fill: int = 0, format: str = "box32", transform: str = "driver"):
        """This scene's BVH (``driver.bvh.instances.build_scene``), from the cache when the
        same scene files were built with the same options by the same source tree (its
        ``stats["from_cache"]``): a second run of a scene starts tracing without a build."""
        return cached_bvh(self, fill, format, transform)

    def info(self) -> dict:
        """The ``lumibench`` object of a JSON (docs/statistics.md)."""
        d = DEFINITIONS[self.lumibench]
        empty = [s for s in self.skipped if s["why"] == EMPTY]
        return {"id": d.id, "name": d.name, "root": self.root, "models": len(self.models),
                "triangles": int(len(self.mesh)), "partial": self.partial,
                "missing": list(self.missing),
                "skipped": [s for s in self.skipped if s["why"] != EMPTY], "empty": len(empty),
                "light": ("sky" if d.light is None else "point"), "fov_deg": d.fov}


def _digest(paths: list[Path], base: Path) -> str:
    h = hashlib.blake2b(digest_size=16)
    for p in paths:
        h.update(f"{p.relative_to(base)}\0{p.stat().st_size}\0".encode())
        with open(p, "rb") as f:
            while chunk := f.read(1 << 20):
                h.update(chunk)
    return h.hexdigest()


def _inputs(d: Definition, base: Path) -> tuple[list[Path], list[Path]]:
    """(OBJ files to load, every file whose contents key the cache)."""
    if d.kind == "folder":
        names = sorted(os.listdir(base))
        objs = [base / n for n in names if n.lower().endswith(".obj")]
        keyed = [base / n for n in names if n.lower().endswith((".obj", ".mtl", ".camera"))]
        return objs, keyed
    model = base
    objs = [model] if model.is_file() else []
    mtls = sorted(model.parent.glob("*.mtl")) if model.parent.is_dir() else []
    return objs, objs + mtls


def _cache_dir() -> Path:
    """``$RAYFLEX_SCENE_CACHE`` when it names a folder, else the build cache's ``scenes``."""
    given = os.environ.get(CACHE_ENV)
    if given and given != "0" and given != "1":
        return Path(given).expanduser()
    from ..verilate import cache_dir
    return cache_dir() / "scenes"


def key_of(name: str, root_dir=None) -> str:
    """The cache key ``load`` gives the scene (its definition and the digest of its files),
    without reading it; "" when the cache is off."""
    if os.environ.get(CACHE_ENV, "1") == "0":
        return ""
    d = check(name, root_dir)
    top = root(root_dir)
    _, keyed = _inputs(d, top / d.path)
    defn = hashlib.blake2b(repr((CACHE_VERSION, d)).encode(), digest_size=8).hexdigest()
    return f"{d.id}-{defn}-{_digest(keyed, top)}"


def load(name: str, root_dir=None, progress: bool = False, use_cache: bool | None = None,
         threads: int | None = None) -> LumiBenchScene:
    """The scene ``lumibench:ID`` (module docstring). ``use_cache`` None: unless
    ``RAYFLEX_SCENE_CACHE=0``. ``threads``: OBJ files read at once (default: the usable
    cores)."""
    t0 = time.perf_counter()
    d = check(name, root_dir)
    top = root(root_dir)
    base = top / d.path
    objs, keyed = _inputs(d, base)
    if use_cache is None:
        use_cache = os.environ.get(CACHE_ENV, "1") != "0"
    key = _digest(keyed, top) if use_cache else ""
    defn = hashlib.blake2b(repr((CACHE_VERSION, d)).encode(), digest_size=8).hexdigest()
    cached = _cache_dir() / f"lumibench-{d.id}-{defn}-{key}.npz" if use_cache else None
    parts = _read_cache(cached) if cached is not None else None
    hit = parts is not None
    if parts is None:
        parts = _assemble(d, top, base, objs, threads)
        if cached is not None:
            _write_cache(cached, parts)
    scene = _scene(d, top, parts)
    scene.load_s, scene.cached = time.perf_counter() - t0, hit
    scene.cache_key = f"{d.id}-{defn}-{key}" if use_cache else ""
    if scene.missing and progress:
        print(f"rayflex: note: {PREFIX}{d.id} is partial: {len(scene.missing)} file(s) missing "
              f"from {top}: {', '.join(scene.missing)}", file=sys.stderr)
    return scene


def _assemble(d: Definition, top: Path, base: Path, objs: list[Path], threads) -> dict:
    """Read the definition's files: a dict of arrays and lists (what the cache holds)."""
    from .objfile import read_obj
    skipped, missing = [], []
    keep = []
    for p in objs:
        if any(s in p.name for s in d.skip):
            skipped.append({"file": str(p.relative_to(top)),
                            "why": "left out by the benchmark's scene list"})
        else:
            keep.append(p)
    if d.kind == "folder":
        have = {p.stem for p in objs}
        for mtl in sorted(base.glob("*.mtl")):
            if mtl.stem not in have:
                missing.append(str(mtl.with_suffix(".obj").relative_to(top)))
    elif not objs:
        missing.append(d.path)
    n_threads = threads or min(8, len(os.sched_getaffinity(0)))
    if n_threads > 1 and len(keep) > 1:
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(n_threads) as pool:
            models = list(pool.map(read_obj, keep))
    else:
        models = [read_obj(p) for p in keep]
    tris, albedo, emission, names = [], [], [], []
    if d.cornell:
        t, a, e = cornell_box(d.cornell)
        tris.append(t)
        albedo.append(a)
        emission.append(e)
        names.append("(Cornell box)")
    for m in models:
        missing += [str(Path(x).relative_to(top)) for x in m.missing
                    if str(Path(x).relative_to(top)) not in missing]
        if not len(m.triangles):
            skipped.append({"file": str(m.path.relative_to(top)), "why": EMPTY})
            continue
        t = m.triangles
        if d.matrix is not None:
            mat = np.asarray(d.matrix, np.float64)
            t = (t.astype(np.float64) @ mat[:, :3].T + mat[:, 3]).astype(np.float32)
        tris.append(t)
        albedo.append(m.albedo)
        emission.append(np.zeros((len(t), 3), np.float32))
        names.append(str(m.path.relative_to(top)))
    if not tris:
        raise SceneError(f"{PREFIX}{d.id}: no triangles in {base}")
    camera = None
    if d.kind == "folder":
        cams = sorted(base.glob("*.camera"))
        if cams:
            camera = _read_camera(cams[0])
        else:
            missing.append(str((base / "Camera.camera").relative_to(top)))
    sizes = np.array([len(t) for t in tris], np.int64)
    return {"triangles": np.concatenate(tris), "albedo": np.concatenate(albedo),
            "emission": np.concatenate(emission), "sizes": sizes,
            "meta": {"models": names, "missing": missing, "skipped": skipped, "camera": camera}}


_SOURCE: list = []


def _source_digest() -> str:
    """BLAKE2b of the package's Python sources: a BVH cached by another version of the
    builder (or of anything it uses) is not used."""
    if not _SOURCE:
        h = hashlib.blake2b(digest_size=8)
        pkg = Path(__file__).resolve().parent.parent
        for p in sorted(pkg.rglob("*.py")):
            h.update(str(p.relative_to(pkg)).encode() + b"\0" + p.read_bytes())
        _SOURCE.append(h.hexdigest())
    return _SOURCE[0]


def cached_bvh(scene: "LumiBenchScene", fill: int, format: str, transform: str):
    """``LumiBenchScene.build_bvh``: the image and its statistics in ``cache_dir()/scenes``
    beside the scene, keyed by the scene's key, the options and the source tree; kept on the
    scene object for the next build in this process."""
    from ..bvh.instances import build_scene
    if not scene.cache_key:
        return build_scene(scene, fill=fill, format=format, transform=transform)
    two = scene.instances is not None
    memo = scene.__dict__.setdefault("_bvh", {})        # this process's builds of the scene
    if (format, fill, two) in memo:
        bvh = memo[(format, fill, two)]
        if two:
            bvh.transform = transform
        bvh.stats.update(build_s=0.0, from_cache=True)     # no time spent on it this time
        return bvh
    bvh = _cached_bvh(scene, fill, format, transform, two)
    memo[(format, fill, two)] = bvh
    return bvh


def _cached_bvh(scene, fill, format, transform, two):
    from ..bvh.instances import TwoLevelBVH, build_scene
    from ..bvh4 import BVH4
    path = _cache_dir() / (f"lumibench-{scene.cache_key}-bvh-{format}-f{fill}-"
                           f"{'two' if two else 'flat'}-{_source_digest()}.npz")
    t0 = time.perf_counter()
    try:
        with np.load(path, allow_pickle=False) as z:
            image, roots = z["image"], z["blas_root"]
            meta = json.loads(str(z["meta"]))
        stats = dict(meta["stats"], build_s=time.perf_counter() - t0, from_cache=True)
        if two:
            bvh = TwoLevelBVH(image, scene.instances, stats, format, roots, meta["blas"])
            bvh.transform = transform
        else:
            bvh = BVH4(image, scene.triangles, stats, format)
        return bvh
    except (OSError, ValueError, KeyError):
        pass
    bvh = build_scene(scene, fill=fill, format=format, transform=transform)
    meta = {"stats": bvh.stats, "blas": getattr(bvh, "blas", None)}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with open(tmp, "wb") as f:
            np.savez(f, image=bvh.image, meta=np.array(json.dumps(meta, default=_plain)),
                     blas_root=np.asarray(getattr(bvh, "blas_root", np.zeros(0, np.uint32))))
        os.replace(tmp, path)
    except OSError:
        pass
    return bvh


def _plain(v):
    return v.item() if hasattr(v, "item") else str(v)


def _read_camera(path: Path) -> list:
    """eye x y z, centre x y z: the first six numbers of a ``.camera`` file."""
    try:
        words = path.read_text(errors="replace").split()
        values = [float(w) for w in words[:6]]
    except (OSError, ValueError):
        values = []
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise SceneError(f"{path}: a camera file holds six numbers (eye x y z, centre x y z)")
    return values


def _read_cache(path: Path) -> dict | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in ("triangles", "albedo", "emission", "sizes")}
            out["meta"] = json.loads(str(z["meta"]))
        return out
    except (OSError, ValueError, KeyError):
        return None


def _write_cache(path: Path, parts: dict) -> None:
    """Write the cache entry atomically; a cache that cannot be written is skipped."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with open(tmp, "wb") as f:
            np.savez(f, meta=np.array(json.dumps(parts["meta"])),
                     **{k: parts[k] for k in ("triangles", "albedo", "emission", "sizes")})
        os.replace(tmp, path)
    except OSError:
        try:
            tmp.unlink()
        except (OSError, UnboundLocalError):
            pass


def _scene(d: Definition, top: Path, parts: dict) -> LumiBenchScene:
    from ..instances import Instances
    from ..workloads import Materials
    from .camera import frame
    tris = parts["triangles"]
    meta = parts["meta"]
    offsets = np.concatenate(([0], np.cumsum(parts["sizes"])))
    meshes = [tris[offsets[i]:offsets[i + 1]] for i in range(len(parts["sizes"]))]
    k = len(meshes)
    eye_centre = meta["camera"] if d.kind == "folder" else list(d.eye) + list(d.centre)
    if eye_centre is None:
        camera = frame(tris.reshape(-1, 3), up=UP, fov_deg=d.fov).validate()
    else:
        camera = Camera(tuple(eye_centre[:3]), tuple(eye_centre[3:]), UP, float(d.fov))
        camera = camera.validate()
    lo = tris.reshape(-1, 3).min(0).astype(np.float64)
    hi = tris.reshape(-1, 3).max(0).astype(np.float64)
    diag = float(np.linalg.norm(hi - lo)) or 1.0
    if d.light is None:
        light = SkyLight(SKY, tuple(((lo + hi) / 2).tolist()), 10.0 * diag)
    else:
        pos, radius = d.light
        r2 = float(np.sum((np.asarray(pos) - (lo + hi) / 2) ** 2))
        light = SphereLight(tuple(pos), float(radius), (r2,) * 3)
    instances = Instances(meshes, np.arange(k), np.tile(np.eye(3, 4, dtype=np.float32), (k, 1, 1)))
    materials = Materials(parts["albedo"], parts["emission"])
    return LumiBenchScene(tris, camera, (SIZE, SIZE), d.id, materials, [light], True, AO_EXTENT,
                          instances, lumibench=d.id, models=list(meta["models"]),
                          missing=list(meta["missing"]), skipped=list(meta["skipped"]),
                          root=str(top))


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
