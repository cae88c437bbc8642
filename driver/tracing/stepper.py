"""What the traversal does when a ray enters an instance (docs/instances.md): the
``instances`` hook of ``driver.traversal.traverse``.

A ray whose next node is an instance node fetches it (128 bytes), transforms its world ray (on
the host with ``driver.instances.transform_ray``, or as a TRANSFORM request on the datapath),
prepares it again (``driver.core.datapath.prepare_rays``: the transformed ray is a new row of the
issuer's ray table) and continues at the BLAS root in the same stack, with its nearest t as the
extent; when its stack falls back below the entry, the world ray is restored.
"""

from __future__ import annotations

import numpy as np

from ..core.datapath import prepare_rays
from ..core.layout import (INSTANCE_BYTES, INSTANCE_NODE, INSTANCE_TYPE, NO_CHILD, NodeRef,
                           read_nodes)
from ..instances import DATAPATH, check_transform, transform_ray
from .issue import transformed


class InstanceStepper:
    """Per-ray instance state of one traversal (see the module docstring).

    rays : (n,) prepared world rays (``REQUEST_DTYPE``); issue : the traversal's issuer
    (``driver.tracing.issue``): ``issue.add_rays(prepared, rays, instance node pointers)`` appends
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
                o2, d2 = transformed(self.issue.transforms(r, ptr, nearest[r]))
                self.transform_ops[r] += 1
                self._calls.append(len(r))
            else:
                o2, d2 = transform_ray(node["world_to_object"], self.world["origin"][r],
                                       self.world["dir"][r])
            ok = (np.isfinite(o2).all(1) & np.isfinite(d2).all(1) & (d2 != 0).any(1))
            go, skip = r[ok], r[~ok]
            if len(go):
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
