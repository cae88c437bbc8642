"""LumiBench's scenes, read from a clone of the benchmark's repository (docs/lumibench.md).

LumiBench (Liu et al., IISWC 2023) defines 16 scenes in the code of its application (a fork of
RayTracingInVulkan): a folder of OBJ files (each model its own bottom-level acceleration
structure, placed once in the top level) or a single model with a model matrix, a camera (a
``.camera`` file of eye and centre, or fixed in code), a vertical field of view, and a light
(a sky from the direction (0, 1, 0), or a point light with a radius). ``DEFINITIONS`` holds
those definitions (``driver.scenes.lumibench_defs``); ``load(id)`` reproduces one from the repository at ``root()``
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

Loaded scenes are cached (``CACHE_VERSION``) as an ``.npz`` in ``cache_root()/scenes``, keyed by
the definition and the contents (BLAKE2b) of every file it reads, so a second run of a scene
reads one file instead of its OBJ files (``RAYFLEX_SCENE_CACHE``: 0 bypasses the cache, a
folder puts it there).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..backends.cache import cache_root
from ..bvh.instances import TwoLevelBVH
from ..bvh4 import BVH4, build_scene
from ..core.errors import SceneError
from ..core.words import plural
from ..instances import Instances
from .camera import Camera, frame
from .lumibench_defs import (AO_EXTENT, CACHE_ENV, CACHE_VERSION, DEFINITIONS, EMPTY, PREFIX,
                             ROOT_ENV, SHADERS, SIZE, SKY, SPP, UP, Definition, SkyLight,
                             SphereLight, available, check, cornell_box, definition,
                             is_lumibench, root, using_root)
from .materials import Materials
from .model import Scene
from ..core.layout import DEFAULT_FORMAT

# the definitions' names are this module's too: ``lumibench.X`` is the whole scene API
__all__ = ["AO_EXTENT", "CACHE_ENV", "CACHE_VERSION", "DEFINITIONS", "EMPTY", "PREFIX",
           "ROOT_ENV", "SHADERS", "SIZE", "SKY", "SPP", "UP", "Definition", "LumiBenchScene",
           "SkyLight", "SphereLight", "available", "cached_bvh", "check", "cornell_box",
           "definition", "is_lumibench", "key_of", "load", "root", "using_root"]

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

    def build_bvh(self, fill: int = 0, format: str = DEFAULT_FORMAT, transform: str = "driver"):
        """This scene's BVH (``driver.bvh4.build_scene``), from the cache when the
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
    """``$RAYFLEX_SCENE_CACHE`` when it names a folder, else the tool cache's ``scenes``."""
    given = os.environ.get(CACHE_ENV)
    if given and given != "0" and given != "1":
        return Path(given).expanduser()
    return cache_root() / "scenes"


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
        print(f"rayflex: note: {PREFIX}{d.id} is partial: "
              f"{plural(len(scene.missing), 'file')} missing "
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
    """``LumiBenchScene.build_bvh``: the image and its statistics in ``cache_root()/scenes``
    beside the scene, keyed by the scene's key, the options and the source tree; kept on the
    scene object for the next build in this process."""
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
    path = _cache_dir() / (f"lumibench-{scene.cache_key}-bvh-{format}-f{fill}-"
                           f"{'two' if two else 'flat'}-{_source_digest()}.npz")
    bvh = _read_bvh(path, scene, format, transform, two)
    if bvh is not None:
        return bvh
    # one process builds, the others wait and read its image (two Dask workers starting runs
    # of the same scene would otherwise both build it)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path.with_name(f".{path.name}.lock"), "w")
    except OSError:
        lock = None
    try:
        if lock is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
            bvh = _read_bvh(path, scene, format, transform, two)
            if bvh is not None:
                return bvh
        bvh = build_scene(scene, fill=fill, format=format, transform=transform)
        _write_bvh(path, bvh)
        return bvh
    finally:
        if lock is not None:
            lock.close()                                # releases the lock


def _read_bvh(path: Path, scene, format: str, transform: str, two: bool):
    """The cached image at ``path`` as a BVH of ``scene`` (None: not there or unreadable)."""
    t0 = time.perf_counter()
    try:
        with np.load(path, allow_pickle=False) as z:
            image, roots = z["image"], z["blas_root"]
            meta = json.loads(str(z["meta"]))
    except (OSError, ValueError, KeyError):
        return None
    stats = dict(meta["stats"], build_s=time.perf_counter() - t0, from_cache=True)
    if two:
        bvh = TwoLevelBVH(image, scene.instances, stats, format, roots, meta["blas"])
        bvh.transform = transform
        return bvh
    return BVH4(image, scene.triangles, stats, format)


def _write_bvh(path: Path, bvh) -> None:
    """Write ``bvh`` to ``path`` atomically (nothing, if the cache cannot be written)."""
    meta = {"stats": bvh.stats, "blas": getattr(bvh, "blas", None)}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            np.savez(f, image=bvh.image, meta=np.array(json.dumps(meta, default=_plain)),
                     blas_root=np.asarray(getattr(bvh, "blas_root", np.zeros(0, np.uint32))))
        os.replace(tmp, path)
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass


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
