"""``rayflex suite``: a benchmark's runs, each on the RTL with every ray checked and replayed on
the RT unit (docs/lumibench.md).

A suite is a list of runs (``Run``: a name, a scene, a workload, a frame size and samples per
pixel). LumiBench is the built-in one (``lumibench_runs``): every scene x shader the given
repository can make, each at the benchmark's 128 x 128 and 2 samples per pixel, named like the
benchmark's logs (``BATH_AO``); ``read_suite`` reads any other list from a TOML file.

Every run (``execute``) loads its scene (a LumiBench scene from its cache after the first
time), builds its BVH, traces the frame on the backend with the design point's datapath, checks
every ray against Embree (adjudicated, ``driver.adjudicate``) and replays the frame on the
point's RT units (``rtunit_memory``; with ``ideal`` also with free node fetches, ``rtunit``;
docs/rtunit.md); on the RT unit in RTL (backend "rtunit") the unit times the frame itself
(``unit_rtl``, its replay compared: docs/rtunit_rtl.md). Runs are independent tasks: in this process, or on Dask workers
(``--workers``, ``--scheduler``, the cluster code of ``driver.tiles``), scene by scene, the
most expensive first (a worker keeps its last scene and BVH for its next run of that scene); a
suite of one run spreads that run's tiles over the workers instead. Each finished run is
written at once into the output folder as ``NAME.json`` (its statistics, docs/statistics.md)
and ``NAME.png`` (its image), atomically; a suite started again on the same folder skips every
run whose JSON was made by the same source tree with the same run and design point, so an
interrupted suite resumes where it stopped. At the end ``summary.json`` and ``summary.csv``
(one row per run: rays, ops per ray, RT-unit utilization with the node memory, bytes from
memory per ray, cache hit rate, energy per ray, the check's classes) and ``summary.png`` (those
figures per run, grouped by shader).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import shutil
import sys
import time
import uuid
from dataclasses import asdict, dataclass
from pathlib import Path

from PIL import Image

from . import suite_report
from .backends import unit_memo
from .backends.rtunit import UNIT_BACKEND
from .core.errors import RayflexError
from .core.outputs import jsonable
from .core.progress import bar as progress_bar
from .core.progress import phase
from .core.provenance import git_commit, provenance, rayflex_version
from .core.words import plural
from .design import clock_figures
from .lumibench_shaders import WORKLOADS
from .scenes import lumibench as lb
from .sweep import _box_op, energy_key, energy_per_ray, energy_tables
from .tiles import _client

SUITES = ("lumibench",)     # the built-in suites
SUMMARY = ("summary.json", "summary.csv", "summary.png", "images.png")
_RUN_KEYS = {"name", "scene", "workload", "size", "spp", "bounces", "ao_rays", "seed"}
_COST = {"lumibench-pt": 4.0, "path": 4.0, "lumibench-ao": 2.5, "ao": 2.5}   # order only


class SuiteError(RayflexError):
    """A bad suite: file, run list, or output folder (one line)."""


@dataclass(frozen=True)
class Run:
    """One run of a suite: ``name`` (its files' stem), ``scene``, ``workload``, and the
    workload options that differ from the design point's."""

    name: str
    scene: str
    workload: str
    size: int = 128
    spp: int = 2
    bounces: int | None = None
    ao_rays: int | None = None
    seed: int | None = None

    def point(self, base):
        """The design point of this run: ``base`` with the run's workload fields."""
        extra = {k: v for k, v in (("bounces", self.bounces), ("ao_rays", self.ao_rays),
                                   ("seed", self.seed)) if v is not None}
        return base.replace(scene=self.scene, workload=self.workload, size=self.size,
                            spp=self.spp, **extra)


def lumibench_runs(root=None, scenes=None, shaders=None) -> tuple[list[Run], dict]:
    """(runs, skipped): LumiBench's runs that ``root`` can make, restricted to ``scenes`` (IDs)
    and ``shaders`` (pt, sh, ao); ``skipped``: run or scene -> why not (one line each)."""
    shader_names = {w.split("-")[1]: w for w in WORKLOADS}
    wanted = None if shaders is None else [s.strip().lower() for s in shaders]
    for s in wanted or ():
        if s not in shader_names:
            raise SuiteError(f"--workloads: unknown shader {s!r}; LumiBench's: "
                             f"{', '.join(shader_names)}")
    ids = list(lb.DEFINITIONS) if scenes is None else [s.strip().upper() for s in scenes]
    for sid in ids:
        if sid not in lb.DEFINITIONS:
            raise SuiteError(f"--scenes: unknown LumiBench scene {sid!r}; scenes: "
                             f"{', '.join(lb.DEFINITIONS)}")
    why = lb.available(root)
    runs, skipped = [], {}
    for sid in ids:
        d = lb.DEFINITIONS[sid]
        if why[sid]:
            skipped[sid] = why[sid]
            continue
        for shader in d.shaders:
            if wanted is None or shader in wanted:
                runs.append(Run(f"{sid}_{shader.upper()}", f"{lb.PREFIX}{sid}",
                                shader_names[shader], lb.SIZE, lb.SPP))
    return runs, skipped


def read_suite(path) -> tuple[str, list[Run]]:
    """(name, runs) of a suite TOML file: optional top-level ``name`` and defaults ``size``,
    ``spp``, ``bounces``, ``ao_rays``, ``seed``; one ``[[runs]]`` table per run with ``scene``
    and ``workload`` (required), ``name`` (default SCENE_WORKLOAD) and any of the defaults'
    keys. Scene paths are relative to the file. One-line SuiteError for a bad file."""
    from .scenes.scene import _read_toml
    path = Path(path).expanduser()
    if not path.is_file():
        raise SuiteError(f"--suite {path}: no such file")
    data = _read_toml(path)
    top = {"name", "runs", *(_RUN_KEYS - {"name", "scene", "workload"})}
    unknown = set(data) - top
    if unknown:
        raise SuiteError(f"{path}: unknown key(s) {', '.join(sorted(unknown))}; allowed: "
                         f"{', '.join(sorted(top))}")
    specs = data.get("runs")
    if not isinstance(specs, list) or not specs:
        raise SuiteError(f"{path}: needs at least one [[runs]] table (scene, workload)")
    defaults = {k: v for k, v in data.items() if k in _RUN_KEYS - {"name"}}
    runs = []
    for i, spec in enumerate(specs):
        if not isinstance(spec, dict) or set(spec) - _RUN_KEYS:
            bad = sorted(set(spec) - _RUN_KEYS) if isinstance(spec, dict) else []
            raise SuiteError(f"{path}: runs[{i}]: unknown key(s) {', '.join(bad)}; allowed: "
                             f"{', '.join(sorted(_RUN_KEYS))}")
        spec = {**defaults, **spec}
        if not isinstance(spec.get("scene"), str) or not isinstance(spec.get("workload"), str):
            raise SuiteError(f"{path}: runs[{i}] needs scene and workload (strings)")
        scene = spec["scene"]
        local = path.parent / scene
        if ":" not in scene and ("/" in scene or "." in Path(scene).name) and local.exists():
            scene = str(local)
        name = spec.get("name") or _default_name(spec["scene"], spec["workload"])
        runs.append(Run(name, scene, spec["workload"], int(spec.get("size", 128)),
                        int(spec.get("spp", 2)), spec.get("bounces"), spec.get("ao_rays"),
                        spec.get("seed")))
    names = [r.name for r in runs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise SuiteError(f"{path}: two runs named {dup[0]} (give each a name)")
    bad = [n for n in names if not n or any(c in n for c in '/\\:*?"<>|') or n.startswith(".")]
    if bad:
        raise SuiteError(f"{path}: run name {bad[0]!r} is not a file name")
    return str(data.get("name") or path.stem), runs


def _default_name(scene: str, workload: str) -> str:
    stem = scene.split(":", 1)[1] if ":" in scene else Path(scene).stem
    return f"{stem}_{workload.removeprefix('lumibench-').upper()}"


def check_runs(runs: list[Run], base) -> list:
    """Every run's design point, checked before any work (one-line errors)."""
    points = []
    for r in runs:
        try:
            points.append(r.point(base))
        except ValueError as e:
            raise SuiteError(f"run {r.name}: {e}") from None
    return points


# ---------------------------------------------------------------------------------------------
# one run

def key(run: Run, point, backend: str) -> str:
    """What makes a run's result: the run, its design point, the backend and the source tree."""
    text = json.dumps([asdict(run), point.as_dict(), backend, rayflex_version(), git_commit()],
                      sort_keys=True, default=str)
    return hashlib.blake2b(text.encode(), digest_size=12).hexdigest()


MEMO_DIR = ".unit-batches"   # in the output folder: the unit's batches the runs share, until done
SPLIT_TILE = 128       # the tile of a run whose tiles are spread over the workers


def execute(run: Run, point, backend: str = "rtl", root=None, ideal: bool = False,
            energy: dict | None = None, workers: int = 1,
            scheduler: str | None = None, memo: str | None = None) -> tuple[dict, bytes]:
    """Trace, check and replay one run (a task: pure in its inputs); returns its JSON document
    and its PNG image bytes. The frame is one tile in this process, or with ``workers`` > 1 or
    a ``scheduler`` tiles of ``SPLIT_TILE`` on the Dask cluster (a suite of one run). ``memo``:
    the folder of the RT unit's batches the suite's runs share (``unit_memo``)."""
    from .render import render
    from .scenes.scene import load_scene
    t0 = time.perf_counter()
    with lb.using_root(root):       # partial scenes are reported once, by the summary
        scene = _scene(point.scene, load_scene)
    t_load = time.perf_counter() - t0
    split = workers > 1 or bool(scheduler)
    with unit_memo.memo(memo) if memo else contextlib.nullcontext():
        res = render(scene, point.size, point.size, backend=backend, progress=False,
                     check_embree=True, point=point,
                     rtunit=backend != UNIT_BACKEND and ("ideal" if ideal else True),
                     tile=SPLIT_TILE if split else max(point.size, 1),
                     workers=workers, scheduler=scheduler)
    stats = res.stats
    if energy:
        _add_energy(stats, energy)
    info = scene.info() if hasattr(scene, "info") else {}
    doc = {"provenance": provenance(point), "run": asdict(run), "key": key(run, point, backend),
           "scene": scene.name, "width": point.size, "height": point.size,
           **({"lumibench": info} if info else {}), **stats,
           "clock": clock_figures(point, stats),
           "timing": _timing(stats, t_load, time.perf_counter() - t0, scene)}
    buf = io.BytesIO()
    Image.fromarray(res.image).save(buf, format="PNG")
    return doc, buf.getvalue()


_LAST: dict = {}     # this process's last LumiBench scene: its runs of other shaders reuse it


def _scene(name: str, load_scene):
    """The scene of a run. A LumiBench scene is kept for this process's next run of the same
    scene (the suite makes a scene's shaders one after another), with what is built from its
    triangles: the Embree scene of the check (``driver.check``)."""
    if not lb.is_lumibench(name):
        return load_scene(name)
    t0 = time.perf_counter()
    key = lb.key_of(name)
    last = _LAST.get(key)
    if key and last is not None:
        last.load_s = time.perf_counter() - t0
        return last
    scene = lb.load(name)
    _LAST.clear()
    if scene.cache_key:
        _LAST[scene.cache_key] = scene
    return scene


def _timing(stats: dict, load_s: float, wall_s: float, scene) -> dict:
    """Where a run's wall time went: loading the scene, building its BVH, and the rest (the
    trace on the datapath, the Embree check, the RT-unit replay, shading): ``rays_per_s`` is
    the rays over that rest, the run's speed end to end outside loading and BVH build."""
    build = float((stats.get("bvh") or {}).get("build_s", 0.0))
    trace = max(wall_s - load_s - build, 1e-9)
    return {"load_s": load_s, "bvh_build_s": build, "trace_s": trace, "wall_s": wall_s,
            "rays_per_s": stats.get("rays", 0) / trace,
            "scene_cached": bool(getattr(scene, "cached", False))}


def _add_energy(stats: dict, energy: dict) -> None:
    """``energy_per_ray`` of the frame and each ray type, as a sweep gives it (by level:
    ``signals``; ``gates`` null), from the configuration's energy per op
    (``driver.sweep.energy_per_ray``)."""
    table = energy.get("table")
    bop = energy.get("box_op", "box")
    for s in [stats, *stats.get("by_type", {}).values()]:
        s["energy_per_ray"] = {"signals": energy_per_ray(s, table, bop), "gates": None}


# ---------------------------------------------------------------------------------------------
# the suite

def done_runs(out: Path, runs: list[Run], points: list, backend: str) -> dict:
    """{run name: its document} of the runs already made in ``out`` by this source tree."""
    done = {}
    for r, p in zip(runs, points):
        path = out / f"{r.name}.json"
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(doc, dict) and doc.get("key") == key(r, p, backend) \
                and (out / f"{r.name}.png").is_file():
            done[r.name] = doc
    return done


def run_suite(name: str, runs: list[Run], base, out, backend: str = "rtl", root=None,
              workers: int = 1, scheduler: str | None = None, ideal: bool = False,
              skipped: dict | None = None, progress: bool = True) -> dict:
    """Make every run not already in ``out`` (module docstring); returns the summary.
    ``root``: the LumiBench repository (default: ``driver.scenes.lumibench.root()``)."""
    with lb.using_root(root):
        return _run_suite(name, runs, base, out, backend, root, workers, scheduler, ideal,
                          skipped, progress)


def _run_suite(name, runs, base, out, backend, root, workers, scheduler, ideal, skipped,
               progress) -> dict:
    t0 = time.perf_counter()
    out = Path(out)
    points = check_runs(runs, base)
    out.mkdir(parents=True, exist_ok=True)
    done = done_runs(out, runs, points, backend)
    todo = [(r, p) for r, p in zip(runs, points) if r.name not in done]
    cost = {r.name: _cost(r, p, root) for r, p in todo}
    per_scene: dict = {}
    for r, _ in todo:
        per_scene[r.scene] = per_scene.get(r.scene, 0.0) + cost[r.name]
    todo = _order(todo, cost, per_scene, backend == UNIT_BACKEND)
    if progress:
        print(f"rayflex: suite {name}: {plural(len(runs), 'run')}, {len(done)} already in {out}, "
              f"{len(todo)} to make", file=sys.stderr, flush=True)
    with phase("energy per op (level signals)", progress):
        energy = _energy(base)
    bar = progress_bar(len(todo), f"suite {name}", "run", progress)
    bar.hook(0, len(todo))
    memo = out / MEMO_DIR if backend == UNIT_BACKEND else None
    for n, (r, doc, png) in enumerate(_execute_all(todo, backend, root, ideal, energy,
                                                   workers, scheduler, memo), 1):
        _write_run(out, r.name, doc, png)
        done[r.name] = doc
        bar.hook(n, len(todo))
        if progress:
            bar.set_postfix_str(f"{r.name} {doc['timing']['wall_s']:.1f} s")
    bar.close()
    if memo is not None:              # every run made: its shared batches are not needed again
        shutil.rmtree(memo, ignore_errors=True)
    summary = suite_report.summary(name, runs, done, skipped or {}, base, backend, root,
                       time.perf_counter() - t0, len(todo), workers, scheduler)
    suite_report.write_summary(out, summary)
    return summary


def _cost(run: Run, point, root) -> float:
    """A guess of a run's cost, to start the most expensive first (the suite's wall time is
    the longest worker's): the workload's rays per sample, the pixels and samples, and the
    log of the scene's size on disk (LumiBench scenes: their OBJ files)."""
    size = 1.0
    if lb.is_lumibench(run.scene):
        try:
            d = lb.definition(run.scene)
            base = lb.root(root) / d.path
            files = base.glob("*.obj") if base.is_dir() else [base]
            size = float(sum(f.stat().st_size for f in files))
        except (ValueError, OSError):
            pass
    return (_COST.get(run.workload, 1.0) * point.size ** 2 * point.spp
            * math.log10(10.0 + size))


def _energy(base) -> dict:
    """Energy per op of the design point's configuration (``driver.sweep.energy_tables``)."""
    tables = energy_tables([base], progress=False)
    return {"table": tables[energy_key(base.config, base.latency)]["signals"],
            "box_op": _box_op(base)}


def _order(todo: list, cost: dict, per_scene: dict, unit: bool) -> list:
    """The runs in the order they are handed out: the most expensive scene's runs first, its
    longest run first, so that a worker that finishes a run of a scene takes the next run of
    the same scene (and keeps the scene and its BVH). Through the RT unit in RTL (``unit``),
    whose runs of a scene share their camera rays' batch (``unit_memo``), each scene's longest
    run first, then the others: a scene's second run starts after its first has traced the
    camera rays, while the other worker makes other scenes' runs."""
    todo = sorted(todo, key=lambda rp: (-per_scene[rp[0].scene], -cost[rp[0].name]))
    if not unit:
        return todo
    first, seen = [], set()
    for r, p in todo:
        if r.scene not in seen:
            seen.add(r.scene)
            first.append((r, p))
    rest = sorted((rp for rp in todo if rp not in first), key=lambda rp: -cost[rp[0].name])
    return first + rest


def _execute_all(todo, backend, root, ideal, energy, workers, scheduler, memo=None):
    """(run, document, png) of every run to make, in this process or on Dask (``memo``: the
    folder of the RT unit's batches the runs share, ``execute``)."""
    if not todo:
        return
    memo = str(memo) if memo is not None else None
    if len(todo) == 1 or (workers == 1 and not scheduler):     # one run: its tiles spread
        for r, p in todo:
            doc, png = execute(r, p, backend, root, ideal, energy, workers, scheduler, memo)
            yield r, doc, png
        return
    with _client(workers, scheduler) as client:
        sid = uuid.uuid4().hex[:12]
        futures = {client.submit(execute, r, p, backend, str(root) if root else None, ideal,
                                 energy, memo=memo, key=f"rayflex-suite-{sid}-{i}", retries=2): r
                   for i, (r, p) in enumerate(todo)}
        from distributed import as_completed
        try:
            for fut in as_completed(futures):
                doc, png = fut.result()
                yield futures[fut], doc, png
        finally:
            client.cancel(list(futures))


def _write_run(out: Path, name: str, doc: dict, png: bytes) -> None:
    """NAME.png then NAME.json, each atomically (the JSON last: it marks the run done)."""
    for path, data in ((out / f"{name}.png", png),
                       (out / f"{name}.json",
                        (json.dumps(jsonable(doc), indent=1) + "\n").encode())):
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_bytes(data)
        tmp.replace(path)
