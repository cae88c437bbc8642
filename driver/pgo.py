"""Training workload for the profile-guided build of the "rtl" harness library.

``driver.backends.verilate.build_library(train=...)`` compiles the harness instrumented, runs

    python -m driver.pgo '{"DISJOINT": 0, "EXTENDED": 0, "LATENCY": 11}' /path/to/librayflex_....so

and recompiles with the profile this run wrote. The workload is what the library is for, on scenes
other than the benchmark's: primary rays of an icosphere seen from outside and of the built-in room
seen from inside, traversed through the library (the wavefront fast path ``run_nodes`` and the
RT-unit replay ``rf_replay``), a slice of the same requests through ``run``, an ambient-occlusion
frame of the room replayed in one kernel (camera and any-hit rays interleaved, with the node memory,
and in warps on two RT units with an L2), and, for an EXTENDED
build, Euclidean and cosine distance jobs. Every result is checked against the golden model; the
build runs this on the instrumented library and again on the optimised one, so a library that
computes anything wrong fails the build instead of being cached. Deterministic; a few seconds.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import trimesh

from . import workloads
from .backends.golden import GoldenBackend
from .backends.harness import HarnessBackend, use_library
from .bvh4 import build
from .scenes.camera import frame, primary_rays
from .core.datapath import ANGULAR, EUCLIDEAN
from .knn import LANES, pad, run_jobs
from .rtunit import MemoryModel
from .rtunit.gpu import replay_frame, timing_differences, waves_of
from .rtunit.plan import Schedule
from .scenes.scene import load_scene
from .tracer import trace

# (mesh, image size): a convex object from outside, a closed room from inside
SCENES = (("icosphere", 96), ("room", 64))
RUN_SLICE = 4000           # requests of the first scene also streamed through run()
KNN_SHAPE = (32, 48, 61)   # queries, candidates, dimensions (not a multiple of any lane count)


class TrainingMismatch(RuntimeError):
    """The instrumented library disagrees with the golden model."""


def _scene(name: str):
    if name == "icosphere":
        mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
        return mesh, frame(mesh.vertices)
    scene = load_scene(name)
    return scene.mesh, scene.camera


def _check(what: str, ok: bool) -> None:
    if not ok:
        raise TrainingMismatch(f"PGO training: {what} differs from the golden model")


def train(params: dict[str, int]) -> dict:
    """Run the training workload on this process's harness library for ``params`` (see
    ``driver.backends.harness.use_library``); returns request counts. Raises TrainingMismatch on a wrong result."""
    opts = dict(extended=bool(params["EXTENDED"]), disjoint=bool(params["DISJOINT"]),
                latency=int(params["LATENCY"]), compressed=bool(params.get("COMPRESSED", 0)),
                transform=bool(params.get("TRANSFORM", 0)))
    counts = {"traversal": 0, "run": 0, "knn": 0}
    for i, (name, size) in enumerate(SCENES):
        mesh, cam = _scene(name)
        bvh = build(mesh)
        o, d = primary_rays(cam, size, size)
        ref = trace(bvh, o, d, backend="golden", record=i == 0)
        # rays_in_flight: the wavefront pass, then the RT-unit replay of it, checked bit for bit
        got = trace(bvh, o, d, backend=HarnessBackend(**opts), rays_in_flight=64)
        _check(f"{name} traversal", np.array_equal(got.prim, ref.prim)
               and np.array_equal(got.t.view(np.uint32), ref.t.view(np.uint32)))
        counts["traversal"] += int(got.record.ops)
        if i == 0:
            req = ref.record.requests(np.arange(min(RUN_SLICE, ref.record.ops)))
            rsp = HarnessBackend(**opts).run(req)
            _check("run()", rsp.tobytes() == GoldenBackend(**opts).run(req).tobytes())
            counts["run"] += len(req)
    counts["replay"] = _train_gpu_replay(opts)
    if opts["extended"]:
        rng = np.random.default_rng(1)
        nq, nc, dim = KNN_SHAPE
        q = rng.standard_normal((nq, dim)).astype(np.float32)
        c = rng.standard_normal((nc, dim)).astype(np.float32)
        qi, ci = (a.ravel() for a in np.meshgrid(np.arange(nq), np.arange(nc), indexing="ij"))
        for op in (EUCLIDEAN, ANGULAR):
            a, b = pad(q, LANES[op]), pad(c, LANES[op])
            got = run_jobs(HarnessBackend(**opts), op, a, b, qi, ci, dim)
            ref = run_jobs(GoldenBackend(**opts), op, a, b, qi, ci, dim)
            _check(f"knn opcode {op}", got.tobytes() == ref.tobytes())
            counts["knn"] += len(qi) * (a.shape[1] // LANES[op])
    return counts


def _train_gpu_replay(opts: dict) -> int:
    """The replay as commands run it (``driver.rtunit.gpu``): an ambient-occlusion frame of the
    room (camera rays and any-hit rays interleaved in one kernel) with the default node memory,
    and in warps of 8 on two units with MSHRs, sectors and an L2; each replayed on the model
    (every response checked against the traversal's) and as the pipelines' timing (every count
    and time checked against the model's). Returns the requests replayed."""
    scene = load_scene("room")
    be = HarnessBackend(**opts)
    res = workloads.run(workloads.setup_for(scene), build(scene.mesh), 32, 32,
                        lambda b, o, d, **k: trace(b, o, d, backend=be, record=True, **k), "ao",
                        ao_rays=2)
    waves = waves_of(res.batches)
    gpu = MemoryModel(cache_bytes=16384, ways=8, line_bytes=128, sector_bytes=32, hit_latency=4,
                      mshrs=16, l2_bytes=262144, l2_latency=40)
    for memory, schedule in ((MemoryModel(), Schedule("one-kernel")),
                             (gpu, Schedule("one-kernel", warp_size=8, rt_units=2))):
        fr = replay_frame(waves, 64, 1, memory, schedule, width=32, datapath="rtl")
        _check("RT-unit replay of a one-kernel frame", fr.verified)
        ft = replay_frame(waves, 64, 1, memory, schedule, width=32, datapath="timing")
        _check("RT-unit timing replay of a one-kernel frame", not timing_differences(fr, ft))
    return 2 * sum(w.record.ops for w in waves)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m driver.pgo PARAMS_JSON LIBRARY", file=sys.stderr)
        return 2
    params = {k: int(v) for k, v in json.loads(argv[0]).items()}
    use_library(params, argv[1])
    t0 = time.perf_counter()
    counts = train(params)
    print(f"PGO workload {params}: {counts}, {time.perf_counter() - t0:.1f} s, results = golden")
    return 0


if __name__ == "__main__":
    sys.exit(main())
