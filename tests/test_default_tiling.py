"""Bounded memory by default: a big primary frame is tiled without ``--tile``, and a frame
tiled because of its size is the same frame as one wavefront."""

from __future__ import annotations

import numpy as np

import driver.render
from driver.render import (BASE_BYTES, FRAME_BYTES_PER_PIXEL, MEMORY_TILE, PEAK_BYTES_PER_RAY,
                           WHOLE_FRAME_PIXELS, plan_tile, render)


def test_big_primary_frame_is_tiled_by_default(monkeypatch):
    monkeypatch.setattr(driver.render, "available_memory", lambda: 64 * 2**30)
    assert plan_tile(256 * 256, "primary", 1, None, 1, None) is None
    assert plan_tile(WHOLE_FRAME_PIXELS, "primary", 1, None, 1, None) is None
    assert plan_tile(WHOLE_FRAME_PIXELS + 1, "primary", 1, None, 1, None) == MEMORY_TILE
    assert plan_tile(4096 * 4096, "primary", 1, None, 1, None) == MEMORY_TILE
    assert plan_tile(4096 * 4096, "primary", 1, 32, 1, None) == 32       # --tile wins
    # the estimate of the tiled 4096² frame (buffers + one tile) stays far below 3 GiB, and the
    # largest whole frame below 1.5 GiB
    tiled = BASE_BYTES + FRAME_BYTES_PER_PIXEL * 4096**2 + PEAK_BYTES_PER_RAY * MEMORY_TILE**2
    assert tiled < 1.5 * 2**30
    assert BASE_BYTES + PEAK_BYTES_PER_RAY * WHOLE_FRAME_PIXELS < 1.5 * 2**30


def test_frame_tiled_for_its_size_equals_the_whole_frame(monkeypatch):
    whole = render("sphere", 40, 30, backend="golden", progress=False)
    assert whole.trace is not None                                   # one wavefront
    monkeypatch.setattr(driver.render, "WHOLE_FRAME_PIXELS", 40 * 30 - 1)
    tiled = render("sphere", 40, 30, backend="golden", progress=False)
    assert tiled.trace is None and tiled.stats["tile"] == MEMORY_TILE
    assert np.array_equal(whole.image, tiled.image)
    assert np.array_equal(whole.ops, tiled.ops)
    for key in ("rays", "hits", "box_ops", "tri_ops", "ops"):
        assert whole.stats[key] == tiled.stats[key], key
