"""What a rendering scene holds besides its triangles and camera: lights (``PointLight``,
``QuadLight``) and per-triangle materials (``Materials``), the scene types every scene module and
the workloads share (docs/workloads.md); and ``Built``, the content of a built-in rendering scene
(``driver.scenes.builtins``, ``driver.scenes.city``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_ALBEDO = 0.75


@dataclass(frozen=True)
class PointLight:
    """A point light: ``position`` (3,), radiant ``intensity`` (3,) (W/sr per channel)."""

    position: tuple
    intensity: tuple = (1.0, 1.0, 1.0)

    def sample(self, u1, u2):
        """(points (k, 3), light normals or None, emitted radiance x area factor (k, 3))."""
        k = len(u1)
        p = np.broadcast_to(np.asarray(self.position, np.float64), (k, 3))
        return p, None, np.broadcast_to(np.asarray(self.intensity, np.float64), (k, 3))


@dataclass(frozen=True)
class QuadLight:
    """A parallelogram light ``corner + s*u + t*v`` (s, t in [0, 1]) emitting ``emission``
    (radiance, 3) from the side of its normal ``u x v``."""

    corner: tuple
    u: tuple
    v: tuple
    emission: tuple = (1.0, 1.0, 1.0)

    def sample(self, u1, u2):
        c, u, v = (np.asarray(x, np.float64) for x in (self.corner, self.u, self.v))
        nrm = np.cross(u, v)
        area = float(np.linalg.norm(nrm))
        p = c + u1[:, None] * u + u2[:, None] * v
        k = len(u1)
        return (p, np.broadcast_to(nrm / area, (k, 3)),
                np.broadcast_to(np.asarray(self.emission, np.float64) * area, (k, 3)))


@dataclass
class Materials:
    """Per-triangle diffuse ``albedo`` (m, 3) and ``emission`` (m, 3) (radiance)."""

    albedo: np.ndarray
    emission: np.ndarray

    @classmethod
    def plain(cls, m: int) -> "Materials":
        return cls(np.full((m, 3), DEFAULT_ALBEDO), np.zeros((m, 3)))


@dataclass
class Built:
    """A built-in scene: triangles (m, 3, 3) float32 (None: an instanced scene too large to
    flatten, ``instances`` only), per-triangle albedo and emission (m, 3),
    lights (``PointLight``, ``QuadLight``), camera (position, look_at, up, fov_deg),
    double-sided."""

    triangles: np.ndarray
    albedo: np.ndarray
    emission: np.ndarray
    lights: list
    camera: dict
    double_sided: bool
    instances: object = None        # driver.instances.Instances whose flattening is triangles
