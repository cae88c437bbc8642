"""How a traversal step's requests reach a datapath backend (the ``Issue`` of
``driver.traversal``), and the recorder of every request for the RT-unit replay.

- ``NodeIssue``: a backend with ``run_nodes`` (the "rtl" harness) gets (ray index, node pointer,
  extent) triples and assembles the request words itself from the packed ray table and the BVH4
  image (no per-request Python work); the host decodes only the response bits it needs.
- ``RequestIssue``: any other backend gets a ``REQUEST_DTYPE`` array built in numpy from the
  prepared rays and the decoded nodes, by the same rules (tests check the words are identical).
- ``Recorder``: wraps either and keeps every request and response as a
  ``driver.tracing.record.Record``.

Both check that the responses come back in order with the ray index in their ``tag``. The ray
table grows when a traversal enters instances (``add_rays``: each transformed ray is a new row,
``driver.instances``); a request then names its ray by that row. With the instance transform on
the datapath, ``transforms`` issues a batch of TRANSFORM requests the same way: a world ray's
row and an instance node's pointer each (the harness, or ``request_operands``, puts the node's
``world_to_object`` on the request's ``matrix``).
"""

from __future__ import annotations

import time

import numpy as np

from ..backends.base import NodeBackend
from ..backends.build import backend_params
from ..bvh4 import request_operands
from ..core.datapath import DatapathError
from ..core.layout import NO_CHILD
from ..core.wire import RESPONSE, RSP_WORDS, pack_responses, ray_words
from ..traversal import StepResponses
from .record import Record


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


