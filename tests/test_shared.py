"""The SHARED build (docs/tradeoffs.md#sharing-registers): an extended beat's vectors travel on
the request registers' box and triangle bits. The same results as every configuration, bit for
bit: the RTL against the golden model on the extended streams under random back-pressure, with
and without the q8 decode register (the second request register)."""

from __future__ import annotations

import pytest

from driver.core.configs import DESIGN_CONFIGS, SHARED_SUFFIX, parse_config
from driver.design import DesignPoint
from support.streams import extended_stream
from support.testbench import Testbench


def test_config_names():
    assert parse_config("extended-unified" + SHARED_SUFFIX) == {
        "EXTENDED": 1, "DISJOINT": 0, "SHARED": 1}
    assert parse_config("extended-disjoint-q8-shared-fused") == {
        "EXTENDED": 1, "DISJOINT": 1, "COMPRESSED": 1, "FUSED": 1, "SHARED": 1}
    assert parse_config("baseline-unified-shared") is None       # no vectors to share
    assert parse_config("extended-unified-fused-shared") is None  # suffixes in their order
    assert "extended-unified-q8-shared" in DESIGN_CONFIGS
    p = DesignPoint(config="extended-unified-shared")
    assert p.shared and p.extended and p.backend_options()["shared"]
    assert p.rtl_params()["SHARED"] == 1 and "SHARED" not in DesignPoint().rtl_params()
    with pytest.raises(ValueError, match="--config: unknown value 'baseline-unified-shared'"):
        DesignPoint(config="baseline-unified-shared")


# The default suite streams through the build with every option (extended-disjoint-q8-shared);
# extended-unified-shared, a Verilator model of its own, runs with -m slow.
@pytest.mark.parametrize("disjoint,compressed,gaps,stalls", [
    (True, True, 0.5, 0.5), (True, True, 0.9, 0.1),
    pytest.param(False, False, 0.5, 0.5, marks=pytest.mark.slow),
    pytest.param(False, False, 0.9, 0.1, marks=pytest.mark.slow)],
    ids=["disjoint-q8-gaps0.5-stalls0.5", "disjoint-q8-gaps0.9-stalls0.1",
         "unified-gaps0.5-stalls0.5", "unified-gaps0.9-stalls0.1"])
def test_rtl_shared_extended(disjoint, compressed, gaps, stalls):
    req, _ = extended_stream(21, n_jobs=20, n_box=1500, n_tri=1000)
    Testbench("rtl", extended=True, disjoint=disjoint, compressed=compressed, shared=True,
              gaps=gaps, stalls=stalls, seed=21).run(req)
