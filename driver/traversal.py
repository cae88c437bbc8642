"""BVH4 traversal, wavefront style (docs/datapath.md#traversal): the loop and nothing else.

Every ray has a stack of node pointers (root first). Each step, every ray with a non-empty stack
pops one node and turns it into one datapath request:

- box node -> QUADBOX with the node's four child boxes and extent = the ray's nearest t so far;
  the response lists the children nearest first (``box_index``/``box_hit``), and the hit ones are
  pushed in reverse so that the nearest is popped next;
- a q8 box node (q8 and q8g images) -> the same QUADBOX on its decoded child boxes;
- a triangle-pair leaf or a group leaf (q8g: 3 to 6 triangles) -> one TRIANGLE request of the
  ray per triangle, in the leaf's order: the first in this step; then a ``LEAF_NEXT_TYPE``
  pointer naming the leaf's next triangle is pushed and so is the ray's next request (an any-hit
  ray finished by one triangle never issues the rest);
- triangle node -> TRIANGLE; on ``tri_hit`` the host computes
  ``t = float32(t_num) / float32(t_den)`` and keeps it if ``t < nearest`` (strictly: on an exact
  tie the triangle found first stays). An any-hit ray (occlusion) is finished by that first
  accepted triangle: the rest of its stack is dropped and never issued.

``cull=True`` (off by default: docs/datapath.md#traversal has a stack of node pointers only) also
keeps each pushed child's entry distance (the response's ``box_tmin``) on the stack, as CPU
traversals such as Embree's do, and drops a popped box node without a request when that distance is
not below the ray's nearest hit. The request it saves would have come back with four misses: the
node's child boxes lie inside its own stored box (the builder grows boxes monotonically), so each
child's ``tmin`` is at least the node's, hence at least the ray's extent, and QUADBOX's ``tmin <
tmax`` fails. So hits are exactly those of ``cull=False`` and only box requests (and the bytes their
nodes would have cost) disappear. Triangle nodes are never dropped: their ``t`` is not bounded
by their box's rounded ``tmin``. The stack then holds a float32 per entry beside the pointer,
which an RT unit would pay for in stack storage.

All of a step's requests go to the datapath through one ``issue`` call (``driver.tracing.issue``:
the "rtl" harness assembles them from the ray table and the BVH4 image; other backends get request
arrays), so the datapath sees a full stream and Python does a handful of vectorised numpy
operations per step, never work per request. The traversal knows nothing of backends, recording,
timing or statistics: ``driver.tracer`` composes those around it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .core.layout import (BOX_NODE, BOX_TYPE, NO_CHILD, NODE_BYTES, Q8_NODE, Q8_TYPE, TRI_TYPE,
                          NodeRef, leaf_count, leaf_next, leaf_prim_word, leaf_request, node_word)

_LANES = np.arange(BOX_NODE["child"].shape[0])
_CHILD_WORD = np.zeros(8, np.int64)           # per box-node type (a two-level image has both)
_CHILD_WORD[BOX_TYPE] = node_word(BOX_NODE, "child")
_CHILD_WORD[Q8_TYPE] = node_word(Q8_NODE, "child")
_BYTES = np.zeros(8, np.int64)                # per pointer type: node bytes a request fetches
for _t, _b in NODE_BYTES.items():
    _BYTES[_t] = _b


@dataclass
class StepResponses:
    """What a step's datapath responses tell the traversal, for the box requests (``bi`` order)
    and the triangle requests (``ti`` order) of the step.

    box_index : (nb, 4) integer, child slots nearest first; box_hit : (nb, 4) bool, same order
    tri_hit : (nt,) bool; t_num, t_den : (nt,) float32
    words : (n, RSP_WORDS) uint32 response words of the whole step, when the issuer has them
    box_tmin : (nb, 4) float32, entry distances in box_index order (needed by ``cull``)
    """

    box_index: np.ndarray
    box_hit: np.ndarray
    tri_hit: np.ndarray
    t_num: np.ndarray
    t_den: np.ndarray
    words: np.ndarray | None = None
    box_tmin: np.ndarray | None = None


# issue(active rays (n,) int64, node pointers (n,) uint32, extents (n,) float32,
#       box rows (nb,) intp, triangle rows (nt,) intp) -> StepResponses
Issue = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], StepResponses]


@dataclass
class Traversal:
    """Per-ray results of a traversal.

    nearest : (n,) float32, t of the hit (the ray's extent where it found none)
    prim : (n,) int64, primitive id of the hit (-1: none)
    box_ops, tri_ops : (n,) int64, QUADBOX / TRIANGLE requests issued for each ray
    node_bytes : (n,) int64, node bytes each ray's requests fetched (``layout.NODE_BYTES``)
    culled : (n,) int64, box nodes dropped from each ray's stack by ``cull`` (no request)
    cull_events : (k, 3) int64 (none without ``cull``): a row per ray and step that culled, of
        the ray, the requests it had issued before (its chain position: box, triangle and
        TRANSFORM requests) and the entries it culled then (what an RT unit's pop port does)
    step_requests, step_box_requests : (calls,) int64, requests (all / QUADBOX) per backend
        call: one per step, and before it the step's TRANSFORM requests, if any (an instance
        transform on the datapath)
    """

    nearest: np.ndarray
    prim: np.ndarray
    box_ops: np.ndarray
    tri_ops: np.ndarray
    step_requests: np.ndarray
    step_box_requests: np.ndarray
    culled: np.ndarray
    node_bytes: np.ndarray
    cull_events: np.ndarray = None


def traverse(bvh, extent: np.ndarray, issue: Issue, any_hit: bool = False,
             progress: Callable[[int, int], None] | None = None,
             cull: bool = False, instances=None) -> Traversal:
    """Traverse ``bvh`` (a ``driver.bvh4.BVH4``) for n rays whose extents are ``extent`` (n,)
    float32; ``issue`` runs each step's requests on a datapath (see ``Issue``). ``any_hit``: a ray
    ends at its first accepted triangle (occlusion). ``cull``: drop box nodes whose entry
    distance is not below the nearest hit (module docstring). ``progress(done_rays, total_rays)``
    is called once per step. ``instances``: a ``driver.tracing.stepper.InstanceStepper``
    (two-level images): it enters the instance nodes on top of the stacks before each step, and
    the requests name each ray by its row in the issuer's ray table (``instances.row``)."""
    n = len(extent)
    nearest = np.array(extent, np.float32, copy=True)
    prim = np.full(n, -1, np.int64)
    box_ops = np.zeros(n, np.int64)
    tri_ops = np.zeros(n, np.int64)
    node_bytes = np.zeros(n, np.int64)
    # a popped box node leaves <= 3 siblings per level on the stack and pushes <= 4 children
    stack = np.empty((n, 3 * bvh.stats["depth"] + 2), np.uint32)
    stack[:, 0] = bvh.root
    dist = np.zeros(stack.shape, np.float32) if cull else None    # entry distances (root: 0)
    culled = np.zeros(n, np.int64)
    sp = np.ones(n, np.int64)
    steps, steps_box, events = [], [], [np.zeros((0, 3), np.int64)]
    image = bvh.image.view("<u4")
    active = np.arange(n)
    while len(active):
        sp[active] -= 1
        if cull:
            active = _cull_logged(active, stack, dist, sp, nearest, culled, events,
                                  box_ops + tri_ops, instances)
            if not len(active):
                if progress is not None:
                    progress(n, n)
                break
        if instances is not None:
            active = instances.step(active, stack, sp, nearest)
            calls = instances.transform_calls()     # TRANSFORM batches: a backend call each
            steps += calls
            steps_box += [0] * len(calls)
            if not len(active):
                if progress is not None:
                    progress(n, n)
                break
        ptr = stack[active, sp[active]]
        typ = NodeRef.type(ptr)
        is_box = NodeRef.is_box(ptr)
        bi, ti = np.flatnonzero(is_box), np.flatnonzero(~is_box)
        base = NodeRef.word(ptr)
        node_bytes[active] += _BYTES[typ]
        rows = active if instances is None else instances.row[active]
        rsp = issue(rows, ptr, nearest[active], bi, ti)
        steps.append(len(active))
        steps_box.append(len(bi))

        # box nodes: push the hit children, farthest first, so that the nearest is popped next
        ray_b = active[bi]
        box_ops[ray_b] += 1
        children = image[base[bi, None] + _CHILD_WORD[typ[bi], None] + _LANES]
        _push_hit_children(ray_b, children, rsp, stack, dist, sp)

        # triangle nodes: keep a strictly nearer hit; an any-hit ray is done at its first one
        ray_t = active[ti]
        tri_ops[ray_t] += 1
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = rsp.t_num / rsp.t_den
        better = rsp.tri_hit & (t < nearest[ray_t])
        nearest[ray_t[better]] = t[better]
        tb = ti[better]
        prim[ray_t[better]] = image[leaf_prim_word(ptr[tb])].astype(np.int64)
        if instances is not None:
            instances.hit(ray_t[better])
        if any_hit:
            sp[ray_t[better]] = 0
        _push_rest_of_leaf(active, ti, typ, ptr, better if any_hit else None, image, stack, sp)

        active = active[sp[active] > 0]
        if progress is not None:
            progress(n - len(active), n)
    return Traversal(nearest, prim, box_ops, tri_ops, np.array(steps, np.int64),
                     np.array(steps_box, np.int64), culled, node_bytes, np.concatenate(events))


def _cull_logged(active, stack, dist, sp, nearest, culled, events, issued,
                 instances) -> np.ndarray:
    """``_cull``, and a row in ``events`` for each ray that culled: the ray, the requests it
    had issued (``issued``: its box and triangle requests, and its TRANSFORM requests) and the
    entries it culled now (``Traversal.cull_events``)."""
    before = culled[active]
    rays = active
    active = _cull(active, stack, dist, sp, nearest, culled)
    got = culled[rays] - before
    r = rays[got > 0]
    issued = issued[r] + (instances.transform_ops[r] if instances is not None else 0)
    events.append(np.stack([r, issued, got[got > 0]], axis=1).astype(np.int64))
    return active


def _push_hit_children(ray_b, children, rsp, stack, dist, sp) -> None:
    """Push the hit children of the box nodes of rays ``ray_b`` (their four child pointers
    ``children``, the box responses ``rsp``), farthest first, so that the nearest is popped
    next; with culling (``dist`` not None) also their entry distances."""
    hit = rsp.box_hit[:, ::-1]
    child = np.take_along_axis(children, rsp.box_index.astype(np.intp), 1)[:, ::-1]
    if (child[hit] == NO_CHILD).any():
        raise RuntimeError("the datapath reported a hit on an unused box slot")
    col = sp[ray_b][:, None] + np.cumsum(hit, axis=1) - 1
    r, c = np.nonzero(hit)
    stack[ray_b[r], col[r, c]] = child[r, c]
    if dist is not None:
        dist[ray_b[r], col[r, c]] = rsp.box_tmin[:, ::-1][r, c]
    sp[ray_b] += hit.sum(axis=1)


def _push_rest_of_leaf(active, ti, typ, ptr, done, image, stack, sp) -> None:
    """The rest of a leaf is the ray's next request: its next triangle, named by a
    LEAF_NEXT_TYPE pointer, pushed for the triangle-node requests ``ti`` of the step (``done``:
    an any-hit step's accepted hits, whose rays end here; None for closest-hit)."""
    leaf = ti[typ[ti] != TRI_TYPE]
    if done is not None:
        leaf = leaf[~done[np.searchsorted(ti, leaf)]]
    k = leaf_request(ptr[leaf])[1] + 1
    more = k < leaf_count(image, ptr[leaf])
    leaf, k = leaf[more], k[more]
    ray_l = active[leaf]
    stack[ray_l, sp[ray_l]] = leaf_next(ptr[leaf], k)
    sp[ray_l] += 1


def _cull(active, stack, dist, sp, nearest, culled) -> np.ndarray:
    """Pop, for every active ray, the box nodes on top of its stack whose entry distance is not
    below its nearest hit (``sp`` already points at the top entry); returns the rays that still
    have an entry to issue."""
    while True:
        top = sp[active]
        drop = NodeRef.is_box(stack[active, top]) & (dist[active, top] >= nearest[active])
        if not drop.any():
            return active
        gone = active[drop]
        culled[gone] += 1
        sp[gone] -= 1
        active = active[sp[active] >= 0]
        sp[gone[sp[gone] < 0]] = 0
