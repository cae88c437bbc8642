"""The builders on generated and on every reachable mesh, under a watchdog.

Property-based (hypothesis): meshes of random topology (``support.corpus``: non-manifold edges
shared by 3 or more triangles, duplicate and flipped triangles, zero-area and repeated-vertex
triangles, isolated vertices, T-junctions, huge and tiny coordinates, disconnected soups),
built in every format: each build ends within a per-triangle time bound, every node contains
its children, every triangle is in exactly one leaf reached from the root, and the hits of rays
at the mesh equal box32's. Then every mesh the repository reaches: the scenes, the meshes the
tests write and the mesh files of the packages it installs. Every build runs in the watchdog's
worker (``support.watchdog``): a hang is a failure naming the phase, not a suite that never
ends. The default run draws 75 meshes and skips the reachable meshes that only repeat the
bunny (``SLOW_REACHABLE``); ``-m slow`` draws thousands, 10,000 through the q8 encoders, and
checks every reachable mesh.
"""

from __future__ import annotations

import importlib.resources
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from support import corpus, meshes
from support.watchdog import Watchdog

BOUND_S = 60.0            # s per mesh and check, plus BOUND_PER_TRI_S per triangle: a hang
BOUND_PER_TRI_S = 2e-4    # bound, far above the build's time on a loaded machine
SETTINGS = dict(deadline=None, derandomize=True, database=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def bound(n: int) -> float:
    return BOUND_S + BOUND_PER_TRI_S * n


@pytest.fixture(scope="module")
def watchdog():
    dog = Watchdog()
    # the first call loads every kernel (compiles them on a fresh machine)
    dog.call(900, corpus.check_mesh, corpus.random_spec(np.random.default_rng(0)))
    yield dog
    dog.close()


def test_the_watchdog_names_the_phase_of_a_hang(watchdog):
    t0 = time.monotonic()
    with pytest.raises(AssertionError, match="still in phase 'spinning'"):
        watchdog.call(2.0, corpus.spin)
    assert time.monotonic() - t0 < 30
    assert watchdog.call(60, corpus.check_mesh, mesh=corpus.generate(
        corpus.random_spec(np.random.default_rng(1))), formats=("q8",))["triangles"] > 0


def test_the_mesh_whose_matching_looped(watchdog):
    """Nine triangles on five vertices, every edge shared by 3 to 5 of them: the q8 matching
    never ended on it (tests/test_q8_image.py has the unit tests of the cause)."""
    v = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)], np.float32)
    f = np.array([[0, 1, 2], [3, 1, 0], [3, 0, 4], [2, 0, 3], [4, 0, 1], [1, 2, 4], [0, 2, 3],
                  [3, 1, 0], [1, 3, 2]])
    watchdog.call(bound(9), corpus.check_mesh, mesh=(v, f))


@settings(max_examples=15, **SETTINGS)
@given(spec=corpus.spec_strategy())
def test_generated_meshes_build_check_and_hit_as_box32(watchdog, spec):
    watchdog.call(bound(2000), corpus.check_mesh, spec)


@settings(max_examples=60, **SETTINGS)
@given(spec=corpus.spec_strategy())
def test_generated_meshes_build_and_check(watchdog, spec):
    watchdog.call(bound(2000), corpus.check_mesh, spec, n_rays=0)


@pytest.mark.slow
@settings(max_examples=3000, **SETTINGS)
@given(spec=corpus.spec_strategy())
def test_many_generated_meshes_build_check_and_hit_as_box32(watchdog, spec):
    watchdog.call(bound(2000), corpus.check_mesh, spec)


@pytest.mark.slow
def test_ten_thousand_generated_meshes_through_the_q8_encoders(watchdog):
    """10,000 meshes drawn with numpy (``corpus.random_spec``) built q8 and q8g and checked;
    prints the worst pairing time per triangle (the benchmark of docs/bvh.md)."""
    from driver.studies.bvh import PAIRING
    rng = np.random.default_rng(2024)
    worst, sizes = {}, []
    for i in range(10_000):
        spec = corpus.random_spec(rng)
        out = watchdog.call(bound(2000), corpus.check_mesh, spec, formats=("q8", "q8g"),
                            n_rays=0, cpu=True)
        n = out["triangles"]
        sizes.append(n)
        for fmt in ("q8", "q8g"):
            for clock in ("wall", "cpu"):
                times = out[fmt][clock]
                for what, keys in (("matching", ("matching",)), ("pairing", PAIRING)):
                    us = 1e6 * sum(times[k] for k in keys) / n
                    key = f"{fmt} {what} {clock}"
                    if us > worst.get(key, (0,))[0]:
                        worst[key] = (round(us, 3), n, i)
    print(f"10,000 meshes of {min(sizes)} to {max(sizes)} triangles (median "
          f"{int(np.median(sizes))}); worst microseconds per triangle (value, triangles, mesh):")
    for key, value in sorted(worst.items()):
        print(f"  {key}: {value}")


