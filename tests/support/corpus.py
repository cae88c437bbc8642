"""Generated geometry for the builders: meshes of random topology and the checks every format
must pass on them (tests/test_geometry_corpus.py).

A mesh is made from a ``spec`` (a dict of small numbers, which hypothesis draws and shrinks, or
a seeded generator fills, ``random_spec``) by ``generate``: a random surface over a small pool
of vertices (so edges are shared, often by three or more triangles), then, as the spec asks,
fans of triangles around one edge (non-manifold edges), duplicated and flipped triangles,
zero-area triangles (a repeated vertex, a point, three collinear vertices), isolated vertices,
T-junctions, disconnected copies at other places and scales, integer-lattice coordinates
(coplanar, axis-aligned and coincident geometry) and huge or tiny coordinates. It is built from
triangles or as a mesh (vertex rows shared or one row per corner).

``check_mesh`` builds it in every format and checks: box32 every image invariant
(``support.images.check_bvh``: every node contains its children, every triangle in exactly one
leaf reached from the root), q8 and q8g the containment of every node's decoded child boxes and
every triangle in exactly one leaf reached from the root (``support.images.check_image``), and
the hits of rays at the mesh equal box32's (t bit for bit; the primitive too except between
triangles hit at the same t). It runs in the watchdog's worker (``support.watchdog``) and
reports its phases.
"""

from __future__ import annotations

import time

import numpy as np

FORMATS = ("box32", "q8", "q8g")
SCALES = (1.0, 1e-30, 1e30, 1e-3, 1e4, 0.0)      # 0.0: clusters at mixed scales
_LIMITS = {"n_base": (1, 60), "pool": (3, 24), "fans": (0, 3), "fan_size": (3, 12),
           "dups": (0, 6), "flips": (0, 6), "degenerate": (0, 6), "isolated": (0, 5),
           "tjunctions": (0, 3), "clusters": (1, 3)}


def random_spec(rng: np.random.Generator) -> dict:
    """A spec drawn with numpy (the many-mesh runs), in the ranges hypothesis draws from."""
    spec = {k: int(rng.integers(lo, hi + 1)) for k, (lo, hi) in _LIMITS.items()}
    spec.update(seed=int(rng.integers(0, 2 ** 32)), scale=float(rng.choice(SCALES)),
                lattice=bool(rng.integers(2)), mesh_input=bool(rng.integers(2)),
                split_rows=bool(rng.integers(2)), double_sided=bool(rng.integers(2)))
    return spec


def spec_strategy():
    """The hypothesis strategy of specs."""
    from hypothesis import strategies as st
    fields = {k: st.integers(lo, hi) for k, (lo, hi) in _LIMITS.items()}
    fields.update(seed=st.integers(0, 2 ** 32 - 1), scale=st.sampled_from(SCALES),
                  lattice=st.booleans(), mesh_input=st.booleans(), split_rows=st.booleans(),
                  double_sided=st.booleans())
    return st.fixed_dictionaries(fields)


