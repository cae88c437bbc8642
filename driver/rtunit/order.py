"""Ray order in the RT unit: which ray enters the ray pool next (``rtunit.replay(ray_order=...)``).

The RT-unit replay issues each ray's recorded request chain; the order in which rays enter the
pool changes which rays share the node cache at a time, hence the hit rate, the bytes fetched and
the cycles, never a request or a response (the replay still checks every response bit for bit).
The policies (``POLICIES``):

- ``index``: rays enter in ray (pixel) order, the RT unit without any ray reordering.
- ``hash``: windows of W consecutive rays sorted by a grid-spherical coherence key (Garanzha &
  Loop 2010; Vulkan-Sim's coherence engine): the Morton code of the ray origin's cell on a
  ``GRID_BITS``-per-axis grid over the scene box, then the direction's spherical bin
  (``THETA_BITS`` bits of the polar angle, ``PHI_BITS`` of the azimuth). Ties keep ray order.
- ``twopoint``: the same sort by the Morton codes of the origin's cell and of an estimated end
  point's cell, origin + direction x min(extent, scene diagonal) (Vulkan-Sim's two-point hash):
  shadow and AO rays have a finite extent, so their end point is known.
- ``affinity``: node-affinity scheduling in the C++ scheduler (sim/rtunit_scheduler.cpp): the RT
  unit holds W rays of which R hold an issue slot; a ray whose next node is not in the node cache
  gives up its slot while its node is fetched (its fetch starts at once) and the slot goes to a
  held ray whose next node is present, first the parked rays whose node has arrived, then a new
  ray (in index order). Ray queues waiting on nodes, as in Aila & Karras's treelet scheduling
  (HPG 2010), with the treelet one node.
- ``hash-affinity``: the ``hash`` order feeding the ``affinity`` scheduler.
- ``treelet``: treelet scheduling (Aila & Karras, "Architecture considerations for tracing
  incoherent rays", HPG 2010) in the C++ scheduler: the BVH is cut into treelets of about
  ``TreeletConfig.treelet_bytes`` (``treelets``); the W held rays wait in per-treelet queues (the
  queue of the treelet of their next node); the unit works on at most ``TreeletConfig.active``
  treelets at once, picking the one with the most queued rays, so a treelet's nodes are fetched
  once and used by many rays; a ray leaving an active treelet joins the queue of its next one.

The cost of each policy (``cost``): what a hardware sorter or scheduler does per ray and the bytes
of ray state its window needs, derived from the request layout (``driver.core.layout``).

The study of docs/rayorder.md (every policy at every window, per scene and ray type) is
``driver.studies.rayorder``.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

from ..core.layout import (BOX_NODE, BOX_TYPE, INSTANCE_NODE, INSTANCE_TYPE, NO_CHILD, NODE_BYTES,
                           Q8_NODE, Q8_TYPE, NodeRef, leaf_request, node_word, read_nodes)
from ..core.wire import REQUEST

GRID_BITS = 5          # origin (and end point) cells per axis: 2**GRID_BITS
THETA_BITS = 2         # polar-angle bins of the direction: 2**THETA_BITS
PHI_BITS = 3           # azimuth bins of the direction: 2**PHI_BITS
DEFAULT_WINDOW = 1024
# What a waiting ray must keep until it is issued: the ray (its tag, the ray index, names it).
# The prepared fields of the request (inverse direction, shear, kx/ky/kz) are recomputed at issue.
RAY_STATE_FIELDS = ("tag", "origin", "dir", "extent", "flags")
POINTER_BYTES = 4      # a node pointer (driver.core.layout.NodeRef) on the traversal stack


@dataclass(frozen=True)
class Policy:
    """One ray-order policy: ``key``: the sort key (None: no sort); ``schedule``: the C++
    scheduler holds the window's rays (node affinity, or with ``treelets`` the treelet queues)."""

    name: str
    key: str | None
    schedule: bool
    help: str
    treelets: bool = False