# ----------------------------------------------------------------------------------------------
# every mesh the repository reaches


# the reachable meshes that repeat the bunny, checked with -m slow only: bunny_grid's BLASes are the
# bunny and a floor quad (and loading it flattens 21 bunnies: ~15 s), bunny_floor is the bunny
# on that floor, city's first BLAS the bunny again
SLOW_REACHABLE = ("bunny_grid", "bunny_floor", "city[0]")


def _reachable(every: bool = True):
    """(name, (vertices, faces)) of every mesh the scenes, the tests' meshes and the installed
    packages' mesh files give (``every=False``: not those of ``SLOW_REACHABLE``)."""
    import trimesh

    from driver.scenes.scene import available, load_scene
    out = []
    for name in available():
        if not every and name in SLOW_REACHABLE:
            continue
        scene = load_scene(name)
        inst = scene.instances
        if inst is None:
            m = scene.mesh
            out.append((name, (np.asarray(m.vertices, np.float32), np.asarray(m.faces))))
        else:
            for j, tris in enumerate(inst.meshes):
                if every or f"{name}[{j}]" not in SLOW_REACHABLE:
                    out.append((f"{name}[{j}]", _soup(tris)))
    for name, tris in (("soup", meshes.soup(300, seed=9)), ("room", meshes.box_room(3)),
                       ("icosphere", meshes.icosphere(3)), ("degenerate", meshes.degenerate())):
        out.append((f"tests:{name}", _soup(tris)))
    b = meshes.bricks()                        # a LEGO-like model: the old matching looped
    out.append(("tests:bricks", (np.asarray(b.vertices, np.float32), np.asarray(b.faces))))
    for pkg in ("pymeshfix",):
        root = importlib.resources.files(pkg)
        for path in sorted(root.rglob("*")) if hasattr(root, "rglob") else []:
            if path.suffix.lower() in (".ply", ".obj", ".stl", ".off", ".glb", ".gltf"):
                m = trimesh.load(str(path), force="mesh", process=False)
                out.append((f"{pkg}:{path.name}",
                            (np.asarray(m.vertices, np.float32), np.asarray(m.faces))))
    return out


def _soup(tris):
    tris = np.asarray(tris, np.float32)
    return tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3)


def _check_reachable(watchdog, every: bool) -> None:
    found = _reachable(every)
    names = [n for n, _ in found]
    assert "bunny" in names and any(n.startswith("pymeshfix:") for n in names)
    assert any(n.startswith("city[") for n in names) and "tests:bricks" in names
    assert every or not set(SLOW_REACHABLE) & set(names)
    seen = set()
    for name, mesh in found:
        key = hash(mesh[0][mesh[1]].tobytes())          # the same triangles under two names
        if key in seen:
            continue
        seen.add(key)
        n = len(mesh[1])
        try:
            watchdog.call(bound(n), corpus.check_mesh, mesh=mesh, n_rays=64)
        except AssertionError as e:
            raise AssertionError(f"{name}: {e}") from None


def test_every_reachable_mesh_in_every_format(watchdog):
    _check_reachable(watchdog, every=False)


@pytest.mark.slow
def test_every_reachable_mesh_in_every_format_with_the_bunny_copies(watchdog):
    _check_reachable(watchdog, every=True)


def test_two_level_scenes_in_every_format(watchdog, tmp_path):
    """The instanced scenes (and a glTF that places one mesh three times) as two-level images:
    every format builds, and q8/q8g hit as box32 does."""
    path = meshes.reuse_glb(tmp_path / "reuse.glb")
    for name in ("city", str(path)):
        watchdog.call(bound(300_000), corpus.check_two_level, name)


@pytest.mark.slow
def test_the_bunny_grid_as_two_level_images_in_every_format(watchdog):
    """bunny_grid (its load flattens 21 bunnies: ~15 s; in the default run
    tests/test_instances.py checks a small grid of the same construction in q8 against box32)."""
    watchdog.call(bound(300_000), corpus.check_two_level, "bunny_grid")