def generate(spec: dict) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (k, 3) float32, faces (n, 3) int64) of ``spec`` (module docstring)."""
    rng = np.random.default_rng(spec["seed"])
    pool = spec["pool"]
    if spec["lattice"]:
        verts = [rng.integers(-2, 3, (pool, 3)).astype(np.float64)]
    else:
        verts = [rng.normal(size=(pool, 3))]
    nv = pool

    def add(points) -> np.ndarray:
        nonlocal nv
        points = np.atleast_2d(np.asarray(points, np.float64))
        verts.append(points)
        nv += len(points)
        return np.arange(nv - len(points), nv)

    faces = [rng.integers(0, pool, (spec["n_base"], 3))]      # repeated ids: degenerate too
    for _ in range(spec["fans"]):                              # k triangles on one edge
        a, b = rng.choice(pool, 2, replace=False)
        k = spec["fan_size"]
        c = add(verts[0][a] + rng.normal(size=(k, 3)))
        flip = rng.integers(2, size=k).astype(bool)
        faces.append(np.where(flip[:, None], np.stack([np.full(k, b), np.full(k, a), c], 1),
                              np.stack([np.full(k, a), np.full(k, b), c], 1)))
    allf = np.concatenate(faces)
    if spec["dups"]:
        faces.append(allf[rng.integers(0, len(allf), spec["dups"])])
    if spec["flips"]:
        faces.append(allf[rng.integers(0, len(allf), spec["flips"])][:, [0, 2, 1]])
    for i in range(spec["degenerate"]):
        a, b = rng.choice(pool, 2, replace=False)
        kind = i % 3
        if kind == 0:
            faces.append(np.array([[a, a, b]]))                # repeated vertex
        elif kind == 1:
            faces.append(np.array([[a, a, a]]))                # a point
        else:
            m = add(0.5 * (verts[0][a] + verts[0][b]))[0]      # collinear
            faces.append(np.array([[a, m, b]]))
    for _ in range(spec["tjunctions"]):                        # a vertex on another's edge
        a, b, c = rng.choice(pool, 3, replace=False)
        m, d = add([0.5 * (verts[0][a] + verts[0][b]),
                    verts[0][c] + rng.normal(size=3)])
        faces.append(np.array([[a, b, c], [a, m, d], [m, b, d]]))
    if spec["isolated"]:
        add(rng.normal(size=(spec["isolated"], 3)) * 3)
    v = np.concatenate(verts)
    f = np.concatenate(faces).astype(np.int64)
    if spec["scale"]:
        v *= spec["scale"]
    vs, fs = [v], [f]
    for c in range(1, spec["clusters"]):                       # disconnected copies
        scale = spec["scale"] or 10.0 ** rng.integers(-4, 5)
        vs.append(v * (scale / (spec["scale"] or 1.0)) + rng.normal(size=3) * 10 * scale)
        fs.append(f + c * len(v))
    v = np.concatenate(vs).astype(np.float32)
    f = np.concatenate(fs)
    if spec["split_rows"]:                                     # one vertex row per corner
        v, f = v[f].reshape(-1, 3), np.arange(3 * len(f)).reshape(-1, 3)
    return v, f


def rays(tris: np.ndarray, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n rays at the mesh (float64): half from random points around it towards random points of
    its triangles (most of them hit), half in random directions."""
    rng = np.random.default_rng(seed)
    t = tris.astype(np.float64)
    lo, hi = t.reshape(-1, 3).min(0), t.reshape(-1, 3).max(0)
    ext = np.maximum(hi - lo, np.abs(hi).max() * 1e-3 + 1e-30)
    o = rng.uniform(lo - 0.5 * ext, hi + 0.5 * ext, (n, 3))
    w = rng.dirichlet((1, 1, 1), n // 2)
    target = np.einsum("nk,nkc->nc", w, t[rng.integers(0, len(t), n // 2)])
    d = np.concatenate([target - o[:n // 2], rng.normal(size=(n - n // 2, 3))])
    bad = ~(np.abs(d) > 0).any(1) | ~np.isfinite(d.astype(np.float32)).all(1)
    d[bad] = (1.0, 0.0, 0.0)
    return o, d


def check_mesh(spec: dict | None = None, mesh=None, formats=FORMATS, n_rays: int = 64,
               cpu: bool = False, on_phase=None) -> dict:
    """Build the mesh of ``spec`` (or ``mesh``: (vertices, faces)) in ``formats`` and check it
    (module docstring). Returns {"triangles": n, format: the build's ``phase_s``, or with
    ``cpu`` {"wall": ``phase_s``, "cpu": ``phase_cpu_s``}}."""
    from driver.bvh4 import build
    from driver.tracer import trace
    from support.images import check_bvh, check_image

    on_phase = on_phase or (lambda name: None)
    on_phase("generate")
    v, f = generate(spec) if mesh is None else mesh
    tris = v[f]
    mesh_input = spec is None or spec["mesh_input"]
    if mesh_input:
        import trimesh
        src = trimesh.Trimesh(v, f, process=False, validate=False)
    else:
        src = tris
    out, built = {"triangles": len(tris)}, {}
    for fmt in formats:
        def phase(name, fmt=fmt):
            on_phase(f"{fmt} build: {name}")
        bvh = build(src, format=fmt, on_phase=phase, progress=False)
        on_phase(f"{fmt} image check")
        if fmt == "box32":
            check_bvh(bvh)
        else:
            check_image(bvh, tris)
        built[fmt] = bvh
        out[fmt] = ({"wall": bvh.stats["phase_s"], "cpu": bvh.stats["phase_cpu_s"]} if cpu
                    else bvh.stats["phase_s"])
    if "box32" in built and n_rays:
        on_phase("trace")
        o, d = rays(tris, n_rays, spec["seed"] if spec else 0)
        ds = bool(spec and spec["double_sided"])
        ref = trace(built["box32"], o, d, backend="golden", double_sided=ds)
        for fmt in formats:
            if fmt != "box32":
                on_phase(f"{fmt} trace")
                same_hits(ref, trace(built[fmt], o, d, backend="golden", double_sided=ds))
    return out


def same_hits(a, b) -> int:
    """Assert that trace results a and b hit the same rays at the same t, bit for bit, and the
    same primitive except between triangles hit at one t; returns the number of such ties."""
    assert np.array_equal(a.hit, b.hit), "hit/miss differs from box32"
    assert np.array_equal(a.t.view(np.uint32), b.t.view(np.uint32)), "t differs from box32"
    diff = a.prim != b.prim
    assert a.hit[diff].all()
    return int(diff.sum())


def check_two_level(scene_name: str, n_rays: int = 256, on_phase=None) -> dict:
    """Build the two-level image of an instanced scene in every format (``build_two_level``,
    every BLAS and the TLAS) and check that camera rays and random rays hit in q8 and q8g as in
    box32. Returns {format: the image's ``phase_s``}."""
    from driver.bvh.instances import build_two_level
    from driver.scenes.camera import primary_rays
    from driver.scenes.scene import load_scene
    from driver.tracer import trace

    on_phase = on_phase or (lambda name: None)
    on_phase("load")
    scene = load_scene(scene_name)
    k = int(np.sqrt(n_rays))
    o, d = primary_rays(scene.camera, k, k)
    out, ref = {}, None
    for fmt in FORMATS:
        def phase(name, fmt=fmt):
            on_phase(f"{fmt} two-level build: {name}")
        bvh = build_two_level(scene.instances, format=fmt, on_phase=phase, progress=False)
        on_phase(f"{fmt} trace")
        res = trace(bvh, o, d, backend="golden")
        if ref is None:
            ref = res
            assert res.hit.sum() > 0
        else:
            same_hits(ref, res)
        out[fmt] = bvh.stats["phase_s"]
    return out


def spin(on_phase=None) -> None:
    """Never return (the watchdog's own test)."""
    on_phase("spinning")
    while True:
        time.sleep(0.05)
