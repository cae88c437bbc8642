"""Instances: meshes placed by 3x4 transforms, and the ray transform (docs/instances.md).

- ``Instances``: a scene's instanced geometry: a list of meshes ((m, 3, 3) float32 triangles each),
  the mesh of every instance and its ``object_to_world`` 3x4 transform; the flattened world-space
  triangles (instance after instance, each mesh's triangles in order) are what ``prim`` indexes.
- ``transform_ray``: the ray into object space, every product and sum rounded to float32 in the
  order of the instance transform (docs/instances.md).
- ``TRANSFORMS``: where the transform runs: "driver" (``transform_ray`` on the host) or
  "datapath" (a ``TRANSFORM`` request per instance entered, issued on the frame's backend with
  the step's other requests; the same bits).
- ``world_boxes``: the world boxes of instances from their object-space boxes;
  ``InstancedTriangles``, ``PerInstance``: the flattened triangles and per-instance attributes
  indexed like per-triangle arrays, without flattening.

What the traversal does when a ray enters an instance is ``driver.tracing.stepper``; the
two-level image itself is built by ``driver.bvh.instances.build_two_level``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np



def transform_ray(m, o, d):
    """(o', d') float32 (n, 3): rays ``o``, ``d`` (n, 3) through 3x4 matrices ``m`` ((3, 4) or
    (n, 3, 4)), each product and sum rounded to float32, in this order::

        o'[r] = ((m[r][0]*o[0] + m[r][1]*o[1]) + m[r][2]*o[2]) + m[r][3]
        d'[r] = (m[r][0]*d[0] + m[r][1]*d[1]) + m[r][2]*d[2]
    """
    m = np.asarray(m, np.float32)
    o = np.asarray(o, np.float32).reshape(-1, 3)
    d = np.asarray(d, np.float32).reshape(-1, 3)
    if m.ndim == 2:
        m = m[None]
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        def rows(v):
            return (m[:, :, 0] * v[:, None, 0] + m[:, :, 1] * v[:, None, 1]) \
                + m[:, :, 2] * v[:, None, 2]
        o2 = (rows(o) + m[:, :, 3]).astype(np.float32)
        d2 = rows(d).astype(np.float32)
    return o2, d2


# Where the instance transform runs (the ``--transform`` values, docs/instances.md): both give
# the same bits.
DATAPATH = "datapath"
TRANSFORMS = {
    "driver": "on the host (transform_ray), as RDNA2/3's traversal shader does",
    DATAPATH: "a TRANSFORM request on the datapath per instance entered, as RDNA4's RT unit "
              "does (the backend is built with the TRANSFORM operation)",
}


def check_transform(transform: str) -> str:
    """``transform`` if it names an entry of ``TRANSFORMS``, else a one-line ValueError."""
    if transform not in TRANSFORMS:
        raise ValueError(f"transform must be one of {tuple(TRANSFORMS)}, got {transform!r}")
    return transform


# Instances.flatten transforms each instance's triangles as one block when instances average at
# least this many triangles (a loop over instances), else gathers them all at once
FLATTEN_BLOCK = 64


def affine(m) -> np.ndarray:
    """(..., 4, 4) float64 homogeneous matrices of (..., 3, 4) transforms."""
    m = np.asarray(m, np.float64)
    out = np.zeros(m.shape[:-2] + (4, 4))
    out[..., :3, :] = m
    out[..., 3, 3] = 1.0
    return out


@dataclass
class Instances:
    """Instanced geometry.

    meshes : list of (m_j, 3, 3) float32 triangle arrays (object space)
    mesh : (k,) int64, the mesh of instance i
    object_to_world : (k, 3, 4) float32, instance i's transform (row-major 3x4)
    """

    meshes: list
    mesh: np.ndarray
    object_to_world: np.ndarray

    def __post_init__(self):
        self.meshes = [np.ascontiguousarray(m, np.float32).reshape(-1, 3, 3) for m in self.meshes]
        self.mesh = np.asarray(self.mesh, np.int64).reshape(-1)
        self.object_to_world = np.asarray(self.object_to_world, np.float32).reshape(-1, 3, 4)
        if len(self.mesh) != len(self.object_to_world) or not len(self.mesh):
            raise ValueError("instances need one mesh index per transform, at least one")
        if self.mesh.min() < 0 or self.mesh.max() >= len(self.meshes):
            raise ValueError("an instance names a mesh that does not exist")
        if not np.isfinite(self.object_to_world).all():
            raise ValueError("instance transforms must be finite (in float32)")
        det = np.linalg.det(self.object_to_world[:, :, :3].astype(np.float64))
        if not (np.abs(det) > 0).all():
            raise ValueError("an instance transform is singular (its 3x3 part has determinant 0)")
        counts = np.array([len(m) for m in self.meshes], np.int64)[self.mesh]
        self.prim_base = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)

    def __len__(self) -> int:
        return len(self.mesh)

    @property
    def triangles_total(self) -> int:
        """Instanced triangles: the flattened scene's triangle count."""
        return int(sum(len(self.meshes[j]) for j in self.mesh))

    @property
    def blas_triangles(self) -> int:
        """Triangles stored in the BLASes: once per mesh used by an instance, and once more for
        a mesh that also has mirrored instances (``driver.bvh.instances``)."""
        keys = np.unique(self.mesh * 2 + self.mirrored)
        return int(sum(len(self.meshes[k // 2]) for k in keys))

    @property
    def mirrored(self) -> np.ndarray:
        """(k,) bool: instances whose transform has a negative determinant."""
        return np.linalg.det(self.object_to_world[:, :, :3].astype(np.float64)) < 0

    def world_to_object(self) -> np.ndarray:
        """(k, 3, 4) float32: the inverse transforms, computed in float64 and rounded once."""
        return np.linalg.inv(affine(self.object_to_world))[:, :3, :].astype(np.float32)

    def locate(self, prim) -> tuple[np.ndarray, np.ndarray]:
        """(instance, local triangle index) of flattened primitive ids (>= 0)."""
        prim = np.asarray(prim, np.int64)
        inst = np.searchsorted(self.prim_base, prim, side="right") - 1
        return inst, prim - self.prim_base[inst]

    def world_triangles(self, prim) -> np.ndarray:
        """(len(prim), 3, 3) float32 world-space triangles of flattened primitive ids: the mesh's
        vertices through ``object_to_world`` (float64, rounded once)."""
        prim = np.asarray(prim, np.int64).reshape(-1)
        inst, local = self.locate(prim)
        out = np.empty((len(prim), 3, 3), np.float32)
        for j in np.unique(self.mesh[inst]) if len(prim) else ():
            sel = np.flatnonzero(self.mesh[inst] == j)
            m = self.object_to_world[inst[sel]].astype(np.float64)
            v = self.meshes[j][local[sel]].astype(np.float64)              # (s, 3, 3)
            out[sel] = (np.einsum("src,svc->svr", m[:, :, :3], v) + m[:, None, :, 3])
        return out

    def flatten(self) -> np.ndarray:
        """(triangles_total, 3, 3) float32: every instance's triangles in world space, as
        ``world_triangles`` gives them (the same arithmetic: float64, rounded once)."""
        total = self.triangles_total
        if len(self.mesh) * FLATTEN_BLOCK > total:   # many small instances: one gather
            return self.world_triangles(np.arange(total))
        out = np.empty((total, 3, 3), np.float32)    # few large ones: a block per instance
        m = self.object_to_world.astype(np.float64)
        wide: dict[int, np.ndarray] = {}
        for k, j in enumerate(self.mesh.tolist()):
            if j not in wide:
                wide[j] = self.meshes[j].astype(np.float64)
            b = self.prim_base[k]
            out[b:b + len(wide[j])] = np.einsum("rc,svc->svr", m[k, :, :3], wide[j]) + m[k, :, 3]
        return out


def world_boxes(instances: Instances, local_boxes: np.ndarray) -> np.ndarray:
    """(k, 2, 3) float32 world boxes of instances whose object-space boxes are ``local_boxes``
    (k, 6): the 8 corners through ``object_to_world`` in float64, rounded outward."""
    lo, hi = local_boxes[:, :3], local_boxes[:, 3:]
    sel = (np.arange(8)[:, None] >> np.arange(3)) & 1                   # (8, 3) corner choice
    corners = np.where(sel[None], hi[:, None, :], lo[:, None, :])       # (k, 8, 3)
    m = instances.object_to_world.astype(np.float64)
    w = np.einsum("krc,kvc->kvr", m[:, :, :3], corners) + m[:, None, :, 3]
    wlo = np.nextafter(w.min(1).astype(np.float32), np.float32(-np.inf))
    whi = np.nextafter(w.max(1).astype(np.float32), np.float32(np.inf))
    return np.stack([wlo, whi], axis=1)


class InstancedTriangles:
    """The flattened world-space triangles of ``Instances`` without flattening them: rows are
    computed when indexed (``tris[prim]`` -> (k, 3, 3) float32), so a scene of 10^8 instanced
    triangles costs only its meshes. ``len``, ``bounds()`` and ``np.asarray`` (which does
    flatten: small scenes only) as for an (n, 3, 3) array."""

    def __init__(self, instances: Instances):
        self.instances = instances

    def __len__(self) -> int:
        return self.instances.triangles_total

    @property
    def shape(self) -> tuple:
        return (len(self), 3, 3)

    def __getitem__(self, prim) -> np.ndarray:
        return self.instances.world_triangles(prim)

    def __array__(self, dtype=None, copy=None):
        flat = self.instances.flatten()
        return flat if dtype is None else flat.astype(dtype)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) float64 (3,): the world box of every instance's mesh vertices."""
        inst = self.instances
        lo = np.array([m.reshape(-1, 3).min(0) for m in inst.meshes], np.float64)
        hi = np.array([m.reshape(-1, 3).max(0) for m in inst.meshes], np.float64)
        wb = world_boxes(inst, np.concatenate([lo, hi], 1)[inst.mesh]).astype(np.float64)
        return wb[:, 0].min(0), wb[:, 1].max(0)


class PerInstance:
    """A per-triangle attribute that is constant over each instance (e.g. an albedo): ``values``
    (k, ...) per instance, indexed by flattened primitive ids like an (n, ...) array."""

    def __init__(self, instances: Instances, values):
        self.instances, self.values = instances, np.asarray(values)

    def __len__(self) -> int:
        return self.instances.triangles_total

    def __getitem__(self, prim) -> np.ndarray:
        return self.values[self.instances.locate(prim)[0]]
