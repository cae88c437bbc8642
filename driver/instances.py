"""Instances: meshes placed by 3x4 transforms, the ray transform, and what the traversal does when
a ray enters an instance (docs/instances.md).

- ``Instances``: a scene's instanced geometry: a list of meshes ((m, 3, 3) float32 triangles each),
  the mesh of every instance and its ``object_to_world`` 3x4 transform; the flattened world-space
  triangles (instance after instance, each mesh's triangles in order) are what ``prim`` indexes.
- ``transform_ray``: the ray into object space, every product and sum rounded to float32 in the
  order of the instance transform (docs/instances.md).
- ``TRANSFORMS``: where the transform runs: "driver" (``transform_ray`` on the host) or
  "datapath" (a ``TRANSFORM`` request per instance entered, issued on the frame's backend with
  the step's other requests; the same bits).
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

from .core.layout import (INSTANCE_BYTES, INSTANCE_NODE, INSTANCE_TYPE, NO_CHILD, NodeRef,
                          read_nodes)



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
        """(triangles_total, 3, 3) float32: every instance's triangles in world space."""
        return self.world_triangles(np.arange(self.triangles_total))


class InstanceStepper:
    """Per-ray instance state of one traversal (see the module docstring).

    rays : (n,) prepared world rays (``REQUEST_DTYPE``); issue : the traversal's issuer
    (``driver.issue``): ``issue.add_rays(prepared, rays, instance node pointers)`` appends
    transformed rays to its ray table and returns their rows (rows 0..n-1 are the world rays);
    with ``transform`` "datapath", ``issue.transforms(rows, pointers, extents)`` runs the
    TRANSFORM requests of world rays by instance nodes and returns their response words.
    """

    def __init__(self, bvh, rays: np.ndarray, issue, transform: str = "driver"):
        self.on_datapath = check_transform(transform) == DATAPATH
        self.image = bvh.image.view("<u4")
        self.world = rays
        self.issue = issue
        n = len(rays)
        self.row = np.arange(n, dtype=np.int64)         # the issuer's row of each ray's ray
        self.base = np.zeros(n, np.int64)               # stack index of the BLAS root entry
        self.inside = np.zeros(n, bool)
        self.current = np.full(n, -1, np.int64)         # instance the ray is in
        self.hit_instance = np.full(n, -1, np.int64)
        self.instance_ops = np.zeros(n, np.int64)       # instances entered
        self.transform_ops = np.zeros(n, np.int64)      # TRANSFORM requests (on the datapath)
        self._calls: list[int] = []                     # TRANSFORM batches not yet reported
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
            ptr = top[enter]
            node = read_nodes(self.image, ptr, INSTANCE_NODE)
            self.instance_ops[r] += 1
            self.node_bytes[r] += INSTANCE_BYTES
            if self.on_datapath:      # one TRANSFORM request per ray, on its world row (= r)
                from .tracing.issue import transformed
                o2, d2 = transformed(self.issue.transforms(r, ptr, nearest[r]))
                self.transform_ops[r] += 1
                self._calls.append(len(r))
            else:
                o2, d2 = transform_ray(node["world_to_object"], self.world["origin"][r],
                                       self.world["dir"][r])
            ok = (np.isfinite(o2).all(1) & np.isfinite(d2).all(1) & (d2 != 0).any(1))
            go, skip = r[ok], r[~ok]
            if len(go):
                from .core.datapath import prepare_rays
                prepared = prepare_rays(o2[ok], d2[ok], nearest[go], self.world["flags"][go])
                # the instance node is the TRANSFORM request's own on the datapath; in the
                # driver it is fetched before the BLAS root (the record's ``before``)
                via = np.full(len(go), NO_CHILD, np.uint32) if self.on_datapath else ptr[ok]
                self.row[go] = self.issue.add_rays(prepared, go, via)
                self.base[go] = sp[go]
                self.inside[go] = True
                self.current[go] = node["instance"][ok].astype(np.int64)
                stack[go, sp[go]] = node["blas"][ok]
            if len(skip):
                sp[skip] -= 1
                active = active[sp[active] >= 0]
                sp[skip[sp[skip] < 0]] = 0

    def transform_calls(self) -> list[int]:
        """The sizes of the TRANSFORM batches issued since the last call (each one backend
        call), in order."""
        calls, self._calls = self._calls, []
        return calls

    def hit(self, rays) -> None:
        """Rays ``rays`` accepted a triangle in their current instance."""
        self.hit_instance[rays] = self.current[rays]


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
        from .bvh.instances import world_boxes
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


