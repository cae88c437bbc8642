"""Small procedural test meshes, as (n, 3, 3) float32 triangle arrays (or trimesh meshes).

Winding follows docs/datapath.md#triangle: a face is hit from the side its (B-A)x(C-A) normal points
to.

- ``soup(n, seed)``: random triangles of mixed size in [-1, 1]^3, random orientation.
- ``box_room(k)``: an axis-aligned room with inward-facing walls (k x k quads per wall, all flat
  axis-aligned triangles) and an outward-facing crate inside.
- ``icosphere(subdivisions, radius)``: trimesh's icosphere, outward faces (seen from outside only).
- ``degenerate()``: zero-area triangles (repeated vertex, collinear), axis-aligned flat triangles in
  x/y/z planes, a tiny triangle and exact duplicates.
- ``bunny()``: the 99,785-triangle Stanford bunny shipped with pymeshfix (trimesh mesh, cached).
- ``reuse_glb(path)``: a GLB scene that places one icosphere three times (three instances of one
  mesh, 240 instanced triangles); returns ``path``.
- ``small_instances()``: five overlapping instances of two tiny meshes (``Instances``), and
  ``instance_rays(n, seed)``: rays over them.
"""

from __future__ import annotations

import functools
import importlib.resources

import numpy as np
import trimesh

from driver.instances import Instances