POLICIES = {p.name: p for p in (
    Policy("index", None, False, "rays enter in ray (pixel) order"),
    Policy("hash", "hash", False, "windows sorted by origin cell and direction bin"),
    Policy("twopoint", "twopoint", False, "windows sorted by origin cell and end-point cell"),
    Policy("affinity", None, True,
           "rays missing the node cache yield their slot to rays whose next node is cached"),
    Policy("hash-affinity", "hash", True, "hash order into the affinity scheduler"),
    Policy("treelet", None, True, "rays queue per BVH treelet; the unit works on the treelets "
           "with the most queued rays", treelets=True),
)}
DEFAULT_POLICY = "index"


@dataclass(frozen=True)
class RayOrder:
    """How rays enter the RT unit: a policy of ``POLICIES`` with its window of rays (None: the
    default, ``DEFAULT_WINDOW``) and, for "treelet", its ``TreeletConfig`` (None: the default)."""

    policy: str = DEFAULT_POLICY
    window: int | None = None
    treelets: "TreeletConfig | None" = None


def policy(name: str) -> Policy:
    if name not in POLICIES:
        raise ValueError(f"unknown ray order {name!r} (choose from {', '.join(POLICIES)})")
    return POLICIES[name]


def check_window(window) -> int:
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ValueError(f"the ray window must be an integer >= 1, got {window!r}")
    return int(window)


# ----------------------------------------------------------------------------------------------
# Keys


def _ray_field(ray_words: np.ndarray, name: str) -> np.ndarray:
    f = REQUEST.field[name]
    cols = np.ascontiguousarray(ray_words[:, f.word:f.word + f.count], np.uint32)
    return cols.view(np.float32).reshape(len(ray_words), *f.shape)


def root_pointer(record) -> int:
    """The BVH root's pointer: the first node of every chain."""
    chain_idx, chain_off = record.chains()
    return int(record.ptr[chain_idx[chain_off[np.flatnonzero(np.diff(chain_off))[0]]]])


def scene_box(record) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the union of the root node's child boxes (every chain starts at the root)."""
    root = root_pointer(record)
    node = read_nodes(record.image, np.array([root], np.uint32), BOX_NODE)[0]
    box = node["box"][node["child"] != NO_CHILD]
    return box[:, :3].min(0).astype(np.float64), box[:, 3:].max(0).astype(np.float64)


def _cells(p: np.ndarray, lo, hi, bits: int) -> np.ndarray:
    q = np.clip(np.nan_to_num((p - lo) / np.maximum(hi - lo, 1e-30)), 0.0, 1.0)
    return np.minimum((q * (1 << bits)).astype(np.int64), (1 << bits) - 1)


def morton(cells: np.ndarray, bits: int) -> np.ndarray:
    """Interleave the bits of (n, k) integer cells (bit b of axis j -> bit b * k + j)."""
    cells = np.asarray(cells, np.uint64)
    k = cells.shape[1]
    out = np.zeros(len(cells), np.uint64)
    for b in range(bits):
        for j in range(k):
            out |= ((cells[:, j] >> np.uint64(b)) & np.uint64(1)) << np.uint64(b * k + j)
    return out


def keys(record, kind: str) -> np.ndarray:
    """(n,) uint64 coherence keys of the record's rays (``kind``: "hash" or "twopoint"): its
    world rays, the first ``record.rays`` rows of the ray table (an instanced scene's
    object-space rays follow them)."""
    words = record.ray_words[:record.rays]
    o = _ray_field(words, "origin").astype(np.float64)
    d = _ray_field(words, "dir").astype(np.float64)
    lo, hi = scene_box(record)
    cell = morton(_cells(o, lo, hi, GRID_BITS), GRID_BITS)
    if kind == "hash":
        u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
        theta = np.arccos(np.clip(u[:, 2], -1.0, 1.0)) / np.pi                  # [0, 1]
        phi = (np.arctan2(u[:, 1], u[:, 0]) + np.pi) / (2 * np.pi)              # [0, 1]
        tb = np.minimum((theta * (1 << THETA_BITS)).astype(np.uint64), (1 << THETA_BITS) - 1)
        pb = np.minimum((phi * (1 << PHI_BITS)).astype(np.uint64), (1 << PHI_BITS) - 1)
        return (cell << np.uint64(THETA_BITS + PHI_BITS)) | (tb << np.uint64(PHI_BITS)) | pb
    if kind == "twopoint":
        ext = _ray_field(words, "extent").astype(np.float64)
        diag = float(np.linalg.norm(hi - lo))
        t = np.minimum(np.where(np.isfinite(ext), ext, diag), diag)
        end = morton(_cells(o + d * t[:, None], lo, hi, GRID_BITS), GRID_BITS)
        return (cell << np.uint64(3 * GRID_BITS)) | end
    raise ValueError(f"unknown key {kind!r}")


