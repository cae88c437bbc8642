"""From the binary tree to 4-wide box nodes: which binary nodes become box nodes.

Collapse (``collapse_sah``): the dynamic programme of Ylitie, Karras and Laine 2017 ("Efficient
incoherent ray traversal on GPUs through compressed wide BVHs"), specialised to one triangle per
leaf: the SAH cost of a wide tree is the sum of the areas of its used child slots (box and
triangle nodes), so with ``D(n, k)`` = least cost of representing binary subtree ``n`` by at most
``k`` slots of its wide parent::

    leaf:       D(n, k) = A(n)
    interior:   D(n, 1) = A(n) + min_{a=1..3} D(l, a) + D(r, 4 - a)     (n becomes a box node)
                D(n, k) = min(D(n, k - 1), min_{a=1..k-1} D(l, a) + D(r, k - a))

The root is always a box node; its slots come from the ``D(n, 1)`` choice. The wide nodes are
emitted breadth first (root first; a node's box children in slot order), which is the order the
image writer numbers them in.

The greedy collapse (``_collapse``, ``collapse="greedy"`` of ``driver.bvh.pipeline.build``,
kept for comparisons) starts each 4-wide node with the binary node's two children and twice
replaces the interior child of largest surface area by its two children (triangle children
are never opened).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .params import WIDTH


@njit(cache=True, nogil=True)
def _dp(left, right, area):
    """Bottom-up D(n, k) table (see module docstring) and the choices: choice[n, k-1] = slots
    given to the left child (0: D(n, k) = D(n, k - 1)). k runs to WIDTH - 1 only: a child of a
    split gets at most WIDTH - 1 slots (its sibling needs one)."""
    return dp_table(left, right, area, area, np.full(len(left), np.inf))[0]


@njit(cache=True, nogil=True)
def dp_table(left, right, leaf_cost, node_cost, alt_cost):
    """``_dp``'s table with costs per node: a leaf n costs ``leaf_cost[n]``, an interior node
    made a wide node ``node_cost[n]`` plus its children's, or, in one slot, ``alt_cost[n]``
    instead if less (``driver.bvh.q8``'s group leaves; inf: never). Returns (choice, alt (m,)
    bool: where the alternative is the least D(n, 1))."""
    m = len(left)
    d = np.empty((m, WIDTH - 1))
    choice = np.zeros((m, WIDTH - 1), np.int8)
    alt = np.zeros(m, np.bool_)
    for n in range(m - 1, -1, -1):                         # children are numbered after parents
        l, r = left[n], right[n]
        if l < 0:
            d[n, :] = leaf_cost[n]
            continue
        best, ba = np.inf, 0
        for a in range(1, WIDTH):
            c = d[l, a - 1] + d[r, WIDTH - a - 1]
            if c < best:
                best, ba = c, a
        d[n, 0] = node_cost[n] + best
        choice[n, 0] = ba
        if alt_cost[n] < d[n, 0]:
            d[n, 0], alt[n] = alt_cost[n], True
        for k in range(2, WIDTH):
            best, ba = d[n, k - 2], 0
            for a in range(1, k):
                c = d[l, a - 1] + d[r, k - a - 1]
                if c < best:
                    best, ba = c, a
            d[n, k - 1] = best
            choice[n, k - 1] = ba
    return choice, alt


@njit(cache=True, inline="always")
def pop_slots(work, wp, choice):
    """Pop the top (binary node x, slots k) of a walk's stack ``work`` (``wp`` entries) down the
    table ``choice``: k lowered to the slots x really takes where the table chose fewer. Returns
    (wp - 1, x, k). The collapse (``_emit``) and the group leaves' choice
    (``driver.bvh.q8g``) walk their tables with it."""
    wp -= 1
    x, k = work[wp, 0], work[wp, 1]
    while k > 1 and choice[x, k - 1] == 0:
        k -= 1
    return wp, x, k


@njit(cache=True, inline="always")
def push_children(work, wp, x, k, c, left, right):
    """Push binary node x's children onto the walk's stack, the right one with k - c slots, the
    left one (popped first) with c. Returns the new ``wp``."""
    work[wp, 0], work[wp, 1] = right[x], k - c
    work[wp + 1, 0], work[wp + 1, 1] = left[x], c
    return wp + 2


@njit(cache=True, nogil=True)
def _emit(left, right, choice):
    """Wide nodes breadth first: (slots (k, 4) binary ids, -1 = unused, used first; depth of
    each wide node)."""
    m = len(left)
    cap = max(1, (m + 1) // 2)                             # wide nodes <= interior nodes + 1
    slots = np.full((cap, WIDTH), -1, np.int64)
    depth = np.zeros(cap, np.int64)
    queue = np.empty(cap, np.int64)
    queue[0] = 0
    head, tail = 0, 1
    work = np.empty((2 * WIDTH + 2, 2), np.int64)         # (binary node, slots) to expand
    while head < tail:
        n = queue[head]
        row = head
        head += 1
        used = 0
        if left[n] < 0:                                    # single-triangle tree
            slots[row, 0] = n
            continue
        a = choice[n, 0]
        work[0, 0], work[0, 1] = right[n], WIDTH - a        # stack: right pushed first
        work[1, 0], work[1, 1] = left[n], a
        wp = 2
        while wp > 0:
            wp, x, k = pop_slots(work, wp, choice)
            if k == 1:
                slots[row, used] = x
                used += 1
                if left[x] >= 0:
                    queue[tail] = x
                    depth[tail] = depth[row] + 1
                    tail += 1
            else:
                wp = push_children(work, wp, x, k, choice[x, k - 1], left, right)
    return slots[:tail], depth[:tail]


def collapse_sah(left, right, area):
    """SAH-optimal 4-wide levels from the binary tree: a list, root level first, of (k, 4) arrays
    of binary node ids per wide box node (-1 = unused slot; used slots first)."""
    slots, depth = _emit(left, right, _dp(left, right, area))
    return np.split(slots, np.flatnonzero(np.diff(depth)) + 1)


def _collapse(left, right, area):
    """Greedy collapse: 4-wide levels from the binary tree: a list, root level first, of (k, 4) arrays of binary
    node ids per 4-wide box node (-1 = unused slot; used slots first)."""
    levels = []
    if left[0] < 0:                                       # single triangle: root has one child
        slots = np.array([[0, -1, -1, -1]])
    else:
        slots = np.full((1, 4), -1)
        slots[0, :2] = left[0], right[0]
    while len(slots):
        rows = np.arange(len(slots))
        for free in (2, 3):                               # open the largest interior child, twice
            interior = (slots >= 0) & (left[slots] >= 0)
            a = np.where(interior, area[slots], -np.inf)
            j = np.argmax(a, axis=1)
            ok = interior[rows, j]
            r, jj = rows[ok], j[ok]
            opened = slots[r, jj]
            slots[r, jj] = left[opened]
            slots[r, free] = right[opened]
        levels.append(slots)
        nxt = slots[(slots >= 0) & (left[slots] >= 0)]          # row-major: breadth-first order
        slots = np.full((len(nxt), 4), -1)
        slots[:, 0], slots[:, 1] = left[nxt], right[nxt]
    return levels
