"""The geometry of the built-in meshes ``room`` and ``soup`` (``driver.scenes.scene.builtin``
makes the validated meshes of them): vertex and face arrays."""

from __future__ import annotations

import numpy as np
import trimesh


def grid_box(lo, hi, n: int, inward: bool):
    """Axis-aligned box surface, each face split into n x n quads (2 triangles each); faces wound
    outward (trimesh convention), or inward if ``inward``. Returns (vertices, faces)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    verts, faces = [], []
    s = np.linspace(0.0, 1.0, n + 1)
    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            uu, vv = np.meshgrid(s, s, indexing="ij")
            p = np.empty(uu.shape + (3,))
            p[..., axis] = hi[axis] if side else lo[axis]
            p[..., a] = lo[a] + uu * (hi[a] - lo[a])
            p[..., b] = lo[b] + vv * (hi[b] - lo[b])
            base = sum(len(v) for v in verts)
            verts.append(p.reshape(-1, 3))
            idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + base
            q0, q1, q2, q3 = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
            f = np.concatenate([np.stack([q0, q1, q2], -1).reshape(-1, 3),
                                np.stack([q0, q2, q3], -1).reshape(-1, 3)])
            # (a, b, axis) is right-handed, so q0 q1 q2 faces +axis: flip on the low side
            if (side == 0) != inward:
                f = f[:, ::-1]
            faces.append(f)
    return np.concatenate(verts), np.concatenate(faces)


def room():
    """(vertices, faces) of a closed 8 x 8 x 3 room (walls face inward) with a box and a sphere
    standing in it."""
    parts = [grid_box((-4, -4, 0), (4, 4, 3), 4, inward=True),
             grid_box((0.5, 0.5, 0), (2, 2, 1.5), 1, inward=False)]
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.8)
    parts.append((s.vertices + [-1.5, 1.0, 0.8], s.faces))
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    return np.concatenate(verts), np.concatenate(faces)


def soup(n: int = 256, seed: int = 7):
    """(vertices, faces) of n random triangles (seeded) in about [-1, 1]^3; random winding, so
    about half face away."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-1, 1, (n, 1, 3))
    tri = centres + rng.normal(0, 0.2, (n, 3, 3))
    return tri.reshape(-1, 3), np.arange(3 * n).reshape(n, 3)
