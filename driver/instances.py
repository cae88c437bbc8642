"""Instances: meshes placed by 3x4 transforms, the ray transform, and what the traversal does when
a ray enters an instance (docs/instances.md).

- ``Instances``: a scene's instanced geometry: a list of meshes ((m, 3, 3) float32 triangles each),
  the mesh of every instance and its ``object_to_world`` 3x4 transform; the flattened world-space
  triangles (instance after instance, each mesh's triangles in order) are what ``prim`` indexes.
- ``transform_ray``: the ray into object space, every product and sum rounded to float32 in the
  order of the instance transform (docs/instances.md); the one function a datapath ``TRANSFORM``
  operation replaces (``TRANSFORMS``: only "driver" today).
- ``InstanceStepper``: the traversal's hook (``driver.traversal.traverse(instances=...)``): a ray
  whose next node is an instance node fetches it (128 bytes), transforms its world ray, prepares
  it again (``driver.datapath.prepare_rays``: the transformed ray is a new row of the issuer's
  ray table) and continues at the BLAS root in the same stack, with its nearest t as the extent;
  when its stack falls back below the entry, the world ray is restored.

The two-level image itself is built by ``driver.bvh.instances.build_two_level``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .layout import INSTANCE_BYTES, INSTANCE_NODE, INSTANCE_TYPE, NodeRef, read_nodes

TRANSFORMS = ("driver",)        # where the instance transform runs (a datapath op may join)


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
        """Triangles stored once per distinct mesh used by an instance."""
        return int(sum(len(self.meshes[j]) for j in np.unique(self.mesh)))

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
        """(triangles_total, 3, 3) float32: every instance's triangles in world space."""
        return self.world_triangles(np.arange(self.triangles_total))


class InstanceStepper:
    """Per-ray instance state of one traversal (see the module docstring).

    rays : (n,) prepared world rays (``REQUEST_DTYPE``); add_rays(prepared, rays, instance node
    pointers) : appends transformed rays to the issuer's ray table and returns their rows (rows
    0..n-1 are the world rays; ``driver.issue``).
    """

    def __init__(self, bvh, rays: np.ndarray, add_rays):
        self.image = bvh.image.view("<u4")
        self.world = rays
        self.add_rays = add_rays
        n = len(rays)
        self.row = np.arange(n, dtype=np.int64)         # the issuer's row of each ray's ray
        self.base = np.zeros(n, np.int64)               # stack index of the BLAS root entry
        self.inside = np.zeros(n, bool)
        self.current = np.full(n, -1, np.int64)         # instance the ray is in
        self.hit_instance = np.full(n, -1, np.int64)
        self.instance_ops = np.zeros(n, np.int64)       # instances entered
        self.node_bytes = np.zeros(n, np.int64)         # instance node bytes fetched

    def step(self, active, stack, sp, nearest) -> np.ndarray:
        """Before a step's requests: restore the world ray of rays that left their instance and
        enter the instance nodes on top of the stacks (``sp`` points at the top entry). Returns
        the rays that still have a request to issue (a ray whose transformed direction is zero
        or not finite skips that instance)."""
        while True:
            out = self.inside[active] & (sp[active] < self.base[active])
            if out.any():
                r = active[out]
                self.inside[r] = False
                self.row[r] = r
                self.current[r] = -1
            top = stack[active, sp[active]]
            enter = NodeRef.type(top) == INSTANCE_TYPE
            if not enter.any():
                return active
            r = active[enter]
            node = read_nodes(self.image, top[enter], INSTANCE_NODE)
            self.instance_ops[r] += 1
            self.node_bytes[r] += INSTANCE_BYTES
            o2, d2 = transform_ray(node["world_to_object"], self.world["origin"][r],
                                   self.world["dir"][r])
            ok = (np.isfinite(o2).all(1) & np.isfinite(d2).all(1) & (d2 != 0).any(1))
            go, skip = r[ok], r[~ok]
            if len(go):
                from .datapath import prepare_rays
                prepared = prepare_rays(o2[ok], d2[ok], nearest[go], self.world["flags"][go])
                self.row[go] = self.add_rays(prepared, go, top[enter][ok])
                self.base[go] = sp[go]
                self.inside[go] = True
                self.current[go] = node["instance"][ok].astype(np.int64)
                stack[go, sp[go]] = node["blas"][ok]
            if len(skip):
                sp[skip] -= 1
                active = active[sp[active] >= 0]
                sp[skip[sp[skip] < 0]] = 0

    def hit(self, rays) -> None:
        """Rays ``rays`` accepted a triangle in their current instance."""
        self.hit_instance[rays] = self.current[rays]
