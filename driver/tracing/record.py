"""The record of a traversal: every datapath request in issue order, with its responses, as the
issuers of ``driver.tracing.issue`` keep it; what the RT-unit replay (``driver.rtunit.replay``)
issues again under its schedule."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bvh4 import request_operands
from ..core.layout import INSTANCE_TYPE, NodeRef
from ..core.wire import RAY_WORDS, REQ_WORDS, unpack_requests


@dataclass
class Record:
    """Every datapath request of a traversal, in issue order (wavefront step by step, rays in
    index order within a step).

    ray_words : (n, RAY_WORDS) uint32, the packed prepared rays (``driver.core.wire.ray_words``)
    image : (k,) uint32, the BVH4 memory image as little-endian words
    ray, ptr : (m,) uint32, ray index and node pointer of request i (an instance node's
        pointer is a TRANSFORM request: the instance transform on the datapath)
    extent : (m,) float32, the ray's nearest t when request i was issued
    responses : (m, RSP_WORDS) uint32 response words of the functional run, or None
    params : RTL build parameters for the replay (EXTENDED, DISJOINT, LATENCY)
    chain : (m,) uint32, the ray (request chain) of request i when requests name rows of a
        ray table that has more rows than rays (a two-level image: a ray that enters an
        instance continues on its object-space row; ``driver.instances``); None: ``ray``
    before : (m,) uint32, a node fetched before request i's own node (the instance node a ray
        reads on entering an instance; ``NO_CHILD``: none), or None
    world_rays : the number of rays (chains) when ``chain`` is given
    """

    ray_words: np.ndarray
    image: np.ndarray
    ray: np.ndarray
    ptr: np.ndarray
    extent: np.ndarray
    responses: np.ndarray | None
    params: dict
    chain: np.ndarray | None = None
    before: np.ndarray | None = None
    world_rays: int | None = None

    @property
    def rays(self) -> int:
        return len(self.ray_words) if self.world_rays is None else int(self.world_rays)

    @property
    def ops(self) -> int:
        return len(self.ray)

    @property
    def box_ops(self) -> int:
        return int(NodeRef.is_box(self.ptr).sum())

    @property
    def transform_ops(self) -> int:
        """TRANSFORM requests (an instance node's pointer: the transform on the datapath)."""
        return int((NodeRef.type(self.ptr) == INSTANCE_TYPE).sum())

    def chains(self):
        """(chain_idx (m,) int64, chain_off (n + 1,) int64): ray r's requests, in issue order,
        are record indices chain_idx[chain_off[r]:chain_off[r + 1]]."""
        key = self.ray if self.chain is None else self.chain
        order = np.argsort(key, kind="stable").astype(np.int64)
        count = np.bincount(key.astype(np.int64), minlength=self.rays)
        off = np.zeros(self.rays + 1, np.int64)
        np.cumsum(count, out=off[1:])
        return order, off

    def requests(self, index=None) -> np.ndarray:
        """The recorded requests as a ``REQUEST_DTYPE`` array (all, or ``index``), built in
        Python from the rays and the image, as ``driver.traversal`` builds them for generic
        backends (for the cycle-by-cycle backend and for tests)."""
        index = np.arange(self.ops) if index is None else np.asarray(index)
        words = np.zeros((len(index), REQ_WORDS), np.uint32)
        words[:, :RAY_WORDS] = self.ray_words[self.ray[index]]
        req = unpack_requests(words)
        req["tag"] = self.ray[index]
        req["extent"] = self.extent[index]
        request_operands(req, self.image, self.ptr[index], bool(self.params.get("COMPRESSED")))
        return req
