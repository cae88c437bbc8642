"""The built-in ``city``: a scene at game scale made of instances (docs/instances.md).

A square grid of ``side`` x ``side`` cells (default 110: 12,100 cells), one instance per cell, plus
a floor under the whole grid and a quad light above its centre:

- every 8th cell (cell index i % 8 == 0) a Stanford bunny (99,785 triangles), 3 to 6 units tall,
  turned about z, every other one of them mirrored (a negative-determinant transform);
- cells with i % 8 in (1, 2, 5): a tree (a cone on a cylinder, 1.5 to 3 times its unit size);
- the other cells: a building (a box), 4 to 8 units wide on each side, 4 to 30 units tall,
  taller towards the centre.

Placement is counter-based: every number of instance i (position jitter, angle, size, height,
mirroring) is a hash of (seed, i, which number), so any instance can be generated alone and the
scene is the same on every machine. With the defaults: 12,101 instances of 4 meshes, 151,410,335
instanced triangles (1,513 bunnies), 199,664 triangles in the 5 BLASes (the bunny twice: once
for its mirrored instances). Single-sided, z up; a camera above one corner looks across the
city.
"""

from __future__ import annotations

import numpy as np

from ..instances import Instances, PerInstance
from .materials import Built, QuadLight

PITCH = 10.0            # cell size (scene units)
SIDE = 110              # cells per side
_MUL = (0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB)


def counter_uniform(seed: int, i, k: int) -> np.ndarray:
    """Uniform numbers in [0, 1), a pure function of (seed, i, k): splitmix64 of the three
    (``i``: an integer array)."""
    with np.errstate(over="ignore"):
        x = (np.asarray(i, np.uint64) * np.uint64(_MUL[0])
             + np.uint64((seed * 0x100000001B3 + k * 0x2545F4914F6CDD1D) & (2**64 - 1)))
        x = (x ^ (x >> np.uint64(30))) * np.uint64(_MUL[1])
        x = (x ^ (x >> np.uint64(27))) * np.uint64(_MUL[2])
        x = x ^ (x >> np.uint64(31))
    return (x >> np.uint64(11)).astype(np.float64) * 2.0 ** -53


def _tree() -> np.ndarray:
    """(m, 3, 3) a tree of unit size: a cylinder trunk (radius 0.12, height 0.5) under a cone
    (radius 0.5, height 1.0), standing on z = 0."""
    import trimesh
    trunk = trimesh.creation.cylinder(0.12, 0.5, sections=12)
    trunk.apply_translation([0, 0, 0.25])
    crown = trimesh.creation.cone(0.5, 1.0, sections=16)
    crown.apply_translation([0, 0, 0.45])
    return np.concatenate([trunk.triangles, crown.triangles]).astype(np.float32)


def _building() -> np.ndarray:
    """(12, 3, 3) a unit box [-0.5, 0.5]^2 x [0, 1] (outward faces)."""
    import trimesh
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    box.apply_translation([0, 0, 0.5])
    return box.triangles.astype(np.float32)


def _rot_z(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros(angle.shape + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 1, 0], r[..., 1, 1], r[..., 2, 2] = c, -s, s, c, 1.0
    return r


def city_instances(bunny: np.ndarray, side: int = SIDE, seed: int = 0):
    """(``driver.instances.Instances``, per-instance albedo (k, 3)): the city of the module
    docstring; ``bunny`` (m, 3, 3) z-up triangles."""
    bunny = np.asarray(bunny, np.float64)
    pts = bunny.reshape(-1, 3)
    lo, hi = pts.min(0), pts.max(0)
    unit_bunny = ((bunny - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
                  / (hi[2] - lo[2])).astype(np.float32)                 # 1 unit tall, feet at 0
    n = int(side) ** 2
    i = np.arange(n)
    u = [counter_uniform(seed, i, k) for k in range(6)]
    cx, cy = (i % side + 0.5) * PITCH, (i // side + 0.5) * PITCH
    kind = np.full(n, 2)                                                 # building
    kind[np.isin(i % 8, (1, 2, 5))] = 1                                  # tree
    kind[i % 8 == 0] = 0                                                 # bunny
    m = np.zeros((n, 3, 4))
    centre = np.hypot(cx - side * PITCH / 2, cy - side * PITCH / 2) / (side * PITCH / 2)
    # buildings: axis-aligned boxes, 4..8 wide, 4..30 tall (taller near the centre)
    b = kind == 2
    height = 4 + 26 * u[2][b] * np.clip(1.2 - centre[b], 0.2, 1.0)
    m[b, :, :3] = np.einsum("kij,kj->kij", np.broadcast_to(np.eye(3), (b.sum(), 3, 3)),
                            np.stack([4 + 4 * u[0][b], 4 + 4 * u[1][b], height], 1))
    # trees and bunnies: turned about z, scaled uniformly; every other bunny mirrored in x
    for k, (s0, s1) in ((1, (1.5, 3.0)), (0, (3.0, 6.0))):
        sel = kind == k
        scale = s0 + (s1 - s0) * u[0][sel]
        r = _rot_z(2 * np.pi * u[1][sel]) * scale[:, None, None]
        if k == 0:
            r[u[2][sel] < 0.5] = r[u[2][sel] < 0.5] @ np.diag([-1.0, 1.0, 1.0])
        m[sel, :, :3] = r
    jitter = PITCH * 0.1
    m[:, 0, 3] = cx + jitter * (2 * u[4] - 1)
    m[:, 1, 3] = cy + jitter * (2 * u[5] - 1)
    extent = side * PITCH
    floor = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]],
                     np.float32)                                          # +z, counter-clockwise
    fm = np.diag([extent + 2 * PITCH, extent + 2 * PITCH, 1.0])
    floor_m = np.hstack([fm, [[-PITCH], [-PITCH], [0.0]]])[None]
    meshes = [unit_bunny, _tree(), _building(), floor]
    inst = Instances(meshes, np.append(kind, 3), np.concatenate([m, floor_m]))
    albedo = np.array([(0.80, 0.76, 0.70), (0.25, 0.55, 0.25), (0.70, 0.70, 0.72),
                       (0.50, 0.50, 0.48)])[inst.mesh]
    return inst, albedo


def city(bunny, side: int = SIDE):
    """The ``Built`` of the city (``driver.scenes.builtins``): ``triangles`` is None (the
    scene is never flattened), materials per instance."""
    inst, albedo = city_instances(bunny(), side)
    extent = side * PITCH
    h = 0.6 * extent
    s = 0.25 * extent
    corner = (extent / 2 - s / 2, extent / 2 - s / 2, h)
    radiance = 2.0 * h * h / (s * s)                # about 2 irradiance under the light
    light = QuadLight(corner, (0.0, s, 0.0), (s, 0.0, 0.0), (radiance,) * 3)   # u x v = -z
    camera = {"position": (-0.08 * extent, -0.08 * extent, 0.22 * extent),
              "look_at": (0.45 * extent, 0.45 * extent, 0.0), "up": (0.0, 0.0, 1.0),
              "fov_deg": 50.0}
    zeros = np.zeros((len(inst), 3))
    return Built(None, PerInstance(inst, albedo), PerInstance(inst, zeros), [light], camera,
                 False, inst)
