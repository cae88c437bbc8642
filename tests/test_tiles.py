"""Frames as tiles, alone and on a real Dask LocalCluster (driver.tiles)."""

import os
import signal
import socket

import numpy as np
import pytest

from driver import tiles, workloads
from driver.bvh4 import build
from driver.scenes.scene import load_scene

OPTS = dict(spp=2, bounces=2, seed=5)
SAME = ("rays", "hits", "box_ops", "tri_ops", "ops", "node_bytes_fetched")


@pytest.fixture(scope="module")
def scene():
    b = load_scene("bunny_floor")
    return workloads.setup_for(b), build(b.triangles)


@pytest.fixture(scope="module")
def whole(scene):
    setup, bvh = scene
    return tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=10 ** 6,
                              check_embree=True)


def same_frame(a, b, cycles=True):
    assert np.array_equal(a.radiance, b.radiance)
    assert a.ops.keys() == b.ops.keys()
    for k in a.ops:
        assert np.array_equal(a.ops[k], b.ops[k])
    keys = SAME + (("cycles", "utilization") if cycles else ())
    assert {k: a.stats[k] for k in keys} == {k: b.stats[k] for k in keys}
    for kind in a.stats["by_type"]:
        sa, sb = a.stats["by_type"][kind], b.stats["by_type"][kind]
        assert {k: sa[k] for k in keys} == {k: sb[k] for k in keys}
    assert a.stats.get("embree") == b.stats.get("embree")


def test_plan_covers_every_pixel_once():
    for w, h, t in ((40, 30, 16), (7, 5, 64), (64, 64, 64), (65, 1, 8)):
        px = np.concatenate(tiles.plan(w, h, t))
        assert np.array_equal(np.sort(px), np.arange(w * h))
    with pytest.raises(ValueError, match="--tile"):
        tiles.plan(8, 8, 0)


@pytest.mark.parametrize("tile", [7, 16])
def test_tiles_alone_make_the_whole_frame(scene, whole, tile):
    setup, bvh = scene
    part = tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=tile,
                              check_embree=True)
    same_frame(whole, part, cycles=False)       # cycles: one wavefront per tile (see driver.tiles)
    assert whole.stats["embree"]["hit_mismatch"] == 0


def test_two_workers_give_the_frame_of_one(scene):
    setup, bvh = scene
    one = tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=16)
    seen = []
    two = tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=16, workers=2,
                             progress=lambda d, n: seen.append((d, n)))
    same_frame(one, two)
    assert seen[-1] == (6, 6)


def _worker_env():
    return (os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS"),
            os.environ.get("RAYFLEX_THREADS"))


def test_local_workers_keep_glibc_adaptive_malloc(monkeypatch):
    # Dask's default MALLOC_TRIM_THRESHOLD_ made every tile 1.2-1.4x slower (page faults);
    # a cluster made earlier in this process may have leaked it into os.environ: clear it here
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    with tiles._client(1, None) as client:
        (env,) = client.run(_worker_env).values()
    assert env == (None, "1", "1")     # Dask's other worker settings stay; one model each


def test_a_killed_worker_changes_nothing(scene):
    from distributed import LocalCluster
    setup, bvh = scene
    one = tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=8)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        pids = [nanny.pid for nanny in cluster.workers.values()]     # the worker processes
        assert all(pids)
        killed = []

        def progress(done, total):
            if done == 3 and not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        two = tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=8,
                                 scheduler=cluster.scheduler_address, progress=progress)
    assert killed
    same_frame(one, two)


@pytest.mark.parametrize("backend", ["golden", "rtl"])
def test_tiles_on_threads_give_the_frame_of_one_thread(scene, monkeypatch, backend):
    """Tiles traced on threads (one backend each) and merged as they finish: the same frame,
    with the RT-unit replay of every tile, as one thread tracing them in order."""
    from driver.design import DesignPoint
    setup, bvh = scene
    opts = dict(OPTS, rtunit=DesignPoint(rays_in_flight=16), width=24)
    frames = {}
    for threads in ("1", "3"):
        monkeypatch.setenv("RAYFLEX_THREADS", threads)
        assert tiles.tile_lanes(backend, 9) == int(threads)
        seen = []
        frames[threads] = tiles.render_tiles(setup, bvh, 24, 24, "path", opts, backend,
                                             tile=8, check_embree=True,
                                             progress=lambda d, n: seen.append(d))
        assert seen == list(range(1, 10))
    one, three = frames["1"], frames["3"]
    same_frame(one, three)
    for key in ("cycles", "frame_cycles", "bytes_from_memory", "latency_mean"):
        assert one.stats["rtunit_memory"][key] == three.stats["rtunit_memory"][key]
    assert tiles.tile_lanes(("pyverilator", {}), 9) == 1 and tiles.tile_lanes(object(), 9) == 1


def test_an_error_on_a_thread_stops_the_other_tiles(scene, monkeypatch):
    import threading
    setup, bvh = scene
    monkeypatch.setenv("RAYFLEX_THREADS", "2")
    real, calls = tiles.run, []

    def run(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise ValueError("a tile failed")
        return real(*a, **k)

    monkeypatch.setattr(tiles, "run", run)
    before = threading.active_count()
    with pytest.raises(ValueError, match="a tile failed"):
        tiles.render_tiles(setup, bvh, 40, 30, "path", OPTS, "golden", tile=8)
    assert len(calls) < 20                       # 20 tiles: the frame stopped early
    assert threading.active_count() == before        # the pool's threads are gone


def test_an_error_in_a_tile_stops_the_frame(scene):
    setup, bvh = scene
    with pytest.raises(ValueError, match="unknown backend"):
        tiles.render_tiles(setup, bvh, 16, 16, "path", OPTS, "no-such-backend", tile=8,
                           workers=2)


def test_a_scheduler_that_does_not_answer_is_a_one_line_error(scene, monkeypatch):
    setup, bvh = scene
    monkeypatch.setattr(tiles, "CONNECT_TIMEOUT", "1s")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]            # a free port: nothing listens there
    address = f"tcp://127.0.0.1:{port}"
    with pytest.raises(OSError, match=f"no Dask scheduler answers at {address}"):
        tiles.render_tiles(setup, bvh, 16, 16, "path", OPTS, "golden", scheduler=address)


def test_the_check_set_up_thread_fails_quietly(monkeypatch, capfd):
    """The check's set-up on a side thread leaves a failure to the check itself (which reports
    it as a one-line error): nothing printed from the thread."""
    from driver import check

    def broken(triangles):
        raise OSError("no Embree here")

    monkeypatch.setattr(check, "_embree_scene", broken)
    thread = check.prepare_check(np.zeros((2, 3, 3), np.float32))
    thread.join(timeout=60)
    assert not thread.is_alive()
    assert capfd.readouterr().err == ""
