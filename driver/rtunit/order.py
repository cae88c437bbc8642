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

The cost of each policy (``cost``): what a hardware sorter or scheduler does per ray and the bytes
of ray state its window needs, derived from the request layout (``driver.layout``).

``python -m driver.rtunit.order --json docs/rayorder.json --plot images/rayorder.png`` runs the
study of docs/rayorder.md: per scene and ray type, every policy at every window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..layout import BOX_NODE, NO_CHILD, REQUEST, NodeRef, read_nodes

GRID_BITS = 5          # origin (and end point) cells per axis: 2**GRID_BITS
THETA_BITS = 2         # polar-angle bins of the direction: 2**THETA_BITS
PHI_BITS = 3           # azimuth bins of the direction: 2**PHI_BITS
DEFAULT_WINDOW = 1024
STUDY_WINDOWS = (64, 256, 1024, 4096)
# What a waiting ray must keep until it is issued: the ray (its tag, the ray index, names it).
# The prepared fields of the request (inverse direction, shear, kx/ky/kz) are recomputed at issue.
RAY_STATE_FIELDS = ("tag", "origin", "dir", "extent", "flags")
POINTER_BYTES = 4      # a node pointer (driver.layout.NodeRef) on the traversal stack


@dataclass(frozen=True)
class Policy:
    """One ray-order policy: ``key``: the sort key (None: no sort); ``schedule``: the C++
    node-affinity scheduler holds the window's rays."""

    name: str
    key: str | None
    schedule: bool
    help: str


POLICIES = {p.name: p for p in (
    Policy("index", None, False, "rays enter in ray (pixel) order"),
    Policy("hash", "hash", False, "windows sorted by origin cell and direction bin"),
    Policy("twopoint", "twopoint", False, "windows sorted by origin cell and end-point cell"),
    Policy("affinity", None, True,
           "rays missing the node cache yield their slot to rays whose next node is cached"),
    Policy("hash-affinity", "hash", True, "hash order into the affinity scheduler"),
)}
DEFAULT_POLICY = "index"


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


def scene_box(record) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the union of the root node's child boxes (every chain starts at the root)."""
    chain_idx, chain_off = record.chains()
    root = record.ptr[chain_idx[chain_off[np.flatnonzero(np.diff(chain_off))[0]]]]
    node = read_nodes(record.image, np.array([root], np.uint32), BOX_NODE)[0]
    box = node["box"][node["child"] != NO_CHILD]
    return box[:, :3].min(0).astype(np.float64), box[:, 3:].max(0).astype(np.float64)


def _cells(p: np.ndarray, lo, hi, bits: int) -> np.ndarray:
    q = np.clip((p - lo) / np.maximum(hi - lo, 1e-30), 0.0, 1.0)
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
    """(n,) uint64 coherence keys of the record's rays (``kind``: "hash" or "twopoint")."""
    o = _ray_field(record.ray_words, "origin").astype(np.float64)
    d = _ray_field(record.ray_words, "dir").astype(np.float64)
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
        ext = _ray_field(record.ray_words, "extent").astype(np.float64)
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
    if pol.key is None:
        return None
    k = keys(record, pol.key)
    n = len(k)
    # a stable sort by (window number, key) sorts every window on its own
    return np.lexsort((k, np.arange(n) // w)).astype(np.int64)


# ----------------------------------------------------------------------------------------------
# Cost


def ray_state_bytes() -> int:
    """Bytes a waiting ray occupies in a sorter's or scheduler's buffer: ``RAY_STATE_FIELDS`` of
    the request layout (the prepared fields are recomputed at issue)."""
    return math.ceil(sum(REQUEST.field[f].total_bits for f in RAY_STATE_FIELDS) / 8)


def tree_depth(record) -> int:
    """Box levels of the record's BVH (the root with only triangle children: 1)."""
    lo_chain = record.chains()
    level = np.array([record.ptr[lo_chain[0][0]]], np.uint32) if record.ops else np.zeros(0)
    depth = 0
    while len(level):
        depth += 1
        child = read_nodes(record.image, level, BOX_NODE)["child"].ravel()
        level = child[(child != NO_CHILD) & NodeRef.is_box(child)]
    return depth


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
         sched: dict | None = None) -> dict:
    """What policy ``name`` with a window of ``window`` rays costs in hardware, for ``rays`` rays:
    keys computed, comparisons (a bitonic network per window), buffer entries and their bytes;
    for the scheduler, the rays it holds beyond the pool with their traversal state (ray, next
    node pointer, stack) and how often it parked and resumed rays (``sched``: the replay's
    counts)."""
    pol, w = policy(name), check_window(window)
    ray_b = ray_state_bytes()
    out = {"ray_order": name, "ray_window": w, "ray_state_bytes": ray_b}
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
        if sched:
            out.update({k: sched[k] for k in ("parked", "resumed", "max_parked", "max_held")},
                       extra_tag_lookups=sched["resumed"],
                       parked_per_ray=sched["parked"] / rays if rays else 0.0)
    return out