def transformed(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(o', d'), each (m, 3) float32, of TRANSFORM response words (m, RSP_WORDS)."""
    return _float(words, "xf_origin").copy(), _float(words, "xf_dir").copy()


def _check_order(got_tags: np.ndarray, active: np.ndarray, name: str) -> None:
    if len(got_tags) != len(active) or not np.array_equal(got_tags, active):
        raise RuntimeError(f"backend {name!r} returned responses out of order or with altered "
                           "tags")


class _Rows:
    """A table of rows that grows by appending (capacity doubling); ``rows`` is the used part.
    The issuers keep their rays in one: a traversal through instances appends each transformed
    ray (``driver.instances``) and names it by its row."""

    def __init__(self, rows: np.ndarray):
        self._buf, self.n = rows, len(rows)

    @property
    def rows(self) -> np.ndarray:
        return self._buf[:self.n]

    def append(self, new: np.ndarray) -> np.ndarray:
        if self.n + len(new) > len(self._buf):
            grown = np.empty((max(2 * len(self._buf), self.n + len(new)),) + self._buf.shape[1:],
                             self._buf.dtype)
            grown[:self.n] = self.rows
            self._buf = grown
        self._buf[self.n:self.n + len(new)] = new
        self.n += len(new)
        return np.arange(self.n - len(new), self.n, dtype=np.int64)


class NodeIssue:
    """Issue a step through ``backend.run_nodes`` (the harness assembles the requests)."""

    def __init__(self, backend, rays: np.ndarray, bvh, name: str):
        self.backend, self.name = backend, name
        self._table = _Rows(ray_words(rays))
        self.image = bvh.image.view("<u4")
        self.wall_s = 0.0         # time inside the backend (the simulation's share)

    @property
    def ray_words(self) -> np.ndarray:
        return self._table.rows

    def add_rays(self, rays: np.ndarray, owner=None, via=None) -> np.ndarray:
        """Append prepared rays to the ray table; returns their rows (``owner``, ``via``: see
        ``Recorder.add_rays``)."""
        return self._table.append(ray_words(rays))

    def _run(self, active, ptr, ext) -> np.ndarray:
        t0 = time.perf_counter()
        words = self.backend.run_nodes(self.ray_words, self.image, active, ptr, ext)
        self.wall_s += time.perf_counter() - t0
        _check_order(words[:, RESPONSE.field["tag"].word], active, self.name)
        return words

    def transforms(self, rows, ptr, ext) -> np.ndarray:
        """Response words (m, RSP_WORDS) of the TRANSFORM requests of ray-table rows ``rows``
        by the instance nodes ``ptr`` (extent ``ext``, unused by the operation). The harness
        does not check requests: a build without the operation is refused here."""
        if not backend_params(self.backend)["TRANSFORM"]:
            raise DatapathError("TRANSFORM needs backend(..., transform=True)")
        return self._run(rows, ptr, ext)

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        words = self._run(active, ptr, ext)
        wb, wt = words[bi], words[ti]
        return StepResponses(_bits(wb, "box_index"), _bits(wb, "box_hit").astype(bool),
                             _bits(wt, "tri_hit").astype(bool), _float(wt, "t_num"),
                             _float(wt, "t_den"), words, _float(wb, "box_tmin"))


class RequestIssue:
    """Issue a step as a ``REQUEST_DTYPE`` array through ``backend.run``."""

    def __init__(self, backend, rays: np.ndarray, bvh, name: str, words: bool = False):
        self.backend, self.bvh, self.name = backend, bvh, name
        self._table = _Rows(rays)
        self.words = words        # also return the response words (for recording)
        self.wall_s = 0.0

    @property
    def rays(self) -> np.ndarray:
        return self._table.rows

    @property
    def ray_words(self) -> np.ndarray:
        return ray_words(self.rays)

    def add_rays(self, rays: np.ndarray, owner=None, via=None) -> np.ndarray:
        """Append prepared rays to the ray table; returns their rows (``owner``, ``via``: see
        ``Recorder.add_rays``)."""
        return self._table.append(rays)

    def _run(self, active, ptr, ext) -> np.ndarray:
        req = self.rays[active]
        req["extent"] = ext
        req["tag"] = active
        request_operands(req, self.bvh.image, ptr, bool(backend_params(self.backend)["COMPRESSED"]))
        t0 = time.perf_counter()
        rsp = self.backend.run(req)
        self.wall_s += time.perf_counter() - t0
        _check_order(rsp["tag"], active, self.name)
        return rsp

    def transforms(self, rows, ptr, ext) -> np.ndarray:
        """Response words of TRANSFORM requests (``NodeIssue.transforms``)."""
        return pack_responses(self._run(rows, ptr, ext))

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        rsp = self._run(active, ptr, ext)
        return StepResponses(rsp["box_index"][bi], rsp["box_hit"][bi].astype(bool),
                             rsp["tri_hit"][ti].astype(bool),
                             rsp["t_num"][ti].astype(np.float32),
                             rsp["t_den"][ti].astype(np.float32),
                             pack_responses(rsp) if self.words else None,
                             rsp["box_tmin"][bi].astype(np.float32))


class Recorder:
    """Wraps an issuer and keeps every request (ray, node pointer, extent) and its response
    words, in issue order; ``record(params)`` returns them as a
    ``driver.tracing.record.Record``."""

    def __init__(self, inner, rays: np.ndarray, bvh):
        self.inner = inner
        if isinstance(inner, RequestIssue):
            inner.words = True
        self.image = bvh.image.view("<u4")
        self.parts: list[tuple] = []
        self.world_rays = len(rays)
        self._owner = _Rows(np.arange(len(rays), dtype=np.uint32))   # row -> ray
        self._via = _Rows(np.full(len(rays), NO_CHILD, np.uint32))   # row -> instance node

    @property
    def wall_s(self) -> float:
        return self.inner.wall_s

    @property
    def ray_words(self) -> np.ndarray:
        return self.inner.ray_words

    def add_rays(self, rays: np.ndarray, owner=None, via=None) -> np.ndarray:
        """Append prepared rays (``NodeIssue.add_rays``); ``owner``: the ray each row belongs to,
        ``via``: the instance node it entered (the record's ``chain`` and ``before``)."""
        self._owner.append(np.asarray(owner, np.uint32))
        self._via.append(np.asarray(via, np.uint32))
        return self.inner.add_rays(rays)

    def __call__(self, active, ptr, ext, bi, ti) -> StepResponses:
        rsp = self.inner(active, ptr, ext, bi, ti)
        self._keep(active, ptr, ext, rsp.words)
        return rsp

    def transforms(self, rows, ptr, ext) -> np.ndarray:
        """``NodeIssue.transforms``, recorded: the TRANSFORM requests join the rays' chains."""
        words = self.inner.transforms(rows, ptr, ext)
        self._keep(rows, ptr, ext, words)
        return words

    def _keep(self, active, ptr, ext, words) -> None:
        self.parts.append((np.asarray(active).astype(np.uint32), np.asarray(ptr, np.uint32),
                           np.asarray(ext, np.float32), words))

    def record(self, params: dict):
        def cat(k, dtype, shape=(0,)):
            return (np.concatenate([p[k] for p in self.parts]) if self.parts
                    else np.zeros(shape, dtype))

        ray = cat(0, np.uint32)
        chain = before = None
        if self._owner.n > self.world_rays:          # rays entered instances (other rows)
            chain = self._owner.rows[ray]
            before = np.full(len(ray), NO_CHILD, np.uint32)
            rows, first = np.unique(ray, return_index=True)     # a row's first request: the
            before[first] = self._via.rows[rows]                 # BLAS root, after its node
        return Record(self.ray_words, self.image, ray, cat(1, np.uint32),
                      cat(2, np.float32), cat(3, np.uint32, (0, RSP_WORDS)), params, chain,
                      before, self.world_rays if chain is not None else None)


def issuer(backend, rays: np.ndarray, bvh, name: str, record: bool = False):
    """The issuer for ``backend`` (``NodeIssue`` when it has ``run_nodes``), wrapped in a
    ``Recorder`` when ``record``."""
    fast = isinstance(backend, NodeBackend)
    inner = NodeIssue(backend, rays, bvh, name) if fast else RequestIssue(backend, rays, bvh, name)
    return Recorder(inner, rays, bvh) if record else inner
