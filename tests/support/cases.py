"""The paper's 20 directed cases (docs/datapath.md#directed-cases) as request arrays with their
expected results.

Shared by the golden-model tests and the RTL tests: each case is (name, request, check) where
``check(response_row)`` asserts the paper's expected outcome.
"""

from __future__ import annotations

import numpy as np

from driver import QUADBOX, TRIANGLE, prepare_rays

INF = np.inf
UNIT = (-1, -1, -1, 1, 1, 1)
FAR = (INF, INF, INF, INF, INF, INF)           # an unused box slot: a box at +inf
SLAB = lambda x0, x1: (x0, -.5, -.5, x1, .5, .5)  # noqa: E731


def box_request(origin, direction, boxes, extent=INF):
    """One QUADBOX request; slots after ``boxes`` hold the unused box at +inf."""
    r = prepare_rays([origin], [direction], extent)
    r["opcode"] = QUADBOX
    boxes = list(boxes) + [FAR] * (4 - len(boxes))
    r["box"][0] = np.array(boxes, np.float32)
    return r


FRONT = ((1, -1, -1), (0, 1, -1), (-1, -1, -1))


def tri_request(tri, direction, origin=(0, 0, 0), extent=4000):
    """One TRIANGLE request."""
    r = prepare_rays([origin], [direction], extent)
    r["opcode"] = TRIANGLE
    r["tri"][0] = np.array(tri, np.float32)
    return r


def t_of(rsp):
    return np.float32(rsp["t_num"]) / np.float32(rsp["t_den"])


def expect_box(order_t):
    """order_t: list of (index, t) for the hits in sorted order; the rest must be misses."""
    def check(rsp):
        hits = int(rsp["box_hit"].sum())
        assert hits == len(order_t), (rsp["box_hit"], rsp["box_tmin"])
        for j, (idx, t) in enumerate(order_t):
            assert rsp["box_index"][j] == idx
            assert rsp["box_tmin"][j] == np.float32(t)
        for j in range(hits, 4):
            assert not rsp["box_hit"][j] and rsp["box_tmin"][j] == np.inf
        missing = [i for i in range(4) if i not in [i for i, _ in order_t]]
        assert list(rsp["box_index"][hits:]) == missing        # misses last, in index order
    return check


def expect_tri(t=None, num_den=None):
    def check(rsp):
        if t is None:
            assert not rsp["tri_hit"]
            return
        assert rsp["tri_hit"]
        if num_den is not None:
            assert (rsp["t_num"], rsp["t_den"]) == num_den
        np.testing.assert_allclose(t_of(rsp), t, rtol=1e-6)
    return check


CASES = [
    ("box1_inside", box_request((.5, -.5, .5), (1e-4, -1e-4, -1e-3), [UNIT]), expect_box([(0, 0)])),
    ("box2_outside_away", box_request((2, 0, 0), (1, 0, 0), [UNIT]), expect_box([])),
    ("box3_surface_away", box_request((1, 0, 0), (1, 0, 0), [UNIT]), expect_box([])),
    ("box4_corner_away", box_request((1, 1, 1), (1, 1, 1), [UNIT]), expect_box([])),
    ("box5_corner_along_edge", box_request((1, 1, 1), (0, -1, 0), [UNIT]), expect_box([])),
    ("box6_outside_towards", box_request((-2, 0, 0), (1, 0, 0), [UNIT]), expect_box([(0, 1)])),
    ("box7_two_in_a_row", box_request((-2, 0, 0), (10, 0, 0), [UNIT, SLAB(2, 2.5)]),
     expect_box([(0, 0.1), (1, 0.4)])),
    ("box8_three_and_a_miss",
     box_request((-2, 0, 0), (10, 0, 0), [SLAB(2, 2.5), SLAB(100, 100.25), SLAB(-5, -4), UNIT]),
     expect_box([(3, 0.1), (0, 0.4), (1, 10.2)])),
    ("box9_along_edge", box_request((1, 2, 1), (0, -1, 0), [UNIT]), expect_box([])),
    ("tri1_back_face", tri_request(((-1, -1, -1), (0, 1, -1), (1, -1, -1)), (0, 0, -5)), expect_tri()),
    ("tri2_front", tri_request(FRONT, (0, 0, -1)), expect_tri(1, (4, 4))),
    ("tri3_edge", tri_request(((1, -1, -1), (0, 1, -1), (0, -1, -1)), (0, 0, -5)), expect_tri(0.2)),
    ("tri4_vertex", tri_request(((1, -1, -1), (0, 0, -1), (0, -1, -1)), (0, 0, -5)), expect_tri(0.2)),
    ("tri5_away", tri_request(FRONT, (0, 0, 5)), expect_tri()),
    ("tri6_parallel_to_normal_outside", tri_request(FRONT, (0, 0, -5), origin=(-5, 5, 0)), expect_tri()),
    ("tri7_far", tri_request(tuple((x, y, -100) for x, y, _ in FRONT), (0, 0, -5)), expect_tri(20)),
    ("tri8_oblique", tri_request(((1, -1, -3), (0, 1, -1), (-1, -1, -2)), (0, 0, -5)), expect_tri(0.35)),
    ("tri9_coplanar_edge", tri_request(FRONT, (0, 5, 0), origin=(0, -2, -1)), expect_tri()),
    ("tri10_other_axis", tri_request(((1, -1, 1), (1, 1, 0), (1, -1, -1)), (.25, 0, 0), origin=(-100, 0, 0)),
     expect_tri(404)),
    ("tri11_coplanar_inside", tri_request(FRONT, (0, 5, 0), origin=(0, -1 / 3, -1)), expect_tri()),
]


def all_requests():
    """The 20 cases as one request array, in order (for stream tests)."""
    return np.concatenate([r for _, r, _ in CASES])