EMBREE_SAMPLE_TRIANGLES = 2_000_000   # world triangles an Embree check of a large instanced
EMBREE_SAMPLE_RAYS = 4096             # scene may flatten, and the rays it may take


def embree_sample(instances: Instances, origins, dirs, extent, our_t, our_prim,
                  budget: int = EMBREE_SAMPLE_TRIANGLES, max_rays: int = EMBREE_SAMPLE_RAYS):
    """A sample of rays that an Embree check of a scene too large to flatten can take exactly:
    (rows, triangles, prim). ``rows``: the rays taken, in a fixed pseudo-random order, each ray
    whose instances still fit in ``budget`` flattened triangles, up to ``max_rays``; a ray's
    instances are every instance whose world box (grown by 1e-5 of the scene's size, for the
    float32 traversal's rounding) it crosses before its hit (or its extent, for a miss), and
    the instance it hit. ``triangles``: those instances' world-space triangles; ``prim``: our
    primitive ids of the rays taken, renumbered into them. An Embree hit nearer than ours lies
    in such an instance, so on these rays the check is the full scene's."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    n = len(o)
    t = np.asarray(our_t, np.float64)
    end = np.where(np.isfinite(t), t * (1 + 1e-4),
                   np.broadcast_to(np.asarray(extent, np.float64), (n,)))
    own = np.full(n, -1, np.int64)                      # the instance each ray hit (-1: none)
    ours = np.asarray(our_prim, np.int64) >= 0
    own[ours] = instances.locate(np.asarray(our_prim, np.int64)[ours])[0]
    from .bvh.instances import world_boxes
    lo_m = np.array([m.reshape(-1, 3).min(0) for m in instances.meshes], np.float64)
    hi_m = np.array([m.reshape(-1, 3).max(0) for m in instances.meshes], np.float64)
    wb = world_boxes(instances, np.concatenate([lo_m, hi_m], 1)[instances.mesh]).astype(np.float64)
    pad = 1e-5 * max(float(np.abs(wb).max()), float(np.abs(o).max(initial=0.0)))
    wb[:, 0] -= pad                                     # the float32 traversal's rounding
    wb[:, 1] += pad
    size = np.array([len(m) for m in instances.meshes], np.int64)[instances.mesh]
    dn = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    order = np.random.default_rng(0).permutation(n)
    taken, used = [], np.zeros(len(instances), bool)
    total = 0
    for start in range(0, n, 64):
        rows = order[start:start + 64]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d[rows]
            t0 = (wb[None, :, 0] - o[rows, None]) * inv[:, None]
            t1 = (wb[None, :, 1] - o[rows, None]) * inv[:, None]
        near = np.nan_to_num(np.minimum(t0, t1), nan=-np.inf).max(2)
        far = np.nan_to_num(np.maximum(t0, t1), nan=np.inf).min(2)
        cross = (near <= far) & (far >= 0) & (near <= end[rows, None] + pad / dn[rows, None])
        for r, c in zip(rows, cross):
            c = c.copy()
            if own[r] >= 0:
                c[own[r]] = True                        # its own hit, however it rounded
            new = c & ~used
            if total + int(size[new].sum()) > budget:
                continue                        # this ray would flatten too much: not taken
            used |= new
            total += int(size[new].sum())
            taken.append(r)
        if len(taken) >= max_rays:
            taken = taken[:max_rays]
            break
    rows = np.sort(np.array(taken, np.int64))
    keep = np.flatnonzero(used)
    base = np.concatenate(([0], np.cumsum(size[keep])[:-1])).astype(np.int64)
    tris = (np.concatenate([instances.world_triangles(instances.prim_base[i] + np.arange(size[i]))
                            for i in keep]) if len(keep) else np.zeros((0, 3, 3), np.float32))
    prim = np.asarray(our_prim, np.int64)[rows]
    hit = prim >= 0
    inst, local = instances.locate(prim[hit])
    prim[hit] = base[np.searchsorted(keep, inst)] + local
    return rows, tris, prim
