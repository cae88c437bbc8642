"""How a traversal step's requests reach a datapath backend (the ``Issue`` of
``driver.traversal``), and the recorder of every request for the RT-unit replay.

- ``NodeIssue``: a backend with ``run_nodes`` (the "rtl" harness) gets (ray index, node pointer,
  extent) triples and assembles the request words itself from the packed ray table and the BVH4
  image (no per-request Python work); the host decodes only the response bits it needs.
- ``RequestIssue``: any other backend gets a ``REQUEST_DTYPE`` array built in numpy from the
  prepared rays and the decoded nodes, by the same rules (tests check the words are identical).
- ``Recorder``: wraps either and keeps every request and response as a ``driver.rtunit.Record``.

Both check that the responses come back in order with the ray index in their ``tag``.
"""

from __future__ import annotations

import time

import numpy as np

from .backends.base import NodeBackend
from .bvh4 import request_operands
from .layout import RESPONSE, RSP_WORDS, pack_responses, ray_words
from .traversal import StepResponses


def _bits(words: np.ndarray, name: str) -> np.ndarray:
    """Response field ``name`` (a sub-word integer field) from (m, RSP_WORDS) words."""
    f = RESPONSE.field[name]
    shift = (f.lsb + f.bits * np.arange(f.count, dtype=np.uint32)).astype(np.uint32)
    vals = (words[:, f.word, None] >> shift) & np.uint32((1 << f.bits) - 1)
    return vals if f.shape else vals[:, 0]


def _float(words: np.ndarray, name: str) -> np.ndarray:
    """Float32 field ``name``: (m,) for a scalar field, (m, count) for an array field."""
    f = RESPONSE.field[name]
    vals = words[:, f.word:f.word + f.words].view(np.float32)
    return vals if f.shape else vals[:, 0]


def _check_order(got_tags: np.ndarray, active: np.ndarray, name: str) -> None:
    if len(got_tags) != len(active) or not np.array_equal(got_tags, active):
        raise RuntimeError(f"backend {name!r} returned responses out of order or with altered "
                           "tags")


class NodeIssue:
    """Issue a step through ``backend.run_nodes`` (the harness assembles the requests)."""

    def __init__(self, backend, rays: np.ndarray, bvh, name: str):
        self.backend, self.name = backend, name
        self.ray_words = ray_words(rays)
        self.image = bvh.image.view("<u4")
        self.wall_s = 0.0         # time inside the backend (the simulation's share)

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        t0 = time.perf_counter()
        words = self.backend.run_nodes(self.ray_words, self.image, active, ptr, ext)
        self.wall_s += time.perf_counter() - t0
        _check_order(words[:, RESPONSE.field["tag"].word], active, self.name)
        wb, wt = words[bi], words[ti]
        return StepResponses(_bits(wb, "box_index"), _bits(wb, "box_hit").astype(bool),
                             _bits(wt, "tri_hit").astype(bool), _float(wt, "t_num"),
                             _float(wt, "t_den"), words, _float(wb, "box_tmin"))


class RequestIssue:
    """Issue a step as a ``REQUEST_DTYPE`` array through ``backend.run``."""

    def __init__(self, backend, rays: np.ndarray, bvh, name: str, words: bool = False):
        self.backend, self.rays, self.bvh, self.name = backend, rays, bvh, name
        self.words = words        # also return the response words (for recording)
        self.wall_s = 0.0

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        req = self.rays[active]
        req["extent"] = ext
        req["tag"] = active
        request_operands(req, self.bvh.image, ptr)
        t0 = time.perf_counter()
        rsp = self.backend.run(req)
        self.wall_s += time.perf_counter() - t0
        _check_order(rsp["tag"], active, self.name)
        return StepResponses(rsp["box_index"][bi], rsp["box_hit"][bi].astype(bool),
                             rsp["tri_hit"][ti].astype(bool),
                             rsp["t_num"][ti].astype(np.float32),
                             rsp["t_den"][ti].astype(np.float32),
                             pack_responses(rsp) if self.words else None,
                             rsp["box_tmin"][bi].astype(np.float32))


class Recorder:
    """Wraps an issuer and keeps every request (ray, node pointer, extent) and its response
    words, in issue order; ``record(params)`` returns them as a ``driver.rtunit.Record``."""

    def __init__(self, inner, rays: np.ndarray, bvh):
        self.inner = inner
        if isinstance(inner, RequestIssue):
            inner.words = True
        self.ray_words = getattr(inner, "ray_words", None)
        if self.ray_words is None:
            self.ray_words = ray_words(rays)
        self.image = bvh.image.view("<u4")
        self.parts: list[tuple] = []

    @property
    def wall_s(self) -> float:
        return self.inner.wall_s

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        rsp = self.inner(active, ptr, ext, bi, ti)
        self.parts.append((active.astype(np.uint32), ptr, np.asarray(ext, np.float32),
                           rsp.words))
        return rsp

    def record(self, params: dict):
        from .rtunit import Record

        def cat(k, dtype, shape=(0,)):
            return (np.concatenate([p[k] for p in self.parts]) if self.parts
                    else np.zeros(shape, dtype))

        return Record(self.ray_words, self.image, cat(0, np.uint32), cat(1, np.uint32),
                      cat(2, np.float32), cat(3, np.uint32, (0, RSP_WORDS)), params)


def issuer(backend, rays: np.ndarray, bvh, name: str, record: bool = False):
    """The issuer for ``backend`` (``NodeIssue`` when it has ``run_nodes``), wrapped in a
    ``Recorder`` when ``record``."""
    fast = isinstance(backend, NodeBackend)
    inner = NodeIssue(backend, rays, bvh, name) if fast else RequestIssue(backend, rays, bvh, name)
    return Recorder(inner, rays, bvh) if record else inner