def soup(n: int, seed: int = 0) -> np.ndarray:
    """n random triangles: centres uniform in [-1, 1]^3, edge lengths ~ 0.02 .. 0.6."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-1, 1, (n, 1, 3))
    size = 10 ** rng.uniform(-1.7, -0.2, (n, 1, 1))
    return (centre + size * rng.normal(size=(n, 3, 3))).astype(np.float32)


def _quad_grid(origin, u, v, k):
    """k x k quads spanning origin + [0,1]u + [0,1]v, two triangles each, normal along u x v."""
    s = np.linspace(0, 1, k + 1)
    p = origin + s[:, None, None] * u + s[None, :, None] * v          # (k+1, k+1, 3)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    t1 = np.stack([a, b, c], axis=2).reshape(-1, 3, 3)
    t2 = np.stack([a, c, d], axis=2).reshape(-1, 3, 3)
    return np.concatenate([t1, t2])


def _box(lo, hi, k: int, inward: bool) -> np.ndarray:
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    ext = hi - lo
    faces = []
    for ax in range(3):
        u_ax, v_ax = (ax + 1) % 3, (ax + 2) % 3
        u = np.zeros(3)
        v = np.zeros(3)
        u[u_ax], v[v_ax] = ext[u_ax], ext[v_ax]             # u x v points along +ax
        for side, base in ((+1, hi), (-1, lo)):
            o = lo.copy()
            o[ax] = base[ax]
            plus = (side > 0) != inward                     # want the normal along +ax
            tris = _quad_grid(o, u, v, k) if plus else _quad_grid(o, v, u, k)
            faces.append(tris)
    return np.concatenate(faces)


def box_room(k: int = 3) -> np.ndarray:
    """Room [-2, 3] x [-1, 1.5] x [-1.25, 2] with inward walls (12 k^2 triangles) plus an
    outward-facing crate [0.25, 1] x [-1, -0.25] x [-0.5, 0.125] (12 triangles)."""
    room = _box((-2, -1, -1.25), (3, 1.5, 2), k, inward=True)
    crate = _box((0.25, -1, -0.5), (1, -0.25, 0.125), 1, inward=False)
    return np.concatenate([room, crate]).astype(np.float32)


def icosphere(subdivisions: int = 2, radius: float = 1.0) -> np.ndarray:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.triangles, np.float32)


def degenerate() -> np.ndarray:
    """Zero-area, flat axis-aligned, tiny and duplicated triangles (32 triangles)."""
    tris = [
        [(0, 0, 0), (0, 0, 0), (0, 0, 0)],                  # a point
        [(1, 1, 1), (1, 1, 1), (2, 0, 1)],                  # repeated vertex
        [(0, 0, 0), (1, 1, 1), (2, 2, 2)],                  # collinear
        [(-1, 0.5, 0), (1, 0.5, 0), (3, 0.5, 0)],           # collinear and axis-aligned
    ]
    rng = np.random.default_rng(3)
    for ax in range(3):                                     # flat in an axis plane, both windings
        for _ in range(8):
            t = rng.uniform(-1, 1, (3, 3))
            t[:, ax] = np.float32(rng.uniform(-1, 1))
            tris.append(t if len(tris) % 2 else t[::-1])
    tris.append([(0.5, 0.5, 0.5), (0.5 + 1e-6, 0.5, 0.5), (0.5, 0.5 + 1e-6, 0.5)])   # tiny
    tris += [tris[5], tris[6], tris[5]]                     # exact duplicates
    return np.asarray(tris, np.float32)


@functools.lru_cache(maxsize=1)
def bunny() -> trimesh.Trimesh:
    """The Stanford bunny from pymeshfix's example data (not ``import pymeshfix.examples``,
    which needs pyvista)."""
    p = importlib.resources.files("pymeshfix") / "examples" / "StanfordBunny.ply"
    return trimesh.load(str(p), force="mesh")


def reuse_glb(path):
    """Write a GLB scene of three nodes that reuse one icosphere (translated by 0, 3 and 6 along
    x) to ``path``; returns it."""
    s = trimesh.Scene()
    s.add_geometry(trimesh.creation.icosphere(1), geom_name="ico", node_name="n0")
    for i in (1, 2):
        s.graph.update(frame_to=f"n{i}", frame_from=s.graph.base_frame, geometry="ico",
                       matrix=trimesh.transformations.translation_matrix([3.0 * i, 0, 0]))
    s.export(str(path))
    return path


def bricks(nx: int = 12, ny: int = 8, nz: int = 3, seed: int = 0) -> trimesh.Trimesh:
    """A LEGO-like model, the kind of mesh the q8 matching once looped on (tinybvh's legocar,
    10,992 triangles, is not redistributed here): unit bricks on a grid, each its own closed box
    whose corners coincide bit for bit with its neighbours' (the edges of touching bricks are
    shared by 4 to 8 triangles), a fifth of them missing, and on top of each exposed brick a
    16-sided stud whose caps are triangle fans: 8,940 triangles for the defaults."""
    rng = np.random.default_rng(seed)
    parts = []
    for x in range(nx):
        for y in range(ny):
            height = 0
            for z in range(nz):
                if rng.random() < 0.2:
                    continue
                parts.append(trimesh.creation.box(
                    extents=(1, 1, 1),
                    transform=trimesh.transformations.translation_matrix((x, y, z))))
                height = z + 1
            if height:
                stud = trimesh.creation.cylinder(radius=0.3, height=0.2, sections=16)
                stud.apply_translation((x, y, height - 0.5 + 0.1))
                parts.append(stud)
    return trimesh.util.concatenate(parts)


def small_instances() -> Instances:
    """Five overlapping instances of two tiny meshes (an icosahedron, 20 triangles; a box, 12),
    side by side along x, 0.8 apart at unit size; instance 3 turned about z and scaled
    non-uniformly."""
    ico = trimesh.creation.icosphere(0).triangles
    box = trimesh.creation.box().triangles
    a = 0.7
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    mats = []
    for i in range(5):
        m = turn @ np.diag([1.5, 0.7, 1.2]) if i == 3 else np.eye(3)
        mats.append(np.hstack([m, [[i * 0.8 - 1.6], [0.3 * (i % 2)], [0.0]]]))
    return Instances([ico, box], np.array([0, 1, 0, 1, 0]), np.array(mats))


def instance_rays(n=256, seed=0):
    """Rays from the plane z = -5 towards +z, over the instances."""
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-2, 2, n), np.full(n, -5.0)])
    d = np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), np.ones(n)])
    return o.astype(np.float32), d.astype(np.float32)
