"""``rayflex bench --scene-load``: how long a LumiBench scene takes to load and to build, the
first time and from the cache, and the peak memory of each (docs/lumibench.md).

Each phase runs in a fresh Python process (``python -m driver.load_bench PHASE ...``), as a user's
run would: ``cold`` loads the scene with an empty scene cache and builds its BVH; ``warm`` loads it
again and its BVH (from the cache the cold phase wrote): the time until a second run starts
tracing. Each reports its wall and CPU time split into imports, loading and building,
and its peak resident memory (``ru_maxrss``). ``synthetic_root`` writes a LumiBench-format
folder of N OBJ files (wavy grids of quads, an MTL each, a camera file) to measure a scene of
any size.
"""

from __future__ import annotations

import time

_T_MODULE = time.time()         # before this module's imports: the driver's import time

import json  # noqa: E402
import os  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from .core.progress import phase as show  # noqa: E402
from .design import DesignPoint  # noqa: E402
from .scenes import lumibench as lb  # noqa: E402
from .core.layout import DEFAULT_FORMAT

PHASES = ("cold", "warm")


def synthetic_root(path, files: int, triangles: int, seed: int = 0) -> Path:
    """Write a LumiBench root at ``path`` whose BATH folder holds ``files`` OBJ files of about
    ``triangles`` triangles in all (quads, written as Blender writes them: ``v``, ``vt``,
    ``vn`` and ``f v/vt/vn`` lines), an MTL per file and a camera file; returns the root."""
    rng = np.random.default_rng(seed)
    folder = Path(path) / "Scenes" / "Bathroom"
    folder.mkdir(parents=True, exist_ok=True)
    per = max(2, triangles // max(files, 1))
    side = max(1, int(round((per / 2) ** 0.5)))
    u = np.arange(side + 1)
    gx, gz = np.meshgrid(u, u, indexing="ij")
    quads = np.stack([gx[:-1, :-1] * (side + 1) + gz[:-1, :-1],
                      gx[1:, :-1] * (side + 1) + gz[1:, :-1],
                      gx[1:, 1:] * (side + 1) + gz[1:, 1:],
                      gx[:-1, 1:] * (side + 1) + gz[:-1, 1:]], -1).reshape(-1, 4) + 1
    faces = "\n".join("f " + " ".join(f"{i}/{i}/{i}" for i in q) for q in quads.tolist())
    cells = int(np.ceil(files ** (1 / 3)))
    for k in range(files):
        cx, cy, cz = k % cells, (k // cells) % cells, k // cells ** 2
        x = cx * 1.2 + gx.reshape(-1) / side
        z = cz * 1.2 + gz.reshape(-1) / side
        y = cy * 1.2 + 0.1 * np.sin(6 * x + rng.uniform(0, 6)) * np.cos(5 * z)
        v = "\n".join(f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in zip(x, y, z))
        vt = "\n".join(f"vt {a:.6f} {b:.6f}" for a, b in zip(gx.reshape(-1) / side,
                                                              gz.reshape(-1) / side))
        vn = "\n".join("vn 0.0000 1.0000 0.0000" for _ in range(len(x)))
        name = f"part_{k:04d}"
        (folder / f"{name}.obj").write_text(
            f"# synthetic\nmtllib {name}.mtl\no {name}\n{v}\n{vt}\n{vn}\nusemtl m{k}\n{faces}\n")
        (folder / f"{name}.mtl").write_text(
            f"newmtl m{k}\nKd {rng.uniform():.6f} {rng.uniform():.6f} {rng.uniform():.6f}\n")
    centre = np.array([cells * 0.6, cells * 0.6, cells * 0.6])
    eye = centre + np.array([0.3, 0.5, 1.0]) * cells * 2.5
    (folder / "Camera.camera").write_text(" ".join(f"{x:.6f}" for x in (*eye, *centre)) + "\n")
    return Path(path)


def phase(name: str, scene: str, root: str, cache: str, bvh_format: str = DEFAULT_FORMAT) -> dict:
    """One phase in this process (module docstring); the times are from the process's start
    where ``RAYFLEX_T0`` gives it."""
    t_start = float(os.environ.get("RAYFLEX_T0", time.time()))
    wall0, cpu0 = min(_T_MODULE, time.time()), time.process_time()
    os.environ["RAYFLEX_SCENE_CACHE"] = cache
    t_imp = time.time()
    scene = lb.load(scene, root)
    t_load = time.time()
    bvh = DesignPoint(bvh_format=bvh_format).build(scene)     # as a run builds it
    t_build = time.time()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {"phase": name, "cached": scene.cached,
            "bvh_cached": bool(bvh.stats.get("from_cache")),
            "triangles": int(len(scene.triangles)),
            "models": len(scene.models), "start_s": wall0 - t_start,
            "import_s": t_imp - wall0, "load_s": t_load - t_imp, "build_s": t_build - t_load,
            "to_tracing_s": t_build - t_start, "cpu_s": time.process_time() - cpu0,
            "peak_rss_bytes": rss, "bvh_bytes": int(bvh.image.nbytes)}


def load_bench(scene: str, root, synthetic: tuple | None = None, bvh_format: str = DEFAULT_FORMAT,
               progress: bool = True) -> dict:
    """Both phases of ``scene`` from ``root`` in fresh processes, with a cache of their own;
    ``synthetic`` (files, triangles): measure a synthetic root instead (``synthetic_root``)."""
    with tempfile.TemporaryDirectory(prefix="rayflex-load-") as tmp:
        if synthetic:
            with show(f"writing {synthetic[0]:,} OBJ files of {synthetic[1]:,} triangles",
                      progress):
                root = synthetic_root(Path(tmp) / "root", *synthetic)
            scene = "lumibench:BATH"
        cache = str(Path(tmp) / "cache")
        out = {"scene": scene, "root": None if synthetic else str(root),
               "synthetic": None if not synthetic else {"files": synthetic[0],
                                                        "triangles": synthetic[1]},
               "bvh_format": bvh_format}
        for name in PHASES:
            with show(f"{name} load and build of {scene}", progress):
                out[name] = fresh_process("driver.load_bench",
                                          [name, scene, str(root), cache, bvh_format],
                                          f"scene-load phase {name}")
        return out


def fresh_process(module: str, args: list[str], what: str) -> dict:
    """Run ``python -m module args`` in a fresh process, which reports one JSON object on its
    last line of output and may time itself from ``RAYFLEX_T0`` (when it was started); returns
    that object, or raises RuntimeError with ``what`` and the process's last line of errors."""
    env = dict(os.environ, RAYFLEX_T0=repr(time.time()))
    r = subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True,
                       env=env)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"{what} failed: {last}")
    return json.loads(r.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    print(json.dumps(phase(*sys.argv[1:6])))
