"""The scene object every layer above passes around: a mesh (or instances), a camera, a default
image size, and for rendering workloads materials, lights, double-sidedness and an AO radius
(``driver.scenes.scene`` loads one from a name or a file)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import SceneError
from ..instances import InstancedTriangles
from .camera import Camera

DEFAULT_SIZE = 256


@dataclass
class Scene:
    """mesh : trimesh.Trimesh (process=False; None for a scene of instances too large to
    flatten: ``city``); camera : Camera; size : default (width, height);
    materials : ``driver.scenes.materials.Materials`` or None (uniform grey); lights : workload
    lights (empty: a default light); double_sided : trace with NO_CULL; ao_radius : None = default."""

    mesh: object                    # trimesh.Trimesh, or None
    camera: Camera
    size: tuple = (DEFAULT_SIZE, DEFAULT_SIZE)
    name: str = "scene"
    materials: object = None
    lights: list = field(default_factory=list)
    double_sided: bool = False
    ao_radius: float | None = None
    instances: object = None        # driver.instances.Instances, or None: one mesh

    @property
    def triangles(self) -> np.ndarray:
        """(n, 3, 3) float32 vertex positions of every face; row i is primitive id i. A scene
        of instances too large to flatten (``mesh`` None) gives an
        ``driver.instances.InstancedTriangles``, computed row by row when indexed."""
        if self.mesh is None:
            return InstancedTriangles(self.instances)
        return triangles(self.mesh)

    def flattened(self) -> "Scene":
        """This scene traced as one mesh: its flattened triangles in one BVH (the same
        primitive ids); SceneError for a scene too large to flatten (``mesh`` None)."""
        if self.mesh is None:
            raise SceneError(f"scene {self.name!r} is too large to flatten "
                             f"({self.instances.triangles_total:,} instanced triangles)")
        return dataclasses.replace(self, instances=None)

    def counts(self) -> dict:
        """``instances``, ``instanced_triangles`` (triangles of the flattened scene) and
        ``blas_triangles`` (triangles stored once per mesh); a one-mesh scene is one instance."""
        if self.instances is None:
            n = len(self.mesh.faces)
            return {"instances": 1, "instanced_triangles": n, "blas_triangles": n}
        i = self.instances
        return {"instances": len(i), "instanced_triangles": i.triangles_total,
                "blas_triangles": i.blas_triangles}


def triangles(mesh) -> np.ndarray:
    """(n, 3, 3) float32 vertex positions A, B, C of every face of a ``trimesh.Trimesh``, in face
    order."""
    return np.asarray(mesh.vertices, np.float32)[np.asarray(mesh.faces)]
