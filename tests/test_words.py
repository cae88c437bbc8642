"""Counts in words and table cells (driver.core.words): "1 edge tie", "0 edge ties", "1 run",
and one mark for a missing value in every table."""

from __future__ import annotations

import math

from driver.check import summary
from driver.core.words import MISSING, cell, plural


def test_plural_agrees_with_the_count():
    assert [plural(n, "run") for n in (0, 1, 2)] == ["0 runs", "1 run", "2 runs"]
    assert plural(1, "vertex", "vertices") == "1 vertex"
    assert plural(3, "vertex", "vertices") == "3 vertices"
    assert plural(12832, "edge tie", fmt=",") == "12,832 edge ties"


def test_the_embree_line_says_1_edge_tie_and_0_edge_ties():
    """The check's line read "1 edge ties" and, decided exactly, "0 edge tie"."""
    e = {"rays_compared": 1, "hit_mismatch": 1, "prim_mismatch": 0, "edge_ties": 1,
         "max_t_rel_err": 0.0, "adjudicated": {"classes": {
             "agree": 1, "edge_tie": 0, "embree_wrong": 0, "datapath_wrong": 0}}}
    assert summary(e) == ("embree: 1 ray compared, 1 hit/miss mismatch, 0 primitive "
                          "mismatches, 1 edge tie, max t rel err 0; decided exactly: 1 agree, "
                          "0 edge ties, 0 embree wrong, 0 datapath wrong")


def test_a_missing_value_is_one_mark():
    assert cell(None, ".3f") == cell(math.nan, ".3f") == MISSING
    assert cell(0.5, ".3f") == "0.500" and cell(7, ",") == "7"