def key_bits(kind: str) -> int:
    return 3 * GRID_BITS + (THETA_BITS + PHI_BITS if kind == "hash" else 3 * GRID_BITS)


def permutation(record, name: str, window: int) -> np.ndarray | None:
    """The order in which the record's rays enter the pool under policy ``name``: (n,) int64 ray
    indices, each window of ``window`` consecutive rays sorted by the policy's key (stable);
    None for index order."""
    pol, w = policy(name), check_window(window)
    if pol.key is None or not record.ops:
        return None
    k = keys(record, pol.key)
    n = len(k)
    # a stable sort by (window number, key) sorts every window on its own
    return np.lexsort((k, np.arange(n) // w)).astype(np.int64)


# ----------------------------------------------------------------------------------------------
# Treelets

_CHILD_WORDS = {BOX_TYPE: node_word(BOX_NODE, "child"), Q8_TYPE: node_word(Q8_NODE, "child")}
_SLOTS = BOX_NODE["child"].shape[0]
assert Q8_NODE["child"].shape[0] == _SLOTS


def image_tree(image, root: int) -> tuple[np.ndarray, np.ndarray]:
    """The nodes reachable from ``root`` in a node image, breadth first: (ptr (n,) uint32, parent
    (n,) int64 index, -1 for the root). Box nodes (box32, q8) lead to their children, an instance
    node to its BLAS root; a leaf (triangle, pair or group) is one node; a node reached twice (a
    BLAS shared by instances) is listed once."""
    words = np.asarray(image).reshape(-1).view("<u4")
    level, up = np.array([root], np.uint32), np.array([-1], np.int64)
    ptrs, parents, seen, base = [], [], np.zeros(0, np.int64), 0
    while len(level):
        off = NodeRef.offset(level)
        _, first = np.unique(off, return_index=True)
        keep = np.sort(first)[~np.isin(off[np.sort(first)], seen)]
        level, up = level[keep], up[keep]
        ptrs.append(level)
        parents.append(up)
        seen = np.union1d(seen, NodeRef.offset(level))
        typ, word = NodeRef.type(level), NodeRef.word(level)
        idx = np.arange(len(level), dtype=np.int64) + base
        base += len(level)
        kids, kup = [], []
        for t, cw in _CHILD_WORDS.items():
            sel = typ == t
            c = words[word[sel][:, None] + cw + np.arange(_SLOTS)]
            ok = c != NO_CHILD
            kids.append(c[ok])
            kup.append(np.broadcast_to(idx[sel][:, None], c.shape)[ok])
        sel = typ == INSTANCE_TYPE
        kids.append(words[word[sel] + node_word(INSTANCE_NODE, "blas")])
        kup.append(idx[sel])
        level, up = np.concatenate(kids).astype(np.uint32), np.concatenate(kup)
    return np.concatenate(ptrs), np.concatenate(parents)


def node_bytes(ptrs) -> np.ndarray:
    """Bytes of each node (``driver.core.layout.NODE_BYTES`` by pointer type)."""
    table = np.zeros(8, np.int64)
    for t, b in NODE_BYTES.items():
        table[t] = b
    return table[NodeRef.type(ptrs)]


def treelets(ptrs: np.ndarray, parent: np.ndarray, budget: int) -> np.ndarray:
    """(n,) int64 treelet of each node of ``image_tree`` (breadth first, parents before their
    children): connected pieces of the tree of at most ``budget`` bytes (a node larger than the
    budget alone), formed bottom up: each node's treelet takes its children's open treelets,
    smallest first, while they fit; the children's treelets that do not fit are closed. (Grown
    top down from each treelet's root instead, as Aila & Karras 2010 did, the cut leaves many
    tiny treelets near the leaves.) Treelets are numbered in breadth-first order of their roots
    (the root's is 0)."""
    n = len(ptrs)
    size = node_bytes(ptrs)
    order = np.argsort(parent, kind="stable")               # children grouped by parent
    counts = np.bincount(parent[parent >= 0], minlength=n)
    start = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    kids = order[n - int(counts.sum()):]                    # the root (parent -1) sorts first
    open_ = size.copy()
    merged = np.zeros(n, bool)
    for v in range(n - 1, -1, -1):
        lo, hi = start[v], start[v + 1]
        if lo == hi:
            continue
        ch = kids[lo:hi]
        ch = ch[np.argsort(open_[ch], kind="stable")]
        room = np.cumsum(open_[ch]) + size[v] <= budget
        merged[ch[room]] = True
        open_[v] = size[v] + open_[ch[room]].sum()
    out = np.cumsum(~merged) - 1
    for v in np.flatnonzero(merged):                        # parents first
        out[v] = out[parent[v]]
    return out


@dataclass(frozen=True)
class TreeletConfig:
    """Treelet scheduling: treelets of at most ``treelet_bytes`` (a fraction of the node cache),
    ``active`` treelets worked on at once; ``prefetch``: fetch all of a treelet's nodes when it is
    picked; ``park``: a ray whose next node misses gives up its slot while the node is fetched
    (as ``affinity``); ``borrow``: when every active treelet's queue is empty and no more
    treelets may be active, an idle slot serves one request of the longest queue (without
    activating its treelet) instead of staying idle. docs/rayorder.md compares the defaults with
    the variants ``TREELET_VARIANTS``."""

    treelet_bytes: int = 8 * 1024
    active: int = 4
    prefetch: bool = False
    park: bool = True
    borrow: bool = True

    def __post_init__(self):
        for name in ("treelet_bytes", "active"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"treelets: {name} must be an integer >= 1, got {v!r}")

    def describe(self) -> dict:
        return {"treelet_bytes": int(self.treelet_bytes), "active_treelets": int(self.active),
                "prefetch": bool(self.prefetch), "park": bool(self.park),
                "borrow": bool(self.borrow)}


DEFAULT_TREELETS = TreeletConfig()


@dataclass
class TreeletSchedule:
    """What the C++ treelet scheduler needs for one record: the treelet of each request, the
    number of treelets, the treelets active at once, and (with prefetch) every node's offset,
    bytes and treelet."""

    request_treelet: np.ndarray
    n_treelets: int
    active: int
    prefetch: bool
    park: bool
    borrow: bool
    node_offset: np.ndarray
    node_size: np.ndarray
    node_treelet: np.ndarray

    def prefetch_lists(self):
        """(tl_off (T + 1,), node offsets, node bytes) with treelet t's nodes at
        [tl_off[t], tl_off[t + 1]), or three Nones without prefetch."""
        if not self.prefetch:
            return None, None, None
        by = np.argsort(self.node_treelet, kind="stable")
        off = np.zeros(self.n_treelets + 1, np.int64)
        np.cumsum(np.bincount(self.node_treelet, minlength=self.n_treelets), out=off[1:])
        return (off, np.ascontiguousarray(self.node_offset[by], np.int64),
                np.ascontiguousarray(self.node_size[by], np.int64))

    def describe(self) -> dict:
        return {"treelets": self.n_treelets, "nodes": len(self.node_offset)}


_TREE_CACHE: dict = {}


def _image_key(record) -> tuple:
    """(digest of the record's node image, its root pointer): the key of the per-image caches
    (every batch of a frame replays on the same image)."""
    image = np.ascontiguousarray(record.image)
    return hashlib.blake2b(image.tobytes(), digest_size=16).digest(), root_pointer(record)


def treelet_schedule(record, config: TreeletConfig = DEFAULT_TREELETS) -> TreeletSchedule:
    """The treelet table of the record's BVH (``image_tree``, ``treelets``; cached per image and
    budget) and the treelet of each recorded request (by its node's offset: a leaf's later
    triangles are in their leaf's treelet)."""
    key = (*_image_key(record), int(config.treelet_bytes))
    if key not in _TREE_CACHE:
        ptrs, parent = image_tree(record.image, key[1])
        tl = treelets(ptrs, parent, int(config.treelet_bytes))
        off = NodeRef.offset(ptrs)
        by = np.argsort(off)
        _TREE_CACHE.clear()
        _TREE_CACHE[key] = (off[by], node_bytes(ptrs)[by], tl[by])
    off, size, tl = _TREE_CACHE[key]
    req = leaf_request(record.ptr)[0] * 4       # a leaf's later triangle: the leaf's own offset
    at = np.minimum(np.searchsorted(off, req), len(off) - 1)
    if len(req) and not np.array_equal(off[at], req):
        raise ValueError("a recorded request names a node the BVH image's tree does not hold")
    return TreeletSchedule(tl[at].astype(np.int32), int(tl.max()) + 1, int(config.active),
                           bool(config.prefetch), bool(config.park), bool(config.borrow), off, size,
                           tl)


# ----------------------------------------------------------------------------------------------
# Cost


def ray_state_bytes() -> int:
    """Bytes a waiting ray occupies in a sorter's or scheduler's buffer: ``RAY_STATE_FIELDS`` of
    the request layout (the prepared fields are recomputed at issue)."""
    return math.ceil(sum(REQUEST.field[f].total_bits for f in RAY_STATE_FIELDS) / 8)


def tree_depth(record) -> int:
    """Box levels of the record's BVH (the root with only leaf children: 1), for any node image
    (``image_tree``)."""
    if not record.ops:
        return 0
    key = ("depth", *_image_key(record))
    if key not in _DEPTH_CACHE:
        ptrs, parent = image_tree(record.image, root_pointer(record))
        level = np.zeros(len(ptrs), np.int64)
        for i in range(1, len(ptrs)):                     # parents come first
            level[i] = level[parent[i]] + 1
        _DEPTH_CACHE.clear()
        _DEPTH_CACHE[key] = int(level[NodeRef.is_box(ptrs)].max()) + 1
    return _DEPTH_CACHE[key]


_DEPTH_CACHE: dict = {}


def stack_entries(depth: int) -> int:
    """Traversal stack capacity of ``driver.traversal``: a popped box node leaves <= 3 siblings
    per level and pushes <= 4 children."""
    return 3 * depth + 2


def bitonic_compare_exchanges(w: int) -> int:
    """Compare-exchange elements of a bitonic sorting network of w inputs (w rounded up to a
    power of two): w/2 per stage, log2(w) (log2(w) + 1) / 2 stages."""
    p = max(1, int(2 ** math.ceil(math.log2(max(w, 1)))))
    lg = int(math.log2(p))
    return p // 2 * lg * (lg + 1) // 2


def cost(name: str, window: int, rays: int, rays_in_flight: int, depth: int,
         sched: dict | None = None, treelets=None) -> dict:
    """What policy ``name`` with a window of ``window`` rays costs in hardware, for ``rays`` rays:
    keys computed, comparisons (a bitonic network per window), buffer entries and their bytes;
    for the scheduler, the rays it holds beyond the pool with their traversal state (ray, next
    node pointer, stack) and how often it parked and resumed rays (``sched``: the replay's
    counts)."""
    pol, w = policy(name), check_window(window)
    ray_b = ray_state_bytes()
    out = {"ray_order": name, "ray_window": w, "rays": rays, "ray_state_bytes": ray_b}
    if pol.key is not None:
        full, rest = divmod(rays, w)
        cmp = full * bitonic_compare_exchanges(w) + (bitonic_compare_exchanges(rest) if rest else 0)
        out.update(keys_computed=rays, key_bits=key_bits(pol.key), sort_buffer_entries=w,
                   sort_buffer_bytes=w * (ray_b + (key_bits(pol.key) + 7) // 8),
                   compare_exchanges=cmp, compare_exchanges_per_ray=cmp / rays if rays else 0.0)
    if pol.schedule:
        held = max(w - rays_in_flight, 0)
        traversal_b = ray_b + POINTER_BYTES * (1 + stack_entries(depth))
        out.update(held_rays=w, extra_rays_held=held, traversal_state_bytes=traversal_b,
                   extra_state_bytes=held * traversal_b)
        if sched and not pol.treelets:
            out.update({k: sched[k] for k in ("parked", "resumed", "max_parked", "max_held")},
                       extra_tag_lookups=sched["resumed"],
                       parked_per_ray=sched["parked"] / rays if rays else 0.0)
    if pol.treelets and treelets is not None:
        config, tab = treelets
        out.update(treelet_cost(config, tab.n_treelets, len(tab.node_offset), w))
        if sched:
            out.update(picks=sched["picks"], max_queued=sched["max_queued"],
                       parked=sched["parked"], resumed=sched["resumed"],
                       borrowed=sched["borrowed"],
                       max_held=sched["max_held"],
                       pick_comparisons=sched["picks"] * max(tab.n_treelets - 1, 0),
                       picks_per_ray=sched["picks"] / rays if rays else 0.0)
    return out


def _bits(n: int) -> int:
    """Bits of an index into n things."""
    return max(1, math.ceil(math.log2(max(n, 2))))


def treelet_cost(config: TreeletConfig, n_treelets: int, nodes: int, window: int) -> dict:
    """Storage of treelet scheduling beyond the held rays' state: the per-treelet queues (a linked
    list through the W ray entries: a next index per entry; per treelet a head, a tail and a count)
    and the treelet table (a treelet number per node; an image laid out treelet by treelet would
    need only the treelets' start offsets)."""
    queue_bits = window * _bits(window) + n_treelets * (2 * _bits(window) + _bits(window + 1))
    return {**config.describe(), "treelets": n_treelets, "treelet_nodes": nodes,
            "queue_entries": window, "queue_bytes": math.ceil(queue_bits / 8),
            "treelet_table_bytes": math.ceil(nodes * _bits(n_treelets) / 8)}


_SUMMED = ("keys_computed", "compare_exchanges", "parked", "resumed", "extra_tag_lookups", "rays",
           "picks", "pick_comparisons", "borrowed")
_MAXED = ("max_parked", "max_held", "traversal_state_bytes", "extra_state_bytes", "max_queued",
          "queue_bytes", "treelet_table_bytes", "treelets", "treelet_nodes")


def merge_costs(costs: list[dict]) -> dict:
    """The cost of several replays run one after another (``cost`` dicts with their ``rays``):
    counts added, buffer sizes the largest, per-ray figures over all rays."""
    out = dict(costs[0])
    for k in _SUMMED:
        if k in out:
            out[k] = sum(c[k] for c in costs)
    for k in _MAXED:
        if k in out:
            out[k] = max(c[k] for c in costs)
    rays = out["rays"]
    if "compare_exchanges" in out:
        out["compare_exchanges_per_ray"] = out["compare_exchanges"] / rays if rays else 0.0
    if "parked" in out:
        out["parked_per_ray"] = out["parked"] / rays if rays else 0.0
    if "picks" in out:
        out["picks_per_ray"] = out["picks"] / rays if rays else 0.0
    return out


# ----------------------------------------------------------------------------------------------
# The study (docs/rayorder.md)


def floor_bytes(records, line_bytes: int) -> int:
    """Bytes every order must fetch with a cold cache: each distinct line the batches touch, once
    per batch (each replay starts cold)."""
    total = 0
    for rec in records:
        size = node_bytes(rec.ptr)
        off = NodeRef.offset(rec.ptr)[size > 0]      # a pair's second triangle: no bytes more
        size = size[size > 0]
        first, last = off // line_bytes, (off + size - 1) // line_bytes
        lines = np.unique(np.concatenate([first, last]))
        total += len(lines) * line_bytes
    return total
